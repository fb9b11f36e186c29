"""Seeded random URDF chains with awkward features, for checking orbitflex against Pinocchio.

Each chain has
- joint origins with random rpy (every frame rotated) and random offsets;
- joint axes that are random unit vectors written scaled by a non-unit factor (orbitflex and
  Pinocchio both normalise), plus some exactly axis-aligned ones (signed), which Pinocchio
  turns into its specialised RX/RY/RZ joints;
- inertial frames with random rpy and a full (off-diagonal) inertia tensor in that frame;
- fixed joints in the middle of the chain (a mass-carrying "spacer" link, sometimes two in a
  row, sometimes right after the base), a massless frame link without an ``<inertial>``;
- a fixed EE link at the end (with mass) and a massless tool-centre-point link under it, which
  is the EE link;
- a fixed sensor link (with mass) branching off a link in the middle of the chain, so the tree
  has two leaves and ``ee_link`` must be named;
- a mix of revolute (with limits) and continuous joints (at least one of each).

Inertias are physically valid: principal moments of a solid ellipsoid (positive definite and
strictly satisfying the triangle inequality), rotated by a random rotation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List

import numpy as np

__all__ = ["RandomChain", "random_chain", "random_rotation", "rpy_to_matrix"]


def rpy_to_matrix(rpy) -> np.ndarray:
    """URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation matrix (QR of a Gaussian matrix, sign-fixed)."""
    a = rng.normal(size=(3, 3))
    qm, rm = np.linalg.qr(a)
    qm = qm @ np.diag(np.sign(np.diag(rm)))
    if np.linalg.det(qm) < 0:
        qm[:, 0] *= -1
    return qm


def _f(x: float) -> str:
    # repr keeps every bit, so both parsers read identical doubles.
    return repr(float(x))


def _vec(v) -> str:
    return " ".join(_f(x) for x in v)


def _random_rpy(rng: np.random.Generator) -> np.ndarray:
    # Any rpy is valid URDF; pitch stays off ±π/2 so the angles round-trip if printed back.
    return np.array([rng.uniform(-np.pi, np.pi), rng.uniform(-1.5, 1.5), rng.uniform(-np.pi, np.pi)])


def _inertial(rng: np.random.Generator, mass: float, size: float) -> str:
    """An ``<inertial>`` with a random COM frame and a full inertia tensor in that frame."""
    a, b, c = rng.uniform(0.2, 1.0, size=3) * size
    principal = mass / 5.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    rot = random_rotation(rng)
    inertia = rot @ np.diag(principal) @ rot.T
    com = rng.uniform(-0.5, 0.5, size=3) * size
    rpy = _random_rpy(rng)
    return (
        "    <inertial>\n"
        f'      <origin xyz="{_vec(com)}" rpy="{_vec(rpy)}"/>\n'
        f'      <mass value="{_f(mass)}"/>\n'
        f'      <inertia ixx="{_f(inertia[0, 0])}" ixy="{_f(inertia[0, 1])}" '
        f'ixz="{_f(inertia[0, 2])}" iyy="{_f(inertia[1, 1])}" iyz="{_f(inertia[1, 2])}" '
        f'izz="{_f(inertia[2, 2])}"/>\n'
        "    </inertial>\n"
    )


def _link(name: str, inertial: str = "") -> str:
    return f'  <link name="{name}">\n{inertial}  </link>\n'


def _joint(name, kind, parent, child, xyz, rpy, axis=None) -> str:
    s = f'  <joint name="{name}" type="{kind}">\n'
    s += f'    <parent link="{parent}"/>\n    <child link="{child}"/>\n'
    s += f'    <origin xyz="{_vec(xyz)}" rpy="{_vec(rpy)}"/>\n'
    if axis is not None:
        s += f'    <axis xyz="{_vec(axis)}"/>\n'
    if kind == "revolute":
        s += '    <limit lower="-3.0" upper="3.0" effort="100" velocity="10"/>\n'
    s += "  </joint>\n"
    return s


@dataclass
class RandomChain:
    """A generated URDF and what a test needs to know about it."""

    seed: int
    xml: str
    ee_link: str
    joint_names: List[str]
    continuous: List[bool]
    base_link: str = "base"
    fixed_links: List[str] = field(default_factory=list)

    @property
    def dof(self) -> int:
        return len(self.joint_names)


def random_chain(seed: int, dof: int | None = None) -> RandomChain:
    """A random serial chain (see the module docstring), reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    n = int(dof if dof is not None else rng.integers(3, 8))
    if n < 3:
        raise ValueError("random_chain needs dof >= 3")
    kinds = ["revolute" if rng.random() < 0.5 else "continuous" for _ in range(n)]
    i_rev, i_cont = rng.choice(n, size=2, replace=False)
    kinds[int(i_rev)], kinds[int(i_cont)] = "revolute", "continuous"

    # Which links get fixed spacers after them (index -1 = the base), and where the sensor hangs.
    spacer_after = set(int(i) for i in rng.choice(np.arange(-1, n - 1), size=min(2, n), replace=False))
    double_spacer = int(rng.choice(sorted(spacer_after)))
    sensor_on = int(rng.integers(1, n))  # a moving link in the middle (not the last one)

    parts: List[str] = []
    fixed_links: List[str] = []
    base_mass = float(rng.uniform(20.0, 200.0))
    parts.append(_link("base", _inertial(rng, base_mass, 1.0)))

    def spacers(parent: str, tag: str) -> str:
        """Fixed links hung in series after ``parent``; returns the last one."""
        count = 2 if int(tag) == double_spacer else 1
        for k in range(count):
            name = f"spacer{tag}_{k}"
            fixed_links.append(name)
            # The second spacer of a pair is a massless frame without <inertial>.
            inertial = _inertial(rng, float(rng.uniform(0.2, 2.0)), 0.2) if k == 0 else ""
            parts.append(_link(name, inertial))
            parts.append(
                _joint(f"fix{tag}_{k}", "fixed", parent, name,
                       rng.uniform(-0.3, 0.3, 3), _random_rpy(rng))
            )
            parent = name
        return parent

    parent = "base"
    if -1 in spacer_after:
        parent = spacers(parent, "-1")
    joint_names = []
    for i in range(n):
        child = f"link{i + 1}"
        jname = f"j{i + 1}"
        joint_names.append(jname)
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        style = rng.random()
        if style < 0.25:
            # Exactly axis-aligned, signed (Pinocchio's specialised joints).
            axis = np.zeros(3)
            axis[int(rng.integers(3))] = rng.choice([-1.0, 1.0])
        else:
            # Unit direction written with a non-unit length.
            axis = u * float(rng.choice([2.5, 0.3, 1.7]))
        parts.append(_link(child, _inertial(rng, float(rng.uniform(0.5, 8.0)), 0.5)))
        parts.append(
            _joint(jname, kinds[i], parent, child, rng.uniform(-0.6, 0.6, 3), _random_rpy(rng), axis)
        )
        parent = child
        if i + 1 == sensor_on:
            fixed_links.append("sensor")
            parts.append(_link("sensor", _inertial(rng, float(rng.uniform(0.1, 1.0)), 0.1)))
            parts.append(
                _joint("sensor_mount", "fixed", child, "sensor", rng.uniform(-0.2, 0.2, 3), _random_rpy(rng))
            )
        if i in spacer_after and i < n - 1:
            parent = spacers(parent, str(i))

    # Fixed EE: a tool with mass, then a massless TCP frame (the EE link).
    fixed_links += ["tool", "tcp"]
    parts.append(_link("tool", _inertial(rng, float(rng.uniform(0.2, 3.0)), 0.2)))
    parts.append(_joint("tool_mount", "fixed", parent, "tool", rng.uniform(-0.3, 0.3, 3), _random_rpy(rng)))
    parts.append(_link("tcp"))
    parts.append(_joint("tcp_mount", "fixed", "tool", "tcp", rng.uniform(-0.3, 0.3, 3), _random_rpy(rng)))

    # Shuffle element order: URDF order must not matter to either parser.
    order = rng.permutation(len(parts))
    body = "".join(parts[i] for i in order)
    xml = f'<?xml version="1.0"?>\n<robot name="random_chain_{seed}">\n{body}</robot>\n'
    return RandomChain(
        seed=seed,
        xml=xml,
        ee_link="tcp",
        joint_names=joint_names,
        continuous=[k == "continuous" for k in kinds],
        fixed_links=fixed_links,
    )


if __name__ == "__main__":  # pragma: no cover - manual inspection
    import sys

    print(random_chain(int(sys.argv[1]) if len(sys.argv) > 1 else 0).xml)
