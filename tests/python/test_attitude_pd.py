"""AttitudePD: the bus held by its reaction wheels (issue 26 phase 2), callables on the wheel and
base-wrench channels, the wheels file and the CLI's wheel case."""

import argparse
import pickle
import subprocess
import sys

import numpy as np
import pytest

import orbitflex as of
from orbitflex.cli.slew import SPACE_ARM_SLEW, choose_gains, slew_controller
from orbitflex.wheels_file import WheelsFileError, read_wheels, wheels_from_dict

ROBOT = of.models.space_arm()
JOINTS = of.models.space_arm_joints()
FREE = of.FlexibleArm(ROBOT, JOINTS)
ARM = of.FlexibleArm(ROBOT, JOINTS, wheels=of.models.pyramid_wheels())
S3 = 1 / np.sqrt(3)
PYRAMID_AXES = np.array([[S3, S3, S3], [-S3, S3, S3], [-S3, -S3, S3], [S3, -S3, S3]])


def demo_slew(steps, dt=1e-3):
    """The demo's motor PD: the quintic slew of SPACE_ARM_SLEW over 5 s at 0.25 Hz."""
    gains = choose_gains(FREE, argparse.Namespace(kp=None, kd=None, bandwidth=0.25, damping_ratio=1.0))
    return slew_controller(FREE, SPACE_ARM_SLEW, steps, dt, 5.0, gains)


def bus_rotation(traj):
    q = traj.base_pose[:, 3:]
    return np.asarray(of.rotation_angle(q[0], q))


def test_the_wheels_hold_the_bus_within_a_milliradian_through_the_demo_slew():
    steps = 20000
    pd = demo_slew(steps)
    free = FREE.simulate(FREE.state(), 1e-3, steps, u=pd)
    held = ARM.simulate(ARM.state(), 1e-3, steps, u=pd, wheel_torque=of.AttitudePD(*of.models.PYRAMID_GAINS))
    # free floating, the slew turns the bus by 19.75° (the demo's summary)
    assert np.degrees(bus_rotation(free)[-1]) == pytest.approx(19.75, abs=0.01)
    assert bus_rotation(held).max() < 1e-3
    # the wheels did the work within their limits, and the momentum is conserved whole
    wheels = of.models.pyramid_wheels()
    assert np.abs(held.wheel_torque).max() <= wheels.max_torque[0]
    assert np.abs(held.wheel_speed).max() < wheels.max_speed[0]
    assert np.abs(held.wheel_speed).max() > 100.0  # the arm's momentum went into the wheels
    drift = np.abs(ARM.momentum(held.x[-1]) - ARM.momentum(held.x[0])).max()
    assert drift < 1e-9


def test_the_law_and_its_signs_by_hand():
    """u = −M T, T = −kp e − kd ω, e = 2 vec(q_ref* ⊗ q_B) (w ≥ 0), M the pseudo-inverse."""
    rng = np.random.default_rng(3)
    q_ref = rng.normal(size=4)
    q_ref /= np.linalg.norm(q_ref)
    kp, kd = np.array([3.0, 5.0, 7.0]), np.array([0.5, 0.25, 2.0])
    pd = of.AttitudePD(kp, kd, attitude=q_ref)
    x = ARM.state(q=rng.normal(size=7) * 0.3, base_pose=np.r_[0.1, 0.2, 0.3, rng.normal(size=4)],
                  base_twist=rng.normal(size=6) * 0.1, wheel_speed=rng.normal(size=4))
    qb = x[3:7]
    conj = np.r_[-q_ref[:3], q_ref[3]]

    def product(a, b):
        av, aw, bv, bw = a[:3], a[3], b[:3], b[3]
        return np.r_[aw * bv + bw * av + np.cross(av, bv), aw * bw - av @ bv]

    qe = product(conj, qb)
    qe = qe if qe[3] >= 0 else -qe
    omega = x[ARM.state_slices["base_twist"]][:3]
    torque = -kp * 2 * qe[:3] - kd * omega
    expected = -np.linalg.pinv(PYRAMID_AXES.T) @ torque
    np.testing.assert_allclose(pd.command(ARM, x), expected, rtol=1e-12, atol=1e-12)
    # what the wheels push on the bus, −Σ u_w a_w, is the torque asked for
    np.testing.assert_allclose(-PYRAMID_AXES.T @ pd.command(ARM, x), torque, rtol=1e-12, atol=1e-12)


def test_a_given_allocation_is_used_and_checked():
    x = ARM.state(base_twist=[0.01, -0.02, 0.03, 0, 0, 0])
    pinv = np.linalg.pinv(PYRAMID_AXES.T)
    np.testing.assert_allclose(of.AttitudePD(1.0, 2.0, allocation=pinv).command(ARM, x),
                               of.AttitudePD(1.0, 2.0).command(ARM, x), rtol=1e-13, atol=1e-16)
    # another valid allocation (A M = 1): wheels 0..2 only when wheel 3 is off
    a3 = PYRAMID_AXES[:3].T
    m = np.vstack([np.linalg.inv(a3), np.zeros((1, 3))])
    u = of.AttitudePD(1.0, 2.0, allocation=m).command(ARM, x)
    assert u[3] == 0.0
    np.testing.assert_allclose(PYRAMID_AXES.T @ u, PYRAMID_AXES.T @ of.AttitudePD(1.0, 2.0).command(ARM, x),
                               rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match=r"allocation: expected shape \(4, 3\).*given shape \(3, 3\)"):
        of.AttitudePD(1.0, 2.0, allocation=np.eye(3)).command(ARM, x)


def test_bad_input_is_named():
    planar = of.ReactionWheels([[1, 0, 0], [0, 1, 0], [S3 * np.sqrt(1.5), S3 * np.sqrt(1.5), 0]],
                               np.zeros((3, 3)), 1.0, 0.01, 0.01, 1.0, 100.0)
    arm = of.FlexibleArm(ROBOT, JOINTS, wheels=planar)
    with pytest.raises(ValueError, match=r"wheel axes \(1, 0, 0\), \(0, 1, 0\), .* all lie in one plane"):
        arm.simulate(arm.state(), 1e-3, 2, wheel_torque=of.AttitudePD(1.0, 1.0))
    with pytest.raises(ValueError, match="the arm has no reaction wheels"):
        FREE.simulate(FREE.state(), 1e-3, 2, wheel_torque=of.AttitudePD(1.0, 1.0))
    with pytest.raises(ValueError, match="kp"):
        of.AttitudePD(-1.0, 1.0)
    with pytest.raises(ValueError, match=r"kd: .*length 3"):
        of.AttitudePD(1.0, [1.0, 2.0])
    with pytest.raises(ValueError, match="attitude"):
        of.AttitudePD(1.0, 1.0, attitude=[0, 0, 0, 0])
    with pytest.raises(ValueError, match=r"attitude: expected None, shape \(4,\) or \(steps, 4\)"):
        of.AttitudePD(1.0, 1.0, attitude=np.zeros((2, 2, 4)))
    with pytest.raises(ValueError, match="rate: goes with a table of attitudes"):
        of.AttitudePD(1.0, 1.0, rate=np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"attitude: expected at least 5 rows .* given 3 rows"):
        ARM.simulate(ARM.state(), 1e-3, 5, wheel_torque=of.AttitudePD(1.0, 1.0, attitude=np.tile([0, 0, 0, 1.0], (3, 1))))


def test_a_table_of_attitudes_is_followed_row_by_row():
    steps = 50
    table = np.tile([0.0, 0.0, 0.0, 1.0], (steps, 1))
    table[10:] = [0.0, 0.0, np.sin(0.005), np.cos(0.005)]  # 0.01 rad about z from step 10
    pd = of.AttitudePD(100.0, 10.0, attitude=table)
    x = ARM.state()
    assert np.all(pd.command(ARM, x, step=9) == 0.0)
    u = pd.command(ARM, x, step=10)
    # bus 0.01 rad behind the target about z: T_z = +kp 2 sin(0.005) pushes it forward
    np.testing.assert_allclose(-PYRAMID_AXES.T @ u, [0, 0, 100.0 * 2 * np.sin(0.005)], atol=1e-12)


def test_a_callable_on_the_wheels_equals_the_controller_bit_for_bit():
    steps = 300
    pd = demo_slew(steps)
    target = [0.0, 0.0, 0.0, 1.0]
    att = of.AttitudePD(*of.models.PYRAMID_GAINS, attitude=target)
    rust = ARM.simulate(ARM.state(), 1e-3, steps, u=pd, wheel_torque=att)
    calls = []

    def acs(t, x):
        calls.append(t)
        return att.command(ARM, x)

    python = ARM.simulate(ARM.state(), 1e-3, steps, u=pd, wheel_torque=acs)
    assert len(calls) == steps
    assert np.array_equal(rust.x, python.x) and np.array_equal(rust.wheel_torque, python.wheel_torque)


def test_a_callable_base_wrench_closes_a_loop():
    steps = 200
    pd = demo_slew(steps)
    wrench = np.array([0.1, -0.2, 0.3, 1.0, 2.0, -1.0])
    table = FREE.simulate(FREE.state(), 1e-3, steps, u=pd, base_wrench=wrench)
    called = FREE.simulate(FREE.state(), 1e-3, steps, u=pd, base_wrench=lambda t, x: wrench)
    assert np.array_equal(table.x, called.x)
    # a thruster PD on the bus rate, closed through the callable, slows the bus's rotation
    layout = FREE.state_slices["base_twist"]
    damped = FREE.simulate(FREE.state(), 1e-3, steps, u=pd,
                           base_wrench=lambda t, x: np.r_[-5000.0 * x[layout][:3], 0, 0, 0])
    free = FREE.simulate(FREE.state(), 1e-3, steps, u=pd)
    assert np.linalg.norm(damped.base_twist[-1, :3]) < 0.5 * np.linalg.norm(free.base_twist[-1, :3])


def test_a_failing_wheel_callable_is_a_simulation_error_keeping_the_rows():
    def broken(t, x):
        if t > 0.0045:
            raise RuntimeError("ACS lost")
        return np.zeros(4)

    with pytest.raises(of.SimulationError, match="the wheel_torque controller failed: .*ACS lost") as e:
        ARM.simulate(ARM.state(), 1e-3, 10, wheel_torque=broken)
    assert e.value.step == 5 and len(e.value.trajectory.t) == 6
    assert isinstance(e.value.__cause__, RuntimeError)
    with pytest.raises(of.SimulationError, match=r"wheel_torque returned by the controller: .*length 4"):
        ARM.simulate(ARM.state(), 1e-3, 3, wheel_torque=lambda t, x: np.zeros(3))


def test_attitude_pd_pickles():
    pd = of.AttitudePD([1.0, 2.0, 3.0], 4.0, attitude=np.tile([0, 0, 0, 1.0], (3, 1)),
                       allocation=np.linalg.pinv(PYRAMID_AXES.T), rate=np.ones((3, 3)))
    back = pickle.loads(pickle.dumps(pd))
    x = ARM.state(base_twist=[0.01, 0.02, 0.03, 0, 0, 0])
    assert np.array_equal(back.command(ARM, x, step=1), pd.command(ARM, x, step=1))
    assert "AttitudePD(kp=[1.0, 2.0, 3.0]" in repr(back)


def test_the_example_wheels_file_is_the_built_in_pyramid(tmp_path):
    from pathlib import Path

    spec = read_wheels(Path(__file__).parents[2] / "examples" / "wheels.toml")
    pyramid = of.models.pyramid_wheels()
    np.testing.assert_allclose(spec.wheels.axes, pyramid.axes, atol=1e-15)
    np.testing.assert_allclose(spec.wheels.positions, pyramid.positions, atol=1e-15)
    assert list(spec.kp) == [of.models.PYRAMID_GAINS[0]] * 3
    assert len(wheels_from_dict({"pyramid": True, "defaults": {"max_speed": 100.0},
                                 "attitude_pd": {"kp": 1, "kd": 2}}).wheels.axes) == 4


@pytest.mark.parametrize("spec, message", [
    ({"pyramid": True}, r"\[attitude_pd\] with kp and kd is required"),
    ({"pyramid": True, "attitude_pd": {"kp": 1}}, r"'kd' is required"),
    ({"wheel": [{"axis": [1, 0, 0]}], "attitude_pd": {"kp": 1, "kd": 1}}, r"wheel\[0\].position: expected three"),
    ({"wheel": [{"axis": [1, 0, 0], "position": [0, 0, 0]}], "attitude_pd": {"kp": 1, "kd": 1}},
     r"wheel\[0\].mass: missing"),
    ({"defaults": {"spin": 1.0}, "pyramid": True, "attitude_pd": {"kp": 1, "kd": 1}}, r"\[defaults\].spin: unknown key"),
    ({"pyramid": True, "defaults": {"spin_inertia": -1.0}, "attitude_pd": {"kp": 1, "kd": 1}}, "spin_inertia"),
    ({"whels": []}, "unknown key"),
])
def test_bad_wheels_files_are_named(spec, message):
    with pytest.raises(WheelsFileError, match=message):
        wheels_from_dict(spec, "w.toml")


def test_the_demo_prints_and_plots_the_wheel_case(tmp_path):
    result = subprocess.run([sys.executable, "-m", "orbitflex", "demo", "--duration", "1", "--quiet",
                             "--no-animation", "--out", "out"], capture_output=True, text=True, cwd=tmp_path,
                            timeout=600, env={**__import__("os").environ, "MPLBACKEND": "Agg"})
    assert result.returncode == 0, result.stderr[-2000:]
    assert "the same slew with 4 reaction wheels holding the bus" in result.stdout
    assert "bus attitude error  max" in result.stdout and "of the 800 rad/s limit" in result.stdout
    assert (tmp_path / "out" / "wheels.png").exists()
    bad = tmp_path / "bad.toml"
    bad.write_text("pyramid = true\n")
    result = subprocess.run([sys.executable, "-m", "orbitflex", "demo", "--duration", "0.01", "--quiet",
                             "--no-animation", "--no-plots", "--wheels", str(bad), "--out", "out"],
                            capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert result.returncode != 0 and "--wheels" in result.stderr and "[attitude_pd]" in result.stderr
