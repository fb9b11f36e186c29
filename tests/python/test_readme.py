"""Every Python block of README.md and of the documentation's Markdown pages (docs/**/*.md, the
built site excluded) runs as written, as a script would run it (``__name__ == "__main__"``, in a
temporary directory). Blocks marked ``text`` (or another language) are not Python and are
skipped; a fragment that needs names from elsewhere fails here. (The tutorials and the gallery,
docs/**/*.py, are executed by the site's build, docs/build.sh.)"""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = [ROOT / "README.md",
             *sorted(p for p in (ROOT / "docs").rglob("*.md") if "_build" not in p.relative_to(ROOT / "docs").parts)]


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
    # the README's examples moved into these pages (issue 30); each must keep running
    assert {document for document, _, _ in BLOCKS} >= {
        "README.md", "docs/getting_started.md", "docs/simulation.md", "docs/visualisation.md",
        "docs/batches.md", "docs/derivatives.md", "docs/modes.md", "docs/planning.md", "docs/trees.md",
        "docs/model.md", "docs/cosimulation.md"}
    assert len(BLOCKS) >= 20


@pytest.mark.parametrize("document, line, code", BLOCKS, ids=[f"{d}:{n}" for d, n, _ in BLOCKS])
def test_a_python_block_runs(document, line, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, f"{document} line {line}", "exec"), {"__name__": "__main__"})


def test_the_readme_states_what_is_unique_and_names_the_peers_fairly():
    # It said that no other rigid-body library keeps a motor state per joint; MuJoCo's dcmotor
    # keeps electrical state per actuator, Jiminy and AGX/OpenPLX model flexible joints.
    text = (ROOT / "README.md").read_text()
    assert "No other rigid-body library" not in text
    claim = text[text.index("## How it compares"):text.index("## Documentation")]
    for words in ("free-floating base", "analytical derivatives of the whole RK4 step",
                  "planning through the\nflexible-joint inverse dynamics", "dcmotor", "Jiminy", "OpenPLX",
                  "Modelica", "armature", "SPART", "SpaceDyn", "Basilisk"):
        assert words in claim, words
    # the full statement moved to the site's front page, with the same care
    index = (ROOT / "docs" / "index.md").read_text()
    claim = index[index.index("**Spong flexible joints:**"):index.index("- **Fixed-step RK4**")]
    for words in ("free-floating", "analytical derivatives of the whole RK4 step", "dcmotor", "Jiminy",
                  "OpenPLX", "armature"):
        assert words in claim, words


# --- the README as a front page (issue 30) ---------------------------------------------------------

README_LIMIT = 12_000  # characters


def _anchors(markdown: str) -> set:
    """The anchors GitHub (and the docs site, myst_heading_anchors) gives the headings: lower
    case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"^```.*?^```", "", markdown, flags=re.S | re.M)
    found = set()
    for heading in re.findall(r"^#{1,6} +(.+?) *$", text, flags=re.M):
        slug = re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
        found.add(slug)
    return found


def _links(markdown: str) -> list:
    """Every Markdown link and image target outside code blocks and code spans."""
    text = re.sub(r"^```.*?^```", "", markdown, flags=re.S | re.M)
    text = re.sub(r"`[^`\n]*`", "", text)
    return re.findall(r"\]\(([^)\s]+)\)", text)


def test_the_readme_is_a_front_page():
    text = (ROOT / "README.md").read_text()
    assert len(text) <= README_LIMIT, f"README.md has {len(text)} characters, more than {README_LIMIT}"
    # what a front page must have: the two commands, one example, one figure, the peers, the docs
    assert "pip install -v '.[viz]' && orbitflex demo" in text
    assert "pip install '.[test]' && cargo test --release --workspace && (cd tests/python && python -m pytest -q)" in text
    assert len([b for b in BLOCKS if b[0] == "README.md"]) == 1
    assert len(re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", text)) == 1
    for section in ("## Two commands", "## How it compares", "## Documentation"):
        assert section in text, section


def test_every_link_of_the_readme_resolves_in_the_repository():
    text = (ROOT / "README.md").read_text()
    links = _links(text)
    assert len(links) >= 15
    for link in links:
        if re.match(r"[a-z]+://", link):
            continue  # external: checked where there is a network, not here
        path, _, anchor = link.partition("#")
        target = (ROOT / path) if path else ROOT / "README.md"
        assert target.resolve().is_relative_to(ROOT), link
        assert target.is_file(), f"README.md links to {link}: no such file"
        if anchor:
            assert anchor in _anchors(target.read_text()), f"README.md links to {link}: no such heading"


def test_a_broken_readme_link_is_caught():
    # the two checks above can fail: a missing file and a missing heading are both seen
    assert "no-such-heading" not in _anchors((ROOT / "BENCHMARKS.md").read_text())
    assert "build" in _anchors((ROOT / "BENCHMARKS.md").read_text())
    assert _links("see [x](docs/nowhere.md) and `[y](z.md)`") == ["docs/nowhere.md"]
    assert not (ROOT / "docs" / "nowhere.md").exists()


def test_every_docs_page_is_in_the_site():
    # a page dropped into docs/ without a toctree line would be built but unreachable; Sphinx
    # warns about it (and -W fails the build), and this says which page, without building
    docs = ROOT / "docs"
    toctrees = "\n".join(m for p in docs.rglob("*.md") if "_build" not in p.parts
                         for m in re.findall(r"^```\{toctree\}\n(.*?)^```", p.read_text(), flags=re.S | re.M))
    listed = {line.strip() for line in toctrees.splitlines() if line.strip() and not line.startswith(":")}
    for page in [*docs.rglob("*.md"), *docs.rglob("*.py")]:
        rel = page.relative_to(docs)
        if "_build" in rel.parts or rel.name in ("conf.py",) or rel.as_posix() == "index.md":
            continue
        name = rel.with_suffix("").as_posix()
        folder_name = rel.with_suffix("").name
        assert name in listed or (rel.parent != Path(".") and folder_name in listed), f"docs/{rel} is in no toctree"
