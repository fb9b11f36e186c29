# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""``orbitflex demo`` and ``orbitflex simulate``: run the slew, print the summary, write the
outputs."""

from __future__ import annotations

import argparse
import json
import sys
import textwrap
import time
import warnings
from pathlib import Path
from typing import Any, Dict, List, Optional, TYPE_CHECKING

import numpy as np

from .. import FlexibleArm, MotorPD, SimulationError, Trajectory, models
from .errors import CliError, output_folder
from .jobs import Job, Outcome, ProgressBar, WarningPrinter, failure_reason
from .memory import check_memory, step_count
from .plan import (
    DEMO_PLAN_GOAL, PLAN_OUTPUTS, comparison_summary, demo_comparison, describe_binding,
    limits_dict, print_comparison,
)
from .plan_plots import plan_caption, plot_plan_speed, plot_plan_torque, plot_plan_vs_rigid
from .plots import Figures, plot
from .robots import BUS_SIDE, DEFAULTS_SCALING, load_arm
from .slew import SPACE_ARM_SLEW, check_step, choose_gains, per_joint, slew_controller
from .summary import divergence_onset, gain_text, print_summary, summarise
from .wheels import WHEELS_OUTPUTS, plot_wheel_case, print_wheel_case, run_wheel_case, wheels_for

if TYPE_CHECKING:
    from .plan import Comparison


OUTPUTS = {
    "trajectory.npz": "t, x (named columns), u, momentum, energy, EE pose, spring torque, deflection",
    "trajectory.csv": "t and x with named columns (--csv)",
    "summary.json": "the summary above, as numbers",
    "joint_vs_motor_angles.png": "link angles q and motor angles θ; below, the motor lead θ − q",
    "deflection.png": "joint deflection θ − q, one panel per joint, with its peak spring torque",
    "base_attitude.png": "bus yaw, pitch, roll (z-y'-x'') and total rotation since t = 0",
    "ee_path.png": "EE path in 3-D (equal axes) with the arm and bus at the start and end; zoomed",
    "momentum_drift.png": "drift of angular (N·m·s) and linear (N·s) momentum",
    "animation.html": "3-D animation, opens offline in a browser: bus, arm, EE trail, motor-side ghost",
}


SIMULATE_EPILOG = """\
joint parameters (--params joints.toml): [defaults] applies to every joint, and a
[joints.<name>] table (URDF joint name) overrides it for one joint; link-side SI units:
  stiffness      spring between motor and link, N·m/rad (required)
  motor_inertia  motor inertia seen from the link, kg·m²; or instead:
  gear_ratio     with rotor_inertia: motor_inertia = gear_ratio² · rotor_inertia
  rotor_inertia  rotor inertia, kg·m²
  damping        damper in parallel with the spring, N·m·s/rad (default 0)
  motor_damping  motor friction, N·m·s/rad (default 0)

example joints.toml:
  [defaults]
  stiffness = 1.5e4
  gear_ratio = 100.0
  rotor_inertia = 5e-5
  damping = 1.0
  motor_damping = 0.05

  [joints.elbow]
  stiffness = 8e3
  motor_inertia = 0.5

{defaults}

examples:
  orbitflex simulate ur5_robot.urdf --ee-link tool0 --base-mass 500
  orbitflex simulate arm.urdf --params joints.toml --locked-joints finger1,finger2 --csv
""".format(defaults=textwrap.fill(f"without --params: FlexibleJoints.defaults_for(robot): {DEFAULTS_SCALING}.", 88))


def simulate(arm: FlexibleArm, pd: MotorPD, steps: int, dt: float, progress: bool,
             record_every: int = 1) -> Outcome:
    """Simulates ``steps`` steps under ``pd`` in one ``simulate`` call, keeping one row in
    ``record_every`` (and the final row). A run that diverges keeps the rows computed before the
    failure, the last good state last."""
    bar = ProgressBar(steps) if progress else None
    printer = WarningPrinter()
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = printer
        try:
            traj = arm.simulate(arm.state(), dt, steps, u=pd, progress=bar.to if bar else None,
                                record_every=record_every)
            outcome = Outcome(traj, time.perf_counter() - start, record_every=record_every)
        except SimulationError as e:
            outcome = Outcome(e.trajectory, time.perf_counter() - start, e, record_every=record_every)
    if bar is not None:
        bar.close()
    outcome.warnings = printer.count
    if outcome.failure is not None:
        kept = outcome.failure.step
        where = ""
        if record_every == 1 and "diverged" in str(outcome.failure):
            outcome.onset = divergence_onset(outcome.traj)
            where = (f"; the divergence set in after step {outcome.onset} (t = {outcome.traj.t[outcome.onset]:.6g} s): "
                     f"the summary and plots describe the run up to there")
        print(f"orbitflex: the run failed: {failure_reason(outcome.failure)}; the files keep the {kept} "
              f"steps before the failure{where} (exit code 1)", file=sys.stderr)
    return outcome


def run(job: Job, args: argparse.Namespace) -> int:
    steps = step_count(args.duration, args.dt, "--duration/--dt", "shorten --duration or lengthen --dt")
    check_memory(steps, job.arm.dof, record_every=args.record_every)
    gains = choose_gains(job.arm, args)
    pd = slew_controller(job.arm, job.slew, steps, args.dt, args.slew_time, gains)
    limit = check_step(job.arm, pd, gains, args.dt, args.force)
    out = output_folder(args.out)
    print(f"{job.name}: {job.arm.dof} joints, total mass {job.arm.robot.total_mass:.1f} kg, "
          f"dt = {args.dt:g} s (RK4 limit of the closed loop at rest: {limit:.3g} s)")
    if job.note:
        print(job.note)
    modes = None
    if job.compare_plans:  # the demo: the structural modes its controller closes (docs/modes.md)
        from ..analysis import closed_loop_modes

        modes, line = closed_loop_modes(job.arm, job.arm.state(), pd, count=3, base="free")
        print(line)
    outcome = simulate(job.arm, pd, steps, args.dt, progress=not args.quiet, record_every=args.record_every)
    wheels = wheels_for(args, demo=job.compare_plans)
    wheel_case = None
    if wheels is not None and outcome.failure is None:
        wheel_case = run_wheel_case(job, wheels, pd, steps, args.dt, outcome.meaningful(), args.record_every)
    elif wheels is not None:
        print("orbitflex: the wheel case is not run: the free-floating run it is compared with failed",
              file=sys.stderr)
    comparison, note = demo_comparison(job.arm, job.name, args.dt) if job.compare_plans else (None, None)
    with np.errstate(all="ignore"):  # a diverged run's finite part may overflow in the summary
        summary = summarise(job.name, outcome, steps)
        summary["controller"] = {**gains.as_dict(), "rk4_stability_limit_s": limit}
        if modes is not None:
            summary["closed_loop_modes"] = [
                {"frequency_hz": float(f), "damping_ratio": float(z), "dominant_joint": str(j)}
                for f, z, j in zip(modes.frequency_hz[:3], modes.damping_ratio[:3], modes.dominant_joints[:3])]
        if comparison is not None:
            summary["planned_slew"] = {"goal_rad": DEMO_PLAN_GOAL.tolist(), "base": comparison.plan.base,
                                       "limits": limits_dict(comparison.plan.limits),
                                       **comparison_summary(comparison)}
        if wheel_case is not None:
            summary["wheels"] = wheel_case.summary()
        files = write_outputs(job, outcome, summary, out, args, comparison)
        if wheel_case is not None and not args.no_plots:
            files += plot_wheel_case(wheel_case, job, args.dt, out)
    print_summary(summary, job.arm.dof)
    if wheel_case is not None:
        print_wheel_case(wheel_case)
    if comparison is not None:
        print_demo_comparison(comparison, note)
    descriptions = {**OUTPUTS, **PLAN_OUTPUTS, **WHEELS_OUTPUTS}
    width = max(len(str(f)) for f in files)
    print(f"\nwrote {len(files)} files:")
    for f in files:
        print(f"  {str(f):<{width}}  {descriptions[f.name]}")
    return 0 if outcome.failure is None else 1


def print_demo_comparison(c: Comparison, note: Optional[str]) -> None:
    """The demo's planned slew beside its rigid-joint plan."""
    limits = c.plan.limits
    goal = ", ".join(f"{v:g}" for v in DEMO_PLAN_GOAL)
    print(f"\norbitflex: minimum-time slew of '{c.name}' to q = [{goal}] rad, free floating, planned "
          f"with the flexible joints and as if they were rigid")
    print(f"  limits (the URDF's) motor torque {gain_text(np.asarray(limits.motor_torque))} N·m, "
          f"joint speed {gain_text(np.asarray(limits.joint_speed))} rad/s")
    print(f"  flexible plan       {c.plan.duration:.4f} s, binding {describe_binding(c.plan)}")
    print(f"  rigid-joint plan    {c.rigid.duration:.4f} s, binding {describe_binding(c.rigid)}")
    if note:
        print(f"  note                {note}")
    print_comparison(c)


def animation(job: Job, traj: Trajectory, out: Path, args: argparse.Namespace) -> List[Path]:
    """``animation.html`` (:func:`orbitflex.viz.write_animation`, 30 frames per simulated second,
    with the motor-side ghost, and the bus of ``--base-mass`` as a translucent cube), or nothing,
    with a note, when meshcat is not installed."""
    try:
        from .. import viz

        viz._meshcat()
    except ImportError:
        print("note: animation.html not written: the 3-D view needs pip install 'orbitflex[viz]'")
        return []
    path = out / "animation.html"
    packages = dict(getattr(args, "package", None) or [])
    bus = []
    if getattr(args, "base_mass", None) is not None:
        bus = [{"kind": "box", "size": [job.bus_side] * 3, "origin": [*job.bus_com, 0, 0, 0, 1],
                "color": [0.85, 0.68, 0.28, 0.45]}]
    viz.write_animation(traj, path, fps=viz.DEFAULT_FPS, ghost=True, packages=packages, shapes=bus)
    return [path]


def write_outputs(job: Job, outcome: Outcome, summary: Dict[str, Any], out: Path,
                  args: argparse.Namespace, comparison: Optional["Comparison"] = None) -> List[Path]:
    traj = outcome.traj
    files = [out / "trajectory.npz"]
    try:
        traj.save_npz(files[0])
        if args.csv:
            files.append(out / "trajectory.csv")
            traj.save_csv(files[-1])
        files.append(out / "summary.json")
        files[-1].write_text(json.dumps(summary, indent=2))
        if not args.no_plots:
            files += plot(job, outcome, args.dt, out)
            if comparison is not None:
                figures = Figures(out, plan_caption(comparison))
                plot_plan_vs_rigid(figures, comparison)
                plot_plan_torque(figures, comparison)  # every limit the plan respects, against it
                plot_plan_speed(figures, comparison)
                files += figures.files
    except OSError as e:
        raise CliError("--out", f"cannot write {files[-1]}: {e.strerror or e}") from None
    if not args.no_animation:
        try:
            files += animation(job, traj, out, args)
        except OSError as e:
            raise CliError("--out", f"cannot write {out / 'animation.html'}: {e.strerror or e}") from None
    return files


def demo_job(args: argparse.Namespace) -> Job:
    robot = models.space_arm()
    arm = FlexibleArm(robot, models.space_arm_joints())
    return Job(arm, robot.name, SPACE_ARM_SLEW, BUS_SIDE, np.zeros(3), compare_plans=True)


def simulate_job(args: argparse.Namespace) -> Job:
    arm, side, com, note = load_arm(args)
    slew = per_joint(args.slew, "--slew", arm.robot, default=0.3)
    return Job(arm, arm.robot.name, slew, side, com, note)
