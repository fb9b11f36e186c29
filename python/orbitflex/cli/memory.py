# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""Memory: a run that cannot fit is refused before anything is allocated. The sizes and the
check are the library's (:func:`orbitflex.run_bytes`, :func:`orbitflex.check_run_memory`); this
module names the flag to change."""

from __future__ import annotations

import math
import sys
from typing import Callable, Dict, Optional, Union

from .. import _core
from .errors import CliError


def step_count(span: float, dt: float, flag: str, advice: str,
               rounding: Callable[[float], int] = round) -> int:
    """The steps of ``dt`` in ``span`` seconds, ``rounding(span / dt)``; a count past the largest
    float (``--duration 1e300 --dt 1e-10``) is refused on ``flag``."""
    steps = span / dt
    if not math.isfinite(steps):
        raise CliError(flag, f"{span:g} s in steps of {dt:g} s is more than {sys.float_info.max:.3g} "
                             f"steps; {advice}")
    return int(rounding(steps))


def recorded_rows(steps: int, record_every: int) -> int:
    """Rows a run of ``steps`` steps keeps with ``record_every`` (``simulate``'s rule): rows 0,
    k, 2k, ... and the final row (:func:`orbitflex.recorded_rows`)."""
    return int(_core.recorded_rows(steps, record_every))


def run_bytes(steps: int, n: int, record_every: int = 1) -> Dict[str, Union[int, float]]:
    """Bytes a run of ``steps`` steps of an ``n``-joint arm allocates, by part, keeping one row
    in ``record_every`` (:func:`orbitflex.run_bytes`)."""
    return dict(_core.run_bytes(steps, n, record_every))


def free_memory() -> Optional[int]:
    """Bytes of memory available to new allocations, or None where the system does not say
    (:func:`orbitflex.available_memory`)."""
    result: Optional[int] = _core.available_memory()
    return result


def check_memory(steps: int, n: int, flag: str = "--duration/--dt",
                 advice: str = "shorten --duration or lengthen --dt", record_every: int = 1) -> None:
    """A ``CliError`` on ``flag`` when the run does not fit in the memory available: what it
    needs, by part, against what is free, and ``advice``."""
    try:
        _core.check_run_memory(steps, n, record_every)
    except MemoryError as e:
        raise CliError(flag, f"{e}; {advice}") from None


def gb(size: float) -> str:
    """A size in GB, or TB from 1000 GB (three significant digits: an absurd size stays short)."""
    return f"{size / 1e9:.3g} GB" if size < 1e12 else f"{size / 1e12:.3g} TB"
