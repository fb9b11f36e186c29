#!/usr/bin/env bash
# Instructions per call (callgrind's Ir) of two builds of examples/bench_cpp_match, side by side:
# the cost of a change, for the rule that a refactor may not cost more than 2 % in instructions.
#
#   bash benches/callgrind_compare.sh OLD_BIN NEW_BIN          # e.g. a scratch worktree's build
#   MODELS="panda space_arm" ITERS_SCALE=1 bash benches/callgrind_compare.sh A B
#
# A scratch build of an older tree: `git worktree add /tmp/old <commit>`, copy this tree's
# `target/release` there (only orbitflex recompiles), `cargo build --release --example
# bench_cpp_match` in it. Each program runs one measurement (`--only NAME --iters N`) under
# callgrind with `--blocks 1` and `--blocks 3`; (Ir₃ − Ir₁) / 2N counts the calls alone, setup
# excluded (the method of benches/pinocchio_cpp/callgrind.sh). `simulate_1e4` is reported per
# step (10⁴ steps under MotorPD, its record included); `aba` includes its argument checks.
set -euo pipefail
[ $# -eq 2 ] || { echo "usage: $0 OLD_BIN NEW_BIN" >&2; exit 2; }
old=$1 new=$2
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
command -v valgrind >/dev/null || { echo "valgrind not found (apt-get install valgrind)" >&2; exit 1; }
prefix=$(python3 -c "import os, pinocchio as p; f = os.path.abspath(p.__file__); print(f[:f.index('cmeel.prefix') + len('cmeel.prefix')])")
robots=$prefix/share/example-robot-data/robots
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp "$root/models/space_arm.urdf" "$work/space_arm.urdf"
declare -A model_args=(
  [panda]="$robots/panda_description/urdf/panda.urdf panda_hand_tcp panda_finger_joint1 panda_finger_joint2"
  [space_arm]="$work/space_arm.urdf -"
)
read -r -a models <<<"${MODELS:-panda space_arm}"
# name:calls per block (callgrind runs about 50× slower than the processor)
quantities="aba:100 rnea:100 crba:100 rk4_step:100 aba_derivatives:20 step_jacobians:10 simulate_1e4:1"
total_ir() { # total_ir PROGRAM ARGS...: total Ir of the run
  valgrind --tool=callgrind --callgrind-out-file="$work/cg.out" "$@" >/dev/null 2>"$work/cg.err" ||
    { cat "$work/cg.err" >&2; exit 1; }
  sed -n 's/^totals: *//p; s/^summary: *//p' "$work/cg.out" | head -1
}
echo "| model | call | old | new | new / old |"
echo "|---|---|---:|---:|---:|"
for model in "${models[@]}"; do
  # shellcheck disable=SC2086
  set -- ${model_args[$model]}
  for q in $quantities; do
    name=${q%%:*} iters=${q##*:}
    per=()
    for prog in "$old" "$new"; do
      a=$(total_ir "$prog" "$@" --only "$name" --iters "$iters" --blocks 1)
      b=$(total_ir "$prog" "$@" --only "$name" --iters "$iters" --blocks 3)
      calls=$((2 * iters))
      [ "$name" = simulate_1e4 ] && calls=$((calls * 10000))
      per+=("$(( (b - a) / calls ))")
    done
    label=$name
    [ "$name" = simulate_1e4 ] && label="simulate, per step"
    python3 -c "import sys; o, n = map(int, sys.argv[3:]); print(f'| {sys.argv[1]} | \`{sys.argv[2]}\` | {o:,} | {n:,} | {n / o:.3f} |')" \
      "$model" "$label" "${per[0]}" "${per[1]}"
  done
done
