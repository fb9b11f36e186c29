"""``orbitflex.Simulator``: stepped from Python, bit for bit ``arm.simulate``'s states with the same
inputs; held inputs, outputs, save/restore, errors, threads and Ctrl-C."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

import orbitflex


@pytest.fixture(scope="module")
def arm() -> orbitflex.FlexibleArm:
    return orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())


def moving_state(arm: orbitflex.FlexibleArm) -> np.ndarray:
    rng = np.random.default_rng(5)
    n = arm.dof
    q = rng.uniform(-1, 1, n)
    return arm.state(q=q, theta=q + rng.uniform(-0.01, 0.01, n), qd=rng.uniform(-0.3, 0.3, n),
                     base_twist=rng.uniform(-0.1, 0.1, 6), base_pose=[0.1, 0.2, 0.3, 0.2, 0.1, 0.0, 1.9])


def test_steps_equal_simulate_with_per_step_tables(arm):
    rng = np.random.default_rng(1)
    steps, n = 300, arm.dof
    u = rng.uniform(-5, 5, (steps, n))
    base = rng.uniform(-2, 2, (steps, 6))
    ee = rng.uniform(-1, 1, (steps, 6))
    x0 = moving_state(arm)
    traj = arm.simulate(x0, 1e-3, steps, u=u, base_wrench=base, ee_wrench=ee)
    sim = orbitflex.Simulator(arm, x0, 1e-3)
    assert np.array_equal(sim.x, traj.x[0])
    for k in range(steps):
        sim.step(u=u[k], base_wrench=base[k], ee_wrench=ee[k])
        assert np.array_equal(sim.x, traj.x[k + 1]), k
        assert sim.t == traj.t[k + 1]


def test_held_inputs_and_step_n_equal_simulate_with_constants(arm):
    x0 = moving_state(arm)
    u = np.linspace(-1, 1, arm.dof)
    traj = arm.simulate(x0, 1e-3, 1000, u=u, base_wrench=[0, 0, 0.1, 1, 0, 0])
    sim = orbitflex.Simulator(arm, x0, 1e-3)
    sim.step(u=u, base_wrench=[0, 0, 0.1, 1, 0, 0], n=1000)  # the long path, without the GIL
    assert np.array_equal(sim.x, traj.x[-1])
    assert sim.steps == 1000
    held = orbitflex.Simulator(arm, x0, 1e-3)
    held.step(u=u, base_wrench=[0, 0, 0.1, 1, 0, 0])
    for _ in range(999):
        held.step()  # the inputs stay
    assert np.array_equal(held.x, traj.x[-1])
    assert np.array_equal(held.inputs["u"], u)
    assert held.inputs["ee_wrench"] is None


def test_a_python_pd_closing_the_loop_equals_the_same_run_tabulated(arm):
    # the master's controller in Python, its torques recorded, replayed through simulate
    n, dt, steps = arm.dof, 1e-3, 500
    kp, kd, target = 600.0, 150.0, np.full(n, 0.2)
    sim = orbitflex.Simulator(arm, arm.state(), dt)
    torques = []
    for _ in range(steps):
        out = sim.outputs()
        u = kp * (target - out["theta"]) - kd * out["theta_dot"]
        torques.append(u)
        sim.step(u=u)
    traj = arm.simulate(arm.state(), dt, steps, u=np.array(torques))
    assert np.array_equal(sim.x, traj.x[-1])
    # on its way to the target: every joint has covered more than a quarter of the way in 0.5 s
    assert np.abs(sim.outputs()["q"] - 0.2).max() < 0.75 * 0.2


def test_outputs(arm):
    sim = orbitflex.Simulator(arm, moving_state(arm), 1e-3)
    sim.step(u=np.full(arm.dof, 0.5), n=10)
    x = sim.x
    out = sim.outputs()
    layout = arm.state_slices
    assert np.array_equal(out["q"], x[layout["q"]])
    assert np.array_equal(out["deflection"], x[layout["theta"]] - x[layout["q"]])
    assert np.array_equal(out["base_pose"], x[layout["base_pose"]])
    assert np.array_equal(out["base_twist"], x[layout["base_twist"]])
    assert out["ee_poses"].shape == (1, 7)
    assert np.array_equal(out["ee_poses"][0], arm.ee_pose(x))
    assert np.array_equal(out["momentum"], arm.momentum(x))
    assert out["energy"] == arm.energy(x)
    j = arm.joints
    k, d = np.asarray(j.stiffness), np.asarray(j.damping)
    tau = k * (x[layout["theta"]] - x[layout["q"]]) + d * (x[layout["theta_dot"]] - x[layout["qd"]])
    assert np.allclose(out["spring_torque"], tau, rtol=1e-14, atol=0)


def test_save_restore_and_reset(arm):
    x0 = moving_state(arm)
    sim = orbitflex.Simulator(arm, x0, 1e-3)
    sim.step(u=np.ones(arm.dof), n=40)
    blob = sim.save()
    assert isinstance(blob, bytes)
    saved = sim.x
    sim.step(n=60)
    ahead = sim.x
    sim.step(u=np.zeros(arm.dof), n=5)
    sim.restore(blob)
    assert np.array_equal(sim.x, saved) and sim.steps == 40
    sim.step(n=60)
    assert np.array_equal(sim.x, ahead)
    sim.reset(x0)
    assert sim.t == 0.0 and np.array_equal(sim.inputs["u"], np.zeros(arm.dof))

    other = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.FlexibleJoints(1e4, 1.0))
    foreign = orbitflex.Simulator(other, x0, 1e-3)
    with pytest.raises(orbitflex.ModelError, match="saved from another arm"):
        foreign.restore(blob)
    with pytest.raises(orbitflex.ModelError, match="not a saved orbitflex simulator state"):
        sim.restore(b"hello")


def test_bad_arguments(arm):
    sim = orbitflex.Simulator(arm, arm.state(), 1e-3)
    with pytest.raises(orbitflex.ModelError, match="u: expected length 7"):
        sim.step(u=np.ones(3))
    with pytest.raises(orbitflex.ModelError, match="not finite"):
        sim.step(u=np.full(7, np.nan))
    with pytest.raises(orbitflex.ModelError, match="n: expected an integer >= 1"):
        sim.step(n=0)
    with pytest.raises(orbitflex.ModelError, match="reaction wheels"):
        sim.step(wheel_torque=[0.1])
    with pytest.raises(orbitflex.ModelError, match="dt"):
        orbitflex.Simulator(arm, arm.state(), -1e-3)
    with pytest.raises(orbitflex.ModelError, match="x0"):
        orbitflex.Simulator(arm, np.zeros(5), 1e-3)
    assert sim.steps == 0, "a refused step takes no step"


def test_a_diverging_step_raises_and_keeps_the_last_good_state(arm):
    x0 = moving_state(arm)
    with pytest.raises(orbitflex.SimulationError) as failed_run, pytest.warns(RuntimeWarning, match="stability"):
        arm.simulate(x0, 0.2, 10_000)
    sim = orbitflex.Simulator(arm, x0, 0.2)
    with pytest.raises(orbitflex.SimulationError, match="diverged") as failed:
        sim.step(n=10_000)
    assert failed.value.step == failed_run.value.step == sim.steps
    assert np.array_equal(sim.x, failed_run.value.trajectory.x[-1])


def test_one_simulator_per_thread(arm):
    # Two simulators stepped on two threads at once equal the same runs made one after the
    # other; one simulator used by a second thread while it steps refuses at once.
    x0 = moving_state(arm)
    alone = orbitflex.Simulator(arm, x0, 1e-3)
    alone.step(u=np.ones(7), n=3000)
    sims = [orbitflex.Simulator(arm, x0, 1e-3) for _ in range(2)]
    threads = [threading.Thread(target=s.step, kwargs=dict(u=np.ones(7), n=3000)) for s in sims]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for s in sims:
        assert np.array_equal(s.x, alone.x)

    shared = orbitflex.Simulator(arm, x0, 1e-3)
    errors = []
    started = threading.Event()

    def long_step() -> None:
        started.set()
        shared.step(n=200_000)

    worker = threading.Thread(target=long_step)
    worker.start()
    started.wait()
    for _ in range(2000):
        try:
            shared.x
        except RuntimeError as e:
            errors.append(str(e))
            break
    worker.join()
    assert shared.steps == 200_000
    if errors:  # unless the step finished before the first look
        assert "another thread is using this simulator" in errors[0]


def test_ctrl_c_stops_a_long_step():
    code = textwrap.dedent("""
        import os, signal, threading, time
        import numpy as np, orbitflex
        arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
        sim = orbitflex.Simulator(arm, arm.state(), 1e-4)
        sent = []
        def kill():
            sent.append(time.perf_counter())
            os.kill(os.getpid(), signal.SIGINT)
        threading.Timer(0.3, kill).start()
        try:
            sim.step(u=np.ones(7), n=100_000_000)
            print("FINISHED")
        except KeyboardInterrupt:
            print(f"INTERRUPTED {time.perf_counter() - sent[0]:.3f} {sim.steps}")
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                            env=dict(os.environ, RUST_BACKTRACE="0"))
    assert "INTERRUPTED" in result.stdout, result.stdout + result.stderr[-2000:]
    latency, steps = result.stdout.split()[1:3]
    assert float(latency) < 1.5  # 50 ms looks; loose for a shared CI machine
    assert 0 < int(steps) < 100_000_000  # the steps taken are kept
