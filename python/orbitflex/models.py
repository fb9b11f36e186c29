"""Built-in models.

``space_arm()``: a 500 kg, 1.5 m cube spacecraft bus carrying a 7-joint, 86 kg space arm (two
carbon-fibre booms of 2.0 m and 1.8 m, a 3-joint wrist, a 3 kg end-effector), EE link ``ee``.
The URDF text is embedded in the compiled module (``space_arm_urdf()``).

``DEFAULT_BUS_SIDE`` (1.5 m): the edge of the solid cube that stands for a bus given by its mass
alone, in ``Robot.with_base_inertia(mass)`` and ``orbitflex simulate --base-mass``.

``pyramid_wheels()``: four reaction wheels in a pyramid inside that bus, sized to hold it through
the demo's slew (``orbitflex demo``); ``PYRAMID_GAINS`` the ``AttitudePD`` gains that do.

``capture_scenario()``: the built-in space arm holding a pre-grasp posture under its motor PD
while a 200 kg target (a 1.0 × 1.2 × 1.4 m box) spinning at 2 deg/s about its major axis drifts
onto the end-effector at 2 cm/s; see :class:`CaptureScenario`.

``dual_arm()``: the same bus carrying two of those arms, mounted 0.9 m apart on the same face
(the right arm is the mirror image of the left): 14 joints, ``left_*`` first, end-effectors
``left_ee`` and ``right_ee``, 672 kg in all (``dual_arm_urdf()``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from ._core import (
    DEFAULT_BUS_SIDE,
    DUAL_ARM_URDF,
    SPACE_ARM_URDF,
    CaptureWhen,
    FlexibleArm,
    FlexibleJoints,
    MotorPD,
    ReactionWheels,
    Robot,
    Target,
    Trajectory,
    _capture_scenario,
)

__all__ = [
    "DEFAULT_BUS_SIDE",
    "space_arm",
    "space_arm_urdf",
    "space_arm_joints",
    "pyramid_wheels",
    "PYRAMID_GAINS",
    "dual_arm",
    "dual_arm_urdf",
    "dual_arm_joints",
    "capture_scenario",
    "CaptureScenario",
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


# AttitudePD gains (kp N·m/rad, kd N·m·s/rad, per base axis) that hold the built-in bus within
# 1e-3 rad through the demo's slew with pyramid_wheels(): about 3.7 Hz, damping ratio ≈ 1.1 on
# the bus (≈ 190 kg·m² about each axis), so the arm's reaction (≈ 50 N·m peak) leaves ≈ 4e-4 rad.
PYRAMID_GAINS = (2.0e5, 2.0e4)


def pyramid_wheels(spin_inertia: float = 0.25, transverse_inertia: float = 0.15, mass: float = 12.0,
                   max_torque: float = 60.0, max_speed: float = 800.0, friction: float = 0.0,
                   elevation_deg: float = math.degrees(math.atan(1 / math.sqrt(2))),
                   radius: float = 0.45, depth: float = -0.45) -> ReactionWheels:
    """Four reaction wheels in a pyramid: spin axes at ``elevation_deg`` above the bus's x-y
    plane and at azimuths 45°, 135°, 225°, 315° (the default elevation 35.26° puts them along
    ``(±1, ±1, 1)/√3``, equal capacity about every axis); centres ``radius`` m out along each
    axis's azimuth and ``depth`` m along z (base frame), inside the built-in 1.5 m bus.

    The defaults are sized for the demo: the built-in arm's 5 s slew, with the bus held by
    ``AttitudePD(*PYRAMID_GAINS)``, needs about 50 N·m of wheel torque at its peak and leaves
    about 110 N·m·s in the wheels: ``spin_inertia`` 0.25 kg·m² (at ``max_speed`` 800 rad/s,
    200 N·m·s per wheel), ``max_torque`` 60 N·m. Large for reaction wheels (a fast slew of
    a 2 m arm is a large disturbance): shrink them to see saturation."""
    el = math.radians(elevation_deg)
    axes, positions = [], []
    for k in range(4):
        az = math.radians(45.0 + 90.0 * k)
        axes.append([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        positions.append([radius * math.cos(az), radius * math.sin(az), depth])
    return ReactionWheels(axes, positions, mass, spin_inertia, transverse_inertia, max_torque, max_speed,
                          friction=friction)


@dataclass(frozen=True)
class CaptureScenario:
    """A capture run as values (``capture_scenario()``).

    - ``arm``: the built-in space arm (500 kg bus, 7 flexible joints);
    - ``x0``: the arm at rest in its pre-grasp posture (springs relaxed);
    - ``target``: the 200 kg client at ``t = 0``;
    - ``when``: the trigger (1 cm, 5 cm/s, 5 deg);
    - ``controller``: the motor PD (0.25 Hz, damping ratio 1) holding the pre-grasp posture
      before and after the capture;
    - ``dt`` (s), ``duration`` (s), ``meet`` (s): when the handle would reach the EE exactly
      (the trigger fires once it is within ``when.distance``, 0.5 s earlier at 2 cm/s).
    """

    arm: FlexibleArm
    x0: np.ndarray
    target: Target
    when: CaptureWhen
    controller: MotorPD
    dt: float
    duration: float
    meet: float

    @property
    def steps(self) -> int:
        """``round(duration / dt)``."""
        return int(round(self.duration / self.dt))

    def run(self, duration: Optional[float] = None, **simulate: Any) -> Trajectory:
        """``arm.simulate`` of the scenario (``duration`` in s, default the scenario's), with
        its target and trigger; other keywords (``record_every``, ``progress``, ...) pass on."""
        steps = self.steps if duration is None else int(round(duration / self.dt))
        return self.arm.simulate(
            self.x0, self.dt, steps, self.controller,
            target=self.target, capture=self.when, **simulate,
        )


def capture_scenario(
    tumble_deg_s: float = 2.0, drift: float = 0.02, meet: float = 5.0
) -> CaptureScenario:
    """The built-in capture scenario: the space arm, holding its pre-grasp posture, captures a
    200 kg target spinning at ``tumble_deg_s`` (deg/s) about its major axis, whose handle
    drifts onto the end-effector along its approach axis at ``drift`` (m/s), reaching it at
    ``meet`` (s). Computed in Rust (``orbitflex::capture::scenario``)."""
    d = _capture_scenario(tumble_deg_s, drift, meet)
    arm = FlexibleArm(space_arm(), space_arm_joints())
    target = Target(d["mass"], d["inertia"], d["pose"], d["twist"], d["grasp"], name=d["name"])
    return CaptureScenario(
        arm=arm,
        x0=d["x0"],
        target=target,
        when=CaptureWhen(d["distance"], d["speed"], d["angle"]),
        controller=MotorPD(d["kp"], d["kd"], d["theta_ref"]),
        dt=d["dt"],
        duration=d["duration"],
        meet=d["meet"],
    )
