"""The simulation contract that Rust owns (the upper-floors rebuild): the closed-loop stability
warning, the progress hook, the recorded motor torques, SimulationError raised from Rust, and the
state layout given by Rust rather than worked out again in Python."""

from __future__ import annotations

import pickle
import re
import warnings

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, MotorPD, SimulationError


@pytest.fixture(scope="module")
def arm():
    return FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())


def test_regression_stability_check_missed_the_held_pd_divergence(arm):
    # The README's MotorPD(kp=2000, kd=800) on the built-in joints diverges at dt = 1 ms (at step
    # 195); the old per-joint estimate said 1.34 ms and gave no warning.
    pd = MotorPD(kp=2000.0, kd=800.0, theta_ref=np.full(7, 0.2))
    limit = arm.rk4_stability_limit(u=pd).dt
    assert limit < 1e-3
    with pytest.warns(RuntimeWarning, match="closed loop") as record:
        with pytest.raises(SimulationError) as e:
            arm.simulate(arm.state(), 1e-3, 2000, u=pd)
    assert e.value.step == 195
    stated = re.search(r"stability limit ([0-9.e+-]+) s", str(record[0].message))
    assert float(stated.group(1)) == pytest.approx(limit, rel=1e-4)
    # just inside the limit the same loop runs; just outside it diverges
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        arm.simulate(arm.state(), 0.98 * limit, 20_000, u=pd)
    with pytest.warns(RuntimeWarning):
        with pytest.raises(SimulationError):
            arm.simulate(arm.state(), 1.02 * limit, 20_000, u=pd)


def test_stability_limit_depends_on_the_controller_and_state(arm):
    x = arm.state(q=np.full(7, 0.3), qd=np.full(7, 0.1))
    open_loop = arm.rk4_stability_limit(x)
    assert not open_loop.open_loop and not open_loop.estimated  # no controller: nothing unknown
    table = arm.rk4_stability_limit(x, u=np.zeros(7))
    assert table.dt == open_loop.dt and not table.open_loop  # a table has no feedback
    unknown = arm.rk4_stability_limit(x, u=lambda t, x: np.zeros(7))
    assert unknown.dt == open_loop.dt and unknown.open_loop  # unknown feedback: the open loop, flagged
    soft = arm.rk4_stability_limit(x, u=MotorPD(kp=10.0, kd=1.0, theta_ref=np.zeros(7)))
    stiff = arm.rk4_stability_limit(x, u=MotorPD(kp=2000.0, kd=800.0, theta_ref=np.zeros(7)))
    assert stiff.dt < soft.dt <= open_loop.dt * (1 + 1e-3)
    assert float(stiff) == stiff.dt


def test_stability_limit_names_the_fastest_mode(arm):
    # Rust gave the fastest mode and Python only dt: now both, as a small named result. Under a
    # stiff held PD the fastest mode is the wrist's motor pole, near −(kd + β)/j (real, 1/s),
    # and the step limit is near the held-derivative bound 2j/kd (docs/model.md §5.2).
    j = arm.joints.motor_inertia[-1]
    limit = arm.rk4_stability_limit(u=MotorPD(kp=2000.0, kd=800.0, theta_ref=np.zeros(7)))
    assert isinstance(limit, orbitflex.StabilityLimit) and isinstance(limit.fastest_mode, complex)
    assert limit.fastest_mode.real == pytest.approx(-801.0 / j, rel=0.01) and limit.fastest_mode.imag == 0
    assert limit.fastest_mode_hz == pytest.approx(abs(limit.fastest_mode) / (2 * np.pi), rel=1e-12)
    assert limit.dt == pytest.approx(2 * j / 800.0, rel=0.01)
    assert re.fullmatch(r"StabilityLimit\(dt=9\.59\d+e-4, fastest_mode=\(-2\.08\d+e3[+-]0e0j\), "
                        r"open_loop=False, estimated=False\)", repr(limit)), repr(limit)


def test_progress_reports_every_thousand_steps_and_the_end(arm):
    calls = []
    traj = arm.simulate(arm.state(), 1e-3, 3000, u=np.ones(7), progress=lambda d, s: calls.append((d, s)))
    assert calls == [(1024, 3000), (2048, 3000), (3000, 3000)]
    assert len(traj) == 3001


def test_progress_works_with_a_python_controller(arm):
    calls = []
    arm.simulate(arm.state(), 1e-3, 1100, u=lambda t, x: np.zeros(7),
                 progress=lambda d, s: calls.append(d))
    assert calls == [1024, 1100]


def test_an_exception_in_progress_stops_the_run_and_propagates(arm):
    class Stop(Exception):
        pass

    def progress(done, steps):
        raise Stop(done)

    with pytest.raises(Stop) as e:
        arm.simulate(arm.state(), 1e-3, 5000, u=np.ones(7), progress=progress)
    assert e.value.args == (1024,)


def test_trajectory_records_the_motor_torque_of_each_step(arm):
    pd = MotorPD(kp=50.0, kd=5.0, theta_ref=np.full(7, 0.1), feedforward=np.full(7, 0.5))
    traj = arm.simulate(arm.state(), 1e-3, 20, u=pd)
    assert traj.u.shape == (20, 7)
    want = 50.0 * (0.1 - traj.theta[:-1]) + 5.0 * (0.0 - traj.theta_dot[:-1]) + 0.5
    np.testing.assert_allclose(traj.u, want, rtol=1e-15, atol=1e-15)
    table = np.arange(20 * 7, dtype=float).reshape(20, 7) * 1e-3
    np.testing.assert_array_equal(arm.simulate(arm.state(), 1e-3, 20, u=table).u, table)


def test_trajectory_arrays_are_read_only_views(arm):
    traj = arm.simulate(arm.state(), 1e-3, 5, u=np.ones(7))
    for name in ["t", "x", "u", "q", "theta_dot", "momentum", "energy", "ee_pose"]:
        with pytest.raises(ValueError):
            getattr(traj, name)[0] = 1.0
    slices = arm.state_slices
    # "wheel_speed" is empty without reaction wheels (and then shares no memory: it has none)
    assert list(slices) == ["base_pose", "q", "theta", "base_twist", "qd", "theta_dot", "wheel_speed"]
    assert traj.wheel_speed.shape == (6, 0)
    for name, s in slices.items():
        np.testing.assert_array_equal(getattr(traj, name), traj.x[:, s])
        assert np.shares_memory(getattr(traj, name), traj.x) or getattr(traj, name).size == 0


def test_simulation_error_is_raised_from_rust_with_its_cause(arm):
    assert orbitflex.SimulationError is orbitflex._core.SimulationError
    assert issubclass(SimulationError, RuntimeError)

    def failing(t, x):
        if t > 0.0025:
            raise ZeroDivisionError("actuator")
        return np.zeros(7)

    with pytest.raises(SimulationError) as e:
        arm.simulate(arm.state(), 1e-3, 10, u=failing)
    err = e.value
    assert (err.step, err.time) == (3, pytest.approx(0.003))
    assert isinstance(err.__cause__, ZeroDivisionError)
    assert isinstance(err.trajectory, orbitflex.Trajectory) and len(err.trajectory) == 4
    assert err.trajectory.u.shape == (3, 7)
    again = pickle.loads(pickle.dumps(err))
    assert (again.step, again.time, str(again)) == (err.step, err.time, str(err))
    np.testing.assert_array_equal(again.trajectory.x, err.trajectory.x)


def test_motor_pd_pickles_exactly(arm):
    table = np.random.default_rng(1).normal(size=(30, 7))
    for pd in [MotorPD(kp=2000.0, kd=800.0, theta_ref=np.full(7, 0.2)),
               MotorPD(kp=np.arange(7.0), kd=1.5, theta_ref=table, theta_dot_ref=table * 2,
                       feedforward=np.full(7, 0.25))]:
        again = pickle.loads(pickle.dumps(pd))
        np.testing.assert_array_equal(again.kp, pd.kp)
        np.testing.assert_array_equal(again.kd, pd.kd)
        a = arm.simulate(arm.state(), 5e-4, 30, u=pd)
        b = arm.simulate(arm.state(), 5e-4, 30, u=again)
        np.testing.assert_array_equal(a.x, b.x)


@pytest.mark.parametrize("bad", ["1e-3", True, None, 1j])
def test_dt_must_be_a_real_number(arm, bad):
    with pytest.raises(orbitflex.ModelError, match="dt"):
        arm.simulate(arm.state(), bad, 3)


@pytest.mark.parametrize("bad", [1.5, True, -1, 10**20, "3"])
def test_steps_must_be_a_count(arm, bad):
    with pytest.raises(orbitflex.ModelError, match="steps"):
        arm.simulate(arm.state(), 1e-3, bad)


def test_motor_pd_gains_come_from_the_joints_physics_and_say_what_they_cannot_do(arm):
    # docs/model.md §5.3: two roots of each joint's closed loop at s² + 2ζωs + ω² = 0; the Rust
    # tests check the placement, this the Python surface.
    kp, kd = arm.motor_pd_gains(0.25)
    np.testing.assert_array_equal(np.c_[kp, kd], np.c_[arm.motor_pd_gains(0.25, damping_ratio=1.0)])
    assert kp.shape == kd.shape == (7,) and (kp > 0).all() and (kd >= 0).all()
    # the rigid rule kp = (j + m) ω² with m the free-floating joint-space inertia, within the
    # spring's correction (at most 8 % here, at 0.25 Hz against resonances of 1.5 Hz and up)
    M = arm.robot.mass_matrix(np.zeros(7))
    m = np.diag(M[6:, 6:] - M[6:, :6] @ np.linalg.solve(M[:6, :6], M[:6, 6:]))
    rigid = (arm.joints.motor_inertia + m) * (2 * np.pi * 0.25) ** 2
    assert np.all(np.abs(kp / rigid - 1) < 0.08), kp / rigid
    # the configuration matters: a folded elbow changes what the shoulder drives
    folded = np.r_[0, 0, 0, 2.0, 0, 0, 0]
    assert not np.allclose(arm.motor_pd_gains(0.25, q=folded)[0][:3], kp[:3], rtol=1e-3)
    with pytest.raises(orbitflex.ModelError, match=r"^bandwidth: 2 Hz is more than the joints' springs can carry"):
        arm.motor_pd_gains(2.0)
    with pytest.raises(orbitflex.ModelError, match=r"^damping_ratio: expected a finite number > 0, given 0"):
        arm.motor_pd_gains(0.25, 0.0)
    with pytest.raises(orbitflex.ModelError, match=r"^q: "):
        arm.motor_pd_gains(0.25, q=np.zeros(3))


def test_motor_servo_gains_make_each_motor_a_critically_damped_servo_on_its_own_inertia(arm):
    # kp = j ω², kd = 2 j ω: the motor alone (j θ̈ = -kp θ - kd θ̇) has the double root -ω
    j, w = arm.joints.motor_inertia, 2 * np.pi * 5.0
    kp, kd = arm.motor_servo_gains(5.0)
    np.testing.assert_array_equal(kp, j * (w * w))
    np.testing.assert_array_equal(kd, 2 * j * w)
    assert np.allclose(kd**2, 4 * j * kp, rtol=1e-14)  # discriminant zero: critically damped
    for bad, shown in ((0.0, "0"), (-1.0, "-1"), (float("nan"), "NaN")):
        with pytest.raises(orbitflex.ModelError, match=rf"^bandwidth: expected a finite number > 0, given {shown}"):
            arm.motor_servo_gains(bad)
