"""Planning with reaction wheels (issue 26 phase 2): plans on a wheeled arm, what holding the bus
through a held-base plan asks of the wheels (Plan.wheel_demand), and a held-base plan tracked with
the wheels under AttitudePD instead of the open-loop wrench."""

import numpy as np
import pytest

import orbitflex as of
from orbitflex.cli.slew import SPACE_ARM_SLEW

ROBOT = of.models.space_arm()
JOINTS = of.models.space_arm_joints()
FREE = of.FlexibleArm(ROBOT, JOINTS)
WHEELS = of.models.pyramid_wheels()
ARM = of.FlexibleArm(ROBOT, JOINTS, wheels=WHEELS)
LIMITS = of.Limits.from_urdf(ROBOT)


@pytest.fixture(scope="module")
def held():
    return of.plan_slew(ARM, SPACE_ARM_SLEW, limits=LIMITS, base="held")


def test_a_held_plan_does_not_see_the_wheels(held):
    """A held bus does not turn: the wheels' mass on it and their spin change nothing."""
    plain = of.plan_slew(FREE, SPACE_ARM_SLEW, limits=LIMITS, base="held")
    assert held.duration == plain.duration
    assert np.array_equal(held.base_wrench, plain.base_wrench) and np.array_equal(held.u, plain.u)
    assert len(held.initial_state()) == len(ARM.state())


def test_a_free_plan_on_a_wheeled_arm_is_exact():
    """Unpowered frictionless wheels at rest keep a·ω + Ω = 0: the bus carries only their locked
    parts, which the plan models; tracking it on the full model follows its bus attitude."""
    plan = of.plan_slew(ARM, SPACE_ARM_SLEW, limits=LIMITS, base="free")
    plain = of.plan_slew(FREE, SPACE_ARM_SLEW, limits=LIMITS, base="free")
    assert not np.array_equal(plan.base_pose, plain.base_pose)  # the wheels' mass moves the bus less
    run = plan.track(1e-3, 1000.0, 100.0)
    assert run["base_attitude_error"] < 1e-6
    # with the plain plan's bus path, the wheeled arm misses by the wheels' inertia
    q = plain.base_pose[-1, 3:]
    assert of.rotation_angle(plan.base_pose[-1, 3:], q) > 1e-3
    with pytest.raises(ValueError, match="friction"):
        rubbing = of.models.pyramid_wheels(friction=0.01)
        of.plan_slew(of.FlexibleArm(ROBOT, JOINTS, wheels=rubbing), SPACE_ARM_SLEW, limits=LIMITS, base="free")


def test_wheel_demand_is_the_holding_moment_allocated_and_integrated(held):
    d = held.wheel_demand(WHEELS)
    axes = np.asarray(WHEELS.axes)
    moment = held.base_wrench[:, :3]
    # the wheels push −Σ u_w a_w on the bus: the plan's holding moment (frictionless wheels)
    np.testing.assert_allclose(-d["torque"] @ axes, moment, rtol=1e-12, atol=1e-12 * np.abs(moment).max())
    # h = −∫ M dt (trapezoid over the plan's samples), and h = Σ J_s Ω a
    t = d["t"]
    h = -np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * np.diff(t)[:, None] * (moment[1:] + moment[:-1]), axis=0)])
    scale = np.abs(h).max()
    np.testing.assert_allclose(d["momentum"], h, atol=1e-10 * scale)
    np.testing.assert_allclose(d["momentum"], (d["speed"] * WHEELS.spin_inertia) @ axes, atol=1e-12 * scale)
    # the arm ends at rest: the momentum goes back out of the wheels
    assert np.abs(d["momentum"][-1]).max() < 1e-6 * scale
    assert d["peak_momentum"] == pytest.approx(np.linalg.norm(d["momentum"], axis=1).max(), rel=1e-15)
    b = d["binding"]
    ratios = {"max_torque": d["peak_torque"] / WHEELS.max_torque, "max_speed": d["peak_speed"] / WHEELS.max_speed}
    assert b["ratio"] == pytest.approx(max(r.max() for r in ratios.values()), rel=1e-15)
    assert b["ratio"] == pytest.approx(ratios[b["limit"]][b["wheel"]], rel=1e-15)
    # small wheels cannot hold it: the speed binds, past its bound
    small = of.models.pyramid_wheels(spin_inertia=0.01, transverse_inertia=0.006, max_speed=600.0)
    b = held.wheel_demand(small)["binding"]
    assert b["limit"] == "max_speed" and b["ratio"] > 1.0


def test_wheel_demand_refuses_a_free_plan_and_flat_axes():
    plan = of.plan_slew(FREE, SPACE_ARM_SLEW, limits=LIMITS, base="free")
    with pytest.raises(ValueError, match="free-floating plan asks nothing of the wheels"):
        plan.wheel_demand(WHEELS)
    held = of.plan_slew(FREE, SPACE_ARM_SLEW * 0.1, limits=LIMITS, base="held")
    flat = of.ReactionWheels([[1, 0, 0], [0, 1, 0]], np.zeros((2, 3)), 1.0, 0.1, 0.1, 1.0, 100.0)
    with pytest.raises(ValueError, match=r"\(1, 0, 0\), \(0, 1, 0\) all lie in one plane"):
        held.wheel_demand(flat)


def test_a_held_plan_tracked_with_the_wheels(held):
    wheels_run = held.track(1e-3, 1000.0, 100.0, wheel_torque=of.AttitudePD(*of.models.PYRAMID_GAINS))
    traj = wheels_run["trajectory"]
    assert wheels_run["base_attitude_error"] < 1e-3  # the bus keeps its pointing
    assert wheels_run["base_position_error"] > 1e-2  # it is not held in translation: it drifts
    assert np.abs(traj.wheel_torque).max() <= WHEELS.max_torque[0]
    demand = held.wheel_demand(WHEELS)
    # the momentum moved into the wheels mid-slew, as the demand says to within the bus's drift
    peak = np.abs(traj.wheel_speed).max()
    assert 0.5 * demand["peak_speed"].max() < peak < 1.5 * demand["peak_speed"].max()
    with pytest.raises(ValueError, match="the arm has no reaction wheels"):
        of.plan_slew(FREE, SPACE_ARM_SLEW * 0.1, limits=LIMITS, base="held").track(
            1e-3, 1000.0, 100.0, wheel_torque=of.AttitudePD(1.0, 1.0))
