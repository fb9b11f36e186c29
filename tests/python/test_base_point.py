"""Held base moment bounds about the system centre of mass (``Limits(base_point="com")``).

A held base's holding wrench is ``[n_B; F_B]`` about the base origin (base frame). About the
system COM ``C``, at ``r_c(q)`` from the origin, the same wrench has the moment
``n_C = n_B − r_c × F_B`` (a force F at P: ``(P − B) × F`` about B, ``(P − C) × F`` about C).

Checked here: a closed form (a link turning about a joint on the bus's z axis: about the origin
the holding moment is ``(I_l + m l²) q̈``, about the system COM ``(I_l + μ l²) q̈`` with the
reduced mass ``μ = m M/(M + m)``); on a three-joint arm, tilted and offset, against Pinocchio's
``centerOfMass`` (free-flyer at identity, so its world frame is the base frame), the plan keeps
every ``|n_C,k|`` and ``|n_C|`` within its bound and the binding one at it, and the binding names
the point; ``"origin"`` is the default, bit for bit; a free-floating plan refuses ``"com"`` and
says why. Tolerances as in test_base_limits.py: the duration bisected to 1e-10, the samples refined
onto each peak to O(h³), 1e-7 for both."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import orbitflex as of

pin = pytest.importorskip("pinocchio")

SIGMA2 = 2520.0 * (3.0 / 14.0) ** 3 / np.sqrt(7.0)
LOOSE = dict(motor_torque=1e6, joint_speed=1e3)
TOL = 1e-7
M_BUS, M_LINK, L, I_LINK = 100.0, 10.0, 0.5, 0.2
ONE_LINK = f"""<robot name="one_link">
<link name="bus"><inertial><origin xyz="0 0 0"/><mass value="{M_BUS}"/>
  <inertia ixx="30" iyy="40" izz="50" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="j" type="revolute"><parent link="bus"/><child link="link"/><origin xyz="0 0 0"/>
  <axis xyz="0 0 1"/><limit effort="1e6" velocity="1e3" lower="-10" upper="10"/></joint>
<link name="link"><inertial><origin xyz="{L} 0 0"/><mass value="{M_LINK}"/>
  <inertia ixx="0.1" iyy="{I_LINK}" izz="{I_LINK}" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>"""
THREE = """<robot name="three">
<link name="bus"><inertial><origin xyz="0.05 -0.02 0.1"/><mass value="80"/>
  <inertia ixx="30" iyy="40" izz="50" ixy="1" ixz="0" iyz="2"/></inertial></link>
<joint name="a" type="revolute"><parent link="bus"/><child link="l1"/><origin xyz="0.3 0 0.5" rpy="0.4 0.2 0"/>
  <axis xyz="0 0 1"/><limit effort="1e6" velocity="1e3" lower="-10" upper="10"/></joint>
<link name="l1"><inertial><origin xyz="0.3 0.05 0.1"/><mass value="6"/>
  <inertia ixx="0.5" iyy="0.6" izz="0.4" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="b" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.6 0 0.1" rpy="0 0.3 0.1"/>
  <axis xyz="0 1 0"/><limit effort="1e6" velocity="1e3" lower="-10" upper="10"/></joint>
<link name="l2"><inertial><origin xyz="0.4 0 0"/><mass value="5"/>
  <inertia ixx="0.2" iyy="0.5" izz="0.5" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="c" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0.8 0 0"/>
  <axis xyz="1 0 0"/><limit effort="1e6" velocity="1e3" lower="-10" upper="10"/></joint>
<link name="l3"><inertial><origin xyz="0.1 0.2 0"/><mass value="3"/>
  <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>"""
GOAL = [1.0, -0.8, 1.3]


def arm_of(urdf):
    robot = of.Robot.from_urdf_string(urdf)
    n = robot.dof
    return of.FlexibleArm(robot, of.FlexibleJoints([1e4] * n, motor_inertia=[0.5] * n))


def about_com(plan, urdf):
    """``n_C = n_B − r_c × F_B`` at every sample, ``r_c`` from Pinocchio."""
    model = pin.buildModelFromXML(urdf, pin.JointModelFreeFlyer())
    data = model.createData()
    wrench = plan.base_wrench
    out = np.empty((len(plan.t), 3))
    for k, q in enumerate(plan.q):
        qp = pin.neutral(model)
        for name, qi in zip(plan.arm.robot.joint_names, q):
            qp[model.joints[model.getJointId(name)].idx_q] = qi
        r_c = pin.centerOfMass(model, data, qp)
        out[k] = wrench[k, :3] - np.cross(r_c, wrench[k, 3:])
    return out


@pytest.mark.parametrize("point, inertia", [
    ("origin", I_LINK + M_LINK * L**2),
    ("com", I_LINK + M_LINK * M_BUS / (M_BUS + M_LINK) * L**2),
])
def test_one_link_moment_closed_form(point, inertia):
    arm, delta, limit = arm_of(ONE_LINK), 1.2, 0.8
    for limits in (of.Limits(**LOOSE, base_torque_axes=[1e3, 1e3, limit], base_point=point),
                   of.Limits(**LOOSE, base_torque=limit, base_point=point)):
        plan = of.plan_slew(arm, [delta], limits=limits, base="held")
        assert plan.duration == pytest.approx(np.sqrt(inertia * delta * SIGMA2 / limit), rel=TOL)
        b = plan.binding
        assert b["point"] == point and b["value"] == pytest.approx(limit, rel=TOL)
        assert (b["limit"], b["axis"]) in (("base_torque_axes", 2), ("base_torque", None))


@pytest.mark.parametrize("key", ["base_torque_axes", "base_torque"])
def test_a_three_joint_plan_respects_the_com_moment_and_binds_on_it(key):
    arm = arm_of(THREE)
    loose = of.plan_slew(arm, GOAL, limits=of.Limits(1e6, 0.5), base="held")
    n_c = about_com(loose, THREE)
    peaks = np.abs(n_c).max(axis=0) if key == "base_torque_axes" else np.linalg.norm(n_c, axis=1).max()
    # about the origin the moment is different: the option matters on this arm
    assert not np.allclose(np.abs(loose.base_wrench[:, :3]).max(axis=0), np.abs(n_c).max(axis=0), rtol=0.05)
    bounds = 0.6 * peaks * (np.array([1.0, 0.9, 1.1]) if key == "base_torque_axes" else 1.0)
    plan = of.plan_slew(arm, GOAL, limits=of.Limits(1e6, 0.5, base_point="com", **{key: bounds}), base="held")
    n_c = about_com(plan, THREE)
    reached = np.abs(n_c).max(axis=0) if key == "base_torque_axes" else np.linalg.norm(n_c, axis=1).max()
    assert np.all(reached <= bounds * (1 + TOL)), (reached, bounds)
    b = plan.binding
    assert b["limit"] == key and b["point"] == "com"
    bound = bounds[b["axis"]] if key == "base_torque_axes" else bounds
    assert b["value"] == pytest.approx(bound, rel=TOL)
    assert (reached[b["axis"]] if key == "base_torque_axes" else reached) == pytest.approx(bound, rel=1e-6)
    assert plan.duration > loose.duration


def test_origin_is_the_default_bit_for_bit():
    arm = arm_of(THREE)
    given = dict(base_torque_axes=[3.0, 2.0, 4.0], base_torque=4.0, base_force_axes=30.0)
    plain = of.plan_slew(arm, GOAL, limits=of.Limits(1e6, 0.5, **given), base="held")
    origin = of.plan_slew(arm, GOAL, limits=of.Limits(1e6, 0.5, base_point="origin", **given), base="held")
    assert plain.duration == origin.duration and plain.binding == origin.binding
    assert np.array_equal(plain.base_wrench, origin.base_wrench) and np.array_equal(plain.t, origin.t)
    assert plain.binding["point"] in ("origin", None)
    assert of.plan_slew(arm, GOAL, limits=of.Limits(0.5, 0.5), base="held").binding["point"] is None


def test_a_free_base_refuses_the_com_and_bad_names_are_errors():
    arm = arm_of(ONE_LINK)
    with pytest.raises(ValueError, match=r'^limits.base_point: "com" names the point a held base.s moment bounds'
                       r".*the system COM stays still"):
        of.plan_slew(arm, [1.0], limits=of.Limits(**LOOSE, base_rate=0.1, base_point="com"), base="free")
    with pytest.raises(ValueError, match=r'^base_point: expected "origin" .* or "com" .*, given "centre"'):
        of.Limits(**LOOSE, base_point="centre")


def test_limits_keep_their_point():
    limits = of.Limits(2.0, [0.1], base_torque_axes=3.0, base_point="com")
    assert limits.base_point == "com" and of.Limits(2.0, 0.1).base_point == "origin"
    again = pickle.loads(pickle.dumps(limits))
    assert repr(again) == repr(limits) and again.base_point == "com"
    assert repr(limits).endswith(', base_torque_axes=[3.0, 3.0, 3.0], base_point="com")')
    assert "base_point" not in repr(of.Limits(2.0, 0.1))
