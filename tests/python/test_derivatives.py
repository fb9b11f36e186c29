"""Derivatives of the dynamics (issue: analytical derivatives): the rigid ones against Pinocchio's
``computeRNEADerivatives`` and ``computeABADerivatives`` after the convention map (1e-9), the
flexible arm's step Jacobians composed over several steps against finite differences of a
simulation, the tangent space, and the generalized Jacobian."""

from __future__ import annotations

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, FlexibleJoints, ModelError
from pin_helpers import aba_derivatives, rel_err, rnea_derivatives
from test_pinocchio import states

TOL = 1e-9


def test_rigid_derivatives_equal_pinocchio(loaded):
    case, robot, pin_robot = loaded
    for s in states(case, robot, count=2):
        mine = robot.inverse_dynamics_derivatives(
            s["q"], s["base_twist"], s["qd"], s["base_acc"], s["qdd"], ee_wrench=s["ee_wrench"]
        )
        theirs = rnea_derivatives(pin_robot, s["q"], s["base_twist"], s["qd"], s["base_acc"], s["qdd"],
                                  ee_wrench=s["ee_wrench"])
        for key in ("q", "v", "a"):
            err = rel_err(mine[key], theirs[key])
            assert err <= TOL, f"{case.name} ID d/d{key}: {err:.2e}"
        mine = robot.forward_dynamics_derivatives(
            s["q"], s["base_twist"], s["qd"], s["tau"], base_wrench=s["base_wrench"], ee_wrench=s["ee_wrench"]
        )
        theirs = aba_derivatives(pin_robot, s["q"], s["base_twist"], s["qd"], s["tau"],
                                 base_wrench=s["base_wrench"], ee_wrench=s["ee_wrench"])
        for key in ("q", "v", "tau", "base_wrench"):
            err = rel_err(mine[key], theirs[key])
            assert err <= TOL, f"{case.name} FD d/d{key}: {err:.2e}"
        assert mine["ee_wrench"].shape == (6 + robot.dof, 6)


@pytest.fixture(scope="module")
def arm():
    return FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())


def moving_state(arm, seed=1):
    rng = np.random.default_rng(seed)
    n = arm.dof
    q = rng.uniform(-1, 1, n)
    return arm.state(q=q, theta=q + rng.uniform(-0.01, 0.01, n), qd=rng.uniform(-0.3, 0.3, n),
                     theta_dot=rng.uniform(-0.3, 0.3, n),
                     base_pose=np.r_[rng.normal(size=3), rng.normal(size=4)],
                     base_twist=rng.uniform(-0.1, 0.1, 6))


def test_tangent_space(arm):
    x = moving_state(arm)
    assert arm.tangent_size == 12 + 4 * arm.dof
    rng = np.random.default_rng(2)
    for _ in range(10):
        dx = rng.uniform(-1, 1, arm.tangent_size)
        y = arm.integrate(x, dx)
        np.testing.assert_allclose(arm.difference(x, y), dx, atol=1e-12)
        np.testing.assert_allclose(arm.integrate(x, arm.difference(x, y)), y, atol=1e-14)
    # the rotation part turns the base about its own axes: δφ = (0, 0, π/2) is a quarter turn
    dx = np.zeros(arm.tangent_size)
    dx[5] = np.pi / 2
    turned = arm.integrate(arm.state(), dx)
    np.testing.assert_allclose(turned[3:7], [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)], atol=1e-15)
    with pytest.raises(ModelError, match="dx: expected length"):
        arm.integrate(x, np.zeros(arm.state_size))


def test_step_jacobians_compose_to_the_sensitivity_of_a_run(arm):
    # Composing k step Jacobians along a run equals finite differences of a k-step simulation.
    x0, dt, k = moving_state(arm, 3), 1e-3, 20
    u = np.full(arm.dof, 2.0)
    traj = arm.simulate(x0, dt, k, u=u)
    total = np.eye(arm.tangent_size)
    for i in range(k):
        total = arm.step_jacobians(traj.x[i], dt, u=u)["x"] @ total
    h = 1e-6
    fd = np.zeros_like(total)
    end = traj.x[-1]
    for c in range(arm.tangent_size):
        dx = np.zeros(arm.tangent_size)
        dx[c] = h
        plus = arm.simulate(arm.integrate(x0, dx), dt, k, u=u).x[-1]
        dx[c] = -h
        minus = arm.simulate(arm.integrate(x0, dx), dt, k, u=u).x[-1]
        fd[:, c] = (arm.difference(end, plus) - arm.difference(end, minus)) / (2 * h)
    assert rel_err(total, fd) < 1e-6


def test_linearize_is_the_derivative_jacobians(arm):
    x = moving_state(arm, 4)
    u = np.linspace(-1, 1, arm.dof)
    f, g = arm.linearize(x, u)
    full = arm.derivative_jacobians(x, u)
    np.testing.assert_array_equal(f, full["x"])
    np.testing.assert_array_equal(g, full["u"])
    # θ̈ = (u − τ − β θ̇)/j: G is 1/j on the motor-rate rows
    j = arm.parameters[1]
    rows = slice(12 + 3 * arm.dof, 12 + 4 * arm.dof)
    np.testing.assert_allclose(g[rows], np.diag(1 / j), rtol=1e-15)
    assert not g[: 12 + 3 * arm.dof].any()
    # one step is I + dt F + O(dt²): the remainder shrinks fourfold when dt halves
    def remainder(dt):
        return np.abs(arm.step_jacobians(x, dt, u)["x"] - np.eye(len(f)) - dt * f).max()

    assert remainder(1e-5) < (1e-5 * np.abs(f).max()) ** 2
    assert 3.5 < remainder(2e-5) / remainder(1e-5) < 4.5


def test_generalized_jacobian_keeps_the_momentum_zero():
    robot = orbitflex.models.space_arm()
    q = np.linspace(-0.5, 0.5, robot.dof)
    qd = np.linspace(0.3, -0.2, robot.dof)
    m = robot.mass_matrix(q)
    base = -np.linalg.solve(m[:6, :6], m[:6, 6:] @ qd)
    np.testing.assert_allclose(robot.momentum([0, 0, 0, 0, 0, 0, 1], q, base, qd), 0, atol=1e-10)
    twist = robot.ee_base_operator(q) @ base + robot.ee_jacobian(q) @ qd
    np.testing.assert_allclose(robot.generalized_jacobian(q) @ qd, twist, rtol=1e-12, atol=1e-13)
