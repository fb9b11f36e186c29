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
- **detumble time** (s after the capture): from when both the bus's rate ``|ω_B|`` and the
  captured target's ``|ω_t|`` stay below ``bus_rate`` (deg/s) to the end of the run: the whole
  stack has stopped turning, not only the bus (an attitude loop that is fast against the arm can
  hold the bus while the arm and its catch swing); ``nan`` if not by the end. Internal torques
  (the arm's motors) cannot change the stack's total angular momentum: without an attitude
  actuator (reaction wheels, thrusters) the stack keeps turning with its share of the target's
  momentum, reported as **final bus rate**;
- with **reaction wheels** (an arm built with ``wheels=``): the momentum they took, ``|h|`` of
  ``h = Σ J_s (a·ω_B + Ω) a`` (N·m·s, base frame) at the end and at its peak, and how close they
  came to their limits: the peak ``|Ω|/max_speed`` and ``|u|/max_torque`` (overall and per wheel;
  ``u`` the torque applied after the run's saturation) and ``wheels_saturated``, true when a
  wheel's applied torque reached its ``max_torque`` or its speed its ``max_speed``: then the
  wheels did not deliver what the attitude controller asked for.

The rigid stack, for predicting a detumble (:func:`stack_inertia`, :func:`stack_rate`,
:func:`detumble_gains`, :func:`rigid_stack_rates`): once the arm's vibration has died, bus, arm
and target turn as one rigid body of rotational inertia ``I`` about their centre of mass (the
wheels locked to the bus but for their free spin). With ``AttitudePD`` gains equal on the three
axes, ``e`` the bus's attitude error and small rates, ``I ë = −kp e − kd ė``: in the principal
axes of ``I`` three independent second-order loops, ``ω_n,i = √(kp/I_i)`` and
``ζ_i = kd / (2 √(kp I_i))``. The major axis is the slowest; an under-damped loop's rate decays
as ``exp(−ζ ω_n t)``, so reaching ``ε`` from ``ω_0`` takes about ``ln(ω_0/ε)/(ζ ω_n)``.
"""

from __future__ import annotations

import math
from typing import Any, Dict, Tuple

import numpy as np

from ._core import FlexibleArm, Trajectory

__all__ = ["detumble_metrics", "stack_inertia", "stack_rate", "detumble_gains", "rigid_stack_rates",
           "wheel_momentum"]


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


def _skew_vector(m: np.ndarray) -> np.ndarray:
    return np.array([m[2, 1], m[0, 2], m[1, 0]])


def stack_inertia(arm: FlexibleArm, x: Any) -> Tuple[float, np.ndarray, np.ndarray]:
    """The rigid stack of ``arm`` at state ``x``: its joints locked at ``q`` and its reaction
    wheels locked to the bus but for their free spin (the spin inertia ``J_s a aᵀ`` excluded: a
    wheel's axial rate is what its motor drives). Returns the total mass (kg), the centre of mass
    (m, base frame, from the base origin) and the rotational inertia about it (kg·m², base axes).

    Read from ``arm.momentum`` of six probe states (the base at the origin, at rest but for one
    unit component of its twist, each wheel turning at ``−a·ω_B``): its columns are the stack's
    6×6 spatial inertia ``[[I_O, m[c]×], [m[c]×ᵀ, m 1]]``, and the inertia about the centre of
    mass is the Schur complement ``I_O − m [c]× [c]×ᵀ``. Pass a captured run's ``arm_after``
    (the target is then part of the stack)."""
    x = np.asarray(x, dtype=np.float64)
    sl = arm.state_slices
    axes = np.asarray(arm.wheels.axes) if arm.wheels is not None else np.zeros((0, 3))
    a = np.empty((6, 6))
    for j in range(6):
        twist = np.zeros(6)
        twist[j] = 1.0
        probe = arm.state(q=x[sl["q"]], theta=x[sl["q"]], base_twist=twist,
                          wheel_speed=-(axes @ twist[:3]) if len(axes) else None)
        a[:, j] = arm.momentum(probe)
    mass = float(np.trace(a[3:, 3:]) / 3.0)
    com = _skew_vector(a[:3, 3:]) / mass
    inertia = a[:3, :3] - a[:3, 3:] @ a[3:, :3] / mass
    return mass, com, 0.5 * (inertia + inertia.T)


def wheel_momentum(arm: FlexibleArm, x: Any) -> np.ndarray:
    """The reaction wheels' spin momentum ``h = Σ J_s (a·ω_B + Ω) a`` (N·m·s, base frame) at
    state(s) ``x`` ((3,) for one state, (rows, 3) for rows); zeros for an arm without wheels."""
    x = np.asarray(x, dtype=np.float64)
    if arm.wheels is None:
        return np.zeros(x.shape[:-1] + (3,))
    sl = arm.state_slices
    axes, js = np.asarray(arm.wheels.axes), np.asarray(arm.wheels.spin_inertia)
    omega = x[..., sl["base_twist"]][..., :3]
    spin = js * (omega @ axes.T + x[..., sl["wheel_speed"]])
    h: np.ndarray = spin @ axes
    return h


def stack_rate(arm: FlexibleArm, x: Any) -> np.ndarray:
    """The rate (rad/s, base axes) at which the rigid stack (:func:`stack_inertia`) would turn
    with the angular momentum ``arm`` has at ``x``: ``I⁻¹ (R_Bᵀ (L_O − r_c × p) − h)``, its
    momentum about its centre of mass ``r_c`` less the wheels' spin ``h``. It is what the bus
    turns at once the arm's vibration has died (momentum is conserved: the arm's motors cannot
    change it; only the wheels, by taking ``h``)."""
    from ._core import rotation_matrix

    x = np.asarray(x, dtype=np.float64)
    _, com, inertia = stack_inertia(arm, x)
    pose = x[arm.state_slices["base_pose"]]
    rot = rotation_matrix(pose[3:])
    momentum = arm.momentum(x)
    centre = pose[:3] + rot @ com
    about_com = rot.T @ (momentum[:3] - np.cross(centre, momentum[3:]))
    rate: np.ndarray = np.linalg.solve(inertia, about_com - wheel_momentum(arm, x))
    return rate


def detumble_gains(inertia: Any, bandwidth: float, damping_ratio: float = 0.7) -> Tuple[float, float]:
    """``AttitudePD`` gains ``(kp, kd)``, the same on every axis, that give the rigid stack of
    rotational inertia ``inertia`` (3×3, kg·m²) the natural frequency ``bandwidth`` (rad/s) and
    damping ratio ``damping_ratio`` about its major principal axis (``I_max``):
    ``kp = ω² I_max``, ``kd = 2 ζ ω I_max``. The other axes are faster and better damped.

    Keep ``bandwidth`` well below the arm's lowest mode with its catch (its motor loop loaded by
    the target): there the stack turns as one rigid body and :func:`rigid_stack_rates` predicts
    it; a faster loop holds the bus while the arm and the target swing on."""
    i = np.linalg.eigvalsh(np.asarray(inertia, dtype=np.float64))
    if not (i[0] > 0 and np.all(np.isfinite(i))):
        raise ValueError(f"inertia: expected a symmetric positive definite (3, 3) matrix, given eigenvalues {i}")
    if not (bandwidth > 0 and damping_ratio > 0):
        raise ValueError(f"bandwidth and damping_ratio: expected > 0, given {bandwidth}, {damping_ratio}")
    big = float(i[-1])
    return bandwidth ** 2 * big, 2.0 * damping_ratio * bandwidth * big


def rigid_stack_rates(inertia: Any, kp: float, kd: float, error: Any, rate: Any, t: Any) -> np.ndarray:
    """The rates (rad/s, base axes; (len(t), 3)) of the linearised rigid stack under
    ``AttitudePD(kp, kd)`` (scalar gains), from attitude error ``error`` (rad, ``2 vec(q_e)``) and
    rate ``rate`` (rad/s) at ``t = 0``, at times ``t`` (s): ``I ë = −kp e − kd ė`` solved in the
    principal axes of ``I``, each axis the closed form of a damped oscillator with
    ``ω_n,i = √(kp/I_i)``, ``ζ_i = kd/(2√(kp I_i))`` (module docs)."""
    moments, axes = np.linalg.eigh(np.asarray(inertia, dtype=np.float64))
    t = np.asarray(t, dtype=np.float64)
    e0 = axes.T @ np.asarray(error, dtype=np.float64)
    w0 = axes.T @ np.asarray(rate, dtype=np.float64)
    out = np.empty((t.size, 3))
    for i, moment in enumerate(moments):
        # roots of I s² + kd s + kp; e(t) = c1 e^{s1 t} + c2 e^{s2 t}, ė the rate
        disc = complex(kd * kd - 4.0 * kp * moment)
        s1 = (-kd + disc ** 0.5) / (2.0 * moment)
        s2 = (-kd - disc ** 0.5) / (2.0 * moment)
        # critically damped (to 1e-6: the two-root form would lose digits to cancellation, the
        # repeated-root form is off by O((δ t)²), δ = |s1 − s2|/2): e = (c1 + c2 t) e^{s t}
        if abs(s1 - s2) <= 1e-6 * abs(s1):
            s = s1.real
            c1, c2 = e0[i], w0[i] - s * e0[i]
            out[:, i] = np.exp(s * t) * (c2 + s * (c1 + c2 * t))
        else:
            c2 = (w0[i] - s1 * e0[i]) / (s2 - s1)
            c1 = e0[i] - c2
            out[:, i] = (c1 * s1 * np.exp(s1 * t) + c2 * s2 * np.exp(s2 * t)).real
    rates: np.ndarray = out @ axes.T
    return rates


def _wheel_metrics(traj: Trajectory) -> Dict[str, Any]:
    """The wheels' share of :func:`detumble_metrics` (module docs); NaN and no wheels without."""
    arm = traj.arm
    if arm.wheels is None:
        return {"wheels": 0, "wheel_momentum_nms": math.nan, "peak_wheel_momentum_nms": math.nan,
                "peak_wheel_speed_fraction": math.nan, "peak_wheel_torque_fraction": math.nan,
                "peak_wheel_speed_fraction_per_wheel": [], "peak_wheel_torque_fraction_per_wheel": [],
                "wheels_saturated": False}
    w = arm.wheels
    h = np.linalg.norm(wheel_momentum(arm, np.asarray(traj.x)), axis=1)
    speed = np.abs(np.asarray(traj.wheel_speed)).max(axis=0) / np.asarray(w.max_speed)
    torque_rows = np.abs(np.asarray(traj.wheel_torque))
    torque = torque_rows.max(axis=0) / np.asarray(w.max_torque) if len(torque_rows) else np.zeros(speed.size)
    return {
        "wheels": int(speed.size),
        "wheel_momentum_nms": float(h[-1]),
        "peak_wheel_momentum_nms": float(h.max()),
        "peak_wheel_speed_fraction": float(speed.max()),
        "peak_wheel_torque_fraction": float(torque.max()),
        "peak_wheel_speed_fraction_per_wheel": speed.tolist(),
        "peak_wheel_torque_fraction_per_wheel": torque.tolist(),
        "wheels_saturated": bool(speed.max() >= 1.0 or torque.max() >= 1.0),
    }


def detumble_metrics(traj: Trajectory, joint_rate: float = 1e-3, bus_rate: float = 0.05) -> Dict[str, Any]:
    """The detumbling metrics of a run with a capture (module docs for the definitions):
    ``capture_time`` (s), ``energy_loss`` (J), ``impulse_force`` (N·s) and ``impulse_moment``
    (N·m·s) magnitudes, ``bus_kick_deg_s``, ``peak_bus_rate_deg_s``, ``final_bus_rate_deg_s``,
    ``peak_spring_torque`` (N·m), ``peak_spring_torque_per_joint`` (list), ``peak_deflection``
    (rad), ``peak_deflection_per_joint``, ``settle_time`` and ``detumble_time`` (s after the
    capture, nan if not reached), the thresholds used, and the wheels' ``wheels`` (count),
    ``wheel_momentum_nms``, ``peak_wheel_momentum_nms``, ``peak_wheel_speed_fraction``,
    ``peak_wheel_torque_fraction`` (and ``..._per_wheel`` lists) and ``wheels_saturated`` (nan, []
    and False without wheels). A run without a capture: ``captured`` False and the capture's
    values nan (peaks over the whole run)."""
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
    out.update(_wheel_metrics(traj))
    if not captured:
        out.update(capture_time=nan, energy_loss=nan, impulse_force=nan, impulse_moment=nan,
                   bus_kick_deg_s=nan, settle_time=nan, detumble_time=nan)
        return out
    e = events[0]
    n = traj.arm.dof
    omega = slice(7 + 2 * n, 10 + 2 * n)
    wt = np.degrees(np.linalg.norm(np.asarray(traj.target)[:, 7:10], axis=1))
    kick = np.degrees(np.linalg.norm(e.x_after[omega]) - np.linalg.norm(e.x_before[omega]))
    out.update(
        capture_time=e.time,
        energy_loss=e.energy_loss,
        impulse_force=float(np.linalg.norm(e.impulse[3:])),
        impulse_moment=float(np.linalg.norm(e.impulse[:3])),
        bus_kick_deg_s=float(kick),
        settle_time=_stays_below(t, qd, joint_rate, start),
        detumble_time=_stays_below(t, np.maximum(w, wt), bus_rate, start),
    )
    return out
