#!/usr/bin/env bash
# orbitflex (Rust) against Pinocchio's C++ on the same URDFs, in one run (BENCHMARKS.md).
#
#   bash benches/pinocchio_cpp/run.sh [ROUNDS]        # default 5 rounds; 0: only build
#   BUILDS="clang gcc" bash benches/pinocchio_cpp/run.sh 3
#
# Builds bench_aba.cpp against the headers and shared libraries of the `pin` wheel (its cmeel
# prefix) in up to four configurations, each into $target/pinocchio_cpp/bench_aba_<build>
# (rebuilt when bench_aba.cpp is newer or the compile command changed):
#
#   clang         clang++ (14) -O3 -DNDEBUG, baseline x86-64
#   clang-native  clang++ (14) -O3 -DNDEBUG -march=native, with the layout guard described below
#   gcc           g++ -O3 -DNDEBUG, baseline x86-64
#   wheel         g++ -O3 -DNDEBUG -DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION: aba, rnea, crba and
#                 both derivative algorithms are not compiled here but called in
#                 libpinocchio_default.so, the wheel's own binary (its explicit instantiations
#                 for double), which is what `pip install pin` gives a C++ user; only the RK4
#                 glue around `aba` is compiled by g++.
#
# BUILDS picks some of them (default: all four). Without clang++ the two clang builds are skipped
# with a message. CLANGXX overrides the clang++ to use. Each compile is single-threaded; the clang
# ones take 3-6 minutes and 2.5 GB of memory on a 2-core machine.
#
# Then builds examples/bench_cpp_match.rs with cargo --release and, per round and per model, runs
# the Rust program and every C++ build back to back (the order reversed every other round), and
# prints one markdown table: the median time of each build and of orbitflex, which build was
# fastest, and the ratio orbitflex / Pinocchio (< 1: orbitflex is faster) against the fastest
# build and against each one, as medians of the per-round ratios. It also checks that every build
# computed the same joint accelerations and the same RK4 step as orbitflex.
#
# Needs: g++, python3 with `pin` and `example-robot-data` (pip), Eigen 3 headers and the
# urdfdom model headers. The wheel ships neither: `apt-get install libeigen3-dev
# liburdfdom-headers-dev` (and `clang-14` for the clang builds). Only the declarations of
# urdf_model are used (the URDF is parsed inside libpinocchio_parsers.so), so Debian's urdfdom
# headers do.
#
# -march=native. Compiled with AVX, Eigen raises its alignment of fixed-size objects (to 32 or 64
# bytes) and of its heap blocks, so the harness and the wheel's libraries, compiled for baseline
# x86-64 (16 bytes), disagree on the layout of Model and Data and on how Eigen's heap blocks are
# freed: a Model built in libpinocchio_parsers.so then crashes this program. The guard
# -DEIGEN_MAX_ALIGN_BYTES=16 keeps every object's layout at the baseline's 16 bytes, and
# -DEIGEN_MALLOC_ALREADY_ALIGNED=1 makes Eigen allocate with plain malloc/free as the libraries do
# (with AVX it would otherwise use its own over-aligned allocator, whose blocks free() cannot
# release). Eigen then uses unaligned AVX loads, and the compiler still emits AVX and FMA code:
# the script counts the FMA and ymm/zmm instructions in the harness's ABA passes after the build.
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

clangxx=${CLANGXX:-}
if [ -z "$clangxx" ]; then
  for c in clang++-14 clang++; do
    command -v "$c" >/dev/null && { clangxx=$c; break; }
  done
fi

# Pinocchio's CMake exports these definitions (lib/cmake/pinocchio): its joint variant has more
# alternatives than Boost.MPL's default limit of 20.
defs="-DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS
      -DBOOST_FUSION_INVOKE_MAX_ARITY=12 -DPINOCCHIO_WITH_URDFDOM -DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3
      -DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0 -DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0"
native_guard="-DEIGEN_MAX_ALIGN_BYTES=16 -DEIGEN_MALLOC_ALREADY_ALIGNED=1"

builds=()
for b in ${BUILDS:-clang clang-native gcc wheel}; do
  case $b in
    clang | clang-native)
      if [ -z "$clangxx" ]; then
        echo "skipping build '$b': no clang++ found (apt-get install clang-14, or set CLANGXX)" >&2
        continue
      fi ;;
    gcc | wheel) ;;
    *) echo "unknown build '$b' (known: clang clang-native gcc wheel)" >&2; exit 2 ;;
  esac
  builds+=("$b")
done
[ ${#builds[@]} -gt 0 ] || { echo "no C++ build to run" >&2; exit 1; }

build_cpp() { # build_cpp NAME: compile bench_aba_NAME if missing, stale or built differently
  local name=$1 bin=$out/bench_aba_$1 cxx flags
  case $name in
    clang) cxx=$clangxx flags="-O3 -DNDEBUG" ;;
    clang-native) cxx=$clangxx flags="-O3 -DNDEBUG -march=native $native_guard" ;;
    gcc) cxx=g++ flags="-O3 -DNDEBUG" ;;
    wheel) cxx=g++ flags="-O3 -DNDEBUG -DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION" ;;
  esac
  # shellcheck disable=SC2206
  local cmd=($cxx $flags -std=c++17 $defs -I"$prefix/include" -I"$urdf_inc" -I"$eigen"
    "$here/bench_aba.cpp" -o "$bin" -L"$prefix/lib" -Wl,-rpath,"$prefix/lib"
    -lpinocchio_parsers -lpinocchio_default -lurdfdom_model -lconsole_bridge)
  if [ -x "$bin" ] && [ ! "$here/bench_aba.cpp" -nt "$bin" ] && [ "$(cat "$bin.cmd" 2>/dev/null)" = "${cmd[*]}" ]; then
    return
  fi
  echo "building $bin ($cxx $flags; several minutes)" >&2
  "${cmd[@]}" 2>"$bin.log" || { cat "$bin.log" >&2; exit 1; }
  echo "${cmd[*]}" >"$bin.cmd"
  if [ "$name" = clang-native ] && command -v objdump >/dev/null; then
    # The guard must not cost the native code: count AVX/FMA instructions in the ABA passes.
    objdump -d -C --no-show-raw-insn "$bin" | awk '
      /^[0-9a-f]+ <.*>:$/ { hot = ($0 ~ /Aba(Local|World)Convention/) }
      hot && /^ +[0-9a-f]+:\t/ { n++; if (/[yz]mm/) v++; if (/vfn?m(add|sub)/) f++ }
      END { printf "clang-native: ABA passes have %d instructions, %d on ymm/zmm registers, %d FMA\n", n, v, f
            if (f == 0) print "WARNING: no FMA in the ABA passes; is -march=native in effect?" }' >&2
  fi
}
for b in "${builds[@]}"; do build_cpp "$b"; done
[ "$rounds" -gt 0 ] || exit 0

echo "building examples/bench_cpp_match (cargo --release)" >&2
(cd "$root" && cargo build --quiet --release --example bench_cpp_match)
rust=$target/release/examples/bench_cpp_match

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
sides=(rust "${builds[@]}")
log=$out/log.txt
: >"$log"
for round in $(seq 1 "$rounds"); do
  for model in "${models[@]}"; do
    # shellcheck disable=SC2086
    set -- ${model_args[$model]}
    order=("${sides[@]}")
    if [ $((round % 2)) -eq 0 ]; then
      order=()
      for ((i = ${#sides[@]} - 1; i >= 0; i--)); do order+=("${sides[i]}"); done
    fi
    for side in "${order[@]}"; do
      if [ "$side" = rust ]; then
        "$rust" "$@" --only aba,rnea,crba,rk4_step,aba_derivatives,rnea_derivatives,step_jacobians,step_jacobians_central_differences | sed "s/^/$round $model rust /" >>"$log"
      else
        "$out/bench_aba_$side" "$@" | sed "s/^/$round $model $side /" >>"$log"
      fi
    done
  done
  echo "round $round/$rounds done" >&2
done

python3 - "$log" "$(lscpu | sed -n 's/^Model name: *//p')" "${builds[*]}" \
  "$($clangxx --version 2>/dev/null | head -1 || true)" "$(g++ --version | head -1)" "${models[*]}" <<'EOF'
import statistics, sys
from collections import defaultdict

log, cpu, builds, clang_version, gcc_version = sys.argv[1], sys.argv[2], sys.argv[3].split(), sys.argv[4], sys.argv[5]
models = sys.argv[6].split()
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


def ratio(model, ours, build, theirs):
    """Median over rounds of the ratio within each round (the programs ran back to back)."""
    a, b = times.get((model, "rust", ours), []), times.get((model, build, theirs), [])
    return statistics.median(x / y for x, y in zip(a, b)) if a and b else None


for model in models:
    for build in builds:
        for name in ("check_qdd", "check_step"):
            a, b = checks.get((model, "rust", name)), checks.get((model, build, name))
            if a and b:
                err = max(abs(x - y) for x, y in zip(a, b)) / max(1.0, max(abs(y) for y in b))
                status = "ok" if err < 1e-8 else "MISMATCH"
                print(f"agreement {model} {build} {name[6:]}: max rel diff {err:.1e} ({status})", file=sys.stderr)
            else:
                print(f"agreement {model} {build} {name[6:]}: MISSING", file=sys.stderr)
rounds = len(next(iter(times.values())))
print(f"\nRust (cargo --release) vs Pinocchio C++ builds, {cpu}, {rounds} rounds")
print(f"({', '.join(v for v in (clang_version, gcc_version) if v)})\n")
print("Times: median ns per call over rounds. Ratios: orbitflex / Pinocchio, the median of the "
      "per-round ratios (< 1: orbitflex is faster); 'fastest' is the build with the lowest median.\n")
head = "| model | call | orbitflex | " + " | ".join(builds) + " | fastest | ratio to fastest | " + \
    " | ".join(f"ratio {b}" for b in builds) + " |"
print(head)
print("|---|---|" + "---:|" * (1 + len(builds)) + "---|---:|" + "---:|" * len(builds))
pairs = [("aba", "aba_local", "`aba` (LOCAL)"),
         ("aba", "aba_world", "`aba` (WORLD)"),
         ("rnea", "rnea", "`rnea`"),
         ("crba", "crba_local", "`crba` (LOCAL)"),
         ("rk4_step", "rk4_step", "RK4 step (4 × aba)"),
         ("aba_derivatives", "aba_derivatives", "`computeABADerivatives`"),
         ("rnea_derivatives", "rnea_derivatives", "`computeRNEADerivatives`")]
for model in models:
    for ours, theirs, label in pairs:
        a = med.get((model, "rust", ours))
        bt = {b: med.get((model, b, theirs)) for b in builds}
        if not a or not all(bt.values()):
            continue
        fastest = min(builds, key=lambda b: bt[b])
        cells = " | ".join(f"{bt[b]:.0f}" for b in builds)
        rs = " | ".join(f"{ratio(model, ours, b, theirs):.2f}" for b in builds)
        print(f"| {model} | {label} | {a:.0f} | {cells} | {fastest} | **{ratio(model, ours, fastest, theirs):.2f}** | {rs} |")
print()
for model in models:
    def per_round(side, fd):
        return statistics.median(s / a for s, a in zip(times[(model, side, "rk4_step")], times[(model, side, fd)]))
    if (model, "rust", "rk4_step") in times:
        parts = [f"{per_round('rust', 'aba'):.2f} orbitflex"] + \
            [f"{per_round(b, 'aba_local'):.2f} {b}" for b in builds if (model, b, "rk4_step") in times]
        print(f"{model}: RK4 step / forward dynamics = " + ", ".join(parts) + "  ")
print()
for model in models:
    jac, step = times.get((model, "rust", "step_jacobians")), times.get((model, "rust", "rk4_step"))
    cd = times.get((model, "rust", "step_jacobians_central_differences"))
    if jac and step and cd:
        print(f"{model}: step_jacobians / RK4 step = {statistics.median(j / s for j, s in zip(jac, step)):.1f}; "
              f"central differences / step_jacobians = {statistics.median(c / j for c, j in zip(cd, jac)):.1f}  ")
EOF
