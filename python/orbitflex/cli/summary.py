# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""The summary of a run: what it printed and ``summary.json``, from the trajectory."""

from __future__ import annotations

from typing import Any, Dict, Optional, TYPE_CHECKING, Tuple

import numpy as np

from .. import rotation_angle, Plan, Trajectory
from .jobs import failure_reason

if TYPE_CHECKING:
    from .jobs import Outcome
    from .slew import Array


def rotation_angle_deg(q0: Array, q1: Array) -> Array:
    """Angle (deg) of the rotation between unit quaternions (x, y, z, w): ``q0`` (4,) and ``q1``
    (4,) or (k, 4) (:func:`orbitflex.rotation_angle`)."""
    angle: Array = np.degrees(rotation_angle(q0, q1))
    return angle


def energy_steps(traj: Trajectory) -> Tuple[Array, Array, Array]:
    """Per step of the record, the power balance's terms (docs/model.md, section 6) by the
    trapezoid rule (``traj.u`` held over each step): ``(ΔE, motor work, dissipated energy)``,
    (rows − 1,) each (:meth:`Trajectory.energy_steps`). With no external wrench, ``ΔE = motor
    work − dissipated`` up to the quadrature and RK4 errors."""
    steps = traj.energy_steps()
    return steps[:, 0], steps[:, 1], steps[:, 2]


def energy_balance(traj: Trajectory) -> Tuple[float, float, float]:
    """``(E(T) - E(0), motor work, dissipated energy)`` over the record
    (:meth:`Trajectory.energy_balance`)."""
    change, work, dissipated = traj.energy_balance()
    return change, work, dissipated


# A run whose energy balance misses by more than this share of the energy that flowed has left
# the physics: the integrator, not the motors, is making the energy.
DIVERGED_BALANCE = 0.01


def divergence_onset(traj: Trajectory) -> int:
    """The last row of a diverged run (kept with every step's torque) before the divergence set
    in: the last row up to which the energy balance ``E(t) − E(0) = motor work − dissipated``
    still held to ``DIVERGED_BALANCE`` of the energy that flowed (``Σ|ΔE|``). An unstable step
    makes energy the physics does not: the residual grows with the energy itself from then on,
    by a factor per step, while a stable run's residual is the quadrature's (1e-7 of the flow in
    the demo; a few % over the first steps at a coarse dt)."""
    with np.errstate(all="ignore"):
        change, work, dissipated = energy_steps(traj)
        residual = np.abs(np.r_[0.0, np.cumsum(change - (work - dissipated))])
        flow = np.r_[0.0, np.cumsum(np.abs(change))]
        held = np.flatnonzero(residual <= DIVERGED_BALANCE * flow)
    return int(held[-1])  # row 0 always holds (0 ≤ 0)


def angle_unit(largest_rad: float) -> Tuple[float, str]:
    """``(factor, unit)`` that shows angles up to ``largest_rad`` with readable numbers:
    deg from 1°, else mrad, µrad or nrad."""
    if largest_rad >= np.radians(1.0):
        return float(np.degrees(1.0)), "deg"
    for factor, unit in ((1e3, "mrad"), (1e6, "µrad")):
        if largest_rad * factor >= 1.0:
            return factor, unit
    return 1e9, "nrad"


def summarise(name: str, outcome: Outcome, steps_asked: int) -> Dict[str, Any]:
    """The summary; with ``record_every`` > 1 the peaks and drifts are over the kept rows, and the
    energy balance (which needs the torque of every step) is left out (None). A diverged run is
    summarised up to the onset of its divergence (:func:`divergence_onset`), where known."""
    traj = outcome.meaningful()
    steps = outcome.steps_done(steps_asked)
    h = traj.momentum
    h_drift = np.abs(h - h[0]).max(axis=0)
    de = float(traj.energy[-1] - traj.energy[0])
    balance: Dict[str, Optional[float]] = dict.fromkeys(
        ("motor_work_J", "dissipated_J", "energy_balance_residual_J", "energy_flow_J"))
    if outcome.record_every == 1:
        de, work, dissipated = energy_balance(traj)
        balance = {"motor_work_J": work, "dissipated_J": dissipated,
                   "energy_balance_residual_J": de - (work - dissipated),
                   "energy_flow_J": float(np.sum(np.abs(np.diff(traj.energy))))}
    deflection = np.abs(traj.deflection).max(axis=0)
    summary: Dict[str, Any] = {
        "model": name,
        "completed": outcome.failure is None,
        "warnings": outcome.warnings,
        "steps_requested": steps_asked,
        "steps": steps,
        "record_every": outcome.record_every,
        "rows": len(outcome.traj.t),
        "simulated_s": float(outcome.traj.t[-1]),
        "steps_per_second": steps / outcome.elapsed if outcome.elapsed > 0 else float("inf"),
        "base_attitude_change_deg": float(rotation_angle_deg(traj.base_pose[0, 3:], traj.base_pose[-1, 3:])),
        "base_displacement_m": float(np.linalg.norm(traj.base_pose[-1, :3] - traj.base_pose[0, :3])),
        "max_deflection_deg": float(np.degrees(deflection.max())),
        "max_deflection_joint": traj.arm.robot.joint_names[int(deflection.argmax())],
        "momentum_drift_angular": float(h_drift[:3].max()),
        "momentum_drift_linear": float(h_drift[3:].max()),
        "energy_change_J": de,
        **balance,
        "ee_travel_m": ee_travel(traj),
    }
    if outcome.failure is not None:
        summary.update(failure_step=outcome.failure.step, failure_time_s=outcome.failure.time,
                       failure=failure_reason(outcome.failure), divergence_onset_step=outcome.onset,
                       divergence_onset_time_s=None if outcome.onset is None else float(traj.t[-1]))
    return summary


def print_summary(s: Dict[str, Any], dof: int) -> None:
    status = "" if s["completed"] else " FAILED"
    print(f"\norbitflex: free-floating slew of '{s['model']}' ({dof} flexible joints){status}")
    if not s["completed"]:
        print(f"  FAILED at           {s['failure']}")
        onset = s["divergence_onset_step"]
        if onset is not None:
            print(f"  divergence          set in after step {onset} (t = {s['divergence_onset_time_s']:.6g} s): from there "
                  f"the energy balance stops holding to {DIVERGED_BALANCE:.0%} of the energy that flowed, the")
            print(f"                      integrator making the energy; the numbers below describe t = 0 to "
                  f"{s['divergence_onset_time_s']:.6g} s (the files keep every finite step)")
        else:
            print(f"                      the numbers below describe the finite part before the failure "
                  f"(t = 0 to {s['simulated_s']:.6g} s, {s['steps']} of {s['steps_requested']} steps)")
    print(f"  simulated           {s['simulated_s']:.6g} s in {s['steps']} RK4 steps, "
          f"{s['steps_per_second']:,.0f} steps/s")
    pd = s.get("controller")
    if pd is not None:
        rule = ("as given by --kp/--kd" if pd["bandwidth_hz"] is None else
                f"bandwidth {pd['bandwidth_hz']:g} Hz, damping ratio {pd['damping_ratio']:g}"
                + (f"; {' and '.join(pd['given'])} as given" if pd["given"] else ""))
        print(f"  motor PD            kp = {gain_text(np.asarray(pd['kp']))} N·m/rad, "
              f"kd = {gain_text(np.asarray(pd['kd']))} N·m·s/rad ({rule})")
        print(f"                      RK4 stability limit of the closed loop {pd['rk4_stability_limit_s']:.3g} s")
    if s["record_every"] > 1:
        print(f"  recorded            {s['rows']} rows: one step in {s['record_every']} and the last "
              f"(--record-every); peaks and drifts below are over these rows")
    print(f"  base attitude       rotated by {s['base_attitude_change_deg']:.3f} deg "
          f"(origin moved {s['base_displacement_m'] * 1e3:.3g} mm)")
    largest = np.radians(s["max_deflection_deg"])
    factor, unit = angle_unit(largest)
    in_deg = "" if unit == "deg" else f" ({s['max_deflection_deg']:.3g} deg)"
    print(f"  joint deflection    max {largest * factor:.3g} {unit}{in_deg} at {s['max_deflection_joint']}")
    travel = s["ee_travel_m"]
    if isinstance(travel, dict):
        print("  EE travel           " + ", ".join(f"{link} {v:.3g} m" for link, v in travel.items()))
    else:
        print(f"  EE travel           {travel:.3g} m")
    if not s["completed"]:
        cause = "growth of the diverging run"
    elif s["warnings"]:
        cause = "dt is past the RK4 stability limit (see the warning): not to be trusted"
    else:
        cause = "RK4 truncation and round-off"
    print(f"  momentum drift      {s['momentum_drift_angular']:.2e} N·m·s (angular), "
          f"{s['momentum_drift_linear']:.2e} N·s (linear): {cause}")
    if s["motor_work_J"] is None:
        print(f"  energy balance      E(T) − E(0) = {s['energy_change_J']:+.6g} J; motor work and damping "
              f"loss not computed: they need every step's torque (--record-every 1)")
        return
    print(f"  energy balance      E(T) − E(0) = {s['energy_change_J']:+.6g} J = motor work "
          f"{s['motor_work_J']:+.6g} J − damping loss {s['dissipated_J']:.6g} J + residual")
    residual, flow = s["energy_balance_residual_J"], s["energy_flow_J"]
    share = f"{abs(residual) / flow:.1e} of the {flow:.4g} J that flowed (Σ|ΔE| over the steps)" if flow > 0 else "no energy flowed"
    print(f"                      residual {residual:.2e} J (work and loss by the trapezoid rule over "
          f"the steps): {share}")


def ee_paths(traj: Trajectory) -> Array:
    """EE positions, (rows, k, 3) for k end-effectors (k = 1 on a chain)."""
    poses = np.asarray(traj.ee_pose)
    return (poses[:, None, :3] if poses.ndim == 2 else poses[:, :, :3])


def ee_travel(traj: Trajectory) -> Any:
    """Start-to-end EE displacement (m): a number for one end-effector, a dict by link name for
    several."""
    paths = ee_paths(traj)
    travel = [float(np.linalg.norm(paths[-1, e] - paths[0, e])) for e in range(paths.shape[1])]
    links = traj.arm.robot.ee_links
    return travel[0] if len(links) == 1 else dict(zip(links, travel))


def torque_share(plan: Plan, run: Dict[str, Any]) -> Tuple[float, int]:
    """The largest commanded ``peak |u_i| / limit_i`` of a run, and its joint."""
    share = run["peak_motor_torque"] / np.asarray(plan.limits.motor_torque)
    return float(share.max()), int(share.argmax())


def gain_range(values: Array) -> str:
    """``= v`` if every joint has it, else ``min … max``."""
    if np.all(values == values[0]):
        return f"= {values[0]:.4g}"
    return f"{values.min():.3g} … {values.max():.3g} per joint"


def gain_text(values: Array) -> str:
    """One number if every joint has it, else the list."""
    if np.all(values == values[0]):
        return f"{values[0]:.4g}"
    return "[" + ", ".join(f"{v:.4g}" for v in values) + "]"
