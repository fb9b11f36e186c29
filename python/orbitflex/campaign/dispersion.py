# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
# (pandas, Dask and their stubs come with orbitflex[campaign]: a base install type-checks clean)
"""The dispersions of a campaign: the parameters that can be dispersed, their units, and
:class:`Dispersion`, one random draw per run."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

import numpy as np
import numpy.typing as npt

from .. import ModelError
from .wheels import WHEEL_PARAMETERS, WHEEL_POSITIVE, WHEEL_UNITS


Array = npt.NDArray[np.float64]


PARAMETERS = ("stiffness", "motor_inertia", "damping", "motor_damping", "kp", "kd", "goal", "q0",
              "base_rate", "payload_mass", *WHEEL_PARAMETERS)


JOINT_PARAMETERS = ("stiffness", "motor_inertia", "damping", "motor_damping")


POSITIVE = {"stiffness": "> 0", "motor_inertia": "> 0", "damping": ">= 0", "motor_damping": ">= 0",
            "kp": ">= 0", "kd": ">= 0", "payload_mass": ">= 0", **WHEEL_POSITIVE}


UNITS = {"stiffness": "N·m/rad", "motor_inertia": "kg·m²", "damping": "N·m·s/rad",
         "motor_damping": "N·m·s/rad", "kp": "N·m/rad", "kd": "N·m·s/rad", "goal": "rad",
         "q0": "rad", "base_rate": "rad/s", "payload_mass": "kg", **WHEEL_UNITS}


DISTRIBUTIONS = ("normal", "lognormal", "uniform")


TITLES = {"peak_deflection": "peak deflection |θ − q|", "peak_torque": "peak motor torque |u|",
          "final_error": "final error |q − goal|", "settling_time": "settling time",
          "base_attitude_change": "bus rotation, start to end", "ee_error": "EE distance from the nominal end"}


METRICS = {"peak_deflection": "rad", "peak_torque": "N·m", "final_error": "rad",
           "settling_time": "s", "base_attitude_change": "rad", "ee_error": "m"}


class CampaignError(ModelError):
    """A campaign that cannot run as declared: the message names the field (``dispersion[1].std``),
    what was expected and what was given."""


def _vector(value: Any, what: str) -> Optional[Array]:
    if value is None:
        return None
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise CampaignError(f"{what}: expected a number or a list of numbers, given {value!r}") from None
    if a.ndim > 1 or not np.isfinite(a).all():
        raise CampaignError(f"{what}: expected finite numbers (a scalar or a list), given {value!r}")
    return a


@dataclass(frozen=True)
class Dispersion:
    """One dispersed parameter: ``parameter`` (see the module docs), ``distribution``
    (``"normal"``, ``"lognormal"`` or ``"uniform"``) and its width: ``std`` (normal, absolute),
    ``relative`` (normal or uniform, a fraction of the nominal), ``sigma`` (lognormal),
    ``low``/``high`` (uniform: the drawn values themselves, not offsets from the nominal).
    ``per_joint=False`` draws one number for every element."""

    parameter: str
    distribution: str = "normal"
    std: Any = None
    relative: Optional[float] = None
    sigma: Optional[float] = None
    low: Any = None
    high: Any = None
    per_joint: bool = True

    def check(self, where: str) -> None:
        """Checks the declaration; ``where`` names it in errors (``dispersion[2]``)."""
        if not isinstance(self.per_joint, bool):
            raise CampaignError(f"{where}.per_joint: expected true or false, given {self.per_joint!r}")
        if self.parameter not in PARAMETERS:
            raise CampaignError(f"{where}.parameter: expected one of {', '.join(PARAMETERS)}, "
                                f"given {self.parameter!r}")
        if self.distribution not in DISTRIBUTIONS:
            raise CampaignError(f"{where}.distribution: expected one of {', '.join(DISTRIBUTIONS)}, "
                                f"given {self.distribution!r}")
        given = {k for k in ("std", "relative", "sigma", "low", "high") if getattr(self, k) is not None}
        allowed = {"normal": [{"std"}, {"relative"}], "lognormal": [{"sigma"}],
                   "uniform": [{"low", "high"}, {"relative"}]}[self.distribution]
        if given not in allowed:
            options = " or ".join("/".join(sorted(a)) for a in allowed)
            raise CampaignError(f"{where}: a {self.distribution} dispersion takes {options}, given "
                                f"{', '.join(sorted(given)) or 'none'}")
        for name in given:
            values = _vector(getattr(self, name), f"{where}.{name}")
            assert values is not None
            if name in ("relative", "sigma") and values.ndim != 0:
                raise CampaignError(f"{where}.{name}: expected one number (for every element), given "
                                    f"{getattr(self, name)!r}; std, low and high may be per element")
            if name in ("std", "relative", "sigma") and (values < 0).any():
                raise CampaignError(f"{where}.{name}: expected >= 0, given {getattr(self, name)!r}")
        if self.low is not None and (np.asarray(self.low) > np.asarray(self.high)).any():
            raise CampaignError(f"{where}: expected low <= high, given low={self.low!r}, high={self.high!r}")

    def sample(self, rng: np.random.Generator, nominal: Array) -> Array:
        """Draws this parameter for one run around ``nominal`` (its nominal value, of the
        parameter's shape)."""
        size = nominal.shape if self.per_joint else ()
        if self.distribution == "normal":
            z = rng.standard_normal(size)
            if self.relative is not None:
                return nominal * (1.0 + float(self.relative) * z)
            return nominal + np.asarray(self.std, dtype=np.float64) * z
        if self.distribution == "lognormal":
            return nominal * np.exp(float(self.sigma) * rng.standard_normal(size))  # type: ignore[arg-type]
        s = rng.random(size)
        if self.relative is not None:
            r = float(self.relative)
            return nominal * (1.0 + r * (2.0 * s - 1.0))
        low, high = np.asarray(self.low, dtype=np.float64), np.asarray(self.high, dtype=np.float64)
        return np.broadcast_to(low + (high - low) * s, nominal.shape).copy()
