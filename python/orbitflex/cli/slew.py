# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""The slew of ``demo`` and ``simulate``: its quintic reference, its motor PD's gains and the check
of the step against the closed loop's RK4 stability limit."""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

from .. import FlexibleArm, MotorPD, Robot, quintic_reference
from .errors import CliError, cli_words


Array = npt.NDArray[np.float64]


Rows = npt.NDArray[np.intp]  # indices of the rows drawn in a plot


SPACE_ARM_SLEW = np.array([0.4, 0.6, -0.5, 0.8, -0.6, 0.5, 1.0])


@dataclass
class Gains:
    """The motor PD of a slew: its gains per joint and where they came from."""

    kp: Array  # N·m/rad
    kd: Array  # N·m·s/rad
    bandwidth_hz: Optional[float]  # the closed-loop bandwidth they were chosen for (None: both given)
    damping_ratio: Optional[float]
    given: Tuple[str, ...] = ()  # the flags that set gains directly: "--kp", "--kd"

    def as_dict(self) -> Dict[str, Any]:
        return {"kp": self.kp.tolist(), "kd": self.kd.tolist(), "bandwidth_hz": self.bandwidth_hz,
                "damping_ratio": self.damping_ratio, "given": list(self.given)}


def choose_gains(arm: FlexibleArm, args: argparse.Namespace) -> Gains:
    """The slew's motor PD: ``--kp``/``--kd`` where given, the rest from ``--bandwidth`` and
    ``--damping-ratio`` (:meth:`FlexibleArm.motor_pd_gains`, at the start, q = 0). Never from dt."""
    given = tuple(flag for flag, value in (("--kp", args.kp), ("--kd", args.kd)) if value is not None)
    kp = kd = None
    if len(given) < 2:
        try:
            kp, kd = arm.motor_pd_gains(args.bandwidth, args.damping_ratio)
        except ValueError as e:
            raise CliError("--bandwidth", cli_words(str(e)).removeprefix("bandwidth: ")) from None
    if args.kp is not None:
        kp = per_joint(args.kp, "--kp", arm.robot)
    if args.kd is not None:
        kd = per_joint(args.kd, "--kd", arm.robot)
    assert kp is not None and kd is not None
    rule = len(given) < 2
    return Gains(np.asarray(kp), np.asarray(kd), args.bandwidth if rule else None,
                 args.damping_ratio if rule else None, given)


def slew_controller(arm: FlexibleArm, slew: Array, steps: int, dt: float, slew_time: float,
                    gains: Gains) -> MotorPD:
    """The motor PD with ``gains`` that follows a quintic slew of ``slew`` (rad per joint) over
    ``slew_time`` seconds, tabulated for ``steps`` steps of ``dt``."""
    theta_ref, theta_dot_ref = quintic_reference(np.zeros_like(slew), slew, slew_time, dt, steps)
    return MotorPD(gains.kp, gains.kd, theta_ref, theta_dot_ref)


def check_step(arm: FlexibleArm, pd: MotorPD, gains: Gains, dt: float, force: bool) -> float:
    """The RK4 stability limit (s) of the closed loop at rest; a ``--dt`` past it is refused
    (with ``--force``: a warning, and the run goes on). The controller never changes with dt."""
    limit = arm.rk4_stability_limit(u=pd).dt
    if dt > limit:
        advice = (f"use --dt {round_down(DT_MARGIN * limit):g} or less, or a lower "
                  + ("--bandwidth" if gains.bandwidth_hz is not None else "--kp/--kd"))
        message = (f"{dt:g} s is past the RK4 stability limit {limit:.3g} s of the closed loop (the arm "
                   f"under its motor PD, the torque held over each step)")
        if not force:
            raise CliError("--dt", f"{message}; {advice}, or --force to run anyway")
    return limit  # with --force, simulate warns and runs


# Default RK4 step of the tracking runs (s), lowered to a round value within this share of the
# stability limit when the limit requires it.
TRACK_DT = 1e-3
DT_MARGIN = 0.8


def round_down(x: float) -> float:
    """The largest 1, 2 or 5 times a power of ten that is at most ``x`` (> 0)."""
    decade = 10.0 ** math.floor(math.log10(x))
    return next(m * decade for m in (5, 2, 1) if m * decade <= x * (1 + 1e-12))


def per_joint(values: Optional[Sequence[float]], flag: str, robot: Robot, default: Optional[float] = None) -> Array:
    """``values`` for every joint: one value (for all) or one per joint, in the robot's order."""
    if values is None:
        assert default is not None
        return np.full(robot.dof, default)
    array = np.asarray(values, dtype=float)
    if len(array) == 1:
        return np.full(robot.dof, array[0])
    if len(array) != robot.dof:
        raise CliError(flag, f"expected 1 or {robot.dof} values (one per joint: "
                             f"{', '.join(robot.joint_names)}), given {len(array)}")
    return array
