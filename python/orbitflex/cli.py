"""Command line: ``orbitflex demo`` and ``orbitflex simulate URDF``.

Both run the same job: a free-floating slew of the arm under the built-in motor-side PD
controller, long enough to show the base's reaction and the joints' vibration, then print a
summary and write plots and the trajectory into an output folder.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import List, Optional

import numpy as np

from . import FlexibleArm, FlexibleJoints, MotorPD, Robot, SimulationError, models

# Default slew for the built-in arm (rad, link side), one entry per joint.
SPACE_ARM_SLEW = np.array([0.4, 0.6, -0.5, 0.8, -0.6, 0.5, 1.0])


def quintic(s: np.ndarray) -> tuple:
    """Rest-to-rest quintic 10s^3 - 15s^4 + 6s^5 on s in [0, 1], and its derivative in s."""
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4


def pd_gains(arm: FlexibleArm, q0: np.ndarray, bandwidth_hz: float, dt: float, damping_ratio: float = 1.0):
    """Motor-side PD gains that place each joint's slow (rigid) mode near ``bandwidth_hz``:
    ``kp = w^2 (m_i + j_i)``, ``kd = 2 zeta w (m_i + j_i)``, with ``m_i`` the diagonal of ``M_r``.

    The derivative gain also creates a fast motor pole near ``-kd / j``; RK4 is stable on the real
    axis only for ``|lambda dt| < 2.78``, so ``kd`` is capped at ``0.5 j / dt``."""
    _, j, _, _ = arm.parameters
    m = np.diag(arm.robot.mass_matrix(q0))[6:]
    w = 2 * np.pi * bandwidth_hz
    return w**2 * (m + j), np.minimum(2 * damping_ratio * w * (m + j), 0.5 * j / dt)


def slew_controller(arm: FlexibleArm, slew: np.ndarray, steps: int, dt: float, slew_time: float,
                    bandwidth_hz: float) -> MotorPD:
    """The motor PD that follows a quintic slew of ``slew`` (rad per joint) over ``slew_time``
    seconds, tabulated for ``steps`` steps of ``dt``."""
    t = np.arange(steps) * dt
    shape, dshape = quintic(t / slew_time)
    theta_ref = np.outer(shape, slew)
    theta_dot_ref = np.outer(dshape / slew_time, slew)
    kp, kd = pd_gains(arm, np.zeros(arm.dof), bandwidth_hz, dt)
    return MotorPD(kp, kd, theta_ref, theta_dot_ref)


def run_slew(arm: FlexibleArm, pd: MotorPD, steps: int, dt: float, progress: bool = True):
    """Simulates ``steps`` steps under ``pd`` in one ``simulate`` call, with a progress bar;
    returns ``(trajectory, seconds)``. A run that stops early keeps the steps computed before it."""
    bar = _progress(steps, progress)
    start = time.perf_counter()
    try:
        traj = arm.simulate(arm.state(), dt, steps, u=pd, progress=bar.to)
    except SimulationError as e:
        traj = e.trajectory
        reason = str(e).split(": ", 1)[-1]
        print(f"warning: the run stopped at step {e.step} (t = {e.time:.6g} s): {reason}; "
              f"keeping the {len(traj) - 1} steps computed", file=sys.stderr)
    elapsed = time.perf_counter() - start
    bar.close()
    return traj, elapsed


class _NoBar:
    def to(self, done: int, total: int) -> None:
        pass

    def close(self) -> None:
        pass


class _Bar:
    """A tqdm bar driven by ``simulate``'s ``progress(done, total)`` callback."""

    def __init__(self, total: int):
        from tqdm import tqdm

        self.bar = tqdm(total=total, unit="step", desc="simulating", file=sys.stderr, mininterval=0.25)

    def to(self, done: int, total: int) -> None:
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        self.bar.close()


def _progress(total: int, enabled: bool):
    if not enabled:
        return _NoBar()
    try:
        return _Bar(total)
    except ImportError:  # tqdm is a dependency, but keep the simulator usable without it
        return _NoBar()


def rotation_angle_deg(q0: np.ndarray, q1: np.ndarray) -> float:
    """Angle (deg) of the rotation between two unit quaternions (x, y, z, w)."""
    return float(np.degrees(2 * np.arccos(np.clip(abs(np.dot(q0, q1)), -1.0, 1.0))))


def energy_balance(traj) -> tuple:
    """Energy bookkeeping of the power balance (docs/model.md, section 6) with the trapezoid rule
    on the recorded states (``traj.u`` held over each step): returns
    ``(E(T) - E(0), motor work, dissipated energy)``. With no external wrench,
    ``E(T) - E(0) = motor work - dissipated`` up to the quadrature and RK4 errors."""
    u = traj.u
    _, _, d, beta = traj.arm.parameters
    td, qd = traj.theta_dot, traj.qd
    rows = len(u)
    dt = np.diff(traj.t[: rows + 1])
    dissipation = ((td - qd) ** 2 * d).sum(axis=1) + (td**2 * beta).sum(axis=1)
    motor = 0.5 * ((u * td[:rows]).sum(axis=1) + (u * td[1 : rows + 1]).sum(axis=1))
    work = float(np.sum(dt * motor))
    dissipated = float(np.sum(0.5 * dt * (dissipation[:rows] + dissipation[1 : rows + 1])))
    return float(traj.energy[rows] - traj.energy[0]), work, dissipated


def summarise(name: str, traj, elapsed: float) -> dict:
    steps = len(traj.t) - 1
    h = traj.momentum
    h_drift = np.abs(h - h[0]).max(axis=0)
    de, work, dissipated = energy_balance(traj)
    gross = float(np.sum(np.abs(np.diff(traj.energy)))) or 1.0
    summary = {
        "model": name,
        "steps": steps,
        "simulated_s": float(traj.t[-1]),
        "steps_per_second": steps / elapsed if elapsed > 0 else float("inf"),
        "base_attitude_change_deg": rotation_angle_deg(traj.base_pose[0, 3:], traj.base_pose[-1, 3:]),
        "base_displacement_m": float(np.linalg.norm(traj.base_pose[-1, :3] - traj.base_pose[0, :3])),
        "max_deflection_deg": float(np.degrees(np.abs(traj.deflection).max())),
        "max_deflection_joint": traj.arm.robot.joint_names[int(np.abs(traj.deflection).max(axis=0).argmax())],
        "momentum_drift_angular": float(h_drift[:3].max()),
        "momentum_drift_linear": float(h_drift[3:].max()),
        "energy_change_J": de,
        "motor_work_J": work,
        "dissipated_J": dissipated,
        "energy_balance_residual_J": de - (work - dissipated),
        "energy_flow_J": gross,
        "ee_travel_m": float(np.linalg.norm(traj.ee_pose[-1, :3] - traj.ee_pose[0, :3])),
    }
    print(f"\norbitflex: free-floating slew of '{name}' ({traj.arm.dof} flexible joints)")
    print(f"  simulated           {summary['simulated_s']:.1f} s in {steps} RK4 steps, "
          f"{summary['steps_per_second']:,.0f} steps/s")
    print(f"  base attitude       changed by {summary['base_attitude_change_deg']:.3f} deg "
          f"(origin moved {summary['base_displacement_m'] * 1e3:.2f} mm)")
    print(f"  joint deflection    max {summary['max_deflection_deg']:.4f} deg at {summary['max_deflection_joint']}")
    print(f"  EE travel           {summary['ee_travel_m']:.3f} m")
    print(f"  momentum drift      {summary['momentum_drift_angular']:.2e} N m s (angular), "
          f"{summary['momentum_drift_linear']:.2e} N s (linear)  (RK4 truncation)")
    print(f"  energy balance      motors {work:+.6g} J, damping {-dissipated:+.6g} J, "
          f"E(T) - E(0) = {de:+.6g} J; residual {de - work + dissipated:.2e} J "
          f"({abs(de - work + dissipated) / gross:.1e} of the {gross:.4g} J that flowed)")
    return summary


def plot(traj, out: Path) -> List[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = traj.t
    names = traj.arm.robot.joint_names
    files = []

    def save(fig, name):
        path = out / name
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        files.append(path)

    fig, ax = plt.subplots(figsize=(9, 5))
    for i, name in enumerate(names):
        line, = ax.plot(t, np.degrees(traj.q[:, i]), label=f"q {name}")
        ax.plot(t, np.degrees(traj.theta[:, i]), "--", color=line.get_color(), lw=1)
    ax.set(xlabel="time (s)", ylabel="angle (deg)", title="Link angles q (solid) and motor angles θ (dashed)")
    ax.legend(fontsize=7, ncol=2)
    save(fig, "joint_vs_motor_angles.png")

    fig, ax = plt.subplots(figsize=(9, 5))
    for i, name in enumerate(names):
        ax.plot(t, np.degrees(traj.deflection[:, i]), label=name)
    ax.set(xlabel="time (s)", ylabel="θ − q (deg)", title="Joint deflection (spring stretch)")
    ax.legend(fontsize=7, ncol=2)
    save(fig, "deflection.png")

    quat = traj.base_pose[:, 3:]
    x, y, z, w = quat.T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    fig, ax = plt.subplots(figsize=(9, 4))
    for v, label in ((roll, "roll"), (pitch, "pitch"), (yaw, "yaw")):
        ax.plot(t, np.degrees(v), label=label)
    ax.set(xlabel="time (s)", ylabel="deg", title="Base attitude (roll-pitch-yaw of the bus): the reaction to the slew")
    ax.legend()
    save(fig, "base_attitude.png")

    p = traj.ee_pose[:, :3]
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    ax.plot(p[:, 0], p[:, 1], p[:, 2])
    ax.scatter(*p[0], color="green", label="start")
    ax.scatter(*p[-1], color="red", label="end")
    ax.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title="EE path in the inertial frame")
    ax.legend()
    save(fig, "ee_path.png")

    h = traj.momentum
    fig, ax = plt.subplots(figsize=(9, 4))
    labels = ["Kx", "Ky", "Kz", "Lx", "Ly", "Lz"]
    for i in range(6):
        ax.plot(t, h[:, i] - h[0, i], label=labels[i], lw=1)
    ax.set(xlabel="time (s)", ylabel="h(t) − h(0)", title="Momentum drift (angular N·m·s, linear N·s): round-off level")
    ax.legend(ncol=6, fontsize=8)
    save(fig, "momentum_drift.png")
    return files


def _run(arm, name, slew, args) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    steps = int(round(args.duration / args.dt))
    pd = slew_controller(arm, slew, steps, args.dt, args.slew_time, args.bandwidth)
    limit = arm.rk4_stability_limit(u=pd)
    print(f"{name}: {arm.dof} joints, total mass {arm.robot.total_mass:.1f} kg, "
          f"dt = {args.dt:g} s (RK4 limit of the closed loop at rest: {limit:.3g} s)")
    traj, elapsed = run_slew(arm, pd, steps, args.dt, progress=not args.quiet)
    summary = summarise(name, traj, elapsed)
    traj.save_npz(out / "trajectory.npz")
    files = [] if args.no_plots else plot(traj, out)
    print(f"\nwrote {out / 'trajectory.npz'}" + "".join(f"\n      {f}" for f in files))
    import json

    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return 0 if len(traj.t) - 1 == int(round(args.duration / args.dt)) else 1


def _common(p: argparse.ArgumentParser, duration: float) -> None:
    p.add_argument("--duration", type=float, default=duration, help="simulated time, s (default %(default)s)")
    p.add_argument("--dt", type=float, default=1e-3, help="RK4 step, s (default %(default)s)")
    p.add_argument("--slew-time", type=float, default=5.0, help="duration of the quintic slew, s (default %(default)s)")
    p.add_argument("--bandwidth", type=float, default=0.25, help="PD bandwidth per joint, Hz (default %(default)s)")
    p.add_argument("--out", default="orbitflex_out", help="output folder (default %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="orbitflex", description="Flexible-joint space manipulator simulation.")
    sub = parser.add_subparsers(dest="command")
    demo = sub.add_parser("demo", help="simulate the built-in space arm (bus + 7-joint arm), free floating")
    _common(demo, 20.0)
    sim = sub.add_parser("simulate", help="simulate your URDF, free floating, with the same slew")
    sim.add_argument("urdf", help="path to the URDF; the root link is the floating base")
    sim.add_argument("--params", required=True, help="joint-parameter TOML keyed by joint name")
    sim.add_argument("--ee-link", default=None, help="EE link (default: the unique leaf)")
    sim.add_argument("--locked-joints", nargs="*", default=None, help="joints held at zero (e.g. fingers)")
    sim.add_argument("--slew", type=float, nargs="*", default=None,
                     help="slew per joint, rad (default 0.3 rad on every joint)")
    _common(sim, 10.0)
    args = parser.parse_args(argv)
    if args.command is None:
        args = parser.parse_args(["demo"] + (argv or []))
    for name in ("duration", "dt", "slew_time", "bandwidth"):
        value = getattr(args, name)
        if not (np.isfinite(value) and value > 0):
            parser.error(f"--{name.replace('_', '-')}: expected a finite number > 0, given {value}")
    if args.dt > args.duration:
        parser.error(f"--dt: expected at most --duration ({args.duration}), given {args.dt}")
    try:
        if args.command == "demo":
            robot = models.space_arm()
            arm = FlexibleArm(robot, models.space_arm_joints())
            return _run(arm, robot.name, SPACE_ARM_SLEW, args)
        robot = Robot.from_urdf(args.urdf, ee_link=args.ee_link, locked_joints=args.locked_joints)
        arm = FlexibleArm(robot, FlexibleJoints.from_toml(args.params, robot))
        slew = np.full(robot.dof, 0.3) if not args.slew else np.asarray(args.slew, dtype=float)
        if len(slew) == 1:
            slew = np.full(robot.dof, slew[0])
        if len(slew) != robot.dof:
            parser.error(f"--slew: expected 1 or {robot.dof} values, given {len(slew)}")
        return _run(arm, robot.name, slew, args)
    except (ValueError, FileNotFoundError) as e:
        print(f"orbitflex: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
