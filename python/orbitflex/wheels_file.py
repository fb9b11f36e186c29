"""Reaction wheels and their attitude controller from a TOML file (``--wheels wheels.toml``).

The file (see ``examples/wheels.toml``)::

    [defaults]            # applies to every wheel; a [[wheel]] entry may override any key
    mass = 12.0                  # kg
    spin_inertia = 0.25          # J_s, kg·m² about the spin axis
    transverse_inertia = 0.15    # J_t, kg·m² about any axis through the centre normal to it
    max_torque = 60.0            # N·m, motor torque limit
    max_speed = 800.0            # rad/s relative to the bus
    friction = 0.0               # N·m·s/rad, viscous, on the wheel speed

    [[wheel]]                    # one table per wheel, in order
    axis = [0.5774, 0.5774, 0.5774]   # unit spin axis, base frame
    position = [0.32, 0.32, -0.45]    # centre, base frame, m

    [attitude_pd]                # the controller holding the bus (required)
    kp = 2.0e5                   # N·m/rad: one number or one per base axis [x, y, z]
    kd = 2.0e4                   # N·m·s/rad

or, instead of the ``[[wheel]]`` tables, ``pyramid = true`` for the four wheels of
``orbitflex.models.pyramid_wheels()`` with the ``[defaults]`` given (and ``elevation_deg``,
``radius``, ``depth`` in ``[defaults]`` to move them).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Union

import numpy as np

from ._core import AttitudePD, ReactionWheels

WHEEL_KEYS = ("mass", "spin_inertia", "transverse_inertia", "max_torque", "max_speed", "friction")
PYRAMID_KEYS = ("elevation_deg", "radius", "depth")


class WheelsFileError(ValueError):
    """A wheels file that cannot be read: names the file, the key and what is wrong."""


@dataclass
class WheelsFile:
    """What a wheels file declares: the wheels, the controller's gains, and where it came from."""

    wheels: ReactionWheels
    kp: np.ndarray  # (3,) N·m/rad
    kd: np.ndarray  # (3,) N·m·s/rad
    source: str

    def controller(self) -> AttitudePD:
        """The ``AttitudePD`` holding the bus at its initial attitude with the file's gains."""
        return AttitudePD(self.kp, self.kd)


def read_wheels(path: Union[str, "Path"]) -> WheelsFile:
    """Reads a wheels file (see the module docstring); ``WheelsFileError`` names what is wrong."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise WheelsFileError(f"{path}: cannot read the wheels file ({e.strerror})") from None
    try:
        spec = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise WheelsFileError(f"{path}: malformed TOML: {e}") from None
    return wheels_from_dict(spec, str(path))


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise WheelsFileError(f"{where}: expected a number, given {value!r}")
    return float(value)


def _gains(table: Dict[str, Any], key: str, where: str) -> np.ndarray:
    if key not in table:
        raise WheelsFileError(f"{where}: '{key}' is required (N·m/rad for kp, N·m·s/rad for kd)")
    value = table[key]
    if isinstance(value, list):
        if len(value) != 3:
            raise WheelsFileError(f"{where}.{key}: expected one number or three (x, y, z), given {len(value)}")
        return np.array([_number(v, f"{where}.{key}") for v in value])
    return np.full(3, _number(value, f"{where}.{key}"))


def wheels_from_dict(spec: Dict[str, Any], source: str = "wheels") -> WheelsFile:
    """A :class:`WheelsFile` from the tables of a wheels file."""
    known = {"defaults", "wheel", "pyramid", "attitude_pd"}
    unknown = sorted(set(spec) - known)
    if unknown:
        raise WheelsFileError(f"{source}: unknown key(s) {', '.join(unknown)}; expected {', '.join(sorted(known))}")
    defaults = dict(spec.get("defaults", {}))
    pyramid = spec.get("pyramid", False)
    for key in defaults:
        if key not in WHEEL_KEYS and not (pyramid and key in PYRAMID_KEYS):
            allowed = WHEEL_KEYS + (PYRAMID_KEYS if pyramid else ())
            raise WheelsFileError(f"{source}: [defaults].{key}: unknown key; expected one of {', '.join(allowed)}")
    values = {k: _number(v, f"{source}: [defaults].{k}") for k, v in defaults.items()}
    try:
        if pyramid is True:
            if "wheel" in spec:
                raise WheelsFileError(f"{source}: give either pyramid = true or [[wheel]] tables, not both")
            from .models import pyramid_wheels

            wheels = pyramid_wheels(**values)
        elif pyramid is not False:
            raise WheelsFileError(f"{source}: pyramid: expected true or false, given {pyramid!r}")
        else:
            wheels = _listed(spec.get("wheel"), values, source)
    except WheelsFileError:
        raise
    except (ValueError, TypeError) as e:
        raise WheelsFileError(f"{source}: {e}") from None
    if "attitude_pd" not in spec:
        raise WheelsFileError(f"{source}: [attitude_pd] with kp and kd is required (the controller that "
                              f"holds the bus)")
    pd = spec["attitude_pd"]
    extra = sorted(set(pd) - {"kp", "kd"})
    if extra:
        raise WheelsFileError(f"{source}: [attitude_pd].{extra[0]}: unknown key; expected kp, kd")
    kp, kd = _gains(pd, "kp", f"{source}: [attitude_pd]"), _gains(pd, "kd", f"{source}: [attitude_pd]")
    AttitudePD(kp, kd)  # the gains' own checks (finite, ≥ 0)
    return WheelsFile(wheels, kp, kd, source)


def _listed(entries: Any, defaults: Dict[str, float], source: str) -> ReactionWheels:
    if not isinstance(entries, list) or not entries:
        raise WheelsFileError(f"{source}: no wheels: give [[wheel]] tables (axis, position) or pyramid = true")
    axes: List[List[float]] = []
    positions: List[List[float]] = []
    columns: Dict[str, List[float]] = {k: [] for k in WHEEL_KEYS}
    for i, entry in enumerate(entries):
        where = f"{source}: wheel[{i}]"
        for key in ("axis", "position"):
            v = entry.get(key)
            if not isinstance(v, list) or len(v) != 3:
                raise WheelsFileError(f"{where}.{key}: expected three numbers (base frame), given {v!r}")
        axes.append([_number(v, f"{where}.axis") for v in entry["axis"]])
        positions.append([_number(v, f"{where}.position") for v in entry["position"]])
        for key in entry:
            if key not in WHEEL_KEYS and key not in ("axis", "position"):
                raise WheelsFileError(f"{where}.{key}: unknown key; expected axis, position, {', '.join(WHEEL_KEYS)}")
        for key in WHEEL_KEYS:
            if key in entry:
                columns[key].append(_number(entry[key], f"{where}.{key}"))
            elif key in defaults:
                columns[key].append(defaults[key])
            elif key == "friction":
                columns[key].append(0.0)
            else:
                raise WheelsFileError(f"{where}.{key}: missing (give it here or in [defaults])")
    c = {k: np.array(v) for k, v in columns.items()}
    return ReactionWheels(np.array(axes), np.array(positions), c["mass"], c["spin_inertia"],
                          c["transverse_inertia"], c["max_torque"], c["max_speed"], friction=c["friction"])
