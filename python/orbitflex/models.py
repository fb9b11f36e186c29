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
from dataclasses import dataclass, replace
from typing import Any, Optional

import numpy as np

from ._core import (
    DEFAULT_BUS_SIDE,
    DUAL_ARM_URDF,
    SPACE_ARM_URDF,
    AttitudePD,
    CaptureWhen,
    FlexibleArm,
    FlexibleJoints,
    MotorPD,
    ReactionWheels,
    Robot,
    Target,
    Trajectory,
    _capture_scenario,
    rotation_matrix,
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
    "DETUMBLE_BANDWIDTH",
]

# The AttitudePD bandwidth (rad/s) with which capture_scenario(wheels=...) detumbles the stack by
# default (damping ratio 0.7 about its major axis): a ninth of the lowest mode of the arm holding
# its 200 kg catch under the stack-tuned motor PD (0.143 Hz = 0.90 rad/s, ζ ≈ 0.58), so the stack
# turns as one rigid body under the attitude loop (orbitflex.detumble).
DETUMBLE_BANDWIDTH = 0.05


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

    - ``arm``: the built-in space arm (500 kg bus, 7 flexible joints), with ``wheels`` if given;
    - ``x0``: the arm at rest in its pre-grasp posture (springs relaxed, wheels at rest);
    - ``target``: the 200 kg client at ``t = 0``;
    - ``when``: the trigger (1 cm, 5 cm/s, 5 deg);
    - ``controller``: the motor PD holding the pre-grasp posture before and after the capture
      (0.25 Hz, damping ratio 1, tuned for the arm alone or for the arm holding its catch:
      ``motor_pd``);
    - ``wheel_controller``: the ``AttitudePD`` driving the wheels (holding the bus at its
      initial attitude; ``None`` without wheels);
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
    wheel_controller: Optional[AttitudePD] = None

    @property
    def steps(self) -> int:
        """``round(duration / dt)``."""
        return int(round(self.duration / self.dt))

    def run(self, duration: Optional[float] = None, **simulate: Any) -> Trajectory:
        """``arm.simulate`` of the scenario (``duration`` in s, default the scenario's), with
        its target, trigger and wheel controller; other keywords (``record_every``,
        ``progress``, ...) pass on."""
        steps = self.steps if duration is None else int(round(duration / self.dt))
        if self.wheel_controller is not None:
            simulate.setdefault("wheel_torque", self.wheel_controller)
        return self.arm.simulate(
            self.x0, self.dt, steps, self.controller,
            target=self.target, capture=self.when, **simulate,
        )

    def stack(self) -> FlexibleArm:
        """The arm holding the target as it would at the exact meeting (the handle's frame on
        the EE's): ``robot.with_payload`` of the target at the grasp's pose, with the arm's
        joints and wheels. What the stack-tuned motor PD and the default detumble gains are
        computed for (a run's ``arm_after`` differs only by the trigger's small offset)."""
        t = self.target
        grasp = np.asarray(t.grasp)
        r = rotation_matrix(grasp[3:])  # the handle's axes in the target's frame: R_{t,g}
        com = r.T @ (np.asarray(t.com) - grasp[:3])
        inertia = r.T @ np.asarray(t.inertia) @ r
        robot = self.arm.robot.with_payload(t.mass, inertia, com)
        return FlexibleArm(robot, self.arm.joints, wheels=self.arm.wheels)


def capture_scenario(
    tumble_deg_s: float = 2.0, drift: float = 0.02, meet: float = 5.0,
    wheels: Optional[ReactionWheels] = None, attitude_pd: Optional[AttitudePD] = None,
    motor_pd: Optional[str] = None,
) -> CaptureScenario:
    """The built-in capture scenario: the space arm, holding its pre-grasp posture, captures a
    200 kg target spinning at ``tumble_deg_s`` (deg/s) about its major axis, whose handle
    drifts onto the end-effector along its approach axis at ``drift`` (m/s), reaching it at
    ``meet`` (s). Computed in Rust (``orbitflex::capture::scenario``).

    ``wheels``: reaction wheels in the bus (``ReactionWheels``; ``pyramid_wheels()`` fits) to
    detumble the stack after the capture, driven by ``attitude_pd`` (an ``AttitudePD``; default
    :func:`orbitflex.detumble.detumble_gains` of the stack's inertia at ``DETUMBLE_BANDWIDTH`` rad/s,
    damping ratio 0.7, holding the bus at its initial attitude). The arm's motors alone cannot
    remove the stack's angular momentum; the wheels take it.

    ``motor_pd``: ``"arm"`` tunes the motor PD (0.25 Hz, damping ratio 1) for the arm alone,
    ``"stack"`` for the arm holding its catch (:meth:`CaptureScenario.stack`: stiffer; the arm
    alone then rings at ≈ 0.22 Hz, ζ ≈ 0.89). Default ``"stack"`` with wheels, ``"arm"``
    without. Tuned for the arm alone, the arm holding 200 kg swings at 0.025 Hz with a damping
    ratio of 0.085: it takes minutes to settle, and a detumble waits for it."""
    from .detumble import detumble_gains, stack_inertia

    if motor_pd is None:
        motor_pd = "arm" if wheels is None else "stack"
    if motor_pd not in ("arm", "stack"):
        raise ValueError(f"motor_pd: expected 'arm' or 'stack', given {motor_pd!r}")
    if attitude_pd is not None and wheels is None:
        raise ValueError("attitude_pd: given without wheels; give the ReactionWheels it drives (wheels=)")
    if wheels is not None and not isinstance(wheels, ReactionWheels):
        raise TypeError(f"wheels: expected a ReactionWheels, given {type(wheels).__name__}")
    if attitude_pd is not None and not isinstance(attitude_pd, AttitudePD):
        raise TypeError(f"attitude_pd: expected an AttitudePD, given {type(attitude_pd).__name__}")
    d = _capture_scenario(tumble_deg_s, drift, meet)
    arm = FlexibleArm(space_arm(), space_arm_joints(), wheels=wheels)
    x0 = np.asarray(d["x0"])
    if wheels is not None:
        n = arm.dof
        x0 = arm.state(q=x0[7:7 + n], theta=x0[7 + n:7 + 2 * n])
    target = Target(d["mass"], d["inertia"], d["pose"], d["twist"], d["grasp"], name=d["name"])
    s = CaptureScenario(
        arm=arm,
        x0=x0,
        target=target,
        when=CaptureWhen(d["distance"], d["speed"], d["angle"]),
        controller=MotorPD(d["kp"], d["kd"], d["theta_ref"]),
        dt=d["dt"],
        duration=d["duration"],
        meet=d["meet"],
    )
    stack = s.stack() if (motor_pd == "stack" or (wheels is not None and attitude_pd is None)) else None
    if motor_pd == "stack" and stack is not None:
        kp, kd = stack.motor_pd_gains(0.25, 1.0, q=d["theta_ref"])
        s = replace(s, controller=MotorPD(kp, kd, d["theta_ref"]))
    if wheels is not None:
        if attitude_pd is None and stack is not None:
            attitude_pd = AttitudePD(*detumble_gains(stack_inertia(stack, x0)[2], DETUMBLE_BANDWIDTH, 0.7))
        s = replace(s, wheel_controller=attitude_pd)
    return s
