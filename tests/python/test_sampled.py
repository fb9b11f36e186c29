"""Controllers at their own rate (issue 26 phase 2): orbitflex.Sampled(controller, rate_hz, delay)
with zero-order hold and whole-sample delays, checked bit for bit against hand-held tables and
hand-written sampled callables."""

import contextlib
import warnings
from typing import Iterator

import numpy as np
import pytest

import orbitflex as of

ROBOT = of.models.space_arm()
JOINTS = of.models.space_arm_joints()
FREE = of.FlexibleArm(ROBOT, JOINTS)
ARM = of.FlexibleArm(ROBOT, JOINTS, wheels=of.models.pyramid_wheels())
DT, STEPS = 1e-3, 400


def held(table, every, delay=0):
    """Row k of the run: the row sampled at the last multiple of `every` at or before k,
    `delay` samples back (zeros before the first arrives)."""
    out = np.zeros_like(table)
    for k in range(len(table)):
        j = k // every - delay
        if j >= 0:
            out[k] = table[j * every]
    return out


@pytest.mark.parametrize("delay", [0, 1, 3])
def test_a_table_at_100_hz_is_the_hand_held_table(delay):
    rng = np.random.default_rng(delay)
    table = rng.normal(size=(STEPS, 7)) * 5.0
    sampled = FREE.simulate(FREE.state(), DT, STEPS, u=of.Sampled(table, 100.0, delay=delay))
    by_hand = FREE.simulate(FREE.state(), DT, STEPS, u=held(table, 10, delay))
    assert np.array_equal(sampled.x, by_hand.x) and np.array_equal(sampled.u, by_hand.u)
    if delay:
        assert np.all(sampled.u[: 10 * delay] == 0.0)


@contextlib.contextmanager
def warning_if(expected: bool, match: str) -> Iterator[None]:
    """Expects one RuntimeWarning matching `match` when `expected`, else none at all."""
    if expected:
        with pytest.warns(RuntimeWarning, match=match):
            yield
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            yield


@pytest.mark.parametrize("rate_hz, every, delay", [(50.0, 20, 0), (50.0, 20, 2), (1000.0, 1, 0)])
def test_attitude_pd_at_its_rate_is_the_hand_written_sampled_loop(rate_hz, every, delay):
    att = of.AttitudePD(*of.models.PYRAMID_GAINS, attitude=[0, 0, 0, 1.0])
    u = np.tile(np.linspace(-20.0, 20.0, 7), (STEPS, 1))
    rows = []

    def by_hand(t, x):
        k = int(round(t / DT))
        if k % every == 0:
            rows.append(att.command(ARM, x))
        j = len(rows) - 1 - delay
        return rows[j] if j >= 0 else np.zeros(4)

    # the pyramid's gains at 50 Hz are stable without delay and unstable two samples late
    # (spectral radius above 1: docs/bus_control.md), and simulate says so before it starts
    with warning_if(delay == 2, "makes an unstable loop"):
        sampled = ARM.simulate(ARM.state(), DT, STEPS, u=u, wheel_torque=of.Sampled(att, rate_hz, delay=delay))
    hand = ARM.simulate(ARM.state(), DT, STEPS, u=u, wheel_torque=by_hand)
    assert np.array_equal(sampled.x, hand.x) and np.array_equal(sampled.wheel_torque, hand.wheel_torque)
    if every > 1:
        # the torque does change at the samples and only there
        changes = np.flatnonzero(np.any(np.diff(sampled.wheel_torque, axis=0) != 0, axis=1)) + 1
        assert len(changes) > 3 and np.all(changes % every == 0)
    if rate_hz == 1000.0:
        plain = ARM.simulate(ARM.state(), DT, STEPS, u=u, wheel_torque=att)
        assert np.array_equal(plain.x, sampled.x)


def test_motor_pd_at_its_rate_and_a_callable_called_only_at_the_samples():
    ref = np.tile(np.linspace(0.0, 0.2, 7), (STEPS, 1))
    pd = of.MotorPD(50.0, 10.0, ref)
    fast = FREE.simulate(FREE.state(), DT, STEPS, u=pd)
    # these gains sampled at 25 Hz are (mildly) unstable on the light wrist motors
    with warning_if(True, "makes an unstable loop"):
        slow = FREE.simulate(FREE.state(), DT, STEPS, u=of.Sampled(pd, 25.0))
    assert not np.array_equal(fast.u, slow.u)
    np.testing.assert_array_equal(slow.u, held(slow.u, 40))  # held over 40 steps
    times = []

    def acs(t, x):
        times.append(t)
        return np.zeros(6)

    # 30 Hz on 1 ms steps: not a whole number of steps; sample j at the first step at or after j/30
    FREE.simulate(FREE.state(), DT, 101, base_wrench=of.Sampled(acs, 30.0))
    steps = [int(round(t / DT)) for t in times]
    assert steps == [0, 34, 67, 100]


def test_bad_rates_and_wrapped_errors_are_named():
    with pytest.raises(ValueError, match="rate_hz: expected a finite rate > 0"):
        of.Sampled(of.MotorPD(1.0, 1.0, np.zeros(7)), 0.0)
    with pytest.raises(ValueError, match="rate_hz"):
        of.Sampled(np.zeros(7), float("nan"))
    with pytest.raises(OverflowError):
        of.Sampled(np.zeros(7), 10.0, delay=-1)
    with pytest.raises(ValueError, match=r"u: .*\(400, 7\)"):
        FREE.simulate(FREE.state(), DT, STEPS, u=of.Sampled(np.zeros((3, 7)), 10.0))
    s = of.Sampled(of.AttitudePD(1.0, 2.0), 10.0, delay=2)
    assert (s.rate_hz, s.delay) == (10.0, 2) and "Sampled(rate_hz=10, delay=2)" == repr(s)
    import pickle

    back = pickle.loads(pickle.dumps(of.Sampled(np.ones(7), 10.0, 1)))
    assert back.delay == 1 and np.array_equal(back.controller, np.ones(7))
