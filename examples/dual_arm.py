"""One arm of the built-in dual-arm servicer slews; the other holds still. How much does the slew
disturb the holding arm's end-effector and the bus?

    python examples/dual_arm.py [--out dual_arm.png]

The servicer (``orbitflex.models.dual_arm()``: a 500 kg bus, two 7-joint, 86 kg arms mounted
0.9 m apart on its front face) floats free with zero momentum. The left arm follows a
minimum-time slew planned for the flexible joints (``plan_slew`` with the base free), driven by a
motor PD with the plan's feedforward. The right arm's motors hold their angles at zero with a
stiffer motor PD (5000 N·m/rad, 300 N·m·s/rad) and no feedforward, as a holding arm would: it learns of the slew only through the bus
and through its own compliant joints.

Printed, and plotted with ``--out``:

- the bus attitude change (deg) and the drift of its centre (mm);
- the right end-effector's displacement in the inertial frame (mm): the bus's motion carries it;
- the right end-effector's displacement relative to the bus (mm): the reaction torques bend the
  right arm's joints (spring deflection) and push its motors off their references.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import orbitflex

DT = 1e-3  # s
# the left arm's slew: a reach from the folded pose (joints 0-6); the right arm stays at zero
LEFT_GOAL = [0.6, -0.5, 0.4, 0.9, -0.6, 0.5, 0.8]


def rotation_angle_deg(q0: np.ndarray, q1: np.ndarray) -> float:
    """The angle (deg) of the rotation between two unit quaternions (x, y, z, w)."""
    return float(np.degrees(2.0 * np.arccos(min(1.0, abs(float(np.dot(q0, q1)))))))


def run(settle: float = 2.0, hold_kp: float = 5000.0, hold_kd: float = 300.0):
    """The slew and the hold; returns the plan, the trajectory and the derived series."""
    robot = orbitflex.models.dual_arm()
    arm = orbitflex.FlexibleArm(robot, orbitflex.models.dual_arm_joints())
    n = robot.dof
    goal = np.zeros(n)
    goal[:7] = LEFT_GOAL
    # the URDF's joint speeds (0.15–0.4 rad/s), and a motor budget within its efforts
    torque = [60, 60, 60, 30, 15, 15, 15] * 2
    limits = orbitflex.Limits(motor_torque=torque, joint_speed=robot.velocity_limits)
    plan = orbitflex.plan_slew(arm, goal, limits=limits, base="free")

    steps = int(np.ceil((plan.duration + settle) / DT))
    ref = plan.reference(DT, steps)
    feedforward = np.array(ref["u"])
    feedforward[:, 7:] = 0.0  # the right arm holds with feedback alone
    theta_ref = np.array(ref["theta_ref"])
    theta_dot_ref = np.array(ref["theta_dot_ref"])
    theta_ref[:, 7:] = 0.0
    theta_dot_ref[:, 7:] = 0.0
    # left arm: the gains that track the plan; right arm: a stiffer hold (kd within RK4's
    # stability limit at this dt for the wrist motors' inertia)
    kp = np.r_[np.full(7, 1000.0), np.full(7, hold_kp)]
    kd = np.r_[np.full(7, 100.0), np.full(7, hold_kd)]
    pd = orbitflex.MotorPD(kp=kp, kd=kd, theta_ref=theta_ref, theta_dot_ref=theta_dot_ref,
                           feedforward=feedforward)
    traj = arm.simulate(plan.initial_state(), DT, steps, u=pd)

    right = robot.ee_links.index("right_ee")
    ee = np.asarray(traj.ee_pose)[:, right, :3]  # (rows, 3), inertial frame
    identity = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    relative = np.array([robot.body_poses(identity, q)[n + 1 + right, :3] for q in traj.q])
    base = np.asarray(traj.base_pose)
    series = {
        "t": np.asarray(traj.t),
        "bus_attitude_deg": np.array([rotation_angle_deg(base[0, 3:], b[3:]) for b in base]),
        "bus_drift_mm": 1e3 * np.linalg.norm(base[:, :3] - base[0, :3], axis=1),
        "right_ee_inertial_mm": 1e3 * np.linalg.norm(ee - ee[0], axis=1),
        "right_ee_on_bus_mm": 1e3 * np.linalg.norm(relative - relative[0], axis=1),
        "right_deflection_mrad": 1e3 * np.abs(np.asarray(traj.deflection)[:, 7:]).max(axis=1),
    }
    return robot, plan, traj, series


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=None, help="write a plot to this PNG")
    args = parser.parse_args(argv)

    robot, plan, traj, s = run()
    h = np.asarray(traj.momentum)
    print(f"{robot.name}: {robot.dof} joints, end-effectors {robot.ee_links}, dt = {DT} s")
    print(f"left-arm slew: {plan.duration:.2f} s, bound by {plan.binding['limit']} on "
          f"{plan.binding['joint_name']}; run {s['t'][-1]:.2f} s")
    print(f"bus: turned up to {s['bus_attitude_deg'].max():.2f} deg, centre moved up to "
          f"{s['bus_drift_mm'].max():.1f} mm")
    print(f"right EE: moved up to {s['right_ee_inertial_mm'].max():.1f} mm in the inertial frame, "
          f"{s['right_ee_on_bus_mm'].max():.3f} mm relative to the bus "
          f"(joint deflection up to {s['right_deflection_mrad'].max():.3f} mrad)")
    print(f"momentum stays zero: |h| ≤ {np.abs(h).max():.1e}")

    if args.out:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(3, 1, figsize=(8, 8.5), sharex=True, layout="constrained")
        fig.suptitle(f"{robot.name}: the left arm slews, the right arm holds (dt = {DT} s)",
                     fontsize=11)
        t = s["t"]
        axes[0].plot(t, s["bus_attitude_deg"], color="tab:purple")
        axes[0].set(ylabel="bus attitude change (deg)")
        twin = axes[0].twinx()
        twin.plot(t, s["bus_drift_mm"], color="tab:gray", ls="--")
        twin.set(ylabel="bus centre drift (mm), dashed")
        axes[1].plot(t, s["right_ee_inertial_mm"], color="tab:blue")
        axes[1].set(ylabel="right EE, inertial (mm)")
        axes[2].plot(t, s["right_ee_on_bus_mm"], color="tab:red")
        axes[2].set(xlabel="time (s)", ylabel="right EE relative to the bus (mm)")
        twin = axes[2].twinx()
        twin.plot(t, s["right_deflection_mrad"], color="tab:orange", ls="--")
        twin.set(ylabel="largest right-arm |θ − q| (mrad), dashed")
        for ax in axes:
            ax.axvline(plan.duration, color="black", lw=0.6, ls=":")
            ax.grid(alpha=0.3)
        axes[0].set_title("dotted line: the end of the left arm's slew", fontsize=9)
        fig.savefig(args.out, dpi=110)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
