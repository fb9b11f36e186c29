"""The source distribution (what pip compiles where no wheel fits): ``maturin sdist`` writes it
from the checkout; it must carry the C runtime's crate (``capi/``), its header and the build
backend, no local build products, and a workspace in which ``cargo build -p orbitflex-capi``
finds the runtime once the backend has run.

Compiling the sdist takes minutes (two release builds of the core from nothing), too slow for
CI: docs/install.md records the hand check (``python -m build --sdist``, then ``pip install``
of it in a fresh virtual environment, then ``orbitflex fmu`` and FMPy). This test covers what
broke it: maturin's sdist drops the ``capi`` workspace member, and an explicit ``include`` list
in Cargo.toml took a local ``docs/_build`` into the archive."""

from __future__ import annotations

import importlib.util
import json
import shutil
import subprocess
import tarfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

if shutil.which("maturin") is None or shutil.which("cargo") is None:
    pytest.skip("maturin and cargo write and read the sdist (pip install maturin)", allow_module_level=True)
if not (ROOT / "pyproject.toml").is_file():  # pragma: no cover - tests copied out of the tree
    pytest.skip("needs the source tree", allow_module_level=True)


def packages(tree: Path) -> set:
    meta = subprocess.run(["cargo", "metadata", "--format-version", "1", "--no-deps", "--offline"], cwd=tree,
                          check=True, capture_output=True, text=True)
    return {p["name"] for p in json.loads(meta.stdout)["packages"]}


def test_the_sdist_carries_the_runtime_and_builds_it_after_the_backend(tmp_path):
    subprocess.run(["maturin", "sdist", "--out", str(tmp_path)], cwd=ROOT, check=True, capture_output=True)
    (archive,) = tmp_path.glob("orbitflex-*.tar.gz")
    # a few hundred kB of sources; a local docs build (tens of MB) must stay out
    assert archive.stat().st_size < 4_000_000, archive.stat().st_size
    with tarfile.open(archive) as tar:
        names = {Path(*Path(n).parts[1:]).as_posix() for n in tar.getnames()}
        tar.extractall(tmp_path / "src")
    assert not any(n.startswith(("docs/_build", "target/", ".venv")) for n in names), \
        sorted(n for n in names if n.startswith(("docs/_build", "target/", ".venv")))[:5]
    assert not any(n.endswith((".so", ".dylib", ".dll")) for n in names)
    for needed in ("capi/Cargo.toml", "capi/src/api.rs", "capi/src/fmi3.rs", "include/orbitflex.h",
                   "build_backend/orbitflex_backend.py", "Cargo.lock", "models/space_arm.urdf",
                   "docs/model.md", "python/orbitflex/fmu.py"):
        assert needed in names, needed
    (tree,) = (tmp_path / "src").iterdir()
    # maturin's sdist keeps only the members the Python crate depends on ...
    assert "orbitflex-capi" not in packages(tree)
    # ... and the build backend puts capi back before building the runtime
    spec = importlib.util.spec_from_file_location("sdist_backend", tree / "build_backend/orbitflex_backend.py")
    assert spec is not None and spec.loader is not None
    backend = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(backend)
    assert backend.ROOT == tree
    backend.restore_capi_member("cargo")
    assert packages(tree) == {"orbitflex", "orbitflex-capi"}
    text = (tree / "Cargo.toml").read_text()
    backend.restore_capi_member("cargo")  # once only
    assert (tree / "Cargo.toml").read_text() == text


def test_the_backend_leaves_a_checkout_as_it_is():
    spec = importlib.util.spec_from_file_location("checkout_backend", ROOT / "build_backend/orbitflex_backend.py")
    assert spec is not None and spec.loader is not None
    backend = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(backend)
    before = (ROOT / "Cargo.toml").read_bytes()
    backend.restore_capi_member("cargo")
    assert (ROOT / "Cargo.toml").read_bytes() == before
    assert "orbitflex-capi" in packages(ROOT)
