#!/usr/bin/env bash
# Installs a built wheel into a fresh virtual environment that cannot reach a Rust toolchain, then
# runs the import checks (.ci/wheel_smoke.py) and `orbitflex demo`. Proves that the wheel needs no
# compiler (docs/install.md, "Checking a wheel").
#
#   .ci/wheel_check.sh dist/orbitflex-*.whl [python3.9]
#
# The second argument is the interpreter to make the venv with (default python3): an abi3 wheel
# must install on every CPython >= 3.9. The dependencies (numpy, matplotlib, tqdm) come from the
# package index as wheels; nothing is built from source (--only-binary :all:).
set -euo pipefail
wheel=$(realpath "${1:?usage: .ci/wheel_check.sh WHEEL [PYTHON]}")
python=${2:-python3}
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/orbitflex-wheel-check.XXXXXX")
trap 'rm -rf "$work"' EXIT

# A PATH without any directory that holds cargo, rustc or rustup, and no Rust variables.
clean_path=""
IFS=: read -r -a dirs <<<"$PATH"
for dir in "${dirs[@]}"; do
  [ -n "$dir" ] || continue
  if [ -e "$dir/cargo" ] || [ -e "$dir/rustc" ] || [ -e "$dir/rustup" ]; then continue; fi
  clean_path="${clean_path:+$clean_path:}$dir"
done
python=$(command -v "$python")
"$python" -m venv "$work/venv"
run() {
  env -u CARGO -u RUSTC -u CARGO_HOME -u RUSTUP_HOME -u RUSTUP_TOOLCHAIN -u RUSTFLAGS \
    -u VIRTUAL_ENV -u PYTHONPATH MATURIN_NO_INSTALL_RUST=1 \
    PATH="$work/venv/bin:$clean_path" "$@"
}

cd "$work"
echo "== toolchain: none"
run bash -c 'for tool in cargo rustc rustup; do
  if command -v "$tool" >/dev/null; then echo "$tool is reachable: $(command -v "$tool")"; exit 1; fi
done; echo "cargo, rustc and rustup are not on PATH; CARGO/RUSTC unset"; env | grep -E "^(CARGO|RUSTC)=" && exit 1 || true'

echo "== install $(basename "$wheel") with $("$work/venv/bin/python" --version)"
start=$(date +%s%N)
run python -m pip install --quiet --only-binary :all: "$wheel"
echo "installed in $(( ($(date +%s%N) - start) / 1000000 )) ms:"
run python -m pip list --format freeze | grep -i -E '^(orbitflex|numpy|matplotlib|tqdm)=='

echo "== import checks"
run python "$here/wheel_smoke.py"

echo "== orbitflex demo"
start=$(date +%s%N)
run orbitflex demo --no-animation --quiet --out "$work/demo" >"$work/demo.log"
grep -E "steps/s|momentum drift|flexible plan " "$work/demo.log" || true
ls "$work/demo"
test -s "$work/demo/summary.json" && test -s "$work/demo/trajectory.npz"
echo "demo ran in $(( ($(date +%s%N) - start) / 1000000 )) ms"
if [ -n "${KEEP_DEMO:-}" ]; then cp -r "$work/demo" "$KEEP_DEMO"; fi
echo "wheel_check: $(basename "$wheel") installs and runs without a Rust toolchain"
