"""Linear analysis of an arm with reaction wheels (``arm.modes``, ``arm.state_space``,
``orbitflex.analysis.sampled_loop``): the closed loop of a MotorPD and an AttitudePD against
numpy's ``eig`` of the finite-difference Jacobian of the closed-loop derivative, a simulated
small-amplitude response against the linear model, and sampled attitude loops whose spectral
radius says whether a simulation diverges."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import orbitflex
from orbitflex import analysis
from orbitflex.models import PYRAMID_GAINS, pyramid_wheels

scipy_linalg = pytest.importorskip("scipy.linalg")


def wheeled_arm() -> orbitflex.FlexibleArm:
    return orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints(),
                                 wheels=pyramid_wheels())


def posture(arm: orbitflex.FlexibleArm) -> np.ndarray:
    return arm.state(q=[0.2, -0.6, 0.4, 1.1, -0.3, 0.5, 0.1])


def controllers(arm: orbitflex.FlexibleArm, x: np.ndarray):
    theta = x[arm.state_slices["theta"]]
    motor = orbitflex.MotorPD(kp=[800.0] * 7, kd=[300.0] * 7, theta_ref=theta)
    quat = x[3:7]
    attitude = orbitflex.AttitudePD(*PYRAMID_GAINS, attitude=quat)
    return motor, attitude


def closed_loop_fd(arm, x, motor, attitude, h=1e-6):
    """Central differences of the closed-loop derivative along x ⊕ dx: rows 6.. are the
    additive blocks (the pose rows' tangent map is the Rust suite's)."""
    t = arm.tangent_size
    theta_ref = x[arm.state_slices["theta"]]
    kp, kd = np.asarray(motor.kp), np.asarray(motor.kd)

    def f(y):
        u = kp * (theta_ref - y[arm.state_slices["theta"]]) - kd * y[arm.state_slices["theta_dot"]]
        return arm.derivative(y, u=u, wheel_torque=attitude.command(arm, y))[7:]

    out = np.zeros((t - 6, t))
    for c in range(t):
        dx = np.zeros(t)
        dx[c] = h
        out[:, c] = (f(arm.integrate(x, dx)) - f(arm.integrate(x, -dx))) / (2 * h)
    return out


def test_closed_loop_eigenvalues_equal_numpy_eig_of_the_finite_difference_jacobian():
    """The modes' eigenvalues under MotorPD + AttitudePD equal numpy's eig of the closed-loop
    Jacobian formed by central differences (its pose rows, which no controller touches, taken
    from the analytical A). Bound: the Jacobian's entries agree to ≈ 1e-7 relative (h = 1e-6,
    truncation h² |f'''| and round-off ε|f|/h), and the eigenvalues of this diagonalisable A
    move by at most κ(V)·‖δA‖; with κ ≈ 1e2 and ‖A‖ ≈ 1e4 that is 1e-1 absolute at worst,
    so we compare each eigenvalue to 1e-4 relative to the largest |λ| (≈ 2e3/s)."""
    arm = wheeled_arm()
    x = posture(arm)
    motor, attitude = controllers(arm, x)
    ss = arm.state_space(x, u=(motor, attitude), inputs=[], outputs=[])
    fd = closed_loop_fd(arm, x, motor, attitude)
    assert np.abs(ss.A[6:] - fd).max() < 1e-5 * np.abs(fd).max()
    a = ss.A.copy()
    a[6:] = fd
    ours = arm.modes(x, u=(motor, attitude)).eigenvalues
    theirs = np.linalg.eigvals(a)
    scale = np.abs(theirs).max()
    for lam in theirs:
        assert np.min(np.abs(ours - lam)) < 1e-4 * scale, lam
    m = arm.modes(x, u=(motor, attitude))
    assert (m.rigid_body, m.wheel_spin) == (3, 4)
    # the same loop through wheel_torque=, as simulate takes it
    same = arm.modes(x, u=motor, wheel_torque=attitude)
    assert np.allclose(same.eigenvalues, m.eigenvalues, rtol=0, atol=1e-9 * scale)


def test_small_amplitude_response_follows_the_linear_model():
    """From x̄ ⊕ ε v the nonlinear run under both PDs follows the linear model. The run's
    controllers hold their torques over each RK4 step, so the linear prediction is the sampled
    loop at the step: dx_k = (Φ + Γ K)^k ε v with Φ = e^{A dt}, Γ = ∫₀^dt e^{As} ds B from the
    open plant and K = the PDs' gain (read off the closed loop: A_closed − A = B K). The
    continuous loop e^{A_closed t} differs from it by O(|λ| dt) (≈ 1 % at dt = 1e-3 s, 1e-4 at
    the 2e-4 s used here), which is why the sampling is modelled. Bound: quadratic terms give ≲ ε relative; RK4's local error with
    the input held, (|λ| dt)⁵/120 per step with |λ| dt ≤ 0.2 at dt = 2e-4 s, sums over 2500
    steps to ≲ 1e-4 relative on the fast, heavily damped motor modes. 1e-3 of the state's
    largest component."""
    arm = wheeled_arm()
    x = posture(arm)
    motor, attitude = controllers(arm, x)
    groups = ["motor_torque", "wheel_torque"]
    closed = arm.state_space(x, u=(motor, attitude), inputs=groups, outputs=[])
    plant = arm.state_space(x, inputs=groups, outputs=[])
    gain = np.linalg.lstsq(plant.B, closed.A - plant.A, rcond=None)[0]
    assert np.abs(plant.B @ gain - (closed.A - plant.A)).max() < 1e-9 * np.abs(closed.A).max()
    dt, steps = 2e-4, 2500
    s, m = plant.B.shape
    aug = np.zeros((s + m, s + m))
    aug[:s, :s], aug[:s, s:] = plant.A * dt, plant.B * dt
    e = scipy_linalg.expm(aug)
    step = e[:s, :s] + e[:s, s:] @ gain
    rng = np.random.default_rng(3)
    v = np.zeros(arm.tangent_size)
    v[3:6] = rng.normal(size=3) * 0.1        # the bus turned
    v[6:13] = rng.normal(size=7) * 0.1       # the links deflected
    v[-4:] = rng.normal(size=4)              # wheel speeds
    eps = 1e-5
    traj = arm.simulate(arm.integrate(x, eps * v), dt, steps, u=motor, wheel_torque=attitude)
    z = v.copy()
    for k in range(1, steps + 1):
        z = step @ z
        if k in (100, 1000, 2500):
            got = arm.difference(x, traj.x[k]) / eps
            assert np.abs(got - z).max() < 1e-3 * np.abs(z).max(), (k, np.abs(got - z).max(), np.abs(z).max())


def test_sampled_attitude_loop_predicts_divergence():
    """The pyramid's AttitudePD (kd = 2e4 N·m·s/rad on a bus of ≈ 190 kg·m²) sampled with zero-order
    hold needs k_d T < 2 I (Jury's condition for a rigid body, tests/wheel_linear.rs): about
    50 Hz. At 40 Hz the discrete loop has ρ ≈ 1.55 and the simulation grows by about ρ per
    sample (small amplitudes: the wheels stay far below their 60 N·m); at 50 Hz it is stable
    and the attitude error decays; one sample of delay at 50 Hz makes it unstable again.
    simulate warns exactly for the unstable ones."""
    arm = wheeled_arm()
    x = posture(arm)
    motor, attitude = controllers(arm, x)
    x0 = arm.integrate(x, np.r_[0, 0, 0, 1e-8, -1e-8, 1e-8, np.zeros(arm.tangent_size - 6)])
    dt, steps = 1e-3, 500  # 20 samples at 40 Hz, whole steps per sample
    for rate, delay, unstable in [(40.0, 0, True), (50.0, 0, False), (50.0, 1, True)]:
        sampled = orbitflex.Sampled(attitude, rate, delay)
        loop = analysis.sampled_loop(arm, x, sampled, u=motor)
        assert loop.unstable == unstable, (rate, delay, loop.spectral_radius)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            run = arm.simulate(x0, dt, steps, u=motor, wheel_torque=sampled)
        warned = [str(w.message) for w in caught if "sampled" in str(w.message)]
        assert bool(warned) == unstable, warned
        error = np.array([np.linalg.norm(arm.difference(x, row)[3:6]) for row in run.x])
        assert np.abs(run.wheel_torque).max() < 60.0  # linear: no saturation
        if unstable:
            assert f"wheel_torque: the AttitudePD sampled at {rate:g} Hz" in warned[0]
            assert f"delay {delay} samples" in warned[0]
            assert error[-1] > 100 * error[0]
            if delay == 0:
                per_sample = (error[-1] / error[steps // 2]) ** (1 / (rate * dt * steps / 2))
                assert abs(per_sample / loop.spectral_radius - 1) < 0.1, (per_sample, loop.spectral_radius)
        else:
            assert loop.spectral_radius <= loop.threshold
            assert error[-1] < 0.5 * error[0]


def test_wheel_inputs_outputs_and_bad_input():
    arm = wheeled_arm()
    x = posture(arm)
    ss = arm.state_space(x, inputs=["wheel_torque"], outputs=["wheel_speed", "base_rate"])
    assert ss.inputs == [f"wheel_torque[{w}]" for w in range(4)]
    assert ss.outputs[:4] == [f"wheel_speed[{w}]" for w in range(4)]
    assert ss.states[-4:] == [f"wheel_speed[{w}]" for w in range(4)]
    assert ss.A.shape == (arm.tangent_size, arm.tangent_size)
    plain = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    with pytest.raises(orbitflex.ModelError, match=r"\"wheel_torque\" drives reaction wheels, and the arm has none"):
        plain.state_space(plain.state(), inputs="wheel_torque")
    with pytest.raises(orbitflex.ModelError, match=r"AttitudePD: the arm has no reaction wheels"):
        plain.modes(plain.state(), u=orbitflex.AttitudePD(1.0, 1.0))
    at_limit = x.copy()
    at_limit[arm.state_slices["wheel_speed"]] = [800.0, 0, 0, 0]
    with pytest.raises(orbitflex.ModelError, match=r"wheel 0 turns at 800 rad/s, at its speed limit"):
        arm.modes(at_limit)
    with pytest.raises(orbitflex.ModelError, match=r"an AttitudePD turns the bus, which base=\"held\" holds still"):
        arm.modes(arm.state(), u=orbitflex.AttitudePD(1.0, 1.0), base="held")
    with pytest.raises(orbitflex.ModelError, match=r"controller: expected a Sampled"):
        analysis.sampled_loop(arm, x, orbitflex.AttitudePD(1.0, 1.0))


def test_cli_modes_with_wheels(tmp_path, capsys):
    """``orbitflex modes --wheels`` closes the bus loop with the file's AttitudePD (its gains
    overridable), counts the wheel spins, and names its flags in usage errors."""
    import json
    import pathlib

    from orbitflex.cli import main

    toml = pathlib.Path(__file__).resolve().parents[2] / "examples" / "wheels.toml"
    if not toml.exists():
        pytest.skip("needs the source tree")
    out = tmp_path / "out"
    code = main(["modes", "--wheels", str(toml), "--kp", "800", "--kd", "300", "--inputs", "wheel_torque",
                 "--outputs", "base_attitude,wheel_speed", "--out", str(out), "--no-plots"])
    assert code == 0
    text = capsys.readouterr().out
    assert "3 rigid-body modes separated out, and 4 wheel spins" in text
    doc = json.loads((out / "modes.json").read_text())
    assert doc["wheel_spin_modes"] == 4 and doc["rigid_body_modes"] == 3 and doc["closed_loop"]
    # open loop: zero attitude gains leave the bus's rotations rigid
    assert main(["modes", "--wheels", str(toml), "--attitude-kp", "0", "--attitude-kd", "0",
                 "--out", str(out), "--no-plots"]) == 0
    assert "13 rigid-body modes separated out, and 4 wheel spins" in capsys.readouterr().out
    for argv, flag in ((["modes", "--attitude-kp", "3"], "--attitude-kp"),
                       (["modes", "--wheels", str(toml), "--attitude-kd", "1", "2"], "--attitude-kd"),
                       (["modes", "--wheels", str(toml), "--base", "held"], "--wheels"),
                       (["modes", "--wheels", str(tmp_path / "none.toml")], "--wheels")):
        assert main(argv + ["--out", str(out), "--no-plots"]) == 2
        assert f"orbitflex: error: {flag}:" in capsys.readouterr().err
