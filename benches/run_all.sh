#!/usr/bin/env bash
# Every benchmark behind BENCHMARKS.md, in one command. The tables go to stdout and to
# $CARGO_TARGET_DIR/benchmarks/results.md (default target/benchmarks/).
#
#   bash benches/run_all.sh              # about 30 minutes on a 2-core machine
#   QUICK=1 bash benches/run_all.sh      # shorter criterion runs, fewer rounds (about 10 minutes)
#   INSTALL=1 bash benches/run_all.sh    # first rebuild and install the wheel from this tree
#
# Steps: (1) criterion, `cargo bench --bench dynamics`, and the ratio targets measured interleaved,
# `cargo run --release --example bench_ratios`; (2) Rust vs Pinocchio's C++,
# benches/pinocchio_cpp/run.sh; (3) Python vs Pinocchio's bindings, benches/compare_pinocchio.py
# (uses the installed `orbitflex`); (4) the target-cpu check, benches/target_cpu.sh.
# Needs: cargo, g++, python3 with orbitflex, pin, example-robot-data and numpy; Eigen 3 and urdfdom
# headers for step 2 (`apt-get install libeigen3-dev liburdfdom-headers-dev`), and clang-14 for its
# clang builds (skipped without it). Step 3's native Pinocchio times come from step 2's g++ build.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$root/target}
res=$CARGO_TARGET_DIR/benchmarks
mkdir -p "$res"
if [ -n "${QUICK:-}" ]; then
  rounds=3 crit=(-- --warm-up-time 1 --measurement-time 2) py=(--blocks 9 --sim-blocks 3 --rounds 3)
else
  rounds=7 crit=() py=(--blocks 21 --sim-blocks 5 --rounds 7)
fi

if [ -n "${INSTALL:-}" ]; then
  echo "== building and installing the wheel" >&2
  rm -rf "$CARGO_TARGET_DIR/wheels"
  maturin build --release -o "$CARGO_TARGET_DIR/wheels" >&2
  python3 -m pip install --force-reinstall --no-deps "$CARGO_TARGET_DIR"/wheels/orbitflex-*.whl >&2
fi

{
  echo "# orbitflex benchmarks, $(date -u +%Y-%m-%dT%H:%MZ)"
  echo
  echo "Machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores; $(rustc --version); $(g++ --version | head -1)"
  echo "Python orbitflex: $(python3 -c 'import orbitflex; print(orbitflex.__file__)')"
} >"$res/results.md"

echo "== (1) criterion: cargo bench --bench dynamics ${crit[*]}" >&2
cargo bench --bench dynamics "${crit[@]}" >"$res/criterion.log" 2>&1
python3 benches/criterion_table.py "$CARGO_TARGET_DIR/criterion" >"$res/criterion.md"
echo "== (1b) interleaved ratios: cargo run --release --example bench_ratios" >&2
{ echo; cargo run --quiet --release --example bench_ratios; } >>"$res/criterion.md"

echo "== (2) Rust vs Pinocchio C++: benches/pinocchio_cpp/run.sh $rounds" >&2
bash benches/pinocchio_cpp/run.sh "$rounds" >"$res/cpp.md"

echo "== (3) Python vs Pinocchio: benches/compare_pinocchio.py ${py[*]}" >&2
python3 benches/compare_pinocchio.py "${py[@]}" \
  --rust-bin "$CARGO_TARGET_DIR/release/examples/bench_cpp_match" \
  --cpp-bin "$CARGO_TARGET_DIR/pinocchio_cpp/bench_aba_gcc" \
  --json "$res/python.json" >"$res/python.md"

echo "== (4) target-cpu: benches/target_cpu.sh $rounds" >&2
bash benches/target_cpu.sh "$rounds" >"$res/target_cpu.md"

for part in criterion cpp python target_cpu; do
  { echo; echo "## $part"; echo; cat "$res/$part.md"; } >>"$res/results.md"
done
cat "$res/results.md"
