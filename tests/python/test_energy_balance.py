"""``Trajectory.energy_steps`` and ``Trajectory.energy_balance`` (Rust): the power balance of a run,
against the trapezoid-rule formula written out in numpy."""

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, MotorPD


@pytest.fixture(scope="module")
def run():
    arm = FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    theta, theta_dot = orbitflex.quintic_reference(np.zeros(7), np.full(7, 0.3), 0.5, 1e-3, 600)
    pd = MotorPD(np.full(7, 200.0), np.full(7, 20.0), theta, theta_dot)
    return arm, arm.simulate(arm.state(), 1e-3, 600, u=pd)


def test_steps_are_the_trapezoid_rule_on_the_power(run):
    arm, traj = run
    _, _, d, beta = arm.parameters
    td, qd, u = traj.theta_dot, traj.qd, traj.u
    h = np.diff(traj.t)
    dissipation = ((td - qd) ** 2 * d).sum(axis=1) + (td**2 * beta).sum(axis=1)
    motor = 0.5 * ((u * td[:-1]).sum(axis=1) + (u * td[1:]).sum(axis=1))
    steps = traj.energy_steps()
    assert steps.shape == (600, 3)
    np.testing.assert_array_equal(steps[:, 0], np.diff(traj.energy))
    # the same sums of 7 products in another order: a few roundings of the largest term
    scale = np.abs(u * td[:-1]).sum(axis=1) + np.abs(u * td[1:]).sum(axis=1)
    assert np.all(np.abs(steps[:, 1] - h * motor) <= 16 * np.finfo(float).eps * h * scale)
    np.testing.assert_allclose(steps[:, 2], 0.5 * h * (dissipation[:-1] + dissipation[1:]), rtol=1e-14)


def test_balance_closes_to_the_quadrature(run):
    arm, traj = run
    change, work, dissipated = traj.energy_balance()
    steps = traj.energy_steps()
    assert change == traj.energy[-1] - traj.energy[0]
    assert work == pytest.approx(steps[:, 1].sum(), rel=1e-13)
    assert dissipated == pytest.approx(steps[:, 2].sum(), rel=1e-13)
    assert work > 0 and dissipated > 0
    # O(dt²) quadrature error: a small share of the energy that flowed
    assert abs(change - (work - dissipated)) < 1e-4 * (work + dissipated)
