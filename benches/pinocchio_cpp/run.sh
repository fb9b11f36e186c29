#!/usr/bin/env bash
# orbitflex (Rust) against Pinocchio's C++ on the same URDFs, in one run (BENCHMARKS.md).
#
#   bash benches/pinocchio_cpp/run.sh [ROUNDS]        # default 5 rounds
#
# Builds bench_aba.cpp with g++ -O3 -DNDEBUG against the headers and shared libraries of the
# `pin` wheel (its cmeel prefix), and examples/bench_cpp_match.rs with cargo --release. Then,
# per round and per model, runs the C++ and the Rust program back to back (alternating which
# goes first) and prints the medians over rounds as a markdown table of ratios
# orbitflex / Pinocchio (< 1: orbitflex is faster). It also checks that both computed the same
# joint accelerations and the same RK4 step, so the two time the same model.
#
# Needs: g++, python3 with `pin` and `example-robot-data` (pip), Eigen 3 headers and the
# urdfdom model headers. The wheel ships neither: `apt-get install libeigen3-dev
# liburdfdom-headers-dev`. Only the declarations of urdf_model are used (the URDF is parsed
# inside libpinocchio_parsers.so), so Debian's urdfdom headers do.
#
# Both sides are built for the baseline x86-64, as both wheels ship. The C++ side cannot be built
# with -march=native against the wheel's libraries: the Model made in libpinocchio_parsers.so then
# crashes in ~Model() in this program (an ABI mismatch); see benches/target_cpu.sh for Rust.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
rounds=${1:-5}
target=${CARGO_TARGET_DIR:-$root/target}
out=$target/pinocchio_cpp
mkdir -p "$out"

prefix=$(python3 -c "import os, pinocchio as p; f = os.path.abspath(p.__file__); print(f[:f.index('cmeel.prefix') + len('cmeel.prefix')])")
robots=$prefix/share/example-robot-data/robots
eigen=""
for d in "$prefix/include/eigen3" /usr/include/eigen3 /usr/local/include/eigen3; do
  [ -f "$d/Eigen/Core" ] && { eigen=$d; break; }
done
[ -n "$eigen" ] || { echo "Eigen 3 headers not found: apt-get install libeigen3-dev" >&2; exit 1; }
urdf_inc=""
for d in "$prefix/include" "$prefix/include/urdfdom" /usr/include /usr/local/include; do
  [ -f "$d/urdf_model/model.h" ] && { urdf_inc=$d; break; }
done
[ -n "$urdf_inc" ] || { echo "urdf_model headers not found: apt-get install liburdfdom-headers-dev" >&2; exit 1; }

# Pinocchio's CMake exports these definitions (lib/cmake/pinocchio): its joint variant has more
# alternatives than Boost.MPL's default limit of 20.
defs="-DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS
      -DBOOST_FUSION_INVOKE_MAX_ARITY=12 -DPINOCCHIO_WITH_URDFDOM -DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3
      -DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0 -DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0"
cpp=$out/bench_aba
if [ ! -x "$cpp" ] || [ "$here/bench_aba.cpp" -nt "$cpp" ]; then
  echo "building $cpp (g++ -O3 -DNDEBUG; about 2 minutes)" >&2
  # shellcheck disable=SC2086
  g++ -O3 -DNDEBUG -std=c++17 $defs -I"$prefix/include" -I"$urdf_inc" -I"$eigen" \
    "$here/bench_aba.cpp" -o "$cpp" -L"$prefix/lib" -Wl,-rpath,"$prefix/lib" \
    -lpinocchio_parsers -lpinocchio_default -lurdfdom_model -lconsole_bridge 2>"$out/build.log" ||
    { cat "$out/build.log" >&2; exit 1; }
fi
echo "building examples/bench_cpp_match (cargo --release)" >&2
(cd "$root" && cargo build --quiet --release --example bench_cpp_match)
rust=${CARGO_TARGET_DIR:-$target}/release/examples/bench_cpp_match

space=$out/space_arm.urdf
python3 -c "import orbitflex; open('$space', 'w').write(orbitflex.models.space_arm_urdf())" 2>/dev/null ||
  cp "$root/models/space_arm.urdf" "$space"

declare -A model_args=(
  [panda]="$robots/panda_description/urdf/panda.urdf panda_hand_tcp panda_finger_joint1 panda_finger_joint2"
  [space_arm]="$space -"
)
log=$out/log.txt
: >"$log"
for round in $(seq 1 "$rounds"); do
  for model in panda space_arm; do
    # shellcheck disable=SC2086
    set -- ${model_args[$model]}
    if [ $((round % 2)) -eq 1 ]; then order="cpp rust"; else order="rust cpp"; fi
    for side in $order; do
      if [ "$side" = cpp ]; then
        "$cpp" "$@" | sed "s/^/$round $model $side /" >>"$log"
      else
        "$rust" "$@" --only aba,rnea,crba,rk4_step,aba_derivatives,rnea_derivatives,step_jacobians | sed "s/^/$round $model $side /" >>"$log"
      fi
    done
  done
  echo "round $round/$rounds done" >&2
done

python3 - "$log" "$(lscpu | sed -n 's/^Model name: *//p')" <<'EOF'
import statistics, sys
from collections import defaultdict

log, cpu = sys.argv[1], sys.argv[2]
times = defaultdict(list)      # (model, side, name) -> [ns per round]
checks = {}
for line in open(log):
    round_, model, side, name, *values = line.split()
    if name.startswith("check_"):
        checks[(model, side, name)] = [float(v) for v in values]
    elif name not in ("model",) and values:
        try:
            times[(model, side, name)].append(float(values[0]))
        except ValueError:
            pass
med = {k: statistics.median(v) for k, v in times.items()}


def ratio(model, ours, theirs):
    """Median over rounds of the ratio within each round (the two ran back to back)."""
    a, b = times.get((model, "rust", ours), []), times.get((model, "cpp", theirs), [])
    return statistics.median(x / y for x, y in zip(a, b)) if a and b else None


for model in ("panda", "space_arm"):
    for name in ("check_qdd", "check_step"):
        a, b = checks.get((model, "rust", name)), checks.get((model, "cpp", name))
        if a and b:
            err = max(abs(x - y) for x, y in zip(a, b)) / max(1.0, max(abs(y) for y in b))
            status = "ok" if err < 1e-8 else "MISMATCH"
            print(f"agreement {model} {name[6:]}: max rel diff {err:.1e} ({status})", file=sys.stderr)
print(f"\nRust vs Pinocchio C++ (g++ -O3 -DNDEBUG; cargo --release), {cpu}, "
      f"median of {len(next(iter(times.values())))} rounds\n")
print("Times are medians over rounds; the ratio is the median of the per-round ratios.\n")
print("| model | algorithm | orbitflex (µs) | Pinocchio (µs) | ratio |")
print("|---|---|---:|---:|---:|")
pairs = [("aba", "aba_local", "forward dynamics: `aba` vs `aba` (LOCAL)"),
         ("aba", "aba_world", "forward dynamics: `aba` vs `aba` (WORLD)"),
         ("rnea", "rnea", "inverse dynamics: `rnea` vs `rnea`"),
         ("crba", "crba_local", "mass matrix: `crba` vs `crba` (LOCAL)"),
         ("rk4_step", "rk4_step", "one flexible-joint RK4 step (4 × aba)"),
         ("aba_derivatives", "aba_derivatives", "forward-dynamics derivatives vs `computeABADerivatives`"),
         ("rnea_derivatives", "rnea_derivatives", "inverse-dynamics derivatives vs `computeRNEADerivatives`")]
for model in ("panda", "space_arm"):
    for ours, theirs, label in pairs:
        a, b = med.get((model, "rust", ours)), med.get((model, "cpp", theirs))
        if a and b:
            print(f"| {model} | {label} | {a / 1e3:.2f} | {b / 1e3:.2f} | {ratio(model, ours, theirs):.2f} |")
for model in ("panda", "space_arm"):
    per_round = lambda side, fd: statistics.median(
        s / a for s, a in zip(times[(model, side, "rk4_step")], times[(model, side, fd)]))
    if (model, "rust", "rk4_step") in times and (model, "cpp", "rk4_step") in times:
        print(f"\n{model}: RK4 step / forward dynamics = {per_round('rust', 'aba'):.2f} for orbitflex, "
              f"{per_round('cpp', 'aba_local'):.2f} for Pinocchio", end="")
print()
for model in ("panda", "space_arm"):
    jac, step = times.get((model, "rust", "step_jacobians")), times.get((model, "rust", "rk4_step"))
    cd = times.get((model, "rust", "step_jacobians_central_differences"))
    if jac and step and cd:
        print(f"\n{model}: step_jacobians / RK4 step = {statistics.median(j / s for j, s in zip(jac, step)):.1f}; "
              f"central differences / step_jacobians = {statistics.median(c / j for c, j in zip(cd, jac)):.1f}", end="")
print()
EOF
