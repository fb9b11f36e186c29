"""A seeded random serial chain as URDF, for timing forward dynamics against n.

    python3 benches/pinocchio_cpp/chain_urdf.py N [SEED] > chain.urdf

Links 0.2-0.5 m apart with a general roll-pitch-yaw at every joint origin, unit axes in random
directions, masses 1-5 kg with rotated principal inertias and offset centres of mass; the EE
link is `link{N}`. Both orbitflex and Pinocchio load the same file (run.sh's harnesses take any
URDF: `bench_cpp_match chain.urdf link{N}`, `bench_aba_<build> chain.urdf link{N}`).
"""
import sys

import numpy as np


def chain(n: int, seed: int = 1) -> str:
    rng = np.random.default_rng(seed)
    out = ['<robot name="chain_%d">' % n]

    def link(name: str, mass: float) -> None:
        c = rng.uniform(-0.1, 0.1, 3)
        a, b = rng.uniform(0.02, 0.2, 2)
        i = np.array([a, b, rng.uniform(abs(a - b) + 0.01, a + b)]) * mass
        out.append(
            f'<link name="{name}"><inertial><origin xyz="{c[0]} {c[1]} {c[2]}" '
            f'rpy="{rng.uniform(-3, 3)} {rng.uniform(-1.5, 1.5)} {rng.uniform(-3, 3)}"/>'
            f'<mass value="{mass}"/><inertia ixx="{i[0]}" ixy="0" ixz="0" iyy="{i[1]}" iyz="0" '
            f'izz="{i[2]}"/></inertial></link>'
        )

    link("base", 50.0)
    for k in range(1, n + 1):
        link(f"link{k}", rng.uniform(1.0, 5.0))
        xyz = rng.normal(size=3)
        xyz *= rng.uniform(0.2, 0.5) / np.linalg.norm(xyz)
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        rpy = rng.uniform(-3, 3, 3)
        out.append(
            f'<joint name="joint{k}" type="revolute"><parent link="{"base" if k == 1 else f"link{k - 1}"}"/>'
            f'<child link="link{k}"/><origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" '
            f'rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/><axis xyz="{axis[0]} {axis[1]} {axis[2]}"/>'
            f'<limit lower="-3" upper="3" effort="100" velocity="2"/></joint>'
        )
    out.append("</robot>")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    sys.stdout.write(chain(int(sys.argv[1]), int(sys.argv[2]) if len(sys.argv) > 2 else 1))
