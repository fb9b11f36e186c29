"""Hold the built-in space arm's pose against a push on its end-effector with an LQR designed on
orbitflex's step Jacobians, and compare it with a motor PD.

    python examples/lqr_hold.py [--duration 4] [--out lqr_hold.png]

The arm rests at a bent pose on its free-floating bus. At t = 0.2 s something pushes the
end-effector sideways for 0.1 s (20 N). Three controllers hold the pose:

- none: the motors are left free (u = 0);
- a motor PD on the motor angles θ (kp = 400 N·m/rad, kd = 150 N·m·s/rad);
- an LQR on the joints' full state (q, θ, q̇, θ̇), designed on the discrete linearisation
  A = ∂x⁺/∂x, B = ∂x⁺/∂u of one RK4 step at the resting pose (``arm.step_jacobians``).

Free floating, the joint subsystem at rest does not depend on the base's pose or twist, so the
LQR is designed on that block alone; the bus is free and reacts as momentum requires.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import orbitflex


def joint_indices(n: int) -> np.ndarray:
    """Where δq, δθ, δq̇, δθ̇ sit in the tangent [δr | δφ | δq | δθ | δω | δv | δq̇ | δθ̇]."""
    return np.r_[6 : 6 + 2 * n, 12 + 2 * n : 12 + 4 * n]


def dlqr(a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray, iterations: int = 20000) -> np.ndarray:
    """The discrete-time LQR gain K (u = −K x) by iterating the Riccati equation to convergence."""
    p = q.copy()
    for _ in range(iterations):
        gain = np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a)
        nxt = q + a.T @ p @ (a - b @ gain)
        if np.abs(nxt - p).max() <= 1e-10 * np.abs(nxt).max():
            return gain
        p = nxt
    raise RuntimeError("the Riccati iteration did not converge")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=4.0, help="simulated time, s")
    parser.add_argument("--out", default=None, help="write a plot to this PNG")
    args = parser.parse_args(argv)

    robot = orbitflex.models.space_arm()
    arm = orbitflex.FlexibleArm(robot, orbitflex.models.space_arm_joints())
    n, dt = arm.dof, 1e-3
    q0 = np.array([0.3, -0.4, 0.5, 0.8, -0.3, 0.4, 0.2])
    x_eq = arm.state(q=q0)
    steps = int(round(args.duration / dt))

    # the push: 20 N along the EE's y axis for 0.1 s; the EE exerts −f on what pushes it
    push = np.zeros((steps, 6))
    push[200:300, 4] = -20.0

    jac = arm.step_jacobians(x_eq, dt)
    idx = joint_indices(n)
    a, b = jac["x"][np.ix_(idx, idx)], jac["u"][idx]
    weights = np.r_[np.full(n, 1e4), np.full(n, 1e2), np.full(n, 1e2), np.full(n, 1.0)]
    gain = dlqr(a, b, np.diag(weights), np.eye(n) * 1e-2)

    def lqr(t: float, x: np.ndarray) -> np.ndarray:
        return -gain @ arm.difference(x_eq, x)[idx]

    controllers = {
        "none": None,
        "motor PD": orbitflex.MotorPD(kp=400.0, kd=150.0, theta_ref=q0),
        "LQR": lqr,
    }
    ee0 = arm.ee_pose(x_eq)[:3]
    results = {}
    print(f"space arm at rest, 20 N push on the EE for 0.1 s at t = 0.2 s; dt = {dt:g} s, "
          f"{args.duration:g} s simulated")
    print(f"{'controller':<10} {'peak EE error (mm)':>20} {'final EE error (mm)':>20} {'peak |u| (N·m)':>16}")
    for name, u in controllers.items():
        traj = arm.simulate(x_eq, dt, steps, u=u, ee_wrench=push)
        # the EE relative to the bus: the bus itself drifts after the push (momentum)
        error = np.array([np.linalg.norm(p - ee0) for p in relative_ee(arm, traj)]) * 1e3
        results[name] = (traj, error)
        print(f"{name:<10} {error.max():>20.2f} {error[-1]:>20.3f} {np.abs(traj.u).max():>16.1f}")

    if args.out:
        plot(results, dt, args.out)
        print(f"wrote {args.out}")
    return 0


def relative_ee(arm: orbitflex.FlexibleArm, traj: orbitflex.Trajectory) -> np.ndarray:
    """The EE position in the bus's frame (what the arm's controller can hold), per state."""
    out = []
    for x in traj.x:
        at_origin = x.copy()
        at_origin[:7] = [0, 0, 0, 0, 0, 0, 1]
        out.append(arm.ee_pose(at_origin)[:3])
    return np.array(out)


def plot(results, dt: float, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.5))
    for name, (traj, error) in results.items():
        ax.plot(traj.t, error, label=name)
    ax.axvspan(0.2, 0.3, color="0.9", label="push (20 N)")
    ax.set(xlabel="time (s)", ylabel="EE position error in the bus frame (mm)",
           title=f"Holding the space arm's pose against a push on the EE\nmodel space_arm, dt = {dt * 1e3:g} ms")
    ax.set_yscale("symlog", linthresh=0.01)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    sys.exit(main())
