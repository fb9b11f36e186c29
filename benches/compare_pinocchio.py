#!/usr/bin/env python3
"""orbitflex against Pinocchio (``pin``) from Python, on the same models in one run (BENCHMARKS.md).

    python3 benches/compare_pinocchio.py [--blocks 15] [--sim-blocks 5] [--json out.json]
        [--rust-bin target/release/examples/bench_cpp_match] [--cpp-bin .../bench_aba_gcc]

Models: the built-in space arm (its URDF written to a temporary file), panda (fingers locked, EE
``panda_hand_tcp``) and ur5 (EE ``tool0``), each with a free-flyer root in Pinocchio and zero
gravity. Sections:

1. Per call: ``robot.forward_dynamics`` vs ``pin.aba``, ``robot.inverse_dynamics`` vs
   ``pin.rnea``, ``robot.mass_matrix`` vs ``pin.crba``.
2. Binding overhead (with ``--rust-bin`` and ``--cpp-bin``): the Python per-call time minus the
   native per-call time of the same algorithm, for each library.
3. Whole simulation: ``arm.simulate`` (10⁴ RK4 steps, ``MotorPD``) vs a flexible-joint RK4 loop
   written in Python around ``pin.aba`` (model §4 equations, numpy, preallocated arrays).
4. ``simulate`` from Python vs the pure-Rust loop (with ``--rust-bin``): the same run timed
   inside ``examples/bench_cpp_match.rs``.

Timing: each comparison alternates the two sides block by block (the order flips every block),
and reports the median time per call over blocks; the ratio is orbitflex / Pinocchio (< 1:
orbitflex is faster). Before timing, each pair is checked to compute the same numbers.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import timeit

import numpy as np
import orbitflex
import pinocchio as pin

# Flexible joints of the README (j = N² J_rotor) and its motor PD, for every model.
STIFFNESS, GEAR, ROTOR, DAMPING, MOTOR_DAMPING = 2e4, 160.0, 4e-5, 2.0, 1.0
KP, KD, THETA_REF = 2000.0, 800.0, 0.2
DT, STEPS = 1e-3, 10_000


def robots_dir() -> str:
    """example-robot-data's ``robots`` folder (the cmeel prefix of the pip wheels)."""
    try:
        import example_robot_data  # type: ignore

        d = example_robot_data.getModelPath("ur_description/urdf/ur5_robot.urdf")
        if os.path.isdir(os.path.join(d, "ur_description")):
            return d
    except Exception:
        pass
    f = os.path.abspath(pin.__file__)
    if "cmeel.prefix" in f:
        d = os.path.join(f[: f.index("cmeel.prefix") + len("cmeel.prefix")], "share", "example-robot-data", "robots")
        if os.path.isdir(d):
            return d
    raise FileNotFoundError("example-robot-data's robots folder not found (pip install example-robot-data)")


# A base and one link: the dynamics cost next to nothing, so the Python time per call is mostly
# the bindings' own overhead (argument conversion, result allocation).
ONE_LINK_URDF = """<robot name="one_link">
  <link name="base"><inertial><origin xyz="0 0 0"/><mass value="10"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="joint1" type="revolute"><parent link="base"/><child link="link1"/>
    <origin xyz="0.5 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit effort="10" velocity="1" lower="-3" upper="3"/></joint>
  <link name="link1"><inertial><origin xyz="0.2 0 0"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial></link>
</robot>
"""


def model_specs(tmpdir: str) -> dict:
    robots = robots_dir()
    space = os.path.join(tmpdir, "space_arm.urdf")
    with open(space, "w") as fh:
        fh.write(orbitflex.models.space_arm_urdf())
    one = os.path.join(tmpdir, "one_link.urdf")
    with open(one, "w") as fh:
        fh.write(ONE_LINK_URDF)
    return {
        "one_link": (one, None, []),
        "space_arm": (space, None, []),
        "panda": (
            os.path.join(robots, "panda_description", "urdf", "panda.urdf"),
            "panda_hand_tcp",
            ["panda_finger_joint1", "panda_finger_joint2"],
        ),
        "ur5": (os.path.join(robots, "ur_description", "urdf", "ur5_robot.urdf"), "tool0", []),
    }


class Pair:
    """One URDF as an orbitflex Robot and a Pinocchio model with a free-flyer root, one state."""

    def __init__(self, name: str, path: str, ee_link, locked, seed: int = 4):
        self.name, self.path, self.ee_link, self.locked = name, path, ee_link, list(locked)
        self.robot = orbitflex.Robot.from_urdf(path, ee_link=ee_link, locked_joints=locked or None)
        model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())
        if locked:
            model = pin.buildReducedModel(model, [model.getJointId(j) for j in locked], pin.neutral(model))
        model.gravity = pin.Motion.Zero()
        self.model, self.data = model, model.createData()
        n = self.n = self.robot.dof
        assert model.nv == 6 + n and model.nq == 7 + n, (model.nq, model.nv, n)
        # A serial chain: Pinocchio's joints after the free flyer are orbitflex's, in order.
        assert list(model.names)[2:] == list(self.robot.joint_names), (list(model.names), self.robot.joint_names)

        rng = np.random.default_rng(seed)
        self.q = rng.uniform(-1.0, 1.0, n)
        w, v = rng.uniform(-0.2, 0.2, 3), rng.uniform(-0.2, 0.2, 3)
        self.twist = np.r_[w, v]  # orbitflex [ω; v]
        self.qd = rng.uniform(-0.5, 0.5, n)
        self.tau = rng.uniform(-5.0, 5.0, n)
        self.base_acc = rng.uniform(-1.0, 1.0, 6)  # classical [ω̇; v̇]
        self.qdd = rng.uniform(-1.0, 1.0, n)
        # Pinocchio: configuration [r; quat; q], velocity [v; ω; q̇], spatial base acceleration.
        self.q_pin = np.r_[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, self.q]
        self.v_pin = np.r_[v, w, self.qd]
        self.tau_pin = np.r_[np.zeros(6), self.tau]
        a_lin = self.base_acc[3:] - np.cross(w, v)
        self.a_pin = np.r_[a_lin, self.base_acc[:3], self.qdd]

    def check(self) -> dict:
        """Largest relative differences of the joint parts (base conventions differ, model §6.5)."""
        r, m, d = self.robot, self.model, self.data
        fd = r.forward_dynamics(self.q, self.twist, self.qd, self.tau)
        ddq = pin.aba(m, d, self.q_pin, self.v_pin, self.tau_pin)
        id_ = r.inverse_dynamics(self.q, self.twist, self.qd, self.base_acc, self.qdd)
        tau = pin.rnea(m, d, self.q_pin, self.v_pin, self.a_pin)
        mm = r.mass_matrix(self.q)
        mp = pin.crba(m, d, self.q_pin)
        mp = np.triu(mp) + np.triu(mp, 1).T
        rel = lambda a, b: float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))
        return {
            "forward_dynamics": rel(fd[6:], ddq[6:]),
            "inverse_dynamics": rel(id_[6:], tau[6:]),
            "mass_matrix": rel(mm[6:, 6:], mp[6:, 6:]),
        }


def calibrate(timer: timeit.Timer, seconds: float) -> int:
    """Number of calls that takes about ``seconds``."""
    number = 1
    while True:
        t = timer.timeit(number)
        if t >= seconds / 4 or number >= 1 << 24:
            return max(1, int(number * seconds / max(t, 1e-9)))
        number *= 4


def alternate(stmt_a: str, stmt_b: str, env: dict, blocks: int, block_s: float = 0.02):
    """Median seconds per call of two statements, timed in alternating blocks."""
    ta, tb = timeit.Timer(stmt_a, globals=env), timeit.Timer(stmt_b, globals=env)
    na, nb = calibrate(ta, block_s), calibrate(tb, block_s)
    sa, sb = [], []
    for k in range(blocks):
        for side in ("ab" if k % 2 == 0 else "ba"):
            if side == "a":
                sa.append(ta.timeit(na) / na)
            else:
                sb.append(tb.timeit(nb) / nb)
    return statistics.median(sa), statistics.median(sb)


def per_call(pairs: dict, blocks: int) -> list:
    rows = []
    for name, p in pairs.items():
        env = {
            "fd": p.robot.forward_dynamics,
            "id_": p.robot.inverse_dynamics,
            "mm": p.robot.mass_matrix,
            "aba": pin.aba,
            "rnea": pin.rnea,
            "crba": pin.crba,
            "model": p.model,
            "data": p.data,
            **{k: getattr(p, k) for k in ("q", "twist", "qd", "tau", "base_acc", "qdd", "q_pin", "v_pin", "tau_pin", "a_pin")},
        }
        for what, ours, theirs in [
            ("forward dynamics", "fd(q, twist, qd, tau)", "aba(model, data, q_pin, v_pin, tau_pin)"),
            ("inverse dynamics", "id_(q, twist, qd, base_acc, qdd)", "rnea(model, data, q_pin, v_pin, a_pin)"),
            ("mass matrix", "mm(q)", "crba(model, data, q_pin)"),
        ]:
            a, b = alternate(ours, theirs, env, blocks)
            rows.append({"model": name, "what": what, "orbitflex_us": a * 1e6, "pinocchio_us": b * 1e6, "ratio": a / b})
            print(f"  {name:9s} {what:17s} orbitflex {a * 1e6:7.2f} µs  pin {b * 1e6:7.2f} µs  ratio {a / b:.2f}", file=sys.stderr)
    return rows


# ----------------------------------------------------------------------------- simulation
def flexible_arm(robot):
    joints = orbitflex.FlexibleJoints.from_gear(
        stiffness=STIFFNESS, gear_ratio=GEAR, rotor_inertia=ROTOR, damping=DAMPING, motor_damping=MOTOR_DAMPING
    )
    return orbitflex.FlexibleArm(robot, joints)


def motor_pd(n: int):
    return orbitflex.MotorPD(kp=KP, kd=KD, theta_ref=np.full(n, THETA_REF))


def pin_simulate(model, data, x0: np.ndarray, dt: float, steps: int) -> np.ndarray:
    """Flexible-joint RK4 in Python around ``pin.aba`` (model §4, §5), as fast as we could write it.

    State ``[q_pin (7+n) | θ (n) | v_pin (6+n) | θ̇ (n)]``; Pinocchio's base velocity ``[v; ω]`` is
    in the base frame and its spatial base acceleration is the derivative of those components,
    so ``v̇_pin = aba(...)``. Motor PD once per step from the state at its start. Preallocated
    arrays, in-place numpy, scalar math for the 7 pose rates.
    """
    n = model.nv - 6
    nq, nv = 7 + n, 6 + n
    size = nq + n + nv + n
    it, iv, itd = nq, nq + n, nq + n + nv  # offsets of θ, v_pin, θ̇
    k = np.full(n, STIFFNESS)
    d = np.full(n, DAMPING)
    inv_j = np.full(n, 1.0 / (GEAR * GEAR * ROTOR))
    beta = np.full(n, MOTOR_DAMPING)
    theta_ref = np.full(n, THETA_REF)
    traj = np.empty((steps + 1, size))
    traj[0] = x0
    x = x0.copy()
    trial = np.empty(size)
    ks = [np.empty(size) for _ in range(4)]
    tau_pin = np.zeros(nv)
    tau = tau_pin[6:]
    spring, tmp, u = np.empty(n), np.empty(n), np.empty(n)
    aba = pin.aba

    def derivative(x, out):
        q_pin, theta, v_pin, theta_dot = x[:nq], x[it:iv], x[iv:itd], x[itd:]
        # τ = k (θ − q) + d (θ̇ − q̇)
        np.subtract(theta, q_pin[7:], out=spring)
        np.multiply(spring, k, out=spring)
        np.subtract(theta_dot, v_pin[6:], out=tmp)
        np.multiply(tmp, d, out=tmp)
        np.add(spring, tmp, out=tau)
        out[iv:itd] = aba(model, data, q_pin, v_pin, tau_pin)
        # ṙ = R v, quat' = ½ quat ⊗ (ω, 0)
        qx, qy, qz, qw = q_pin[3:7].tolist()
        vx, vy, vz, wx, wy, wz = v_pin[:6].tolist()
        out[0] = (1 - 2 * (qy * qy + qz * qz)) * vx + 2 * (qx * qy - qz * qw) * vy + 2 * (qx * qz + qy * qw) * vz
        out[1] = 2 * (qx * qy + qz * qw) * vx + (1 - 2 * (qx * qx + qz * qz)) * vy + 2 * (qy * qz - qx * qw) * vz
        out[2] = 2 * (qx * qz - qy * qw) * vx + 2 * (qy * qz + qx * qw) * vy + (1 - 2 * (qx * qx + qy * qy)) * vz
        out[3] = 0.5 * (qw * wx + qy * wz - qz * wy)
        out[4] = 0.5 * (qw * wy + qz * wx - qx * wz)
        out[5] = 0.5 * (qw * wz + qx * wy - qy * wx)
        out[6] = -0.5 * (qx * wx + qy * wy + qz * wz)
        out[7:nq] = v_pin[6:]
        out[it:iv] = theta_dot
        # θ̈ = (u − τ − β θ̇) / j
        np.multiply(beta, theta_dot, out=tmp)
        np.subtract(u, tau, out=spring)
        np.subtract(spring, tmp, out=spring)
        np.multiply(spring, inv_j, out=out[itd:])

    k1, k2, k3, k4 = ks
    half, sixth = 0.5 * dt, dt / 6.0
    for step in range(steps):
        # u = K_p (θ_ref − θ) − K_d θ̇, from the state at the start of the step
        np.subtract(theta_ref, x[it:iv], out=u)
        u *= KP
        np.multiply(x[itd:], KD, out=tmp)
        u -= tmp
        derivative(x, k1)
        np.multiply(k1, half, out=trial)
        trial += x
        derivative(trial, k2)
        np.multiply(k2, half, out=trial)
        trial += x
        derivative(trial, k3)
        np.multiply(k3, dt, out=trial)
        trial += x
        derivative(trial, k4)
        k2 += k3
        k2 *= 2.0
        k2 += k1
        k2 += k4
        k2 *= sixth
        x += k2
        x[3:7] /= math.sqrt(float(x[3:7] @ x[3:7]))
        traj[step + 1] = x
    return traj


def to_pin_state(x: np.ndarray, n: int) -> np.ndarray:
    """orbitflex ``[r, quat, q, θ, ω, v, q̇, θ̇]`` as the Python loop's ``[r, quat, q, θ, v, ω, q̇, θ̇]``."""
    w, v = x[7 + 2 * n : 10 + 2 * n], x[10 + 2 * n : 13 + 2 * n]
    return np.r_[x[: 7 + 2 * n], v, w, x[13 + 2 * n :]]


def simulation(pairs: dict, blocks: int, steps: int) -> list:
    rows = []
    for name, p in pairs.items():
        n = p.n
        arm = flexible_arm(p.robot)
        x0 = arm.state()
        x0_pin = to_pin_state(x0, n)
        # Same trajectory on both sides (round-off only), so the loop is a fair stand-in.
        ours = arm.simulate(x0, DT, steps, u=motor_pd(n)).x
        theirs = pin_simulate(p.model, p.data, x0_pin, DT, steps)
        mapped = np.array([to_pin_state(row, n) for row in ours[:: max(1, steps // 100)]])
        err = float(np.abs(mapped - theirs[:: max(1, steps // 100)]).max() / np.abs(theirs).max())
        t_ours, t_theirs = [], []
        for b in range(blocks):
            for side in ("ab" if b % 2 == 0 else "ba"):
                t0 = time.perf_counter()
                if side == "a":
                    arm.simulate(x0, DT, steps, u=motor_pd(n))
                    t_ours.append(time.perf_counter() - t0)
                else:
                    pin_simulate(p.model, p.data, x0_pin, DT, steps)
                    t_theirs.append(time.perf_counter() - t0)
        a, b_ = statistics.median(t_ours), statistics.median(t_theirs)
        rows.append(
            {
                "model": name,
                "steps": steps,
                "orbitflex_s": a,
                "pinocchio_python_loop_s": b_,
                "ratio": a / b_,
                "orbitflex_steps_per_s": steps / a,
                "pinocchio_steps_per_s": steps / b_,
                "max_rel_state_diff": err,
            }
        )
        print(
            f"  {name:9s} simulate {steps} steps: orbitflex {a * 1e3:7.1f} ms  pin+Python RK4 {b_ * 1e3:8.1f} ms  "
            f"ratio {a / b_:.3f}  (state agreement {err:.1e})",
            file=sys.stderr,
        )
    return rows


def run_native(cmd: list) -> dict:
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    values = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 2:
            try:
                values[parts[0]] = float(parts[1])
            except ValueError:
                pass
    return values


def native_args(p: Pair) -> list:
    return [p.path, p.ee_link or "-", *p.locked]


def binding_overhead(pairs: dict, rust_bin: str, cpp_bin: str, rounds: int, blocks: int) -> list:
    """Python per-call time minus native per-call time, rounds interleaved with the natives."""
    rows = []
    for name in ("one_link", "panda", "space_arm"):
        p = pairs[name]
        py = {k: [] for k in ("fd", "id", "mm", "aba", "rnea", "crba")}
        nat = {k: [] for k in ("rs_aba", "rs_rnea", "rs_crba", "cpp_aba", "cpp_rnea", "cpp_crba")}
        env = {
            "fd": p.robot.forward_dynamics, "id_": p.robot.inverse_dynamics, "mm": p.robot.mass_matrix,
            "aba": pin.aba, "rnea": pin.rnea, "crba": pin.crba, "model": p.model, "data": p.data,
            **{k: getattr(p, k) for k in ("q", "twist", "qd", "tau", "base_acc", "qdd", "q_pin", "v_pin", "tau_pin", "a_pin")},
        }
        for _ in range(rounds):
            rs = run_native([rust_bin, *native_args(p), "--only", "aba,rnea,crba", "--blocks", "5"])
            cpp = run_native([cpp_bin, *native_args(p), "--only", "aba_local,rnea,crba_local", "--blocks", "5"])
            nat["rs_aba"].append(rs["aba"] * 1e-9)
            nat["rs_rnea"].append(rs["rnea"] * 1e-9)
            nat["rs_crba"].append(rs["crba"] * 1e-9)
            nat["cpp_aba"].append(cpp["aba_local"] * 1e-9)
            nat["cpp_rnea"].append(cpp["rnea"] * 1e-9)
            nat["cpp_crba"].append(cpp["crba_local"] * 1e-9)
            for key, ours, theirs in [
                (("fd", "aba"), "fd(q, twist, qd, tau)", "aba(model, data, q_pin, v_pin, tau_pin)"),
                (("id", "rnea"), "id_(q, twist, qd, base_acc, qdd)", "rnea(model, data, q_pin, v_pin, a_pin)"),
                (("mm", "crba"), "mm(q)", "crba(model, data, q_pin)"),
            ]:
                a, b = alternate(ours, theirs, env, blocks)
                py[key[0]].append(a)
                py[key[1]].append(b)
        med = {k: statistics.median(v) for k, v in {**py, **nat}.items()}
        for what, ours, theirs, rs, cpp in [
            ("forward dynamics", "fd", "aba", "rs_aba", "cpp_aba"),
            ("inverse dynamics", "id", "rnea", "rs_rnea", "cpp_rnea"),
            ("mass matrix", "mm", "crba", "rs_crba", "cpp_crba"),
        ]:
            o_over = med[ours] - med[rs]
            p_over = med[theirs] - med[cpp]
            rows.append(
                {
                    "model": name, "what": what,
                    "orbitflex_python_us": med[ours] * 1e6, "orbitflex_native_us": med[rs] * 1e6,
                    "orbitflex_overhead_us": o_over * 1e6,
                    "pinocchio_python_us": med[theirs] * 1e6, "pinocchio_native_us": med[cpp] * 1e6,
                    "pinocchio_overhead_us": p_over * 1e6, "ratio": o_over / p_over,
                }
            )
            print(
                f"  {name:9s} {what:17s} overhead orbitflex {o_over * 1e6:5.2f} µs  pin {p_over * 1e6:5.2f} µs  ratio {o_over / p_over:.2f}",
                file=sys.stderr,
            )
    return rows


def python_vs_rust(pairs: dict, rust_bin: str, rounds: int) -> dict:
    """``arm.simulate`` from Python vs the pure-Rust ``FlexibleArm::simulate`` on the space arm."""
    p = pairs["space_arm"]
    arm = flexible_arm(p.robot)
    x0 = arm.state()
    py, rs = [], []
    for r in range(rounds):
        for side in ("pr" if r % 2 == 0 else "rp"):
            if side == "p":
                times = []
                for _ in range(3):
                    t0 = time.perf_counter()
                    arm.simulate(x0, DT, STEPS, u=motor_pd(p.n))
                    times.append(time.perf_counter() - t0)
                py.append(statistics.median(times))
            else:
                rs.append(run_native([rust_bin, p.path, "-", "--only", "simulate_1e4", "--blocks", "3"])["simulate_1e4"] * 1e-9)
    a, b = statistics.median(py), statistics.median(rs)
    print(f"  space_arm simulate 10^4 steps: Python {a * 1e3:.1f} ms  pure Rust {b * 1e3:.1f} ms  ratio {a / b:.3f}", file=sys.stderr)
    return {"model": "space_arm", "steps": STEPS, "python_s": a, "rust_s": b, "ratio": a / b}


# ----------------------------------------------------------------------------- report
def markdown(result: dict) -> str:
    lines = [
        f"Machine: {result['machine']}; Python {result['python']}, numpy {result['numpy']}, "
        f"pin {result['pinocchio']}, orbitflex {result['orbitflex']}.",
        "",
        "Per call from Python (median µs; ratio = orbitflex / Pinocchio, < 1: orbitflex faster):",
        "",
        "| model | call | orbitflex (µs) | Pinocchio (µs) | ratio |",
        "|---|---|---:|---:|---:|",
    ]
    names = {
        "forward dynamics": "`forward_dynamics` vs `pin.aba`",
        "inverse dynamics": "`inverse_dynamics` vs `pin.rnea`",
        "mass matrix": "`mass_matrix` vs `pin.crba`",
    }
    for r in result["per_call"]:
        lines.append(f"| {r['model']} | {names[r['what']]} | {r['orbitflex_us']:.2f} | {r['pinocchio_us']:.2f} | {r['ratio']:.2f} |")
    if result.get("overhead"):
        lines += [
            "",
            "Binding overhead per call (Python time − native time of the same algorithm, µs):",
            "",
            "| model | call | orbitflex Python / Rust | overhead | Pinocchio Python / C++ | overhead | ratio |",
            "|---|---|---:|---:|---:|---:|---:|",
        ]
        for r in result["overhead"]:
            lines.append(
                f"| {r['model']} | {r['what']} | {r['orbitflex_python_us']:.2f} / {r['orbitflex_native_us']:.2f} | "
                f"{r['orbitflex_overhead_us']:.2f} | {r['pinocchio_python_us']:.2f} / {r['pinocchio_native_us']:.2f} | "
                f"{r['pinocchio_overhead_us']:.2f} | {r['ratio']:.2f} |"
            )
    lines += [
        "",
        f"Whole simulation, {result['simulation'][0]['steps']} RK4 steps at dt = {DT:g} s under a motor PD (median s):",
        "",
        "| model | orbitflex `simulate` (s) | Python RK4 loop on `pin.aba` (s) | ratio | "
        "4 × steps × `pin.aba` alone (s) | ratio to that floor | orbitflex steps/s | state agreement |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    aba_us = {r["model"]: r["pinocchio_us"] for r in result["per_call"] if r["what"] == "forward dynamics"}
    for r in result["simulation"]:
        floor = 4 * r["steps"] * aba_us[r["model"]] * 1e-6
        lines.append(
            f"| {r['model']} | {r['orbitflex_s']:.4f} | {r['pinocchio_python_loop_s']:.3f} | {r['ratio']:.3f} | "
            f"{floor:.3f} | {r['orbitflex_s'] / floor:.2f} | {r['orbitflex_steps_per_s']:,.0f} | {r['max_rel_state_diff']:.0e} |"
        )
    if result.get("python_vs_rust"):
        r = result["python_vs_rust"]
        lines += [
            "",
            f"`simulate` from Python vs the pure-Rust loop (space arm, {STEPS} steps): "
            f"{r['python_s'] * 1e3:.1f} ms vs {r['rust_s'] * 1e3:.1f} ms, ratio {r['ratio']:.3f} "
            f"({(r['ratio'] - 1) * 100:+.1f} %).",
        ]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blocks", type=int, default=15, help="alternating blocks per per-call comparison")
    ap.add_argument("--sim-blocks", type=int, default=5, help="alternating runs per simulation comparison")
    ap.add_argument("--steps", type=int, default=STEPS, help="steps per simulation (default 10^4)")
    ap.add_argument("--rounds", type=int, default=5, help="rounds for the comparisons with native programs")
    ap.add_argument("--rust-bin", help="examples/bench_cpp_match binary (cargo build --release --example bench_cpp_match)")
    ap.add_argument("--cpp-bin", help="a bench_aba_<build> binary of benches/pinocchio_cpp/run.sh, e.g. target/pinocchio_cpp/bench_aba_gcc")
    ap.add_argument("--models", default="space_arm,panda,ur5,one_link")
    ap.add_argument("--json", help="also write the results here")
    args = ap.parse_args()

    cpu = platform.processor() or platform.machine()
    try:
        cpu = next(l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name"))
    except (OSError, StopIteration):
        pass
    result = {
        "machine": f"{cpu}, {os.cpu_count()} cores",
        "python": platform.python_version(),
        "numpy": np.__version__,
        "pinocchio": pin.__version__,
        "orbitflex": getattr(orbitflex, "__version__", "?"),
    }
    with tempfile.TemporaryDirectory() as tmp:
        specs = model_specs(tmp)
        pairs = {name: Pair(name, *specs[name]) for name in args.models.split(",")}
        print("agreement with Pinocchio (joint parts, max relative difference):", file=sys.stderr)
        result["agreement"] = {}
        for name, p in pairs.items():
            c = p.check()
            result["agreement"][name] = c
            print(f"  {name:9s} " + "  ".join(f"{k} {v:.1e}" for k, v in c.items()), file=sys.stderr)
            assert max(c.values()) < 1e-8, f"{name}: orbitflex and Pinocchio disagree: {c}"
        print("per call from Python:", file=sys.stderr)
        result["per_call"] = per_call(pairs, args.blocks)
        if args.rust_bin and args.cpp_bin and {"one_link", "panda", "space_arm"} <= pairs.keys():
            print("binding overhead:", file=sys.stderr)
            result["overhead"] = binding_overhead(pairs, args.rust_bin, args.cpp_bin, args.rounds, max(5, args.blocks // 3))
        print("whole simulation:", file=sys.stderr)
        result["simulation"] = simulation({k: v for k, v in pairs.items() if k != "one_link"}, args.sim_blocks, args.steps)
        if args.rust_bin and "space_arm" in pairs:
            print("simulate from Python vs pure Rust:", file=sys.stderr)
            result["python_vs_rust"] = python_vs_rust(pairs, args.rust_bin, args.rounds)
    print(markdown(result))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(result, fh, indent=1)


if __name__ == "__main__":
    main()
