"""Which FMU runtime `write_fmu` packs: an explicit $ORBITFLEX_RUNTIME wins over the packaged one."""
from __future__ import annotations

from pathlib import Path

import pytest

from orbitflex.fmu import runtime_library


def test_the_environment_variable_wins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # the packaged runtime was searched first, so a freshly built library named by the variable
    # was silently ignored whenever an older one sat in the package
    chosen = tmp_path / "liborbitflex_c.so"
    chosen.write_bytes(b"")
    monkeypatch.setenv("ORBITFLEX_RUNTIME", str(chosen))
    assert runtime_library() == chosen


def test_a_variable_naming_no_file_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    missing = tmp_path / "nothing.so"
    monkeypatch.setenv("ORBITFLEX_RUNTIME", str(missing))
    with pytest.raises(FileNotFoundError, match=f"ORBITFLEX_RUNTIME names {missing}, which is not a file"):
        runtime_library()


def test_without_the_variable_the_package_or_a_recipe(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("ORBITFLEX_RUNTIME", raising=False)
    try:
        found = runtime_library()
    except FileNotFoundError as e:
        assert "cargo build --release -p orbitflex-capi" in str(e)
    else:
        assert found.parent.name == "_runtime" and found.is_file()
