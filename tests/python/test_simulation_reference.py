"""An independent reference of the flexible-joint simulator (model §3-§5), in numpy + ``pin.aba``.

The reference is written from docs/model.md alone:
- spring torque ``τ = k (θ − q) + d (θ̇ − q̇)``; motor ``θ̈ = (u − τ − β θ̇) / j``;
- rigid dynamics from Pinocchio's ABA (free-flyer, zero gravity), turned into orbitflex's
  classical base acceleration ``α_B = [ω̇; a_lin + ω × v]``, then, exactly as model §4,
  ``ω̇_B = α_B[0:3]`` and ``v̇_B = α_B[3:6] − ω_B × v_B``;
- ``ṙ_B = R_B v_B`` (``R_B`` the rotation of the normalised quaternion),
  ``quat' = ½ quat ⊗ (ω_B, 0)`` (Hamilton product, x, y, z, w);
- classic RK4 with inputs held over the step, the quaternion renormalised after each step; a
  controller sees the state and time at the START of the step.

It is compared with ``FlexibleArm.derivative``/``step``/``simulate`` on robots not used elsewhere
for tuning: ur5 (example-robot-data) and a held-out random chain. Both sides integrate the same
equations with the same RK4, so they must agree to round-off (1e-9 relative).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import orbitflex
from conftest import SIM_CHAIN_SEED, chain_case, erd_case
from pin_helpers import quat_to_matrix, random_quaternion, rel_err

TOL = 1e-9

# A stability warning here would be spurious (dt is far below the limit): make it an error.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")


# ------------------------------------------------------------------------------- the reference


def quat_mul(p, q):
    """Hamilton product p ⊗ q, both (x, y, z, w)."""
    pv, pw = np.asarray(p[:3]), p[3]
    qv, qw = np.asarray(q[:3]), q[3]
    vec = pw * qv + qw * pv + np.cross(pv, qv)
    return np.concatenate([vec, [pw * qw - pv @ qv]])


class ReferenceArm:
    """model §3-§5 on top of Pinocchio (``pr`` is a pin_helpers.PinRobot)."""

    def __init__(self, pr, k, j, d, beta):
        self.pr = pr
        self.n = pr.n
        self.k, self.j, self.d, self.beta = (np.broadcast_to(np.asarray(a, float), (pr.n,)) for a in (k, j, d, beta))

    def split(self, x):
        n = self.n
        return dict(
            r=x[0:3], quat=x[3:7], q=x[7 : 7 + n], theta=x[7 + n : 7 + 2 * n],
            w=x[7 + 2 * n : 10 + 2 * n], v=x[10 + 2 * n : 13 + 2 * n],
            qd=x[13 + 2 * n : 13 + 3 * n], theta_dot=x[13 + 3 * n : 13 + 4 * n],
        )

    def derivative(self, x, u, base_wrench, ee_wrench):
        s = self.split(np.asarray(x, dtype=float))
        tau = self.k * (s["theta"] - s["q"]) + self.d * (s["theta_dot"] - s["qd"])
        twist = np.concatenate([s["w"], s["v"]])
        # [α_B; q̈] in orbitflex's convention (classical α_B), from Pinocchio's ABA.
        acc = self.pr.forward_dynamics(s["q"], twist, s["qd"], tau, base_wrench, ee_wrench)
        alpha, qdd = acc[:6], acc[6:]
        w_dot = alpha[:3]
        v_dot = alpha[3:] - np.cross(s["w"], s["v"])
        theta_ddot = (u - tau - self.beta * s["theta_dot"]) / self.j
        r_dot = quat_to_matrix(s["quat"]) @ s["v"]
        quat_dot = 0.5 * quat_mul(s["quat"], np.concatenate([s["w"], [0.0]]))
        return np.concatenate([r_dot, quat_dot, s["qd"], s["theta_dot"], w_dot, v_dot, qdd, theta_ddot])

    def step(self, x, dt, u, base_wrench, ee_wrench):
        f = lambda y: self.derivative(y, u, base_wrench, ee_wrench)  # noqa: E731
        k1 = f(x)
        k2 = f(x + 0.5 * dt * k1)
        k3 = f(x + 0.5 * dt * k2)
        k4 = f(x + dt * k3)
        out = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        out[3:7] /= np.linalg.norm(out[3:7])
        return out

    def simulate(self, x0, dt, steps, controller, base_wrench, ee_wrench):
        """``controller(k, t, x) -> u``; wrenches: functions of the step index."""
        xs = [np.array(x0, dtype=float)]
        for k in range(steps):
            x = xs[-1]
            u = controller(k, k * dt, x)
            xs.append(self.step(x, dt, u, base_wrench(k), ee_wrench(k)))
        return np.array(xs)

    def energy(self, x):
        s = self.split(x)
        twist = np.concatenate([s["w"], s["v"]])
        kinetic = self.pr.kinetic_energy(s["q"], twist, s["qd"])
        defl = s["theta"] - s["q"]
        return kinetic + 0.5 * np.sum(self.j * s["theta_dot"] ** 2) + 0.5 * np.sum(self.k * defl**2)


# ------------------------------------------------------------------------------- fixtures


def _setup(case, salt):
    robot, pr = case.load()
    n = robot.dof
    rng = case.rng(salt)
    # Stiffness and motor inertia keep the stiffest mode far inside RK4's limit at dt = 1 ms
    # (checked: simulate must not warn, see pytestmark).
    k = rng.uniform(200.0, 800.0, n)
    j = rng.uniform(0.05, 0.2, n)
    d = rng.uniform(0.5, 3.0, n)
    beta = rng.uniform(0.1, 1.0, n)
    joints = orbitflex.FlexibleJoints(k, j, damping=d, motor_damping=beta)
    init = dict(
        q=rng.uniform(-1.5, 1.5, n),
        theta=None,
        qd=rng.normal(0.0, 0.8, n),
        theta_dot=rng.normal(0.0, 0.8, n),
        base_pose=np.concatenate([rng.normal(0.0, 1.0, 3), random_quaternion(rng)]),
        base_twist=rng.normal(0.0, 0.4, 6),
    )
    init["theta"] = init["q"] + rng.normal(0.0, 0.02, n)
    return robot, pr, joints, ReferenceArm(pr, k, j, d, beta), init, rng


def _x_manual(init):
    """The state vector laid out by hand from model §4."""
    return np.concatenate(
        [init["base_pose"], init["q"], init["theta"], init["base_twist"], init["qd"], init["theta_dot"]]
    )


SIM_CASES = {
    "ur5": lambda: erd_case("ur5"),
    f"chain{SIM_CHAIN_SEED}": lambda: chain_case(SIM_CHAIN_SEED),
}


@pytest.fixture(scope="module", params=list(SIM_CASES))
def sim(request):
    case = SIM_CASES[request.param]()
    return (case, *_setup(case, "sim"))


# ------------------------------------------------------------------------------- tests


def test_state_layout(sim):
    case, robot, pr, joints, ref, init, rng = sim
    arm = orbitflex.FlexibleArm(robot, joints)
    x = arm.state(**init)
    assert x.shape == (13 + 4 * robot.dof,)
    assert rel_err(x, _x_manual(init)) <= 1e-15


@pytest.mark.parametrize("method", ["recursive", "operator"])
def test_derivative_and_step(sim, method):
    case, robot, pr, joints, ref, init, rng = sim
    arm = orbitflex.FlexibleArm(robot, joints, method=method)
    n = robot.dof
    x = _x_manual(init)
    for _ in range(3):
        u = rng.normal(0.0, 20.0, n)
        fb = rng.normal(0.0, 50.0, 6)
        f = rng.normal(0.0, 10.0, 6)
        xd = arm.derivative(x, u=u, base_wrench=fb, ee_wrench=f)
        ref_xd = ref.derivative(x, u, fb, f)
        err = rel_err(xd, ref_xd)
        assert err <= TOL, f"derivative: rel err {err:.3e}\n{xd - ref_xd}"
        # Without inputs, the defaults must be zeros.
        assert rel_err(arm.derivative(x), ref.derivative(x, np.zeros(n), np.zeros(6), np.zeros(6))) <= TOL
        xs = arm.step(x, 2e-3, u=u, base_wrench=fb, ee_wrench=f)
        ref_xs = ref.step(x, 2e-3, u, fb, f)
        assert rel_err(xs, ref_xs) <= TOL
        assert abs(np.linalg.norm(xs[3:7]) - 1.0) < 1e-14
        x = ref_xs


def _inputs(robot, rng, steps, dt):
    n = robot.dof
    t = np.arange(steps) * dt
    freq = rng.uniform(1.0, 6.0, n)
    amp = rng.uniform(5.0, 30.0, n)
    u_table = amp * np.sin(np.outer(t, freq) * 2 * np.pi + rng.uniform(0, 6, n))
    fb_table = rng.normal(0.0, 30.0, 6) * np.cos(np.outer(t, rng.uniform(1.0, 4.0, 6)) * 2 * np.pi)
    f_const = rng.normal(0.0, 8.0, 6)
    return u_table, fb_table, f_const


STEPS = 400
DT = 1e-3


def test_simulate_table_inputs(sim):
    """Time-varying u and base wrench tables, constant EE wrench, damping on, velocities non-zero."""
    case, robot, pr, joints, ref, init, rng = sim
    arm = orbitflex.FlexibleArm(robot, joints)
    u_table, fb_table, f_const = _inputs(robot, case.rng("tables"), STEPS, DT)
    x0 = arm.state(**init)
    traj = arm.simulate(x0, DT, STEPS, u=u_table, base_wrench=fb_table, ee_wrench=f_const)
    xs = ref.simulate(x0, DT, STEPS, lambda k, t, x: u_table[k], lambda k: fb_table[k], lambda k: f_const)
    assert traj.x.shape == xs.shape
    assert np.allclose(traj.t, np.arange(STEPS + 1) * DT, rtol=0, atol=1e-12)
    errs = [rel_err(a, b) for a, b in zip(traj.x, xs)]
    worst = int(np.argmax(errs))
    assert errs[worst] <= TOL, f"step {worst}: rel err {errs[worst]:.3e}"
    # The run must actually have gone somewhere (not a trivially equal standstill).
    assert rel_err(traj.x[-1], traj.x[0]) > 1e-2
    # Diagnostics along the trajectory against Pinocchio / the reference.
    for k in (0, STEPS // 2, STEPS):
        s = ref.split(xs[k])
        twist = np.concatenate([s["w"], s["v"]])
        base_pose = np.concatenate([s["r"], s["quat"]])
        assert rel_err(traj.momentum[k], pr.momentum(base_pose, s["q"], twist, s["qd"])) <= TOL
        assert abs(traj.energy[k] - ref.energy(xs[k])) / max(1.0, abs(ref.energy(xs[k]))) <= TOL
        oMf = pr.ee_placement(s["q"], base_pose)
        assert rel_err(traj.ee_pose[k, :3], oMf.translation) <= TOL
        quat_ref = pin.Quaternion(oMf.rotation).coeffs()  # (x, y, z, w)
        quat = traj.ee_pose[k, 3:]
        assert min(rel_err(quat, quat_ref), rel_err(quat, -quat_ref)) <= TOL


def test_simulate_operator_method(sim):
    """The dense operator form drives the same simulation (shorter run: O(n³) per call)."""
    case, robot, pr, joints, ref, init, rng = sim
    steps = 60
    arm = orbitflex.FlexibleArm(robot, joints, method="operator")
    u_table, fb_table, f_const = _inputs(robot, case.rng("operator"), steps, DT)
    x0 = arm.state(**init)
    traj = arm.simulate(x0, DT, steps, u=u_table, base_wrench=fb_table, ee_wrench=f_const)
    xs = ref.simulate(x0, DT, steps, lambda k, t, x: u_table[k], lambda k: fb_table[k], lambda k: f_const)
    assert max(rel_err(a, b) for a, b in zip(traj.x, xs)) <= TOL


def test_callable_equals_table(sim):
    """A callable returning the table row is the table; it is called once per step at the start."""
    case, robot, pr, joints, ref, init, rng = sim
    steps = 150
    arm = orbitflex.FlexibleArm(robot, joints)
    u_table, fb_table, f_const = _inputs(robot, case.rng("callable"), steps, DT)
    x0 = arm.state(**init)
    calls = []

    def u_fn(t, x):
        calls.append((t, np.array(x)))
        return u_table[len(calls) - 1]

    traj_fn = arm.simulate(x0, DT, steps, u=u_fn, base_wrench=fb_table, ee_wrench=f_const)
    traj_tab = arm.simulate(x0, DT, steps, u=u_table, base_wrench=fb_table, ee_wrench=f_const)
    assert len(calls) == steps
    assert np.array_equal(traj_fn.x, traj_tab.x)
    for k, (t, x) in enumerate(calls):
        assert t == pytest.approx(k * DT, abs=1e-12)
        assert np.array_equal(x, traj_fn.x[k]), f"callable saw a state other than the start of step {k}"


def test_state_feedback_callable_and_motor_pd(sim):
    """Motor PD as MotorPD (Rust), as a Python callable, and in the reference, all agree."""
    case, robot, pr, joints, ref, init, rng = sim
    n = robot.dof
    steps = 300
    r = case.rng("pd")
    kp = r.uniform(20.0, 80.0, n)
    kd = r.uniform(1.0, 5.0, n)
    t = np.arange(steps) * DT
    theta_ref = init["q"] + 0.3 * np.sin(np.outer(t, r.uniform(1.0, 3.0, n)) * 2 * np.pi)
    theta_dot_ref = r.normal(0.0, 0.2, n)
    feedforward = r.normal(0.0, 3.0, (steps, n))
    _, fb_table, f_const = _inputs(robot, r, steps, DT)

    def law(k, x):
        s = ref.split(x)
        return kp * (theta_ref[k] - s["theta"]) + kd * (theta_dot_ref - s["theta_dot"]) + feedforward[k]

    arm = orbitflex.FlexibleArm(robot, joints)
    x0 = arm.state(**init)
    pd = orbitflex.MotorPD(kp, kd, theta_ref, theta_dot_ref=theta_dot_ref, feedforward=feedforward)
    traj_pd = arm.simulate(x0, DT, steps, u=pd, base_wrench=fb_table, ee_wrench=f_const)
    step_of = {}

    def u_fn(tt, x):
        k = int(round(tt / DT))
        step_of[k] = True
        return law(k, x)

    traj_fn = arm.simulate(x0, DT, steps, u=u_fn, base_wrench=fb_table, ee_wrench=f_const)
    assert sorted(step_of) == list(range(steps))
    xs = ref.simulate(x0, DT, steps, lambda k, tt, x: law(k, x), lambda k: fb_table[k], lambda k: f_const)
    for name, traj in (("MotorPD", traj_pd), ("callable", traj_fn)):
        errs = [rel_err(a, b) for a, b in zip(traj.x, xs)]
        worst = int(np.argmax(errs))
        assert errs[worst] <= TOL, f"{name}: step {worst}: rel err {errs[worst]:.3e}"
    # The controller mattered: without it the run is different.
    free = arm.simulate(x0, DT, steps, base_wrench=fb_table, ee_wrench=f_const)
    assert rel_err(free.x[-1], xs[-1]) > 1e-3
