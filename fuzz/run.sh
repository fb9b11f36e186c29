#!/usr/bin/env bash
# Runs every fuzz target for SECONDS (default 60) with cargo-fuzz on the nightly toolchain:
#
#   bash fuzz/run.sh [SECONDS]     (0: skip)
#
# Targets: urdf (bytes -> the URDF loader -> the dynamics), urdf_structured (a generator of
# trees, cycles, absurd numbers and deep nesting), toml (the joint-parameter reader). Seeds are
# in fuzz/seeds/ (plus the example-robot-data URDFs when that package is installed), tokens in
# fuzz/*.dict. Exits non-zero on a crash, a timeout or an out-of-memory; skips, with a message,
# when no nightly toolchain is installed.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
# libFuzzer reads -max_total_time=0 as "no limit": 0 seconds means no fuzzing at all.
if ! [[ "$seconds" =~ ^[0-9]+$ ]]; then
  echo "fuzz: SECONDS must be a whole number of seconds, given '$seconds'" >&2
  exit 2
fi
if [ "$seconds" -eq 0 ]; then
  echo "fuzz: skipped: 0 s asked"
  exit 0
fi
if ! rustup toolchain list 2>/dev/null | grep -q '^nightly'; then
  echo "fuzz: skipped: no nightly toolchain (rustup toolchain install nightly, then bash fuzz/run.sh)"
  exit 0
fi
if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "fuzz: installing cargo-fuzz" >&2
  cargo install --locked --quiet cargo-fuzz
fi
mkdir -p fuzz/corpus/urdf fuzz/corpus/urdf_structured fuzz/corpus/toml
prefix=$(python3 -c "import os, pinocchio as p; f = os.path.abspath(p.__file__); print(f[:f.index('cmeel.prefix') + len('cmeel.prefix')])" 2>/dev/null || true)
if [ -n "$prefix" ] && [ -d "$prefix/share/example-robot-data/robots" ]; then
  find "$prefix/share/example-robot-data/robots" -name '*.urdf' -size -2M -exec cp -n {} fuzz/corpus/urdf/ \; 2>/dev/null || true
fi
log=$(mktemp)
run() {
  local target=$1 seeds=$2; shift 2
  echo "fuzz: $target for ${seconds} s" >&2
  local status=0
  cargo +nightly fuzz run -O -s none "$target" "fuzz/corpus/$target" $seeds -- \
    -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 "$@" \
    >"$log" 2>&1 || status=$?
  grep -E '^(Done|stat::number_of_executed_units|SUMMARY|==[0-9]+== ERROR)|panicked' "$log" >&2 || true
  if [ "$status" -ne 0 ]; then
    tail -n 40 "$log" >&2
    echo "fuzz: $target FAILED (artifacts in fuzz/artifacts/$target)" >&2
    return "$status"
  fi
}
run urdf fuzz/seeds/urdf -dict=fuzz/urdf.dict
run urdf_structured ""
run toml fuzz/seeds/toml -dict=fuzz/toml.dict
