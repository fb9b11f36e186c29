# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""Campaigns with the bus held by reaction wheels: the wheel parameters a campaign can disperse,
each run's wheels and ``AttitudePD``, and the wheel metrics of each run.

A campaign with ``wheels`` holds the bus at its initial attitude with ``AttitudePD(attitude_kp,
attitude_kd)`` in every run. The controller allocates the bus torque over the **nominal** axes
(the flight software knows the wheels as designed): a run whose axes are misaligned thus holds
the bus with an allocation that is slightly wrong, as a real one would.

Dispersible (each per wheel, ``k`` values, unless ``per_joint = false``):

- ``wheel_spin_inertia`` (kg·m², ``J_s``; the transverse inertia ``J_t`` scales with it, a rotor
  of the same shape, so that the rotor stays physical: ``J_t ≥ J_s / 2``),
  ``wheel_max_torque`` (N·m), ``wheel_max_speed`` (rad/s), ``wheel_friction`` (N·m·s/rad);
- ``wheel_misalignment`` (rad, nominal 0): each spin axis tipped by this angle about
  ``a × e_z`` (or ``a × e_x`` for an axis along z), normalised: the axis moves away from the
  bus's z axis for a positive angle;
- ``attitude_kp`` (N·m/rad) and ``attitude_kd`` (N·m·s/rad), per base axis (3 values).

Metrics per run, over the rows the campaign keeps (every ``record_every``-th step and the last):
``peak_wheel_speed_fraction`` (``max |Ω| / max_speed`` over wheels and rows),
``peak_wheel_torque_fraction`` (``max |u| / max_torque``, the applied torques) and
``pointing_error`` (rad: the largest rotation of the bus from its initial attitude)."""

from __future__ import annotations

from typing import Any, Dict, Optional, Sequence

import numpy as np
import numpy.typing as npt

from .. import AttitudePD, ReactionWheels, rotation_angle

Array = npt.NDArray[np.float64]


WHEEL_PARAMETERS = ("wheel_spin_inertia", "wheel_max_torque", "wheel_max_speed", "wheel_friction",
                    "wheel_misalignment", "attitude_kp", "attitude_kd")

WHEEL_POSITIVE = {"wheel_spin_inertia": "> 0", "wheel_max_torque": "> 0", "wheel_max_speed": "> 0",
                  "wheel_friction": ">= 0", "attitude_kp": ">= 0", "attitude_kd": ">= 0"}

WHEEL_UNITS = {"wheel_spin_inertia": "kg·m²", "wheel_max_torque": "N·m", "wheel_max_speed": "rad/s",
               "wheel_friction": "N·m·s/rad", "wheel_misalignment": "rad", "attitude_kp": "N·m/rad",
               "attitude_kd": "N·m·s/rad"}

WHEEL_METRICS = {"peak_wheel_speed_fraction": "1", "peak_wheel_torque_fraction": "1", "pointing_error": "rad"}

WHEEL_TITLES = {"peak_wheel_speed_fraction": "peak wheel speed / max_speed",
                "peak_wheel_torque_fraction": "peak wheel torque / max_torque",
                "pointing_error": "bus pointing error (max)"}


def nominal(wheels: Optional[ReactionWheels], kp: Any, kd: Any) -> Dict[str, Array]:
    """The nominal values of the wheel parameters (empty without wheels)."""
    if wheels is None:
        return {}
    k = len(wheels)
    return {"wheel_spin_inertia": np.asarray(wheels.spin_inertia, dtype=np.float64).copy(),
            "wheel_max_torque": np.asarray(wheels.max_torque, dtype=np.float64).copy(),
            "wheel_max_speed": np.asarray(wheels.max_speed, dtype=np.float64).copy(),
            "wheel_friction": np.asarray(wheels.friction, dtype=np.float64).copy(),
            "wheel_misalignment": np.zeros(k),
            "attitude_kp": np.broadcast_to(np.asarray(kp, dtype=np.float64), (3,)).copy(),
            "attitude_kd": np.broadcast_to(np.asarray(kd, dtype=np.float64), (3,)).copy()}


def tipped(axes: Array, angles: Array) -> Array:
    """Each unit axis tipped by its angle (rad) about ``a × e_z`` (``a × e_x`` for an axis along
    z), away from the z axis for a positive angle; unit axes."""
    out = axes.copy()
    for w, (a, angle) in enumerate(zip(axes, angles)):
        if angle == 0.0:
            continue
        normal = np.cross([0.0, 0.0, 1.0], a)
        if np.linalg.norm(normal) < 1e-9:
            normal = np.cross([1.0, 0.0, 0.0], a)
        normal /= np.linalg.norm(normal)
        # Rodrigues about the normal (a ⟂ normal): a cos + (normal × a) sin
        turned = a * np.cos(angle) + np.cross(normal, a) * np.sin(angle)
        out[w] = turned / np.linalg.norm(turned)
    return out


def run_wheels(wheels: ReactionWheels, values: Dict[str, Array]) -> ReactionWheels:
    """The wheels of one run: the nominal ones with the run's drawn parameters."""
    axes = tipped(np.asarray(wheels.axes, dtype=np.float64), values["wheel_misalignment"])
    spin = values["wheel_spin_inertia"]
    transverse = np.asarray(wheels.transverse_inertia) * (spin / np.asarray(wheels.spin_inertia))
    return ReactionWheels(axes, np.asarray(wheels.positions), np.asarray(wheels.mass), spin, transverse,
                          values["wheel_max_torque"], values["wheel_max_speed"], values["wheel_friction"])


def controller(wheels: ReactionWheels, values: Dict[str, Array]) -> AttitudePD:
    """The run's ``AttitudePD``: its gains, holding the initial attitude, allocating over the
    nominal axes (the minimum-norm pseudo-inverse of ``wheels``' axes)."""
    axes = np.asarray(wheels.axes, dtype=np.float64)
    return AttitudePD(values["attitude_kp"], values["attitude_kd"], allocation=np.linalg.pinv(axes.T))


def key(values: Dict[str, Array]) -> tuple:  # type: ignore[type-arg]
    """The wheel parameters that make a run's arm, for the cache of arms."""
    if "wheel_spin_inertia" not in values:
        return ()
    names = ("wheel_spin_inertia", "wheel_max_torque", "wheel_max_speed", "wheel_friction", "wheel_misalignment")
    return tuple(np.concatenate([values[p].ravel() for p in names]).tolist())


def metrics(batch: Any, arms: Sequence[Any]) -> Dict[str, Array]:
    """The wheel metrics of each run of ``batch`` (module docs), NaN for a run that failed."""
    ok = np.asarray(batch.ok)
    speed = np.abs(np.asarray(batch.wheel_speed))                   # (B, rows, k)
    torque = np.abs(np.asarray(batch.wheel_torque))                 # (B, rows - 1, k)
    max_speed = np.stack([np.asarray(a.wheels.max_speed) for a in arms])[:, None, :]
    max_torque = np.stack([np.asarray(a.wheels.max_torque) for a in arms])[:, None, :]
    speed_fraction = np.nanmax(speed / max_speed, axis=(1, 2))
    torque_fraction = np.nanmax(torque / max_torque, axis=(1, 2)) if torque.shape[1] else np.zeros(len(ok))
    pose = np.asarray(batch.base_pose)
    pointing = np.array([np.nanmax(rotation_angle(p[0, 3:7], p[:, 3:7])) for p in pose])
    return {"peak_wheel_speed_fraction": np.where(ok, speed_fraction, np.nan),
            "peak_wheel_torque_fraction": np.where(ok, torque_fraction, np.nan),
            "pointing_error": np.where(ok, pointing, np.nan)}
