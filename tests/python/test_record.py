"""``simulate(record_every=k)`` and ``simulate(on_rows=..., chunk_rows=...)``: the kept rows are
the full run's rows bit for bit, on success and on failure, in memory and streamed; bad arguments
name themselves; memory stays bounded."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, MotorPD, SimulationError

DT = 1e-3


@pytest.fixture(scope="module")
def arm():
    return FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())


@pytest.fixture(scope="module")
def pd():
    return MotorPD(kp=50.0, kd=20.0, theta_ref=np.full(7, 0.2))


def kept(steps, k):
    """The rule: rows 0, k, 2k, ... and the final row."""
    rows = list(range(0, steps + 1, k))
    return rows if rows[-1] == steps else rows + [steps]


def assert_rows(traj, full, rows):
    """``traj`` holds exactly ``full``'s rows ``rows`` (and the inputs of the steps starting
    at each but the last)."""
    np.testing.assert_array_equal(traj.t, full.t[rows])
    np.testing.assert_array_equal(traj.x, full.x[rows])
    np.testing.assert_array_equal(traj.u, full.u[rows[:-1]])


@pytest.mark.parametrize("steps,k,count", [
    (300, 1, 301), (300, 10, 31), (300, 7, 44), (300, 300, 2), (300, 1000, 2), (0, 5, 1),
])
def test_kept_rows_are_the_full_runs_rows_bit_for_bit(arm, pd, steps, k, count):
    full = arm.simulate(arm.state(), DT, steps, u=pd)
    traj = arm.simulate(arm.state(), DT, steps, u=pd, record_every=k)
    rows = kept(steps, k)
    assert len(rows) == count == len(traj)  # steps // k + 1, + 1 when k does not divide steps
    assert traj.t.shape == (count,) and traj.x.shape == (count, arm.state_size)
    assert traj.u.shape == (count - 1, arm.dof)
    assert_rows(traj, full, rows)
    np.testing.assert_array_equal(traj.t, np.array(rows) * DT)


def test_record_every_one_is_the_default_bit_for_bit(arm, pd):
    a = arm.simulate(arm.state(), DT, 200, u=pd)
    b = arm.simulate(arm.state(), DT, 200, u=pd, record_every=1)
    c = arm.simulate(arm.state(), DT, 200, u=pd, record_every=np.int64(1))
    for t in (b, c):
        np.testing.assert_array_equal(t.t, a.t)
        np.testing.assert_array_equal(t.x, a.x)
        np.testing.assert_array_equal(t.u, a.u)


def test_python_controller_and_tables_follow_the_same_rule(arm):
    table = np.sin(np.arange(100 * 7, dtype=float)).reshape(100, 7)
    full = arm.simulate(arm.state(), DT, 100, u=table)
    calls = []

    def controller(t, x):
        calls.append(t)
        return table[len(calls) - 1]

    traj = arm.simulate(arm.state(), DT, 100, u=controller, record_every=30)
    assert len(calls) == 100  # still called once per step
    assert_rows(traj, full, [0, 30, 60, 90, 100])
    assert_rows(arm.simulate(arm.state(), DT, 100, u=table, record_every=30), full, [0, 30, 60, 90, 100])


@pytest.mark.parametrize("k,rows", [(10, [0, 10, 20, 30, 37]), (37, [0, 37]), (1, list(range(38)))])
def test_a_failed_run_keeps_its_rows_and_ends_on_the_last_good_state(arm, k, rows):
    table = np.sin(np.arange(100 * 7, dtype=float)).reshape(100, 7)
    full = arm.simulate(arm.state(), DT, 100, u=table)

    def controller(t, x):
        step = int(round(t / DT))
        if step == 37:
            raise KeyError("lost the reference")
        return table[step]

    with pytest.raises(SimulationError) as e:
        arm.simulate(arm.state(), DT, 100, u=controller, record_every=k)
    assert (e.value.step, e.value.time) == (37, 37 * DT)
    assert "step 37" in str(e.value)
    assert isinstance(e.value.__cause__, KeyError)
    assert_rows(e.value.trajectory, full, rows)


def test_a_diverged_run_ends_on_the_state_before_the_divergence(arm):
    # MotorPD(kp=2000, kd=800) at dt = 1 ms diverges at step 195 (test_simulation_contract.py)
    pd = MotorPD(kp=2000.0, kd=800.0, theta_ref=np.full(7, 0.2))
    with pytest.warns(RuntimeWarning):
        with pytest.raises(SimulationError) as full:
            arm.simulate(arm.state(), DT, 1000, u=pd)
        with pytest.raises(SimulationError) as e:
            arm.simulate(arm.state(), DT, 1000, u=pd, record_every=50)
    assert e.value.step == full.value.step == 195
    assert str(e.value) == str(full.value)
    assert_rows(e.value.trajectory, full.value.trajectory, [0, 50, 100, 150, 195])


class Collector:
    """An ``on_rows`` that keeps what it receives."""

    def __init__(self):
        self.chunks = []

    def __call__(self, t, x, u):
        self.chunks.append((t, x, u))

    def cat(self, i):
        return np.concatenate([c[i] for c in self.chunks])

    @property
    def sizes(self):
        return [len(c[0]) for c in self.chunks]


@pytest.mark.parametrize("steps,k,chunk,sizes", [
    (300, 7, 10, [10, 10, 10, 10, 4]),  # 44 rows
    (300, 1, 100, [100, 100, 100, 1]),  # 301 rows
    (300, 10, 31, [31]),  # exactly one chunk
    (300, 10, 1, [1] * 31),
    (300, 1000, 5, [2]),
])
def test_streaming_delivers_every_kept_row_once_in_order(arm, pd, steps, k, chunk, sizes):
    memory = arm.simulate(arm.state(), DT, steps, u=pd, record_every=k)
    sink = Collector()
    last = arm.simulate(arm.state(), DT, steps, u=pd, record_every=k, on_rows=sink, chunk_rows=chunk)
    assert sink.sizes == sizes
    for t, x, u in sink.chunks:
        assert x.shape == (len(t), arm.state_size) and t.dtype == x.dtype == u.dtype == np.float64
        assert x.flags.writeable  # the caller's own arrays
    assert [len(c[2]) for c in sink.chunks] == sizes[:-1] + [sizes[-1] - 1]
    np.testing.assert_array_equal(sink.cat(0), memory.t)
    np.testing.assert_array_equal(sink.cat(1), memory.x)
    np.testing.assert_array_equal(sink.cat(2), memory.u)
    # the returned trajectory holds only the final row
    assert (last.t.shape, last.x.shape, last.u.shape) == ((1,), (1, arm.state_size), (0, arm.dof))
    np.testing.assert_array_equal(last.x[0], memory.x[-1])
    assert last.t[0] == memory.t[-1]


def test_streaming_default_chunk_is_1024_rows(arm):
    sink = Collector()
    arm.simulate(arm.state(), DT, 3000, on_rows=sink)
    assert sink.sizes == [1024, 1024, 953]


def test_a_failed_streamed_run_flushes_before_raising(arm):
    table = np.sin(np.arange(100 * 7, dtype=float)).reshape(100, 7)
    full = arm.simulate(arm.state(), DT, 100, u=table)

    def controller(t, x):
        step = int(round(t / DT))
        if step == 37:
            raise KeyError("lost the reference")
        return table[step]

    sink = Collector()
    with pytest.raises(SimulationError) as e:
        arm.simulate(arm.state(), DT, 100, u=controller, record_every=10, on_rows=sink, chunk_rows=3)
    assert e.value.step == 37
    assert sink.sizes == [3, 2]
    np.testing.assert_array_equal(sink.cat(1), full.x[[0, 10, 20, 30, 37]])
    np.testing.assert_array_equal(sink.cat(2), full.u[[0, 10, 20, 30]])
    # the error's trajectory is the last good state alone
    np.testing.assert_array_equal(e.value.trajectory.x, full.x[[37]])


def test_an_exception_in_on_rows_stops_the_run_and_propagates(arm, pd):
    calls = []

    class Full(Exception):
        pass

    def on_rows(t, x, u):
        calls.append(len(t))
        if len(calls) == 2:
            raise Full("disk full")

    with pytest.raises(Full, match="disk full"):
        arm.simulate(arm.state(), DT, 10_000, u=pd, on_rows=on_rows, chunk_rows=100)
    assert calls == [100, 100]  # stopped at once: no third chunk, no flush
    # with a Python controller too
    calls.clear()
    with pytest.raises(Full):
        arm.simulate(arm.state(), DT, 10_000, u=lambda t, x: np.zeros(7), on_rows=on_rows, chunk_rows=100)
    assert calls == [100, 100]


def test_memory_is_bounded_by_the_chunk(arm):
    # 10^6 steps of a 1-joint arm: the returned trajectory holds one row, the chunks 500 at most
    robot = orbitflex.Robot.from_urdf_string(
        '<robot name="one"><link name="base"><inertial><mass value="100"/>'
        '<inertia ixx="10" iyy="10" izz="10" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<link name="l1"><inertial><origin xyz="0.5 0 0"/><mass value="2"/>'
        '<inertia ixx="0.01" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
        '<axis xyz="0 0 1"/></joint></robot>')
    small = FlexibleArm(robot, orbitflex.FlexibleJoints(1e3, 0.1, 0.5, 0.1))
    sizes, last_t = [], []

    def on_rows(t, x, u):
        sizes.append(x.shape[0])
        last_t.append(t[-1])

    steps = 1_000_000
    traj = small.simulate(small.state(), 1e-4, steps, u=np.ones(1), on_rows=on_rows, chunk_rows=500)
    assert (traj.t.shape, traj.x.shape, traj.u.shape) == ((1,), (1, small.state_size), (0, 1))
    assert max(sizes) == 500 and sum(sizes) == steps + 1 and len(sizes) == 2001
    assert last_t[-1] == traj.t[0] == steps * 1e-4
    # record_every alone: O(rows)
    traj = small.simulate(small.state(), 1e-4, steps, u=np.ones(1), record_every=10_000)
    assert traj.x.shape == (101, small.state_size)
    assert traj.t[-1] == steps * 1e-4


@pytest.mark.parametrize("value,words", [
    (0, "given int (0)"),
    (-3, "given int (-3)"),
    (2.0, "given float (2.0)"),
    (True, "given bool (True)"),
    ("4", "given str ('4')"),
])
def test_bad_record_every_is_an_error_naming_it(arm, value, words):
    with pytest.raises(orbitflex.ModelError) as e:
        arm.simulate(arm.state(), DT, 10, record_every=value)
    assert str(e.value) == f"record_every: expected an integer >= 1, {words}"


@pytest.mark.parametrize("value,words", [
    (0, "given int (0)"), (-1, "given int (-1)"), (1.5, "given float (1.5)"), (False, "given bool (False)"),
])
def test_bad_chunk_rows_is_an_error_naming_it(arm, value, words):
    with pytest.raises(orbitflex.ModelError) as e:
        arm.simulate(arm.state(), DT, 10, on_rows=lambda t, x, u: None, chunk_rows=value)
    assert str(e.value) == f"chunk_rows: expected an integer >= 1, {words}"


def test_chunk_rows_without_on_rows_and_a_non_callable_on_rows_are_errors(arm):
    with pytest.raises(orbitflex.ModelError, match=r"^chunk_rows: sizes the chunks given to on_rows; give on_rows"):
        arm.simulate(arm.state(), DT, 10, chunk_rows=5)
    with pytest.raises(orbitflex.ModelError, match=r"^on_rows: expected a callable on_rows\(t, x, u\), given int$"):
        arm.simulate(arm.state(), DT, 10, on_rows=3)


def test_progress_still_reports_every_step_count(arm):
    calls = []
    arm.simulate(arm.state(), DT, 3000, record_every=100, progress=lambda d, s: calls.append((d, s)),
                 on_rows=lambda t, x, u: None)
    assert calls == [(1024, 3000), (2048, 3000), (3000, 3000)]


def test_ctrl_c_stops_a_long_streamed_run():
    # as test_robustness.py's, with record_every and on_rows: SIGINT after half a second raises
    # KeyboardInterrupt promptly, and the chunks delivered before it were whole
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
        sizes = []
        threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
        start = time.perf_counter()
        try:
            arm.simulate(arm.state(), 1e-4, 200_000, u=pd, record_every=3, on_rows=lambda t, x, u: sizes.append(len(t)), chunk_rows=64)
            print("FINISHED", time.perf_counter() - start)
        except KeyboardInterrupt:
            assert all(s == 64 for s in sizes[:-1]), sizes
            print("INTERRUPTED", len(sizes) > 0, time.perf_counter() - start)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert "INTERRUPTED True" in out.stdout, out.stdout + out.stderr
    assert float(out.stdout.split()[-1]) < 3.0, out.stdout
