"""The public Python API (docs/model.md §3–§5 and the public names): constructors, state layout, derivative, inputs
of ``simulate``, ``Trajectory`` views and files, the operator dictionary, the built-in model and
the ``.pyi`` stub.

Expected values are computed here by hand from the model's formulas (docs/model.md), or by a second route through
the API (e.g. ``step`` in a loop against ``simulate``), never copied from a run.
"""

from __future__ import annotations

import ast
import csv
import inspect
import pathlib
import textwrap

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, FlexibleJoints, MotorPD, Robot

# ---------------------------------------------------------------------------------------------
# A small, deliberately irregular 3-joint chain (tilted axes, offset COMs, rotated COM frames)
# ---------------------------------------------------------------------------------------------

URDF = """<?xml version="1.0"?>
<robot name="tilted3">
  <link name="bus">
    <inertial><origin xyz="0.02 -0.01 0.03" rpy="0 0 0"/><mass value="40"/>
      <inertia ixx="4" ixy="0.1" ixz="0" iyy="5" iyz="0.2" izz="6"/></inertial>
  </link>
  <link name="upper">
    <inertial><origin xyz="0.3 0.02 0" rpy="0.1 0.2 0.3"/><mass value="3"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.11"/></inertial>
  </link>
  <link name="fore">
    <inertial><origin xyz="0.25 0 0.01" rpy="0 0 0"/><mass value="2"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial>
  </link>
  <link name="hand">
    <inertial><origin xyz="0.05 0 0" rpy="0 0 0"/><mass value="0.8"/>
      <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.003"/></inertial>
  </link>
  <link name="tool"/>
  <joint name="shoulder" type="revolute">
    <parent link="bus"/><child link="upper"/>
    <origin xyz="0.5 0 0.2" rpy="0 0.3 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="1"/>
  </joint>
  <joint name="elbow" type="continuous">
    <parent link="upper"/><child link="fore"/>
    <origin xyz="0.6 0 0" rpy="0.2 0 0"/><axis xyz="0 1 1"/>
  </joint>
  <joint name="wrist" type="revolute">
    <parent link="fore"/><child link="hand"/>
    <origin xyz="0.5 0 0" rpy="0 0 0.4"/><axis xyz="1 0 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="1"/>
  </joint>
  <joint name="tool_mount" type="fixed">
    <parent link="hand"/><child link="tool"/>
    <origin xyz="0.1 0 0" rpy="0 0 0"/>
  </joint>
</robot>
"""
NAMES = ["shoulder", "elbow", "wrist"]
n = 3
K = np.array([120.0, 90.0, 60.0])
J = np.array([0.05, 0.04, 0.02])
D = np.array([0.3, 0.2, 0.1])
BETA = np.array([0.02, 0.03, 0.01])


@pytest.fixture(scope="module")
def robot():
    return Robot.from_urdf_string(URDF)


@pytest.fixture(scope="module")
def arm(robot):
    return FlexibleArm(robot, FlexibleJoints(K, J, damping=D, motor_damping=BETA))


@pytest.fixture(scope="module")
def operator_arm(robot):
    return FlexibleArm(robot, FlexibleJoints(K, J, damping=D, motor_damping=BETA), method="operator")


def random_state(arm, seed):
    rng = np.random.default_rng(seed)
    quat = rng.normal(size=4)
    return arm.state(
        q=rng.uniform(-1, 1, n),
        theta=rng.uniform(-1, 1, n),
        qd=rng.uniform(-1, 1, n),
        theta_dot=rng.uniform(-1, 1, n),
        base_pose=np.concatenate([rng.normal(size=3), quat]),
        base_twist=rng.uniform(-0.5, 0.5, 6),
    )


def quat_to_matrix(quat):
    """Rotation (base -> inertial components) of a unit quaternion (x, y, z, w)."""
    x, y, z, w = quat
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def hamilton(a, b):
    """Hamilton product of quaternions (x, y, z, w)."""
    av, aw = np.asarray(a[:3]), a[3]
    bv, bw = np.asarray(b[:3]), b[3]
    return np.concatenate([aw * bv + bw * av + np.cross(av, bv), [aw * bw - av @ bv]])


# ---------------------------------------------------------------------------------------------
# Robot basics
# ---------------------------------------------------------------------------------------------


def test_robot_attributes(robot):
    assert robot.dof == 3
    assert robot.joint_names == NAMES
    assert robot.name == "tilted3"
    assert robot.ee_link == "tool"  # the unique leaf, through the fixed joint
    assert robot.body_names == ["bus", "upper", "fore", "hand"]
    masses = robot.body_masses
    assert masses.shape == (4,)
    np.testing.assert_allclose(masses, [40.0, 3.0, 2.0, 0.8])  # "tool" is massless, merged
    assert robot.total_mass == pytest.approx(45.8)


def test_from_urdf_equals_from_urdf_string(robot, tmp_path):
    path = tmp_path / "tilted3.urdf"
    path.write_text(URDF)
    from_file = Robot.from_urdf(str(path))
    q = np.array([0.3, -0.2, 0.5])
    np.testing.assert_array_equal(from_file.mass_matrix(q), robot.mass_matrix(q))
    assert from_file.joint_names == robot.joint_names


def test_output_shapes_and_dtypes(robot):
    q, v, qd = np.zeros(n), np.zeros(6), np.zeros(n)
    assert robot.mass_matrix(q).shape == (6 + n, 6 + n)
    assert robot.bias_forces(q, v, qd).shape == (6 + n,)
    assert robot.ee_jacobian(q).shape == (6, n)
    assert robot.ee_base_operator(q).shape == (6, 6)
    assert robot.forward_dynamics(q, v, qd, np.zeros(n)).shape == (6 + n,)
    assert robot.inverse_dynamics(q, v, qd, np.zeros(6), np.zeros(n)).shape == (6 + n,)
    assert robot.momentum([0, 0, 0, 0, 0, 0, 1], q, v, qd).shape == (6,)
    assert isinstance(robot.kinetic_energy(q, v, qd), float)
    assert robot.mass_matrix(q).dtype == np.float64


# ---------------------------------------------------------------------------------------------
# FlexibleJoints constructors
# ---------------------------------------------------------------------------------------------


def test_scalars_broadcast_to_every_joint(robot):
    joints = FlexibleJoints(150.0, 0.07)
    assert joints.stiffness == 150.0 and joints.motor_inertia == 0.07
    assert joints.damping == 0.0 and joints.motor_damping == 0.0  # defaults
    arm = FlexibleArm(robot, joints)
    k, j, d, beta = arm.parameters
    for got, want in [(k, 150.0), (j, 0.07), (d, 0.0), (beta, 0.0)]:
        assert got.shape == (n,)
        np.testing.assert_array_equal(got, np.full(n, want))


def test_arrays_and_mixed_scalars(robot):
    joints = FlexibleJoints(K, 0.05, damping=D, motor_damping=0.01)
    np.testing.assert_array_equal(joints.stiffness, K)
    np.testing.assert_array_equal(joints.damping, D)
    k, j, d, beta = FlexibleArm(robot, joints).parameters
    np.testing.assert_array_equal(k, K)
    np.testing.assert_array_equal(j, np.full(n, 0.05))
    np.testing.assert_array_equal(d, D)
    np.testing.assert_array_equal(beta, np.full(n, 0.01))
    # lists and tuples work like arrays
    k2, *_ = FlexibleArm(robot, FlexibleJoints(list(K), tuple(J))).parameters
    np.testing.assert_array_equal(k2, K)


def test_from_gear_reflects_rotor_inertia(robot):
    gear = np.array([160.0, 100.0, 50.0])
    rotor = np.array([4e-5, 3e-5, 1.5e-5])
    joints = FlexibleJoints.from_gear(K, gear, rotor, damping=D, motor_damping=BETA)
    np.testing.assert_allclose(joints.motor_inertia, gear**2 * rotor, rtol=1e-15)
    k, j, d, beta = FlexibleArm(robot, joints).parameters
    np.testing.assert_allclose(j, gear**2 * rotor, rtol=1e-15)
    np.testing.assert_array_equal(k, K)
    np.testing.assert_array_equal(d, D)
    np.testing.assert_array_equal(beta, BETA)
    scalar = FlexibleJoints.from_gear(100.0, 160.0, 4e-5)
    assert scalar.motor_inertia == pytest.approx(160.0**2 * 4e-5, rel=1e-15)
    mixed = FlexibleJoints.from_gear(100.0, gear, 2e-5)
    np.testing.assert_allclose(mixed.motor_inertia, gear**2 * 2e-5, rtol=1e-15)


TOML = """
[defaults]
stiffness = 200.0
motor_inertia = 0.06
damping = 0.5

[joints.elbow]
stiffness = 90.0
gear_ratio = 120.0
rotor_inertia = 2.5e-5
motor_damping = 0.04

[joints.wrist]
motor_inertia = 0.01
damping = 0.0
"""


def test_from_toml_defaults_and_joint_tables(robot, tmp_path):
    path = tmp_path / "params.toml"
    path.write_text(TOML)
    joints = FlexibleJoints.from_toml(str(path), robot)
    k, j, d, beta = FlexibleArm(robot, joints).parameters
    np.testing.assert_allclose(k, [200.0, 90.0, 200.0], rtol=1e-15)
    np.testing.assert_allclose(j, [0.06, 120.0**2 * 2.5e-5, 0.01], rtol=1e-15)
    np.testing.assert_allclose(d, [0.5, 0.5, 0.0], rtol=1e-15)
    np.testing.assert_allclose(beta, [0.0, 0.04, 0.0], rtol=1e-15)
    # pathlib paths and TOML text give the same parameters
    same = FlexibleJoints.from_toml(path, robot)
    text = FlexibleJoints.from_toml_string(TOML, robot)
    for other in (same, text):
        for a, b in zip(FlexibleArm(robot, other).parameters, (k, j, d, beta)):
            np.testing.assert_array_equal(a, b)


def test_from_toml_gear_in_defaults(robot):
    joints = FlexibleJoints.from_toml_string(
        "[defaults]\nstiffness = 50.0\ngear_ratio = 80.0\nrotor_inertia = 1e-5\n", robot
    )
    np.testing.assert_allclose(joints.motor_inertia, np.full(n, 80.0**2 * 1e-5), rtol=1e-15)


# ---------------------------------------------------------------------------------------------
# arm.state
# ---------------------------------------------------------------------------------------------


def test_state_defaults(arm):
    x = arm.state()
    assert x.shape == (13 + 4 * n,) == (arm.state_size,)
    assert arm.dof == n
    expected = np.zeros(13 + 4 * n)
    expected[6] = 1.0  # identity quaternion, w last
    np.testing.assert_array_equal(x, expected)


def test_state_places_each_block(arm):
    q = np.array([0.1, 0.2, 0.3])
    theta = np.array([0.4, 0.5, 0.6])
    qd = np.array([0.7, 0.8, 0.9])
    td = np.array([1.0, 1.1, 1.2])
    pose = np.array([1.0, 2.0, 3.0, 0.0, 0.0, np.sin(0.2), np.cos(0.2)])
    twist = np.array([0.01, 0.02, 0.03, 0.4, 0.5, 0.6])
    x = arm.state(q=q, theta=theta, qd=qd, theta_dot=td, base_pose=pose, base_twist=twist)
    np.testing.assert_array_equal(x[0:7], pose)
    np.testing.assert_array_equal(x[7:10], q)
    np.testing.assert_array_equal(x[10:13], theta)
    np.testing.assert_array_equal(x[13:19], twist)
    np.testing.assert_array_equal(x[19:22], qd)
    np.testing.assert_array_equal(x[22:25], td)


def test_state_theta_defaults_to_q(arm):
    q = np.array([0.3, -0.1, 0.7])
    x = arm.state(q=q)
    np.testing.assert_array_equal(x[7:10], q)
    np.testing.assert_array_equal(x[10:13], q)  # relaxed springs
    y = arm.state(theta=q)  # theta alone leaves q at zero
    np.testing.assert_array_equal(y[7:10], np.zeros(n))
    np.testing.assert_array_equal(y[10:13], q)


def test_state_normalises_the_quaternion(arm):
    x = arm.state(base_pose=[0, 0, 0, 0, 0, 0, 2.0])
    np.testing.assert_array_equal(x[3:7], [0, 0, 0, 1.0])
    raw = np.array([0.3, -0.4, 1.2, 2.0])
    x = arm.state(base_pose=np.concatenate([[1.0, 2.0, 3.0], raw]))
    np.testing.assert_allclose(x[3:7], raw / np.linalg.norm(raw), rtol=1e-15)
    np.testing.assert_array_equal(x[0:3], [1.0, 2.0, 3.0])


# ---------------------------------------------------------------------------------------------
# derivative (model §4)
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_derivative_layout_and_motor_equation(arm, robot, seed):
    x = random_state(arm, seed)
    rng = np.random.default_rng(100 + seed)
    u = rng.normal(size=n)
    fb = rng.normal(size=6)
    f = rng.normal(size=6)
    xdot = arm.derivative(x, u, fb, f)
    assert xdot.shape == x.shape

    r, quat, q, theta = x[0:3], x[3:7], x[7:10], x[10:13]
    omega, v, qd, td = x[13:16], x[16:19], x[19:22], x[22:25]

    # configuration block: rates
    np.testing.assert_allclose(xdot[0:3], quat_to_matrix(quat) @ v, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(xdot[3:7], 0.5 * hamilton(quat, np.append(omega, 0.0)),
                               rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(xdot[7:10], qd)  # q̇ block is the qd part of x
    np.testing.assert_array_equal(xdot[10:13], td)  # θ̇ block is the theta_dot part of x

    # motor side by hand: θ̈ = (u − τ − β θ̇) / j, τ = k (θ − q) + d (θ̇ − q̇)
    tau = K * (theta - q) + D * (td - qd)
    np.testing.assert_allclose(xdot[22:25], (u - tau - BETA * td) / J, rtol=1e-13)

    # link side: the rigid forward dynamics driven by the spring torque
    acc = robot.forward_dynamics(q, x[13:19], qd, tau, base_wrench=fb, ee_wrench=f)
    np.testing.assert_allclose(xdot[13:16], acc[0:3], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(xdot[16:19], acc[3:6] - np.cross(omega, v), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(xdot[19:22], acc[6:], rtol=1e-12, atol=1e-12)


def test_derivative_defaults_are_zero_inputs(arm):
    x = random_state(arm, 7)
    np.testing.assert_array_equal(arm.derivative(x), arm.derivative(x, np.zeros(n), np.zeros(6), np.zeros(6)))


# ---------------------------------------------------------------------------------------------
# step and simulate
# ---------------------------------------------------------------------------------------------

DT = 1e-3


def test_step_equals_simulate_one_step(arm):
    # Identity attitude: simulate's renormalisation of x0 is exact, so the results are identical.
    x = arm.state(q=[0.1, 0.2, -0.3], theta=[0.2, 0.1, -0.2], qd=[0.1, 0.0, 0.3],
                  theta_dot=[0.0, -0.2, 0.1], base_twist=[0.01, -0.02, 0.03, 0.1, 0.2, -0.1])
    u, fb, f = np.array([0.5, -0.2, 0.1]), np.arange(6) * 0.1, np.arange(6) * -0.05
    stepped = arm.step(x, DT, u, fb, f)
    traj = arm.simulate(x, DT, 1, u=u, base_wrench=fb, ee_wrench=f)
    assert traj.x.shape == (2, arm.state_size)
    np.testing.assert_array_equal(traj.x[0], x)
    np.testing.assert_array_equal(traj.x[1], stepped)
    np.testing.assert_array_equal(traj.t, [0.0, DT])
    # Any attitude: equal up to the renormalisation of x0's quaternion (round-off).
    x = random_state(arm, 11)
    traj = arm.simulate(x, DT, 1, u=u, base_wrench=fb, ee_wrench=f)
    np.testing.assert_allclose(traj.x[1], arm.step(x, DT, u, fb, f), rtol=1e-14, atol=1e-15)


def test_step_keeps_unit_quaternion(arm):
    x = random_state(arm, 12)
    y = arm.step(x, 0.01)
    assert np.linalg.norm(y[3:7]) == pytest.approx(1.0, abs=1e-15)


def test_simulate_zero_steps(arm):
    x = random_state(arm, 13)
    traj = arm.simulate(x, DT, 0)
    assert traj.x.shape == (1, arm.state_size)
    np.testing.assert_allclose(traj.x[0], x, rtol=1e-15, atol=1e-16)
    np.testing.assert_array_equal(traj.t, [0.0])


def test_simulate_none_equals_zero_input(arm):
    x = random_state(arm, 14)
    a = arm.simulate(x, DT, 10)
    b = arm.simulate(x, DT, 10, u=np.zeros(n), base_wrench=np.zeros(6), ee_wrench=np.zeros(6))
    np.testing.assert_array_equal(a.x, b.x)


def test_simulate_constant_table_and_callable_agree(arm):
    x = random_state(arm, 15)
    u = np.array([0.3, -0.1, 0.05])
    steps = 12
    const = arm.simulate(x, DT, steps, u=u)
    table = arm.simulate(x, DT, steps, u=np.tile(u, (steps, 1)))
    func = arm.simulate(x, DT, steps, u=lambda t, s: u)
    np.testing.assert_array_equal(const.x, table.x)
    np.testing.assert_array_equal(const.x, func.x)
    np.testing.assert_allclose(const.t, np.arange(steps + 1) * DT, rtol=1e-15)


def test_simulate_per_step_tables_equal_a_loop_of_steps(arm):
    x0 = random_state(arm, 16)
    steps = 8
    rng = np.random.default_rng(16)
    u = rng.normal(size=(steps, n))
    fb = rng.normal(size=(steps, 6))
    f = rng.normal(size=(steps, 6))
    traj = arm.simulate(x0, DT, steps, u=u, base_wrench=fb, ee_wrench=f)
    x = x0
    for k in range(steps):
        x = arm.step(x, DT, u[k], fb[k], f[k])
        np.testing.assert_array_equal(traj.x[k + 1], x)


def test_callable_is_called_once_per_step_with_t_and_x(arm):
    x0 = random_state(arm, 17)
    steps = 15
    seen = []

    def controller(t, x):
        seen.append((t, np.array(x, copy=True)))
        return -0.5 * x[22:25] + 0.01 * t

    traj = arm.simulate(x0, DT, steps, u=controller)
    assert len(seen) == steps
    times = np.array([t for t, _ in seen])
    np.testing.assert_allclose(times, np.arange(steps) * DT, rtol=1e-15, atol=0)
    for k, (_, x) in enumerate(seen):
        assert x.shape == (arm.state_size,)
        np.testing.assert_array_equal(x, traj.x[k])  # the state at the start of step k
    # and the torques are applied as returned
    x = x0
    for k in range(steps):
        x = arm.step(x, DT, -0.5 * x[22:25] + 0.01 * k * DT)
    np.testing.assert_array_equal(traj.x[-1], x)


def test_motor_pd_with_constant_references(arm):
    x0 = random_state(arm, 18)
    kp = np.array([10.0, 20.0, 30.0])
    kd = np.array([1.0, 2.0, 3.0])
    ref = np.array([0.3, 0.2, 0.1])
    rate = np.array([0.01, -0.02, 0.0])
    ff = np.array([0.1, 0.0, -0.1])
    pd = MotorPD(kp, kd, ref, theta_dot_ref=rate, feedforward=ff)
    assert pd.dof == n
    a = arm.simulate(x0, DT, 20, u=pd)
    b = arm.simulate(x0, DT, 20,
                     u=lambda t, x: kp * (ref - x[10:13]) + kd * (rate - x[22:25]) + ff)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-14)
    # scalar gains broadcast, missing rate and feedforward are zero
    c = arm.simulate(x0, DT, 20, u=MotorPD(5.0, 0.5, ref))
    d = arm.simulate(x0, DT, 20, u=lambda t, x: 5.0 * (ref - x[10:13]) - 0.5 * x[22:25])
    np.testing.assert_allclose(c.x, d.x, rtol=0, atol=1e-14)


def test_motor_pd_with_tabulated_references(arm):
    x0 = random_state(arm, 19)
    steps = 20
    s = np.linspace(0.0, 1.0, steps)
    ref = np.outer(s, [0.4, -0.3, 0.2])
    rate = np.outer(np.full(steps, 1.0), [0.4, -0.3, 0.2])
    ff = np.outer(np.sin(s), [0.1, 0.1, 0.1])
    kp, kd = 15.0, np.array([1.0, 1.5, 2.0])
    pd = MotorPD(kp, kd, ref, theta_dot_ref=rate, feedforward=ff)
    a = arm.simulate(x0, DT, steps, u=pd)

    def by_hand(t, x):
        k = int(round(t / DT))
        return kp * (ref[k] - x[10:13]) + kd * (rate[k] - x[22:25]) + ff[k]

    b = arm.simulate(x0, DT, steps, u=by_hand)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-14)
    # extra rows are allowed: only the first `steps` are used
    c = arm.simulate(x0, DT, steps - 5, u=pd)
    np.testing.assert_array_equal(c.x, a.x[: steps - 4])


# ---------------------------------------------------------------------------------------------
# Trajectory
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def traj(arm):
    x0 = random_state(arm, 21)
    return arm.simulate(x0, DT, 25, u=np.array([0.2, -0.1, 0.3]))


VIEWS = {
    "base_pose": (0, 7),
    "q": (7, 7 + n),
    "theta": (7 + n, 7 + 2 * n),
    "base_twist": (7 + 2 * n, 13 + 2 * n),
    "qd": (13 + 2 * n, 13 + 3 * n),
    "theta_dot": (13 + 3 * n, 13 + 4 * n),
}


@pytest.mark.parametrize("name", list(VIEWS))
def test_trajectory_views_are_slices_of_x(traj, name):
    start, stop = VIEWS[name]
    view = getattr(traj, name)
    assert view.shape == (26, stop - start)
    np.testing.assert_array_equal(view, traj.x[:, start:stop])
    assert np.shares_memory(view, traj.x)


def test_trajectory_basics(traj):
    assert len(traj) == 26
    assert traj.t.shape == (26,)
    assert traj.x.shape == (26, 13 + 4 * n)
    assert "Trajectory" in repr(traj)


def test_deflection_and_spring_torque(traj):
    np.testing.assert_array_equal(traj.deflection, traj.theta - traj.q)
    want = K * (traj.x[:, 10:13] - traj.x[:, 7:10]) + D * (traj.x[:, 22:25] - traj.x[:, 19:22])
    np.testing.assert_allclose(traj.spring_torque, want, rtol=1e-14, atol=1e-15)


def test_diagnostics_shapes_and_values(traj, arm, robot):
    rows = len(traj)
    assert traj.momentum.shape == (rows, 6)
    assert traj.energy.shape == (rows,)
    assert traj.ee_pose.shape == (rows, 7)
    for k in (0, rows // 2, rows - 1):
        x = traj.x[k]
        np.testing.assert_allclose(traj.momentum[k], arm.momentum(x), rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(
            traj.momentum[k], robot.momentum(x[0:7], x[7:10], x[13:19], x[19:22]),
            rtol=1e-12, atol=1e-13,
        )
        np.testing.assert_allclose(traj.ee_pose[k], arm.ee_pose(x), rtol=1e-14, atol=1e-15)
        # energy by hand (model §6.2)
        e = (robot.kinetic_energy(x[7:10], x[13:19], x[19:22])
             + 0.5 * J @ x[22:25] ** 2 + 0.5 * K @ (x[10:13] - x[7:10]) ** 2)
        assert traj.energy[k] == pytest.approx(e, rel=1e-12)
        assert arm.energy(x) == pytest.approx(e, rel=1e-12)
    np.testing.assert_allclose(np.linalg.norm(traj.ee_pose[:, 3:], axis=1), 1.0, atol=1e-12)


def test_column_names(traj):
    names = traj.column_names()
    assert len(names) == traj.x.shape[1]
    assert names[:7] == ["r_x", "r_y", "r_z", "quat_x", "quat_y", "quat_z", "quat_w"]
    assert names[7:10] == [f"q[{j}]" for j in NAMES]
    assert names[10:13] == [f"theta[{j}]" for j in NAMES]
    assert names[13:19] == ["omega_x", "omega_y", "omega_z", "v_x", "v_y", "v_z"]
    assert names[19:22] == [f"qd[{j}]" for j in NAMES]
    assert names[22:25] == [f"theta_dot[{j}]" for j in NAMES]


def test_save_npz_round_trip(traj, tmp_path):
    path = tmp_path / "run.npz"
    traj.save_npz(path)
    with np.load(path) as data:
        np.testing.assert_array_equal(data["t"], traj.t)
        np.testing.assert_array_equal(data["x"], traj.x)
        assert list(data["columns"]) == traj.column_names()
        np.testing.assert_array_equal(data["momentum"], traj.momentum)
        np.testing.assert_array_equal(data["energy"], traj.energy)
        np.testing.assert_array_equal(data["ee_pose"], traj.ee_pose)


def test_save_csv_round_trip(traj, tmp_path):
    path = tmp_path / "run.csv"
    traj.save_csv(path)
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    assert header[0] == "t"
    assert header[1:] == traj.column_names()
    assert "q[elbow]" in header and "theta_dot[wrist]" in header
    values = np.array(rows[1:], dtype=float)
    assert values.shape == (len(traj), 1 + traj.x.shape[1])
    np.testing.assert_array_equal(values[:, 0], traj.t)  # lossless (repr of floats)
    np.testing.assert_array_equal(values[:, 1:], traj.x)


# ---------------------------------------------------------------------------------------------
# operators (model §2, §8) and agreement of the two methods
# ---------------------------------------------------------------------------------------------


def test_operators_keys_and_shapes(robot):
    rng = np.random.default_rng(3)
    q, v, qd = rng.normal(size=n), rng.normal(size=6), rng.normal(size=n)
    ops = robot.operators(q, v, qd)
    six_n = 6 * n
    expected = {
        "Phi": (six_n, six_n), "H": (six_n, n), "M": (six_n, six_n),
        "a": (six_n,), "b": (six_n,), "B": (six_n, 6),
        "Phi_hat1": (six_n, 6), "Phi_hat2": (6, six_n),
        "M_b": (6, 6), "M_rb": (6, n), "M_br": (n, 6), "M_r": (n, n),
        "C_B": (6,), "C_r": (n,), "J": (6, n),
    }
    missing = set(expected) - set(ops)
    assert not missing, f"operators() lacks {sorted(missing)}"
    for key, shape in expected.items():
        assert isinstance(ops[key], np.ndarray) and ops[key].dtype == np.float64, key
        assert ops[key].shape == shape, (key, ops[key].shape)

    # The blocks agree with the other entry points and with their defining products (A.16).
    mm = robot.mass_matrix(q)
    np.testing.assert_allclose(ops["M_b"], mm[:6, :6], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(ops["M_rb"], mm[:6, 6:], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(ops["M_br"], mm[6:, :6], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(ops["M_r"], mm[6:, 6:], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(ops["M_br"], ops["M_rb"].T, rtol=1e-12, atol=1e-12)
    c = robot.bias_forces(q, v, qd)
    np.testing.assert_allclose(np.concatenate([ops["C_B"], ops["C_r"]]), c, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(ops["J"], robot.ee_jacobian(q), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(ops["J"], ops["B"].T @ ops["Phi"] @ ops["H"], rtol=1e-10, atol=1e-12)
    H, Phi, M = ops["H"], ops["Phi"], ops["M"]
    np.testing.assert_allclose(ops["M_r"], H.T @ Phi.T @ M @ Phi @ H, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(ops["M_rb"], ops["Phi_hat2"] @ M @ Phi @ H, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(ops["Phi_hat2"], ops["Phi_hat1"].T, rtol=0, atol=0)


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_operator_method_equals_recursive(robot, seed):
    rng = np.random.default_rng(seed)
    q, v, qd = rng.uniform(-2, 2, n), rng.normal(size=6), rng.normal(size=n)
    tau, fb, f = rng.normal(size=n), rng.normal(size=6), rng.normal(size=6)
    acc, qdd = rng.normal(size=6), rng.normal(size=n)
    pairs = [
        ("mass_matrix", (q,), {}),
        ("bias_forces", (q, v, qd), {}),
        ("forward_dynamics", (q, v, qd, tau), {"base_wrench": fb, "ee_wrench": f}),
        ("inverse_dynamics", (q, v, qd, acc, qdd), {"ee_wrench": f}),
    ]
    for name, args, kwargs in pairs:
        fn = getattr(robot, name)
        a = fn(*args, **kwargs, method="recursive")
        b = fn(*args, **kwargs, method="operator")
        np.testing.assert_allclose(b, a, rtol=1e-10, atol=1e-10, err_msg=name)
    default = robot.forward_dynamics(q, v, qd, tau, base_wrench=fb, ee_wrench=f)
    np.testing.assert_array_equal(
        default, robot.forward_dynamics(q, v, qd, tau, base_wrench=fb, ee_wrench=f, method="recursive"))


def test_operator_arm_equals_recursive_arm(arm, operator_arm):
    assert arm.method == "recursive" and operator_arm.method == "operator"
    x = random_state(arm, 31)
    u = np.array([0.2, -0.3, 0.1])
    np.testing.assert_allclose(operator_arm.derivative(x, u), arm.derivative(x, u), rtol=1e-10, atol=1e-10)
    a = arm.simulate(x, DT, 10, u=u)
    b = operator_arm.simulate(x, DT, 10, u=u)
    np.testing.assert_allclose(b.x, a.x, rtol=1e-10, atol=1e-10)


# ---------------------------------------------------------------------------------------------
# Built-in model
# ---------------------------------------------------------------------------------------------


def test_space_arm():
    robot = orbitflex.models.space_arm()
    assert robot.dof == 7
    assert len(robot.joint_names) == 7
    assert robot.total_mass == pytest.approx(586.0, abs=1.0)
    assert robot.ee_link == "ee"
    from_text = Robot.from_urdf_string(orbitflex.models.space_arm_urdf())
    assert from_text.joint_names == robot.joint_names
    q = np.linspace(-0.5, 0.5, 7)
    np.testing.assert_allclose(from_text.mass_matrix(q), robot.mass_matrix(q), rtol=1e-14)
    assert orbitflex.SPACE_ARM_URDF == orbitflex.models.space_arm_urdf()
    arm = FlexibleArm(robot, orbitflex.models.space_arm_joints())
    assert arm.state_size == 13 + 28
    limit = arm.rk4_stability_limit().dt
    assert 1e-3 < limit < 0.1  # the CLI's default dt of 1 ms is stable


def test_public_names():
    for name in ["Robot", "FlexibleJoints", "FlexibleArm", "MotorPD", "Trajectory",
                 "ModelError", "SimulationError", "models", "SPACE_ARM_URDF", "__version__"]:
        assert hasattr(orbitflex, name), name
        assert name in orbitflex.__all__
    assert issubclass(orbitflex.FlexibleArm, orbitflex._core.FlexibleArm)


# ---------------------------------------------------------------------------------------------
# The .pyi stub lists everything the binary exports
# ---------------------------------------------------------------------------------------------

STUB = pathlib.Path(orbitflex.__file__).with_name("_core.pyi")
SOURCE_STUB = pathlib.Path(__file__).resolve().parents[2] / "python" / "orbitflex" / "_core.pyi"


def stub_tree():
    for path in (SOURCE_STUB, STUB):
        if path.exists():
            return path, ast.parse(path.read_text())
    pytest.skip(f"no .pyi stub yet: neither {SOURCE_STUB} nor {STUB} exists")


def assigned_names(body):
    names = set()
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
        elif isinstance(node, (ast.ImportFrom, ast.Import)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    return names


def test_stub_lists_module_attributes():
    path, tree = stub_tree()
    core = orbitflex._core
    public = {name for name in dir(core) if not name.startswith("_")} | {"__version__"}
    missing = public - assigned_names(tree.body)
    assert not missing, f"{path} lacks {sorted(missing)}"


def test_stub_lists_class_members():
    path, tree = stub_tree()
    core = orbitflex._core
    classes = {node.name: node for node in tree.body if isinstance(node, ast.ClassDef)}
    problems = []
    for name in dir(core):
        cls = getattr(core, name)
        if name.startswith("_") or not inspect.isclass(cls) or issubclass(cls, BaseException):
            continue
        if name not in classes:
            problems.append(f"class {name}")
            continue
        listed = assigned_names(classes[name].body)
        for member in vars(cls):
            if member.startswith("_"):
                continue
            if member not in listed:
                problems.append(f"{name}.{member}")
    assert not problems, f"{path} lacks {sorted(set(problems))}"
