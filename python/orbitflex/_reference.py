"""The rest-to-rest quintic profile, from Rust (``orbitflex.quintic_reference`` tabulates a whole
slew; this keeps the profile of the normalised time for the command line's ``quintic``)."""

from __future__ import annotations

from typing import Tuple

import numpy as np
import numpy.typing as npt

from ._core import _quintic_profile

Array = npt.NDArray[np.float64]


def quintic(s: Array) -> Tuple[Array, Array]:
    """Rest-to-rest quintic 10s^3 - 15s^4 + 6s^5 on s in [0, 1] (clamped), and its derivative in
    s, each of the shape of ``s``; evaluated in Rust in factored form."""
    s = np.asarray(s, dtype=np.float64)
    p, dp = _quintic_profile(s.ravel())
    return p.reshape(s.shape), dp.reshape(s.shape)
