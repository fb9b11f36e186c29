"""The type stub matches the compiled module (mypy's stubtest), and the Python package is clean
under ``mypy --strict``: users who type-check their scripts get the real signatures."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import pytest

pytest.importorskip("mypy")

SOURCE = pathlib.Path(__file__).resolve().parents[2] / "python"


def run(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, MYPY_CACHE_DIR=os.devnull if os.name != "nt" else "nul")
    return subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True,
                          timeout=600, cwd=pathlib.Path(__file__).parent, env=env)


def test_stubtest_is_clean():
    result = run("mypy.stubtest", "orbitflex")
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]


@pytest.mark.skipif(not SOURCE.exists(), reason="needs the source tree")
def test_mypy_strict_is_clean_on_the_package():
    result = run("mypy", "--strict", "--no-incremental", str(SOURCE / "orbitflex"))
    assert result.returncode == 0, result.stdout[-4000:]
