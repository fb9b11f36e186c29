# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""``orbitflex plan --wheels wheels.toml``: what holding the bus through a held-base plan asks of
the wheels (``Plan.wheel_demand``), and the plan tracked with the wheels holding the bus under
their ``AttitudePD`` in place of the open-loop wrench (``Plan.track(..., wheel_torque=...)``):
its pointing error and the wheels' peak speed and torque against their limits."""

from __future__ import annotations

import argparse
import warnings
from dataclasses import dataclass
from typing import Any, Dict, Optional

import numpy as np

from .. import FlexibleArm, Plan, SimulationError, plan_slew, rotation_angle
from ..wheels_file import WheelsFile, WheelsFileError, read_wheels
from .errors import CliError
from .jobs import failure_reason


@dataclass
class WheelPlan:
    """The wheels' share of a held-base plan: the open-loop demand and the tracked run."""

    spec: WheelsFile
    demand: Dict[str, Any]  # Plan.wheel_demand
    run: Optional[Dict[str, Any]]  # Plan.track with the wheels, None if it failed
    failure: Optional[str]
    pointing_error: float  # rad, the largest rotation of the bus from its start along the run

    def summary(self) -> Dict[str, Any]:
        w = self.spec.wheels
        d = self.demand
        out: Dict[str, Any] = {
            "source": self.spec.source, "wheels": len(w),
            "attitude_pd": {"kp": self.spec.kp.tolist(), "kd": self.spec.kd.tolist()},
            "demand": {"peak_torque_Nm": d["peak_torque"].tolist(), "peak_speed_rad_s": d["peak_speed"].tolist(),
                       "peak_momentum_Nms": d["peak_momentum"],
                       "binding": {k: d["binding"][k] for k in ("limit", "wheel", "time", "value", "bound", "ratio")}},
            "tracked": None if self.run is None else {
                "max_bus_attitude_error_rad": self.pointing_error,
                "peak_wheel_speed_fraction": self.speed_fraction().tolist(),
                "peak_wheel_torque_fraction": self.torque_fraction().tolist(),
                "base_position_error_m": self.run["base_position_error"],
                "tracking_error_rad": self.run["tracking_error"]},
            "failed": self.failure,
        }
        return out

    def speed_fraction(self) -> np.ndarray:
        assert self.run is not None
        traj = self.run["trajectory"]
        fraction: np.ndarray = np.abs(traj.wheel_speed).max(axis=0) / np.asarray(self.spec.wheels.max_speed)
        return fraction

    def torque_fraction(self) -> np.ndarray:
        assert self.run is not None
        traj = self.run["trajectory"]
        fraction: np.ndarray = np.abs(traj.wheel_torque).max(axis=0) / np.asarray(self.spec.wheels.max_torque)
        return fraction


def wheel_plan(args: argparse.Namespace, plan: Plan, dt: float, kp: np.ndarray, kd: np.ndarray,
               settle: float) -> Optional[WheelPlan]:
    """The wheels' share of ``plan`` for ``--wheels`` (None without it). The plan is made again
    on the arm with the wheels (a held bus does not turn: the same plan), then tracked with the
    wheels holding the bus."""
    path = getattr(args, "wheels", None)
    if path is None:
        return None
    if plan.base != "held":
        raise CliError("--wheels", "the wheels hold the bus of a held-base plan (--base held); a free-floating "
                                   "plan asks nothing of them")
    try:
        spec = read_wheels(path)
    except WheelsFileError as e:
        raise CliError("--wheels", str(e)) from None
    try:
        arm = FlexibleArm(plan.arm.robot, plan.arm.joints, wheels=spec.wheels)
        demand = plan.wheel_demand(spec.wheels)
        stops = np.asarray(plan.stops)
        wheeled = plan_slew(arm, stops[-1], q_start=stops[0], limits=plan.limits, base="held",
                            waypoints=stops[1:-1] if len(stops) > 2 else None)
        controller = spec.controller()
    except ValueError as e:
        raise CliError("--wheels", str(e)) from None
    run, failure, pointing = None, None, float("nan")
    try:
        with warnings.catch_warnings():
            # the tracking runs have reported dt against the RK4 limit of the arm's loop
            warnings.simplefilter("ignore", RuntimeWarning)
            run = wheeled.track(dt, kp, kd, settle, wheel_torque=controller)
        quat = run["trajectory"].base_pose[:, 3:]
        pointing = float(np.max(rotation_angle(quat[0], quat)))
    except SimulationError as e:
        failure = failure_reason(e)
    return WheelPlan(spec, demand, run, failure, pointing)


def print_wheel_plan(w: WheelPlan) -> None:
    """The wheels' lines of ``orbitflex plan``'s summary."""
    d, b = w.demand, w.demand["binding"]
    print(f"\n  wheels              {len(w.spec.wheels)} from {w.spec.source}, holding the bus in place of the wrench")
    print(f"    demand            peak torque {d['peak_torque'].max():.4g} N·m, peak speed {d['peak_speed'].max():.4g} "
          f"rad/s, peak stored momentum {d['peak_momentum']:.4g} N·m·s (open loop, the plan's holding moment)")
    verdict = "within its limits" if b["ratio"] <= 1.0 else "past its limit: these wheels cannot hold the bus"
    print(f"    binding           {b['limit']} of wheel {b['wheel']} at {b['time']:.3f} s: {b['value']:.4g} of "
          f"{b['bound']:.4g} ({b['ratio']:.3f}×), {verdict}")
    if w.run is None:
        print(f"    tracked           the run with the wheels failed: {w.failure}")
        return
    kp, kd = w.spec.kp, w.spec.kd
    gains = f"kp {kp[0]:g}" if np.all(kp == kp[0]) else f"kp {kp.tolist()}"
    gains += f", kd {kd[0]:g}" if np.all(kd == kd[0]) else f", kd {kd.tolist()}"
    print(f"    tracked           AttitudePD ({gains}): bus pointing error at most {w.pointing_error:.3e} rad, "
          f"drift {w.run['base_position_error']:.3g} m")
    print(f"    peak fractions    speed {w.speed_fraction().max():.3f} of max_speed, torque "
          f"{w.torque_fraction().max():.3f} of max_torque (applied, after saturation)")
