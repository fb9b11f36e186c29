"""Regression tests for bugs found in review: loader hangs and panics on disconnected cycles, the
default EE with a locked gripper branch, picklable exceptions, and the stability warning for a
stiff motor PD loop."""

import pickle
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, FlexibleJoints, ModelError, MotorPD, SimulationError

LINK = '<link name="{0}"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'


def urdf(links, joints):
    body = "".join(LINK.format(name) for name in links)
    for name, kind, parent, child in joints:
        axis = '<axis xyz="0 0 1"/>' if kind != "fixed" else ""
        body += f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>{axis}</joint>'
    return f'<robot name="r">{body}</robot>'


# A root with a chain, plus two links joined to each other in a cycle, reached by nothing.
DISCONNECTED_REVOLUTE_CYCLE = urdf(
    ["base", "a", "b", "c"],
    [("j1", "revolute", "base", "a"), ("jb", "revolute", "b", "c"), ("jc", "revolute", "c", "b")],
)
DISCONNECTED_FIXED_CYCLE = urdf(
    ["base", "a", "b", "c"],
    [("j1", "revolute", "base", "a"), ("jb", "fixed", "b", "c"), ("jc", "fixed", "c", "b")],
)


@pytest.mark.parametrize("xml,ee", [(DISCONNECTED_REVOLUTE_CYCLE, "b"), (DISCONNECTED_FIXED_CYCLE, None),
                                    (DISCONNECTED_FIXED_CYCLE, "a")])
def test_disconnected_cycles_are_errors_not_hangs_or_panics(xml, ee):
    # in a subprocess: a regression would hang (the parent walk looped forever) or panic
    code = textwrap.dedent(f"""
        import orbitflex
        try:
            orbitflex.Robot.from_urdf_string({xml!r}, ee_link={ee!r})
        except orbitflex.ModelError as e:
            print("MODELERROR", e)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=20)
    assert out.returncode == 0, out.stderr
    assert "MODELERROR" in out.stdout and "not connected to the root link 'base'" in out.stdout, out.stdout
    assert "b" in out.stdout and "c" in out.stdout


def test_locked_branch_leaves_are_not_ee_candidates():
    xml = urdf(["base", "a", "tool", "jaw"],
               [("j1", "revolute", "base", "a"), ("tool_fix", "fixed", "a", "tool"), ("jaw", "prismatic", "a", "jaw")])
    # the prismatic jaw cannot move, wherever it is: the message says to lock it
    with pytest.raises(ModelError, match=r"joint 'jaw' has type 'prismatic'.*locked_joints"):
        orbitflex.Robot.from_urdf_string(xml)
    with pytest.raises(ModelError, match="lock it"):
        orbitflex.Robot.from_urdf_string(xml, ee_link="tool")
    # locked, its leaf is no end-effector: the tool is the only one
    robot = orbitflex.Robot.from_urdf_string(xml, locked_joints=["jaw"])
    assert robot.ee_link == "tool" and robot.ee_links == ["tool"] and robot.dof == 1
    # named, it is one
    robot = orbitflex.Robot.from_urdf_string(xml, locked_joints=["jaw"], ee_links=["tool", "jaw"])
    assert robot.ee_links == ["tool", "jaw"]
    assert robot.total_mass == pytest.approx(4.0)  # the locked jaw's mass is merged, not dropped


def test_exceptions_survive_pickling():
    with pytest.raises(ModelError) as e:
        orbitflex.Robot.from_urdf_string("<robot")
    again = pickle.loads(pickle.dumps(e.value))
    assert type(again) is ModelError and str(again) == str(e.value)

    robot = orbitflex.models.space_arm()
    arm = FlexibleArm(robot, FlexibleJoints(1e4, 1.0))

    def failing(t, x):
        if t > 0.0015:
            raise RuntimeError("actuator fault")
        return np.zeros(7)

    with pytest.raises(SimulationError) as e:
        arm.simulate(arm.state(), 1e-3, 10, u=failing)
    again = pickle.loads(pickle.dumps(e.value))
    assert (again.step, again.time, str(again)) == (e.value.step, e.value.time, str(e.value))
    np.testing.assert_array_equal(again.trajectory.x, e.value.trajectory.x)


def test_stability_warning_accounts_for_a_stiff_motor_pd():
    robot = orbitflex.models.space_arm()
    arm = FlexibleArm(robot, orbitflex.models.space_arm_joints())
    dt = 1e-3
    assert dt < arm.rk4_stability_limit().dt  # the joint modes alone are fine at this dt
    j = arm.parameters[1]
    hot = MotorPD(kp=10.0, kd=5.0 * j / dt, theta_ref=np.full(7, 0.1))  # pole at -5/dt: unstable
    with pytest.warns(RuntimeWarning, match="closed loop"):
        with pytest.raises(SimulationError):
            arm.simulate(arm.state(), dt, 2000, u=hot)
    calm = MotorPD(kp=10.0, kd=0.2 * j / dt, theta_ref=np.full(7, 0.1))
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        arm.simulate(arm.state(), dt, 200, u=calm)


def test_models_and_trajectories_pickle():
    robot = orbitflex.models.space_arm()
    arm = FlexibleArm(robot, orbitflex.models.space_arm_joints())
    traj = arm.simulate(arm.state(q=np.full(7, 0.1)), 1e-3, 50, u=np.ones(7))
    again = pickle.loads(pickle.dumps(traj))
    np.testing.assert_array_equal(again.x, traj.x)
    np.testing.assert_array_equal(again.energy, traj.energy)
    r2 = pickle.loads(pickle.dumps(robot))
    q = np.linspace(-1, 1, 7)
    np.testing.assert_array_equal(r2.mass_matrix(q), robot.mass_matrix(q))
    assert (r2.joint_names, r2.body_names, r2.ee_link) == (robot.joint_names, robot.body_names, robot.ee_link)
    arm2 = pickle.loads(pickle.dumps(arm))
    np.testing.assert_array_equal(arm2.simulate(arm2.state(), 1e-3, 5).x, arm.simulate(arm.state(), 1e-3, 5).x)


def test_ctrl_c_stops_a_long_run_without_the_gil():
    # A 40-joint chain, 200k steps under MotorPD (several seconds, GIL released): SIGINT after
    # half a second must raise KeyboardInterrupt promptly instead of waiting for the run to end.
    code = textwrap.dedent("""
        import signal, threading, os, time, numpy as np, orbitflex
        link = '<link name="l{0}"><inertial><origin xyz="0.2 0 0"/><mass value="1"/><inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        parts = [link.format(i) for i in range(41)]
        for i in range(40):
            axis = "0 0 1" if i % 2 else "0 1 0"
            parts.append(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i+1}"/><origin xyz="0.4 0 0"/><axis xyz="{axis}"/></joint>')
        robot = orbitflex.Robot.from_urdf_string('<robot name="long">' + "".join(parts) + '</robot>')
        arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints(1e3, 0.1, 0.5, 0.1))
        pd = orbitflex.MotorPD(1.0, 0.5, np.full(40, 0.1))
        threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
        start = time.perf_counter()
        try:
            arm.simulate(arm.state(), 1e-4, 200_000, u=pd)
            print("FINISHED", time.perf_counter() - start)
        except KeyboardInterrupt:
            print("INTERRUPTED", time.perf_counter() - start)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert "INTERRUPTED" in out.stdout, out.stdout + out.stderr
    assert float(out.stdout.split()[-1]) < 3.0, out.stdout
