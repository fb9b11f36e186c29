"""The PEP 517 build backend of ``pip install .``: maturin, after building the C runtime.

The wheel carries two native libraries: the Python extension (``orbitflex/_core.abi3.so``,
built by maturin) and ``orbitflex/_runtime/liborbitflex_c.so``, the C API and FMU runtime of the
``capi/`` workspace member, which ``orbitflex fmu`` copies into every FMU. maturin builds one
crate per wheel, and the Python extension cannot serve as the FMU binary (it needs libpython's
symbols), so this backend first runs ``cargo build --release -p orbitflex-capi``, copies the
library into ``python/orbitflex/_runtime/`` (``[tool.maturin] include`` puts it in the wheel,
``.gitignore`` notwithstanding), then hands over to maturin for everything else.

``ORBITFLEX_SKIP_RUNTIME=1`` skips the runtime (the wheel then writes no FMUs, and says so).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any, Dict, Optional

import maturin
from maturin import *  # noqa: F401,F403  (every hook maturin provides, unchanged)

ROOT = Path(__file__).resolve().parent.parent
RUNTIME_DIR = ROOT / "python" / "orbitflex" / "_runtime"
NAMES = ("liborbitflex_c.so", "liborbitflex_c.dylib", "orbitflex_c.dll")


def build_runtime() -> None:
    """``cargo build --release -p orbitflex-capi`` and a copy of the library into the package."""
    if os.environ.get("ORBITFLEX_SKIP_RUNTIME"):
        return
    cargo = os.environ.get("CARGO", "cargo")
    restore_capi_member(cargo)
    print("orbitflex: building the C runtime (cargo build --release -p orbitflex-capi)", file=sys.stderr)
    subprocess.run([cargo, "build", "--release", "-p", "orbitflex-capi"], cwd=ROOT, check=True)
    target = Path(cargo_metadata(cargo)["target_directory"]) / "release"
    RUNTIME_DIR.mkdir(parents=True, exist_ok=True)
    for name in NAMES:
        if (target / name).exists():
            shutil.copy2(target / name, RUNTIME_DIR / name)
            return
    raise RuntimeError(f"cargo built orbitflex-capi but none of {NAMES} is in {target}")


def cargo_metadata(cargo: str) -> Dict[str, Any]:
    meta = subprocess.run([cargo, "metadata", "--format-version", "1", "--no-deps"], cwd=ROOT,
                          check=True, capture_output=True, text=True)
    data: Dict[str, Any] = json.loads(meta.stdout)
    return data


def restore_capi_member(cargo: str) -> None:
    """Puts ``capi`` back among the workspace members when building from the sdist.

    maturin's sdist rewrites the root ``Cargo.toml`` and keeps only the workspace members the
    Python crate depends on, so ``capi/`` is in the archive but no longer a member, and
    ``cargo build -p orbitflex-capi`` would find no such package. In a git checkout this
    changes nothing."""
    if not (ROOT / "capi" / "Cargo.toml").is_file():
        return
    packages = {p["name"] for p in cargo_metadata(cargo)["packages"]}
    if "orbitflex-capi" in packages:
        return
    manifest = ROOT / "Cargo.toml"
    text = manifest.read_text(encoding="utf-8")
    lines = text.splitlines(keepends=True)
    for i, line in enumerate(lines):
        if line.strip() == "[workspace]":
            if any(after.strip().startswith("members") for after in lines[i + 1:i + 5]):
                raise RuntimeError(f"{manifest}: the workspace lists members but not capi; add \"capi\"")
            lines.insert(i + 1, 'members = ["capi"]  # restored by the build backend (the sdist drops it)\n')
            manifest.write_text("".join(lines), encoding="utf-8")
            print("orbitflex: capi restored as a workspace member (the sdist's Cargo.toml lacks it)",
                  file=sys.stderr)
            return
    raise RuntimeError(f"{manifest} has no [workspace] table: cannot build the C runtime (capi/)")


def build_wheel(wheel_directory: str, config_settings: Optional[Dict[str, Any]] = None,
                metadata_directory: Optional[str] = None) -> str:
    build_runtime()
    return maturin.build_wheel(wheel_directory, config_settings, metadata_directory)


def build_editable(wheel_directory: str, config_settings: Optional[Dict[str, Any]] = None,
                   metadata_directory: Optional[str] = None) -> str:
    build_runtime()
    return maturin.build_editable(wheel_directory, config_settings, metadata_directory)
