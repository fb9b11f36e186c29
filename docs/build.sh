#!/usr/bin/env bash
# Builds the documentation site into docs/_build/html: the Rust API docs (rustdoc, warnings as
# errors) copied under rust/, then Sphinx with every tutorial and the gallery executed. A warning,
# a broken internal link or anchor, or a failing notebook fails the build (exit status ≠ 0).
#
# Needs the installed package and the docs extra: pip install '.[docs]' (or maturin develop
# --release && pip install '.[docs]' in a dev venv). External http(s) links are not checked here
# (no network in CI); `sphinx-build -b linkcheck docs docs/_build/linkcheck` does that where
# there is one.
set -euo pipefail
cd "$(dirname "$0")/.."
# tutorial 7 builds examples/c/slew.c against include/ from the repository (notebooks run in a
# temporary folder)
export ORBITFLEX_SOURCE="$PWD"
start=$SECONDS
export PYTHONWARNINGS="${PYTHONWARNINGS:-}"

RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --quiet
rustdoc_done=$SECONDS

rm -rf docs/_build/html docs/_build/doctrees docs/_build/jupyter_execute
python3 -m sphinx -b html -W --keep-going -n -q -j 1 docs docs/_build/html "$@"

# The site links to the rustdoc at rust/orbitflex/index.html; it must be there.
mkdir -p docs/_build/html/rust
cp -r target/doc/. docs/_build/html/rust/
test -f docs/_build/html/rust/orbitflex/index.html
test -f docs/_build/html/rust/orbitflex/model_documentation/index.html
echo "docs: built docs/_build/html in $((SECONDS - start)) s (rustdoc $((rustdoc_done - start)) s)"
