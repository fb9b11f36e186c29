"""Golden outputs of the command line: what ``orbitflex demo``, ``orbitflex simulate`` and
``orbitflex plan`` print and write on the built-in arm, recorded once and compared on every run.

These guard refactors: the words, units, layout and numbers a user sees must not change. The
recordings live in ``tests/python/golden/``; after a deliberate change of the output, rewrite them
with ``ORBITFLEX_REGEN_GOLDEN=1 python -m pytest test_cli_golden.py`` and review the diff.

How exact. The text is compared line by line: everything but the numbers character for
character, the numbers as printed, except two kinds of figures:
- wall-clock figures (steps per second, seconds of wall time) are masked;
- the momentum drift (free floating from rest, so pure RK4 truncation and round-off, about
  1e-12 N·m·s) is compared within 1e-11 in its units.
The JSON summaries and a digest of the ``.npz`` files (shapes, and five sampled rows of every
array) are compared number by number within ``|a − b| ≤ 1e-9 |b| + 1e-11``. Why that bound: the
runs are at most about 6,000 RK4 steps of quantities of order 1e-3 to 1e3 (rad, m, J, N·m); a
last-bit difference of ``sin``/``cos`` between two libm code paths (glibc picks an FMA variant
where the processor has one) grows, on these damped, stable runs, to at most about
6,000 × 2.2e-16 ≈ 1.3e-12 relative, so 1e-9 relative (and 1e-11 absolute for the quantities
that are themselves round-off, such as the momentum drift and the tracking errors of 1e-9 rad)
leaves room for any x86-64 machine while a change of formula, order of terms or step moves the
numbers by far more. Set ``ORBITFLEX_GOLDEN_EXACT=1`` to require every number bit for bit (the
refactor's check on the machine that recorded the files).
"""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import orbitflex

GOLDEN = Path(__file__).parent / "golden"
REGEN = os.environ.get("ORBITFLEX_REGEN_GOLDEN") == "1"
EXACT = os.environ.get("ORBITFLEX_GOLDEN_EXACT") == "1"
RTOL, ATOL = 1e-9, 1e-11

# (name, arguments after the command, files to digest); {urdf} is the built-in arm's URDF
RUNS = {
    "demo": ("demo", "--duration", "0.5", "--no-plots", "--no-animation"),
    "simulate": ("simulate", "{urdf}", "--duration", "0.3", "--slew-time", "0.25", "--no-animation"),
    "plan": ("plan", "{urdf}", "--goal", "0.3", "--base", "free", "--settle", "0.5"),
}
SUMMARIES = {"demo": "summary.json", "simulate": "summary.json", "plan": "plan_summary.json"}
ARRAYS = {"demo": "trajectory.npz", "simulate": "trajectory.npz", "plan": "plan.npz"}

NUMBER = re.compile(r"[-+]?(?:\d[\d,]*\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
# wall-clock figures: masked
WALL_CLOCK = [re.compile(r"[\d,]+ steps/s"), re.compile(r"\([\d.e+-]+ s of wall time\)")]


def run(name: str, tmp_path: Path) -> tuple[str, Path]:
    urdf = tmp_path / "space_arm.urdf"
    urdf.write_text(orbitflex.models.space_arm_urdf())
    out = tmp_path / "out"
    args = [a.format(urdf=urdf.name) for a in RUNS[name]] + ["--out", "out"]
    if name != "plan":
        args.append("--quiet")
    env = dict(os.environ, MPLBACKEND="Agg", RUST_BACKTRACE="0")
    result = subprocess.run([sys.executable, "-m", "orbitflex", *args], capture_output=True,
                            text=True, cwd=tmp_path, env=env, timeout=300)
    assert result.returncode == 0, (result.stdout[-2000:], result.stderr[-2000:])
    return result.stdout, out


def masked(text: str) -> list[str]:
    lines = []
    for line in text.splitlines():
        for pattern in WALL_CLOCK:
            line = pattern.sub("<wall clock>", line)
        lines.append(line.rstrip())
    return lines


def digest(path: Path) -> dict:
    """Shapes and five sampled rows (first, quarters, last) of every array of an ``.npz``."""
    out = {}
    with np.load(path, allow_pickle=False) as data:
        for key in data.files:
            a = data[key]
            entry: dict = {"shape": list(a.shape), "dtype": a.dtype.kind}
            if a.ndim == 0 or a.dtype.kind not in "fiu":
                entry["value"] = a.tolist()
            elif len(a) > 0:
                picks = sorted({0, len(a) // 4, len(a) // 2, 3 * len(a) // 4, len(a) - 1})
                entry["rows"] = {str(i): a[i].tolist() for i in picks}
            out[key] = entry
    return out


def compare(given, expected, where: str) -> None:
    """Equal structure and strings; numbers within the module's bound (bit for bit if EXACT)."""
    if isinstance(expected, dict):
        assert isinstance(given, dict) and sorted(given) == sorted(expected), (where, given, expected)
        for key in expected:
            if key == "steps_per_second":  # wall clock
                continue
            compare(given[key], expected[key], f"{where}.{key}")
    elif isinstance(expected, list):
        assert isinstance(given, list) and len(given) == len(expected), (where, given, expected)
        for i, (g, e) in enumerate(zip(given, expected)):
            compare(g, e, f"{where}[{i}]")
    elif isinstance(expected, float) and not isinstance(expected, bool):
        assert isinstance(given, (int, float)), (where, given, expected)
        if EXACT or not math.isfinite(expected):
            assert given == expected or (math.isnan(given) and math.isnan(expected)), (where, given, expected)
        else:
            assert abs(given - expected) <= RTOL * abs(expected) + ATOL, (where, given, expected)
    else:
        assert given == expected, (where, given, expected)


def compare_text(given: list[str], expected: list[str], name: str) -> None:
    assert len(given) == len(expected), (name, "\n".join(given))
    for g, e in zip(given, expected):
        assert NUMBER.sub("#", g) == NUMBER.sub("#", e), (name, g, e)
        if "momentum drift" in e and not EXACT:
            for a, b in zip(NUMBER.findall(g), NUMBER.findall(e)):
                assert abs(float(a) - float(b)) <= ATOL, (name, g, e)
        else:
            assert g == e, (name, g, e)


@pytest.mark.parametrize("name", sorted(RUNS))
def test_cli_output_is_unchanged(name, tmp_path):
    stdout, out = run(name, tmp_path)
    text = masked(stdout)
    summary = json.loads((out / SUMMARIES[name]).read_text())
    arrays = digest(out / ARRAYS[name])
    files = {"stdout": GOLDEN / f"{name}_stdout.txt", "summary": GOLDEN / f"{name}_summary.json",
             "arrays": GOLDEN / f"{name}_arrays.json"}
    if REGEN:
        GOLDEN.mkdir(exist_ok=True)
        files["stdout"].write_text("\n".join(text) + "\n")
        files["summary"].write_text(json.dumps(summary, indent=1) + "\n")
        files["arrays"].write_text(json.dumps(arrays, indent=1) + "\n")
        pytest.skip(f"rewrote the golden files of {name}")
    compare_text(text, files["stdout"].read_text().splitlines(), name)
    compare(summary, json.loads(files["summary"].read_text()), f"{name} {SUMMARIES[name]}")
    compare(arrays, json.loads(files["arrays"].read_text()), f"{name} {ARRAYS[name]}")
