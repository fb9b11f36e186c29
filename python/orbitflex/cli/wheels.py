# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""The wheel case of ``demo`` and ``simulate --wheels``: the same slew with reaction wheels
holding the bus under ``AttitudePD``, its summary lines and its plot (wheel speeds and torques
against their limits, and the bus's attitude error)."""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional

import numpy as np

from .. import FlexibleArm, MotorPD, SimulationError, Trajectory, models, rotation_angle
from ..wheels_file import WheelsFile, WheelsFileError, read_wheels
from .errors import CliError
from .jobs import Job
from .plots import Figures, plot_rows, seconds
from .slew import Array

WHEELS_OUTPUTS = {
    "wheels.png": "the wheel case: bus attitude error, wheel speeds and applied torques against their limits",
}


@dataclass
class WheelCase:
    """The slew run again with the bus held by its wheels."""

    spec: WheelsFile
    arm: FlexibleArm
    traj: Trajectory
    elapsed: float  # s of wall time
    failure: Optional[SimulationError]
    pointing_error: Array  # rad per row: the bus's rotation from its initial attitude
    free_rotation_deg: float  # the free-floating run's largest rotation of the bus (deg)
    free_final_deg: float  # and its rotation at the end (deg)
    dt: float  # s, the RK4 step

    def spin_momentum(self) -> Array:
        """The wheels' spin momentum ``Σ J_s (a·ω_B + Ω) a`` per row (base frame, N·m·s)."""
        w = self.spec.wheels
        axes, js = np.asarray(w.axes), np.asarray(w.spin_inertia)
        omega = self.traj.base_twist[:, :3]
        spin = js * (omega @ axes.T + self.traj.wheel_speed)
        momentum: Array = spin @ axes
        return momentum

    def summary(self) -> Dict[str, Any]:
        w = self.spec.wheels
        speed, torque = np.abs(self.traj.wheel_speed), np.abs(self.traj.wheel_torque)
        speed_frac = speed.max(axis=0) / np.asarray(w.max_speed)
        torque_frac = torque.max(axis=0) / np.asarray(w.max_torque) if len(torque) else np.zeros(len(speed_frac))
        h = self.spin_momentum()
        return {
            "source": self.spec.source, "wheels": len(speed_frac),
            "attitude_pd": {"kp": self.spec.kp.tolist(), "kd": self.spec.kd.tolist()},
            "max_bus_attitude_error_rad": float(self.pointing_error.max()),
            "final_bus_attitude_error_rad": float(self.pointing_error[-1]),
            "free_floating_bus_rotation_deg": self.free_rotation_deg,
            "free_floating_final_bus_rotation_deg": self.free_final_deg,
            "peak_wheel_speed_rad_s": speed.max(axis=0).tolist(),
            "peak_wheel_speed_fraction": speed_frac.tolist(),
            "peak_wheel_torque_nm": (torque.max(axis=0) if len(torque) else np.zeros(len(speed_frac))).tolist(),
            "peak_wheel_torque_fraction": torque_frac.tolist(),
            "final_spin_momentum_nms": h[-1].tolist(),
            "failed": None if self.failure is None else str(self.failure),
        }


def wheels_for(args: Any, demo: bool) -> Optional[WheelsFile]:
    """The wheels of ``--wheels``, or for the demo without it the built-in pyramid; None when a
    ``simulate`` has no ``--wheels``."""
    path = getattr(args, "wheels", None)
    if path is None:
        if not demo:
            return None
        kp, kd = models.PYRAMID_GAINS
        return WheelsFile(models.pyramid_wheels(), np.full(3, kp), np.full(3, kd),
                          "orbitflex.models.pyramid_wheels()")
    try:
        return read_wheels(path)
    except WheelsFileError as e:
        raise CliError("--wheels", str(e)) from None


def run_wheel_case(job: Job, spec: WheelsFile, pd: MotorPD, steps: int, dt: float, free: Trajectory,
                   record_every: int = 1) -> WheelCase:
    """The slew of ``job`` under ``pd`` on the arm with ``spec``'s wheels, the bus held by
    ``AttitudePD`` with its gains at the initial attitude."""
    try:
        arm = FlexibleArm(job.arm.robot, job.arm.joints, wheels=spec.wheels)
        controller = spec.controller()
    except ValueError as e:
        raise CliError("--wheels", str(e)) from None
    start = time.perf_counter()
    failure = None
    try:
        with warnings.catch_warnings():
            # the free-floating run has reported dt against the RK4 limit of the arm's loop
            warnings.simplefilter("ignore", RuntimeWarning)
            traj = arm.simulate(arm.state(), dt, steps, u=pd, wheel_torque=controller, record_every=record_every)
    except SimulationError as e:
        traj, failure = e.trajectory, e
    elapsed = time.perf_counter() - start
    quat = traj.base_pose[:, 3:]
    error = np.asarray(rotation_angle(quat[0], quat))
    free_quat = free.base_pose[:, 3:]
    free_rotation = np.degrees(np.asarray(rotation_angle(free_quat[0], free_quat)))
    return WheelCase(spec, arm, traj, elapsed, failure, error, float(free_rotation.max()), float(free_rotation[-1]), dt)


def print_wheel_case(case: WheelCase) -> None:
    s = case.summary()
    w = case.spec.wheels
    k = s["wheels"]
    print(f"\norbitflex: the same slew with {k} reaction wheels holding the bus ({case.spec.source}), "
          f"AttitudePD kp = {fmt(case.spec.kp)} N·m/rad, kd = {fmt(case.spec.kd)} N·m·s/rad")
    if case.failure is not None:
        print(f"  the run failed: {case.failure}")
    err = s["max_bus_attitude_error_rad"]
    print(f"  bus attitude error  max {err:.3g} rad ({np.degrees(err):.3g} deg), {s['final_bus_attitude_error_rad']:.3g} rad "
          f"at the end; free floating the bus turned {s['free_floating_final_bus_rotation_deg']:.4g} deg "
          f"(up to {s['free_floating_bus_rotation_deg']:.4g} deg)")
    i = int(np.argmax(s["peak_wheel_torque_fraction"]))
    print(f"  wheel torque        peak {s['peak_wheel_torque_nm'][i]:.4g} N·m = "
          f"{s['peak_wheel_torque_fraction'][i]:.0%} of the {np.asarray(w.max_torque)[i]:g} N·m limit (wheel {i})")
    j = int(np.argmax(s["peak_wheel_speed_fraction"]))
    print(f"  wheel speed         peak {s['peak_wheel_speed_rad_s'][j]:.4g} rad/s = "
          f"{s['peak_wheel_speed_fraction'][j]:.0%} of the {np.asarray(w.max_speed)[j]:g} rad/s limit (wheel {j})")
    h = np.asarray(s["final_spin_momentum_nms"])
    peak = float(np.linalg.norm(case.spin_momentum(), axis=1).max())
    print(f"  momentum handed over  the wheels hold |h| = {np.linalg.norm(h):.4g} N·m·s at the end "
          f"(peak {peak:.4g} N·m·s), base frame [{fmt(h)}]")
    steps = int(round(case.traj.t[-1] / case.dt))
    rate = steps / case.elapsed if case.elapsed > 0 else float("inf")
    print(f"  simulated           {case.traj.t[-1]:.6g} s in {steps} RK4 steps, {rate:,.0f} steps/s")


def fmt(values: Array) -> str:
    v = np.asarray(values, dtype=float)
    if np.all(v == v[0]):
        return f"{v[0]:.4g}"
    return ", ".join(f"{x:.4g}" for x in v)


def plot_wheel_case(case: WheelCase, job: Job, dt: float, out: Path) -> List[Path]:
    """``wheels.png``: the bus's attitude error against the free-floating rotation, and each
    wheel's speed and applied torque against its limits (dashed)."""
    traj = case.traj
    caption = (f"model {job.name} + {traj.wheel_speed.shape[1]} reaction wheels, "
               f"dt = {seconds(dt)}, {traj.t[-1]:.6g} s run, bus held by AttitudePD")
    figures = Figures(out, caption)
    rows = plot_rows(len(traj.t))
    t = traj.t[rows]
    fig, (top, middle, bottom) = figures.new("Reaction wheels holding the bus", rows=3, height=9.0, sharex=True)
    top.plot(t, case.pointing_error[rows] * 1e3, color="black", lw=1.4, label="bus, held by the wheels")
    top.set(ylabel="attitude error (mrad)",
            title=f"bus rotation from its initial attitude (free floating it turned up to "
                  f"{case.free_rotation_deg:.3g} deg = {np.radians(case.free_rotation_deg) * 1e3:.3g} mrad)")
    top.legend(fontsize=8, loc="upper right")
    w = case.spec.wheels
    max_speed, max_torque = np.asarray(w.max_speed), np.asarray(w.max_torque)
    colors = [f"C{i}" for i in range(traj.wheel_speed.shape[1])]
    for i, c in enumerate(colors):
        middle.plot(t, traj.wheel_speed[rows, i], color=c, lw=1.2, label=f"wheel {i}")
    limit_lines(middle, max_speed, colors, "±max_speed")
    middle.set(ylabel="wheel speed Ω (rad/s)", title="wheel speeds relative to the bus; dashed: ±max_speed")
    middle.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    u_rows = rows[rows < len(traj.wheel_torque)]
    for i, c in enumerate(colors):
        bottom.plot(traj.t[u_rows], traj.wheel_torque[u_rows, i], color=c, lw=1.0, label=f"wheel {i}")
    limit_lines(bottom, max_torque, colors, "±max_torque")
    bottom.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    bottom.set(xlabel="time (s)", ylabel="applied torque u_w (N·m)",
               title="applied wheel torques (after saturation); dashed: ±max_torque")
    figures.save(fig, "wheels.png")
    return figures.files


def limit_lines(ax: Any, limits: Array, colors: List[str], label: str) -> None:
    """Dashed lines at ±limit: one black pair when every wheel has the same limit, else one pair
    per wheel in its colour (infinite limits are not drawn)."""
    finite = np.isfinite(limits)
    if finite.all() and np.all(limits == limits[0]):
        for sign, name in ((1, label), (-1, None)):
            ax.axhline(sign * limits[0], color="black", ls="--", lw=0.9, label=name)
        return
    for i, c in enumerate(colors):
        if finite[i]:
            for sign in (1, -1):
                ax.axhline(sign * limits[i], color=c, ls="--", lw=0.8)
