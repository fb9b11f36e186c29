"""Where one call spends its instructions, by part of the algorithm: callgrind's count of every
executed instruction of the program, each attributed through its inlining chain
(`addr2line -i`) to the line of `aba_kernel` (or the flexible-joint function) it came from.

    CARGO_TARGET_DIR=target/prof cargo build --release --example bench_cpp_match \
        --config 'profile.release.package.orbitflex.debug="line-tables-only"'
    python3 benches/step_parts.py target/prof/release/examples/bench_cpp_match \
        models/space_arm.urdf - --only rk4_step --iters 50

Line tables do not change the generated code. As in `benches/flops.py`, the program runs with
`--blocks 1` and `--blocks 3` and the difference is divided by the 2N extra calls. Instructions
that carry no source line (register moves, spills, loop control: about a quarter of the ABA's)
are given to the part of the nearest attributed instruction before them in the same function.
libm's `sincos` is not in the program's own code and is not listed (callgrind_annotate gives it).
The ABA's passes are told apart by the line numbers of `src/algorithms/aba.rs` below; update
`ABA_LINES` when that function moves.
"""
import collections
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import flops
binary = sys.argv[1]; args = sys.argv[2:]
# the last line of each part of aba_kernel in src/algorithms/aba.rs
ABA_LINES = [(75, 'ABA pass 1 (joint transforms, ω, a_i, b_i)'), (77, 'ABA EE wrenches'),
             (98, 'ABA pass 2 (articulated inertias)'), (107, 'ABA base solve'),
             (10**9, 'ABA pass 3 (accelerations)')]
insns = flops.disassembly(binary)
env = dict(os.environ)
c1, bias = flops.executed(binary, insns, args + ['--blocks', '1'], env)
c3, _ = flops.executed(binary, insns, args + ['--blocks', '3'], env)
iters = int(args[args.index('--iters') + 1]); calls = 2 * iters
diff = {a: (c3.get(a, 0) - c1.get(a, 0)) for a in set(c1) | set(c3)}
diff = {a: d for a, d in diff.items() if d}
addrs = sorted(diff)
out = subprocess.run(['addr2line', '-i', '-f', '-C', '-a', '-e', binary], input='\n'.join(hex(a - bias) for a in addrs),
                     capture_output=True, text=True).stdout.splitlines()
chains = {}; cur = None
i = 0
while i < len(out):
    l = out[i]
    if l.startswith('0x'):
        cur = int(l, 16) + bias; chains[cur] = []; i += 1; continue
    fn = l; loc = out[i + 1] if i + 1 < len(out) else '?'; i += 2
    chains[cur].append((fn, loc))
def cat(chain):
    for fn, loc in chain:
        if 'aba_kernel' not in fn:
            continue
        m = re.search(r'([^/]+\.rs):(\d+)', loc); f, ln = (m.group(1), int(m.group(2))) if m else ('?', 0)
        if 'aba_kernel' in fn and f == 'aba.rs':
            for last, part in ABA_LINES:
                if ln <= last:
                    return part
    for fn, loc in chain:
        fn = fn.replace('unchecked', '')
        for key, name in (('base_pose_rate', 'base-pose kinematics'), ('spring_torque', 'Spong spring torques'),
                          ('assemble_derivative', 'assemble ẋ (motor eq., copies)'), ('advance', 'RK4 combination'),
                          ('Rk4::step', 'RK4 combination'), ('state_defect', 'quaternion projection'),
                          ('normalise_quaternion', 'quaternion projection'), ('project', 'quaternion projection'),
                          ('check', 'argument checks'), ('split', 'state split'), ('aba::aba_unchecked', 'ABA dispatch'),
                          ('derivative_unchecked', 'derivative glue'), ('forward_dynamics_unchecked', 'derivative glue'),
                          ('simulate::step', 'step glue')):
            if key in fn: return name
    return 'other: ' + (chain[-1][0][:60] if chain else '?')
tot = collections.Counter()
cats = {a: cat(chains.get(a, [])) for a in addrs}
# instructions without a source line (moves, spills, loop control) go with the nearest
# attributed instruction before them in the same function
prev = None
unattributed = 0
for a in addrs:
    c = cats[a]
    if c.startswith('other: ') and 'aba_unchecked::avx2' in c and prev and prev.startswith('ABA'):
        unattributed += diff[a] / calls
        c = prev
    prev = c if not c.startswith('other') else prev
    tot[c] += diff[a] / calls
print(f"({unattributed:.0f} instructions without a source line given to the pass before them)")
for k, v in sorted(tot.items(), key=lambda kv: -kv[1]):
    if abs(v) >= 1: print(f"{v:9.0f}  {k}")
print(f"{sum(tot.values()):9.0f}  total (program's own code; libm sincos not included)")
