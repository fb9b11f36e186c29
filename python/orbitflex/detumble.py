"""What a capture did to the stack: :func:`detumble_metrics` of a run with a target.

Definitions (each measured on the rows the run kept, so with ``record_every > 1`` a peak can be
missed between rows):

- **bus kick**: the jump of the bus's angular rate ``|ω_B|`` across the impulse (deg/s), from the
  event's states just before and just after;
- **peak bus rate**: the largest ``|ω_B|`` (deg/s) from the capture to the end of the run;
- **peak spring torque** and **peak deflection** after the capture: the largest ``|τ_s,i|``
  (N·m) and ``|θ_i − q_i|`` (rad) over every joint from the capture on, and per joint;
- **settle time** (s after the capture): from when the joints' rates stay below ``joint_rate``
  (rad/s) to the end of the run: the vibration the grasp excited has died and the stack moves
  as one rigid body; ``nan`` if not by the end;
- **detumble time** (s after the capture): from when ``|ω_B|`` stays below ``bus_rate`` (deg/s) to
  the end of the run; ``nan`` if not by the end. Internal torques (the arm's motors) cannot change
  the stack's total angular momentum: without an attitude actuator (reaction wheels, thrusters)
  the stack keeps turning with its share of the target's momentum, reported as **final bus
  rate**.
"""

from __future__ import annotations

import math
from typing import Any, Dict

import numpy as np

from ._core import Trajectory

__all__ = ["detumble_metrics"]


def _stays_below(t: np.ndarray, values: np.ndarray, limit: float, start: float) -> float:
    """The time after ``start`` from which ``values`` stays ≤ ``limit`` to the end (nan if the
    last value is above)."""
    after = t > start
    above = np.flatnonzero(after & (values > limit))
    if values[-1] > limit:
        return math.nan
    if above.size == 0:
        return 0.0
    return float(t[above[-1] + 1] - start) if above[-1] + 1 < t.size else math.nan


def detumble_metrics(traj: Trajectory, joint_rate: float = 1e-3, bus_rate: float = 0.05) -> Dict[str, Any]:
    """The detumbling metrics of a run with a capture (module docs for the definitions):
    ``capture_time`` (s), ``energy_loss`` (J), ``impulse_force`` (N·s) and ``impulse_moment``
    (N·m·s) magnitudes, ``bus_kick_deg_s``, ``peak_bus_rate_deg_s``, ``final_bus_rate_deg_s``,
    ``peak_spring_torque`` (N·m), ``peak_spring_torque_per_joint`` (list), ``peak_deflection``
    (rad), ``peak_deflection_per_joint``, ``settle_time`` and ``detumble_time`` (s after the
    capture, nan if not reached), and the thresholds used. A run without a capture: ``captured``
    False and the rest nan (peaks over the whole run)."""
    if not (joint_rate > 0 and bus_rate > 0):
        raise ValueError(f"joint_rate and bus_rate: expected > 0, given {joint_rate}, {bus_rate}")
    t = np.asarray(traj.t)
    w = np.degrees(np.linalg.norm(np.asarray(traj.base_twist)[:, :3], axis=1))
    events = traj.events
    captured = bool(events)
    start = events[0].time if captured else -math.inf
    after = t > start
    torque = np.abs(np.asarray(traj.spring_torque))[after]
    deflection = np.abs(np.asarray(traj.deflection))[after]
    qd = np.abs(np.asarray(traj.qd)).max(axis=1)
    nan = math.nan
    out: Dict[str, Any] = {
        "captured": captured,
        "joint_rate_threshold_rad_s": joint_rate,
        "bus_rate_threshold_deg_s": bus_rate,
        "peak_bus_rate_deg_s": float(w[after].max()) if after.any() else nan,
        "final_bus_rate_deg_s": float(w[-1]),
        "peak_spring_torque": float(torque.max()) if torque.size else nan,
        "peak_spring_torque_per_joint": torque.max(axis=0).tolist() if torque.size else [],
        "peak_deflection": float(deflection.max()) if deflection.size else nan,
        "peak_deflection_per_joint": deflection.max(axis=0).tolist() if deflection.size else [],
    }
    if not captured:
        out.update(capture_time=nan, energy_loss=nan, impulse_force=nan, impulse_moment=nan,
                   bus_kick_deg_s=nan, settle_time=nan, detumble_time=nan)
        return out
    e = events[0]
    n = traj.arm.dof
    omega = slice(7 + 2 * n, 10 + 2 * n)
    kick = np.degrees(np.linalg.norm(e.x_after[omega]) - np.linalg.norm(e.x_before[omega]))
    out.update(
        capture_time=e.time,
        energy_loss=e.energy_loss,
        impulse_force=float(np.linalg.norm(e.impulse[3:])),
        impulse_moment=float(np.linalg.norm(e.impulse[:3])),
        bus_kick_deg_s=float(kick),
        settle_time=_stays_below(t, qd, joint_rate, start),
        detumble_time=_stays_below(t, w, bus_rate, start),
    )
    return out
