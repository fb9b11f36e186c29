# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""``orbitflex plan`` and the demo's planned slew: plan with and without the flexible joints, track
both, compare."""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional, TYPE_CHECKING, Tuple

import numpy as np

from .. import FlexibleArm, Limits, MotorPD, Plan, Robot, SimulationError, plan_slew
from .errors import CliError, output_folder
from .jobs import Job, WarningPrinter, failure_reason
from .memory import check_memory, step_count
from .plan_plots import plot_plan
from .plan_wheels import print_wheel_plan, wheel_plan
from .plots import seconds
from .robots import load_arm
from .slew import DT_MARGIN, per_joint, round_down
from .summary import gain_text, torque_share

if TYPE_CHECKING:
    from .slew import Array


# The demo's planned slew (rad), under the built-in URDF's own limits (Limits.from_urdf: its
# <limit effort velocity>): the shoulders' 0.15 rad/s binds.
DEMO_PLAN_GOAL = np.array([0.8, -0.6, 0.5, 1.0, -0.7, 0.6, 0.9])


DEMO_KP, DEMO_KD = 1000.0, 100.0


# Default tracking PD of `orbitflex plan`: each motor a critically damped servo at this
# frequency on its own inertia j: kp = j ω², kd = 2 j ω.
SERVO_HZ = 5.0


# Default RK4 step of the tracking runs (s), lowered to a round value within this share of the
# stability limit when the limit requires it.
TRACK_DT = 1e-3


PLAN_OUTPUTS = {
    "plan.npz": "both plans' arrays, the per-step reference tables, the tracking runs and measures",
    "plan_summary.json": "the summary above, as numbers",
    "plan_angles.png": "planned link angles q, with the stops and the binding instant",
    "plan_deflection.png": "planned joint deflection θ − q per joint, and the tracking run's",
    "plan_motor_torque.png": "planned motor torque u per joint against its limit, scaled to the data",
    "plan_joint_speed.png": "planned joint speed q̇ per joint against its limit, scaled to the data",
    "plan_base.png": "held base: the wrench that holds it, against its limits; free: its attitude",
    "plan_vs_rigid.png": "flexible plan vs rigid-joint plan, both run on the flexible arm",
}


PLAN_EPILOG = """\
Values per joint (--goal, --start, --waypoint, --motor-torque, --joint-speed, --kp, --kd) are
one value for every joint or one per joint, in the model's joint order (depth-first from the
base: base to EE on a chain, one arm after another on a tree); angles in
rad, link side.

Limits: by default the URDF's own, <limit effort> as the motor torque after the gearbox and
<limit velocity> as the joint speed; --motor-torque and --joint-speed replace them (a warning
says where they allow more). A start, waypoint or goal outside a joint's <limit lower upper>
is refused.

The planner (orbitflex.plan_slew) moves every joint along q_a + (q_b − q_a) σ(t/T), σ of degree
9 with derivatives 1–4 zero at both ends, and finds the shortest T per segment for which every
limit holds, with the flexible-joint inverse dynamics (so u includes the motors' extra work to
stretch the springs). The rigid-joint plan of the same slew ignores the springs. Both are then
simulated on the flexible arm (RK4, a motor PD around the plan's θ with its feedforward u, and for
a held base the base wrench), and compared: peak commanded torque against the limit, tracking
error, residual vibration after the slew, base disturbance.

tracking PD: by default kp = j (2π·{hz:g} Hz)² and kd = 2 j (2π·{hz:g} Hz) per joint, j the motor
inertia: a critically damped motor servo. --dt must be within the RK4 stability limit of that
loop (checked; the default 1 ms is lowered when needed).

examples:
  orbitflex plan ur5_robot.urdf --ee-link tool0 --base-mass 500 --goal 0.5 -0.4 0.6 0.3 0.2 0.1 \\
      --motor-torque 150 150 150 28 28 28 --joint-speed 1.0 --base free
  orbitflex plan arm.urdf --params joints.toml --goal 0.5 --waypoint 0.2 --motor-torque 40 \\
      --joint-speed 0.8 --base held --base-force 50 --base-torque 40
""".format(hz=SERVO_HZ)


def servo_gains(arm: FlexibleArm, hz: float = SERVO_HZ) -> Tuple[Array, Array]:
    """``kp = j ω²``, ``kd = 2 j ω`` (ω = 2π hz): each motor a critically damped servo on its own
    inertia ``j`` (:meth:`FlexibleArm.motor_servo_gains`)."""
    kp, kd = arm.motor_servo_gains(hz)
    return kp, kd


def tracking_limit(arm: FlexibleArm, stops: Array, kp: Array, kd: Array) -> float:
    """The RK4 stability limit (s) of the arm under the tracking PD, the smallest over the
    stops (at rest, springs relaxed)."""
    return min(arm.rk4_stability_limit(arm.state(q=stop), MotorPD(kp, kd, stop)).dt for stop in stops)


def tracking_dt(limit: float, requested: Optional[float], flag: str = "--dt") -> Tuple[float, Optional[str]]:
    """The tracking step: ``requested`` if within ``limit``, else a clean error; by default
    TRACK_DT, or a round value within DT_MARGIN of the limit (with a note saying so)."""
    if requested is not None:
        if requested > limit:
            raise CliError(flag, f"{requested:g} s is past the RK4 stability limit {limit:.3g} s of the "
                                 f"arm under the tracking PD (at rest at the stops); use {flag} "
                                 f"{round_down(DT_MARGIN * limit):g} or less, or lower --kp/--kd")
        return requested, None
    if TRACK_DT <= DT_MARGIN * limit:
        return TRACK_DT, None
    dt = round_down(DT_MARGIN * limit)
    return dt, (f"dt = {seconds(dt)}: the default {seconds(TRACK_DT)} is past {DT_MARGIN:.0%} of the RK4 "
                f"stability limit {limit:.3g} s of the arm under the tracking PD")


@dataclass
class Comparison:
    """A plan and its rigid-joint counterpart, both tracked on the flexible arm."""

    name: str  # the model
    plan: Plan
    rigid: Plan
    flexible_run: Dict[str, Any]  # Plan.track's dict
    rigid_run: Dict[str, Any]
    dt: float
    kp: Array
    kd: Array
    settle: float
    elapsed: float  # s of wall time for planning and tracking

    @property
    def runs(self) -> Tuple[Tuple[str, Plan, Dict[str, Any]], Tuple[str, Plan, Dict[str, Any]]]:
        return (("flexible plan", self.plan, self.flexible_run), ("rigid-joint plan", self.rigid, self.rigid_run))


def compare(name: str, plan: Plan, dt: float, kp: Array, kd: Array, settle: float) -> Comparison:
    """Plans the rigid-joint counterpart of ``plan`` and tracks both on the flexible arm."""
    start = time.perf_counter()
    rigid = plan.rigid()
    flexible_run = plan.track(dt, kp, kd, settle)
    rigid_run = rigid.track(dt, kp, kd, settle)
    return Comparison(name, plan, rigid, flexible_run, rigid_run, dt, kp, kd, settle,
                      time.perf_counter() - start)


def comparison_summary(c: Comparison) -> Dict[str, Any]:
    names = c.plan.arm.robot.joint_names
    out: Dict[str, Any] = {"dt_s": c.dt, "kp": c.kp.tolist(), "kd": c.kd.tolist(), "settle_s": c.settle}
    for key, plan, run in (("flexible", c.plan, c.flexible_run), ("rigid", c.rigid, c.rigid_run)):
        share, joint = torque_share(plan, run)
        binding = plan.binding
        out[key] = {
            "duration_s": plan.duration,
            "binding": {k: binding[k] for k in ("limit", "joint", "joint_name", "segment", "time", "value", "bound")},
            "peak_motor_torque_Nm": run["peak_motor_torque"].tolist(),
            "peak_torque_over_limit": share,
            "peak_torque_joint": names[joint],
            "tracking_error_rad": run["tracking_error"],
            "residual_deflection_rad": run["residual_deflection"],
            "residual_link_error_rad": run["residual_link_error"],
            "base_position_error_m": run["base_position_error"],
            "base_attitude_error_rad": run["base_attitude_error"],
        }
    return out


def describe_binding(plan: Plan) -> str:
    """The binding limit of the plan, and its segment when there are several."""
    b = plan.binding
    count = len(plan.segment_durations)
    segment = f" in segment {b['segment'] + 1} of {count}" if count > 1 else ""
    return describe(b) + segment


def describe(b: Dict[str, Any]) -> str:
    """A binding limit in words: which, on which joint, its peak and when."""
    unit = {"motor_torque": "N·m", "joint_speed": "rad/s", "base_force": "N", "base_torque": "N·m"}[b["limit"]]
    where = f" on {b['joint_name']} (joint index {b['joint']})" if b["joint"] is not None else ""
    return f"{b['limit']}{where}: {b['value']:.4g} of {b['bound']:.4g} {unit} at t = {b['time']:.3f} s"


def print_comparison(c: Comparison) -> None:
    """The measures of both tracking runs side by side."""
    names = c.plan.arm.robot.joint_names
    print(f"  tracking runs       both plans on the flexible arm, RK4 dt = {seconds(c.dt)}, {c.settle:g} s at "
          f"rest after each slew ({c.elapsed:.2g} s of wall time),")
    print(f"                      motor PD kp = {gain_text(c.kp)} N·m/rad, kd = {gain_text(c.kd)} N·m·s/rad")
    if c.plan.base == "held":
        print("                      the bus is held by each plan's own base wrench, open loop (no bus controller)")
    rows: List[Tuple[str, str, str]] = [("", "flexible plan", "rigid-joint plan")]
    rows.append(("duration", f"{c.plan.duration:.4f} s", f"{c.rigid.duration:.4f} s"))
    cells = []
    for plan, run in ((c.plan, c.flexible_run), (c.rigid, c.rigid_run)):
        share, joint = torque_share(plan, run)
        over = " OVER" if share > 1 + 1e-9 else ""
        cells.append(f"{run['peak_motor_torque'][joint]:.4g} N·m = {share:.1%} of the limit on {names[joint]}{over}")
    rows.append(("peak commanded torque", cells[0], cells[1]))
    for label, key, unit in (("tracking error max|q − q_plan|", "tracking_error", "rad"),
                             ("residual deflection max|θ − q|", "residual_deflection", "rad"),
                             ("residual link error max|q − q_goal|", "residual_link_error", "rad"),
                             ("base position error", "base_position_error", "m"),
                             ("base attitude error", "base_attitude_error", "rad")):
        rows.append((label, f"{c.flexible_run[key]:.2e} {unit}", f"{c.rigid_run[key]:.2e} {unit}"))
    widths = [max(len(r[k]) for r in rows) for k in range(3)]
    for r in rows:
        print(f"  {r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]}")
    ratio = c.rigid_run["residual_deflection"] / max(c.flexible_run["residual_deflection"], 1e-300)
    times = f"{ratio:,.0f}" if ratio >= 100 else f"{ratio:.3g}"
    print(f"  after the stop the rigid-joint plan leaves {times}× the flexible plan's residual deflection")


PLAN_ERROR_FLAGS = (
    (r"\bq_goal\b", "--goal"),
    (r"\bq_start\b", "--start"),
    (r"\bwaypoints\b", "--waypoint"),
    (r"\bmotor_torque\b", "--motor-torque"),
    (r"\bjoint_speed\b", "--joint-speed"),
    (r"\bbase_force\b", "--base-force"),
    (r"\bbase_torque\b", "--base-torque"),
)


def plan_error(error: Exception) -> CliError:
    """A planner's error under the flag of the first argument it names (else ``URDF``: the
    model), in the CLI's words."""
    message = re.sub(r"^limits(?:\.|: )", "", str(error))
    found = [(m.start(), flag) for pattern, flag in PLAN_ERROR_FLAGS for m in [re.search(pattern, message)] if m]
    flag = min(found)[1] if found else "URDF"
    for pattern, name in PLAN_ERROR_FLAGS:
        message = re.sub(pattern, name, message)
    if message.startswith(flag + ": "):  # "--goal: --goal: ..." reads "--goal: ..."
        message = message[len(flag) + 2:]
    return CliError(flag, message)


def check_stops(stops: List[Tuple[str, Array]]) -> None:
    """Consecutive stops must differ (the planner says so too; here in the CLI's words)."""
    for (name_a, a), (name_b, b) in zip(stops, stops[1:]):
        if np.array_equal(a, b):
            flag, _, which = name_b.partition(" ")
            subject = f"waypoint {which} " if which else ""
            raise CliError(flag, f"{subject}equals {name_a}: there is nothing to slew between them")


def plan_job(args: argparse.Namespace) -> Tuple[Job, Plan]:
    """The arm of the URDF and its planned slew, from the command line."""
    arm, side, com, note = load_arm(args)
    robot = arm.robot
    goal = per_joint(args.goal, "--goal", robot)
    start = per_joint(args.start, "--start", robot, default=0.0)
    waypoints = [per_joint(w, "--waypoint", robot) for w in args.waypoint or []]
    start_name = "--start" if args.start is not None else "--start (default 0 for every joint)"
    check_stops([(start_name, start)] + [(f"--waypoint {k + 1}", w) for k, w in enumerate(waypoints)]
                + [("--goal", goal)])
    if args.base == "free":
        for flag, value in (("--base-force", args.base_force), ("--base-torque", args.base_torque)):
            if value is not None:
                raise CliError(flag, "bounds the wrench of the actuators that hold the base; a free-"
                                     "floating base (--base free) has none: add --base held or drop it")
    limits = plan_limits(robot, args)
    printer = WarningPrinter()  # a LimitWarning: limits past the URDF's, in the CLI's words
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            warnings.showwarning = printer
            plan = plan_slew(arm, goal, q_start=start, limits=limits, base=args.base,
                             waypoints=waypoints or None)
    except ValueError as e:
        raise plan_error(e) from None
    return Job(arm, robot.name, goal - start, side, com, note), plan


def plan_limits(robot: Robot, args: argparse.Namespace) -> Limits:
    """``--motor-torque`` and ``--joint-speed`` where given, else the URDF's own (its ``<limit
    effort velocity>``: :meth:`Limits.from_urdf`), with ``--base-force``/``--base-torque``."""
    torque = None if args.motor_torque is None else per_joint(args.motor_torque, "--motor-torque", robot)
    speed = None if args.joint_speed is None else per_joint(args.joint_speed, "--joint-speed", robot)
    if torque is None or speed is None:
        for flag, given, rated, tag in (("--motor-torque", torque, robot.effort_limits, "effort"),
                                        ("--joint-speed", speed, robot.velocity_limits, "velocity")):
            missing = [name for name, v in zip(robot.joint_names, rated) if not (np.isfinite(v) and v > 0)]
            if given is None and missing:
                raise CliError(flag, f"the URDF states no {tag} limit (<limit {tag}=\"…\">) for "
                                     f"{', '.join(missing)}; give {flag}")
        torque = robot.effort_limits if torque is None else torque
        speed = robot.velocity_limits if speed is None else speed
    try:
        return Limits(torque, speed, args.base_force, args.base_torque)
    except ValueError as e:
        raise plan_error(e) from None


def tracking_setup(arm: FlexibleArm, plan: Plan, args: argparse.Namespace) -> Tuple[float, Array, Array, float, Optional[str]]:
    """``(dt, kp, kd, RK4 limit, note)`` for the tracking runs."""
    kp_default, kd_default = servo_gains(arm)
    kp = kp_default if args.kp is None else per_joint(args.kp, "--kp", arm.robot)
    kd = kd_default if args.kd is None else per_joint(args.kd, "--kd", arm.robot)
    try:
        limit = tracking_limit(arm, plan.stops, kp, kd)
    except ValueError as e:  # gains too large for the eigenvalues to be computed
        flag = "--kd" if str(e).startswith("kd:") else "--kp"
        raise CliError(flag, re.sub(r"^k[pd]: ", "", str(e))) from None
    dt, note = tracking_dt(limit, args.dt)
    return dt, kp, kd, limit, note


def tracking_steps_flag(args: argparse.Namespace, plan: Plan, dt: float) -> Tuple[str, str]:
    """The flag that makes the tracking runs too long, and what to do: ``--settle`` when the
    settling time is what is long, ``--dt`` when it was given, else the gains (a default step
    below TRACK_DT comes from their RK4 stability limit)."""
    if args.settle > plan.duration:
        return "--settle", "shorten --settle"
    if args.dt is not None or dt >= TRACK_DT:
        return "--dt", "lengthen --dt or shorten --settle"
    gains = [flag for flag, given in (("--kp", args.kp), ("--kd", args.kd)) if given is not None]
    flag = "/".join(gains) or "--dt"
    return flag, (f"the step, {dt:.3g} s, is that short because of the tracking PD's RK4 stability limit; "
                  f"lower {flag}")


def plan_command(args: argparse.Namespace) -> int:
    job, plan = plan_job(args)
    arm, robot = job.arm, job.arm.robot
    dt, kp, kd, limit, dt_note = tracking_setup(arm, plan, args)
    out = output_folder(args.out)
    print(f"{job.name}: {arm.dof} joints, total mass {robot.total_mass:.1f} kg, {plan.base} base; "
          f"tracking runs at dt = {seconds(dt)} (RK4 limit under the PD at the stops: {limit:.3g} s)")
    for note in (job.note, dt_note):
        if note:
            print(note)
    flag, advice = tracking_steps_flag(args, plan, dt)
    steps = step_count(1.01 * plan.duration + args.settle, dt, flag, advice, math.ceil)
    check_memory(steps, arm.dof, flag, advice)
    try:
        comparison = compare(job.name, plan, dt, kp, kd, args.settle)
    except ValueError as e:  # a step the runs refuse: longer than a plan that the limits made short
        flag = "--dt" if args.dt is not None else "--motor-torque/--joint-speed"
        raise CliError(flag, re.sub(r"^dt: ", "" if flag == "--dt" else "dt = ", str(e))) from None
    except SimulationError as e:
        print(f"orbitflex: the tracking run failed: {failure_reason(e)}; no outputs written (exit code 1)",
              file=sys.stderr)
        return 1
    wheels = wheel_plan(args, plan, dt, kp, kd, args.settle)
    summary = {"model": job.name, "joints": robot.joint_names, "base": plan.base,
               "stops": plan.stops.tolist(), "segment_durations_s": plan.segment_durations.tolist(),
               "limits": {**limits_dict(plan.limits), "source": limits_source(args)}, **comparison_summary(comparison)}
    if wheels is not None:
        summary["wheels"] = wheels.summary()
    files = write_plan_outputs(comparison, summary, out, args.no_plots)
    print_plan_summary(comparison, limits_source(args))
    if wheels is not None:
        print_wheel_plan(wheels)
    width = max(len(str(f)) for f in files)
    print(f"\nwrote {len(files)} files:")
    for f in files:
        print(f"  {str(f):<{width}}  {PLAN_OUTPUTS[f.name]}")
    return 0


def limits_dict(limits: Limits) -> Dict[str, Any]:
    return {"motor_torque_Nm": np.asarray(limits.motor_torque).tolist(),
            "joint_speed_rad_s": np.asarray(limits.joint_speed).tolist(),
            "base_force_N": limits.base_force, "base_torque_Nm": limits.base_torque}


def limits_source(args: argparse.Namespace) -> str:
    """Where ``orbitflex plan``'s motor-torque and joint-speed limits come from."""
    given = [flag for flag in ("--motor-torque", "--joint-speed") if getattr(args, flag[2:].replace("-", "_")) is not None]
    if len(given) == 2:
        return "as given"
    urdf = "the URDF's <limit effort velocity>" if not given else \
        f"{given[0]} as given, the other the URDF's <limit effort velocity>"
    return urdf


def print_plan_summary(c: Comparison, source: str) -> None:
    plan = c.plan
    limits = plan.limits
    segments = len(plan.segment_durations)
    parts = f" ({segments} segments: " + ", ".join(f"{d:.3f}" for d in plan.segment_durations) + " s)" if segments > 1 else ""
    print(f"\norbitflex: minimum-time slew of '{c.name}' ({plan.arm.dof} flexible joints, {plan.base} base)")
    print(f"  limits              motor torque {gain_text(np.asarray(limits.motor_torque))} N·m, joint speed "
          f"{gain_text(np.asarray(limits.joint_speed))} rad/s ({source})")
    print(f"  duration            {plan.duration:.4f} s{parts}")
    print(f"  binding limit       {describe_binding(plan)}")
    if segments > 1:
        for k, b in enumerate(plan.bindings):
            print(f"    segment {k + 1}         {describe(b)}")
    print(f"  rigid-joint plan    {c.rigid.duration:.4f} s, binding {describe_binding(c.rigid)}")
    print_comparison(c)


def write_plan_outputs(c: Comparison, summary: Dict[str, Any], out: Path, no_plots: bool) -> List[Path]:
    files = [out / "plan.npz"]
    try:
        np.savez(files[0], **plan_arrays(c))
        files.append(out / "plan_summary.json")
        files[-1].write_text(json.dumps(summary, indent=2))
        if not no_plots:
            files += plot_plan(c, out)
    except OSError as e:
        raise CliError("--out", f"cannot write {files[-1]}: {e.strerror or e}") from None
    return files


SAMPLED = ("t", "q", "qd", "qdd", "theta", "theta_dot", "u", "tau", "base_wrench", "base_twist", "base_pose")


MEASURES = ("slew_end", "peak_motor_torque", "tracking_error", "residual_deflection", "residual_link_error",
            "base_position_error", "base_attitude_error")


def plan_arrays(c: Comparison) -> Dict[str, Any]:
    """Everything in plan.npz: the flexible plan's samples unprefixed (as on ``Plan``), the
    rigid-joint plan's with ``rigid_``; the reference tables the runs followed
    (``reference_*``, ``rigid_reference_*``); the runs (``run_t``, ``run_x``, ``run_u`` and
    ``rigid_run_*``, columns named by ``columns``); the measures (``tracking_error``, …,
    ``rigid_tracking_error``, …); the limits, the binding limit, dt and the gains."""
    limits = c.plan.limits
    arrays: Dict[str, Any] = {
        "joint_names": np.array(c.plan.arm.robot.joint_names), "base": np.array(c.plan.base),
        "stops": c.plan.stops, "dt": c.dt, "kp": c.kp, "kd": c.kd, "settle": c.settle,
        "motor_torque_limit": np.asarray(limits.motor_torque), "joint_speed_limit": np.asarray(limits.joint_speed),
        "base_force_limit": np.nan if limits.base_force is None else limits.base_force,
        "base_torque_limit": np.nan if limits.base_torque is None else limits.base_torque,
    }
    for prefix, plan, run in (("", c.plan, c.flexible_run), ("rigid_", c.rigid, c.rigid_run)):
        for name in SAMPLED:
            arrays[prefix + name] = getattr(plan, name)
        arrays[prefix + "segment_durations"] = plan.segment_durations
        b = plan.binding
        arrays[prefix + "binding_limit"] = np.array(b["limit"])
        arrays[prefix + "binding_joint"] = -1 if b["joint"] is None else b["joint"]
        for key in ("segment", "time", "value", "bound"):
            arrays[f"{prefix}binding_{key}"] = b[key]
        for name, table in run["reference"].items():
            arrays[f"{prefix}reference_{name}"] = table
        traj = run["trajectory"]
        arrays[prefix + "run_t"], arrays[prefix + "run_x"], arrays[prefix + "run_u"] = traj.t, traj.x, traj.u
        for name in MEASURES:
            arrays[prefix + name] = run[name]
    arrays["columns"] = np.array(c.flexible_run["trajectory"].column_names())
    return arrays


def demo_comparison(arm: FlexibleArm, name: str, requested_dt: float) -> Tuple[Comparison, Optional[str]]:
    """The demo's planned slew of the built-in arm (free floating, under its URDF's limits) and
    its rigid-joint plan, tracked with the demo's PD at the run's dt (or the largest round dt
    within the stability limit below it)."""
    plan = plan_slew(arm, DEMO_PLAN_GOAL, limits=Limits.from_urdf(arm.robot), base="free")
    kp, kd = np.full(arm.dof, DEMO_KP), np.full(arm.dof, DEMO_KD)
    limit = tracking_limit(arm, plan.stops, kp, kd)
    dt, note = requested_dt, None
    if requested_dt > DT_MARGIN * limit:
        dt = round_down(DT_MARGIN * limit)
        note = (f"the planned slew is tracked at dt = {seconds(dt)}: --dt {requested_dt:g} is past "
                f"{DT_MARGIN:.0%} of the RK4 limit {limit:.3g} s under its PD")
    return compare(name, plan, dt, kp, kd, 2.0), note
