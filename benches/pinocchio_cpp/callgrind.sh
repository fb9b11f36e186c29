#!/usr/bin/env bash
# Instructions per call (callgrind's Ir) of orbitflex and of each Pinocchio C++ build of run.sh,
# on panda and the space arm (MODELS as in run.sh: also dual_arm, solo12): aba, rnea, crba, one
# RK4 step, aba_derivatives, rnea_derivatives.
# Instruction counts do not move with the machine's load, unlike the times of run.sh.
#
#   bash benches/pinocchio_cpp/callgrind.sh              # BUILDS, CLANGXX as in run.sh
#   ITERS=200 bash benches/pinocchio_cpp/callgrind.sh    # calls per block (default 100)
#   MODELS="dual_arm solo12" bash benches/pinocchio_cpp/callgrind.sh
#
# Method. Each program is run under `valgrind --tool=callgrind` for one measurement only
# (`--only NAME --iters N`), twice: with `--blocks 1` and with `--blocks 3`. The two runs do the
# same work (loading the libraries, parsing the URDF, building the model, the agreement checks,
# the N/10 warm-up calls) except for 2N more calls of the measured function in the second, so
#   Ir per call = (Ir of the 3-block run − Ir of the 1-block run) / (2N)
# counts the calls alone, setup excluded; the two extra clock reads and the sort of three block
# times add a few hundred instructions over the 2N calls. The whole program is counted (no
# --toggle-collect), so nothing depends on what the compiler inlined. orbitflex's `aba` includes
# its argument checks; Pinocchio's `aba` and `crba` are the LOCAL convention.
#
# Builds that valgrind cannot run are reported as n/a: valgrind 3.19 does not decode AVX-512,
# which `-march=native` emits on a processor that has it (clang-native on such a machine).
# The programs are built by run.sh (`bash benches/pinocchio_cpp/run.sh 0` builds without timing).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
target=${CARGO_TARGET_DIR:-$root/target}
out=$target/pinocchio_cpp
iters=${ITERS:-100}
command -v valgrind >/dev/null || { echo "valgrind not found (apt-get install valgrind)" >&2; exit 1; }

bash "$here/run.sh" 0 # builds the C++ programs that BUILDS asks for (none if up to date)
(cd "$root" && cargo build --quiet --release --example bench_cpp_match)
rust=$target/release/examples/bench_cpp_match
builds=()
for b in ${BUILDS:-clang clang-native gcc wheel}; do
  [ -x "$out/bench_aba_$b" ] && builds+=("$b")
done

prefix=$(python3 -c "import os, pinocchio as p; f = os.path.abspath(p.__file__); print(f[:f.index('cmeel.prefix') + len('cmeel.prefix')])")
robots=$prefix/share/example-robot-data/robots
space=$out/space_arm.urdf
python3 -c "import orbitflex; open('$space', 'w').write(orbitflex.models.space_arm_urdf())" 2>/dev/null ||
  cp "$root/models/space_arm.urdf" "$space"
# MODELS picks the models (default: the two 7-joint arms of the tables); the branched ones are
# the dual-arm servicer (two 7-joint arms on the bus) and solo12 (a quadruped: four 3-joint legs)
declare -A model_args=(
  [panda]="$robots/panda_description/urdf/panda.urdf panda_hand_tcp panda_finger_joint1 panda_finger_joint2"
  [space_arm]="$space -"
  [dual_arm]="$root/models/dual_arm.urdf -"
  [solo12]="$robots/solo_description/robots/solo12.urdf -"
)
read -r -a models <<<"${MODELS:-panda space_arm}"
# orbitflex's name, then Pinocchio's
quantities="aba:aba_local rnea:rnea crba:crba_local rk4_step:rk4_step aba_derivatives:aba_derivatives rnea_derivatives:rnea_derivatives"

work=$out/callgrind
mkdir -p "$work"
total_ir() { # total_ir OUTFILE PROGRAM ARGS...: run under callgrind, print the total Ir ("" on failure)
  local f=$1
  shift
  if valgrind --tool=callgrind --callgrind-out-file="$f" "$@" >/dev/null 2>"$f.err"; then
    sed -n 's/^totals: *//p; s/^summary: *//p' "$f" | head -1
  fi
}

results=$work/results.txt
: >"$results"
for model in "${models[@]}"; do
  # shellcheck disable=SC2086
  set -- ${model_args[$model]}
  for q in $quantities; do
    ours=${q%%:*} theirs=${q##*:}
    for side in rust "${builds[@]}"; do
      if [ "$side" = rust ]; then prog=$rust name=$ours; else prog=$out/bench_aba_$side name=$theirs; fi
      a=$(total_ir "$work/$model.$side.$ours.1" "$prog" "$@" --only "$name" --iters "$iters" --blocks 1)
      b=$(total_ir "$work/$model.$side.$ours.3" "$prog" "$@" --only "$name" --iters "$iters" --blocks 3)
      if [ -n "$a" ] && [ -n "$b" ]; then
        per_call=$(( (b - a) / (2 * iters) ))
      else
        per_call=n/a
      fi
      echo "$model $ours $side $per_call" >>"$results"
      echo "$model $ours $side: $per_call Ir per call" >&2
    done
  done
done

python3 - "$results" "${builds[*]}" "$iters" "${models[*]}" <<'EOF'
import sys

results, builds, iters = sys.argv[1], sys.argv[2].split(), sys.argv[3]
models = sys.argv[4].split()
ir = {}
for line in open(results):
    model, name, side, value = line.split()
    ir[(model, name, side)] = value
labels = {"aba": "`aba`", "rnea": "`rnea`", "crba": "`crba`", "rk4_step": "RK4 step",
          "aba_derivatives": "`aba_derivatives`", "rnea_derivatives": "`rnea_derivatives`"}
print(f"\nInstructions per call (callgrind Ir; (3 blocks − 1 block) / {2 * int(iters)} calls)\n")
print("| model | call | orbitflex | " + " | ".join(builds) + " | orbitflex / fewest |")
print("|---|---|---:|" + "---:|" * len(builds) + "---:|")


def fmt(v):
    return f"{int(v):,}" if v.isdigit() else v


for model in models:
    for name, label in labels.items():
        ours = ir.get((model, name, "rust"), "n/a")
        theirs = {b: ir.get((model, name, b), "n/a") for b in builds}
        counted = [int(v) for v in theirs.values() if v.isdigit()]
        rel = f"{int(ours) / min(counted):.2f}" if ours.isdigit() and counted else "n/a"
        print(f"| {model} | {label} | {fmt(ours)} | " + " | ".join(fmt(theirs[b]) for b in builds) + f" | {rel} |")
EOF
