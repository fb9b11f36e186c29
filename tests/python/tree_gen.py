"""Seeded random URDF kinematic TREES with awkward features, for checking orbitflex against Pinocchio.

The topology follows spatial_v2's random trees (``autoTree``): the tree bodies are numbered
1, 2, ... and body ``i`` hangs from body ``floor((i - 2 + ceil(bf * u)) / bf)`` (clipped to
``0 .. i-1``), with ``u`` uniform in (0, 1) and ``bf`` a branching factor drawn per tree. Body 0
is the base (the floating spacecraft bus), so several branches leave the base and several leave
the same moving body. One extra body of the tree is carried by a *locked* revolute joint; the
others are the degrees of freedom.

Awkward features (every tree has most of them; ``test_trees.py`` checks that the seeds 0..30
together have all of them):

- joint origins with random rpy (every frame rotated) and random offsets;
- joint axes: random unit vectors written with a non-unit length (both parsers normalise), plus
  some exactly axis-aligned signed ones (Pinocchio's specialised RX/RY/RZ joints);
- full (off-diagonal) inertia tensors in rotated inertial frames with offset COMs;
- fixed "spacer" links with mass in the middle of a branch, sometimes followed by a massless
  frame link (no ``<inertial>``), and then the next moving joints hang from the LAST of them
  (possibly the massless one) while other children may hang from the body's own link;
- a spacer right after the base on some trees;
- a fixed massless ``tcp`` link at the end of every branch (sometimes after a ``tool`` link with
  mass), so the leaf links are the EE links;
- sometimes a fixed ``sensor`` leaf (with mass) on a body that also has children: an EE in the
  middle of a branch;
- a mix of revolute (with limits) and continuous joints (at least one of each);
- a locked revolute joint (``locked_joints``) whose child subtree holds fixed links and
  sometimes further moving joints; the leaves behind it are no default EE;
- the ``<link>`` and ``<joint>`` elements are written in a shuffled order (children before
  parents, siblings in random order), so a loader must sort the tree itself;
- joint and link names carry random labels, so Pinocchio's order (it sorts siblings by joint
  NAME, see below) is unrelated to the file order.

Ordering assumptions (orbitflex's documented convention, computed here from the generator's own
records, not from orbitflex):

- ``joint_names``: the moving (not fixed, not locked) joints in depth-first PRE-order of the link
  tree from the root, the children of a link taken in the order their ``<joint>`` elements
  appear in the file (fixed and locked joints are walked through like any other joint);
- ``parents[i]``: index in ``joint_names`` of the nearest moving joint above joint ``i`` (across
  fixed and locked joints), -1 when that is the base; so ``parents[i] < i``;
- ``link_order``: every link in the same depth-first pre-order;
- ``leaf_links``: the links that are no joint's parent, in ``link_order`` order;
- ``ee_links``: the default EE links, in ``link_order`` order: the leaves not behind a locked
  joint, and each link that carries a locked joint with no such leaf below it (the hand of an
  arm whose gripper is locked); a URDF with one leaf has that leaf.

Pinocchio (observed with 4.1, through urdfdom) does NOT use the file order: it walks the tree depth-first with
the children of a link sorted by joint NAME (urdfdom keeps joints in a std::map). Its
``model.names`` order therefore differs in general; compare by joint name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from urdf_gen import _f, _inertial, _joint, _link, _random_rpy, _vec, random_rotation, rpy_to_matrix

__all__ = ["RandomTree", "JointRecord", "random_tree", "branch_tree", "tree_order", "random_rotation", "rpy_to_matrix"]

MIN_DOF, MAX_DOF = 4, 14


@dataclass
class RandomTree:
    """A generated URDF tree and what a test needs to know about it (see the module docstring
    for the ordering conventions)."""

    name: str
    xml: str
    joint_names: List[str]  # moving joints, orbitflex order (depth-first pre-order, file order)
    parents: List[int]  # parent joint index of each joint, -1 for the base
    ee_links: List[str]  # default EE links (module docstring), pre-order
    locked_joints: List[str] = field(default_factory=list)
    leaf_links: List[str] = field(default_factory=list)  # every leaf link, pre-order
    link_order: List[str] = field(default_factory=list)  # every link, pre-order
    continuous: List[bool] = field(default_factory=list)  # per joint_names entry
    seed: Optional[int] = None

    @property
    def dof(self) -> int:
        return len(self.joint_names)


# ------------------------------------------------------------------------------------ ordering


@dataclass
class JointRecord:
    """One joint record, as written to the file."""

    name: str
    kind: str  # revolute | continuous | fixed
    parent: str
    child: str


def tree_order(links: List[str], joints: List[JointRecord], locked: List[str]) -> Tuple[List[str], List[str], List[int], List[str], List[str]]:
    """``(link_order, joint_names, parents, leaf_links, ee_links)`` of a URDF given by its link
    names and its joints IN FILE ORDER (see the module docstring for the convention)."""
    locked_set = set(locked)
    children: Dict[str, List[JointRecord]] = {}
    has_parent = set()
    for j in joints:
        children.setdefault(j.parent, []).append(j)
        has_parent.add(j.child)
    (root,) = [l for l in links if l not in has_parent]
    link_order: List[str] = []
    joint_names: List[str] = []
    parents: List[int] = []
    behind_lock = set()

    def visit(link: str, carrier: int, behind: bool) -> None:
        """Pre-order: the link, then each child joint's subtree in file order. ``carrier`` is the
        index of the moving joint whose body the link belongs to (-1: the base)."""
        link_order.append(link)
        if behind:
            behind_lock.add(link)
        for j in children.get(link, []):
            child_carrier = carrier
            if j.kind != "fixed" and j.name not in locked_set:
                joint_names.append(j.name)
                parents.append(carrier)
                child_carrier = len(joint_names) - 1
            visit(j.child, child_carrier, behind or j.name in locked_set)

    visit(root, -1, False)
    leaf_links = [l for l in link_order if l not in children]
    free = {l for l in leaf_links if l not in behind_lock}

    def free_below(link: str) -> bool:
        return link in free or any(free_below(j.child) for j in children.get(link, []))

    # a link carrying a locked joint, not itself behind a lock, with no free leaf below it (the
    # hand of an arm whose gripper is locked) is an end-effector in place of the locked leaves
    carriers = {l for l in link_order
                if l not in behind_lock and not free_below(l)
                and any(j.name in locked_set for j in children.get(l, []))}
    if len(leaf_links) == 1:
        ee_links = list(leaf_links)
    else:
        ee_links = [l for l in link_order if l in free or l in carriers] or list(leaf_links)
    return link_order, joint_names, parents, leaf_links, ee_links


# ------------------------------------------------------------------------------------ generator


def _axis(rng: np.random.Generator) -> np.ndarray:
    """A joint axis: a quarter of them signed and axis-aligned, the rest a random direction
    written with a non-unit length (as urdf_gen does)."""
    if rng.random() < 0.25:
        axis = np.zeros(3)
        axis[int(rng.integers(3))] = rng.choice([-1.0, 1.0])
        return axis
    u = rng.normal(size=3)
    return u / np.linalg.norm(u) * float(rng.choice([2.5, 0.3, 1.7]))


def _topology(rng: np.random.Generator, m: int) -> List[int]:
    """spatial_v2-style random parents of tree bodies 1..m (0 = base): ``parent[i] < i``."""
    bf = float(rng.uniform(1.4, 3.0))  # branching factor of this tree
    parent = [-1]  # entry 0 is the base itself
    for i in range(1, m + 1):
        u = float(rng.uniform(1e-9, 1.0))
        p = math.floor((i - 2 + math.ceil(bf * u)) / bf)
        parent.append(min(max(p, 0), i - 1))
    if m >= 3 and rng.random() < 0.6:
        parent[2] = 0  # a second branch straight from the base
    return parent


def random_tree(seed: int, dof: Optional[int] = None) -> RandomTree:
    """A random tree (see the module docstring), reproducible from ``seed``; ``dof`` (4..14)
    moving joints, plus one locked revolute joint."""
    rng = np.random.default_rng(seed)
    n = int(dof if dof is not None else rng.integers(MIN_DOF, MAX_DOF + 1))
    if not MIN_DOF <= n <= MAX_DOF:
        raise ValueError(f"random_tree: dof must be in {MIN_DOF}..{MAX_DOF}, got {n}")
    m = n + 1  # tree bodies: n moving + 1 locked

    # Topology and which body is locked. Redraw (same rng, so still reproducible) until at least
    # two leaves are not behind the locked joint and the tree really branches.
    for _ in range(1000):
        parent = _topology(rng, m)
        locked_body = int(rng.integers(2, m + 1))
        kids = {b: [c for c in range(1, m + 1) if parent[c] == b] for b in range(m + 1)}
        leaves = [b for b in range(1, m + 1) if not kids[b]]

        def behind(b: int) -> bool:
            while b > 0:
                if b == locked_body:
                    return True
                b = parent[b]
            return False

        if len([b for b in leaves if not behind(b)]) >= 2:
            break
    else:  # pragma: no cover - never reached for the seeds used
        raise RuntimeError("random_tree: no suitable topology")

    kinds = {b: ("revolute" if rng.random() < 0.5 else "continuous") for b in range(1, m + 1)}
    kinds[locked_body] = "revolute"
    moving = [b for b in range(1, m + 1) if b != locked_body]
    b_rev, b_cont = rng.choice(moving, size=2, replace=False)
    kinds[int(b_rev)], kinds[int(b_cont)] = "revolute", "continuous"

    # Random labels: names unrelated to the structure (and to Pinocchio's name order).
    label = {b: int(x) for b, x in zip(range(1, m + 1), rng.permutation(np.arange(10, 10 + m)))}
    body_link = {0: "base", **{b: f"link{label[b]}" for b in range(1, m + 1)}}
    body_joint = {b: f"j{label[b]}" for b in range(1, m + 1)}

    links: List[Tuple[str, str]] = []  # (name, xml)
    joints: List[Tuple[JointRecord, str]] = []  # (record, xml)

    def add_link(name: str, inertial: str = "") -> None:
        links.append((name, _link(name, inertial)))

    def add_fixed(name: str, parent_link: str, child: str, spread: float) -> None:
        rec = JointRecord(name, "fixed", parent_link, child)
        joints.append((rec, _joint(name, "fixed", parent_link, child,
                                   rng.uniform(-spread, spread, 3), _random_rpy(rng))))

    add_link("base", _inertial(rng, float(rng.uniform(20.0, 200.0)), 1.0))

    # Spacers: fixed links with mass after a body (the base too), the second of a pair massless.
    # The body's first child (body or tool) hangs from the last spacer, so spacers are mid-branch.
    n_spacers = {b: 0 for b in range(m + 1)}
    for b in range(m + 1):
        if rng.random() < 0.35:
            n_spacers[b] = 1 + int(rng.random() < 0.5)
    if not any(n_spacers.values()):
        n_spacers[int(rng.integers(0, m + 1))] = 2
    if not any(v == 2 for v in n_spacers.values()):
        n_spacers[max(n_spacers, key=n_spacers.get)] = 2  # at least one massless frame link
    end_link = {}
    for b in range(m + 1):
        last = body_link[b]
        for k in range(n_spacers[b]):
            name = f"spacer{label.get(b, 0)}_{k}"
            add_link(name, _inertial(rng, float(rng.uniform(0.2, 2.0)), 0.2) if k == 0 else "")
            add_fixed(f"fix{label.get(b, 0)}_{k}", last, name, 0.3)
            last = name
        end_link[b] = last

    # Moving (and the locked) joints: the first child of a body hangs from its end link, the others
    # from the end link or the body's own link at random (two branches leaving the same link).
    for b in range(1, m + 1):
        p = parent[b]
        siblings_before = [c for c in range(1, b) if parent[c] == p]
        at = end_link[p] if not siblings_before or rng.random() < 0.5 else body_link[p]
        add_link(body_link[b], _inertial(rng, float(rng.uniform(0.5, 8.0)), 0.5))
        rec = JointRecord(body_joint[b], kinds[b], at, body_link[b])
        joints.append((rec, _joint(rec.name, rec.kind, at, rec.child,
                                   rng.uniform(-0.6, 0.6, 3), _random_rpy(rng), _axis(rng))))

    # Leaf bodies end in a massless tcp (after a tool with mass half of the time).
    for b in range(1, m + 1):
        if any(parent[c] == b for c in range(1, m + 1)):
            continue
        at = end_link[b]
        if rng.random() < 0.5:
            add_link(f"tool{label[b]}", _inertial(rng, float(rng.uniform(0.2, 3.0)), 0.2))
            add_fixed(f"tool{label[b]}_mount", at, f"tool{label[b]}", 0.3)
            at = f"tool{label[b]}"
        add_link(f"tcp{label[b]}")
        add_fixed(f"tcp{label[b]}_mount", at, f"tcp{label[b]}", 0.3)

    # Half of the trees get a sensor leaf (with mass) on a moving body that has children.
    inner = [b for b in range(1, m + 1) if b != locked_body and any(parent[c] == b for c in range(1, m + 1))]
    if inner and rng.random() < 0.5:
        b = int(rng.choice(inner))
        add_link("sensor", _inertial(rng, float(rng.uniform(0.1, 1.0)), 0.1))
        add_fixed("sensor_mount", body_link[b], "sensor", 0.2)

    # Shuffle the element order (links and joints mixed).
    parts = [x for _, x in links] + [x for _, x in joints]
    order = rng.permutation(len(parts))
    body = "".join(parts[i] for i in order)
    name = f"random_tree_{seed}"
    xml = f'<?xml version="1.0"?>\n<robot name="{name}">\n{body}</robot>\n'

    # Bookkeeping from the records in the order they were written.
    n_links = len(links)
    joint_file_order = [joints[i - n_links][0] for i in order if i >= n_links]
    locked = [body_joint[locked_body]]
    link_order, joint_names, parents, leaf_links, ee_links = tree_order(
        [l for l, _ in links], joint_file_order, locked
    )
    kind_of = {rec.name: rec.kind for rec, _ in joints}
    return RandomTree(
        name=f"tree{seed}",
        xml=xml,
        joint_names=joint_names,
        parents=parents,
        ee_links=ee_links,
        locked_joints=locked,
        leaf_links=leaf_links,
        link_order=link_order,
        continuous=[kind_of[j] == "continuous" for j in joint_names],
        seed=seed,
    )


def branch_tree() -> RandomTree:
    """The plain ``branch`` case: base -> j1 -> link1, and two branches leaving link1 (joints
    ``ja1 -> ja2`` and ``jb1 -> jb2``), each ending in a massless fixed ``tip`` link. Unit axes,
    unrotated origins and diagonal inertias, written parent before child: easy to debug by hand."""

    def inertial(mass: float, com, diag) -> str:
        return (
            "    <inertial>\n"
            f'      <origin xyz="{_vec(com)}" rpy="0 0 0"/>\n'
            f'      <mass value="{_f(mass)}"/>\n'
            f'      <inertia ixx="{_f(diag[0])}" ixy="0" ixz="0" iyy="{_f(diag[1])}" iyz="0" izz="{_f(diag[2])}"/>\n'
            "    </inertial>\n"
        )

    def joint(name, kind, parent, child, xyz, axis=None) -> str:
        return _joint(name, kind, parent, child, xyz, (0.0, 0.0, 0.0), axis)

    parts = [
        _link("base", inertial(50.0, (0.0, 0.0, 0.0), (4.0, 5.0, 6.0))),
        _link("link1", inertial(3.0, (0.0, 0.0, 0.15), (0.03, 0.03, 0.01))),
        joint("j1", "revolute", "base", "link1", (0.0, 0.0, 0.5), (0.0, 0.0, 1.0)),
        _link("linka1", inertial(2.0, (0.2, 0.0, 0.0), (0.01, 0.02, 0.02))),
        joint("ja1", "revolute", "link1", "linka1", (0.1, 0.0, 0.3), (0.0, 1.0, 0.0)),
        _link("linka2", inertial(1.5, (0.15, 0.0, 0.0), (0.01, 0.015, 0.015))),
        joint("ja2", "continuous", "linka1", "linka2", (0.4, 0.0, 0.0), (1.0, 0.0, 0.0)),
        _link("tipa"),
        joint("tipa_mount", "fixed", "linka2", "tipa", (0.3, 0.0, 0.0)),
        _link("linkb1", inertial(2.0, (-0.2, 0.0, 0.0), (0.01, 0.02, 0.02))),
        joint("jb1", "revolute", "link1", "linkb1", (-0.1, 0.0, 0.3), (0.0, 1.0, 0.0)),
        _link("linkb2", inertial(1.5, (-0.15, 0.0, 0.0), (0.01, 0.015, 0.015))),
        joint("jb2", "revolute", "linkb1", "linkb2", (-0.4, 0.0, 0.0), (0.0, 0.0, 1.0)),
        _link("tipb"),
        joint("tipb_mount", "fixed", "linkb2", "tipb", (-0.3, 0.0, 0.0)),
    ]
    xml = '<?xml version="1.0"?>\n<robot name="branch">\n' + "".join(parts) + "</robot>\n"
    return RandomTree(
        name="branch",
        xml=xml,
        joint_names=["j1", "ja1", "ja2", "jb1", "jb2"],
        parents=[-1, 0, 1, 0, 3],
        ee_links=["tipa", "tipb"],
        locked_joints=[],
        leaf_links=["tipa", "tipb"],
        link_order=["base", "link1", "linka1", "linka2", "tipa", "linkb1", "linkb2", "tipb"],
        continuous=[False, False, True, False, False],
        seed=None,
    )


if __name__ == "__main__":  # pragma: no cover - manual inspection
    import sys

    print(random_tree(int(sys.argv[1]) if len(sys.argv) > 1 else 0).xml)
