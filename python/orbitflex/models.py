"""Built-in models.

``space_arm()``: a 500 kg, 1.5 m cube spacecraft bus carrying a 7-joint, 86 kg space arm (two
carbon-fibre booms of 2.0 m and 1.8 m, a 3-joint wrist, a 3 kg end-effector), EE link ``ee``.
The URDF text is embedded in the compiled module (``space_arm_urdf()``).

``DEFAULT_BUS_SIDE`` (1.5 m): the edge of the solid cube that stands for a bus given by its mass
alone, in ``Robot.with_base_inertia(mass)`` and ``orbitflex simulate --base-mass``.

``dual_arm()``: the same bus carrying two of those arms, mounted 0.9 m apart on the same face
(the right arm is the mirror image of the left): 14 joints, ``left_*`` first, end-effectors
``left_ee`` and ``right_ee``, 672 kg in all (``dual_arm_urdf()``).
"""

from __future__ import annotations

from ._core import DEFAULT_BUS_SIDE, DUAL_ARM_URDF, SPACE_ARM_URDF, FlexibleJoints, Robot

__all__ = [
    "DEFAULT_BUS_SIDE",
    "space_arm",
    "space_arm_urdf",
    "space_arm_joints",
    "dual_arm",
    "dual_arm_urdf",
    "dual_arm_joints",
]


def space_arm() -> Robot:
    """The built-in default model: bus + 7-joint arm (see the module docstring)."""
    return Robot.space_arm()


def space_arm_urdf() -> str:
    """The URDF text of the built-in model, e.g. to write it to a file or load it elsewhere."""
    return SPACE_ARM_URDF


def space_arm_joints() -> FlexibleJoints:
    """Plausible harmonic-drive joint parameters for the built-in arm (link side).

    Stiffness 1e4 N m/rad at the shoulder, 5e3 at the elbow, 2e3 in the wrist (space-arm joints
    are compliant: long output shafts and light gearboxes); reflected motor inertia from gear
    ratio 160 and rotor inertia 4e-5 ... 1.5e-5 kg m^2 (j = 1.02 ... 0.38 kg m^2); light joint
    damping (0.2 N m s/rad) so that residual vibration is visible; motor friction 1 N m s/rad.
    Open loop, RK4 is stable up to dt of about 10 ms; a stiff motor PD lowers that (see
    ``FlexibleArm.rk4_stability_limit``).
    """
    return FlexibleJoints.space_arm()


def dual_arm() -> Robot:
    """The built-in dual-arm servicer: bus + two 7-joint arms (see the module docstring).

    Joints 0-6 are the left arm, 7-13 the right (``robot.parents`` is -1 at 0 and 7);
    ``robot.ee_links == ["left_ee", "right_ee"]``, the order of ``ee_wrench`` rows.
    """
    return Robot.dual_arm()


def dual_arm_urdf() -> str:
    """The URDF text of the dual-arm servicer."""
    return DUAL_ARM_URDF


def dual_arm_joints() -> FlexibleJoints:
    """``space_arm_joints()`` for each arm of ``dual_arm()``: the left arm's 7, then the right's."""
    return FlexibleJoints.dual_arm()
