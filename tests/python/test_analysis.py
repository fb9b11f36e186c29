"""Linear analysis (``arm.modes``, ``arm.frequency_response``, ``arm.state_space``,
``orbitflex.analysis.sweep``, ``orbitflex modes``): against numpy's ``eig`` of ``linearize``,
against Pinocchio's fixed-base derivatives for the held base, against the dense formula and a
simulated sine of the nonlinear model, and the exports to python-control and MATLAB."""

from __future__ import annotations

import json

import numpy as np
import pytest

import orbitflex
from orbitflex import analysis

pin = pytest.importorskip("pinocchio")


def space_arm(damping: float = 0.2, motor_damping: float = 1.0) -> orbitflex.FlexibleArm:
    robot = orbitflex.models.space_arm()
    k, j, _, _ = orbitflex.FlexibleArm(robot, orbitflex.models.space_arm_joints()).parameters
    return orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints(k, j, damping=damping, motor_damping=motor_damping))


def nearest(values: np.ndarray, target: complex) -> complex:
    return complex(values[np.argmin(np.abs(values - target))])


ARMS = {
    "space_arm": lambda: orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints()),
    "dual_arm": lambda: orbitflex.FlexibleArm(orbitflex.models.dual_arm(), orbitflex.models.dual_arm_joints()),
}


@pytest.mark.parametrize("name", sorted(ARMS))
@pytest.mark.parametrize("moving", [False, True])
def test_eigenvalues_equal_numpy_eig_of_linearize(name, moving):
    """Free base: every structural eigenvalue equals one of numpy's ``eig`` of the dense
    ``linearize`` to 1e-9 (relative to |λ|), free and clamped motors (clamped: the matrix without
    θ, θ̇), on a chain and a tree, at rest and moving. The rigid-body eigenvalues are defective
    (Jordan blocks at zero): both methods give them only to about √ε ‖F‖, so they are counted,
    not compared."""
    arm = ARMS[name]()
    n = arm.dof
    rng = np.random.default_rng(5)
    q = rng.uniform(-1, 1, n)
    x = arm.state(q=q, qd=rng.uniform(-0.3, 0.3, n) if moving else None,
                  base_twist=rng.uniform(-0.1, 0.1, 6) if moving else None)
    F, _ = arm.linearize(x)
    keep_clamped = np.r_[0:6 + n, 6 + 2 * n:12 + 3 * n]
    for motors, F_kept in (("free", F), ("clamped", F[np.ix_(keep_clamped, keep_clamped)])):
        m = arm.modes(x, motors=motors)
        reference = np.linalg.eigvals(F_kept)
        assert len(m.eigenvalues) == len(reference)
        lambdas = -m.damping_ratio * m.natural_frequency_hz * 2 * np.pi + 1j * m.frequency_hz * 2 * np.pi
        for lam in lambdas:
            assert abs(nearest(reference, lam) - lam) < 1e-9 * abs(lam), (motors, lam)
        assert m.rigid_body == (6 + n if motors == "free" else 6)


def held_state_matrix_from_pinocchio(arm, x, model):
    """``A`` of the held base from Pinocchio's fixed-base ABA derivatives: ``q̈ = ABA(q, q̇, τ)``
    with ``τ = k (θ − q) + d (θ̇ − q̇)`` chained in, and the motors' own rows."""
    n = arm.dof
    s = arm.state_slices
    q, theta, qd, td = x[s["q"]], x[s["theta"]], x[s["qd"]], x[s["theta_dot"]]
    k, j, d, beta = arm.parameters
    data = model.createData()
    order = [model.getJointId(name) - 1 for name in arm.robot.joint_names]
    perm = np.argsort(order)  # orbitflex joint i is Pinocchio's order[i]
    q_pin, v_pin = np.empty(n), np.empty(n)
    q_pin[order], v_pin[order] = q, qd
    tau = k * (theta - q) + d * (td - qd)
    tau_pin = np.empty(n)
    tau_pin[order] = tau
    pin.computeABADerivatives(model, data, q_pin, v_pin, tau_pin)
    back = np.ix_(order, order)
    dq, dv, minv = data.ddq_dq[back], data.ddq_dv[back], data.Minv
    minv = np.triu(minv) + np.triu(minv, 1).T
    minv = minv[back]
    del perm
    K, D = np.diag(k), np.diag(d)
    A = np.zeros((4 * n, 4 * n))
    A[:n, 2 * n:3 * n] = np.eye(n)
    A[n:2 * n, 3 * n:] = np.eye(n)
    A[2 * n:3 * n] = np.hstack([dq - minv @ K, minv @ K, dv - minv @ D, minv @ D])
    A[3 * n:] = np.hstack([K / j[:, None], -K / j[:, None], D / j[:, None], -np.diag((d + beta) / j)])
    return A


@pytest.mark.parametrize("name", ["space_arm", "dual_arm"])
def test_held_base_matches_pinocchio_fixed_base(tmp_path, name):
    """The held base's state matrix equals the one assembled from Pinocchio's fixed-base model
    (the URDF without a free-flyer) to 1e-9, at a state with moving links and deflected springs,
    on a chain and a tree; its eigenvalues equal numpy's of that matrix to 1e-9, and every shape
    satisfies ``A v = λ v`` to 1e-9."""
    path = tmp_path / f"{name}.urdf"
    path.write_text(getattr(orbitflex.models, f"{name}_urdf")())
    model = pin.buildModelFromUrdf(str(path))
    model.gravity.linear[:] = 0
    base = ARMS[name]()
    k, j, _, _ = base.parameters
    arm = orbitflex.FlexibleArm(base.robot, orbitflex.FlexibleJoints(k, j, damping=0.2, motor_damping=1.0))
    n = arm.dof
    rng = np.random.default_rng(7)
    q = rng.uniform(-1, 1, n)
    x = arm.state(q=q, theta=q + rng.uniform(-0.02, 0.02, n), qd=rng.uniform(-0.3, 0.3, n),
                  theta_dot=rng.uniform(-0.3, 0.3, n))
    ss = arm.state_space(x, base="held")
    want = held_state_matrix_from_pinocchio(arm, x, model)
    assert np.abs(ss.A - want).max() < 1e-9 * np.abs(want).max()
    m = arm.modes(x, base="held")
    reference = np.linalg.eigvals(want)
    lambdas = -m.damping_ratio * m.natural_frequency_hz * 2 * np.pi + 1j * m.frequency_hz * 2 * np.pi
    for lam in lambdas:
        assert abs(nearest(reference, lam) - lam) < 1e-9 * abs(lam)
    for v, lam in zip(m.shapes.T, lambdas):
        kept = v[ss.tangent_index]
        assert np.linalg.norm(ss.A @ kept - lam * kept) < 1e-9 * np.linalg.norm(ss.A) * np.linalg.norm(kept)
        assert np.abs(np.delete(v, ss.tangent_index)).max() == 0


def test_frequency_response_equals_the_dense_formula():
    """``H`` against ``C (jωI − A)⁻¹ B + D`` by numpy's dense solve, to 1e-9 of its scale."""
    arm = space_arm()
    x = arm.state(q=np.linspace(-0.5, 0.5, arm.dof))
    freqs = np.array([0.05, 0.9, 3.3, 14.0, 70.0])
    for kwargs in ({"inputs": ["motor_torque", "base_wrench"], "outputs": ["q", "ee_position", "base_attitude"]},
                   {"inputs": "ee_wrench", "outputs": ["deflection", "spring_torque"], "base": "held"},
                   {"inputs": "theta_ref", "outputs": "q", "u": orbitflex.MotorPD(kp=300.0, kd=30.0,
                                                                                 theta_ref=np.zeros(7))}):
        h = arm.frequency_response(x, freqs, **kwargs)
        ss = arm.state_space(x, **kwargs)
        assert h.shape == (len(freqs), len(ss.outputs), len(ss.inputs))
        for f, got in zip(freqs, h):
            want = ss.C @ np.linalg.solve(2j * np.pi * f * np.eye(len(ss.A)) - ss.A, ss.B) + ss.D
            assert np.abs(got - want).max() < 1e-9 * np.abs(want).max(), (kwargs, f)


def test_frequency_response_equals_a_simulated_sine():
    """At 5 frequencies, the steady response of the nonlinear model (RK4) to a small sine on the
    elbow motor's feedforward, under a motor PD, free floating, equals ``H`` to 1 %. The torque is
    sampled at mid-step, so its zero-order hold adds no half-step delay (the remaining error is
    O((ω dt)²)); the run lasts until the slowest mode has decayed to 0.1 % before the last whole
    periods are fitted; the amplitude (0.05 N·m) keeps the angles below 1e-3 rad, where the
    nonlinear terms are far below 1 %. The simulator also holds the PD's own torque over each step
    (a sampled-data loop, half a step of delay in the feedback): at dt = 1 ms that shifted the
    11 Hz response by 3 %, so the run takes dt = 0.1 ms (about 0.3 % there)."""
    arm = space_arm(damping=3.0)
    n, elbow = arm.dof, 3
    kp, kd = 500.0, 150.0
    pd = orbitflex.MotorPD(kp=kp, kd=kd, theta_ref=np.zeros(n))
    x0 = arm.state()
    m = arm.modes(x0, u=pd)
    decay = min(np.min(m.damping_ratio * m.natural_frequency_hz * 2 * np.pi), np.min(-m.overdamped))
    settle = 7.0 / decay  # e^-7 ≈ 0.1 %
    assert settle < 20
    dt, amplitude = 1e-4, 0.05
    for f in (0.2, 0.7, 2.0, 5.0, 11.0):
        h = arm.frequency_response(x0, [f], inputs="motor_torque", outputs="q", u=pd)[0, elbow, elbow]
        periods = max(2, int(np.ceil(2.0 * f)))
        steps = int(np.ceil((settle + periods / f) / dt))
        t_mid = (np.arange(steps) + 0.5) * dt
        ff = np.zeros((steps, n))
        ff[:, elbow] = amplitude * np.sin(2 * np.pi * f * t_mid)
        run = orbitflex.MotorPD(kp=kp, kd=kd, theta_ref=np.zeros(n), feedforward=ff)
        traj = arm.simulate(x0, dt, steps, u=run, record_every=10)
        keep = traj.t >= traj.t[-1] - periods / f
        t, y = traj.t[keep], traj.q[keep, elbow]
        basis = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t), np.ones_like(t)])
        s, c, _ = np.linalg.lstsq(basis, y, rcond=None)[0]
        measured = (s + 1j * c) / amplitude
        assert abs(measured - h) < 0.01 * abs(h), (f, measured, h)


def test_rigid_body_counts_and_friction():
    """6 + n, 6, n, 0 for free/free, free/clamped, held/free, held/clamped; motor friction that
    damps a joint's free rotation does not change them; a PD's k_p removes the joints'."""
    n = 7
    for beta in (0.0, 5.0):
        arm = space_arm(damping=0.5, motor_damping=beta)
        x = arm.state(q=np.full(n, 0.2))
        counts = [arm.modes(x, base=b, motors=m).rigid_body
                  for b in ("free", "held") for m in ("free", "clamped")]
        assert counts == [6 + n, 6, n, 0]
        assert all(len(arm.modes(x, base=b, motors=m)) == n for b in ("free", "held") for m in ("free", "clamped"))
    pd = orbitflex.MotorPD(kp=100.0, kd=10.0, theta_ref=np.zeros(n))
    assert arm.modes(x, u=pd).rigid_body == 6
    assert arm.modes(x, u=pd, base="held").rigid_body == 0


def test_modes_api_shapes_and_undamped():
    arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    x = arm.state(q=np.full(7, 0.3))
    m = arm.modes(x)
    assert m.shapes.shape == (arm.tangent_size, len(m)) and m.shapes.dtype == np.complex128
    assert np.all(np.diff(m.frequency_hz) >= 0)
    assert m.spring_energy.shape == (len(m), 7) and np.allclose(m.spring_energy.sum(axis=1), 1)
    assert len(m.dominant_joints) == len(m) and "structural modes" in m.table()
    u = arm.modes(x, damping=False)
    assert not u.damped and np.all(u.damping_ratio == 0)
    # the joints' damping is light: damped and undamped frequencies within 1 %
    assert np.allclose(u.frequency_hz, m.natural_frequency_hz, rtol=1e-2)
    # u as torques does not change the model
    assert np.array_equal(arm.modes(x, u=np.ones(7)).frequency_hz, m.frequency_hz)


def test_bad_arguments_are_clear_errors():
    arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    x = arm.state()
    cases = [
        (lambda: arm.modes(x, base="fixed"), "base"),
        (lambda: arm.modes(x, motors="braked"), "motors"),
        (lambda: arm.state_space(x, inputs="torque"), "unknown name \"torque\""),
        (lambda: arm.state_space(x, outputs=["q", 3]), "outputs"),
        (lambda: arm.modes(arm.state(base_twist=[0, 0, 0.1, 0, 0, 0]), base="held"), "base twist"),
        (lambda: arm.modes(arm.state(theta_dot=np.full(7, 0.1)), motors="clamped"), "theta_dot[0]"),
        (lambda: arm.state_space(x, motors="clamped"), "\"motor_torque\" drives the motors"),
        (lambda: arm.modes(x, u=lambda t, s: np.zeros(7)), "not known"),
        (lambda: arm.modes(x[:-1]), "x: expected length 41"),
        (lambda: arm.frequency_response(x, [1.0, 0.0]), "element 1 (0 Hz) is a pole"),
        (lambda: arm.frequency_response(x, [np.nan]), "freqs_hz"),
        (lambda: analysis.sweep(arm, np.zeros((3, 5))), "configurations"),
        (lambda: analysis.sweep(arm, np.zeros((3, 7)), threads=0), "threads"),
    ]
    for call, words in cases:
        with pytest.raises(orbitflex.ModelError, match=None) as info:
            call()
        assert words in str(info.value), (words, str(info.value))


def test_sweep_equals_single_calls_and_names_a_bad_row():
    arm = space_arm()
    q = np.zeros((5, 7))
    q[:, 3] = np.linspace(0, 2, 5)
    s = analysis.sweep(arm, q, motors="clamped", count=3)
    assert s.frequency_hz.shape == (5, 3) and list(s.rigid_body) == [6] * 5
    for i in range(5):
        one = arm.modes(arm.state(q=q[i]), motors="clamped")
        assert np.array_equal(s.frequency_hz[i], one.frequency_hz[:3])
    states = np.array([arm.state(q=row) for row in q])
    assert np.array_equal(analysis.sweep(arm, states, motors="clamped", count=3).frequency_hz, s.frequency_hz)
    states[2, 3:7] = 0.0  # a zero quaternion
    with pytest.raises(orbitflex.ModelError, match=r"configurations\[2\]"):
        analysis.sweep(arm, states)


def test_closed_loop_modes_line_for_the_demo():
    arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    pd = orbitflex.MotorPD(kp=np.full(7, 200.0), kd=np.full(7, 30.0), theta_ref=np.zeros(7))
    modes, line = analysis.closed_loop_modes(arm, arm.state(), pd)
    assert modes.closed_loop and line.startswith("first closed-loop modes (free base): ")
    assert line.count("Hz") == 3 and f"{modes.frequency_hz[0]:.3g} Hz" in line


def test_state_space_exports(tmp_path):
    control = pytest.importorskip("control")
    io = pytest.importorskip("scipy.io")
    arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    x = arm.state(q=np.full(7, 0.1))
    ss = arm.state_space(x, inputs=["motor_torque", "ee_wrench"], outputs=["q", "ee_position"], base="held")
    assert ss.A.shape == (28, 28) and ss.B.shape == (28, 13) and ss.C.shape == (10, 28)
    assert ss.states[0] == "q[shoulder_roll]" and ss.inputs[7] == "ee_moment_x[ee]" and ss.outputs[-1] == "ee_z[ee]"
    assert list(ss.tangent_index[:7]) == list(range(6, 13))
    sys = ss.to_control()
    assert list(sys.input_labels) == ss.inputs and list(sys.output_labels) == ss.outputs
    f = 2.5
    got = sys(2j * np.pi * f)
    want = arm.frequency_response(x, [f], inputs=["motor_torque", "ee_wrench"], outputs=["q", "ee_position"],
                                  base="held")[0]
    assert np.abs(got - want).max() < 1e-9 * np.abs(want).max()
    path = ss.savemat(tmp_path / "arm.mat")
    mat = io.loadmat(path)
    for key in "ABCD":
        assert np.array_equal(mat[key], getattr(ss, key))
    assert [str(c[0]) for c in mat["StateName"][:, 0]] == ss.states
    assert [str(c[0]) for c in mat["InputName"][:, 0]] == ss.inputs
    assert str(mat["base"][0]) == "held"


def test_ee_position_output_is_the_derivative_of_the_ee_pose():
    """The ``ee_position`` rows of ``C`` equal central differences of ``arm.ee_pose`` along the
    tangent (base pose and joint angles), at a turned base."""
    arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    x = arm.state(q=np.linspace(-0.8, 0.8, 7), base_pose=[0.3, -0.2, 0.1, 0.2, -0.1, 0.3, 0.9])
    C = arm.state_space(x, outputs="ee_position").C
    h = 1e-6
    for i in range(6 + 7):
        e = np.zeros(arm.tangent_size)
        e[i] = h
        fd = (arm.ee_pose(arm.integrate(x, e))[:3] - arm.ee_pose(arm.integrate(x, -e))[:3]) / (2 * h)
        assert np.abs(C[:, i] - fd).max() < 1e-7, i


def test_cli_modes(tmp_path, capsys):
    from orbitflex.cli import main

    out = tmp_path / "out"
    code = main(["modes", "--motors", "clamped", "--q", "0", "0.3", "0", "1.2", "0", "0", "0",
                 "--sweep", "elbow_pitch", "0", "2", "6", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "7 structural modes" in text and "6 rigid-body modes" in text
    doc = json.loads((out / "modes.json").read_text())
    assert doc["motors"] == "clamped" and len(doc["modes"]) == 7 and len(doc["sweep"]["angle_rad"]) == 6
    for name in ("modes.png", "bode.png", "campbell.png", "state_space.mat"):
        assert (out / name).stat().st_size > 1000, name
    # usage errors are one line with the flag
    for argv, flag in ((["modes", "--sweep", "nope", "0", "1", "3"], "--sweep"),
                       (["modes", "--kd", "3"], "--kd"),
                       (["modes", "--outputs", "speed"], "--outputs"),
                       (["modes", "--motors", "clamped", "--kp", "10"], "--motors")):
        assert main(argv + ["--out", str(out), "--no-plots"]) == 2
        assert f"orbitflex: error: {flag}:" in capsys.readouterr().err


def test_docs_modes_example_runs(tmp_path, monkeypatch):
    """docs/modes.md's Python example runs as written."""
    import pathlib
    import re

    page = pathlib.Path(__file__).resolve().parents[2] / "docs" / "modes.md"
    if not page.exists():
        pytest.skip("needs the source tree")
    monkeypatch.chdir(tmp_path)
    for block in re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S):
        exec(compile(block, "docs/modes.md", "exec"), {"__name__": "docs"})
    assert (tmp_path / "arm.mat").exists()
