"""Finite inputs too large for floating point: a result that overflows is an error naming the
input that made it overflow, never arrays of inf and NaN (issue 24, "wrong numbers without an
error"). Each public call scans its result once, at the end."""

from __future__ import annotations

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, ModelError, MotorPD

ROBOT = orbitflex.models.space_arm()
N = ROBOT.dof
ARM = FlexibleArm(ROBOT, orbitflex.models.space_arm_joints())
Z, V0 = np.zeros(N), np.zeros(6)


def raises_naming(call, name: str, value: str):
    with pytest.raises(ModelError) as e:
        call()
    message = str(e.value)
    assert message.startswith(f"{name}: too large for floating point"), message
    assert f"= {value}" in message, message
    return message


# ---- the cases ----------------------------------------------------------------------------


def test_forward_dynamics_with_huge_rates_names_qd():
    # returned 13/13 NaN
    m = raises_naming(lambda: ROBOT.forward_dynamics(Z, V0, np.full(N, 1e200), Z), "qd", "1e200")
    assert "forward_dynamics overflowed (13 of its 13 numbers" in m
    raises_naming(lambda: ROBOT.forward_dynamics(Z, V0, np.full(N, 1e200), Z, method="operator"), "qd", "1e200")


def test_inverse_dynamics_with_a_huge_base_twist_names_it():
    raises_naming(lambda: ROBOT.inverse_dynamics(Z, np.full(6, 1e200), Z, V0, Z), "base_twist", "1e200")
    raises_naming(lambda: ROBOT.bias_forces(Z, np.full(6, 1e200), Z), "base_twist", "1e200")


def test_batched_calls_name_the_row():
    qd = np.zeros((3, N))
    qd[2, 4] = -1e200
    m = raises_naming(lambda: ROBOT.forward_dynamics(Z, V0, qd, Z), "qd (row 2)", "-1e200")
    assert "qd[4]" in m


@pytest.mark.parametrize("call", ["forward", "inverse"])
def test_derivatives_with_huge_rates_name_qd(call):
    # returned NaN in their blocks
    qd = np.full(N, 1e154)
    if call == "forward":
        raises_naming(lambda: ROBOT.forward_dynamics_derivatives(Z, V0, qd, Z), "qd", "1e154")
    else:
        raises_naming(lambda: ROBOT.inverse_dynamics_derivatives(Z, V0, qd, V0, Z), "qd", "1e154")


@pytest.mark.parametrize("call", ["linearize", "derivative_jacobians", "derivative"])
def test_flexible_calls_name_the_state_element(call):
    x = ARM.state(qd=np.full(N, 1e154))
    m = raises_naming(lambda: getattr(ARM, call)(x), "x", "1e154")
    assert "(qd[wrist_roll])" in m, m


def test_step_jacobians_with_a_huge_step_names_dt():
    # returned 1120 non-finite entries
    m = raises_naming(lambda: ARM.step_jacobians(ARM.state(), 1e300), "dt", "1e300")
    assert "step_jacobians overflowed" in m


def test_integrate_with_a_huge_tangent_names_dx():
    # returned a NaN quaternion
    raises_naming(lambda: ARM.integrate(ARM.state(), np.full(ARM.tangent_size, 1e300)), "dx", "1e300")


# ---- more of the same, found by trying -----------------------------------------------------------


def test_energies_and_momenta_that_overflow_are_errors():
    raises_naming(lambda: ROBOT.kinetic_energy(Z, V0, np.full(N, 1e200)), "qd", "1e200")
    raises_naming(lambda: ROBOT.momentum([0, 0, 0, 0, 0, 0, 1.0], Z, V0, np.full(N, 1e308)), "qd", "1e308")
    x = ARM.state(qd=np.full(N, 1e200))
    raises_naming(lambda: ARM.energy(x), "x", "1e200")


def test_difference_of_far_apart_states_names_the_state():
    far = ARM.state(base_pose=[1e308, 0, 0, 0, 0, 0, 1])
    back = ARM.state(base_pose=[-1e308, 0, 0, 0, 0, 0, 1])
    m = raises_naming(lambda: ARM.difference(far, back), "x0", "1e308")
    assert "(r_x)" in m


def test_stability_limit_of_an_overflowing_state_says_so():
    # it said "the linearised closed loop has no computable eigenvalues (the QR iteration did
    # not converge)", and simulate said the same before its first step
    x = ARM.state(qd=np.full(N, 1e200))
    raises_naming(lambda: ARM.rk4_stability_limit(x), "x", "1e200")
    raises_naming(lambda: ARM.simulate(x, 1e-3, 10), "x", "1e200")


def test_stability_limit_with_absurd_gains_names_the_gain():
    with pytest.raises(ModelError, match=r"^kp: too large for floating point: .* gains up to 1e300"):
        ARM.rk4_stability_limit(ARM.state(), MotorPD(1e300, 1e300, Z))
    # a stiff loop that can still be computed gets its (tiny) limit
    assert 0 < ARM.rk4_stability_limit(ARM.state(), MotorPD(1e300, 1.0, Z)).dt < 1e-100


def test_large_but_representable_inputs_still_compute():
    # the check looks at the result, not at the size of the inputs
    qd = np.full(N, 1e100)
    acc = ROBOT.forward_dynamics(Z, V0, qd, Z)
    assert np.isfinite(acc).all() and np.abs(acc).max() > 1e150
