"""Capture in a run from Python (issue 29 phase 2): ``simulate(..., target=, capture=)``, the
events and target rows of the ``Trajectory``, the built-in scenario, batches with targets equal
single runs, bad input."""

import pickle

import numpy as np
import pytest

import orbitflex as of


@pytest.fixture(scope="module")
def scenario():
    return of.models.capture_scenario()


@pytest.fixture(scope="module")
def run(scenario):
    # 7 s: the capture at about 4.5 s and 2.5 s after it
    return scenario.run(7.0, record_every=5)


def test_the_scenario_captures_once_with_momentum_kept(scenario, run):
    assert len(run.events) == 1
    e = run.events[0]
    # the handle reaches the EE at meet = 5 s drifting at 2 cm/s: within 1 cm 0.5 s before
    assert abs(e.time - (scenario.meet - 0.01 / 0.02)) < 0.02
    assert e.distance <= scenario.when.distance
    assert e.speed <= scenario.when.speed and e.angle <= scenario.when.angle
    assert e.step == round(e.time / scenario.dt)
    assert e.energy_loss > 0
    # momentum across the impulse, to 1e-12 of its size
    scale = np.abs(e.momentum_before).max()
    np.testing.assert_allclose(e.momentum_after, e.momentum_before, rtol=0, atol=1e-12 * scale)
    # the motors keep their rates
    n = scenario.arm.dof
    np.testing.assert_array_equal(e.x_after[-n:], e.x_before[-n:])
    # the record: the target's rows beside the arm's, the combined arm after
    assert run.target.shape == (len(run), 13)
    assert run.arm_after is not None and run.arm_after.dof == n
    # the row kept at the event (a multiple of record_every here, or not) is the state before
    rows = np.flatnonzero(np.isclose(run.t, e.time, rtol=0, atol=1e-12))
    if rows.size:
        np.testing.assert_array_equal(run.x[rows[0]], e.x_before)
        np.testing.assert_array_equal(run.target[rows[0]], e.target_before)


def test_total_momentum_along_the_run_includes_the_target(scenario, run):
    h = run.momentum
    e = run.events[0]
    before = run.t <= e.time
    # before the capture: the arm alone has none (it starts at rest, the PD is internal); the
    # total is the target's
    assert np.abs(h[0]).max() > 1.0
    # RK4 keeps the momentum of this run to far better than 1e-6 of its size
    scale = np.abs(h[0]).max()
    assert np.abs(h - h[0]).max() < 1e-6 * scale
    assert before.any() and (~before).any()


def test_no_capture_when_the_target_drifts_away(scenario):
    away = of.models.capture_scenario(drift=-0.02)
    traj = away.run(1.0)
    assert traj.events == []
    assert traj.arm_after is None
    plain = away.arm.simulate(away.x0, away.dt, 1000, away.controller)
    np.testing.assert_array_equal(traj.x, plain.x)
    # the free target moves away along the approach axis at 2 cm/s
    moved = np.linalg.norm(traj.target[-1, :3] - traj.target[0, :3])
    assert abs(moved - 0.02) < 1e-9


def test_a_plain_run_has_no_events(scenario):
    traj = scenario.arm.simulate(scenario.x0, scenario.dt, 3, scenario.controller)
    assert traj.events == [] and traj.target is None and traj.arm_after is None


@pytest.mark.parametrize(
    "args, what",
    [((0.0, 0.1, 0.1), "CaptureWhen.distance"), ((0.1, -1.0, 0.1), "CaptureWhen.speed"),
     ((0.1, 0.1, float("nan")), "CaptureWhen.angle")],
)
def test_tolerances_must_be_positive(args, what):
    with pytest.raises(of.ModelError, match=what) as info:
        of.CaptureWhen(*args)
    assert "expected a finite tolerance > 0" in str(info.value)


def test_target_and_capture_come_together(scenario):
    s = scenario
    with pytest.raises(of.ModelError, match="capture: a run with a target needs"):
        s.arm.simulate(s.x0, s.dt, 3, s.controller, target=s.target)
    with pytest.raises(of.ModelError, match="target: a run with a target needs"):
        s.arm.simulate(s.x0, s.dt, 3, s.controller, capture=s.when)
    with pytest.raises(of.ModelError, match="target: expected an orbitflex.Target"):
        s.arm.simulate(s.x0, s.dt, 3, s.controller, target=1.0, capture=s.when)
    with pytest.raises(of.ModelError, match="on_rows"):
        s.arm.simulate(s.x0, s.dt, 3, s.controller, target=s.target, capture=s.when,
                       on_rows=lambda t, x, u: None)


def test_values_pickle(scenario):
    when = pickle.loads(pickle.dumps(scenario.when))
    assert (when.distance, when.speed, when.angle) == (
        scenario.when.distance, scenario.when.speed, scenario.when.angle)
    target = pickle.loads(pickle.dumps(scenario.target))
    np.testing.assert_array_equal(target.state, scenario.target.state)


def test_a_batch_with_targets_equals_single_runs():
    scenarios = [of.models.capture_scenario(rate, 0.02, 0.6) for rate in (1.0, 2.0, 3.5)]
    s0 = scenarios[0]
    batch = of.simulate_capture_batch(
        [s.arm for s in scenarios], np.array([s.x0 for s in scenarios]), s0.dt, 1000,
        [s.controller for s in scenarios], [s.target for s in scenarios], s0.when,
        record_every=3, threads=2)
    assert len(batch) == 3
    for s, traj in zip(scenarios, batch):
        single = s.arm.simulate(s.x0, s.dt, 1000, s.controller, target=s.target,
                                capture=s.when, record_every=3)
        np.testing.assert_array_equal(traj.x, single.x)
        np.testing.assert_array_equal(traj.target, single.target)
        assert [e.step for e in traj.events] == [e.step for e in single.events] != []
