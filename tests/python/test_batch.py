"""``orbitflex.simulate_batch``: a batch equals its runs made one by one with ``arm.simulate``,
bit for bit, for any thread count and every broadcast shape; a failing run leaves the others
complete; bad shapes name themselves; Ctrl-C, progress and the stability warning work. Each test\nruns in SIMD lanes and on the scalar path."""

from __future__ import annotations

import os
import signal
import re
import threading
import time
import warnings

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, FlexibleJoints, ModelError, MotorPD, SimulationError

DT = 2e-3
STEPS = 60
B = 4
N = 7


@pytest.fixture(autouse=True, params=["lanes", "scalar"])
def batch_path(request, monkeypatch):
    """Every test of this file twice: batches in SIMD lanes (the default) and on the scalar
    path (``ORBITFLEX_LANES=1``, read at each call)."""
    if request.param == "scalar":
        monkeypatch.setenv("ORBITFLEX_LANES", "1")
    else:
        monkeypatch.delenv("ORBITFLEX_LANES", raising=False)
    return request.param


@pytest.fixture(scope="module")
def arm():
    return FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())


@pytest.fixture(scope="module")
def x0s(arm):
    """Four starts: rest, and three with different link and base rates."""
    rows = []
    for b in range(B):
        qd = 0.05 * b - 0.01 * np.arange(N)
        rows.append(arm.state(qd=qd, base_twist=[0, 0, 0.01 * b, 0, 0, 0]))
    return np.array(rows)


def torques(b, scale=1.0):
    t = np.arange(STEPS)[:, None] * DT
    return scale * (b + 1) * np.sin(20 * t + np.arange(N))


def assert_same(batch, b, traj):
    """Run ``b`` of ``batch`` (record_every=1) is ``traj`` bit for bit."""
    rows = len(traj)
    np.testing.assert_array_equal(batch.x[b, :rows], traj.x)
    np.testing.assert_array_equal(batch.u[b, : rows - 1], traj.u)
    assert np.isnan(batch.x[b, rows:]).all()
    np.testing.assert_array_equal(batch.final_state[b], traj.x[-1])
    np.testing.assert_array_equal(
        batch.peak_deflection[b], np.abs(traj.deflection).max(axis=0))
    np.testing.assert_array_equal(batch.peak_torque[b], np.abs(traj.u).max(axis=0))
    run = batch.run(b)
    np.testing.assert_array_equal(run.t, traj.t)
    np.testing.assert_array_equal(run.x, traj.x)
    np.testing.assert_array_equal(run.u, traj.u)


@pytest.mark.parametrize("threads", [1, 2, None])
def test_tables_per_run_equal_single_runs_bit_for_bit(arm, x0s, threads):
    u = np.stack([torques(b) for b in range(B)])
    fee = np.array([[0, 0, 0.01 * b, 0.1, 0, 0] for b in range(B)])
    batch = orbitflex.simulate_batch(arm, x0s, DT, STEPS, u=u, ee_wrench=fee, threads=threads)
    assert batch.x.shape == (B, STEPS + 1, arm.state_size)
    assert batch.u.shape == (B, STEPS, N)
    assert batch.t.shape == (STEPS + 1,)
    assert batch.ok.tolist() == [True] * B
    assert batch.failed_step.tolist() == [-1] * B
    assert batch.messages == [None] * B
    for b in range(B):
        traj = arm.simulate(x0s[b], DT, STEPS, u=u[b], ee_wrench=fee[b])
        assert_same(batch, b, traj)
        np.testing.assert_array_equal(batch.t, traj.t)


@pytest.mark.parametrize("u_shape", ["scalar", "(n,)", "(B, n)", "(1, steps, n)", "(B, steps, n)"])
def test_every_u_shape_broadcasts_as_numpy_does(arm, x0s, u_shape):
    per_run = {
        "scalar": (0.7, lambda b: np.full(N, 0.7)),
        "(n,)": (np.linspace(-1, 1, N), lambda b: np.linspace(-1, 1, N)),
        "(B, n)": (np.arange(B * N).reshape(B, N) / 10, lambda b: np.arange(B * N).reshape(B, N)[b] / 10),
        "(1, steps, n)": (torques(0)[None], lambda b: torques(0)),
        "(B, steps, n)": (np.stack([torques(b) for b in range(B)]), torques),
    }[u_shape]
    u, single = per_run
    batch = orbitflex.simulate_batch(arm, x0s, DT, STEPS, u=u, threads=2)
    for b in range(B):
        assert_same(batch, b, arm.simulate(x0s[b], DT, STEPS, u=single(b)))


def test_dispersed_arms_and_controllers(arm, x0s):
    robot = arm.robot
    arms = [FlexibleArm(robot, FlexibleJoints(stiffness=k, motor_inertia=0.5, damping=0.5))
            for k in (500.0, 1000.0, 2000.0, 4000.0)]
    pds = [MotorPD(kp=20.0 + 10 * b, kd=5.0, theta_ref=np.full(N, 0.1)) for b in range(B)]
    batch = orbitflex.simulate_batch(arms, x0s, DT, STEPS, u=pds, threads=2)
    for b in range(B):
        assert_same(batch, b, arms[b].simulate(x0s[b], DT, STEPS, u=pds[b]))
    # one arm and one controller, one start for all: every run is the same run
    same = orbitflex.simulate_batch(arm, x0s[1], DT, STEPS, u=pds[0], base_wrench=np.ones((3, 6)))
    assert same.runs == 3
    assert (same.x[0] == same.x[1]).all() and (same.x[0] == same.x[2]).all()
    assert_same(same, 2, arm.simulate(x0s[1], DT, STEPS, u=pds[0], base_wrench=np.ones(6)))


@pytest.mark.parametrize("every", [1, 7, 23])  # 23: the failing step is a kept row
def test_failing_run_leaves_the_others_complete(arm, x0s, every):
    u = np.stack([torques(b) for b in range(B)])
    u[2, 23] = 1e308  # overflows run 2's state during step 23
    batch = orbitflex.simulate_batch(arm, x0s, DT, STEPS, u=u, record_every=every, threads=2)
    assert batch.ok.tolist() == [True, True, False, True]
    with pytest.raises(SimulationError) as failure:
        arm.simulate(x0s[2], DT, STEPS, u=u[2], record_every=every)
    assert batch.failed_step.tolist() == [-1, -1, failure.value.step, -1] == [-1, -1, 23, -1]
    assert batch.messages[2] == str(failure.value)
    kept = failure.value.trajectory
    run = batch.run(2)
    np.testing.assert_array_equal(run.t, kept.t)
    np.testing.assert_array_equal(run.x, kept.x)
    np.testing.assert_array_equal(run.u, kept.u)
    np.testing.assert_array_equal(batch.final_state[2], kept.x[-1])
    # rows from the failure on are NaN
    failed_rows = batch.t > 23 * DT
    assert np.isnan(batch.x[2, failed_rows]).all()
    assert not np.isnan(batch.x[2, ~failed_rows]).any()
    for b in (0, 1, 3):
        traj = arm.simulate(x0s[b], DT, STEPS, u=u[b], record_every=every)
        np.testing.assert_array_equal(batch.x[b], traj.x)
        np.testing.assert_array_equal(batch.run(b).x, traj.x)


def test_summaries_only(arm, x0s):
    u = np.stack([torques(b) for b in range(B)])
    full = orbitflex.simulate_batch(arm, x0s, DT, STEPS, u=u)
    lean = orbitflex.simulate_batch(arm, x0s, DT, STEPS, u=u, keep_rows=False)
    assert lean.x.shape == (B, 0, arm.state_size) and lean.t.shape == (0,)
    np.testing.assert_array_equal(lean.final_state, full.final_state)
    np.testing.assert_array_equal(lean.peak_deflection, full.peak_deflection)
    np.testing.assert_array_equal(lean.peak_torque, full.peak_torque)
    with pytest.raises(ModelError, match=r"run: this batch kept no rows \(keep_rows=False\)"):
        lean.run(0)


def test_views_and_read_only_arrays(arm, x0s):
    batch = orbitflex.simulate_batch(arm, x0s, DT, 10, u=0.5)
    s = arm.state_slices
    for name in ("base_pose", "q", "theta", "base_twist", "qd", "theta_dot"):
        view = getattr(batch, name)
        np.testing.assert_array_equal(view, batch.x[:, :, s[name]])
        assert np.shares_memory(view, batch.x)
    assert not batch.x.flags.writeable and not batch.ok.flags.writeable
    assert len(batch) == B and batch.runs == B and batch.steps == 10
    assert repr(batch) == "BatchTrajectory(runs=4, rows=11, steps=10, failed=0, dof=7)"
    np.testing.assert_array_equal(batch.run(-1).x, batch.run(3).x)
    with pytest.raises(IndexError, match=r"run: expected an index from -4 to 3, given 4"):
        batch.run(4)


@pytest.mark.parametrize("kwargs,message", [
    (dict(u=np.zeros((3, N))), "runs: x0s gives 4 runs but u gives 3; every leading run axis must have length 1 or the number of runs"),
    (dict(u=np.zeros((4, STEPS - 1, N))), "u: expected shape (7,), (4, 7), (1, 7), (4, 60, 7) or (1, 60, 7), given shape (4, 59, 7)"),
    (dict(u=np.zeros(6)), "u: expected shape (7,), (4, 7), (1, 7), (4, 60, 7) or (1, 60, 7), given shape (6,)"),
    (dict(ee_wrench=np.zeros((4, 7))), "ee_wrench: expected shape (6,), (4, 6), (1, 6), (4, 60, 6) or (1, 60, 6), given shape (4, 7)"),
    (dict(u=lambda k, t, x: np.zeros(N)), "u: simulate_batch runs without the GIL, so it cannot call a Python controller"),
    (dict(threads=0), "threads: expected an integer >= 1, given int (0)"),
    (dict(threads=20000), "threads: expected an integer from 1 to 1024 (or None for every core), given 20000"),
    (dict(record_every=0), "record_every: expected an integer >= 1, given int (0)"),
    (dict(u=np.full(N, np.nan)), "u (run 0): element 0 is not finite (NaN)"),
])
def test_bad_arguments_name_themselves(arm, x0s, kwargs, message):
    with pytest.raises(ModelError) as e:
        orbitflex.simulate_batch(arm, x0s, DT, STEPS, **kwargs)
    assert str(e.value).startswith(message), str(e.value)


def test_bad_states_and_arms_name_the_run(arm, x0s):
    bad = x0s.copy()
    bad[2, 3:7] = 0
    with pytest.raises(ModelError, match=r"^base_pose \(run 2\): the quaternion"):
        orbitflex.simulate_batch(arm, bad, DT, STEPS)
    with pytest.raises(ModelError, match=r"^x0s: expected shape \(41,\), \(4, 41\) or \(1, 41\), given shape \(4, 40\)"):
        orbitflex.simulate_batch(arm, x0s[:, :-1], DT, STEPS)
    small = FlexibleArm(orbitflex.Robot.from_urdf_string(_TWO_LINKS), FlexibleJoints(stiffness=100.0, motor_inertia=0.1))
    with pytest.raises(ModelError, match=r"^arms\[1\]: expected an arm with 7 joints \(as run 0's\), given one with 2 joints"):
        orbitflex.simulate_batch([arm, small], x0s[0], DT, STEPS)
    with pytest.raises(ModelError, match=r"^arm_or_arms\[1\]: expected a FlexibleArm, given str"):
        orbitflex.simulate_batch([arm, "arm"], x0s[0], DT, STEPS)
    with pytest.raises(ModelError, match=r"^u\[1\]: expected a MotorPD \(u\[0\] is one\), given int"):
        orbitflex.simulate_batch(arm, x0s, DT, STEPS, u=[MotorPD(1.0, 1.0, np.zeros(N)), 3, 4, 5])


_TWO_LINKS = """<robot name="two">
  <link name="base"><inertial><mass value="10"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="b"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/><origin xyz="0 0 1"/><limit effort="1" velocity="1" lower="-1" upper="1"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 1 0"/><origin xyz="0 0 1"/><limit effort="1" velocity="1" lower="-1" upper="1"/></joint>
</robot>"""


def test_one_warning_names_the_unstable_runs(arm, x0s):
    stiff = FlexibleArm(arm.robot, FlexibleJoints(stiffness=1e8, motor_inertia=1e-3))
    arms = [arm, stiff, arm, stiff]
    with pytest.warns(RuntimeWarning) as caught:
        batch = orbitflex.simulate_batch(arms, x0s, 5e-3, 20, u=0.1)
    assert len(caught) == 1
    message = str(caught[0].message)
    assert "exceeds the RK4 stability limit of 2 of 4 runs (runs 1, 3;" in message, message
    assert batch.ok.tolist() == [True, False, True, False]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        orbitflex.simulate_batch(arm, x0s, 5e-3, 20, u=0.1)
    # one run, or all: said so ("of 1 of 1 runs (runs 0; …)" read badly)
    limit = stiff.rk4_stability_limit(x0s[1], np.full(stiff.dof, 0.1)).dt
    limit = re.sub(r"e(-?)0*(\d)", r"e\1\2", f"{limit:.4e}")  # as Rust writes it: 8.7955e-6
    for arms, x0, words in (
            (stiff, x0s[1], f"exceeds the RK4 stability limit {limit} s of the run (linearised at its x0); it "
                            f"will likely diverge"),
            ([arm, stiff, arm], x0s[:3], f"exceeds the RK4 stability limit {limit} s of run 1 of 3 (linearised "
                                         f"at its x0); it will likely diverge"),
            ([stiff, stiff], x0s[:2], "exceeds the RK4 stability limit of all 2 runs (runs 0, 1; smallest limit ")):
        with pytest.warns(RuntimeWarning) as caught:
            orbitflex.simulate_batch(arms, x0, 5e-3, 20, u=0.1)
        assert len(caught) == 1 and words in str(caught[0].message), str(caught[0].message)


def test_progress_and_gil_release(arm, x0s):
    reports = []
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(1)
            time.sleep(0.001)

    ticker = threading.Thread(target=count)
    ticker.start()
    try:
        orbitflex.simulate_batch(arm, x0s, 1e-3, 20000, u=0.1, threads=1, keep_rows=False,
                                 progress=lambda done, runs: reports.append((done, runs)))
    finally:
        stop.set()
        ticker.join()
    assert reports[-1] == (B, B)
    assert all(runs == B and 0 <= done <= B for done, runs in reports)
    assert len(reports) >= 2
    # the Python thread ran while the batch computed
    assert len(ticks) > 50


def test_ctrl_c_stops_a_batch_of_short_runs(arm):
    # runs of 500 steps never look at Ctrl-C themselves: the runs not yet started must not start
    x0 = arm.state()
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        # 20,000 runs: over a minute of work on one core if it were not stopped
        orbitflex.simulate_batch(arm, x0, 1e-3, 500, u=np.zeros((20000, N)), threads=1, keep_rows=False)
    assert time.perf_counter() - start < 5


def test_ctrl_c_stops_the_batch(arm, x0s):
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        # about a minute of work on one core if it were not stopped
        orbitflex.simulate_batch(arm, x0s, 1e-3, 10**6, u=0.1, threads=1, keep_rows=False)
    assert time.perf_counter() - start < 10
