"""Trajectory generation from Python: ``FlexibleArm.inverse_dynamics``, ``Limits``,
``plan_slew`` and ``Plan``, and the ``orbitflex plan`` command.

Checked against the forward model (``arm.derivative`` gives back the motion the inverse dynamics
was asked for), against finite differences (the returned rates are the time derivatives), on an
independent fine time grid (every limit holds, the binding one is active), by simulation (the
plan is followed), and against the rigid-joint plan of the same slew. Robots: the built-in space
arm, a random chain (tests/python/urdf_gen.py) and the UR5 of example-robot-data.
"""

from __future__ import annotations

import json
import math
import pickle
import re
import subprocess
import sys
import textwrap
import threading
import time
import warnings
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, FlexibleJoints, Limits, ModelError, Plan, plan_slew
from orbitflex import cli
from conftest import erd_case
from urdf_gen import random_chain

# The test slew: the demo's goal on the built-in arm, free floating, under limits chosen so that
# a motor torque binds (the elbow's 30 N·m): 0.5 rad/s, more than the built-in URDF's 0.15–0.4
# rad/s, so every plan here would warn (LimitWarning). The planner's mechanics are tested where
# torque binds, and the URDF's own limits in their own tests below (`orbitflex demo` uses them).
GOAL = np.array([0.8, -0.6, 0.5, 1.0, -0.7, 0.6, 0.9])
MOTOR_TORQUE = np.array([60.0, 60.0, 60.0, 30.0, 15.0, 15.0, 15.0])
KP, KD, DT = 1000.0, 100.0, 1e-3
pytestmark = pytest.mark.filterwarnings("ignore::orbitflex.LimitWarning")


# ---------------------------------------------------------------------------------------------
# robots
# ---------------------------------------------------------------------------------------------


def spread_joints(n: int, seed: int, damping: float) -> FlexibleJoints:
    """k 200–800 N·m/rad, j 0.05–0.2 kg·m², β 0.1–0.5 N·m·s/rad, damping d (N·m·s/rad)."""
    rng = np.random.default_rng(seed)
    return FlexibleJoints(rng.uniform(200, 800, n), rng.uniform(0.05, 0.2, n), damping, rng.uniform(0.1, 0.5, n))


def load(name: str) -> orbitflex.Robot:
    if name == "space_arm":
        return orbitflex.models.space_arm()
    if name == "chain":
        chain = random_chain(5)
        return orbitflex.Robot.from_urdf_string(chain.xml, ee_link=chain.ee_link)
    case = erd_case(name)
    return orbitflex.Robot.from_urdf(case.path, ee_link=case.ee_link)


ROBOTS = ["space_arm", "chain", "ur5"]


@pytest.fixture(scope="module")
def space_arm() -> FlexibleArm:
    """The built-in arm with its joints (damped: d = 0.2 N·m·s/rad)."""
    return FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())


@pytest.fixture(scope="module")
def demo_plan(space_arm) -> Plan:
    return plan_slew(space_arm, GOAL, limits=Limits(MOTOR_TORQUE, 0.5), base="free")


@pytest.fixture(scope="module")
def demo_runs(demo_plan):
    """The demo plan and its rigid-joint plan, each tracked on the flexible arm."""
    rigid = demo_plan.rigid()
    return demo_plan.track(DT, KP, KD), rigid, rigid.track(DT, KP, KD)


def rel(got, want) -> float:
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    return float(np.abs(got - want).max() / max(np.abs(want).max(), 1e-300))


def random_motion(n: int, seed: int):
    rng = np.random.default_rng(seed)
    return [rng.uniform(-1, 1, n) / (1 + k) for k in range(5)]


def classical_from_derivative(arm: FlexibleArm, x, xdot) -> np.ndarray:
    """``[ω̇; v̇ + ω × v]`` from the state and its derivative."""
    s = arm.state_slices
    twist, rate = x[s["base_twist"]], xdot[s["base_twist"]]
    return np.r_[rate[:3], rate[3:] + np.cross(twist[:3], twist[3:])]


# ---------------------------------------------------------------------------------------------
# inverse dynamics: exact against the forward model
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("damping", [0.0, 0.7])
@pytest.mark.parametrize("name", ROBOTS)
def test_inverse_dynamics_is_exact_against_the_forward_model(name, damping):
    robot = load(name)
    n = robot.dof
    arm = FlexibleArm(robot, spread_joints(n, 3, damping))
    q, qd, qdd, qddd, qdddd = random_motion(n, 11)
    deflection = np.random.default_rng(12).uniform(-0.01, 0.01, n) if damping > 0 else None
    k, j, d, beta = arm.parameters
    pose = np.array([0.3, -0.2, 0.1, 0.1, 0.2, -0.3, 0.9])
    for base in ("held", "free"):
        out = arm.inverse_dynamics(q, qd, qdd, qddd, qdddd, base=base, deflection=deflection)
        assert set(out) == {"theta", "theta_dot", "theta_ddot", "u", "tau", "base_twist", "base_acc", "base_wrench"}
        x = arm.state(q=q, qd=qd, theta=out["theta"], theta_dot=out["theta_dot"], base_pose=pose,
                      base_twist=out["base_twist"])
        xdot = arm.derivative(x, u=out["u"], base_wrench=out["base_wrench"])
        s = arm.state_slices
        assert rel(xdot[s["qd"]], qdd) < 1e-9, (base, rel(xdot[s["qd"]], qdd))
        assert rel(xdot[s["theta_dot"]], out["theta_ddot"]) < 1e-9
        acc = classical_from_derivative(arm, x, xdot)
        # the joints: spring law, motor law, deflection
        delta, rate = out["theta"] - q, out["theta_dot"] - qd
        np.testing.assert_allclose(out["tau"], k * delta + d * rate, rtol=1e-9, atol=1e-9 * np.abs(out["tau"]).max())
        np.testing.assert_allclose(out["u"], j * out["theta_ddot"] + beta * out["theta_dot"] + out["tau"], rtol=1e-12,
                                   atol=1e-12 * np.abs(out["u"]).max())
        if deflection is None:
            np.testing.assert_allclose(delta, out["tau"] / k, rtol=1e-12, atol=1e-15)  # θ − q rounds
        else:
            np.testing.assert_allclose(delta, deflection, rtol=0, atol=1e-15)
        # the rigid bodies, against Robot.inverse_dynamics: [f_B; τ] for the base motion
        rigid = robot.inverse_dynamics(q, out["base_twist"], qd, out["base_acc"], qdd)
        if base == "held":
            assert np.all(out["base_twist"] == 0) and np.all(out["base_acc"] == 0)
            assert np.abs(acc).max() < 1e-9 * max(1.0, np.abs(out["base_wrench"]).max())
            assert rel(rigid[:6], out["base_wrench"]) < 1e-9 and np.abs(out["base_wrench"]).max() > 1e-3
        else:
            assert np.all(out["base_wrench"] == 0)
            assert rel(acc, out["base_acc"]) < 1e-9, rel(acc, out["base_acc"])
            assert np.abs(rigid[:6]).max() < 1e-9 * np.abs(rigid).max()
            # free floating from rest: zero total momentum
            assert np.abs(arm.momentum(x)).max() < 1e-10 * max(1.0, robot.total_mass)
        assert rel(rigid[6:], out["tau"]) < 1e-9


def polynomial(coeffs: np.ndarray, t: float):
    """``q(t)`` with coefficients (n, 7), lowest power first, and its first four derivatives."""
    out = []
    for k in range(5):
        powers = np.arange(k, coeffs.shape[1])
        falling = np.array([math.prod(range(p - k + 1, p + 1)) for p in powers], dtype=float)
        out.append(coeffs[:, k:] @ (falling * t ** (powers - k)))
    return out


def richardson(f, t: float, h: float):
    """``f'(t)`` by central differences with one Richardson step (error O(h⁴))."""
    wide = (f(t + h) - f(t - h)) / (2 * h)
    narrow = (f(t + h / 2) - f(t - h / 2)) / h
    return (4 * narrow - wide) / 3


@pytest.mark.parametrize("name", ["space_arm", "chain"])
def test_motor_rates_are_the_time_derivatives_along_a_polynomial_path(name):
    robot = load(name)
    n = robot.dof
    arm = FlexibleArm(robot, spread_joints(n, 1, 0.0))
    coeffs = np.random.default_rng(4).uniform(-1, 1, (n, 7))
    for base in ("held", "free"):
        def at(t, key):
            return arm.inverse_dynamics(*polynomial(coeffs, t), base=base)[key]

        t = 0.4
        now = arm.inverse_dynamics(*polynomial(coeffs, t), base=base)
        for angle, rate in (("theta", "theta_dot"), ("theta_dot", "theta_ddot")):
            fd = richardson(lambda s: at(s, angle), t, 1e-3)
            assert np.abs(fd - now[rate]).max() < 1e-6 * (1 + np.abs(now[rate]).max()), (base, angle)
        # the deflection is there: the check would pass with θ = q otherwise
        assert np.abs(now["theta"] - polynomial(coeffs, t)[0]).min() > 1e-6
        if base == "free":
            # base_acc is classical: V̇_B = α_B − [0; ω × v]
            twist = now["base_twist"]
            spatial = now["base_acc"] - np.r_[np.zeros(3), np.cross(twist[:3], twist[3:])]
            fd = richardson(lambda s: at(s, "base_twist"), t, 1e-3)
            assert np.abs(fd - spatial).max() < 1e-6, np.abs(fd - spatial).max()


SIGMA = (0, 0, 0, 0, 0, 126, -420, 540, -315, 70)


def exact_jets(goal, t: float, duration: float):
    """``q⁽ᵏ⁾(t) = goal σ⁽ᵏ⁾(t/T)/Tᵏ``, k = 0…4, for the documented path shape
    σ(s) = 126 s⁵ − 420 s⁶ + 540 s⁷ − 315 s⁸ + 70 s⁹: each element exact (rational arithmetic) and
    rounded once (``s = t/T`` is the correctly rounded quotient, as the plan forms it). Free of
    numpy's ``power``, whose last bits differ between processors (SVML on AVX-512), and of the
    monomial form's cancellation (126 − 420 + 540 − 315 + 70 = 1), which costs up to 1471 ulps
    in σ and 10⁶ in its fourth derivative near s = 1."""
    x, T = Fraction(t / duration), Fraction(duration)
    jets = []
    for k in range(5):
        falling = [math.prod(range(p - k + 1, p + 1)) for p in range(k, 10)]
        shape = sum(Fraction(c * f) * x ** (p - k) for p, c, f in zip(range(k, 10), SIGMA[k:], falling))
        jets.append(np.array([float(Fraction(g) * shape / T**k) for g in goal]))
    return jets


def test_a_plan_is_the_inverse_dynamics_of_the_documented_path(space_arm, demo_plan):
    # q(t) = q_start + (q_goal − q_start) σ(t/T): evaluate() agrees with inverse_dynamics on the
    # path's jets (damped joints: given the plan's deflection). The bounds follow from the
    # conditioning, so that the test holds on any processor, libm and numpy:
    # - The jets here are exact, rounded once. The plan forms σ⁽ᵏ⁾ in factored forms of
    #   u = s(1 − s) and v = 1 − 2s (≤ 12 roundings each) and scales them by Δ and wᵏ (≤ 4 more),
    #   so its q, q̇, q̈ are within 32 ε of them, element by element. (The monomial form it used
    #   before was 350 ulps off in q̇ at t = 4.4 s and 10⁶ ulps off near the end of the slew.)
    # - τ: both sides run the same jet recursion (the plan at unit duration, then times w²) on
    #   jets that agree to 32 ε: 2(n+1) = 16 spatial passes of a few roundings each, on terms of
    #   the size of ‖τ‖ along this slew. Measured ≤ 25 ε‖τ‖ over 44 instants with the jets moved
    #   by up to 4 ulps (the same with ORBITFLEX_PORTABLE=1); bound 1e3 ε‖τ‖.
    # - θ̇ = q̇ + δ̇ with δ̇ = (τ − kδ)/d and the same δ on both sides: Δθ̇ = Δq̇ + Δτ/d, plus the
    #   rounding of τ − kδ (kδ ≈ τ: the damper carries only d δ̇ ≪ τ) and of the division,
    #   2 ε‖τ‖/d per side, and that of the plan's closed-form δ̇ (deflection.rs), bounded by the
    #   same scale. 1/d = 5 rad/(N·m·s) is the physics: θ̇'s relative error is ‖τ‖/(d |θ̇|) (up to
    #   2700 here, at t = 0.3 s) times τ's, so a fixed relative bound on θ̇ holds or fails with
    #   the last bits of τ, which is how it failed on an AVX-512 machine (2.1e-10 against 1e-10).
    # - θ̈ = q̈ + (τ̇ − k δ̇)/d: Δθ̈ = Δτ̇/d − (k/d²) Δτ; k/d² ≤ 2.5e5 s⁻¹ amplifies Δτ, and Δτ̇
    #   (the recursion's next order: ≤ 1e3 ε ‖τ̇‖ as τ, with ‖τ̇‖ ≤ 1e3 N·m/s here) adds
    #   ≤ 1e3 ε · 1e3/d ≈ 1.1e-9 rad/s².
    # - u = j θ̈ + β θ̇ + τ: Δu = j Δθ̈ + β Δθ̇ + Δτ, and its own rounding, 3 ε |u|.
    T = demo_plan.duration
    joints = space_arm.joints
    k, d = np.asarray(joints.stiffness), np.asarray(joints.damping)
    j, beta = np.asarray(joints.motor_inertia), np.asarray(joints.motor_damping)
    eps = np.finfo(float).eps
    for t in (0.3, 1.7, 2.9, 4.4, 5.6):
        p = demo_plan.evaluate(t)
        jets = exact_jets(GOAL, t, T)
        for key, jet in zip(("q", "qd", "qdd"), jets):
            np.testing.assert_allclose(p[key], jet, rtol=32 * eps, atol=0, err_msg=f"{key} at t = {t}")
        # the plan's own deflection: θ − q would lose the digits below θ's rounding (~1e-16 rad),
        # which θ̇ = q̇ + (τ − k δ)/d amplifies by k/d = 5e4 and θ̈ by (k/d)² = 2.5e9. θ = fl(q + δ)
        # is within ε/2 |θ| of q + δ, and θ − q rounds by at most ε/2 |θ − q| more.
        gap = np.abs((p["theta"] - p["q"]) - p["deflection"])
        assert np.all(gap <= eps * (np.abs(p["theta"]) + np.abs(p["deflection"]))), gap
        out = space_arm.inverse_dynamics(*jets, base="free", deflection=p["deflection"])
        # well conditioned: relative errors of a few ε (measured ≤ 4e-15) against 1e-10
        for key in ("theta", "base_twist", "base_acc"):
            assert rel(p[key], out[key]) < 1e-10, (t, key, rel(p[key], out[key]))
        scale = np.abs(p["tau"]).max()
        dtau = np.abs(p["tau"] - out["tau"])
        assert np.all(dtau <= 1e3 * eps * scale), (t, dtau / (eps * scale))
        bound_rate = np.abs(p["qd"] - jets[1]) + (dtau + 8 * eps * scale) / d
        error_rate = np.abs(p["theta_dot"] - out["theta_dot"])
        assert np.all(error_rate <= bound_rate), (t, error_rate / bound_rate)
        bound_acc = k / d**2 * (dtau + 4 * eps * np.abs(p["tau"])) + 1e3 * eps * 1e3 / d
        error_acc = np.abs(p["theta_ddot"] - out["theta_ddot"])
        assert np.all(error_acc <= bound_acc), (t, error_acc / bound_acc)
        bound_u = j * bound_acc + beta * bound_rate + dtau + 3 * eps * np.abs(p["u"])
        assert np.all(np.abs(p["u"] - out["u"]) <= bound_u), (t, np.abs(p["u"] - out["u"]) / bound_u)
        assert p["t"] == t and np.all(p["base_wrench"] == 0)


@pytest.mark.parametrize("base", ["held", "free"])
def test_motor_rates_are_the_time_derivatives_along_a_plan(space_arm, base):
    # damped joints: the deflection is integrated along the plan
    plan = plan_slew(space_arm, GOAL, q_start=-0.5 * GOAL, limits=Limits(MOTOR_TORQUE, 0.5), base=base)
    for t in np.linspace(0.05, 0.95, 7) * plan.duration:
        now = plan.evaluate(t)
        for angle, rate in (("q", "qd"), ("qd", "qdd"), ("theta", "theta_dot"), ("theta_dot", "theta_ddot")):
            fd = richardson(lambda s: plan.evaluate(s)[angle], t, 1e-3)
            assert np.abs(fd - now[rate]).max() < 1e-6 * (1 + np.abs(now[rate]).max()), (t, angle)
        if base == "free":
            twist = now["base_twist"]
            spatial = now["base_acc"] - np.r_[np.zeros(3), np.cross(twist[:3], twist[3:])]
            fd = richardson(lambda s: plan.evaluate(s)["base_twist"], t, 1e-3)
            assert np.abs(fd - spatial).max() < 1e-6


def test_the_sample_arrays_are_the_plan_at_the_sample_times(demo_plan):
    plan = demo_plan
    k = len(plan.t)
    assert plan.t[0] == 0 and plan.t[-1] == pytest.approx(plan.duration, rel=1e-15) and np.all(np.diff(plan.t) > 0)
    shapes = {"q": 7, "qd": 7, "qdd": 7, "theta": 7, "theta_dot": 7, "u": 7, "tau": 7, "base_wrench": 6,
              "base_twist": 6, "base_pose": 7}
    for name, width in shapes.items():
        array = getattr(plan, name)
        assert array.shape == (k, width) and not array.flags.writeable, name
    for row in (0, 100, k // 2, k - 1):
        p = plan.evaluate(plan.t[row])
        for name in ("q", "qd", "qdd", "theta", "theta_dot", "u", "tau", "base_twist"):
            assert rel(getattr(plan, name)[row], p[name]) < 1e-9, (row, name)
    # the base pose integrates the twist: starts at the origin, quaternion unit, attitude moves
    np.testing.assert_array_equal(plan.base_pose[0], [0, 0, 0, 0, 0, 0, 1])
    np.testing.assert_allclose(np.linalg.norm(plan.base_pose[:, 3:], axis=1), 1.0, atol=1e-12)
    assert np.abs(plan.base_pose[-1, 3:6]).max() > 0.01
    # at rest at both ends, the springs relaxed at the start; at the end δ = θ − q is rounding
    # (1e-16 rad), which δ̈ = (τ̇ − k δ̇)/d, δ̇ = (τ − k δ)/d amplify by (k/d)² to ~1e-6 in u
    assert np.abs(plan.qd[[0, -1]]).max() == 0 and np.abs(plan.u[0]).max() == 0
    assert np.abs(plan.u[-1]).max() < 1e-5
    np.testing.assert_array_equal(plan.theta[0], plan.q[0])
    np.testing.assert_array_equal(plan.initial_state(), plan.arm.state())


# ---------------------------------------------------------------------------------------------
# the plan: duration, binding limit, every limit on a fine grid
# ---------------------------------------------------------------------------------------------


def test_demo_plan_duration_and_binding_limit(demo_plan):
    assert demo_plan.duration == pytest.approx(5.7894809, rel=1e-7)
    assert demo_plan.binding == {"limit": "motor_torque", "joint": 3, "joint_name": "elbow_pitch", "segment": 0,
                                 "time": pytest.approx(4.12941, abs=1e-4), "value": pytest.approx(30.0, rel=1e-9),
                                 "bound": 30.0, "axis": None, "point": None}
    assert demo_plan.bindings == [demo_plan.binding]
    assert demo_plan.base == "free" and not demo_plan.is_rigid
    np.testing.assert_array_equal(demo_plan.segment_durations, [demo_plan.duration])
    np.testing.assert_array_equal(demo_plan.stops, [np.zeros(7), GOAL])
    np.testing.assert_array_equal(demo_plan.limits.motor_torque, MOTOR_TORQUE)
    np.testing.assert_array_equal(demo_plan.limits.joint_speed, np.full(7, 0.5))  # expanded per joint
    assert repr(demo_plan) == ("Plan(duration=5.789481 s, base='free', rigid=False, binding=motor_torque"
                               "[elbow_pitch] at t=4.1294 s, segments=1)")


def grid_ratios(plan: Plan, times) -> dict:
    """Per channel, the ratio to its limit at each time, from plan.evaluate."""
    limits = plan.limits
    mt, js = np.asarray(limits.motor_torque), np.asarray(limits.joint_speed)
    out = {"motor_torque": [], "joint_speed": [], "base_force": [], "base_torque": []}
    for t in times:
        p = plan.evaluate(t)
        out["motor_torque"].append(np.abs(p["u"]) / mt)
        out["joint_speed"].append(np.abs(p["qd"]) / js)
        f = p["base_wrench"]
        out["base_torque"].append([np.linalg.norm(f[:3]) / limits.base_torque] if limits.base_torque else [0.0])
        out["base_force"].append([np.linalg.norm(f[3:]) / limits.base_force] if limits.base_force else [0.0])
    return {k: np.array(v) for k, v in out.items()}


def check_limits_on_a_grid(plan: Plan, points: int = 5000) -> dict:
    """Every limit holds on ``points`` times (not the planner's samples), and the binding limit
    reaches its bound."""
    times = np.linspace(0, plan.duration, points) + 0.37 * plan.duration / points  # off the samples
    ratios = grid_ratios(plan, times[times < plan.duration])
    for name, r in ratios.items():
        assert r.max() <= 1 + 1e-9, (name, r.max())
    for b in plan.bindings:
        r = ratios[b["limit"]]
        channel = r[:, b["joint"]] if b["joint"] is not None else r[:, 0]
        ends = np.r_[0, np.cumsum(plan.segment_durations)]
        inside = (times[: len(channel)] >= ends[b["segment"]]) & (times[: len(channel)] < ends[b["segment"] + 1])
        assert channel[inside].max() >= 0.995, (b, channel[inside].max())
        # at the binding time the quantity is at its bound
        assert b["value"] / b["bound"] == pytest.approx(1.0, abs=1e-8)
        at = grid_ratios(plan, [b["time"]])[b["limit"]][0]
        assert at[b["joint"] if b["joint"] is not None else 0] == pytest.approx(b["value"] / b["bound"], rel=1e-9)
    return ratios


def test_limits_hold_on_a_fine_grid_free_base(demo_plan):
    check_limits_on_a_grid(demo_plan)


def test_limits_hold_on_a_fine_grid_held_base_with_base_limits(space_arm):
    limits = Limits(MOTOR_TORQUE, 0.5, base_force=40.0, base_torque=60.0)
    plan = plan_slew(space_arm, GOAL, limits=limits, base="held")
    assert plan.duration == pytest.approx(13.0504525, rel=1e-7)
    assert plan.binding["limit"] == "base_torque" and plan.binding["joint"] is None
    assert plan.binding["joint_name"] is None and plan.binding["bound"] == 60.0
    assert plan.binding["time"] == pytest.approx(7.64509, abs=1e-5)
    check_limits_on_a_grid(plan)
    # a held base does not move; its wrench is the one that holds it
    np.testing.assert_array_equal(plan.base_twist, 0)
    np.testing.assert_array_equal(plan.base_pose, np.tile([0, 0, 0, 0, 0, 0, 1.0], (len(plan.t), 1)))


@pytest.mark.parametrize("name", ["chain", "ur5"])
def test_limits_hold_on_a_fine_grid_with_waypoints(name):
    robot = load(name)
    n = robot.dof
    arm = FlexibleArm(robot, spread_joints(n, 5, 0.3))
    rng = np.random.default_rng(8)
    start, waypoint, goal = rng.uniform(-0.6, 0.6, (3, n))
    base_free = plan_slew(arm, goal, q_start=start, limits=Limits(5.0, 0.8), base="held", waypoints=[waypoint])
    # bound the base force at half its unbounded peak: it binds somewhere
    force = np.linalg.norm(base_free.base_wrench[:, 3:], axis=1).max()
    plan = plan_slew(arm, goal, q_start=start, limits=Limits(5.0, 0.8, base_force=0.5 * force), base="held",
                     waypoints=[waypoint])
    assert len(plan.segment_durations) == 2 and len(plan.bindings) == 2
    assert plan.duration == pytest.approx(plan.segment_durations.sum(), rel=1e-15)
    assert plan.duration > base_free.duration
    assert "base_force" in {b["limit"] for b in plan.bindings}
    np.testing.assert_array_equal(plan.stops, [start, waypoint, goal])
    ratios = check_limits_on_a_grid(plan)
    # the arm stops at the waypoint: at rest there
    p = plan.evaluate(plan.segment_durations[0])
    np.testing.assert_allclose(p["q"], waypoint, atol=1e-12)
    assert np.abs(p["qd"]).max() < 1e-12
    assert ratios["base_force"].max() >= 0.995


# ---------------------------------------------------------------------------------------------
# tracking: the plan is followed on the flexible arm
# ---------------------------------------------------------------------------------------------


def test_demo_tracking_numbers(demo_runs, demo_plan):
    flexible, rigid_plan, rigid = demo_runs
    assert rigid_plan.is_rigid and rigid_plan.duration == pytest.approx(5.7906219, rel=1e-7)
    np.testing.assert_array_equal(rigid_plan.theta, rigid_plan.q)  # θ = q: no springs
    assert flexible["tracking_error"] == pytest.approx(1.3545e-6, rel=0.01)
    assert flexible["residual_deflection"] == pytest.approx(1.0804e-7, rel=0.01)
    assert flexible["peak_motor_torque"][3] == pytest.approx(30.0, rel=1e-3)
    assert rigid["tracking_error"] == pytest.approx(1.1083e-2, rel=0.01)
    assert rigid["residual_deflection"] == pytest.approx(7.903e-4, rel=0.01)
    assert rigid["peak_motor_torque"][3] == pytest.approx(32.30, abs=0.01)
    assert flexible["slew_end"] == demo_plan.duration


def test_the_rigid_plan_breaks_the_limit_or_rings(demo_runs, demo_plan):
    # the paper's point: planned as if rigid, the same slew either needs more torque than the
    # limit or leaves the joints vibrating (here both)
    flexible, rigid_plan, rigid = demo_runs
    limit = np.asarray(demo_plan.limits.motor_torque)
    over = np.any(rigid["peak_motor_torque"] > limit * (1 + 1e-6))
    rings = rigid["residual_deflection"] >= 10 * flexible["residual_deflection"]
    assert over or rings
    assert over and rings
    assert np.all(flexible["peak_motor_torque"] <= limit * (1 + 1e-3))


def test_tracking_measures_are_those_of_the_run(demo_runs, demo_plan):
    flexible, _, _ = demo_runs
    traj, ref = flexible["trajectory"], flexible["reference"]
    # per-step tables have `steps` rows; the planned states, like the trajectory, steps + 1
    steps = len(ref["u"])
    assert steps == math.ceil((demo_plan.duration + 2.0) / DT) and len(traj) == steps + 1
    assert ref["q"].shape == (steps + 1, 7) and ref["base_pose"].shape == (steps + 1, 7)
    np.testing.assert_array_equal(ref["t"], np.arange(steps + 1) * DT)
    np.testing.assert_allclose(traj.t, ref["t"], rtol=1e-15, atol=0)
    assert flexible["tracking_error"] == np.abs(traj.q - ref["q"]).max()
    after = traj.t >= demo_plan.duration
    assert flexible["residual_deflection"] == np.abs(traj.deflection[after]).max()
    assert flexible["residual_link_error"] == np.abs(traj.q[after] - GOAL).max()
    np.testing.assert_array_equal(flexible["peak_motor_torque"], np.abs(traj.u).max(axis=0))
    assert flexible["base_position_error"] == pytest.approx(
        np.linalg.norm(traj.base_pose[:, :3] - ref["base_pose"][:, :3], axis=1).max(), rel=1e-12)
    assert flexible["base_attitude_error"] == pytest.approx(
        cli.relative_rotation(ref["base_pose"][:, 3:], traj.base_pose[:, 3:]).max(), rel=1e-6)
    assert traj.arm is demo_plan.arm


def test_reference_tables_drive_simulate_exactly_as_track_does(space_arm):
    # the documented recipe: MotorPD(kp, kd, theta_ref, theta_dot_ref, u) and the base wrench
    plan = plan_slew(space_arm, 0.3 * GOAL, limits=Limits(MOTOR_TORQUE, 0.5), base="held")
    run = plan.track(DT, KP, KD, settle=0.5)
    ref = run["reference"]
    steps = len(ref["u"])
    assert set(ref) == {"t", "u", "theta_ref", "theta_dot_ref", "base_wrench", "q", "base_pose"}
    pd = orbitflex.MotorPD(KP, KD, ref["theta_ref"], ref["theta_dot_ref"], ref["u"])
    traj = space_arm.simulate(plan.initial_state(), DT, steps, u=pd, base_wrench=ref["base_wrench"])
    np.testing.assert_array_equal(traj.x, run["trajectory"].x)
    # the tables: θ at each step's start, u averaged over the step (Simpson), rest after the end
    for k in (0, 700, steps - 1):
        t = k * DT
        a, m, b = plan.evaluate(t), plan.evaluate(t + DT / 2), plan.evaluate(t + DT)
        np.testing.assert_allclose(ref["theta_ref"][k], a["theta"], rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(ref["u"][k], (a["u"] + 4 * m["u"] + b["u"]) / 6, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(ref["base_wrench"][k], (a["base_wrench"] + 4 * m["base_wrench"]
                                                           + b["base_wrench"]) / 6, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(ref["q"][-1], 0.3 * GOAL, atol=1e-15)
    assert np.abs(ref["u"][-1]).max() < 1e-12
    # default: the steps that cover the plan
    assert len(plan.reference(DT)["u"]) == math.ceil(plan.duration / DT)
    assert plan.reference(0.01, steps=3)["u"].shape == (3, 7)


@pytest.mark.parametrize("name", ROBOTS)
@pytest.mark.parametrize("base", ["held", "free"])
def test_a_plan_is_followed_on_the_flexible_arm(name, base):
    robot = load(name)
    n = robot.dof
    joints = orbitflex.models.space_arm_joints() if name == "space_arm" else spread_joints(n, 2, 0.2)
    arm = FlexibleArm(robot, joints)
    goal = np.random.default_rng(9).uniform(-0.5, 0.5, n)
    plan = plan_slew(arm, goal, limits=Limits(20.0 if name == "space_arm" else 4.0, 0.6), base=base)
    kp, kd = cli.servo_gains(arm)
    dt = min(DT, cli.round_down(0.8 * cli.tracking_limit(arm, plan.stops, kp, kd)))
    run = plan.track(dt, kp, kd, settle=1.0)
    assert run["tracking_error"] <= 1e-3, run["tracking_error"]
    assert run["residual_link_error"] <= 1e-3
    if base == "held":
        assert run["base_position_error"] <= 1e-3  # m
        assert run["base_attitude_error"] <= np.radians(0.01)
    else:
        # the base moved, as planned
        assert np.linalg.norm(run["trajectory"].base_pose[-1, 3:6]) > 1e-4
        assert run["base_attitude_error"] <= 1e-3


def test_planning_and_tracking_release_the_gil(demo_plan, space_arm):
    # while plan_slew / track run in a thread, this thread keeps running
    for work in (lambda: plan_slew(space_arm, GOAL, limits=Limits(MOTOR_TORQUE, 0.5), base="held"),
                 lambda: demo_plan.track(DT, KP, KD, settle=0.0)):
        # five runs in a row: one takes only a few ms now, too short to count wakes reliably on a
        # loaded machine; with the GIL held, this thread would not wake at all until the end
        started, wakes = threading.Event(), 0
        thread = threading.Thread(target=lambda: (started.set(), [work() for _ in range(5)]))
        thread.start()
        started.wait()
        time.sleep(0.005)
        while thread.is_alive():
            time.sleep(0.001)
            wakes += 1
        thread.join()
        assert wakes >= 10, wakes


# ---------------------------------------------------------------------------------------------
# Limits, pickling, repr
# ---------------------------------------------------------------------------------------------


def test_limits_keep_what_they_were_given():
    limits = Limits(30, [0.5, 0.6, 0.7], base_force=12.5, base_torque=8)
    assert limits.motor_torque == 30.0 and isinstance(limits.motor_torque, float)
    np.testing.assert_array_equal(limits.joint_speed, [0.5, 0.6, 0.7])
    assert (limits.base_force, limits.base_torque) == (12.5, 8.0)
    assert Limits(1, 2).base_force is None and Limits(1, 2).base_torque is None
    assert repr(limits) == "Limits(motor_torque=30.0, joint_speed=[0.5, 0.6, 0.7], base_force=12.5, base_torque=8.0)"
    # the repr is Python: it evaluates back to the same limits, tiny numbers in exponent form
    assert repr(eval(repr(limits), {"Limits": Limits})) == repr(limits)
    assert repr(Limits(1e-320, 1)) == "Limits(motor_torque=1e-320, joint_speed=1.0, base_force=None, base_torque=None)"
    again = pickle.loads(pickle.dumps(limits))
    assert repr(again) == repr(limits)


def test_plans_pickle_by_planning_again(demo_plan, space_arm):
    for plan in (demo_plan, demo_plan.rigid()):
        again = pickle.loads(pickle.dumps(plan))
        assert type(again) is Plan and again.is_rigid == plan.is_rigid
        assert again.duration == plan.duration and again.binding == plan.binding
        for name in ("t", "q", "u", "theta", "base_pose"):
            np.testing.assert_array_equal(getattr(again, name), getattr(plan, name))
    held = plan_slew(space_arm, GOAL, q_start=-GOAL, limits=Limits(40, 0.5, base_force=30), base="held",
                     waypoints=[0.2 * GOAL])
    again = pickle.loads(pickle.dumps(held))
    assert again.base == "held" and again.limits.base_force == 30
    np.testing.assert_array_equal(again.stops, held.stops)
    np.testing.assert_array_equal(again.u, held.u)


# ---------------------------------------------------------------------------------------------
# errors: ModelError (a ValueError) naming what, where, expected and given
# ---------------------------------------------------------------------------------------------

LIMIT_ERRORS = [
    ((0, 1), {}, "motor_torque: expected a finite limit > 0, given 0"),
    ((-2.5, 1), {}, "motor_torque: expected a finite limit > 0, given -2.5"),
    ((math.nan, 1), {}, "motor_torque: expected a finite limit > 0, given NaN"),
    (([1, 2, -3], 1), {}, "motor_torque[2]: expected a finite limit > 0, given -3"),
    ((1, [1, math.inf]), {}, "joint_speed[1]: expected a finite limit > 0, given inf"),
    ((1, 0), {}, "joint_speed: expected a finite limit > 0, given 0"),
    (([], 1), {}, "motor_torque: expected one value per joint, or one for all, given no values"),
    (([[1, 2]], 1), {}, "motor_torque: expected a number or a 1-D array (one value per joint), given shape [1, 2]"),
    ((1, 1), {"base_force": 0}, "base_force: expected a finite limit > 0, given 0"),
    ((1, 1), {"base_torque": math.nan}, "base_torque: expected a finite limit > 0, given NaN"),
    ((1, 1), {"base_torque": "x"}, "base_torque: expected a real number, given str ('x')"),
    ((1, "fast"), {}, "joint_speed: expected real numbers, given text"),
]


@pytest.mark.parametrize("args, kwargs, message", LIMIT_ERRORS)
def test_bad_limits_are_model_errors(args, kwargs, message):
    with pytest.raises(ModelError) as e:
        Limits(*args, **kwargs)
    assert str(e.value) == message


def test_bad_plan_requests_are_model_errors(space_arm):
    limits = Limits(30, 0.5)

    def error(*args, **kwargs) -> str:
        with pytest.raises(ModelError) as e:
            plan_slew(space_arm, *args, **kwargs)
        return str(e.value)

    assert error(GOAL, limits=Limits([1, 2, 3], 1)) == \
        "limits.motor_torque: expected 7 values (one per joint) or 1 (for all), given 3 values"
    assert error(GOAL, limits=Limits(1, [1, 2])) == \
        "limits.joint_speed: expected 7 values (one per joint) or 1 (for all), given 2 values"
    assert error(GOAL[:3], limits=limits) == "q_goal: expected length 7, given length 3"
    assert error(GOAL, q_start=np.zeros(8), limits=limits) == "q_start: expected length 7, given length 8"
    assert error(GOAL, q_start=GOAL, limits=limits) == "q_goal: equals q_start (to 1e-12 rad): there is nothing to slew"
    assert error(np.zeros(7), limits=limits) == "q_goal: equals q_start (to 1e-12 rad): there is nothing to slew"
    assert error(GOAL, limits=limits, waypoints=[np.zeros(7)]) == \
        "waypoints[0]: equals q_start (to 1e-12 rad): there is nothing to slew"
    assert error(GOAL, limits=limits, waypoints=[GOAL / 2, GOAL]) == "q_goal: equals waypoints[1] (to 1e-12 rad): there is nothing to slew"
    assert error(GOAL, limits=limits, waypoints=GOAL / 2) == (
        "waypoints: expected a list of waypoints, shape (m, 7), given a 1-D array of length 7; wrap a single "
        "waypoint in a list: waypoints=[q]")
    assert error(GOAL, limits=limits, waypoints=[np.ones(6)]) == "waypoints: expected shape (rows, 7), given shape (1, 6)"
    assert error(GOAL, limits=limits, base="fixed") == 'base: expected "held" or "free", given "fixed"'
    assert error(GOAL * np.nan, limits=limits) == "q_goal: element 0 is not finite (NaN)"
    bad = GOAL / 3
    bad[2] = np.inf
    assert error(GOAL, limits=limits, waypoints=[GOAL / 2, bad]) == "waypoints[1]: element 2 is not finite (inf)"
    assert error(GOAL, limits=Limits(1e-300, 0.5)).startswith("limits: no duration up to ")
    # without limits, the URDF's: a model that states none is an error naming every joint
    unstated = FlexibleArm(orbitflex.Robot.from_urdf_string(LIMITED), FlexibleJoints(500.0, 0.1))
    with pytest.raises(ModelError) as e:
        plan_slew(unstated, np.full(3, 0.1))
    assert str(e.value) == ("motor_torque: the model (<urdf string>) states no effort limit (<limit effort=\"…\">), "
                            "or a zero one, for 'unstated'; give motor_torque yourself, or pass "
                            "limits=orbitflex.Limits(motor_torque, joint_speed, base_force=None, base_torque=None)")
    with pytest.raises(TypeError, match="^plan_slew: limits: expected an orbitflex.Limits, given dict$"):
        plan_slew(space_arm, GOAL, limits={"motor_torque": 30})


def test_inverse_dynamics_deflection_misuse_is_a_model_error(space_arm):
    z = np.zeros(7)
    undamped = FlexibleArm(orbitflex.models.space_arm(), FlexibleJoints(2e4, 1.0))

    def error(arm, *args, **kwargs) -> str:
        with pytest.raises(ModelError) as e:
            arm.inverse_dynamics(*args, **kwargs)
        return str(e.value)

    assert error(space_arm, GOAL, z, z, z, z) == (
        "deflection: the joints have damping d > 0, so the deflection θ − q depends on the motion's history; "
        "pass the current deflection (n values, rad), or plan the whole motion with plan_slew")
    assert error(undamped, GOAL, z, z, z, z, deflection=z) == (
        "deflection: every joint has damping d = 0, so θ − q = τ/k is determined by the instant; omit the "
        "deflection")
    assert error(space_arm, GOAL, z, z, z, z, deflection=z[:3]) == "deflection: expected length 7, given length 3"
    assert error(space_arm, GOAL, z, z, z, z, deflection=z * np.nan) == "deflection: element 0 is not finite (NaN)"
    assert error(undamped, GOAL, z, z, z[:6], z) == "qddd: expected length 7, given length 6"
    assert error(undamped, GOAL, z, z, z, z, base="fixed") == 'base: expected "held" or "free", given "fixed"'
    # finite but absurd rates overflow: an error, not arrays of inf and NaN
    assert error(undamped, GOAL, np.full(7, 1e200), z, z, z).startswith(
        "motion: too large for floating point: the inverse dynamics of q, qd, qdd, qddd, qdddd overflowed")


def test_bad_reference_and_track_arguments_are_model_errors(demo_plan):
    def error(f, *args, **kwargs) -> str:
        with pytest.raises(ModelError) as e:
            f(*args, **kwargs)
        return str(e.value)

    assert error(demo_plan.reference, 0) == "dt: expected a finite step > 0 s, given 0"
    assert error(demo_plan.reference, -1e-3) == "dt: expected a finite step > 0 s, given -0.001"
    assert error(demo_plan.reference, 1e-300) == "dt: 1e-300 s makes 5.789e300 steps of 5.789481 s; lengthen dt"
    assert error(demo_plan.reference, 1e-3, steps=-1).startswith("steps: expected an integer from 0 to ")
    assert error(demo_plan.reference, 1e-3, steps=1.5) == "steps: expected an integer >= 0, given float (1.5)"
    assert error(demo_plan.reference, 1e308, steps=3) == "dt: 3 steps of 1e308 s do not end at a finite time"
    assert re.fullmatch(r"steps: 100000000000000 steps of 41 values each need 32800000\.0 GB, more than the "
                        r".* available; lengthen dt or ask for fewer steps",
                        error(demo_plan.reference, 1e-3, steps=10**14))
    assert error(demo_plan.track, DT, [1, 2], 1) == "kp: expected a number or length 7 (one per joint), given length 2"
    assert error(demo_plan.track, DT, 1, -1) == "kd[0]: expected >= 0, given -1"
    assert error(demo_plan.track, DT, 1, 1, settle=-1) == "settle: expected a finite time >= 0 (s), given -1"
    assert error(demo_plan.track, DT, 1, 1, settle=math.inf) == "settle: expected a finite time >= 0 (s), given inf"
    assert error(demo_plan.evaluate, math.nan) == "t: element 0 is not finite (NaN)"
    assert error(demo_plan.evaluate, "a") == "t: expected a real number, given str ('a')"


def test_tracking_refuses_a_step_that_cannot_follow_the_plan(demo_plan, space_arm):
    # past the stability limit of the loop at the start (computed here independently) the run
    # would diverge: refused before it starts, naming dt; a step longer than the plan too
    limit = space_arm.rk4_stability_limit(demo_plan.initial_state(), orbitflex.MotorPD(KP, KD, np.zeros(7))).dt
    assert limit == pytest.approx(7.439e-3, rel=1e-3)
    with pytest.raises(ModelError, match=r"^dt: 0\.05 s is past the RK4 stability limit 7\.439\de-3 s of the "
                                         r"tracking loop"):
        demo_plan.track(0.05, KP, KD, settle=0.0)
    with pytest.raises(ModelError, match=r"^dt: 100 s is longer than the plan \(5\.789"):
        demo_plan.track(100.0, 1e-6, 1e-6, settle=0.0)
    run = demo_plan.track(0.99 * limit, KP, KD, settle=0.0)
    assert np.isfinite(run["trajectory"].x).all()
    # an absurd settling time is blamed on settle, in short numbers
    with pytest.raises(ModelError, match=r"^settle: dt = 0\.001 s over the plan's 5\.789481 s plus settle = 1e300 s makes"):
        demo_plan.track(1e-3, KP, KD, settle=1e300)


def test_ctrl_c_stops_a_long_tracking_run():
    code = textwrap.dedent("""
        import signal, threading, os, time, numpy as np, orbitflex
        arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
        plan = orbitflex.plan_slew(arm, np.full(7, 0.3), limits=orbitflex.Limits(30.0, 0.5))
        threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
        start = time.perf_counter()
        try:
            plan.track(1e-4, 1000.0, 100.0, settle=300.0)   # 3e6 steps: about a minute
            print("FINISHED", time.perf_counter() - start)
        except KeyboardInterrupt:
            print("INTERRUPTED", time.perf_counter() - start)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert "INTERRUPTED" in out.stdout, out.stdout + out.stderr
    assert float(out.stdout.split()[-1]) < 5.0, out.stdout


def test_limits_given_in_the_place_of_q_start_are_named(space_arm):
    with pytest.raises(TypeError, match=r"^plan_slew: q_start: given an orbitflex\.Limits .* limits=\.\.\."):
        plan_slew(space_arm, GOAL, Limits(MOTOR_TORQUE, 0.5))


def test_a_huge_speed_limit_means_no_speed_limit(space_arm):
    plans = [plan_slew(space_arm, GOAL, limits=Limits(MOTOR_TORQUE, v), base="free") for v in (1e3, 1e18, 1.7e308)]
    for plan in plans:
        assert plan.binding["limit"] == "motor_torque"
        assert plan.duration == pytest.approx(plans[0].duration, rel=2e-10)


# ---------------------------------------------------------------------------------------------
# the command line: `orbitflex plan` and the demo's comparison
# ---------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def model_files(tmp_path_factory):
    import test_cli

    folder = tmp_path_factory.mktemp("plan_model")
    (folder / "two_link_sat.urdf").write_text(test_cli.URDF)
    (folder / "two_link_sat.toml").write_text(test_cli.PARAMS)
    return folder / "two_link_sat.urdf", folder / "two_link_sat.toml"


def plan_args(model_files, *extra):
    urdf, params = model_files
    return ["plan", str(urdf), "--params", str(params), "--locked-joints", "finger_slide", *map(str, extra)]


@pytest.fixture(scope="module")
def plan_run(model_files, tmp_path_factory):
    from test_cli import run_cli

    out = tmp_path_factory.mktemp("plan") / "out"
    args = plan_args(model_files, "--goal", 0.8, -0.5, "--waypoint", 0.4, 0.3, "--motor-torque", 2,
                     "--joint-speed", 1, "--base", "free", "--out", out)
    return run_cli(*args, cwd=out.parent), out


def test_plan_command_writes_its_outputs(plan_run, model_files):
    result, out = plan_run
    assert result.returncode == 0, result.stderr[-2000:]
    assert "Traceback" not in result.stderr and result.stderr == ""
    written = {p.name for p in out.iterdir()}
    assert written == set(cli.PLAN_OUTPUTS)
    listed = [line.split() for line in result.stdout.splitlines() if str(out) in line]
    assert {Path(words[0]).name for words in listed} == written
    assert f"wrote {len(written)} files" in result.stdout
    for name in written:
        if name.endswith(".png"):
            assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the printed summary and the files agree with a plan made in Python
    urdf, params = model_files
    robot = orbitflex.Robot.from_urdf(urdf, locked_joints=["finger_slide"])
    arm = FlexibleArm(robot, FlexibleJoints.from_toml(params, robot))
    plan = plan_slew(arm, [0.8, -0.5], limits=Limits(2, 1), base="free", waypoints=[[0.4, 0.3]])
    summary = json.loads((out / "plan_summary.json").read_text())
    assert summary["flexible"]["duration_s"] == plan.duration
    assert summary["segment_durations_s"] == plan.segment_durations.tolist()
    # the summary names the joint limits; "axis" and "point" (base limits) are not among them here
    assert summary["flexible"]["binding"] == {k: v for k, v in plan.binding.items() if k not in ("axis", "point")}
    text = result.stdout
    assert f"duration            {plan.duration:.4f} s (2 segments: " in text
    assert "segment 1         motor_torque on shoulder (joint index 0): 2 of 2 N·m at t = 1.282 s" in text
    for label in ("peak commanded torque", "tracking error", "residual deflection", "base attitude error",
                  "flexible plan", "rigid-joint plan", "× the flexible plan's residual deflection"):
        assert label in text, label
    with np.load(out / "plan.npz") as data:
        np.testing.assert_array_equal(data["u"], plan.u)
        np.testing.assert_array_equal(data["rigid_u"], plan.rigid().u)
        assert data["tracking_error"] == summary["flexible"]["tracking_error_rad"]
        assert data["rigid_residual_deflection"] == summary["rigid"]["residual_deflection_rad"]
        assert data["reference_u"].shape == (math.ceil((plan.duration + 2) / 1e-3), 2)
        assert data["run_x"].shape == (len(data["reference_u"]) + 1, 13 + 8)
        assert list(data["joint_names"]) == ["shoulder", "elbow"] and str(data["base"]) == "free"
        assert str(data["binding_limit"]) == summary["flexible"]["binding"]["limit"]
        assert data["dt"] == 1e-3


def test_plan_command_held_base_without_plots(model_files, tmp_path, capsys):
    code = cli.main(plan_args(model_files, "--goal", 0.8, -0.5, "--motor-torque", 2, 1, "--joint-speed", 1,
                              "--base", "held", "--base-torque", 3, "--kp", 100, "--kd", 10, "--dt", 2e-3,
                              "--settle", 0.5, "--out", tmp_path, "--no-plots"))
    text = capsys.readouterr().out
    assert code == 0
    assert {p.name for p in tmp_path.iterdir()} == {"plan.npz", "plan_summary.json"}
    assert "binding limit       base_torque: 3 of 3 N·m at t = 1.178 s" in text
    assert "RK4 dt = 2 ms" in text and "motor PD kp = 100 N·m/rad, kd = 10 N·m·s/rad" in text
    summary = json.loads((tmp_path / "plan_summary.json").read_text())
    assert summary["base"] == "held" and summary["limits"]["base_torque_Nm"] == 3.0
    assert summary["kp"] == [100.0, 100.0] and summary["dt_s"] == 2e-3 and summary["settle_s"] == 0.5
    assert summary["flexible"]["base_position_error_m"] < 1e-3


def cli_error(argv, capsys) -> str:
    """Runs the CLI in process; returns its one-line error (exit code 2)."""
    try:
        code = cli.main(argv)
    except SystemExit as e:  # argparse
        code = e.code
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("orbitflex: error: "), err
    return lines[0][len("orbitflex: error: "):]


PLAN_CLI_ERRORS = [
    (["--goal", 3.5, -0.5, "--joint-speed", 1],
     "--goal: joint 0 ('shoulder') = 3.5 rad is outside its position limits [-3, 3] rad (the model's <limit "
     "lower upper>)"),
    (["--goal", 0.8, -0.5, "--motor-torque", 2, "--joint-speed", 1, "--start", 0.8, -0.5],
     "--goal: equals --start: there is nothing to slew between them"),
    (["--goal", 0, "--motor-torque", 2, "--joint-speed", 1],
     "--goal: equals --start (default 0 for every joint): there is nothing to slew between them"),
    (["--goal", 0.8, -0.5, "--motor-torque", 2, "--joint-speed", 1, "--waypoint", 0.1, 0.1, "--waypoint", 0.1, 0.1],
     "--waypoint: waypoint 2 equals --waypoint 1: there is nothing to slew between them"),
    (["--goal", 0.8, -0.5, 0.3, "--motor-torque", 2, "--joint-speed", 1],
     "--goal: expected 1 or 2 values (one per joint: shoulder, elbow), given 3"),
    (["--goal", 0.8, -0.5, "--motor-torque", 2, 3, 4, "--joint-speed", 1],
     "--motor-torque: expected 1 or 2 values (one per joint: shoulder, elbow), given 3"),
    (["--goal", 0.8, -0.5, "--motor-torque", 0, "--joint-speed", 1],
     "--motor-torque: expected a finite number > 0, given 0 (see 'orbitflex plan --help')"),
    (["--goal", 0.8, -0.5, "--motor-torque", 2, "--joint-speed", "nan"],
     "--joint-speed: expected a finite number, given nan (see 'orbitflex plan --help')"),
    (["--goal", 0.8, -0.5, "--motor-torque", 2, "--joint-speed", 1, "--base", "free", "--base-force", 3],
     "--base-force: bounds the wrench of the actuators that hold the base; a free-floating base (--base free) "
     "has none: add --base held or drop it"),
    (["--goal", 0.8, -0.5, "--motor-torque", 2, "--joint-speed", 1, "--base", "fixed"],
     "--base: invalid choice: 'fixed' (choose from 'held', 'free') (see 'orbitflex plan --help')"),
    (["--goal", 0.8, -0.5, "--motor-torque", 2, "--joint-speed", 1, "--dt", 0.05],
     "--dt: 0.05 s is past the RK4 stability limit 0.025 s of the arm under the tracking PD (at rest at the "
     "stops); use --dt 0.02 or less, or lower --kp/--kd"),
    (["--goal", 0.8, -0.5, "--motor-torque", 2, "--joint-speed", 1, "--kp", -1],
     "--kp: expected a finite number >= 0, given -1 (see 'orbitflex plan --help')"),
    (["--goal", 0.8, -0.5, "--motor-torque", 2, "--joint-speed", 1, "--kd", 1, 2, 3],
     "--kd: expected 1 or 2 values (one per joint: shoulder, elbow), given 3"),
    (["--goal", 0.8, -0.5, "--motor-torque", 1e-300, "--joint-speed", 1],
     re.compile(r"--motor-torque: no duration up to \S+ s meets them: --motor-torque\[0\] still needs ")),
]


@pytest.mark.parametrize("extra, message", PLAN_CLI_ERRORS)
def test_plan_command_errors_are_one_line(model_files, tmp_path, capsys, extra, message):
    line = cli_error(plan_args(model_files, *extra, "--out", tmp_path / "out", "--no-plots"), capsys)
    if isinstance(message, str):
        assert line == message
    else:
        assert message.match(line), line
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_plan_command_model_errors_name_the_flag(model_files, tmp_path, capsys):
    urdf, params = model_files
    limits = ["--goal", "1", "--motor-torque", "1", "--joint-speed", "1", "--out", str(tmp_path)]
    line = cli_error(["plan", str(urdf), *limits], capsys)
    assert "finger_slide" in line and "locked_joints" not in line, line
    line = cli_error(["plan", str(tmp_path / "missing.urdf"), *limits], capsys)
    assert line.startswith("URDF: ") and "not found" in line


def test_plan_command_error_exit_code_from_the_shell(model_files, tmp_path):
    from test_cli import assert_clean_error, run_cli

    result = run_cli(*plan_args(model_files, "--goal", 0.8, -0.5, "--motor-torque", 2, "--joint-speed", 1,
                                "--dt", 0.05), cwd=tmp_path)
    assert_clean_error(result, "RK4 stability limit", flag="--dt")


def test_default_dt_is_lowered_within_the_stability_limit(model_files, tmp_path, capsys):
    code = cli.main(plan_args(model_files, "--goal", 0.8, -0.5, "--motor-torque", 2, "--joint-speed", 1,
                              "--kp", 1e6, "--settle", 0, "--out", tmp_path, "--no-plots"))
    text = capsys.readouterr().out
    assert code == 0
    assert "dt = 20 µs: the default 1 ms is past 80% of the RK4 stability limit 2.63e-05 s" in text
    assert json.loads((tmp_path / "plan_summary.json").read_text())["dt_s"] == 2e-5


def test_round_down_and_servo_gains(space_arm):
    assert [cli.round_down(x) for x in (0.0295, 0.02, 2.63e-5 * 0.8, 0.0099, 7.4e-3)] == [0.02, 0.02, 2e-5, 0.005, 0.005]
    kp, kd = cli.servo_gains(space_arm)
    _, j, _, _ = space_arm.parameters
    w = 2 * np.pi * cli.SERVO_HZ
    np.testing.assert_allclose(kp, j * w**2, rtol=1e-15)
    np.testing.assert_allclose(kd, 2 * j * w, rtol=1e-15)


def test_plan_help_lists_the_flags(tmp_path):
    from test_cli import run_cli

    result = run_cli("plan", "--help", cwd=tmp_path)
    assert result.returncode == 0
    for flag in ("--goal", "--start", "--waypoint", "--motor-torque", "--joint-speed", "--base-force",
                 "--base-torque", "--base {held,free}", "--dt", "--kp", "--kd", "--settle", "--out", "--no-plots",
                 "--params", "--ee-link", "--locked-joints", "--base-mass"):
        assert flag in result.stdout, flag
    assert "plan" in run_cli("--help", cwd=tmp_path).stdout


@pytest.fixture(scope="module")
def plan_figures(model_files, tmp_path_factory):
    """``{png: figure}`` of `orbitflex plan` for the two-link arm, held (with a base limit) and free."""
    import matplotlib

    matplotlib.use("Agg")
    urdf, params = model_files
    robot = orbitflex.Robot.from_urdf(urdf, locked_joints=["finger_slide"])
    arm = FlexibleArm(robot, FlexibleJoints.from_toml(params, robot))
    kept = {}
    original = cli.Figures.save
    try:
        for base, limits in (("held", Limits([2, 1], 1, base_torque=3)), ("free", Limits(2, 1))):
            plan = plan_slew(arm, [0.8, -0.5], limits=limits, base=base, waypoints=[[0.4, 0.3]])
            comparison = cli.compare(robot.name, plan, 1e-3, *cli.servo_gains(arm), 0.5)
            cli.Figures.save = lambda self, fig, name, base=base: kept.__setitem__((base, name), fig)
            cli.plot_plan(comparison, tmp_path_factory.mktemp("plots"))
            kept[(base, "comparison")] = comparison
    finally:
        cli.Figures.save = original
    yield kept
    import matplotlib.pyplot as plt

    for key, fig in kept.items():
        if key[1] != "comparison":
            plt.close(fig)


def test_every_plan_plot_names_model_duration_and_dt_with_units(plan_figures):
    unit = re.compile(r"\((s|deg|mrad|µrad|nrad|rad|rad/s|N·m|N|m|mm|%)\)$")
    names = {name for _, name in plan_figures} - {"comparison"}
    assert names == {n for n in cli.PLAN_OUTPUTS if n.endswith(".png")}
    for (base, name), fig in plan_figures.items():
        if name == "comparison":
            continue
        c = plan_figures[(base, "comparison")]
        suptitle = fig._suptitle.get_text()
        for words in ("two_link_sat", f"plan {c.plan.duration:.3f} s", "dt = 1 ms", f"{base} base"):
            assert words in suptitle, (name, words, suptitle)
        for ax in fig.axes:
            if not ax.get_visible() or not ax.axison:
                continue
            for label in (ax.get_ylabel(), ax.get_xlabel()):
                assert label == "" or unit.search(label), (name, label)
            assert unit.search(ax.get_ylabel()), (name, ax.get_ylabel())


def test_motor_torque_plot_draws_the_limits_and_marks_the_binding_peaks(plan_figures):
    fig = plan_figures[("free", "plan_motor_torque.png")]
    c = plan_figures[("free", "comparison")]
    shoulder, elbow = [ax for ax in fig.axes if ax.get_visible()]
    for i, ax in enumerate((shoulder, elbow)):
        dashed = sorted(line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == "--")
        # drawn where the torque comes near it (else the panel is scaled to the torque)
        near = np.abs(c.plan.u[:, i]).max() >= 0.5 * 2.0
        assert dashed == ([-2.0, 2.0] if near else []), (i, dashed)
    assert [line.get_ydata()[0] for line in shoulder.get_lines() if line.get_linestyle() == "--"]
    # segment 1 binds on the shoulder's torque: marked, and said in the title
    assert "binds" in shoulder.get_title() and "binds" not in elbow.get_title()
    dots = [line for line in shoulder.get_lines() if line.get_marker() == "o"]
    b = c.plan.bindings[0]
    assert b["limit"] == "motor_torque" and len(dots) == 1
    assert abs(dots[0].get_ydata()[0]) == pytest.approx(b["value"]) and dots[0].get_xdata()[0] == b["time"]


def test_base_plot_shows_the_held_wrench_against_its_limit(plan_figures):
    moment, force = plan_figures[("held", "plan_base.png")].axes
    limit = [line for line in moment.get_lines() if line.get_label() == "limit 3 N·m"]
    assert len(limit) == 1 and limit[0].get_ydata()[0] == 3.0
    assert "(no limit given)" in force.get_title()
    norm = [line for line in moment.get_lines() if line.get_label().startswith("$|n|$")]
    assert max(norm[0].get_ydata()) == pytest.approx(3.0, rel=1e-8)
    attitude, shift = plan_figures[("free", "plan_base.png")].axes
    assert "z-y′-x″" in attitude.get_title() and shift.get_ylabel() == "base origin shift (mm)"


def test_comparison_plot_shows_both_plans_against_the_limit(plan_figures):
    fig = plan_figures[("free", "plan_vs_rigid.png")]
    c = plan_figures[("free", "comparison")]
    bars = fig.axes[0]
    heights = [patch.get_height() for patch in bars.patches]
    expected = [100 * r["peak_motor_torque"] / 2.0 for r in (c.flexible_run, c.rigid_run)]
    np.testing.assert_allclose(heights, np.concatenate(expected), rtol=1e-12)
    assert any(line.get_ydata()[0] == 100 for line in bars.get_lines())  # the limit
    for ax in fig.axes[1:5]:
        labels = [line.get_label() for line in ax.get_lines()]
        assert labels[:2] == ["flexible plan", "rigid-joint plan"] and ax.get_yscale() == "log"
    cells = fig.axes[5].tables[0].get_celld()
    text = {(r, col): cell.get_text().get_text() for (r, col), cell in cells.items()}
    assert text[(0, 1)] == "flexible plan" and text[(0, 2)] == "rigid-joint plan"
    assert f"{c.rigid_run['residual_deflection']:.2e} rad" in text.values()
    assert "kp = 197.4 N·m/rad" in fig._suptitle.get_text()


def test_demo_shows_the_planned_slew_beside_the_rigid_one(tmp_path):
    from test_cli import run_cli

    result = run_cli("demo", "--duration", "0.2", "--out", tmp_path / "out", "--quiet", "--no-plots", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    text = result.stdout
    assert "minimum-time slew of 'space_arm' to q = [0.8, -0.6, 0.5, 1, -0.7, 0.6, 0.9] rad, free floating" in text
    # under the built-in URDF's own limits: its shoulders' 0.15 rad/s binds (T = 0.8 · 630/256 / 0.15)
    assert ("limits (the URDF's) motor torque [250, 250, 250, 200, 100, 80, 60] N·m, joint speed [0.15, 0.15, "
            "0.15, 0.2, 0.3, 0.3, 0.4] rad/s") in text
    assert "flexible plan       13.1250 s, binding joint_speed on shoulder_roll (joint index 0): 0.15 of 0.15 rad/s" in text
    assert "rigid-joint plan    13.1250 s, binding joint_speed on shoulder_roll (joint index 0)" in text
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    planned = summary["planned_slew"]
    assert planned["flexible"]["duration_s"] == pytest.approx(13.125, rel=1e-12)
    assert planned["limits"]["joint_speed_rad_s"] == [0.15, 0.15, 0.15, 0.2, 0.3, 0.3, 0.4]
    # within the URDF's effort, the rigid plan's sin is the vibration it leaves: 7.3e-6 rad after
    # the stop against 1.3e-9, and a 1.3 mrad tracking error against 7e-8
    assert planned["rigid"]["residual_deflection_rad"] > 1000 * planned["flexible"]["residual_deflection_rad"]
    assert planned["rigid"]["tracking_error_rad"] > 1e4 * planned["flexible"]["tracking_error_rad"]
    assert planned["flexible"]["peak_torque_over_limit"] < 0.05
    assert planned["kp"] == [KP] * 7 and planned["dt_s"] == DT


# ---------------------------------------------------------------------------------------------
# the URDF's limits: read, planned under, enforced
# ---------------------------------------------------------------------------------------------

LIMITED = """<robot name="limited">
  <link name="bus"><inertial><mass value="100"/><inertia ixx="10" iyy="10" izz="10" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="a"><inertial><origin xyz="0.3 0 0"/><mass value="2"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="b"><inertial><origin xyz="0.3 0 0"/><mass value="2"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="c"><inertial><origin xyz="0.3 0 0"/><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="revolute" type="revolute"><parent link="bus"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-1.5" upper="0.5" effort="40" velocity="0.7"/></joint>
  <joint name="continuous" type="continuous"><parent link="a"/><child link="b"/><origin xyz="0.6 0 0"/><axis xyz="0 1 0"/>
    <limit effort="20" velocity="1.2"/></joint>
  <joint name="unstated" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.6 0 0"/><axis xyz="0 1 0"/></joint>
</robot>"""


def test_the_urdf_limits_are_read_per_joint():
    robot = orbitflex.Robot.from_urdf_string(LIMITED)
    # a continuous joint turns freely; a joint without <limit> states nothing
    np.testing.assert_array_equal(robot.position_limits, [[-1.5, 0.5], [-np.inf, np.inf], [-np.inf, np.inf]])
    np.testing.assert_array_equal(robot.velocity_limits, [0.7, 1.2, np.inf])
    np.testing.assert_array_equal(robot.effort_limits, [40, 20, np.inf])
    space = orbitflex.models.space_arm()
    np.testing.assert_array_equal(space.velocity_limits, [0.15, 0.15, 0.15, 0.2, 0.3, 0.3, 0.4])
    np.testing.assert_array_equal(space.effort_limits, [250, 250, 250, 200, 100, 80, 60])
    assert space.position_limits[6].tolist() == [-3.05, 3.05]
    # they follow the model through its changes, and a locked joint takes its limits with it
    assert space.with_payload(10.0).velocity_limits.tolist() == space.velocity_limits.tolist()
    locked = orbitflex.Robot.from_urdf_string(LIMITED, locked_joints=["continuous"])
    np.testing.assert_array_equal(locked.effort_limits, [40, np.inf])
    # and what a URDF cannot mean is refused, naming the joint
    with pytest.raises(ModelError, match=r"joint 'revolute': position limits: expected finite lower <= upper \(rad\), "
                                         r"given lower = 1, upper = -1"):
        orbitflex.Robot.from_urdf_string(LIMITED.replace('lower="-1.5" upper="0.5"', 'lower="1" upper="-1"'))
    with pytest.raises(ModelError, match=r"joint 'continuous': velocity limit: expected a finite number >= 0, given -1"):
        orbitflex.Robot.from_urdf_string(LIMITED.replace('velocity="1.2"', 'velocity="-1"'))
    with pytest.raises(ModelError, match=r'<urdf string>: malformed URDF: line 7: <limit effort="x">: expected a number'):
        orbitflex.Robot.from_urdf_string(LIMITED.replace('effort="40"', 'effort="x"'))


def test_limits_from_the_urdf_and_what_they_cannot_give():
    robot = orbitflex.models.space_arm()
    limits = Limits.from_urdf(robot)
    np.testing.assert_array_equal(limits.motor_torque, robot.effort_limits)  # link-side motor torque
    np.testing.assert_array_equal(limits.joint_speed, robot.velocity_limits)
    assert limits.base_force is None and Limits.from_urdf(robot, base_force=50.0).base_force == 50.0
    with pytest.raises(ModelError) as e:
        Limits.from_urdf(orbitflex.Robot.from_urdf_string(LIMITED))
    assert str(e.value) == ("motor_torque: the model (<urdf string>) states no effort limit (<limit effort=\"…\">), "
                            "or a zero one, for 'unstated'; give motor_torque yourself")


def test_a_plan_keeps_to_the_urdf_speeds_by_default(space_arm):
    # The README and the demo planned at 0.5 rad/s, and peaked at 0.34 rad/s on shoulder_roll
    # (the URDF allows 0.15) without a word. Without limits a plan takes the URDF's, and more
    # than them warns.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plan = plan_slew(space_arm, GOAL, base="free")
    speeds = space_arm.robot.velocity_limits
    assert np.abs(plan.qd).max(axis=0) == pytest.approx(np.minimum(speeds, np.abs(plan.qd).max(axis=0)), rel=1e-12)
    assert np.all(np.abs(plan.qd).max(axis=0) <= speeds * (1 + 1e-12))
    # the speed bound is exact: T = |Δq| max σ' / q̇_max, σ'(1/2) = 630/256
    assert plan.duration == pytest.approx(0.8 * (630 / 256) / 0.15, rel=1e-12)
    assert plan.binding["limit"] == "joint_speed" and plan.binding["joint_name"] == "shoulder_roll"
    assert np.all(np.abs(plan.u).max(axis=0) <= space_arm.robot.effort_limits)
    with pytest.warns(orbitflex.LimitWarning) as record:
        plan_slew(space_arm, GOAL, limits=Limits(MOTOR_TORQUE, 0.5), base="free")
    assert str(record[0].message) == (
        "limits allow more than the robot's model states (its URDF's <limit effort velocity>): joint_speed (rad/s): "
        "'shoulder_roll' 0.5 > 0.15, 'shoulder_yaw' 0.5 > 0.15, 'shoulder_pitch' 0.5 > 0.15, 'elbow_pitch' 0.5 > 0.2, "
        "'wrist_pitch' 0.5 > 0.3, 'wrist_yaw' 0.5 > 0.3, 'wrist_roll' 0.5 > 0.4; the plan uses them as given")
    with pytest.warns(orbitflex.LimitWarning, match=r"motor_torque \(N·m\): 'wrist_roll' 61 > 60; the plan"):
        plan_slew(space_arm, GOAL, limits=Limits([250, 250, 250, 200, 100, 80, 61], 0.1), base="free")


def test_a_stop_outside_the_position_limits_is_refused(space_arm):
    # plan_slew to 5 rad on wrist_roll (±3.05) returned a 24.6 s plan without a word
    goal = np.r_[0, 0, 0, 0, 0, 0, 5.0]
    limits = Limits.from_urdf(space_arm.robot)

    def error(**kwargs) -> str:
        with pytest.raises(ModelError) as e:
            plan_slew(space_arm, limits=limits, base="free", **kwargs)
        return str(e.value)

    assert error(q_goal=goal) == ("q_goal: joint 6 ('wrist_roll') = 5 rad is outside its position limits "
                                  "[-3.05, 3.05] rad (the model's <limit lower upper>)")
    assert error(q_goal=np.full(7, 0.1), q_start=np.r_[2.1, 0, 0, 0, 0, -2.2, 0]) == (
        "q_start: joint 5 ('wrist_yaw') = -2.2 rad is outside its position limits [-2, 2] rad (the model's "
        "<limit lower upper>)")
    assert error(q_goal=np.full(7, 0.1), waypoints=[np.full(7, 0.05), np.r_[0, 2.7, 0, 2.61, 0, 0, 0]]) == (
        "waypoints[1]: joint 1 ('shoulder_yaw') = 2.7 rad is outside its position limits [-2.6, 2.6] rad; joint 3 "
        "('elbow_pitch') = 2.61 rad is outside its position limits [-2.6, 2.6] rad (the model's <limit lower upper>)")
    # on the bound is inside
    assert plan_slew(space_arm, np.r_[0, 0, 0, 0, 0, 0, 3.05], limits=limits, base="free").duration > 0


def test_plan_command_takes_the_urdf_limits_unless_told_otherwise(model_files, tmp_path, capsys):
    # two_link_sat's URDF: effort 50 N·m, velocity 1 rad/s on both joints
    code = cli.main(plan_args(model_files, "--goal", 0.8, -0.5, "--out", tmp_path / "a", "--no-plots"))
    out = capsys.readouterr()
    assert code == 0, out.err
    assert "limits              motor torque 50 N·m, joint speed 1 rad/s (the URDF's <limit effort velocity>)" in out.out
    assert "warning" not in out.err
    limits = json.loads((tmp_path / "a" / "plan_summary.json").read_text())["limits"]
    assert limits["motor_torque_Nm"] == [50, 50] and limits["joint_speed_rad_s"] == [1, 1]
    # more than the URDF's: planned as given, with one warning line in the CLI's words
    code = cli.main(plan_args(model_files, "--goal", 0.8, -0.5, "--joint-speed", 2, "--out", tmp_path / "b",
                              "--no-plots"))
    out = capsys.readouterr()
    assert code == 0, out.err
    assert "(--joint-speed as given, the other the URDF's <limit effort velocity>)" in out.out
    warned = [line for line in out.err.splitlines() if "warning" in line]
    assert warned == ["orbitflex: warning: limits allow more than the robot's model states (its URDF's <limit effort "
                      "velocity>): joint_speed (rad/s): 'shoulder' 2 > 1, 'elbow' 2 > 1; the plan uses them as given"]
    # a URDF that states none: the flag to give
    urdf, params = model_files
    bare = tmp_path / "bare.urdf"
    bare.write_text(re.sub(r"<limit[^>]*/>", "", urdf.read_text()))
    line = cli_error(["plan", str(bare), "--params", str(params), "--locked-joints", "finger_slide", "--goal", "0.5",
                      "--motor-torque", "5", "--out", str(tmp_path / "c")], capsys)
    assert line == "--joint-speed: the URDF states no velocity limit (<limit velocity=\"…\">) for shoulder, elbow; give --joint-speed"



def test_every_limit_a_plan_respects_is_plotted_against_it_scaled_to_the_data(plan_figures, model_files, tmp_path):
    # `orbitflex plan` on panda: joint speed bound and no plot showed the speeds; the torque plot
    # drew the torques at 1 % of its scale, every curve flat
    for base in ("held", "free"):
        c = plan_figures[(base, "comparison")]
        for name, values, limits in (("plan_joint_speed.png", c.plan.qd, c.plan.limits.joint_speed),
                                     ("plan_motor_torque.png", c.plan.u, c.plan.limits.motor_torque)):
            axes = [ax for ax in plan_figures[(base, name)].axes if ax.get_visible()]
            assert len(axes) == 2
            for i, ax in enumerate(axes):
                peak, limit = float(np.abs(values[:, i]).max()), float(np.broadcast_to(limits, (2,))[i])
                low, high = ax.get_ylim()
                dashed = [line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == "--"]
                assert f"peak {peak:.3g} of {limit:.3g}" in ax.get_title(), ax.get_title()
                if peak >= 0.5 * limit:  # near it: the limit in view
                    assert sorted(dashed) == [-limit, limit] and high == pytest.approx(1.15 * limit)
                else:  # far below: the data fill the panel, the limit is named
                    assert dashed == [] and high == pytest.approx(1.15 * peak) and "limit off scale" in ax.get_title()
                assert -low == high and high >= peak
    # the free plan is bound by the 1 rad/s of a joint speed: shown against it
    c = plan_figures[("free", "comparison")]
    speed = [ax for ax in plan_figures[("free", "plan_joint_speed.png")].axes if ax.get_visible()]
    bound = [ax for ax in speed if "binds" in ax.get_title()]
    assert any(b["limit"] == "joint_speed" for b in c.plan.bindings) == bool(bound)


def test_a_torque_bar_chart_far_below_its_limit_is_scaled_to_the_bars(tmp_path):
    # the demo's slew under the URDF's limits peaks at 4 % of the motor torque limits
    from test_cli import run_cli

    import matplotlib

    matplotlib.use("Agg")
    arm = FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    plan = plan_slew(arm, GOAL, base="free")
    comparison = cli.compare("space_arm", plan, 1e-3, np.full(7, KP), np.full(7, KD), 0.5)
    kept = {}
    original = cli.Figures.save
    cli.Figures.save = lambda self, fig, name: kept.__setitem__(name, fig)
    try:
        cli.plot_plan_vs_rigid(cli.Figures(tmp_path, "caption"), comparison)
    finally:
        cli.Figures.save = original
    bars = kept["plan_vs_rigid.png"].axes[0]
    top = max(patch.get_height() for patch in bars.patches)
    assert top < 5 and bars.get_ylim()[1] == pytest.approx(1.45 * top)
    assert not [line for line in bars.get_lines() if line.get_ydata()[0] == 100]
    assert f"all under {top:.3g} % of their limits (100 %: off this scale)" in bars.get_title()
    matplotlib.pyplot.close(kept["plan_vs_rigid.png"])
