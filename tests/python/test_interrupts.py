"""Ctrl-C: every long computation without the GIL stops soon after SIGINT and raises
``KeyboardInterrupt``.

Each case runs in a subprocess that sends itself a real SIGINT from a timer thread while the
call runs, and prints how long the call took to stop after the signal. orbitflex looks for
signals every 50 ms (measured: 0.01-0.1 s from signal to exception); the bound asserted here is
loose (1.5 s, three times the half second a user waits) because CI machines are shared, and
speed is measured in benchmarks, not asserted in tests. Before issue 24 these calls took
several seconds (batched rows, per-run stability limits) or ignored the signal until they
finished."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

HARNESS = r"""
import os, signal, sys, threading, time
import numpy as np
import orbitflex

def interrupted(call, after):
    '''Runs call(); SIGINT `after` s into it. Prints the latency from the signal to the
    KeyboardInterrupt, or FINISHED.'''
    sent = []
    def kill():
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)
    timer = threading.Timer(after, kill)
    timer.start()
    try:
        call()
    except KeyboardInterrupt:
        print(f"INTERRUPTED {time.perf_counter() - sent[0]:.3f}")
        return
    finally:
        timer.cancel()
    print("FINISHED", f"{time.perf_counter():.3f}")

def rows_for(call_with_rows, seconds, most):
    '''Rows that keep call_with_rows busy for about `seconds` on this machine (at most `most`).'''
    start = time.perf_counter()
    call_with_rows(2000)
    per_row = (time.perf_counter() - start) / 2000
    return int(min(most, seconds / per_row))
"""

LIMIT = 1.5


def run(body: str, timeout: float = 300.0) -> float:
    """The latency (s) from SIGINT to KeyboardInterrupt of the call in ``body``; its output in
    ``run.output``."""
    code = textwrap.dedent(HARNESS) + textwrap.dedent(body)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout,
                            env=dict(os.environ, RUST_BACKTRACE="0"))
    assert result.returncode == 0, result.stderr[-3000:]
    assert "INTERRUPTED" in result.stdout, result.stdout + result.stderr[-3000:]
    run.output = result.stdout  # type: ignore[attr-defined]
    return float(result.stdout.split("INTERRUPTED")[1].split()[0])


@pytest.mark.parametrize("method,most,after", [("recursive", 2_000_000, 0.2), ("operator", 1_000_000, 0.5)])
def test_ctrl_c_stops_a_batched_call_of_millions_of_rows(method, most, after):
    # Issue 24: a batched forward_dynamics of 4e6 rows took 2.8-5 s to stop. The rows here
    # would take about 20 s (sized on this machine, at most `most` rows: 0.4 GB). A recursive
    # row takes under a microsecond, so the calling thread looks at the clock every few dozen
    # rows; an operator-form row takes tens of microseconds.
    latency = run(f"""
        robot = orbitflex.models.space_arm()
        n = robot.dof
        zero = np.zeros(n)
        def call(rows):
            q = np.broadcast_to(np.linspace(-1, 1, n), (rows, n))
            robot.forward_dynamics(q, np.zeros(6), zero, zero, method="{method}")
        rows = rows_for(call, 20.0, {most})
        q = np.ascontiguousarray(np.broadcast_to(np.linspace(-1, 1, n), (rows, n)))
        interrupted(lambda: robot.forward_dynamics(q, np.zeros(6), zero, zero, method="{method}"), {after})
        """)
    assert latency < LIMIT


def test_ctrl_c_stops_the_stability_checks_of_a_batch_of_distinct_arms():
    # Issue 24: 8000 distinct arms took 7-14 s to stop: the per-run stability limit (a few ms
    # each) did not look for Ctrl-C. No progress report comes before the runs start, so an
    # empty report list shows the signal landed in the checks.
    latency = run("""
        robot = orbitflex.models.space_arm()
        n = robot.dof
        arms = [orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints(2e3 + i, 0.05)) for i in range(8000)]
        pds = [orbitflex.MotorPD(100.0 + i, 10.0, np.zeros(n)) for i in range(8000)]
        reports = []
        interrupted(lambda: orbitflex.simulate_batch(arms, arms[0].state(), 1e-3, 10, u=pds, keep_rows=False,
                                                     progress=lambda done, runs: reports.append(done)), 0.3)
        print("REPORTS", len(reports))
        """)
    assert latency < LIMIT
    assert "REPORTS 0" in run.output  # type: ignore[attr-defined]


def test_ctrl_c_stops_a_batch_of_a_large_model_between_steps():
    # a step of a 300-joint chain takes about a millisecond: the runs look for the cancel flag
    # every 16 steps, not every 1024
    latency = run("""
        parts = ['<link name="l0"><inertial><mass value="50"/><inertia ixx="5" iyy="5" izz="5" ixy="0" ixz="0" iyz="0"/></inertial></link>']
        for i in range(300):
            parts.append(f'<link name="l{i+1}"><inertial><origin xyz="0.1 0 0"/><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>')
            parts.append(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i+1}"/><origin xyz="0.2 0 0"/><axis xyz="0 0 1"/></joint>')
        robot = orbitflex.Robot.from_urdf_string('<robot name="long">' + "".join(parts) + '</robot>')
        arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints(1e3, 0.1))
        interrupted(lambda: orbitflex.simulate_batch(arm, arm.state(), 1e-4, 100_000, u=np.zeros((2, 300)),
                                                     threads=2, keep_rows=False), 1.0)
        """)
    assert latency < LIMIT


def test_ctrl_c_stops_planning_a_large_arm():
    # planning a 300-joint arm through two waypoints takes seconds: the planner looks for the
    # flag before every trial duration
    latency = run("""
        parts = ['<link name="l0"><inertial><mass value="500"/><inertia ixx="50" iyy="50" izz="50" ixy="0" ixz="0" iyz="0"/></inertial></link>']
        for i in range(300):
            axis = "0 0 1" if i % 2 else "0 1 0"
            parts.append(f'<link name="l{i+1}"><inertial><origin xyz="0.1 0 0"/><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>')
            parts.append(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i+1}"/><origin xyz="0.2 0 0"/><axis xyz="{axis}"/></joint>')
        robot = orbitflex.Robot.from_urdf_string('<robot name="long">' + "".join(parts) + '</robot>')
        arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints(1e4, 0.1, 1.0))
        stops = [np.full(300, 0.05), np.full(300, 0.1)]
        interrupted(lambda: orbitflex.plan_slew(arm, np.full(300, 0.2), limits=orbitflex.Limits(100.0, 1.0),
                                                waypoints=stops), 0.3)
        """)
    assert latency < LIMIT
