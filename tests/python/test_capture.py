"""Capture of a free-flying target (model §9): ``orbitflex.Target`` and ``orbitflex.capture``.

The oracle is Pinocchio's ``impulseDynamics`` on the rigid link system plus the target joined by
a second free-flyer, with a 6-D constraint between the EE frame and the handle, restitution 0,
through the overload that takes the constraint Jacobian (``RigidConstraintModel.calc``, then
``getConstraintJacobian``): with pin 4.1.0 the contact-model overload (the proximal solver) leaves
the two frames separating when both bodies move. Motor rates are not part of Pinocchio's model;
orbitflex keeps them (the springs carry no impulse).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import orbitflex
from conftest import chain_case, erd_case
from pin_helpers import PinRobot, quat_to_matrix, random_quaternion, rel_err
from tree_gen import random_tree

TOL = 1e-10


def _joints(n):
    return orbitflex.FlexibleJoints(np.full(n, 500.0), np.full(n, 0.2), damping=0.1, motor_damping=0.3)


def _cases():
    out = []
    for seed in range(6):
        case = chain_case(seed)
        robot, pr = case.load()
        out.append((case.name, robot, pr, robot.ee_links[0]))
    for seed in range(4):
        tree = random_tree(seed)
        robot = orbitflex.Robot.from_urdf_string(tree.xml, locked_joints=list(tree.locked_joints) or None)
        ee = robot.ee_links[-1]
        pr = PinRobot(robot.joint_names, ee, xml=tree.xml, locked_joints=tree.locked_joints)
        out.append((tree.name, robot, pr, ee))
    for name in ("ur5", "panda"):
        robot, pr = erd_case(name).load()
        out.append((name, robot, pr, robot.ee_links[0]))
    return out


CASES = _cases()


def _random_target(rng, arm, x, ee, scale):
    """A target of the order of the arm's mass, its frame within 0.4 m of the EE, tumbling."""
    mass = scale * rng.uniform(0.2, 3.0)
    a, b = rng.uniform(0.1, 1.0, 2)
    c = rng.uniform(abs(a - b) + 0.05, a + b)
    r = quat_to_matrix(random_quaternion(rng))
    inertia = mass * r @ np.diag([a, b, c]) @ r.T * rng.uniform(0.05, 0.5)
    at = arm.ee_pose(x, ee=ee)
    pose = np.concatenate([at[:3] + rng.normal(0, 0.2, 3), random_quaternion(rng)])
    grasp = np.concatenate([rng.normal(0, 0.2, 3), random_quaternion(rng)])
    return orbitflex.Target(mass, inertia, pose, rng.normal(0, 0.3, 6), grasp, com=rng.normal(0, 0.15, 3))


def _random_state(rng, arm):
    n = arm.dof
    return arm.state(
        q=rng.uniform(-np.pi, np.pi, n), theta=rng.uniform(-np.pi, np.pi, n), qd=rng.normal(0, 0.7, n),
        theta_dot=rng.normal(0, 0.7, n),
        base_pose=np.concatenate([rng.normal(0, 1.0, 3), random_quaternion(rng)]),
        base_twist=rng.normal(0, 0.3, 6),
    )


def _split(arm, x):
    n = arm.dof
    return dict(pose=x[:7], q=x[7:7 + n], theta=x[7 + n:7 + 2 * n], twist=x[7 + 2 * n:13 + 2 * n],
                qd=x[13 + 2 * n:13 + 3 * n], theta_dot=x[13 + 3 * n:])


def _se3(pose):
    return pin.SE3(quat_to_matrix(pose[3:7]), np.asarray(pose[:3], float))


def pinocchio_capture(pr: PinRobot, ee_link, s, target):
    """Pinocchio's post-impact velocities: ``(base twist [ω; v], q̇, target twist [ω; v], impulse
    on the EE [moment; force] in the EE frame)``."""
    model = pin.Model(pr.model)
    jt = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "target_free_flyer")
    model.appendBodyToJoint(jt, pin.Inertia(target.mass, target.com, target.inertia), pin.SE3.Identity())
    data = model.createData()
    q = np.concatenate([pr.q_pin(s["q"], s["pose"]), target.pose])
    w = target.twist
    v = np.concatenate([pr.v_pin(s["twist"], s["qd"]), w[3:], w[:3]])
    frame = model.frames[model.getFrameId(ee_link)]
    constraint = pin.RigidConstraintModel(
        pin.ContactType.CONTACT_6D, model, frame.parentJoint, frame.placement, jt, _se3(target.grasp),
        pin.ReferenceFrame.LOCAL,
    )
    cdata = constraint.createData()
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    constraint.calc(model, data, cdata)
    jac = pin.getConstraintJacobian(model, data, constraint, cdata)
    after = pin.impulseDynamics(model, data, q, v, jac, 0.0, 0.0).copy()
    assert np.linalg.norm(jac @ after) < 1e-9 * max(1.0, np.linalg.norm(v)), "the frames still separate"
    nv = pr.model.nv
    arm = pr.from_pin_vec(after[:nv])
    tw = after[nv:]
    # the constraint impulse λ acts on body 1 (the EE) in the contact frame, which is the EE frame
    lam = np.asarray(data.impulse_c).copy()
    return arm[:6], arm[6:], np.concatenate([tw[3:], tw[:3]]), np.concatenate([lam[3:], lam[:3]])


@pytest.mark.parametrize("name,robot,pr,ee", CASES, ids=[c[0] for c in CASES])
def test_post_impact_velocities_equal_pinocchio(name, robot, pr, ee):
    arm = orbitflex.FlexibleArm(robot, _joints(robot.dof))
    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    scale = robot.total_mass
    for _ in range(3):
        x = _random_state(rng, arm)
        target = _random_target(rng, arm, x, ee, scale)
        cap = orbitflex.capture(arm, x, target, ee=ee)
        s = _split(arm, x)
        after = _split(arm, cap.x)
        base, qd, tw, lam = pinocchio_capture(pr, ee, s, target)
        assert rel_err(after["qd"], s["qd"]) > 1e-3, "the capture changed the velocities"
        assert rel_err(after["twist"], base) < TOL, (name, after["twist"], base)
        assert rel_err(after["qd"], qd) < TOL, name
        assert rel_err(cap.target_twist, tw) < TOL, name
        # what the EE receives (λ) is minus what it exerts on the target
        assert rel_err(cap.impulse, -lam) < TOL * max(1.0, np.linalg.norm(lam)), (cap.impulse, lam)
        # the motor side does not jump
        assert np.array_equal(after["theta_dot"], s["theta_dot"])
        assert np.array_equal(after["theta"], s["theta"]) and np.array_equal(after["q"], s["q"])
        assert np.array_equal(after["pose"], s["pose"])


@pytest.mark.parametrize("name,robot,pr,ee", CASES[:4] + CASES[6:8], ids=[c[0] for c in CASES[:4] + CASES[6:8]])
def test_momentum_and_energy(name, robot, pr, ee):
    """Momentum of arm + target is kept to 1e-12 of the parts' momenta (the derivation of the
    bound is in tests/capture.rs); the energy lost is ``E_before − E_after`` to 1e-12 ``E``."""
    arm = orbitflex.FlexibleArm(robot, _joints(robot.dof))
    rng = np.random.default_rng(7)
    for _ in range(3):
        x = _random_state(rng, arm)
        target = _random_target(rng, arm, x, ee, robot.total_mass)
        cap = orbitflex.capture(arm, x, target, ee=ee)
        h_arm, h_t = arm.momentum(x), target.momentum()
        h_after = cap.arm.momentum(cap.x)
        scale = np.linalg.norm(h_arm) + np.linalg.norm(h_t)
        assert np.linalg.norm(h_after - h_arm - h_t) < 1e-12 * scale
        e_before = arm.energy(x) + target.kinetic_energy()
        assert cap.energy_loss > 0
        assert abs(e_before - cap.arm.energy(cap.x) - cap.energy_loss) < 1e-12 * e_before
        assert cap.energy_loss == pytest.approx(0.5 * cap.relative_twist @ cap.impulse, rel=1e-12)


def test_combined_arm_is_with_payload_bit_for_bit():
    name, robot, pr, ee = CASES[6]  # a tree: the payload goes to the named EE
    arm = orbitflex.FlexibleArm(robot, _joints(robot.dof))
    rng = np.random.default_rng(3)
    x = _random_state(rng, arm)
    target = _random_target(rng, arm, x, ee, robot.total_mass)
    cap = orbitflex.capture(arm, x, target, ee=ee)
    loaded = orbitflex.FlexibleArm(
        robot.with_payload(target.mass, inertia=cap.payload_inertia, com=cap.payload_com, ee=ee), arm.joints
    )
    u = rng.normal(0, 1, robot.dof)
    assert np.array_equal(cap.arm.derivative(cap.x, u=u), loaded.derivative(cap.x, u=u))
    q = cap.x[7:7 + robot.dof]
    assert np.array_equal(cap.arm.robot.mass_matrix(q), loaded.robot.mass_matrix(q))
    assert cap.arm.robot.total_mass == pytest.approx(robot.total_mass + target.mass, rel=1e-14)
    assert cap.ee == robot.ee_links.index(ee)
    # the payload is the target where it was: its COM at the same inertial point
    e_pose = arm.ee_pose(x, ee=ee)
    com_inertial = e_pose[:3] + quat_to_matrix(e_pose[3:]) @ cap.payload_com
    t = target.pose
    assert np.allclose(com_inertial, t[:3] + quat_to_matrix(t[3:]) @ target.com, rtol=0, atol=1e-12)


def test_no_relative_twist_no_loss():
    name, robot, pr, ee = CASES[0]
    arm = orbitflex.FlexibleArm(robot, _joints(robot.dof))
    rng = np.random.default_rng(5)
    x = _random_state(rng, arm)
    target = _random_target(rng, arm, x, ee, robot.total_mass)
    probe = orbitflex.capture(arm, x, target)
    assert probe.energy_loss > 0
    # the target moving with the EE: its twist is the EE's just after a capture of it
    moving = target.at_state(np.concatenate([target.pose, probe.target_twist]))
    # capture the moving target with the arm in its post-capture state: nothing to stop
    again = orbitflex.capture(arm, probe.x, moving)
    e = arm.energy(probe.x) + moving.kinetic_energy()
    assert again.energy_loss < 1e-24 * e
    assert np.linalg.norm(again.impulse) < 1e-12 * np.linalg.norm(target.momentum() + arm.momentum(x))


def test_target_values_and_free_motion():
    inertia = np.array([[40.0, 1.0, 0.0], [1.0, 50.0, 2.0], [0.0, 2.0, 60.0]])
    pose = [1.0, 2.0, 3.0, 0.0, 0.0, np.sin(0.3), np.cos(0.3)]
    twist = [0.01, -0.02, 0.035, 0.1, 0.0, -0.05]
    grasp = [0.5, 0.0, 0.2, 0.0, 0.0, 0.0, 1.0]
    t = orbitflex.Target(200.0, inertia, pose, twist, grasp, com=[0.1, 0.0, 0.0], name="client")
    assert t.name == "client" and t.mass == 200.0
    assert np.array_equal(t.inertia, inertia) and np.array_equal(t.com, [0.1, 0.0, 0.0])
    assert np.allclose(t.pose, pose, rtol=0, atol=1e-15) and np.array_equal(t.twist, twist)
    assert np.array_equal(t.state, np.concatenate([t.pose, twist]))
    # momentum by hand: L = R m (v + ω × c), K = R (I_o ω + m c × v) + r × L
    r = quat_to_matrix(pose[3:])
    c, w, v = np.array([0.1, 0, 0]), np.array(twist[:3]), np.array(twist[3:])
    lin = r @ (200.0 * (v + np.cross(w, c)))
    i_o = inertia + 200.0 * (c @ c * np.eye(3) - np.outer(c, c))
    ang = r @ (i_o @ w + 200.0 * np.cross(c, v)) + np.cross(pose[:3], lin)
    assert np.allclose(t.momentum(), np.concatenate([ang, lin]), rtol=1e-13, atol=0)
    v_c = v + np.cross(w, c)
    energy = 0.5 * w @ inertia @ w + 0.5 * 200.0 * v_c @ v_c
    assert t.kinetic_energy() == pytest.approx(energy, rel=1e-13)
    # RK4 on the derivative keeps momentum and energy up to its O(dt⁴) error: halving dt cuts
    # the drift by ~16 (a wrong derivative would leave an O(1) drift that does not shrink)
    def drift(dt, duration=100.0):
        s = t.state.copy()
        for _ in range(int(round(duration / dt))):
            k1 = t.at_state(s).derivative()
            k2 = t.at_state(s + dt / 2 * k1).derivative()
            k3 = t.at_state(s + dt / 2 * k2).derivative()
            k4 = t.at_state(s + dt * k3).derivative()
            s = s + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        moved = t.at_state(s)
        return (np.linalg.norm(moved.momentum() - t.momentum()) / np.linalg.norm(t.momentum()),
                abs(moved.kinetic_energy() - t.kinetic_energy()) / t.kinetic_energy())
    coarse, fine = drift(1.0), drift(0.5)
    assert fine[0] < 1e-7 and fine[1] < 1e-7, fine
    assert coarse[0] / fine[0] > 10 and coarse[1] / fine[1] > 10, (coarse, fine)
    # the handle's inertial pose
    g = t.grasp_pose()
    assert np.allclose(g[:3], np.array(pose[:3]) + r @ np.array(grasp[:3]), rtol=0, atol=1e-14)
    assert "client" in repr(t)
    # a target pickles (process pools, Dask workers) to the same values
    import pickle

    back = pickle.loads(pickle.dumps(t))
    for attr in ("name", "mass", "inertia", "com", "pose", "twist", "grasp"):
        assert np.array_equal(getattr(back, attr), getattr(t, attr)), attr


@pytest.mark.parametrize(
    "kwargs,message",
    [
        (dict(mass=0.0), "target 'target': mass: expected a mass > 0 kg (a free body), given 0"),
        (dict(mass="heavy"), "target 'target': mass: expected a real number"),
        (dict(inertia=[[1, 2, 0], [0, 1, 0], [0, 0, 1]]), "target 'target': inertia: inertia matrix is not symmetric"),
        (dict(inertia=np.diag([1.0, 1.0, 5.0])), "violates the triangle inequality"),
        (dict(inertia=np.diag([-1.0, 2.0, 2.0])), "not positive definite"),
        (dict(inertia=np.diag([0.0, 2.0, 2.0])), "expected every moment > 0"),
        (dict(inertia=np.ones((2, 2))), "target 'target': inertia: expected three principal moments (3,) or a matrix (3, 3), given shape [2, 2]"),
        (dict(pose=[0, 0, 0, 0, 0, 1]), "target 'target': pose: expected length 7, given length 6"),
        (dict(pose=[0, 0, 0, 0, 0, 0, 0]), "target 'target': pose: the quaternion"),
        (dict(twist=[0, 0, np.nan, 0, 0, 0]), "target 'target': twist: element 2 is not finite"),
        (dict(grasp=[0, 0, 0, 0, 0, 0, 2.0]), "target 'target': grasp: the quaternion (elements 3..7, x y z w) has norm 2; expected a unit quaternion"),
        (dict(com=[0, 0], name="debris"), "target 'debris': com: expected length 3, given length 2"),
    ],
)
def test_bad_targets_are_named(kwargs, message):
    args = dict(mass=10.0, inertia=np.diag([1.0, 2.0, 2.5]), pose=[0, 0, 0, 0, 0, 0, 1], twist=np.zeros(6),
                grasp=[0, 0, 0, 0, 0, 0, 1])
    args.update(kwargs)
    with pytest.raises(orbitflex.ModelError) as err:
        orbitflex.Target(**args)
    assert message in str(err.value)


def test_bad_capture_arguments():
    robot = orbitflex.models.space_arm()
    arm = orbitflex.FlexibleArm(robot, _joints(robot.dof))
    x = arm.state()
    target = orbitflex.Target(10.0, np.diag([1.0, 2.0, 2.5]), arm.ee_pose(x), np.zeros(6), [0, 0, 0, 0, 0, 0, 1])
    with pytest.raises(orbitflex.ModelError, match=r"x \(state\): expected length 41, given length 40"):
        orbitflex.capture(arm, x[:-1], target)
    with pytest.raises(orbitflex.ModelError, match="no end-effector named \"nowhere\""):
        orbitflex.capture(arm, x, target, ee="nowhere")
    with pytest.raises(TypeError):
        orbitflex.capture(arm, x, "a target")
    # a target already at the EE, at rest with an arm at rest: nothing happens
    cap = orbitflex.capture(arm, x, target)
    assert cap.energy_loss == 0.0 and np.array_equal(cap.impulse, np.zeros(6)) and np.array_equal(cap.x, x)
    assert "Capture(" in repr(cap)

