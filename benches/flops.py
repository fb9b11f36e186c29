"""Floating-point operations per call of orbitflex's `aba`, `rnea` and `crba`, counted by
executing them: the multiplications and additions (with subtractions) that the processor
retires, not an estimate from the source.

    cargo build --release --example bench_cpp_match
    python3 benches/flops.py [--bin target/release/examples/bench_cpp_match] [--iters 50]

Method. `bench_cpp_match` runs under `valgrind --tool=callgrind --dump-instr=yes` with the
portable (baseline x86-64, SSE2) code path (`ORBITFLEX_PORTABLE=1`), once with `--blocks 1` and
once with `--blocks 3` for one function (`--only NAME --iters N`); the difference of the two runs
is 2N calls of that function and nothing else, so loading, parsing and warm-up cancel (the method
of `benches/pinocchio_cpp/callgrind.sh`). Every executed instruction of the program's own code
is then classified with `objdump`: `mulsd`/`divsd` count one multiplication, `mulpd`/`divpd` two
(both lanes; an unused lane would still count, so this is an upper bound), `addsd`/`subsd` one
addition and `addpd`/`subpd` two, `sqrtsd` one multiplication. Sign flips (`xorpd`), absolute
values, comparisons and moves are not arithmetic and are not counted. libm's `sincos` is left
out (it runs in libm's own object), as the operation counts of Featherstone's book leave out
each revolute joint's sine and cosine.

The models are the seeded random chains of `benches/pinocchio_cpp/chain_urdf.py` (general
link geometry and axes, every joint but the first tilted), so the cost per joint is the slope
`(ops(n₂) − ops(n₁)) / (n₂ − n₁)`, which also removes the floating base's fixed cost.
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
from collections import Counter

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

MUL = {"mulsd": 1, "divsd": 1, "sqrtsd": 1, "mulpd": 2, "divpd": 2, "sqrtpd": 2}
ADD = {"addsd": 1, "subsd": 1, "addpd": 2, "subpd": 2, "addsubpd": 2, "haddpd": 2, "hsubpd": 2}
# AVX spellings (should the AVX2 copy run): the same operations on xmm or, doubled, ymm
for table in (MUL, ADD):
    for name in list(table):
        table["v" + name] = table[name]


def disassembly(binary):
    """{file address: mnemonic} of every instruction of `binary`."""
    out = subprocess.run(["objdump", "-d", "--no-show-raw-insn", binary],
                         capture_output=True, text=True, check=True).stdout
    insns = {}
    for line in out.splitlines():
        m = re.match(r"^\s+([0-9a-f]+):\t(\S+)\s*(.*)$", line)
        if m:
            insns[int(m.group(1), 16)] = (m.group(2), m.group(3))
    return insns


def executed(binary, insns, args, env):
    """{runtime address: times executed} of the binary's own instructions, and the load bias."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "cg.out")
        log = subprocess.run(
            ["valgrind", "--tool=callgrind", "--dump-instr=yes", "--dump-line=no",
             "--compress-strings=no", "--compress-pos=no", f"--callgrind-out-file={out}",
             binary, *args],
            capture_output=True, text=True, env=env)
        if log.returncode != 0:
            sys.exit(f"valgrind failed:\n{log.stderr[-2000:]}")
        name = os.path.realpath(binary)
        counts = Counter()
        ours = skip = False
        with open(out) as f:
            for line in f:
                if line.startswith("ob="):
                    ours = os.path.realpath(line[3:].strip()) == name
                elif line.startswith("calls="):
                    skip = True  # the next cost line is the call's inclusive cost
                elif line.startswith("0x"):
                    if skip:
                        skip = False
                        continue
                    if ours:
                        addr, cost = line.split()[:2]
                        counts[int(addr, 16)] += int(cost)
        # callgrind names the main program's instructions by file address or, for some
        # versions, by load address (0x108000 for a position-independent executable)
        bias = max((0, 0x108000), key=lambda b: sum(1 for addr in counts if addr - b in insns))
        known = sum(1 for addr in counts if addr - bias in insns)
        if known < 0.99 * len(counts):
            sys.exit(f"only {known} of {len(counts)} executed addresses are instructions of {binary}")
        return counts, bias


def flops(binary, insns, args, env):
    """(multiplications, additions, of which in packed instructions) executed by the run."""
    counts, bias = executed(binary, insns, args, env)
    mul = add = packed = 0
    for addr, times in counts.items():
        mnemonic, operands = insns.get(addr - bias, ("", ""))
        wide = 2 if "ymm" in operands else 1
        m, a = MUL.get(mnemonic, 0) * wide, ADD.get(mnemonic, 0) * wide
        mul += times * m
        add += times * a
        if mnemonic.endswith("pd"):
            packed += times * (m + a)
    return mul, add, packed


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--bin", default=os.path.join(ROOT, "target/release/examples/bench_cpp_match"))
    parser.add_argument("--iters", type=int, default=50)
    parser.add_argument("--sizes", default="7,28", help="chain lengths (comma-separated)")
    parser.add_argument("--calls", default="aba,rnea,crba")
    parser.add_argument("--avx2", action="store_true", help="count the AVX2 copy instead")
    a = parser.parse_args()
    env = dict(os.environ)
    if not a.avx2:
        env["ORBITFLEX_PORTABLE"] = "1"
    insns = disassembly(a.bin)
    sizes = [int(s) for s in a.sizes.split(",")]
    result = {}
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            urdf = os.path.join(tmp, f"chain{n}.urdf")
            with open(urdf, "w") as f:
                f.write(subprocess.run([sys.executable, os.path.join(HERE, "pinocchio_cpp/chain_urdf.py"), str(n)],
                                       capture_output=True, text=True, check=True).stdout)
            for call in a.calls.split(","):
                common = [urdf, f"link{n}", "--only", call, "--iters", str(a.iters)]
                m1, a1, p1 = flops(a.bin, insns, common + ["--blocks", "1"], env)
                m3, a3, p3 = flops(a.bin, insns, common + ["--blocks", "3"], env)
                calls = 2 * a.iters
                result[(call, n)] = ((m3 - m1) / calls, (a3 - a1) / calls, (p3 - p1) / calls)
                m, ad, p = result[(call, n)]
                print(f"{call} n={n}: {m:.0f} mul + {ad:.0f} add = {m + ad:.0f} per call, "
                      f"{p:.0f} of them in packed instructions", file=sys.stderr)
    print("\n| call | " + " | ".join(f"n = {n}: m + a" for n in sizes) +
          " | per joint (slope): m + a | of which in packed instructions |")
    print("|---|" + "---:|" * (len(sizes) + 2))
    for call in a.calls.split(","):
        cells = " | ".join(f"{result[(call, n)][0]:.0f} + {result[(call, n)][1]:.0f}" for n in sizes)
        (m1, a1, p1), (m2, a2, p2) = result[(call, sizes[0])], result[(call, sizes[-1])]
        dn = sizes[-1] - sizes[0]
        slope = f"{(m2 - m1) / dn:.1f} + {(a2 - a1) / dn:.1f} = {(m2 - m1 + a2 - a1) / dn:.1f}"
        print(f"| `{call}` | {cells} | {slope} | {(p2 - p1) / dn:.1f} |")


if __name__ == "__main__":
    main()
