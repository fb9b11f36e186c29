"""The reference slews shared by the command line and campaigns: the rest-to-rest quintic."""

from __future__ import annotations

from typing import Tuple

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]


def quintic(s: Array) -> Tuple[Array, Array]:
    """Rest-to-rest quintic 10s^3 - 15s^4 + 6s^5 on s in [0, 1], and its derivative in s."""
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4
