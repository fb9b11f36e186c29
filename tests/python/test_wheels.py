"""Reaction wheels on the bus (docs/model.md, "Reaction wheels"), from Python.

The oracle: Pinocchio's ``aba`` on ``wheels.to_urdf(robot)``, where each wheel is a link on a
continuous joint of the root (joint rate ``Ω``, joint torque ``u_w − c Ω``), after the convention
map of pin_helpers.py. orbitflex's side is the robot loaded from the original URDF with the
wheels in closed form, so a mistake in the URDF writer shows as a mismatch too.

Bounds. The kinematic and motor blocks (``ṙ, quat', q̇, θ̇, θ̈``) are closed forms checked
against numpy to 1e-12 relative. The accelerations ``[α_B; q̈; Ω̇]``: Pinocchio carries each
wheel's gyroscopic terms ``J_s Ω ω`` (up to 0.1 · 600 · 2 ≈ 1e2 N·m here) through its bias
forces, where they cancel against the bus's ``ω × h`` only to round-off (ε · 1e2 ≈ 2e-14 N·m),
amplified by at most the inverse of the smallest articulated inertia (the wheels' ``J_s`` ≥ 1e-2
kg·m²): ≈ 2e-12 rad/s² against accelerations of order 1 and more. 1e-10 relative (the issue's
bound) leaves a margin of about 50; the measured worst case is printed.
"""

from __future__ import annotations

import pickle

import numpy as np
import pinocchio as pin
import pytest

import orbitflex
from pin_helpers import PinRobot, quat_to_matrix, random_quaternion
from tree_gen import random_tree
from urdf_gen import random_chain


def random_wheels(rng, k, limit=1.0):
    axes = rng.normal(size=(k, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    spin = rng.uniform(0.01, 0.1, k)
    return orbitflex.ReactionWheels(
        axes,
        rng.uniform(-0.8, 0.8, (k, 3)),
        rng.uniform(1.0, 10.0, k),
        spin,
        spin * rng.uniform(0.5, 1.0, k),
        max_torque=limit,
        max_speed=1e4,
        friction=rng.uniform(0.0, 0.01, k),
    )


def pyramid():
    """Four wheels in a pyramid, 54.7° from the base z axis."""
    phi = np.pi / 2 * np.arange(4) + 0.3
    axes = np.column_stack([np.sqrt(2 / 3) * np.cos(phi), np.sqrt(2 / 3) * np.sin(phi), np.full(4, np.sqrt(1 / 3))])
    positions = np.column_stack([0.3 * np.cos(phi), 0.3 * np.sin(phi), np.full(4, -0.4)])
    return orbitflex.ReactionWheels(axes, positions, 4.0, 0.04, 0.025, 0.2, 600.0)


def cases():
    out = [("space_arm", orbitflex.Robot.space_arm(), None)]
    for seed in range(3):
        chain = random_chain(seed)
        out.append((f"chain {seed}", orbitflex.Robot.from_urdf_string(chain.xml, ee_link=chain.ee_link), chain.ee_link))
        tree = random_tree(seed)
        robot = orbitflex.Robot.from_urdf_string(tree.xml)
        out.append((f"tree {seed}", robot, None))
    return out


@pytest.mark.parametrize("name,robot,ee_link", cases(), ids=lambda v: v if isinstance(v, str) else "")
def test_derivative_equals_pinocchio_aba_on_the_wheels_as_links(name, robot, ee_link):
    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    worst = 0.0
    for trial in range(3):
        n, k = robot.dof, 1 + 2 * trial
        wheels = random_wheels(rng, k)
        joints = orbitflex.FlexibleJoints(rng.uniform(200, 800, n), rng.uniform(0.1, 1, n), rng.uniform(0, 0.2, n), rng.uniform(0, 0.5, n))
        arm = orbitflex.FlexibleArm(robot, joints, wheels=wheels)
        assert arm.robot is robot
        s = arm.state_slices
        x = arm.state(
            q=rng.uniform(-3, 3, n),
            theta=rng.uniform(-3, 3, n),
            qd=rng.normal(0, 1, n),
            theta_dot=rng.normal(0, 1, n),
            base_pose=np.concatenate([rng.normal(0, 1, 3), random_quaternion(rng)]),
            base_twist=rng.normal(0, 1, 6),
            wheel_speed=rng.uniform(-600, 600, k),
        )
        u, u_w, fb = rng.normal(0, 5, n), rng.uniform(-0.9, 0.9, k), rng.normal(0, 5, 6)
        fe = rng.normal(0, 2, 6) if ee_link else None
        xdot = arm.derivative(x, u, base_wrench=fb, ee_wrench=fe, wheel_torque=u_w)
        assert xdot.shape == (arm.state_size,) == (13 + 4 * n + k,)

        # Pinocchio on the URDF with the wheels as links
        names = [f"reaction_wheel_{w}_spin" for w in range(k)]
        pin_robot = PinRobot(list(robot.joint_names) + names, ee_link or robot.ee_links[0], xml=wheels.to_urdf(robot))
        stretch, stretch_rate = x[s["theta"]] - x[s["q"]], x[s["theta_dot"]] - x[s["qd"]]
        k_, j_, d_, beta = arm.parameters
        tau = k_ * stretch + d_ * stretch_rate
        speed = x[s["wheel_speed"]]
        want = pin_robot.forward_dynamics(
            np.concatenate([x[s["q"]], rng.uniform(-3, 3, k)]),
            x[s["base_twist"]],
            np.concatenate([x[s["qd"]], speed]),
            np.concatenate([tau, u_w - wheels.friction * speed]),
            base_wrench=fb,
            ee_wrench=fe,
        )
        w, v = x[s["base_twist"]][:3], x[s["base_twist"]][3:]
        twist_rate = xdot[s["base_twist"]]
        got = np.concatenate([twist_rate[:3], twist_rate[3:] + np.cross(w, v), xdot[s["qd"]], xdot[s["wheel_speed"]]])
        err = np.max(np.abs(got - want)) / max(1.0, np.max(np.abs(want)))
        assert err < 1e-10, (name, trial, err)
        worst = max(worst, err)

        # kinematic and motor blocks, closed forms
        quat = x[3:7]
        rate = np.concatenate([0.5 * (quat[3] * w + np.cross(quat[:3], w)), [-0.5 * quat[:3] @ w]])
        motor = (u - tau - beta * x[s["theta_dot"]]) / j_
        for got_, want_ in [
            (xdot[0:3], quat_to_matrix(quat) @ v),
            (xdot[3:7], rate),
            (xdot[s["q"]], x[s["qd"]]),
            (xdot[s["theta"]], x[s["theta_dot"]]),
            (xdot[s["theta_dot"]], motor),
        ]:
            assert np.max(np.abs(got_ - want_)) <= 1e-12 * max(1.0, np.max(np.abs(want_)))
    print(f"{name}: worst relative acceleration error {worst:.2e}")


def test_the_pinocchio_model_of_to_urdf_is_the_robot_without_wheels():
    """The writer alone: Pinocchio's mass matrix and bias forces of ``robot.to_urdf()`` (no wheels)
    equal those of the original file, on a chain with fixed links and revolute limits."""
    chain = random_chain(5)
    robot = orbitflex.Robot.from_urdf_string(chain.xml, ee_link=chain.ee_link)
    original = PinRobot(chain.joint_names, chain.ee_link, xml=chain.xml)
    again = PinRobot(list(robot.joint_names), chain.ee_link, xml=robot.to_urdf())
    q = np.random.default_rng(1).uniform(-3, 3, robot.dof)
    m1, m2 = original.mass_matrix(q), again.mass_matrix(q)
    assert np.max(np.abs(m1 - m2)) < 1e-12 * np.max(np.abs(m1))
    twist, qd = np.random.default_rng(2).normal(size=6), np.random.default_rng(3).normal(size=robot.dof)
    b1, b2 = original.bias_forces(q, twist, qd), again.bias_forces(q, twist, qd)
    assert np.max(np.abs(b1 - b2)) < 1e-12 * max(1.0, np.max(np.abs(b1)))


def test_state_layout_and_run_records_with_wheels(tmp_path):
    robot = orbitflex.Robot.space_arm()
    joints = orbitflex.FlexibleJoints.space_arm()
    wheels = pyramid()
    arm = orbitflex.FlexibleArm(robot, joints, wheels=wheels)
    assert arm.wheels is wheels and arm.state_size == 45 and arm.tangent_size == 44
    assert arm.state_slices["wheel_speed"] == slice(41, 45, 1)
    plain = orbitflex.FlexibleArm(robot, joints)
    assert plain.state_slices["wheel_speed"] == slice(41, 41, 1)
    x0 = arm.state(wheel_speed=[100.0, -50.0, 0.0, 599.99])
    steps = 200
    table = np.tile([0.5, -0.1, 0.05, 0.2], (steps, 1))  # 0.5 is beyond max_torque 0.2
    traj = arm.simulate(x0, 1e-2, steps, u=np.zeros(7), wheel_torque=table)
    assert traj.u.shape == (steps, 7) and traj.wheel_torque.shape == (steps, 4)
    assert traj.wheel_speed.shape == (steps + 1, 4)
    applied = traj.wheel_torque
    assert np.all(applied[:, 0] == 0.2) and np.all(applied[:, 1] == -0.1)
    # wheel 3 starts at its speed limit: the torque that would speed it up is cut
    assert np.all(applied[traj.wheel_speed[:-1, 3] >= 600.0, 3] == 0.0)
    assert np.all(traj.wheel_speed[:, 3] < 600.0 + 0.2 * 1e-2 / 0.04 * 1.5)
    # the total momentum of bus, arm and wheels is constant (no external wrench)
    h = traj.momentum
    assert np.max(np.abs(h - h[0])) < 1e-9 * max(1.0, np.max(np.abs(h)))
    # a step by hand equals the run's first step
    x1 = arm.step(x0, 1e-2, np.zeros(7), wheel_torque=table[0])
    assert np.array_equal(x1, traj.x[1])
    # the record keeps the applied torques through pickling and the .npz
    again = pickle.loads(pickle.dumps(traj))
    assert np.array_equal(again.wheel_torque, applied) and np.array_equal(again.x, traj.x)
    assert pickle.loads(pickle.dumps(arm)).state_size == 45
    traj.save_npz(tmp_path / "run.npz")
    saved = np.load(tmp_path / "run.npz")
    assert np.array_equal(saved["wheel_torque"], applied)
    assert np.array_equal(saved["wheel_speed"], traj.wheel_speed)
    assert list(saved["columns"][-4:]) == [f"wheel_speed[{w}]" for w in range(4)]


def test_batch_with_wheels_equals_single_runs():
    arm = orbitflex.FlexibleArm(orbitflex.Robot.space_arm(), orbitflex.FlexibleJoints.space_arm(), wheels=pyramid())
    rng = np.random.default_rng(3)
    runs, steps = 3, 30
    x0s = np.stack([arm.state(q=rng.uniform(-1, 1, 7), wheel_speed=rng.uniform(-599, 599, 4)) for _ in range(runs)])
    wt = rng.uniform(-0.5, 0.5, (runs, steps, 4))
    batch = orbitflex.simulate_batch(arm, x0s, 2e-3, steps, u=rng.normal(0, 1, (runs, 7)), wheel_torque=wt, threads=2)
    assert batch.wheel_torque.shape == (runs, steps, 4) and batch.u.shape == (runs, steps, 7)
    for b in range(runs):
        single = arm.simulate(x0s[b], 2e-3, steps, u=np.asarray(batch.u[b, 0]), wheel_torque=wt[b])
        assert np.array_equal(single.x, batch.x[b])
        assert np.array_equal(single.wheel_torque, batch.wheel_torque[b])
        assert np.array_equal(batch.run(b).wheel_torque, single.wheel_torque)


def test_bad_wheels_and_wheel_torques_are_clear_errors():
    good = dict(axes=[[0, 0, 1.0]], positions=[[0, 0, 0.0]], mass=1.0, spin_inertia=0.02, transverse_inertia=0.015, max_torque=0.1, max_speed=500.0)
    with pytest.raises(orbitflex.ModelError, match=r"axes\[0\]: expected a unit vector \(norm 1 within 1e-5\), given \[0.0, 0.0, 2.0\]"):
        orbitflex.ReactionWheels(**{**good, "axes": [[0, 0, 2.0]]})
    with pytest.raises(orbitflex.ModelError, match=r"axes: expected shape \(k, 3\), one row per wheel, given shape \[3\]"):
        orbitflex.ReactionWheels(**{**good, "axes": [0, 0, 1.0]})
    with pytest.raises(orbitflex.ModelError, match=r"ReactionWheels: expected at least one wheel, given none"):
        orbitflex.ReactionWheels(**{**good, "axes": np.zeros((0, 3)), "positions": np.zeros((0, 3))})
    with pytest.raises(orbitflex.ModelError, match=r"positions: expected shape \(1, 3\)"):
        orbitflex.ReactionWheels(**{**good, "positions": np.zeros((2, 3))})
    with pytest.raises(orbitflex.ModelError, match=r"spin_inertia\[0\]: expected a finite number > 0, given -0.02"):
        orbitflex.ReactionWheels(**{**good, "spin_inertia": -0.02})
    with pytest.raises(orbitflex.ModelError, match=r"mass: expected one number per wheel \(k = 1, from axes\) or a single number, given length 2"):
        orbitflex.ReactionWheels(**{**good, "mass": [1.0, 2.0]})
    with pytest.raises(orbitflex.ModelError, match=r"friction\[0\]: expected a finite number >= 0, given NaN"):
        orbitflex.ReactionWheels(**good, friction=np.nan)
    with pytest.raises(orbitflex.ModelError, match=r"transverse_inertia\[0\]: .*triangle inequality"):
        orbitflex.ReactionWheels(**{**good, "transverse_inertia": 0.005})
    wheels = orbitflex.ReactionWheels(**good)
    robot = orbitflex.Robot.space_arm()
    arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints.space_arm(), wheels=wheels)
    plain = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints.space_arm())
    x = arm.state()
    with pytest.raises(orbitflex.ModelError, match=r"wheel_torque: expected length 1, given length 2"):
        arm.derivative(x, wheel_torque=[0.1, 0.2])
    with pytest.raises(orbitflex.ModelError, match=r"wheel_torque: expected none \(the arm has no reaction wheels\)"):
        plain.derivative(plain.state(), wheel_torque=[0.1])
    with pytest.raises(orbitflex.ModelError, match=r"wheel_torque: the arm has no reaction wheels"):
        plain.simulate(plain.state(), 1e-3, 3, wheel_torque=[0.1])
    with pytest.raises(orbitflex.ModelError, match=r"wheel_torque: expected a table of shape \(3, 1\), given shape \(2, 1\)"):
        arm.simulate(x, 1e-3, 3, wheel_torque=np.zeros((2, 1)))
    with pytest.raises(orbitflex.ModelError, match=r"x: expected length 42, given length 41"):
        arm.derivative(plain.state())
    with pytest.raises(orbitflex.ModelError, match=r"step_jacobians: not available yet for an arm with reaction wheels"):
        arm.step_jacobians(x, 1e-3)
    # the saturation rule, exposed
    assert np.array_equal(wheels.saturate([0.5], [0.0]), [0.1])
    assert np.array_equal(wheels.saturate([0.05], [500.0]), [0.0])
    assert np.array_equal(wheels.saturate([-0.05], [500.0]), [-0.05])
