"""``simulate_batch`` with the bus under control: ``wheel_torque=AttitudePD`` (one shared, or one
per run) and ``Sampled`` controllers on ``u`` and ``wheel_torque``. Each run equals
``arm.simulate`` with the same controllers bit for bit, for any thread count; each run starts
from its own copy (the attitude latched at step 0, the rows held between samples); bad
combinations are refused before any step, naming the channel."""

from __future__ import annotations

import numpy as np
import pytest

import orbitflex
from orbitflex import AttitudePD, ModelError, MotorPD, Sampled

DT = 2e-3
STEPS = 60
B = 3


def pyramid(tilt_error=0.0):
    """Four wheels in a pyramid, 54.7° from the base z axis; ``tilt_error`` (rad) tips every
    axis further from z (a mounting misalignment)."""
    phi = np.pi / 2 * np.arange(4) + 0.3
    tilt = np.arccos(np.sqrt(1 / 3)) + tilt_error
    axes = np.column_stack([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), np.full(4, np.cos(tilt))])
    positions = np.column_stack([0.3 * np.cos(phi), 0.3 * np.sin(phi), np.full(4, -0.4)])
    return orbitflex.ReactionWheels(axes, positions, 4.0, 0.04, 0.025, 0.2, 600.0)


def wheeled_arm(tilt_error=0.0):
    return orbitflex.FlexibleArm(orbitflex.Robot.space_arm(), orbitflex.FlexibleJoints.space_arm(),
                                 wheels=pyramid(tilt_error))


@pytest.fixture(scope="module")
def arm():
    return wheeled_arm()


@pytest.fixture(scope="module")
def x0s(arm):
    """Starts with the bus turning and the links moving, a different one per run."""
    rng = np.random.default_rng(5)
    return np.stack([
        arm.state(q=rng.uniform(-1, 1, 7), qd=rng.uniform(-0.2, 0.2, 7),
                  base_twist=np.r_[rng.uniform(-0.05, 0.05, 3), 0, 0, 0],
                  wheel_speed=rng.uniform(-100, 100, 4))
        for _ in range(B)])


def motor_pds():
    return [MotorPD(20.0 + 5 * b, 2.0 + b, 0.1 * b * np.ones(7)) for b in range(B)]


def attitude_pds():
    return [AttitudePD([0.5 + 0.1 * b, 0.6, 0.7], [1.5, 1.5 + 0.2 * b, 1.0]) for b in range(B)]


def assert_run_is(batch, b, single):
    np.testing.assert_array_equal(batch.x[b], single.x)
    np.testing.assert_array_equal(batch.u[b], single.u)
    np.testing.assert_array_equal(batch.wheel_torque[b], single.wheel_torque)
    np.testing.assert_array_equal(batch.run(b).x, single.x)


def one_per_run(controller, b):
    """Run ``b``'s controller from a batch argument: one shared, a list, or a Sampled of those."""
    if isinstance(controller, Sampled):
        return Sampled(one_per_run(controller.controller, b), controller.rate_hz, controller.delay)
    if isinstance(controller, np.ndarray) and controller.ndim == 3:
        return controller[b]
    return controller[b] if isinstance(controller, list) else controller


CASES = {
    "shared AttitudePD": (None, AttitudePD(0.6, 1.4)),
    "AttitudePD per run": (None, attitude_pds()),
    "both sampled, whole and odd periods, delays": (
        Sampled(motor_pds(), 1 / (3 * DT), 1), Sampled(attitude_pds(), 170.0, 2)),
    "MotorPD per run, AttitudePD at 50 Hz": (motor_pds(), Sampled(AttitudePD(0.6, 1.4), 50.0)),
    "sampled table": (Sampled(np.ones((B, STEPS, 7)) * np.arange(B)[:, None, None], 100.0), None),
}


@pytest.mark.parametrize("case", list(CASES))
def test_each_run_is_the_single_run_with_the_same_controllers(arm, x0s, case):
    u, wheel_torque = CASES[case]
    batches = [orbitflex.simulate_batch(arm, x0s, DT, STEPS, u=u, wheel_torque=wheel_torque, threads=t)
               for t in (1, 2, 3)]
    for other in batches[1:]:
        np.testing.assert_array_equal(other.x, batches[0].x)
        np.testing.assert_array_equal(other.wheel_torque, batches[0].wheel_torque)
    for b in range(B):
        single = arm.simulate(x0s[b], DT, STEPS, u=None if u is None else one_per_run(u, b),
                              wheel_torque=None if wheel_torque is None else one_per_run(wheel_torque, b))
        assert_run_is(batches[0], b, single)
    if wheel_torque is not None:
        # the wheels held the bus: they were driven
        assert np.abs(batches[0].wheel_torque).max() > 1e-3


def test_a_shared_attitude_pd_is_bound_to_each_runs_wheels(x0s):
    """With an arm per run (here each with its wheels tipped differently) a shared AttitudePD
    allocates over each run's own axes, as ``arm.simulate`` does for that arm; an explicit
    allocation (the nominal axes', as flight software knows them) is used as given."""
    arms = [wheeled_arm(e) for e in (0.0, 0.02, -0.03)]
    nominal = AttitudePD(0.6, 1.4, allocation=np.linalg.pinv(np.asarray(pyramid().axes).T))
    for pd in (AttitudePD(0.6, 1.4), nominal):
        batch = orbitflex.simulate_batch(arms, x0s, DT, STEPS, wheel_torque=pd, threads=2)
        for b, arm in enumerate(arms):
            assert_run_is(batch, b, arm.simulate(x0s[b], DT, STEPS, wheel_torque=pd))
    # the runs differ: the allocation followed the axes
    assert not np.array_equal(batch.wheel_torque[0], batch.wheel_torque[1])


def test_the_attitude_target_is_latched_per_run(arm, x0s):
    """``AttitudePD`` without a target holds each run's own initial attitude: runs that start
    at different attitudes, both holding still, get no torque at all."""
    x0 = np.array([arm.state(base_pose=[0, 0, 0, *q]) for q in ([0, 0, 0, 1], [0, np.sin(0.3), 0, np.cos(0.3)])])
    batch = orbitflex.simulate_batch(arm, x0, DT, 10, wheel_torque=AttitudePD(1.0, 1.0))
    assert np.abs(batch.wheel_torque).max() == 0.0


@pytest.mark.parametrize("kwargs, message", [
    (dict(u=AttitudePD(1.0, 1.0)), "u: an AttitudePD drives the reaction wheels (wheel_torque); give torques"),
    (dict(wheel_torque=MotorPD(1.0, 1.0, np.zeros(7))), "wheel_torque: a MotorPD drives the motors (u)"),
    (dict(wheel_torque=[MotorPD(1.0, 1.0, np.zeros(7))] * B), "wheel_torque: a MotorPD drives the motors (u)"),
    (dict(wheel_torque=[AttitudePD(1.0, 1.0)] * 2), "runs: x0s gives 3 runs but wheel_torque gives 2"),
    (dict(wheel_torque=[AttitudePD(1.0, 1.0), 3, 4]), "wheel_torque[1]: expected an AttitudePD (wheel_torque[0] is one), given int"),
    (dict(wheel_torque=[Sampled(AttitudePD(1.0, 1.0), 10.0)] * B), "wheel_torque: a sequence of Sampled; give one Sampled around"),
    (dict(u=Sampled(Sampled(np.zeros(7), 10.0), 10.0)), "u: a Sampled inside a Sampled"),
    (dict(wheel_torque=Sampled(lambda t, x: np.zeros(4), 10.0)), "wheel_torque: simulate_batch runs without the GIL, so it cannot call a Python controller; give wheel torques"),
    (dict(wheel_torque=AttitudePD(1.0, 1.0, allocation=np.eye(3))), "allocation: expected shape (4, 3)"),
])
def test_bad_controllers_are_refused_before_any_step(arm, x0s, kwargs, message):
    with pytest.raises(ModelError) as e:
        orbitflex.simulate_batch(arm, x0s, DT, STEPS, **kwargs)
    assert message in str(e.value)


def test_an_attitude_pd_on_arms_without_wheels_is_refused(x0s):
    bare = orbitflex.FlexibleArm(orbitflex.Robot.space_arm(), orbitflex.FlexibleJoints.space_arm())
    with pytest.raises(ModelError, match="wheel_torque: the arms have no reaction wheels; give none"):
        orbitflex.simulate_batch(bare, bare.state(), DT, STEPS, wheel_torque=Sampled(AttitudePD(1.0, 1.0), 10.0))
