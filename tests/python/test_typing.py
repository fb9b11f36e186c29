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


def test_stubtest_is_clean_with_the_base_install_alone(tmp_path):
    # The optional extras (pandas, Dask, meshcat, umsgpack) and the stubs of tqdm were needed for
    # stubtest to pass: with the base install alone it reported viz.py, campaign.py and cli.py.
    # mypy here sees a Python whose site-packages hold only the base install: orbitflex and its
    # dependencies numpy, matplotlib and tqdm (no types-tqdm).
    import importlib
    import venv

    base = tmp_path / "base"
    venv.EnvBuilder(with_pip=False).create(base)
    python = base / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    site = subprocess.run([str(python), "-c", "import site; print(site.getsitepackages()[0])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    farm = tmp_path / "farm"
    farm.mkdir()
    for name in ("orbitflex", "numpy", "matplotlib", "tqdm"):
        module = importlib.import_module(name)
        try:
            (farm / name).symlink_to(pathlib.Path(module.__file__).parent, target_is_directory=True)
        except OSError:
            pytest.skip("needs symbolic links")
    pathlib.Path(site, "base_install.pth").write_text(str(farm) + "\n")
    config = tmp_path / "mypy.ini"
    config.write_text(f"[mypy]\npython_executable = {python}\n")
    result = run("mypy.stubtest", "--mypy-config-file", str(config), "orbitflex")
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
