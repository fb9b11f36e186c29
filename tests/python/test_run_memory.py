"""The memory a run needs (``orbitflex.run_bytes``, ``check_run_memory``, ``recorded_rows``),
counted in Rust: the closed forms, step counts past any integer type, and the CLI's refusal of a
run that cannot fit, with every size written as it always was."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

import orbitflex
from orbitflex import ModelError


def closed_form(steps, n, k=1):
    """The bytes by part, in Python's exact integers: rows = steps // k + 1 (+ 1 when k does not
    divide steps); tables 2·steps·n; record rows·(14 + 4n) + (rows − 1)·n; diagnostics
    rows·(14 + 4n); 8 bytes a number."""
    rows = steps // k + 1 + (steps % k != 0)
    return {"reference tables": 2 * steps * n * 8,
            "record": rows * (14 + 4 * n) * 8 + (rows - 1) * n * 8,
            "diagnostics": rows * (14 + 4 * n) * 8}


def size(b):
    # integer true division, rounded once: the CLI's old ``b / 1e12`` overflowed past 1.8e308 bytes
    return f"{b / 10**9:.3g} GB" if b < 10**12 else f"{b / 10**12:.3g} TB"


def message(steps, n, k, free):
    """The CLI's message as its Python code wrote it before the sizes moved to Rust (which raised
    OverflowError past 1.8e308 bytes)."""
    parts = closed_form(steps, n, k)
    need = sum(parts.values())
    count = f"{steps:,}" if steps < 1e12 else f"{steps:.3g}"
    sizes = ", ".join(f"{name} {size(b)}" for name, b in parts.items())
    return f"{count} steps of {n} joints need about {size(need)} ({sizes}) but {size(free)} of memory is free"


EXACT = [(0, 1, 1), (1, 7, 1), (1000, 7, 10), (1001, 7, 10), (5, 1, 9), (12, 6, 4),
         (2 * 10**10, 7, 1), (10**12, 7, 1), (123_456_789_012_345, 13, 7), (2**100 + 3, 7, 1000)]


@pytest.mark.parametrize("steps, n, k", EXACT)
def test_the_parts_are_the_closed_forms_exactly(steps, n, k):
    parts = orbitflex.run_bytes(steps, n, k)
    assert parts == closed_form(steps, n, k) and all(type(v) is int for v in parts.values())
    assert orbitflex.recorded_rows(steps, k) == steps // k + 1 + (steps % k != 0)


@pytest.mark.parametrize("steps, n, k", EXACT + [(int(1e300 / 1e-3), 7, 1), (int(1e300 / 1e-7), 7, 3),
                                                  (2**128, 7, 1), (10**50 + 7, 40, 3)])
def test_the_message_is_the_one_the_cli_always_wrote(steps, n, k):
    free = 16 * 10**9
    need = sum(closed_form(steps, n, k).values())
    if need <= free:
        orbitflex.check_run_memory(steps, n, k, available=free)
        return
    with pytest.raises(MemoryError) as e:
        orbitflex.check_run_memory(steps, n, k, available=free)
    assert str(e.value) == message(steps, n, k, free)


def test_past_the_largest_float_the_sizes_are_infinite_and_refused():
    steps = 10**400
    assert orbitflex.run_bytes(steps, 7)["record"] == float("inf")
    with pytest.raises(MemoryError, match=r"^inf steps of 7 joints need about inf TB"):
        orbitflex.check_run_memory(steps, 7, available=2**63)


def test_a_run_that_fits_passes_and_bad_counts_name_themselves():
    need = sum(closed_form(1000, 7).values())
    orbitflex.check_run_memory(1000, 7, available=need)
    with pytest.raises(MemoryError):
        orbitflex.check_run_memory(1000, 7, available=need - 1)
    free = orbitflex.available_memory()
    assert free is None or free > 0
    for call, words in [(lambda: orbitflex.run_bytes(-1, 7), "steps: expected an integer >= 0"),
                        (lambda: orbitflex.run_bytes(10, 7, 0), "record_every: expected an integer >= 1"),
                        (lambda: orbitflex.run_bytes(10.0, 7), "steps: expected an integer >= 0, given float"),
                        (lambda: orbitflex.recorded_rows(10, True), "record_every: expected an integer >= 1")]:
        with pytest.raises(ModelError, match=words):
            call()


@pytest.mark.parametrize("dt", ["1e-7", "1e-10"])
def test_the_cli_refuses_an_absurd_duration_in_one_line(tmp_path, dt):
    # found trying: --dt 1e-7 raised "OverflowError: int too large to convert to float" from the
    # size in TB, and --dt 1e-10 (1e310 steps) "cannot convert float infinity to integer"
    env = dict(os.environ, MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, "-m", "orbitflex", "demo", "--duration", "1e300", "--dt", dt,
                        "--out", str(tmp_path / "o"), "--quiet"], capture_output=True, text=True,
                       cwd=tmp_path, env=env, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-1500:]
    line, = r.stderr.strip().splitlines()
    assert line.startswith("orbitflex: error: --duration/--dt: ") and "shorten --duration" in line, line
    assert not (tmp_path / "o").exists()
