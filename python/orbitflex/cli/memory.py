# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""Memory: a run that cannot fit is refused before anything is allocated."""

from __future__ import annotations

import os
from typing import Dict, Optional

from .errors import CliError


def recorded_rows(steps: int, record_every: int) -> int:
    """Rows a run of ``steps`` steps keeps with ``record_every`` (``simulate``'s rule): rows 0,
    k, 2k, ... and the final row."""
    return steps // record_every + 1 + (steps % record_every != 0)


def run_bytes(steps: int, n: int, record_every: int = 1) -> Dict[str, int]:
    """Bytes a run of ``steps`` steps of an ``n``-joint arm allocates, by part, keeping one row
    in ``record_every``."""
    rows = recorded_rows(steps, record_every)
    return {
        "reference tables": 2 * steps * n * 8,  # theta_ref, theta_dot_ref
        "record": rows * (14 + 4 * n) * 8 + (rows - 1) * n * 8,  # t and x per row, u per kept row
        # momentum (6), energy (1), EE pose (7), deflection, spring torque and the energy
        # balance's temporaries (4n), per row
        "diagnostics": rows * (14 + 4 * n) * 8,
    }


def free_memory() -> Optional[int]:
    """Bytes of free physical memory, or None where the system does not say (not Linux)."""
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


def check_memory(steps: int, n: int, flag: str = "--duration/--dt",
                 advice: str = "shorten --duration or lengthen --dt", record_every: int = 1) -> None:
    parts = run_bytes(steps, n, record_every)
    need, free = sum(parts.values()), free_memory()
    if free is not None and need > free:
        sizes = ", ".join(f"{name} {gb(size)}" for name, size in parts.items())
        count = f"{steps:,}" if steps < 1e12 else f"{steps:.3g}"
        raise CliError(flag, f"{count} steps of {n} joints need about {gb(need)} ({sizes}) but "
                             f"{gb(free)} of memory is free; {advice}")


def gb(size: float) -> str:
    """A size in GB, or TB from 1000 GB (three significant digits: an absurd size stays short)."""
    return f"{size / 1e9:.3g} GB" if size < 1e12 else f"{size / 1e12:.3g} TB"
