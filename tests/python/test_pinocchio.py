"""orbitflex against Pinocchio (model §6.5) on the built-in space arm, ur5, panda (fingers
locked), xarm7 and seeded random chains, for both ``method="recursive"`` and ``"operator"``.

Agreement is ``‖orbitflex − pinocchio‖ / max(1, ‖pinocchio‖) ≤ 1e-9`` after the convention map
of docs/model.md, "Relation to Pinocchio" (implemented in pin_helpers.py). Inputs are scaled with the robot's mass so
that the outputs are O(1) or larger and the relative test is not an absolute one in disguise.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import PIN_CHAIN_SEEDS
from pin_helpers import quat_to_matrix, random_quaternion, rel_err
from urdf_gen import random_chain

TOL = 1e-9
METHODS = ["recursive", "operator"]
STATES_PER_ROBOT = 3


def states(case, robot, count=STATES_PER_ROBOT):
    """Seeded random states and inputs for one robot."""
    rng = case.rng("states")
    n = robot.dof
    scale = robot.total_mass
    out = []
    for _ in range(count):
        out.append(
            dict(
                q=rng.uniform(-np.pi, np.pi, n),
                base_twist=rng.normal(0.0, 0.7, 6),
                qd=rng.normal(0.0, 1.5, n),
                base_pose=np.concatenate([rng.normal(0.0, 2.0, 3), random_quaternion(rng)]),
                tau=rng.normal(0.0, 0.3 * scale, n),
                base_wrench=rng.normal(0.0, scale, 6),
                ee_wrench=rng.normal(0.0, 0.2 * scale, 6),
                base_acc=rng.normal(0.0, 1.0, 6),
                qdd=rng.normal(0.0, 2.0, n),
            )
        )
    return out


def check(name, value, reference, tol=TOL):
    err = rel_err(value, reference)
    assert err <= tol, f"{name}: relative error {err:.3e} > {tol:g}\norbitflex={np.asarray(value)}\npinocchio={np.asarray(reference)}"


# ------------------------------------------------------------------------------- the generator


def test_random_chains_have_the_awkward_features():
    """Guards the generator: the features the comparison relies on are really in the URDFs."""
    import xml.etree.ElementTree as ET

    seen = dict(non_unit_axis=0, aligned_axis=0, continuous=0, revolute=0, mid_fixed=0,
                branch=0, no_inertial=0, off_diagonal=0, rotated_com=0)
    for seed in PIN_CHAIN_SEEDS:
        chain = random_chain(seed)
        root = ET.fromstring(chain.xml)
        joints = root.findall("joint")
        moving_parents = {j.find("parent").get("link") for j in joints if j.get("type") != "fixed"}
        children = {}
        for j in joints:
            children.setdefault(j.find("parent").get("link"), []).append(j)
            kind = j.get("type")
            seen["continuous"] += kind == "continuous"
            seen["revolute"] += kind == "revolute"
            rpy = np.array(j.find("origin").get("rpy").split(), float)
            assert np.all(rpy != 0.0), "every joint origin is rotated"
            if kind == "fixed" and j.find("child").get("link") in moving_parents:
                seen["mid_fixed"] += 1
            if kind != "fixed":
                axis = np.array(j.find("axis").get("xyz").split(), float)
                norm = np.linalg.norm(axis)
                seen["non_unit_axis"] += abs(norm - 1.0) > 0.1
                seen["aligned_axis"] += np.count_nonzero(axis) == 1
        seen["branch"] += any(len(c) > 1 for c in children.values())
        leaves = [l.get("name") for l in root.findall("link") if l.get("name") not in children]
        assert chain.ee_link in leaves and len(leaves) == 2
        for link in root.findall("link"):
            inertial = link.find("inertial")
            if inertial is None:
                seen["no_inertial"] += 1
                continue
            a = {k: float(v) for k, v in inertial.find("inertia").attrib.items()}
            inertia = np.array([[a["ixx"], a["ixy"], a["ixz"]], [a["ixy"], a["iyy"], a["iyz"]],
                                [a["ixz"], a["iyz"], a["izz"]]])
            ev = np.linalg.eigvalsh(inertia)
            assert ev[0] > 0 and 2 * ev[-1] < ev.sum(), f"unphysical inertia in {link.get('name')}"
            seen["off_diagonal"] += abs(a["ixy"]) + abs(a["ixz"]) + abs(a["iyz"]) > 1e-6 * ev[-1]
            seen["rotated_com"] += np.any(np.array(inertial.find("origin").get("rpy").split(), float) != 0)
        assert len(chain.joint_names) >= 3
    assert all(v > 0 for v in seen.values()), seen
    assert seen["branch"] == len(PIN_CHAIN_SEEDS)


# ------------------------------------------------------------------------------- the model itself


def test_model_matches_pinocchio(loaded):
    case, robot, pr = loaded
    model = pr.model
    assert robot.dof == model.nv - 6
    pin_names = [model.names[i] for i in range(2, model.njoints)]
    assert list(robot.joint_names) == pin_names, "joint order differs from Pinocchio's tree order"
    assert robot.total_mass == pytest.approx(sum(inertia.mass for inertia in model.inertias), rel=1e-12)
    if case.ee_link is not None:
        assert robot.ee_link == case.ee_link


# ------------------------------------------------------------------------------- dynamics


@pytest.mark.parametrize("method", METHODS)
def test_mass_matrix(loaded, method):
    case, robot, pr = loaded
    for s in states(case, robot):
        m = robot.mass_matrix(s["q"], method=method)
        check("mass matrix", m, pr.mass_matrix(s["q"]))
        assert np.array_equal(m, m.T) or rel_err(m, m.T) < 1e-14


@pytest.mark.parametrize("method", METHODS)
def test_bias_forces(loaded, method):
    case, robot, pr = loaded
    for s in states(case, robot):
        c = robot.bias_forces(s["q"], s["base_twist"], s["qd"], method=method)
        check("bias forces [C_B; C_r]", c, pr.bias_forces(s["q"], s["base_twist"], s["qd"]))


@pytest.mark.parametrize("method", METHODS)
def test_forward_dynamics_all_inputs(loaded, method):
    case, robot, pr = loaded
    for s in states(case, robot):
        args = (s["q"], s["base_twist"], s["qd"], s["tau"])
        acc = robot.forward_dynamics(
            *args, base_wrench=s["base_wrench"], ee_wrench=s["ee_wrench"], method=method
        )
        ref = pr.forward_dynamics(*args, base_wrench=s["base_wrench"], ee_wrench=s["ee_wrench"])
        check("forward dynamics [α_B; q̈]", acc, ref)
        # Each input on its own, so a sign or frame slip in one of them cannot hide.
        check("FD, joint torques only", robot.forward_dynamics(*args, method=method), pr.forward_dynamics(*args))
        zero = np.zeros(robot.dof)
        check(
            "FD, base wrench only",
            robot.forward_dynamics(*args[:3], zero, base_wrench=s["base_wrench"], method=method),
            pr.forward_dynamics(*args[:3], zero, base_wrench=s["base_wrench"]),
        )
        check(
            "FD, EE wrench only",
            robot.forward_dynamics(*args[:3], zero, ee_wrench=s["ee_wrench"], method=method),
            pr.forward_dynamics(*args[:3], zero, ee_wrench=s["ee_wrench"]),
        )


@pytest.mark.parametrize("method", METHODS)
def test_inverse_dynamics_with_ee_wrench(loaded, method):
    case, robot, pr = loaded
    for s in states(case, robot):
        args = (s["q"], s["base_twist"], s["qd"], s["base_acc"], s["qdd"])
        check(
            "inverse dynamics [f_B; τ]",
            robot.inverse_dynamics(*args, ee_wrench=s["ee_wrench"], method=method),
            pr.inverse_dynamics(*args, ee_wrench=s["ee_wrench"]),
        )
        check(
            "inverse dynamics, no EE wrench",
            robot.inverse_dynamics(*args, method=method),
            pr.inverse_dynamics(*args),
        )


# ------------------------------------------------------------------------------- kinematics


def test_ee_jacobian_and_base_operator(loaded):
    case, robot, pr = loaded
    for s in states(case, robot):
        jac, phi = pr.ee_jacobians(s["q"])
        check("J", robot.ee_jacobian(s["q"]), jac)
        check("Φ_{n+1,B}", robot.ee_base_operator(s["q"]), phi)


def test_ee_twist_from_operators(loaded):
    """``V_{n+1} = Φ_{n+1,B} V_B + J q̇`` against Pinocchio's LOCAL frame velocity."""
    case, robot, pr = loaded
    for s in states(case, robot):
        qp, vp = pr.q_pin(s["q"]), pr.v_pin(s["base_twist"], s["qd"])
        pin.forwardKinematics(pr.model, pr.data, qp, vp)
        vel = pin.getFrameVelocity(pr.model, pr.data, pr.ee_frame, pin.LOCAL)
        twist = robot.ee_base_operator(s["q"]) @ s["base_twist"] + robot.ee_jacobian(s["q"]) @ s["qd"]
        check("EE twist", twist, np.concatenate([vel.angular, vel.linear]))


def test_operators_dict(loaded):
    """The dense operator blocks of (A.19) against Pinocchio's mass matrix, bias and Jacobians."""
    case, robot, pr = loaded
    n = robot.dof
    s = states(case, robot, 1)[0]
    ops = robot.operators(s["q"], s["base_twist"], s["qd"])
    m = pr.mass_matrix(s["q"])
    c = pr.bias_forces(s["q"], s["base_twist"], s["qd"])
    jac, phi = pr.ee_jacobians(s["q"])
    check("M_b", ops["M_b"], m[:6, :6])
    check("M_rb", ops["M_rb"], m[:6, 6:])
    check("M_br", ops["M_br"], m[6:, :6])
    check("M_r", ops["M_r"], m[6:, 6:])
    check("C_B", np.ravel(ops["C_B"]), c[:6])
    check("C_r", np.ravel(ops["C_r"]), c[6:])
    check("J", ops["J"], jac)
    check("Phi_n1_B", ops["Phi_n1_B"], phi)
    # Seed's composite expressions with the stacked operators (A.13-A.19).
    Phi, H, M, B = ops["Phi"], ops["H"], ops["M"], ops["B"]
    assert H.shape == (6 * n, n) and Phi.shape == (6 * n, 6 * n)
    check("Hᵀ Φᵀ M Φ H", H.T @ Phi.T @ M @ Phi @ H, m[6:, 6:])
    check("Bᵀ Φ H (corrected typo)", B.T @ Phi @ H, jac)


# ------------------------------------------------------------------------------- momentum, energy


def test_momentum_inertial_frame(loaded):
    case, robot, pr = loaded
    for s in states(case, robot):
        h = robot.momentum(s["base_pose"], s["q"], s["base_twist"], s["qd"])
        ref = pr.momentum(s["base_pose"], s["q"], s["base_twist"], s["qd"])
        check("momentum", h, ref)
        # The pose matters: the same motion at the identity pose has different inertial momentum.
        ident = np.array([0, 0, 0, 0, 0, 0, 1.0])
        h0 = robot.momentum(ident, s["q"], s["base_twist"], s["qd"])
        check("momentum at identity pose", h0, pr.momentum(ident, s["q"], s["base_twist"], s["qd"]))
        rot = quat_to_matrix(s["base_pose"][3:])
        check("linear momentum rotates with the base", h[3:], rot @ h0[3:])


def test_kinetic_energy(loaded):
    case, robot, pr = loaded
    for s in states(case, robot):
        e = robot.kinetic_energy(s["q"], s["base_twist"], s["qd"])
        ref = pr.kinetic_energy(s["q"], s["base_twist"], s["qd"])
        assert abs(e - ref) / max(1.0, abs(ref)) <= TOL, (e, ref)


# ------------------------------------------------------------------------------- frames


def _urdf_links_depth_first(case) -> list:
    """Every <link> of the case's URDF, depth-first from the root, children in file order
    (read here with ElementTree, independently of orbitflex)."""
    import xml.etree.ElementTree as ET

    text = open(case.path).read() if case.path is not None else case.xml
    root = ET.fromstring(text)
    links = [link.get("name") for link in root.findall("link")]
    children: dict = {}
    parent_of = {}
    for joint in root.findall("joint"):
        parent, child = joint.find("parent").get("link"), joint.find("child").get("link")
        children.setdefault(parent, []).append(child)
        parent_of[child] = parent
    (top,) = [link for link in links if link not in parent_of]
    order, stack = [], [top]
    while stack:
        link = stack.pop()
        order.append(link)
        stack.extend(reversed(children.get(link, [])))
    return order


def test_frame_poses_match_frames_forward_kinematics(loaded):
    """Every URDF link's inertial pose equals Pinocchio's BODY frame of that name after
    ``framesForwardKinematics`` (free-flyer at a random base pose; locked joints at zero)."""
    case, robot, pr = loaded
    assert list(robot.frame_names) == _urdf_links_depth_first(case)
    rng = case.rng("frames")
    model, data = pr.model, pr.data
    for _ in range(3):
        base = np.concatenate([rng.normal(size=3), random_quaternion(rng)])
        q = rng.uniform(-np.pi, np.pi, robot.dof)
        pin.framesForwardKinematics(model, data, pr.q_pin(q, base))
        poses = robot.frame_poses(base, q)
        assert poses.shape == (len(robot.frame_names), 7)
        assert np.all(poses[:, 6] >= 0)
        for name, pose in zip(robot.frame_names, poses):
            placement = data.oMf[model.getFrameId(name, pin.BODY)]
            assert np.abs(pose[:3] - placement.translation).max() < 1e-12, name
            assert np.abs(quat_to_matrix(pose[3:]) - placement.rotation).max() < 1e-12, name
            assert abs(np.linalg.norm(pose[3:]) - 1) < 1e-14
