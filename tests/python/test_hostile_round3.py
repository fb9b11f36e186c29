"""Hostile input, round 3 (issue 24): the cases that do not belong to a surface of their own
(threads, interrupts, overflow, memory, the page, planning and campaigns have their own files),
and the ones found by trying more of the same."""

from __future__ import annotations

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, ModelError, MotorPD

ROBOT = orbitflex.models.space_arm()
ARM = FlexibleArm(ROBOT, orbitflex.models.space_arm_joints())
N = ROBOT.dof


# ---- batch inputs given as buffers ----------------------------------------------------------------


def test_batch_torques_given_as_a_memoryview_are_an_array():
    # u=memoryview(array) raised numpy's "NotImplementedError: multi-dimensional sub-views are
    # not implemented", while a memoryview x0s was accepted
    u = np.linspace(0, 1, 3 * N).reshape(3, N)
    x0s = np.stack([ARM.state()] * 3)
    as_buffer = orbitflex.simulate_batch(ARM, memoryview(x0s), 1e-3, 20, u=memoryview(u))
    as_array = orbitflex.simulate_batch(ARM, x0s, 1e-3, 20, u=u)
    np.testing.assert_array_equal(as_buffer.x, as_array.x)
    # a list of MotorPD is still one controller per run
    pds = [MotorPD(100.0, 10.0, np.zeros(N)) for _ in range(3)]
    assert orbitflex.simulate_batch(ARM, x0s, 1e-3, 5, u=pds).ok.all()


# ---- a heavy bus ------------------------------------------------------------------------------


@pytest.mark.parametrize("mass", [1e10, 1e15])
def test_a_heavy_bus_is_a_legitimate_model_and_holds_the_arm_still(mass):
    # with_base_inertia(1e10, [1e10]*3) was refused: "joint 'wrist_roll' moves links with no
    # inertia about its axis (wrist_roll_link)" (the check was relative to the whole model)
    heavy = ROBOT.with_base_inertia(mass, [mass] * 3)
    rng = np.random.default_rng(24)
    q, qd, tau = rng.normal(size=N), 0.3 * rng.normal(size=N), rng.normal(size=N)
    acc = heavy.forward_dynamics(q, np.zeros(6), qd, tau)
    # a near-held base: the joints move as on a fixed base, M_r q̈ = τ − C_r, up to the base's
    # share of the motion, O(m_arm / m_bus) relative (86 kg against the bus)
    m = heavy.mass_matrix(q)
    c = heavy.bias_forces(q, np.zeros(6), qd)
    fixed = np.linalg.solve(m[6:, 6:], tau - c[6:])
    assert np.abs(acc[6:] - fixed).max() <= 1e3 * 86.0 / mass * np.abs(fixed).max()
    assert np.abs(acc[:6]).max() < 1e3 * 86.0 / mass * np.abs(fixed).max()


def test_links_with_no_inertia_about_their_axis_are_still_refused():
    # the check is relative to each joint's own links now: a point mass on the axis has none
    xml = """<robot name="r"><link name="b"><inertial><mass value="1e10"/><inertia ixx="1e10" iyy="1e10" izz="1e10" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <joint name="j" type="revolute"><parent link="b"/><child link="l"/><axis xyz="0 0 1"/></joint>
      <link name="l"><inertial><mass value="1"/><inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"""
    with pytest.raises(ModelError, match=r"joint 'j' moves links with no inertia about its axis \(l\)"):
        orbitflex.Robot.from_urdf_string(xml)


# ---- found by trying ----------------------------------------------------------------------------


@pytest.mark.parametrize("call", ["simulate", "simulate_batch"])
def test_a_count_past_the_largest_is_not_called_below_one(call):
    # record_every=10**30 said "expected an integer >= 1, given 10**30"
    with pytest.raises(ModelError, match=r"record_every: expected an integer from 1 to 18446744073709551615, given "
                                         r"1000000000000000000000000000000"):
        if call == "simulate":
            ARM.simulate(ARM.state(), 1e-3, 5, record_every=10**30)
        else:
            orbitflex.simulate_batch(ARM, ARM.state(), 1e-3, 5, record_every=10**30)
