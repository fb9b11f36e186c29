"""orbitflex on kinematic TREES (several branches, several end-effectors) against Pinocchio.

Cases: seeded random trees from tree_gen.py (shuffled URDF element order, locked joint with a
subtree, spacers, massless frames, ...), the plain ``branch`` tree, and three branched robots of
example-robot-data:

- ``solo12``  (quadruped): nothing locked, 12 dof, 4 EEs (the feet, the default leaves);
- ``baxter``  (dual arm + head pan): the 4 PRISMATIC gripper finger joints are locked
  (orbitflex moves only revolute/continuous joints), 15 dof, 25 EEs (every leaf not behind a
  locked finger joint: sensors, cameras, visual frames, pedestal, the two gripper frames);
- ``talos``   (talos_reduced.urdf, humanoid): the two revolute gripper joints are locked (their
  fingers are written as fixed mimic joints in this file; the gripper is "a tool"), 30 dof, and
  ``ee_links`` given explicitly: both gripper base links, the left gripper's motor link that sits
  BEHIND its locked joint, and both soles (5 EEs).

Rejected: anymal (b) and allegro hand load in Pinocchio but orbitflex rejects their inertias
(triangle inequality violated in the file).

Conventions (docs/model.md, pin_helpers.py): free-flyer root, zero gravity, base twist
``[ω; v]`` in the base frame, classical base acceleration, wrenches ``[moment; force]``. Every EE
wrench is exerted BY that EE on its environment, in its EE frame; in Pinocchio the body feels
``-f`` at the EE frame, moved to the frame's parent joint and SUMMED over all EEs.

Ordering assumptions (the API under test; see tree_gen.py's docstring):

- ``robot.joint_names``: moving joints in depth-first pre-order of the link tree, children in
  the order of their ``<joint>`` elements in the file; ``robot.parents[i]`` is the index of the
  nearest moving joint above joint ``i``, -1 for the base.
- ``robot.ee_links``: when not given, every leaf link not behind a locked joint, in the same
  depth-first pre-order; when given, the given list (these tests always give it already in
  pre-order, so they do not depend on whether orbitflex keeps or sorts a given list).
- a ``(k, 6)`` ``ee_wrench`` has one row per EE in ``robot.ee_links`` order; the derivatives'
  ``"ee_wrench"`` blocks are ``(6+n, 6k)``, columns ``6e..6e+6`` for EE ``e``.

Only the model test (``test_model``) depends on the ordering assumptions. The numerical tests map
orbitflex's joints and EEs to Pinocchio BY NAME (``robot.joint_names``, ``robot.ee_links``), so
a different but self-consistent order would not fail them. Pinocchio itself orders the children
of a link by joint NAME (urdfdom's std::map), not by file order.

Agreement is ``‖orbitflex − pinocchio‖ / max(1, ‖pinocchio‖) ≤ 1e-9``.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
import zlib
from dataclasses import dataclass, field
from typing import Dict, List, Optional

import numpy as np
import pinocchio as pin
import pytest

import orbitflex
from pin_helpers import (
    PinRobot,
    aba_derivatives,
    random_quaternion,
    rel_err,
    rnea_derivatives,
    robots_dir,
)
from tree_gen import JointRecord, RandomTree, branch_tree, random_tree, tree_order

TOL = 1e-9
METHODS = ["recursive", "operator"]
STATES = 2  # random states per case and test

GENERATOR_SEEDS = list(range(31))  # checked against Pinocchio without orbitflex
TREE_SEEDS = list(range(8))  # compared with orbitflex


# ===================================================================================== cases


@dataclass
class TreeCase:
    """One tree: how to load it, and what the model should be (computed without orbitflex)."""

    name: str
    path: Optional[str] = None
    xml: Optional[str] = None
    ee_links_arg: Optional[List[str]] = None  # passed as ee_links= (None: the default)
    locked_joints: List[str] = field(default_factory=list)
    # Expected model (orbitflex's documented order, see the module docstring):
    joint_names: List[str] = field(default_factory=list)
    parents: List[int] = field(default_factory=list)
    ee_links: List[str] = field(default_factory=list)
    leaf_links: List[str] = field(default_factory=list)

    def text(self) -> str:
        if self.xml is not None:
            return self.xml
        with open(self.path) as fh:
            return fh.read()

    def rng(self, salt: str = "") -> np.random.Generator:
        return np.random.default_rng(zlib.crc32((self.name + salt).encode()))


def parse_urdf(text: str, locked: List[str]):
    """``tree_order`` of a URDF text read with ElementTree (independently of the generator's
    own records): ``(link_order, joint_names, parents, leaf_links, ee_links)``."""
    root = ET.fromstring(text)
    links = [l.get("name") for l in root.findall("link")]
    joints = [
        JointRecord(j.get("name"), j.get("type"), j.find("parent").get("link"), j.find("child").get("link"))
        for j in root.findall("joint")
    ]
    return tree_order(links, joints, locked)


def _generated_case(tree: RandomTree, ee_links_arg=None, ee_links=None, path=None) -> TreeCase:
    return TreeCase(
        name=tree.name,
        path=path,
        xml=None if path is not None else tree.xml,
        ee_links_arg=ee_links_arg,
        locked_joints=list(tree.locked_joints),
        joint_names=list(tree.joint_names),
        parents=list(tree.parents),
        ee_links=list(ee_links if ee_links is not None else tree.ee_links),
        leaf_links=list(tree.leaf_links),
    )


def tree_case(seed: int, tmpdir: str) -> TreeCase:
    """Random tree ``seed``: even seeds load from a file, odd ones from the string. Seeds 0..5
    use the default EEs; seed 6 names a subset of the leaves plus a link in the middle of a branch;
    seed 7 names every leaf, including those behind the locked joint."""
    tree = random_tree(seed)
    path = None
    if seed % 2 == 0:
        path = os.path.join(tmpdir, f"{tree.name}.urdf")
        with open(path, "w") as fh:
            fh.write(tree.xml)
    if seed == 6:
        middle = [l for l in tree.link_order if l.startswith("link") and l not in tree.leaf_links][0]
        chosen = set(tree.ee_links[:2]) | {middle}
        ee = [l for l in tree.link_order if l in chosen]  # in pre-order
        return _generated_case(tree, ee_links_arg=ee, ee_links=ee, path=path)
    if seed == 7:
        ee = list(tree.leaf_links)
        assert any(l not in tree.ee_links for l in ee), "seed 7 must have a leaf behind its locked joint"
        return _generated_case(tree, ee_links_arg=ee, ee_links=ee, path=path)
    return _generated_case(tree, path=path)


def erd_tree_case(name: str) -> TreeCase:
    """A branched robot of example-robot-data; the expected model read from the file."""
    root = robots_dir()
    if name == "solo12":
        path, locked, ee_arg = os.path.join(root, "solo_description/robots/solo12.urdf"), [], None
    elif name == "baxter":
        # Prismatic finger joints cannot move in orbitflex: lock them (their tips then are no EE).
        path = os.path.join(root, "baxter_description/urdf/baxter.urdf")
        locked = ["l_gripper_l_finger_joint", "l_gripper_r_finger_joint",
                  "r_gripper_l_finger_joint", "r_gripper_r_finger_joint"]
        ee_arg = None
    elif name == "talos":
        path = os.path.join(root, "talos_data/robots/talos_reduced.urdf")
        locked = ["gripper_left_joint", "gripper_right_joint"]
        ee_arg = ["gripper_left_base_link", "gripper_left_motor_double_link",
                  "gripper_right_base_link", "left_sole_link", "right_sole_link"]
    else:
        raise KeyError(name)
    with open(path) as fh:
        link_order, joint_names, parents, leaves, default_ee = parse_urdf(fh.read(), locked)
    ee = default_ee
    if ee_arg is not None:
        ee = [l for l in link_order if l in set(ee_arg)]  # in pre-order
        assert len(ee) == len(ee_arg), ee_arg
    return TreeCase(name, path=path, ee_links_arg=None if ee_arg is None else ee, locked_joints=locked,
                    joint_names=joint_names, parents=parents, ee_links=ee, leaf_links=leaves)


ERD_TREES = ["solo12", "baxter", "talos"]
CASE_NAMES = [f"tree{s}" for s in TREE_SEEDS] + ["branch"] + ERD_TREES


def make_case(name: str, tmpdir: str) -> TreeCase:
    if name == "branch":
        return _generated_case(branch_tree())
    if name.startswith("tree"):
        return tree_case(int(name[4:]), tmpdir)
    return erd_tree_case(name)


# ===================================================================================== Pinocchio


class PinTree(PinRobot):
    """PinRobot with one Pinocchio BODY frame per EE link (orbitflex's ``ee_links`` order) and
    external forces summed over every EE."""

    def __init__(self, joint_names, ee_links, path=None, xml=None, locked_joints=None):
        super().__init__(joint_names, ee_links[0], path=path, xml=xml, locked_joints=locked_joints)
        self.ee_names = list(ee_links)
        self.ee_frames = []
        for name in ee_links:
            fid = self.model.getFrameId(name, pin.BODY)
            assert fid < len(self.model.frames), f"Pinocchio has no link frame {name!r}"
            self.ee_frames.append(fid)
        self.total_mass = float(sum(inertia.mass for inertia in self.model.inertias))

    @property
    def k(self) -> int:
        return len(self.ee_names)

    def wrench_rows(self, ee_wrench) -> np.ndarray:
        """``(k, 6)`` rows in ``ee_names`` order from None, a ``(k, 6)`` array or a dict by name."""
        rows = np.zeros((self.k, 6))
        if ee_wrench is None:
            return rows
        if isinstance(ee_wrench, dict):
            for name, f in ee_wrench.items():
                rows[self.ee_names.index(name)] = f
            return rows
        rows[:] = np.asarray(ee_wrench, dtype=float).reshape(self.k, 6)
        return rows

    def fext(self, ee_wrench) -> list:
        """Forces ON the bodies: ``-f_e`` at EE frame ``e``, moved to its parent joint, summed."""
        fext = [pin.Force.Zero() for _ in range(self.model.njoints)]
        for fid, f in zip(self.ee_frames, self.wrench_rows(ee_wrench)):
            frame = self.model.frames[fid]
            on_body = pin.Force(-f[3:6], -f[0:3])  # Force(linear, angular)
            fext[frame.parentJoint] = fext[frame.parentJoint] + frame.placement.act(on_body)
        return fext

    def ee_jacobians(self, q, ee=0):
        """``(J_e, Φ_{e,B})`` of EE ``ee`` (index or name) from the LOCAL frame Jacobian."""
        fid = self.ee_frames[ee if isinstance(ee, (int, np.integer)) else self.ee_names.index(ee)]
        jac = pin.computeFrameJacobian(self.model, self.data, self.q_pin(q), fid, pin.LOCAL)
        jac = np.vstack([jac[3:6], jac[0:3]])[:, self.perm]
        return jac[:, 6:], jac[:, :6]

    def full_jacobian(self, q, ee) -> np.ndarray:
        """``[Φ_{e,B}, J_e]`` (6, 6+n): the EE twist from ``[base_twist; qd]``."""
        jac, phi = self.ee_jacobians(q, ee)
        return np.hstack([phi, jac])


def pinocchio_facts(text: str, locked: List[str]) -> dict:
    """What Pinocchio's UNREDUCED model says about the tree, all by name:
    ``order`` (its own joint order), ``parent`` (joint -> nearest moving joint above, None for
    the base, locked joints skipped), ``leaves`` (link frames no other frame hangs from),
    ``behind_lock`` (links carried by a locked joint or below one), ``body`` (link -> the
    moving joint that carries it, None for the base), ``below_lock`` (moving joints with a
    locked joint above them) and ``kinds`` (joint -> Pinocchio joint model name)."""
    model = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
    names = list(model.names)
    locked_ids = {model.getJointId(n) for n in locked}
    assert all(i < model.njoints for i in locked_ids), locked

    def moving_at_or_above(jid: int):
        while jid in locked_ids:
            jid = model.parents[jid]
        return None if jid <= 1 else names[jid]  # 1 is the free-flyer root joint

    def behind(jid: int) -> bool:
        while jid > 1:
            if jid in locked_ids:
                return True
            jid = model.parents[jid]
        return False

    frames = list(model.frames)
    hung_from = {f.parentFrame for i, f in enumerate(frames) if f.parentFrame != i}
    link_frames = [(i, f) for i, f in enumerate(frames) if f.type == pin.FrameType.BODY]
    return dict(
        order=[names[j] for j in range(2, model.njoints) if j not in locked_ids],
        parent={names[j]: moving_at_or_above(model.parents[j])
                for j in range(2, model.njoints) if j not in locked_ids},
        leaves={f.name for i, f in link_frames if i not in hung_from},
        behind_lock={f.name for _, f in link_frames if behind(f.parentJoint)},
        body={f.name: moving_at_or_above(f.parentJoint) for _, f in link_frames},
        below_lock={names[j] for j in range(2, model.njoints)
                    if j not in locked_ids and behind(model.parents[j])},
        kinds={names[j]: model.joints[j].shortname() for j in range(2, model.njoints)},
    )


def check_against_pinocchio_facts(text, locked, joint_names, parents, leaf_links, ee_links):
    """The expected bookkeeping of a case against Pinocchio's model, matched by name."""
    facts = pinocchio_facts(text, locked)
    assert sorted(facts["order"]) == sorted(joint_names)
    for i, name in enumerate(joint_names):
        expected = None if parents[i] == -1 else joint_names[parents[i]]
        assert facts["parent"][name] == expected, (name, facts["parent"][name], expected)
        assert parents[i] < i, "parents must come first in pre-order"
    assert set(leaf_links) == facts["leaves"]
    free = facts["leaves"] - facts["behind_lock"]
    return facts, (free if free else facts["leaves"])


# ===================================================================================== fixtures


_LOADED: Dict[str, tuple] = {}


@pytest.fixture(scope="module")
def tree_dir(tmp_path_factory):
    return str(tmp_path_factory.mktemp("trees"))


@pytest.fixture(scope="module", params=CASE_NAMES)
def tree(request, tree_dir):
    """``(case, robot, pin_tree)``, loaded once per module. Pinocchio is told orbitflex's joint
    and EE names (it matches them by name; ``test_model`` checks the names themselves)."""
    name = request.param
    if name not in _LOADED:
        case = make_case(name, tree_dir)
        kwargs = {}
        if case.ee_links_arg is not None:
            kwargs["ee_links"] = list(case.ee_links_arg)
        if case.locked_joints:
            kwargs["locked_joints"] = list(case.locked_joints)
        if case.path is not None:
            robot = orbitflex.Robot.from_urdf(case.path, **kwargs)
        else:
            robot = orbitflex.Robot.from_urdf_string(case.xml, **kwargs)
        pr = PinTree(robot.joint_names, robot.ee_links, path=case.path, xml=case.xml,
                     locked_joints=case.locked_joints)
        _LOADED[name] = (case, robot, pr)
    return _LOADED[name]


def states(case: TreeCase, pr: PinTree, count: int = STATES, salt: str = "states") -> list:
    """Seeded random states and inputs, scaled with the robot's mass (outputs O(1) or larger),
    with one wrench per EE (``(k, 6)``, rows in ``pr.ee_names`` order)."""
    rng = case.rng(salt)
    n, k, scale = pr.n, pr.k, pr.total_mass
    out = []
    for _ in range(count):
        out.append(dict(
            q=rng.uniform(-np.pi, np.pi, n),
            base_twist=rng.normal(0.0, 0.7, 6),
            qd=rng.normal(0.0, 1.5, n),
            base_pose=np.concatenate([rng.normal(0.0, 2.0, 3), random_quaternion(rng)]),
            tau=rng.normal(0.0, 0.3 * scale, n),
            base_wrench=rng.normal(0.0, scale, 6),
            ee_wrench=rng.normal(0.0, 0.2 * scale, (k, 6)),
            base_acc=rng.normal(0.0, 1.0, 6),
            qdd=rng.normal(0.0, 2.0, n),
        ))
    return out


def check(name, value, reference, tol=TOL):
    err = rel_err(value, reference)
    assert err <= tol, (f"{name}: relative error {err:.3e} > {tol:g}\n"
                        f"orbitflex={np.asarray(value)}\npinocchio={np.asarray(reference)}")


# ===================================================================================== generator


def test_random_trees_have_the_awkward_features():
    """Guards the generator (Pinocchio only): every seed loads in Pinocchio, its bookkeeping
    equals an independent ElementTree reading of the XML and Pinocchio's tree (by name), and the
    seeds together have every awkward feature the comparison relies on."""
    seen = dict(non_unit_axis=0, aligned_axis=0, continuous=0, revolute=0, mid_fixed=0,
                massless_mid_frame=0, massless_leaf=0, leaf_with_mass=0, off_diagonal=0,
                rotated_com=0, base_branches=0, same_link_branches=0, fixed_after_base=0,
                moving_below_lock=0, child_before_parent_in_file=0, pin_order_differs=0,
                ee_on_inner_body=0)
    for seed in GENERATOR_SEEDS:
        tree = random_tree(seed)
        assert 4 <= tree.dof <= 14
        assert len(tree.ee_links) >= 2, "several EEs"
        assert tree.locked_joints and any(l not in tree.ee_links for l in tree.leaf_links), \
            "a leaf behind the locked joint, which is no EE"
        # 1. The XML read back (ElementTree) gives the generator's bookkeeping.
        link_order, joint_names, parents, leaves, ee = parse_urdf(tree.xml, tree.locked_joints)
        assert (link_order, joint_names, parents, leaves, ee) == (
            tree.link_order, tree.joint_names, tree.parents, tree.leaf_links, tree.ee_links)
        # 2. Pinocchio's tree, by name.
        facts, free = check_against_pinocchio_facts(
            tree.xml, tree.locked_joints, tree.joint_names, tree.parents, tree.leaf_links,
            tree.ee_links)
        # every free leaf is an EE; the others are the links that carry a locked gripper (inner
        # links, not behind the lock)
        assert free <= set(tree.ee_links)
        extra = set(tree.ee_links) - free
        assert all(l not in facts["leaves"] and l not in facts["behind_lock"] for l in extra), extra
        model = pin.buildModelFromXML(tree.xml, pin.JointModelFreeFlyer())
        reduced = pin.buildReducedModel(model, [model.getJointId(j) for j in tree.locked_joints],
                                        pin.neutral(model))
        assert reduced.nv == 6 + tree.dof
        seen["pin_order_differs"] += facts["order"] != tree.joint_names
        # 3. Features, read from the XML.
        root = ET.fromstring(tree.xml)
        joints = root.findall("joint")
        parent_of_link = {j.find("child").get("link"): j for j in joints}
        moving = [j for j in joints if j.get("type") != "fixed"]
        moving_parent_links = [j.find("parent").get("link") for j in moving]
        seen["same_link_branches"] += len(moving_parent_links) > len(set(moving_parent_links))
        seen["base_branches"] += tree.parents.count(-1) >= 2
        inertial_of = {l.get("name"): l.find("inertial") for l in root.findall("link")}
        position = {}
        for i, el in enumerate(root):
            position[(el.tag, el.get("name"))] = i
        for j in joints:
            kind = j.get("type")
            seen["continuous"] += kind == "continuous"
            seen["revolute"] += kind == "revolute"
            rpy = np.array(j.find("origin").get("rpy").split(), float)
            assert np.all(rpy != 0.0), "every joint origin is rotated"
            child, parent = j.find("child").get("link"), j.find("parent").get("link")
            if kind == "fixed" and child in moving_parent_links:
                seen["mid_fixed"] += 1
                seen["massless_mid_frame"] += inertial_of[child] is None
            if kind == "fixed" and parent == "base":
                seen["fixed_after_base"] += 1
            if kind != "fixed":
                axis = np.array(j.find("axis").get("xyz").split(), float)
                seen["non_unit_axis"] += abs(np.linalg.norm(axis) - 1.0) > 0.1
                seen["aligned_axis"] += np.count_nonzero(axis) == 1
            if parent in parent_of_link:
                above = parent_of_link[parent]
                seen["child_before_parent_in_file"] += (
                    position[("joint", j.get("name"))] < position[("joint", above.get("name"))])
        for leaf in tree.leaf_links:
            seen["massless_leaf"] += inertial_of[leaf] is None
            seen["leaf_with_mass"] += inertial_of[leaf] is not None
        seen["moving_below_lock"] += len(facts["below_lock"])
        bodies_with_children = {tree.joint_names[p] for p in tree.parents if p >= 0}
        seen["ee_on_inner_body"] += any(facts["body"][l] in bodies_with_children for l in tree.ee_links)
        for link in root.findall("link"):
            inertial = link.find("inertial")
            if inertial is None:
                continue
            a = {k: float(v) for k, v in inertial.find("inertia").attrib.items()}
            inertia = np.array([[a["ixx"], a["ixy"], a["ixz"]], [a["ixy"], a["iyy"], a["iyz"]],
                                [a["ixz"], a["iyz"], a["izz"]]])
            ev = np.linalg.eigvalsh(inertia)
            assert ev[0] > 0 and 2 * ev[-1] < ev.sum(), f"unphysical inertia in {link.get('name')}"
            seen["off_diagonal"] += abs(a["ixy"]) + abs(a["ixz"]) + abs(a["iyz"]) > 1e-6 * ev[-1]
            seen["rotated_com"] += np.any(np.array(inertial.find("origin").get("rpy").split(), float) != 0)
    assert all(v > 0 for v in seen.values()), seen


@pytest.mark.parametrize("name", ["branch"] + ERD_TREES)
def test_case_bookkeeping_matches_pinocchio(name, tmp_path):
    """The expected models of the plain branch and of the robot files (read with ElementTree)
    against Pinocchio's tree, by name (Pinocchio only)."""
    case = make_case(name, str(tmp_path))
    if name == "branch":  # hand-written expectations: also check them against the XML
        _, joint_names, parents, leaves, ee = parse_urdf(case.text(), case.locked_joints)
        assert (joint_names, parents, leaves, ee) == (
            case.joint_names, case.parents, case.leaf_links, case.ee_links)
    facts, free = check_against_pinocchio_facts(
        case.text(), case.locked_joints, case.joint_names, case.parents, case.leaf_links,
        case.ee_links)
    if case.ee_links_arg is None:
        assert set(case.ee_links) == free
    assert len(case.ee_links) >= 2
    # Every joint left moving is revolute or continuous (what orbitflex can move): Pinocchio's
    # JointModelR{X,Y,Z}, JointModelRUB{X,Y,Z}, JointModelRevolute(Unbounded)Unaligned.
    for j in case.joint_names:
        assert facts["kinds"][j].startswith("JointModelR"), (j, facts["kinds"][j])


# ===================================================================================== the model


def test_model(tree):
    """Joint order, parents and EEs as documented (module docstring), and Pinocchio's parents."""
    case, robot, pr = tree
    assert robot.dof == len(case.joint_names) == pr.model.nv - 6
    assert list(robot.joint_names) == case.joint_names, "joint order is not depth-first pre-order in file order"
    assert list(robot.parents) == case.parents
    assert list(robot.ee_links) == case.ee_links
    # Pinocchio's parent of each joint, by name (its own joint order differs).
    model = pr.model
    index = {name: i for i, name in enumerate(robot.joint_names)}
    for i, name in enumerate(robot.joint_names):
        p = model.parents[model.getJointId(name)]
        expected = -1 if p == 1 else index[model.names[p]]
        assert robot.parents[i] == expected, (name, robot.parents[i], expected)
    assert robot.total_mass == pytest.approx(pr.total_mass, rel=1e-12)


# ===================================================================================== dynamics


@pytest.mark.parametrize("method", METHODS)
def test_mass_matrix(tree, method):
    case, robot, pr = tree
    for s in states(case, pr):
        m = robot.mass_matrix(s["q"], method=method)
        check("mass matrix", m, pr.mass_matrix(s["q"]))


@pytest.mark.parametrize("method", METHODS)
def test_bias_forces(tree, method):
    case, robot, pr = tree
    for s in states(case, pr):
        check("bias forces", robot.bias_forces(s["q"], s["base_twist"], s["qd"], method=method),
              pr.bias_forces(s["q"], s["base_twist"], s["qd"]))


@pytest.mark.parametrize("method", METHODS)
def test_forward_dynamics_several_ee_wrenches(tree, method):
    case, robot, pr = tree
    for s in states(case, pr):
        args = (s["q"], s["base_twist"], s["qd"], s["tau"])
        w = s["ee_wrench"]
        ref = pr.forward_dynamics(*args, base_wrench=s["base_wrench"], ee_wrench=w)
        check("FD, every input, (k, 6) EE wrenches",
              robot.forward_dynamics(*args, base_wrench=s["base_wrench"], ee_wrench=w, method=method), ref)
        as_dict = {name: w[e] for e, name in enumerate(robot.ee_links)}
        check("FD, every input, dict EE wrenches",
              robot.forward_dynamics(*args, base_wrench=s["base_wrench"], ee_wrench=as_dict, method=method), ref)
        check("FD, joint torques only", robot.forward_dynamics(*args, method=method), pr.forward_dynamics(*args))
        # Each EE's wrench alone (the others missing from the dict, so zero): a sign, frame or
        # row slip in one EE cannot hide behind the others.
        zero = np.zeros(robot.dof)
        for e, name in enumerate(robot.ee_links):
            alone = np.zeros_like(w)
            alone[e] = w[e]
            check(f"FD, EE {name!r} wrench only",
                  robot.forward_dynamics(*args[:3], zero, ee_wrench={name: w[e]}, method=method),
                  pr.forward_dynamics(*args[:3], zero, ee_wrench=alone))


@pytest.mark.parametrize("method", METHODS)
def test_inverse_dynamics_several_ee_wrenches(tree, method):
    case, robot, pr = tree
    for s in states(case, pr):
        args = (s["q"], s["base_twist"], s["qd"], s["base_acc"], s["qdd"])
        check("ID, (k, 6) EE wrenches",
              robot.inverse_dynamics(*args, ee_wrench=s["ee_wrench"], method=method),
              pr.inverse_dynamics(*args, ee_wrench=s["ee_wrench"]))
        check("ID, no EE wrench", robot.inverse_dynamics(*args, method=method), pr.inverse_dynamics(*args))


@pytest.mark.parametrize("method", METHODS)
def test_inverse_of_forward_dynamics(tree, method):
    """ID(FD(τ, f_B, f_e)) = [f_B; τ] with several EE wrenches (orbitflex against itself)."""
    case, robot, pr = tree
    for s in states(case, pr, 1):
        acc = robot.forward_dynamics(s["q"], s["base_twist"], s["qd"], s["tau"],
                                     base_wrench=s["base_wrench"], ee_wrench=s["ee_wrench"], method=method)
        back = robot.inverse_dynamics(s["q"], s["base_twist"], s["qd"], acc[:6], acc[6:],
                                      ee_wrench=s["ee_wrench"], method=method)
        check("ID(FD)", back, np.concatenate([s["base_wrench"], s["tau"]]))


# ===================================================================================== kinematics


def test_every_ee_jacobian_and_base_operator(tree):
    """``J_e`` and ``Φ_{e,B}`` of every EE, by name and by index, against Pinocchio's LOCAL
    frame Jacobian of that link, and the EE twist against Pinocchio's frame velocity."""
    case, robot, pr = tree
    for s in states(case, pr):
        qp, vp = pr.q_pin(s["q"]), pr.v_pin(s["base_twist"], s["qd"])
        pin.forwardKinematics(pr.model, pr.data, qp, vp)
        for e, name in enumerate(robot.ee_links):
            jac, phi = pr.ee_jacobians(s["q"], name)
            check(f"J of {name!r} (by name)", robot.ee_jacobian(s["q"], ee=name), jac)
            check(f"J of {name!r} (by index)", robot.ee_jacobian(s["q"], ee=e), jac)
            check(f"Φ of {name!r} (by name)", robot.ee_base_operator(s["q"], ee=name), phi)
            check(f"Φ of {name!r} (by index)", robot.ee_base_operator(s["q"], ee=e), phi)
            vel = pin.getFrameVelocity(pr.model, pr.data, pr.ee_frames[e], pin.LOCAL)
            twist = robot.ee_base_operator(s["q"], ee=e) @ s["base_twist"] + robot.ee_jacobian(s["q"], ee=e) @ s["qd"]
            check(f"twist of {name!r}", twist, np.concatenate([vel.angular, vel.linear]))


def test_momentum_and_kinetic_energy(tree):
    case, robot, pr = tree
    for s in states(case, pr):
        check("momentum", robot.momentum(s["base_pose"], s["q"], s["base_twist"], s["qd"]),
              pr.momentum(s["base_pose"], s["q"], s["base_twist"], s["qd"]))
        e = robot.kinetic_energy(s["q"], s["base_twist"], s["qd"])
        ref = pr.kinetic_energy(s["q"], s["base_twist"], s["qd"])
        assert abs(e - ref) / max(1.0, abs(ref)) <= TOL, (e, ref)


# ===================================================================================== derivatives


def test_derivatives_with_several_ee_wrenches(tree):
    """Analytical ID and FD derivatives against Pinocchio's computeRNEADerivatives /
    computeABADerivatives (mapped by pin_helpers), with every EE loaded at once."""
    case, robot, pr = tree
    for s in states(case, pr, salt="derivatives"):
        mine = robot.inverse_dynamics_derivatives(
            s["q"], s["base_twist"], s["qd"], s["base_acc"], s["qdd"], ee_wrench=s["ee_wrench"])
        theirs = rnea_derivatives(pr, s["q"], s["base_twist"], s["qd"], s["base_acc"], s["qdd"],
                                  ee_wrench=s["ee_wrench"])
        for key in ("q", "v", "a"):
            check(f"ID d/d{key}", mine[key], theirs[key])
        mine = robot.forward_dynamics_derivatives(
            s["q"], s["base_twist"], s["qd"], s["tau"], base_wrench=s["base_wrench"],
            ee_wrench=s["ee_wrench"])
        theirs = aba_derivatives(pr, s["q"], s["base_twist"], s["qd"], s["tau"],
                                 base_wrench=s["base_wrench"], ee_wrench=s["ee_wrench"])
        for key in ("q", "v", "tau", "base_wrench"):
            check(f"FD d/d{key}", mine[key], theirs[key])


def test_derivatives_with_respect_to_the_ee_wrenches(tree):
    """``"ee_wrench"`` blocks, assumed (6+n, 6k) with EE ``e`` in columns ``6e..6e+6``:
    ID: ``+[Φ_{e,B} J_e]ᵀ`` (the EE pushes, so the actuators must push back);
    FD: ``−M⁻¹ [Φ_{e,B} J_e]ᵀ``, with Pinocchio's Jacobians and mass matrix."""
    case, robot, pr = tree
    n, k = robot.dof, len(robot.ee_links)
    s = states(case, pr, 1, salt="derivatives")[0]
    jt = np.hstack([pr.full_jacobian(s["q"], e).T for e in range(k)])  # (6+n, 6k)
    mass = pr.mass_matrix(s["q"])
    mine = robot.inverse_dynamics_derivatives(
        s["q"], s["base_twist"], s["qd"], s["base_acc"], s["qdd"], ee_wrench=s["ee_wrench"])
    assert mine["ee_wrench"].shape == (6 + n, 6 * k)
    check("ID d/d(ee_wrench)", mine["ee_wrench"], jt)
    mine = robot.forward_dynamics_derivatives(
        s["q"], s["base_twist"], s["qd"], s["tau"], base_wrench=s["base_wrench"], ee_wrench=s["ee_wrench"])
    assert mine["ee_wrench"].shape == (6 + n, 6 * k)
    check("FD d/d(ee_wrench)", mine["ee_wrench"], -np.linalg.solve(mass, jt))


# ===================================================================================== API forms


def test_ee_none_is_ambiguous_with_several_ees(tree):
    """``ee=None`` on a several-EE robot raises ValueError naming every EE."""
    case, robot, pr = tree
    assert len(robot.ee_links) >= 2
    q = np.zeros(robot.dof)
    for fn in (robot.ee_jacobian, robot.ee_base_operator):
        with pytest.raises(ValueError) as info:
            fn(q)
        missing = [name for name in robot.ee_links if name not in str(info.value)]
        assert not missing, f"{fn.__name__}: message lacks {missing}: {info.value}"


def test_wrench_forms_agree_and_unknown_names_fail(tree):
    """The dict form equals the (k, 6) form (missing EEs are zero) in forward and inverse
    dynamics, the derivatives and the flexible arm's derivative; an unknown dict key is a
    ValueError naming the key."""
    case, robot, pr = tree
    s = states(case, pr, 1, salt="forms")[0]
    w = s["ee_wrench"].copy()
    w[0] = 0.0  # the first EE is left out of the dict
    as_dict = {name: w[e] for e, name in enumerate(robot.ee_links) if e > 0}
    fd_args = (s["q"], s["base_twist"], s["qd"], s["tau"])
    id_args = (s["q"], s["base_twist"], s["qd"], s["base_acc"], s["qdd"])
    for method in METHODS:
        a = robot.forward_dynamics(*fd_args, ee_wrench=w, method=method)
        b = robot.forward_dynamics(*fd_args, ee_wrench=as_dict, method=method)
        assert rel_err(b, a) <= 1e-14
        a = robot.inverse_dynamics(*id_args, ee_wrench=w, method=method)
        b = robot.inverse_dynamics(*id_args, ee_wrench=as_dict, method=method)
        assert rel_err(b, a) <= 1e-14
    a = robot.forward_dynamics_derivatives(*fd_args, ee_wrench=w)
    b = robot.forward_dynamics_derivatives(*fd_args, ee_wrench=as_dict)
    for key in ("q", "v"):
        assert rel_err(b[key], a[key]) <= 1e-14
    a = robot.inverse_dynamics_derivatives(*id_args, ee_wrench=w)
    b = robot.inverse_dynamics_derivatives(*id_args, ee_wrench=as_dict)
    for key in ("q", "v"):
        assert rel_err(b[key], a[key]) <= 1e-14
    # The flexible arm passes the same forms through.
    arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints.defaults_for(robot))
    x = arm.state(q=s["q"], theta=s["q"], qd=s["qd"], base_twist=s["base_twist"])
    with_w = arm.derivative(x, ee_wrench=w)
    assert rel_err(arm.derivative(x, ee_wrench=as_dict), with_w) <= 1e-14
    assert rel_err(with_w, arm.derivative(x)) > 1e-6, "the EE wrenches must change the motion"
    # Unknown names.
    bad = dict(as_dict)
    bad["no_such_link"] = np.ones(6)
    with pytest.raises(ValueError, match="no_such_link"):
        robot.forward_dynamics(*fd_args, ee_wrench=bad)
    with pytest.raises(ValueError, match="no_such_link"):
        robot.inverse_dynamics(*id_args, ee_wrench=bad)


def test_single_ee_on_a_tree():
    """``ee_link="x"`` on a tree whose other branches still move: one EE, the chain API
    (``ee=None``, a (6,) wrench) works, and equals ``ee_links=["x"]`` and Pinocchio."""
    tree_ = random_tree(3)
    ee = tree_.ee_links[-1]
    robot = orbitflex.Robot.from_urdf_string(tree_.xml, ee_link=ee, locked_joints=tree_.locked_joints)
    same = orbitflex.Robot.from_urdf_string(tree_.xml, ee_links=[ee], locked_joints=tree_.locked_joints)
    assert list(robot.ee_links) == [ee] == list(same.ee_links)
    assert list(robot.joint_names) == tree_.joint_names and list(robot.parents) == tree_.parents
    pr = PinTree(robot.joint_names, [ee], xml=tree_.xml, locked_joints=tree_.locked_joints)
    case = TreeCase("single_ee")
    for s in states(case, pr):
        jac, phi = pr.ee_jacobians(s["q"], 0)
        check("J", robot.ee_jacobian(s["q"]), jac)
        check("Φ", robot.ee_base_operator(s["q"]), phi)
        args = (s["q"], s["base_twist"], s["qd"], s["tau"])
        f = s["ee_wrench"][0]  # (6,)
        ref = pr.forward_dynamics(*args, base_wrench=s["base_wrench"], ee_wrench=f[None, :])
        for method in METHODS:
            check("FD, (6,) wrench", robot.forward_dynamics(*args, base_wrench=s["base_wrench"],
                                                           ee_wrench=f, method=method), ref)
            check("FD, ee_links=[x]", same.forward_dynamics(*args, base_wrench=s["base_wrench"],
                                                            ee_wrench=f, method=method), ref)
