"""The quintic reference from Rust (``orbitflex.quintic_reference``): what the command line and
campaigns tabulate for their motor PD, against the closed form and the former numpy evaluation."""

import numpy as np
import pytest

import orbitflex
from orbitflex._reference import quintic


def numpy_quintic(s):
    """The former evaluation (numpy, powers), the one the command line used before Rust."""
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4


def test_profile_agrees_with_the_power_form_within_its_rounding():
    # Both are sums of three terms bounded by 10 + 15 + 6 = 31 (p) and 30 + 60 + 30 = 120
    # (dp/ds); each term carries at most ~5 roundings (a power, up to 4 ulp on SIMD paths, a
    # product, two sums), so either evaluation is within 31·8·eps (p) and 120·8·eps (dp) of the
    # exact value, and the two within twice that.
    s = np.linspace(-0.1, 1.1, 10_001)
    p, dp = quintic(s)
    p_np, dp_np = numpy_quintic(s)
    eps = np.finfo(float).eps
    assert np.max(np.abs(p - p_np)) <= 2 * 31 * 8 * eps
    assert np.max(np.abs(dp - dp_np)) <= 2 * 120 * 8 * eps
    assert quintic(np.array([[0.0, 0.5], [1.0, 2.0]]))[0].tolist() == [[0.0, 0.5], [1.0, 1.0]]


def test_reference_tabulates_the_slew_row_by_row():
    start, goal, duration, dt, steps = np.array([0.2, -0.4, 1.0]), np.array([1.0, 0.6, 1.0]), 0.5, 0.01, 80
    theta, theta_dot = orbitflex.quintic_reference(start, goal, duration, dt, steps)
    assert theta.shape == theta_dot.shape == (steps, 3)
    t = np.arange(steps) * dt
    p, dp = quintic(t / duration)
    np.testing.assert_array_equal(theta, start + np.outer(p, goal - start))
    np.testing.assert_array_equal(theta_dot, np.outer(dp / duration, goal - start))
    # rest to rest: starts at start, ends held at goal, and the unmoved joint never moves
    np.testing.assert_array_equal(theta[0], start)
    np.testing.assert_array_equal(theta[-1], goal)
    assert not theta_dot[0].any() and not theta_dot[-1].any()
    assert (theta[:, 2] == 1.0).all()
    # the rate integrates to the travel over rows 0..50 (t = 0..T): the trapezoid rule's error
    # is at most T·dt²/12·max|θ⃛| = T·dt²/12·(60/T³)·|Δ| = 2e-3·|Δ| (|p⃛(s)| ≤ 60 on [0, 1])
    rows = theta_dot[:51]
    travel = dt * (rows.sum(axis=0) - 0.5 * (rows[0] + rows[-1]))
    np.testing.assert_allclose(travel, goal - start, rtol=0, atol=2e-3)


@pytest.mark.parametrize("args, message", [
    (([0.0, 0.0], [1.0], 1.0, 1e-3, 3), "goal: expected length 2, given length 1"),
    (([0.0], [1.0], 0.0, 1e-3, 3), "duration: expected a finite duration > 0 s, given 0"),
    (([0.0], [1.0], 1.0, -1e-3, 3), "dt: expected a finite step > 0 s"),
    (([np.nan], [1.0], 1.0, 1e-3, 3), "start"),
    (([0.0], [1.0], 1.0, 1e-3, -2), "steps"),
])
def test_bad_references_are_model_errors(args, message):
    with pytest.raises(orbitflex.ModelError, match=message.replace("(", r"\(")):
        orbitflex.quintic_reference(*args)
