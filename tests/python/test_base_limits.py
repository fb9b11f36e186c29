"""Base limits per axis (``Limits(base_torque_axes=, base_force_axes=, base_rate_axes=,
base_speed_axes=, base_rate=, base_speed=)``): closed forms on a rotor (a disc on a joint along
the bus's z axis, every centre of mass on that axis), and on a tilted, offset link the plan
respects each bound to its tolerance and is active on the binding one; misplaced bounds and bad
values are clear errors.

The rotor: bus inertia I_b (about z) and a disc I_l (about its axis), both centres of mass on the
z axis. Free floating from rest, angular momentum about z stays zero, I_b ω + I_l (ω + q̇) = 0, so
ω_z = −I_l/(I_b + I_l) q̇ and the bus does not translate; held, the moment holding it is
n_z = I_l q̈ (the spring passes the disc's inertia torque to the bus; the motor's rotor turns
inside it and its reaction cancels). The planner's path q = Δ σ(t/T) has σ'max = 630/256 (at
s = 1/2, a sample) and σ''max = 2520 (3/14)³/√7 (at s = (1 − 1/√7)/2), so
T_rate = r Δ σ'max / L and T_torque = √(I_l Δ σ''max / L). The planner bisects the duration to
1e-10 and refines its samples onto each peak (to a parabola's vertex: error O(h³) of a sample
spacing h = 1/512 at most 1e-8 of the peak); 1e-7 bounds both."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import orbitflex as of

I_B, I_L = 50.0, 3.0
ROTOR = f"""<robot name="rotor">
<link name="bus"><inertial><origin xyz="0 0 0"/><mass value="100"/>
  <inertia ixx="30" iyy="40" izz="{I_B}" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="j" type="revolute"><parent link="bus"/><child link="disc"/><origin xyz="0 0 0.5"/>
  <axis xyz="0 0 1"/><limit effort="1e6" velocity="1e3" lower="-10" upper="10"/></joint>
<link name="disc"><inertial><origin xyz="0 0 0.2"/><mass value="10"/>
  <inertia ixx="2" iyy="2" izz="{I_L}" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>"""
OFFSET = """<robot name="offset">
<link name="bus"><inertial><origin xyz="0 0 0"/><mass value="100"/>
  <inertia ixx="30" iyy="40" izz="50" ixy="1" ixz="0" iyz="2"/></inertial></link>
<joint name="j" type="revolute"><parent link="bus"/><child link="arm"/><origin xyz="0.3 0 0.5" rpy="0.4 0.2 0"/>
  <axis xyz="0 0 1"/><limit effort="1e6" velocity="1e3" lower="-10" upper="10"/></joint>
<link name="arm"><inertial><origin xyz="0.6 0.1 0.2"/><mass value="10"/>
  <inertia ixx="1" iyy="2" izz="2.5" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>"""
SIGMA1 = 630.0 / 256.0
SIGMA2 = 2520.0 * (3.0 / 14.0) ** 3 / np.sqrt(7.0)
LOOSE = dict(motor_torque=1e6, joint_speed=1e3)
TOL = 1e-7


def arm_of(urdf):
    return of.FlexibleArm(of.Robot.from_urdf_string(urdf), of.FlexibleJoints([1e4], motor_inertia=[0.5]))


def test_sigma_peaks_are_the_closed_forms():
    s = np.linspace(0.0, 1.0, 200001)
    d1 = 630 * s**4 * (1 - s) ** 4
    d2 = 2520 * s**3 * (1 - s) ** 3 * (1 - 2 * s)
    assert d1.max() == pytest.approx(SIGMA1, rel=1e-14)
    assert np.abs(d2).max() == pytest.approx(SIGMA2, rel=1e-9)   # the grid's nearest point


@pytest.mark.parametrize("delta", [1.0, -0.4])
def test_free_rotor_bus_rate_closed_form(delta):
    arm, limit = arm_of(ROTOR), 0.01
    expected = I_L / (I_B + I_L) * abs(delta) * SIGMA1 / limit
    for limits in (of.Limits(**LOOSE, base_rate_axes=[1.0, 1.0, limit]), of.Limits(**LOOSE, base_rate=limit)):
        plan = of.plan_slew(arm, [delta], limits=limits, base="free")
        assert plan.duration == pytest.approx(expected, rel=TOL)
        b = plan.binding
        assert b["value"] == pytest.approx(limit, rel=TOL) and b["joint"] is None
        assert (b["limit"], b["axis"]) in (("base_rate_axes", 2), ("base_rate", None))
        twist = np.abs(plan.base_twist).max(axis=0)
        assert twist[2] <= limit * (1 + TOL) and np.all(twist[[0, 1, 3, 4, 5]] < 1e-12)


def test_held_rotor_moment_closed_form():
    arm, limit = arm_of(ROTOR), 2.0
    plan = of.plan_slew(arm, [1.0], limits=of.Limits(**LOOSE, base_torque_axes=[1e3, 1e3, limit]), base="held")
    assert plan.duration == pytest.approx(np.sqrt(I_L * SIGMA2 / limit), rel=TOL)
    assert plan.binding["limit"] == "base_torque_axes" and plan.binding["axis"] == 2
    assert np.abs(plan.base_wrench[:, 2]).max() == pytest.approx(limit, rel=TOL)


@pytest.mark.parametrize("base, key, column", [
    ("held", "base_torque_axes", slice(0, 3)), ("held", "base_force_axes", slice(3, 6)),
    ("free", "base_rate_axes", slice(0, 3)), ("free", "base_speed_axes", slice(3, 6)),
])
def test_each_axis_is_respected_and_the_binding_one_is_active(base, key, column):
    """A tilted joint with an offset link moves the bus on every axis: bound each axis at 60 %
    of its peak under a loose plan; the plan respects all three, and the one it reports
    binding is at its bound."""
    arm = arm_of(OFFSET)
    free_run = of.plan_slew(arm, [1.2], limits=of.Limits(1e6, 0.5), base=base)
    table = free_run.base_wrench if base == "held" else free_run.base_twist
    peaks = np.abs(table[:, column]).max(axis=0)
    assert np.all(peaks > 0)
    bounds = 0.6 * peaks * np.array([1.0, 0.9, 1.1])
    plan = of.plan_slew(arm, [1.2], limits=of.Limits(1e6, 0.5, **{key: bounds}), base=base)
    table = plan.base_wrench if base == "held" else plan.base_twist
    reached = np.abs(table[:, column]).max(axis=0)
    assert np.all(reached <= bounds * (1 + TOL)), (reached, bounds)
    b = plan.binding
    assert b["limit"] == key and b["value"] == pytest.approx(bounds[b["axis"]], rel=TOL)
    assert reached[b["axis"]] == pytest.approx(bounds[b["axis"]], rel=1e-6)
    assert plan.duration > free_run.duration


def test_misplaced_and_bad_bounds_are_named():
    arm = arm_of(ROTOR)
    with pytest.raises(ValueError, match=r"^limits.base_rate_axes: bounds the motion of a free-floating base; a held"):
        of.plan_slew(arm, [1.0], limits=of.Limits(**LOOSE, base_rate_axes=0.1), base="held")
    with pytest.raises(ValueError, match=r"^limits.base_force_axes: bounds the wrench that holds a held base"):
        of.plan_slew(arm, [1.0], limits=of.Limits(**LOOSE, base_force_axes=[1, 2, 3]), base="free")
    with pytest.raises(ValueError, match=r"^base_speed_axes\[2\]: expected a finite limit > 0 \(base-frame z axis\), given -1"):
        of.Limits(**LOOSE, base_speed_axes=[1.0, 1.0, -1.0])
    with pytest.raises(ValueError, match=r"^base_torque_axes: expected length 3, given length 2$"):
        of.Limits(**LOOSE, base_torque_axes=[1.0, 2.0])
    with pytest.raises(ValueError, match=r"^base_rate: expected a finite limit > 0, given inf"):
        of.Limits(**LOOSE, base_rate=np.inf)


def test_limits_keep_their_base_bounds():
    limits = of.Limits(2.0, [0.1], base_torque_axes=3.0, base_speed=0.2, base_rate_axes=[0.1, 0.2, 0.3])
    assert limits.base_torque_axes == [3.0, 3.0, 3.0] and limits.base_speed == 0.2
    assert limits.base_rate_axes == [0.1, 0.2, 0.3] and limits.base_force_axes is None and limits.base_rate is None
    again = pickle.loads(pickle.dumps(limits))
    assert repr(again) == repr(limits)
    assert "base_torque_axes=[3.0, 3.0, 3.0]" in repr(limits) and "base_speed=0.2" in repr(limits)
