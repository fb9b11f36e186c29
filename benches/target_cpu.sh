#!/usr/bin/env bash
# Does `-C target-cpu` matter? orbitflex's examples/bench_cpp_match built three times, for the
# default x86-64 baseline (what a portable wheel gets), x86-64-v3 (AVX2 + FMA, Haswell/Zen 1 and
# later) and this machine (native), then run alternately (BENCHMARKS.md, "target-cpu").
#
#   bash benches/target_cpu.sh [ROUNDS]          # default 5
#
# Prints the medians over rounds (µs) and the ratio to the baseline build.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
rounds=${1:-5}
target=${CARGO_TARGET_DIR:-$root/target}
out=$target/target_cpu
mkdir -p "$out"
urdf=$out/space_arm.urdf
cp "$root/models/space_arm.urdf" "$urdf"

cpus="x86-64 x86-64-v3 native"
for cpu in $cpus; do
  echo "building bench_cpp_match with -C target-cpu=$cpu" >&2
  (cd "$root" && CARGO_TARGET_DIR=$out/$cpu RUSTFLAGS="-C target-cpu=$cpu" \
    cargo build --quiet --release --example bench_cpp_match)
done

log=$out/log.txt
: >"$log"
for round in $(seq 1 "$rounds"); do
  # rotate the order every round
  set -- $cpus
  order=$(for i in $(seq 0 2); do k=$(( (i + round) % 3 + 1 )); eval echo \$$k; done)
  for cpu in $order; do
    "$out/$cpu/release/examples/bench_cpp_match" "$urdf" - --only aba,rnea,crba,rk4_step --blocks 9 |
      sed "s/^/$round $cpu /" >>"$log"
  done
  echo "round $round/$rounds done" >&2
done

python3 - "$log" "$(lscpu | sed -n 's/^Model name: *//p')" "$rounds" <<'EOF'
import statistics, sys
from collections import defaultdict
log, cpu_name, rounds = sys.argv[1], sys.argv[2], sys.argv[3]
t = defaultdict(dict)  # (cpu, name) -> {round: ns}
for line in open(log):
    parts = line.split()
    if len(parts) == 4:
        try:
            t[(parts[1], parts[2])][parts[0]] = float(parts[3])
        except ValueError:
            pass
cpus = ["x86-64", "x86-64-v3", "native"]
print(f"\norbitflex on the space arm by -C target-cpu ({cpu_name}; median of {rounds} rounds, µs; "
      "in brackets the median of the per-round ratios to the x86-64 baseline)\n")
print("| call | " + " | ".join(cpus) + " |")
print("|---|" + "---:|" * len(cpus))
for name in ("aba", "rnea", "crba", "rk4_step"):
    base = t[("x86-64", name)]
    cells = []
    for cpu in cpus:
        cur = t[(cpu, name)]
        m = statistics.median(cur.values())
        r = statistics.median(cur[k] / base[k] for k in cur if k in base)
        cells.append(f"{m / 1e3:.2f}" + ("" if cpu == "x86-64" else f" ({r:.2f})"))
    print(f"| {name} | " + " | ".join(cells) + " |")
EOF
