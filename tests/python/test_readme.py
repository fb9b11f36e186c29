"""Every Python block of README.md and docs/*.md runs as written, as a script would run it
(``__name__ == "__main__"``, in a temporary directory). Blocks marked ``text`` (or another
language) are not Python and are skipped; a fragment that needs names from elsewhere fails here."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def python_blocks():
    """``(document, first line, code)`` of every fenced block marked ``python``."""
    blocks = []
    for document in DOCUMENTS:
        text = document.read_text()
        for match in re.finditer(r"^```python\n(.*?)^```", text, flags=re.S | re.M):
            line = text[: match.start()].count("\n") + 2
            blocks.append((document.relative_to(ROOT).as_posix(), line, match.group(1)))
    return blocks


BLOCKS = python_blocks()


def test_the_documents_have_python_examples():
    assert {document for document, _, _ in BLOCKS} == {"README.md", "docs/visualisation.md", "docs/modes.md",
                                                    "docs/cosimulation.md"}
    assert len(BLOCKS) >= 12


@pytest.mark.parametrize("document, line, code", BLOCKS, ids=[f"{d}:{n}" for d, n, _ in BLOCKS])
def test_a_python_block_runs(document, line, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, f"{document} line {line}", "exec"), {"__name__": "__main__"})


def test_the_readme_states_what_is_unique_and_names_the_peers_fairly():
    # It said that no other rigid-body library keeps a motor state per joint; MuJoCo's dcmotor
    # keeps electrical state per actuator, Jiminy and AGX/OpenPLX model flexible joints.
    text = (ROOT / "README.md").read_text()
    assert "No other rigid-body library" not in text
    claim = text[text.index("**Spong flexible joints:**"):text.index("- **Fixed-step RK4**")]
    for words in ("free-floating", "analytical derivatives of the whole RK4 step", "dcmotor", "Jiminy",
                  "OpenPLX", "armature"):
        assert words in claim, words
