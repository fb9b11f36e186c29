"""Detumbling a captured target with the bus's reaction wheels (issue 29, item 1): the scenario
with wheels, the rigid-stack prediction of the detumble, momentum with the wheels' spin, the
wheels' limits in the metrics; and the capture values pickling bit for bit (item 2)."""

import dataclasses
import math
import pickle

import numpy as np
import pytest

import orbitflex as of
from orbitflex import detumble, models


@pytest.fixture(scope="module")
def scenario():
    return models.capture_scenario(wheels=models.pyramid_wheels())


@pytest.fixture(scope="module")
def long_run(scenario):
    # 250 s: the capture at 4.5 s, then the detumble (a time constant 1/(ζ ω_n) ≈ 29 s)
    return scenario.run(250.0, record_every=10)


def _linear_prediction(scenario, traj, horizon):
    """The rigid stack's rates (deg/s) after the capture, on a 10 ms grid, from the combined
    arm's inertia, the gains, and the stack's rate and the bus's attitude error at the capture."""
    e = traj.events[0]
    arm = traj.arm_after
    inertia = detumble.stack_inertia(arm, e.x_after)[2]
    rate = detumble.stack_rate(arm, e.x_after)
    quat = e.x_after[3:7]  # the AttitudePD holds the initial attitude, the identity here
    error = 2.0 * quat[:3] * np.sign(quat[3])
    kp, kd = scenario.wheel_controller.kp[0], scenario.wheel_controller.kd[0]
    t = np.arange(0.0, horizon, 0.01)
    return t, np.degrees(np.linalg.norm(detumble.rigid_stack_rates(inertia, kp, kd, error, rate, t), axis=1))


def test_the_default_gains_come_from_the_stack(scenario):
    inertia = detumble.stack_inertia(scenario.stack(), scenario.x0)[2]
    i_max = np.linalg.eigvalsh(inertia)[-1]
    w, zeta = models.DETUMBLE_BANDWIDTH, 0.7
    np.testing.assert_allclose(scenario.wheel_controller.kp, w * w * i_max, rtol=1e-15)
    np.testing.assert_allclose(scenario.wheel_controller.kd, 2 * zeta * w * i_max, rtol=1e-15)
    # the major axis gets (ω_n, ζ) = (bandwidth, 0.7): √(kp/I) and kd/(2√(kp I))
    kp, kd = scenario.wheel_controller.kp[0], scenario.wheel_controller.kd[0]
    assert math.isclose(math.sqrt(kp / i_max), w, rel_tol=1e-14)
    assert math.isclose(kd / (2 * math.sqrt(kp * i_max)), zeta, rel_tol=1e-14)
    # with wheels the motor PD is tuned for the arm holding its catch: stiffer than for the arm
    plain = models.capture_scenario()
    assert np.all(scenario.controller.kp > plain.controller.kp)


def test_stack_inertia_is_the_rigid_body_of_arm_and_catch(scenario):
    # the stack's mass: the robot's, the wheels' and the target's
    stack = scenario.stack()
    mass, com, inertia = detumble.stack_inertia(stack, scenario.x0)
    wheels = scenario.arm.wheels
    assert math.isclose(mass, stack.robot.total_mass + float(np.sum(wheels.mass)), rel_tol=1e-14)
    assert math.isclose(stack.robot.total_mass, scenario.arm.robot.total_mass + scenario.target.mass, rel_tol=1e-14)
    # a rigid body at rest turning at ω about its centre of mass has momentum I ω there: probe it
    omega = np.array([0.01, -0.02, 0.015])
    v_com = -np.cross(omega, com)  # the base origin's velocity that keeps the centre still
    x = stack.state(q=scenario.x0[7:14], theta=scenario.x0[7:14], base_twist=np.r_[omega, v_com],
                    wheel_speed=-(np.asarray(wheels.axes) @ omega))
    h = stack.momentum(x)
    np.testing.assert_allclose(h[3:], 0.0, atol=1e-12 * mass * np.linalg.norm(v_com))
    np.testing.assert_allclose(h[:3], inertia @ omega, rtol=0, atol=1e-12 * np.abs(inertia @ omega).max())
    np.testing.assert_allclose(detumble.stack_rate(stack, x), omega, rtol=1e-11)


def test_rigid_stack_closed_form_solves_its_ode():
    # I ë = −kp e − kd ė, checked by finite differences of the closed form, in all three regimes:
    # one principal moment is 2000 exactly, so the second pair of gains damps it critically
    inertia = np.array([[300.0, 20.0, 0.0], [20.0, 5000.0, 0.0], [0.0, 0.0, 2000.0]])
    for kp, kd in ((50.0, 2000.0), (50.0, 2 * math.sqrt(50.0 * 2000.0)), (50.0, 100.0)):
        t = np.linspace(0.0, 40.0, 4001)
        e0, w0 = np.array([0.01, -0.02, 0.005]), np.array([0.001, 0.002, -0.003])
        w = detumble.rigid_stack_rates(inertia, kp, kd, e0, w0, t)
        np.testing.assert_allclose(w[0], w0, atol=1e-15)
        e = e0 + np.concatenate([[np.zeros(3)], np.cumsum((w[1:] + w[:-1]) / 2 * 0.01, axis=0)])
        wdot = np.gradient(w, t, axis=0)
        residual = wdot @ inertia.T + kp * e + kd * w
        # trapezoid and central differences: O(h²) with h = 0.01 s against |kd ω| ≈ 1e-1 N·m
        assert np.abs(residual[5:-5]).max() < 1e-3 * max(1.0, np.abs(kd * w).max())


def test_the_stack_detumbles_as_the_rigid_stack_predicts(scenario, long_run):
    traj = long_run
    (e,) = traj.events
    # the prediction holds once the arm turns as a rigid body under the slow attitude loop: its
    # lowest closed-loop mode with the catch (modes of the arm on the bus, wheels' 48 kg aside)
    arm = traj.arm_after
    plain = of.FlexibleArm(arm.robot, arm.joints)
    n = arm.dof
    modes = plain.modes(e.x_after[:13 + 4 * n], u=scenario.controller, base="free")
    w_arm = 2 * math.pi * modes.natural_frequency_hz[0]
    ratio = models.DETUMBLE_BANDWIDTH / w_arm
    assert ratio < 0.1  # the attitude loop is slow against the arm: a rigid stack to first order
    t, predicted = _linear_prediction(scenario, traj, 250.0 - e.time)
    for threshold in (0.01, 0.002):
        t_pred = t[np.flatnonzero(predicted > threshold)[-1] + 1]
        measured = of.detumble_metrics(traj, bus_rate=threshold)["detumble_time"]
        # The flexible arm shifts the stack's slow poles by O(Ω/ω_arm) relative (the attitude
        # loop's damping reaches the catch through the arm's loop), so the time to fall by a given
        # factor moves by as much; allow twice that: 2 × 0.05/0.90 ≈ 11 % (measured: ≈ 1 %).
        assert abs(measured - t_pred) <= 2 * ratio * t_pred, (threshold, measured, t_pred)
    m = of.detumble_metrics(traj)
    assert m["detumble_time"] < 60.0 and m["final_bus_rate_deg_s"] < 1e-4
    # without the wheels the stack keeps turning
    plain_run = models.capture_scenario().run(30.0, record_every=10)
    assert math.isnan(of.detumble_metrics(plain_run)["detumble_time"])


def test_the_wheels_take_the_stack_momentum_within_their_limits(scenario, long_run):
    traj = long_run
    m = of.detumble_metrics(traj)
    (e,) = traj.events
    # at the end the stack is at rest: the wheels hold all the momentum about the centre of mass
    arm = traj.arm_after
    mass, com, _ = detumble.stack_inertia(arm, traj.x[-1])
    rot = of.rotation_matrix(traj.x[-1][3:7])
    h_total = traj.momentum[-1]
    about_com = rot.T @ (h_total[:3] - np.cross(traj.x[-1][:3] + rot @ com, h_total[3:]))
    h_wheels = detumble.wheel_momentum(arm, traj.x[-1])
    np.testing.assert_allclose(h_wheels, about_com, rtol=0, atol=1e-3 * np.linalg.norm(about_com))
    assert math.isclose(m["wheel_momentum_nms"], np.linalg.norm(h_wheels), rel_tol=1e-12)
    assert m["peak_wheel_momentum_nms"] >= m["wheel_momentum_nms"]
    # the pyramid (4 × 200 N·m·s, 60 N·m) is far from its limits
    w = scenario.arm.wheels
    speed = np.abs(traj.wheel_speed).max(axis=0) / w.max_speed
    torque = np.abs(traj.wheel_torque).max(axis=0) / w.max_torque
    np.testing.assert_array_equal(m["peak_wheel_speed_fraction_per_wheel"], speed)
    np.testing.assert_array_equal(m["peak_wheel_torque_fraction_per_wheel"], torque)
    assert 0 < m["peak_wheel_speed_fraction"] < 0.2 and 0 < m["peak_wheel_torque_fraction"] < 0.2
    assert m["wheels_saturated"] is False


def test_saturated_wheels_are_reported():
    # wheels with a 0.05 N·m motor cannot deliver what the gains ask right after the capture
    small = models.pyramid_wheels(max_torque=0.05)
    s = models.capture_scenario(wheels=small)
    traj = s.run(20.0, record_every=10)
    m = of.detumble_metrics(traj)
    assert m["wheels_saturated"] is True
    assert m["peak_wheel_torque_fraction"] == 1.0  # clipped to the limit exactly
    # and momentum is still conserved: saturation changes what the wheels do, not the physics
    h = traj.momentum
    assert np.abs(h - h[0]).max() < 1e-8 * np.abs(h[0]).max()


def test_momentum_with_the_wheels_spin_is_kept_to_rk4_accuracy():
    # total momentum of bus, arm, target and the wheels' spin: across the event to round-off, and
    # along the run to RK4's truncation, which falls as dt⁴ (a term left out would not)
    drift = {}
    for dt in (2e-3, 1e-3):
        s = dataclasses.replace(models.capture_scenario(wheels=models.pyramid_wheels()), dt=dt)
        traj = s.run(20.0, record_every=int(round(0.01 / dt)))
        (e,) = traj.events
        scale = np.abs(e.momentum_before).max()
        np.testing.assert_allclose(e.momentum_after, e.momentum_before, rtol=0, atol=1e-12 * scale)
        after = traj.t > e.time
        drift[dt] = np.abs(traj.momentum[after] - e.momentum_after).max()
        # the wheels' spin changes by far more than the drift: it is in the balance
        spin = detumble.wheel_momentum(traj.arm, traj.x)
        assert np.abs(spin[-1] - spin[0]).max() > 1e6 * drift[dt]
    assert 16 * 0.6 < drift[2e-3] / drift[1e-3] < 16 * 1.6, drift


def test_the_combined_arm_keeps_the_wheels(scenario):
    traj = scenario.run(6.0, record_every=10)
    after = traj.arm_after
    assert after.wheels is not None and after.state_size == scenario.arm.state_size
    # the momentum of the last row is the combined arm's (wheels included), bit for bit
    np.testing.assert_array_equal(traj.momentum[-1], after.momentum(traj.x[-1]))
    # and orbitflex.capture's combined arm too
    (e,) = traj.events
    target = of.Target(scenario.target.mass, scenario.target.inertia, e.target_before[:7],
                       e.target_before[7:], scenario.target.grasp)
    c = of.capture(scenario.arm, e.x_before, target)
    assert c.arm.wheels is not None
    np.testing.assert_array_equal(c.x, e.x_after)


def test_bad_scenario_arguments():
    with pytest.raises(ValueError, match="attitude_pd: given without wheels"):
        models.capture_scenario(attitude_pd=of.AttitudePD(1.0, 1.0))
    with pytest.raises(ValueError, match="motor_pd: expected 'arm' or 'stack', given 'loose'"):
        models.capture_scenario(motor_pd="loose")
    with pytest.raises(TypeError, match="wheels: expected a ReactionWheels, given list"):
        models.capture_scenario(wheels=[1, 2])
    with pytest.raises(ValueError, match="bandwidth and damping_ratio: expected > 0"):
        detumble.detumble_gains(np.eye(3), 0.0)
    with pytest.raises(ValueError, match="inertia: expected a symmetric positive definite"):
        detumble.detumble_gains(-np.eye(3), 0.1)


def _same(a, b):
    """Two capture values equal in every attribute, bit for bit."""
    names = [n for n in dir(a) if not n.startswith("_") and not callable(getattr(a, n))]
    for name in names:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and np.array_equal(x, y, equal_nan=True), name
            assert x.tobytes() == y.tobytes(), name
        elif isinstance(x, (int, float, str, bool)) or x is None:
            assert x == y or (x != x and y != y), name
    return names


def test_capture_values_pickle_bit_for_bit(scenario):
    traj = scenario.run(6.0, record_every=7)
    (e,) = traj.events
    assert "impulse" in _same(e, pickle.loads(pickle.dumps(e)))
    target = pickle.loads(pickle.dumps(scenario.target))
    assert "pose" in _same(scenario.target, target)
    when = pickle.loads(pickle.dumps(scenario.when))
    _same(scenario.when, when)
    c = of.capture(scenario.arm, e.x_before, of.Target(
        scenario.target.mass, scenario.target.inertia, e.target_before[:7], e.target_before[7:],
        scenario.target.grasp))
    c2 = pickle.loads(pickle.dumps(c))
    assert "payload_inertia" in _same(c, c2)
    np.testing.assert_array_equal(c2.arm.momentum(c2.x), c.arm.momentum(c.x))
    # a run with a target keeps its events, target rows and combined arm through pickle
    t2 = pickle.loads(pickle.dumps(traj))
    assert len(t2.events) == 1 and "x_after" in _same(traj.events[0], t2.events[0])
    for name in ("t", "x", "u", "target", "momentum", "energy", "wheel_speed", "wheel_torque"):
        assert getattr(t2, name).tobytes() == getattr(traj, name).tobytes(), name
    assert t2.arm_after.wheels is not None
    assert of.detumble_metrics(t2) == of.detumble_metrics(traj) or _nan_equal(
        of.detumble_metrics(t2), of.detumble_metrics(traj))
    # a scenario (the values a campaign ships) pickles too
    s2 = pickle.loads(pickle.dumps(scenario))
    assert s2.wheel_controller.kp.tobytes() == scenario.wheel_controller.kp.tobytes()


def _nan_equal(a, b):
    assert a.keys() == b.keys()
    for k in a:
        x, y = a[k], b[k]
        assert x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y)), k
    return True


def test_a_batch_with_wheels_equals_single_runs():
    scenarios = [models.capture_scenario(rate, 0.02, 0.6, wheels=models.pyramid_wheels()) for rate in (1.0, 3.0)]
    steps = 1500
    trajs = of.simulate_capture_batch(
        [s.arm for s in scenarios], np.array([s.x0 for s in scenarios]), 1e-3, steps,
        [s.controller for s in scenarios], [s.target for s in scenarios], scenarios[0].when,
        record_every=3, threads=2, wheel_torque=[s.wheel_controller for s in scenarios])
    for s, traj in zip(scenarios, trajs):
        single = s.run(steps * 1e-3, record_every=3)
        assert len(traj.events) == 1
        for name in ("x", "u", "target", "wheel_torque"):
            assert getattr(traj, name).tobytes() == getattr(single, name).tobytes(), name
    with pytest.raises(of.ModelError, match=r"wheel_torque: arms\[0\] has no reaction wheels"):
        plain = models.capture_scenario()
        of.simulate_capture_batch(plain.arm, plain.x0, 1e-3, 10, plain.controller, [plain.target], plain.when,
                                  wheel_torque=scenarios[0].wheel_controller)


def test_on_rows_with_a_target_is_refused_with_the_way_to_stream():
    # kept refused (see docs/capture.md): the callback would not carry the target's rows; the
    # message gives the way to stream a long run: the approach with the target, then the combined
    # arm with on_rows, which continues the run exactly (the motor PD holds no state)
    s = models.capture_scenario()
    with pytest.raises(of.ModelError, match=r"on_rows: not with a target.*traj.arm_after"):
        s.arm.simulate(s.x0, s.dt, 10, s.controller, target=s.target, capture=s.when,
                       on_rows=lambda t, x, u: None)
    whole = s.run(6.0)
    first = s.run(5.0)
    chunks = []
    rest = first.arm_after.simulate(first.x[-1], s.dt, 1000, s.controller,
                                    on_rows=lambda t, x, u: chunks.append(x.copy()))
    streamed = np.concatenate(chunks)
    assert streamed.tobytes() == whole.x[5000:].tobytes()
    assert rest.x[-1].tobytes() == whole.x[-1].tobytes()
