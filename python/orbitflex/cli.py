# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
# (tqdm's stubs and pandas are optional: a base install type-checks clean without them)
"""Command line: ``orbitflex demo``, ``orbitflex simulate URDF``, ``orbitflex plan URDF`` and
``orbitflex campaign FILE``.

``demo`` and ``simulate`` run the same job: a free-floating slew of the arm under the built-in
motor-side PD controller, long enough to show the base's reaction and the joints' vibration, then
print a summary and write the trajectory, ``summary.json`` and plots into an output folder. The
PD's gains come from ``--bandwidth`` and ``--damping-ratio`` (:meth:`FlexibleArm.motor_pd_gains`)
or from ``--kp``/``--kd``, never from ``--dt``; a ``--dt`` past the closed loop's RK4 stability
limit is refused unless ``--force``. The
demo then plans a minimum-time slew of the built-in arm under limits, with the flexible joints
and as if they were rigid, runs both plans on the flexible arm and compares them.

``plan`` does that for a URDF: it plans the minimum-time slew to ``--goal`` under
``--motor-torque``, ``--joint-speed`` (and, for a held base, ``--base-force``, ``--base-torque``)
limits, plans it again as if the joints were rigid, tracks both on the flexible arm, and writes
the plans, the comparison, ``plan_summary.json`` and plots.

``modes`` prints the structural modes of an arm and draws them (``_cli_modes``).

``campaign`` runs a Monte-Carlo campaign file (:mod:`orbitflex.campaign`) locally or on a Dask
cluster (``--scheduler``) and writes the per-run table ``runs.parquet``, ``summary.csv``
(percentiles), ``log.jsonl`` and ``histograms.png``.

Exit codes: 0 for a completed run, 1 when a run diverged (the outputs then describe the finite
part before the failure; ``plan`` writes none; ``campaign``: when any run did, the table marks
it), 2 for a usage error (one line ``orbitflex: error: FLAG: ...``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import textwrap
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, NoReturn, Optional, Sequence, TextIO, Tuple, Type, Union

import numpy as np
import numpy.typing as npt

from . import (FlexibleArm, FlexibleJoints, Limits, ModelError, MotorPD, Plan, Robot, SimulationError, Trajectory,
               __version__, models, plan_slew)

Array = npt.NDArray[np.float64]
Rows = npt.NDArray[np.intp]  # indices of the rows drawn in a plot

# Default slew for the built-in arm (rad, link side), one entry per joint.
SPACE_ARM_SLEW = np.array([0.4, 0.6, -0.5, 0.8, -0.6, 0.5, 1.0])
# Side (m) of the built-in arm's bus, and of the solid cube that --base-mass alone stands for
# (Robot.with_base_inertia's default).
BUS_SIDE = models.DEFAULT_BUS_SIDE

# FlexibleJoints.defaults_for, in a few words: printed when a run uses it, and in the help.
DEFAULTS_SCALING = ("each joint rings at 5 Hz with its motor held, motor inertia = the link-side "
                    "inertia it sees at q = 0, damping 5 % of critical, no motor friction")
DEFAULTS_RULE = (f"joint parameters: FlexibleJoints.defaults_for(robot), scaled to the links "
                 f"({DEFAULTS_SCALING}); give your actuator data with --params joints.toml")

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


# ---------------------------------------------------------------------------------------------
# errors: one line, naming the flag
# ---------------------------------------------------------------------------------------------


class CliError(Exception):
    """A usage error, printed as one line ``orbitflex: error: FLAG: message`` (exit code 2)."""

    def __init__(self, flag: str, message: str):
        super().__init__(f"{flag}: {message}")


def cli_words(message: str) -> str:
    """The library's message with its Python keywords (``ee_link``, ``locked_joints=[...]``)
    replaced by the command-line flags."""

    def locked(match: "re.Match[str]") -> str:
        names = [name.strip().strip("'\"") for name in match.group(1).split(",")]
        return "--locked-joints " + ",".join(names)

    # a list of what the file has names links and joints, not keywords: left as it is
    head, sep, listing = message.partition("; the file has: ")
    head = re.sub(r"locked_joints=\[([^\]]*)\]", locked, head)
    # the keywords, not a link or joint of that name (names are quoted: 'ee_link')
    head = re.sub(r"(?<![\w'\"-])locked_joints(?![\w'\"])", "--locked-joints", head)
    head = re.sub(r"(?<![\w'\"-])ee_links(?![\w'\"])", "--ee-links", head)
    return re.sub(r"(?<![\w'\"-])ee_link(?![\w'\"])", "--ee-link", head) + sep + listing


def urdf_error(error: Exception) -> CliError:
    """A URDF-loading error, under the flag it blames: ``--ee-link`` or ``--locked-joints`` if
    its statement (before the first ``; ``, where advice begins) names one (the first one it
    names), else ``URDF``. Advice such as "lock them with --locked-joints a,b" blames no flag."""
    message = cli_words(str(error))
    statement = message.split("; ", 1)[0]
    named = [(found.start(), flag) for flag in ("--ee-link", "--ee-links", "--locked-joints")
             for found in [re.search(re.escape(flag) + r"(?![\w-])", statement)] if found]
    if not named:
        return CliError("URDF", message)
    flag = min(named)[1]
    # "unknown link (--ee-link) 'x'" reads "unknown link 'x'" once the flag leads the line
    message = message[len(flag) + 2:] if message.startswith(flag + ": ") else message
    return CliError(flag, re.sub(rf" \((?:in )?{flag}\)", "", message))


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``orbitflex: error: --dt: ...`` (exit code 2), and no
    abbreviated flags (``--dur`` is an error, not ``--duration``: a flag added later must not
    change what an existing script means)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        message = re.sub(r"^argument ([^:/ ]+)(?:/\S+)?: ", r"\1: ", message)
        fail(f"{message} (see '{self.prog} --help')")


def fail(message: str) -> NoReturn:
    print(f"orbitflex: error: {message}", file=sys.stderr)
    sys.exit(2)


def positive(text: str) -> float:
    value = finite(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, given {text}")
    return value


def finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, given {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, given {text}")
    return value


# ---------------------------------------------------------------------------------------------
# the slew and its controller
# ---------------------------------------------------------------------------------------------


def quintic(s: Array) -> Tuple[Array, Array]:
    """Rest-to-rest quintic 10s^3 - 15s^4 + 6s^5 on s in [0, 1], and its derivative in s."""
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4


@dataclass
class Gains:
    """The motor PD of a slew: its gains per joint and where they came from."""

    kp: Array  # N·m/rad
    kd: Array  # N·m·s/rad
    bandwidth_hz: Optional[float]  # the closed-loop bandwidth they were chosen for (None: both given)
    damping_ratio: Optional[float]
    given: Tuple[str, ...] = ()  # the flags that set gains directly: "--kp", "--kd"

    def as_dict(self) -> Dict[str, Any]:
        return {"kp": self.kp.tolist(), "kd": self.kd.tolist(), "bandwidth_hz": self.bandwidth_hz,
                "damping_ratio": self.damping_ratio, "given": list(self.given)}


def choose_gains(arm: FlexibleArm, args: argparse.Namespace) -> Gains:
    """The slew's motor PD: ``--kp``/``--kd`` where given, the rest from ``--bandwidth`` and
    ``--damping-ratio`` (:meth:`FlexibleArm.motor_pd_gains`, at the start, q = 0). Never from dt."""
    given = tuple(flag for flag, value in (("--kp", args.kp), ("--kd", args.kd)) if value is not None)
    kp = kd = None
    if len(given) < 2:
        try:
            kp, kd = arm.motor_pd_gains(args.bandwidth, args.damping_ratio)
        except ValueError as e:
            raise CliError("--bandwidth", cli_words(str(e)).removeprefix("bandwidth: ")) from None
    if args.kp is not None:
        kp = per_joint(args.kp, "--kp", arm.robot)
    if args.kd is not None:
        kd = per_joint(args.kd, "--kd", arm.robot)
    assert kp is not None and kd is not None
    rule = len(given) < 2
    return Gains(np.asarray(kp), np.asarray(kd), args.bandwidth if rule else None,
                 args.damping_ratio if rule else None, given)


def slew_controller(arm: FlexibleArm, slew: Array, steps: int, dt: float, slew_time: float,
                    gains: Gains) -> MotorPD:
    """The motor PD with ``gains`` that follows a quintic slew of ``slew`` (rad per joint) over
    ``slew_time`` seconds, tabulated for ``steps`` steps of ``dt``."""
    t = np.arange(steps, dtype=np.float64) * dt
    shape, dshape = quintic(t / slew_time)
    theta_ref = np.outer(shape, slew)
    theta_dot_ref = np.outer(dshape / slew_time, slew)
    return MotorPD(gains.kp, gains.kd, theta_ref, theta_dot_ref)


def check_step(arm: FlexibleArm, pd: MotorPD, gains: Gains, dt: float, force: bool) -> float:
    """The RK4 stability limit (s) of the closed loop at rest; a ``--dt`` past it is refused
    (with ``--force``: a warning, and the run goes on). The controller never changes with dt."""
    limit = arm.rk4_stability_limit(u=pd).dt
    if dt > limit:
        advice = (f"use --dt {round_down(DT_MARGIN * limit):g} or less, or a lower "
                  + ("--bandwidth" if gains.bandwidth_hz is not None else "--kp/--kd"))
        message = (f"{dt:g} s is past the RK4 stability limit {limit:.3g} s of the closed loop (the arm "
                   f"under its motor PD, the torque held over each step)")
        if not force:
            raise CliError("--dt", f"{message}; {advice}, or --force to run anyway")
    return limit  # with --force, simulate warns and runs


# ---------------------------------------------------------------------------------------------
# memory: refuse a run that cannot fit before allocating it
# ---------------------------------------------------------------------------------------------


def recorded_rows(steps: int, record_every: int) -> int:
    """Rows a run of ``steps`` steps keeps with ``record_every`` (``simulate``'s rule): rows 0,
    k, 2k, ... and the final row."""
    return steps // record_every + 1 + (steps % record_every != 0)


def run_bytes(steps: int, n: int, record_every: int = 1) -> Dict[str, int]:
    """Bytes a run of ``steps`` steps of an ``n``-joint arm allocates, by part, keeping one row
    in ``record_every``."""
    rows = recorded_rows(steps, record_every)
    return {
        "reference tables": 2 * steps * n * 8,  # theta_ref, theta_dot_ref
        "record": rows * (14 + 4 * n) * 8 + (rows - 1) * n * 8,  # t and x per row, u per kept row
        # momentum (6), energy (1), EE pose (7), deflection, spring torque and the energy
        # balance's temporaries (4n), per row
        "diagnostics": rows * (14 + 4 * n) * 8,
    }


def free_memory() -> Optional[int]:
    """Bytes of free physical memory, or None where the system does not say (not Linux)."""
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


def check_memory(steps: int, n: int, flag: str = "--duration/--dt",
                 advice: str = "shorten --duration or lengthen --dt", record_every: int = 1) -> None:
    parts = run_bytes(steps, n, record_every)
    need, free = sum(parts.values()), free_memory()
    if free is not None and need > free:
        sizes = ", ".join(f"{name} {gb(size)}" for name, size in parts.items())
        count = f"{steps:,}" if steps < 1e12 else f"{steps:.3g}"
        raise CliError(flag, f"{count} steps of {n} joints need about {gb(need)} ({sizes}) but "
                             f"{gb(free)} of memory is free; {advice}")


def gb(size: float) -> str:
    """A size in GB, or TB from 1000 GB (three significant digits: an absurd size stays short)."""
    return f"{size / 1e9:.3g} GB" if size < 1e12 else f"{size / 1e12:.3g} TB"


# ---------------------------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------------------------


@dataclass
class Job:
    """What to simulate: the arm, its slew (rad per joint) and how to draw its bus."""

    arm: FlexibleArm
    name: str
    slew: Array
    bus_side: float  # m, edge of the cube drawn for the bus in ee_path.png
    bus_com: Array  # m, base frame: the cube's centre
    note: Optional[str] = None  # printed under the header
    compare_plans: bool = False  # also plan the demo's slew and compare it with its rigid-joint plan


@dataclass
class Outcome:
    traj: Trajectory
    elapsed: float  # s of wall time
    failure: Optional[SimulationError] = None
    warnings: int = 0  # how many warnings simulate emitted (dt past the RK4 stability limit)
    record_every: int = 1  # the run kept rows 0, k, 2k, ... and the final row
    onset: Optional[int] = None  # a diverged run: the last row before the divergence set in

    def steps_done(self, steps: int) -> int:
        """Steps completed: all ``steps``, or those before the failure."""
        return steps if self.failure is None else self.failure.step

    def meaningful(self) -> Trajectory:
        """The rows the summary and the plots describe: every row, or for a diverged run those
        up to the onset of the divergence (the files keep every finite row)."""
        if self.onset is None or self.onset == len(self.traj.t) - 1:
            return self.traj
        k = self.onset
        return Trajectory(self.traj.arm, self.traj.t[: k + 1], self.traj.x[: k + 1], self.traj.u[:k])


class ProgressBar:
    """A tqdm bar driven by ``simulate``'s ``progress(done, total)`` callback, opened at the
    first call (after any warning ``simulate`` prints before it starts)."""

    def __init__(self, total: int, unit: str = "step", desc: str = "simulating"):
        self.total = total
        self.unit, self.desc = unit, desc
        self.bar: Any = None

    def to(self, done: int, total: int) -> None:
        if self.bar is None:
            try:
                from tqdm import tqdm
            except ImportError:  # tqdm is a dependency, but keep the simulator usable without it
                return
            self.bar = tqdm(total=self.total, unit=self.unit, desc=self.desc, file=sys.stderr,
                            mininterval=0.25)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


class WarningPrinter:
    """Prints the library's warnings as one line ``orbitflex: warning: ...`` and counts them
    (a ``warnings.showwarning`` replacement)."""

    def __init__(self) -> None:
        self.count = 0

    def __call__(self, message: Union[Warning, str], category: Type[Warning], filename: str,
                 lineno: int, file: Optional[TextIO] = None, line: Optional[str] = None) -> None:
        self.count += 1
        sys.stdout.flush()
        print(f"orbitflex: warning: {cli_words(str(message))}", file=sys.stderr)


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


def failure_reason(e: SimulationError) -> str:
    """``step N (t = T s): why``, from the library's message."""
    reason = str(e).split("): ", 1)[-1]
    return f"step {e.step} (t = {e.time:.6g} s): {cli_words(reason)}"


def run(job: Job, args: argparse.Namespace) -> int:
    steps = int(round(args.duration / args.dt))
    check_memory(steps, job.arm.dof, record_every=args.record_every)
    gains = choose_gains(job.arm, args)
    pd = slew_controller(job.arm, job.slew, steps, args.dt, args.slew_time, gains)
    limit = check_step(job.arm, pd, gains, args.dt, args.force)
    out = output_folder(args.out)
    print(f"{job.name}: {job.arm.dof} joints, total mass {job.arm.robot.total_mass:.1f} kg, "
          f"dt = {args.dt:g} s (RK4 limit of the closed loop at rest: {limit:.3g} s)")
    if job.note:
        print(job.note)
    outcome = simulate(job.arm, pd, steps, args.dt, progress=not args.quiet, record_every=args.record_every)
    comparison, note = demo_comparison(job.arm, job.name, args.dt) if job.compare_plans else (None, None)
    with np.errstate(all="ignore"):  # a diverged run's finite part may overflow in the summary
        summary = summarise(job.name, outcome, steps)
        summary["controller"] = {**gains.as_dict(), "rk4_stability_limit_s": limit}
        if comparison is not None:
            summary["planned_slew"] = {"goal_rad": DEMO_PLAN_GOAL.tolist(), "base": comparison.plan.base,
                                       "limits": limits_dict(comparison.plan.limits),
                                       **comparison_summary(comparison)}
        files = write_outputs(job, outcome, summary, out, args, comparison)
    print_summary(summary, job.arm.dof)
    if comparison is not None:
        print_demo_comparison(comparison, note)
    descriptions = {**OUTPUTS, **PLAN_OUTPUTS}
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
        from . import viz

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


def package_dir(text: str) -> Tuple[str, str]:
    """``--package NAME=DIR``."""
    name, sep, folder = text.partition("=")
    if not sep or not name or not folder:
        raise argparse.ArgumentTypeError(f"expected NAME=DIR (a ROS package and its folder), given {text}")
    if not Path(folder).is_dir():
        raise argparse.ArgumentTypeError(f"package '{name}': {folder} is not a folder")
    return name, folder


def output_folder(path: str) -> Path:
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise CliError("--out", f"{out} exists and is not a folder; name a folder (created if missing)")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise CliError("--out", f"cannot create the folder {out}: {e.strerror or e}") from None
    return out


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


# ---------------------------------------------------------------------------------------------
# summary
# ---------------------------------------------------------------------------------------------


def rotation_angle_deg(q0: Array, q1: Array) -> Array:
    """Angle (deg) of the rotation between unit quaternions (x, y, z, w): ``q0`` (4,) and ``q1``
    (4,) or (k, 4)."""
    angle: Array = np.degrees(2 * np.arccos(np.clip(np.abs(q1 @ q0), 0.0, 1.0)))
    return angle


def energy_steps(traj: Trajectory) -> Tuple[Array, Array, Array]:
    """Per step of the record, the power balance's terms (docs/model.md, section 6) by the
    trapezoid rule (``traj.u`` held over each step): ``(ΔE, motor work, dissipated energy)``,
    (rows − 1,) each. With no external wrench, ``ΔE = motor work − dissipated`` up to the
    quadrature and RK4 errors."""
    u = traj.u
    _, _, d, beta = traj.arm.parameters
    td, qd = traj.theta_dot, traj.qd
    rows = len(u)
    dt = np.diff(traj.t[: rows + 1])
    dissipation = ((td - qd) ** 2 * d).sum(axis=1) + (td**2 * beta).sum(axis=1)
    motor = 0.5 * ((u * td[:rows]).sum(axis=1) + (u * td[1 : rows + 1]).sum(axis=1))
    return np.diff(traj.energy[: rows + 1]), dt * motor, 0.5 * dt * (dissipation[:rows] + dissipation[1 : rows + 1])


def energy_balance(traj: Trajectory) -> Tuple[float, float, float]:
    """``(E(T) - E(0), motor work, dissipated energy)`` over the record (:func:`energy_steps`)."""
    _, work, dissipated = energy_steps(traj)
    rows = len(traj.u)
    return float(traj.energy[rows] - traj.energy[0]), float(np.sum(work)), float(np.sum(dissipated))


# A run whose energy balance misses by more than this share of the energy that flowed has left
# the physics: the integrator, not the motors, is making the energy.
DIVERGED_BALANCE = 0.01


def divergence_onset(traj: Trajectory) -> int:
    """The last row of a diverged run (kept with every step's torque) before the divergence set
    in: the last row up to which the energy balance ``E(t) − E(0) = motor work − dissipated``
    still held to ``DIVERGED_BALANCE`` of the energy that flowed (``Σ|ΔE|``). An unstable step
    makes energy the physics does not: the residual grows with the energy itself from then on,
    by a factor per step, while a stable run's residual is the quadrature's (1e-7 of the flow in
    the demo; a few % over the first steps at a coarse dt)."""
    with np.errstate(all="ignore"):
        change, work, dissipated = energy_steps(traj)
        residual = np.abs(np.r_[0.0, np.cumsum(change - (work - dissipated))])
        flow = np.r_[0.0, np.cumsum(np.abs(change))]
        held = np.flatnonzero(residual <= DIVERGED_BALANCE * flow)
    return int(held[-1])  # row 0 always holds (0 ≤ 0)


def angle_unit(largest_rad: float) -> Tuple[float, str]:
    """``(factor, unit)`` that shows angles up to ``largest_rad`` with readable numbers:
    deg from 1°, else mrad, µrad or nrad."""
    if largest_rad >= np.radians(1.0):
        return float(np.degrees(1.0)), "deg"
    for factor, unit in ((1e3, "mrad"), (1e6, "µrad")):
        if largest_rad * factor >= 1.0:
            return factor, unit
    return 1e9, "nrad"


def summarise(name: str, outcome: Outcome, steps_asked: int) -> Dict[str, Any]:
    """The summary; with ``record_every`` > 1 the peaks and drifts are over the kept rows, and the
    energy balance (which needs the torque of every step) is left out (None). A diverged run is
    summarised up to the onset of its divergence (:func:`divergence_onset`), where known."""
    traj = outcome.meaningful()
    steps = outcome.steps_done(steps_asked)
    h = traj.momentum
    h_drift = np.abs(h - h[0]).max(axis=0)
    de = float(traj.energy[-1] - traj.energy[0])
    balance: Dict[str, Optional[float]] = dict.fromkeys(
        ("motor_work_J", "dissipated_J", "energy_balance_residual_J", "energy_flow_J"))
    if outcome.record_every == 1:
        de, work, dissipated = energy_balance(traj)
        balance = {"motor_work_J": work, "dissipated_J": dissipated,
                   "energy_balance_residual_J": de - (work - dissipated),
                   "energy_flow_J": float(np.sum(np.abs(np.diff(traj.energy))))}
    deflection = np.abs(traj.deflection).max(axis=0)
    summary: Dict[str, Any] = {
        "model": name,
        "completed": outcome.failure is None,
        "warnings": outcome.warnings,
        "steps_requested": steps_asked,
        "steps": steps,
        "record_every": outcome.record_every,
        "rows": len(outcome.traj.t),
        "simulated_s": float(outcome.traj.t[-1]),
        "steps_per_second": steps / outcome.elapsed if outcome.elapsed > 0 else float("inf"),
        "base_attitude_change_deg": float(rotation_angle_deg(traj.base_pose[0, 3:], traj.base_pose[-1, 3:])),
        "base_displacement_m": float(np.linalg.norm(traj.base_pose[-1, :3] - traj.base_pose[0, :3])),
        "max_deflection_deg": float(np.degrees(deflection.max())),
        "max_deflection_joint": traj.arm.robot.joint_names[int(deflection.argmax())],
        "momentum_drift_angular": float(h_drift[:3].max()),
        "momentum_drift_linear": float(h_drift[3:].max()),
        "energy_change_J": de,
        **balance,
        "ee_travel_m": ee_travel(traj),
    }
    if outcome.failure is not None:
        summary.update(failure_step=outcome.failure.step, failure_time_s=outcome.failure.time,
                       failure=failure_reason(outcome.failure), divergence_onset_step=outcome.onset,
                       divergence_onset_time_s=None if outcome.onset is None else float(traj.t[-1]))
    return summary


def print_summary(s: Dict[str, Any], dof: int) -> None:
    status = "" if s["completed"] else " FAILED"
    print(f"\norbitflex: free-floating slew of '{s['model']}' ({dof} flexible joints){status}")
    if not s["completed"]:
        print(f"  FAILED at           {s['failure']}")
        onset = s["divergence_onset_step"]
        if onset is not None:
            print(f"  divergence          set in after step {onset} (t = {s['divergence_onset_time_s']:.6g} s): from there "
                  f"the energy balance stops holding to {DIVERGED_BALANCE:.0%} of the energy that flowed, the")
            print(f"                      integrator making the energy; the numbers below describe t = 0 to "
                  f"{s['divergence_onset_time_s']:.6g} s (the files keep every finite step)")
        else:
            print(f"                      the numbers below describe the finite part before the failure "
                  f"(t = 0 to {s['simulated_s']:.6g} s, {s['steps']} of {s['steps_requested']} steps)")
    print(f"  simulated           {s['simulated_s']:.6g} s in {s['steps']} RK4 steps, "
          f"{s['steps_per_second']:,.0f} steps/s")
    pd = s.get("controller")
    if pd is not None:
        rule = ("as given by --kp/--kd" if pd["bandwidth_hz"] is None else
                f"bandwidth {pd['bandwidth_hz']:g} Hz, damping ratio {pd['damping_ratio']:g}"
                + (f"; {' and '.join(pd['given'])} as given" if pd["given"] else ""))
        print(f"  motor PD            kp = {gain_text(np.asarray(pd['kp']))} N·m/rad, "
              f"kd = {gain_text(np.asarray(pd['kd']))} N·m·s/rad ({rule})")
        print(f"                      RK4 stability limit of the closed loop {pd['rk4_stability_limit_s']:.3g} s")
    if s["record_every"] > 1:
        print(f"  recorded            {s['rows']} rows: one step in {s['record_every']} and the last "
              f"(--record-every); peaks and drifts below are over these rows")
    print(f"  base attitude       rotated by {s['base_attitude_change_deg']:.3f} deg "
          f"(origin moved {s['base_displacement_m'] * 1e3:.3g} mm)")
    largest = np.radians(s["max_deflection_deg"])
    factor, unit = angle_unit(largest)
    in_deg = "" if unit == "deg" else f" ({s['max_deflection_deg']:.3g} deg)"
    print(f"  joint deflection    max {largest * factor:.3g} {unit}{in_deg} at {s['max_deflection_joint']}")
    travel = s["ee_travel_m"]
    if isinstance(travel, dict):
        print("  EE travel           " + ", ".join(f"{link} {v:.3g} m" for link, v in travel.items()))
    else:
        print(f"  EE travel           {travel:.3g} m")
    if not s["completed"]:
        cause = "growth of the diverging run"
    elif s["warnings"]:
        cause = "dt is past the RK4 stability limit (see the warning): not to be trusted"
    else:
        cause = "RK4 truncation and round-off"
    print(f"  momentum drift      {s['momentum_drift_angular']:.2e} N·m·s (angular), "
          f"{s['momentum_drift_linear']:.2e} N·s (linear): {cause}")
    if s["motor_work_J"] is None:
        print(f"  energy balance      E(T) − E(0) = {s['energy_change_J']:+.6g} J; motor work and damping "
              f"loss not computed: they need every step's torque (--record-every 1)")
        return
    print(f"  energy balance      E(T) − E(0) = {s['energy_change_J']:+.6g} J = motor work "
          f"{s['motor_work_J']:+.6g} J − damping loss {s['dissipated_J']:.6g} J + residual")
    residual, flow = s["energy_balance_residual_J"], s["energy_flow_J"]
    share = f"{abs(residual) / flow:.1e} of the {flow:.4g} J that flowed (Σ|ΔE| over the steps)" if flow > 0 else "no energy flowed"
    print(f"                      residual {residual:.2e} J (work and loss by the trapezoid rule over "
          f"the steps): {share}")


# ---------------------------------------------------------------------------------------------
# plots
# ---------------------------------------------------------------------------------------------

PLOT_POINTS = 2000  # rows drawn per line at most: long runs are thinned to keep plotting quick


def plot_rows(k: int) -> Rows:
    """Indices of the rows to draw: every row, or evenly spaced rows and the last one."""
    stride = max(1, math.ceil(k / PLOT_POINTS))
    rows: Rows = np.unique(np.r_[np.arange(0, k, stride), k - 1])
    return rows


def seconds(dt: float) -> str:
    """``dt`` in s, ms or µs."""
    for factor, unit in ((1.0, "s"), (1e3, "ms"), (1e6, "µs")):
        if dt * factor >= 1.0:
            return f"{dt * factor:g} {unit}"
    return f"{dt:g} s"


def power_of_ten(values: Array, unit: str) -> Tuple[float, str]:
    """``(factor, label)`` that writes ``values`` as numbers near 1 in ``10^e unit``."""
    largest = float(np.abs(values).max()) if values.size else 0.0
    if largest == 0.0 or not np.isfinite(largest) or -2 <= math.floor(math.log10(largest)) <= 3:
        return 1.0, unit
    e = math.floor(math.log10(largest))
    return 10.0**-e, f"$10^{{{e}}}$ {unit}"


def euler_zyx(quat: Array) -> Tuple[Array, Array, Array]:
    """``(yaw, pitch, roll)`` (rad) of unit quaternions (x, y, z, w), (k, 4): the intrinsic
    z-y'-x'' sequence, ``R = Rz(yaw) Ry(pitch) Rx(roll)``; yaw and roll unwrapped in time."""
    x, y, z, w = quat.T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.unwrap(yaw), pitch, np.unwrap(roll)


def rotation_matrix(quat: Array) -> Array:
    """The rotation matrix of a unit quaternion (x, y, z, w)."""
    x, y, z, w = quat
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def cube_edges(pose: Array, centre: Array, side: float) -> List[Array]:
    """The 12 edges, (2, 3) each in the inertial frame, of a cube of edge ``side`` centred at
    ``centre`` (base frame) of a base at ``pose`` [r; quat]."""
    corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) * side / 2
    world = pose[:3] + (centre + corners) @ rotation_matrix(pose[3:]).T
    return [world[[a, b]] for a in range(8) for b in range(a + 1, 8)
            if np.count_nonzero(corners[a] != corners[b]) == 1]


class Figures:
    """Saves figures into ``out`` with a common caption (model, dt, simulated time)."""

    def __init__(self, out: Path, caption: str):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        self.plt: Any = plt
        self.out = out
        self.caption = caption
        self.files: List[Path] = []

    def new(self, title: str, rows: int = 1, height: float = 4.5, cols: int = 1, **kw: Any) -> Tuple[Any, Any]:
        fig, axes = self.plt.subplots(rows, cols, figsize=(9.5, height), layout="constrained", **kw)
        fig.suptitle(f"{title}\n{self.caption}", fontsize=11)
        return fig, axes

    def save(self, fig: Any, name: str) -> None:
        path = self.out / name
        fig.savefig(path, dpi=110)
        self.plt.close(fig)
        self.files.append(path)


def plot(job: Job, outcome: Outcome, dt: float, out: Path) -> List[Path]:
    traj = outcome.meaningful()
    caption = f"model {job.name}, dt = {seconds(dt)}, {traj.t[-1]:.6g} s free-floating slew"
    if outcome.record_every > 1:
        caption += f", a row every {seconds(outcome.record_every * dt)} (--record-every {outcome.record_every})"
    if outcome.failure is not None:
        shown = "the finite part" if outcome.onset is None else "up to where it set in"
        caption += f", diverged at t = {outcome.failure.time:.4g} s ({shown} shown)"
    figures = Figures(out, caption)
    rows = plot_rows(len(traj.t))
    plot_angles(figures, traj, rows)
    plot_deflection(figures, traj, rows)
    plot_attitude(figures, traj, rows)
    plot_ee_path(figures, job, traj, rows)
    plot_momentum(figures, traj, rows)
    return figures.files


def joint_legend(ax: Any, title: Optional[str] = None, extra: Sequence[Any] = ()) -> None:
    handles, labels = ax.get_legend_handles_labels()
    handles, labels = handles + [h for h in extra], labels + [h.get_label() for h in extra]
    ax.legend(handles, labels, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0),
              title=title, title_fontsize=8)


def plot_angles(figures: Figures, traj: Trajectory, rows: Rows) -> None:
    from matplotlib.lines import Line2D

    t, names = traj.t[rows], traj.arm.robot.joint_names
    q, lead = traj.q[rows], traj.deflection[rows]
    theta = q + lead
    fig, (top, bottom) = figures.new("Motor lead: link angles q and motor angles θ", rows=2,
                                     height=7.0, sharex=True, gridspec_kw={"height_ratios": (3, 2)})
    for i, name in enumerate(names):
        line, = top.plot(t, np.degrees(q[:, i]), lw=1.6, label=name)
        top.plot(t, np.degrees(theta[:, i]), ":", color="black", lw=0.9)
    top.set(ylabel="angle (deg)", title="q (coloured) and θ (black dotted): θ lies on q at this scale")
    styles = [Line2D([], [], color="gray", lw=1.6, label="q, link"),
              Line2D([], [], color="black", ls=":", lw=0.9, label="θ, motor")]
    joint_legend(top, "joint", styles)
    factor, unit = angle_unit(float(np.abs(lead).max()))
    for i, name in enumerate(names):
        bottom.plot(t, lead[:, i] * factor, lw=1, label=name)
    bottom.axhline(0, color="black", lw=0.5)
    bottom.set(xlabel="time (s)", ylabel=f"θ − q ({unit})", title="motor lead θ − q (spring stretch)")
    joint_legend(bottom, "joint")
    figures.save(fig, "joint_vs_motor_angles.png")


def plot_deflection(figures: Figures, traj: Trajectory, rows: Rows) -> None:
    """One panel per joint, each on its own scale: the deflections of a wrist and a shoulder
    differ by orders of magnitude."""
    t, names = traj.t[rows], traj.arm.robot.joint_names
    deflection = traj.deflection[rows]
    peak_torque = np.abs(traj.spring_torque).max(axis=0)
    n = len(names)
    cols = 1 if n <= 4 else 2
    fig, axes = figures.new("Joint deflection θ − q (spring stretch), one panel per joint",
                            rows=math.ceil(n / cols), height=1.2 + 1.45 * math.ceil(n / cols),
                            cols=cols, sharex=True, squeeze=False)
    for i, ax in enumerate(axes.flat):
        if i >= n:
            ax.set_visible(False)
            continue
        factor, unit = angle_unit(float(np.abs(deflection[:, i]).max()))
        ax.plot(t, deflection[:, i] * factor, lw=1, color=f"C{i % 10}")
        ax.axhline(0, color="black", lw=0.5)
        ax.set_ylabel(unit)
        ax.set_title(f"{names[i]}: peak {np.abs(deflection[:, i]).max() * factor:.3g} {unit}, "
                     f"spring torque peak {peak_torque[i]:.3g} N·m", fontsize=8.5)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    if n % cols:
        axes[-2, -1].xaxis.set_tick_params(labelbottom=True)
        axes[-2, -1].set_xlabel("time (s)")
    figures.save(fig, "deflection.png")


def plot_attitude(figures: Figures, traj: Trajectory, rows: Rows) -> None:
    t, quat = traj.t[rows], traj.base_pose[rows, 3:]
    yaw, pitch, roll = euler_zyx(quat)
    fig, ax = figures.new("Bus attitude: the reaction to the arm's motion (no attitude control)")
    for angle, label in ((yaw, "yaw (about z)"), (pitch, "pitch (about y′)"), (roll, "roll (about x″)")):
        ax.plot(t, np.degrees(angle), lw=1.2, label=label)
    total = rotation_angle_deg(quat[0], quat)
    ax.plot(t, total, color="black", lw=2, label=f"total rotation angle since t = 0 ({total[-1]:.3g}° at the end)")
    ax.axhline(0, color="black", lw=0.5)
    ax.set(xlabel="time (s)", ylabel="angle (deg)",
           title="Euler angles, intrinsic z-y′-x″ (yaw, then pitch, then roll): "
                 "R(base → inertial) = Rz(yaw) · Ry(pitch) · Rx(roll)")
    ax.title.set_fontsize(9)
    # beside the axes, not on them: inside, it covered the yaw curve during the slew
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    figures.save(fig, "base_attitude.png")


def ee_paths(traj: Trajectory) -> Array:
    """EE positions, (rows, k, 3) for k end-effectors (k = 1 on a chain)."""
    poses = np.asarray(traj.ee_pose)
    return (poses[:, None, :3] if poses.ndim == 2 else poses[:, :, :3])


def ee_travel(traj: Trajectory) -> Any:
    """Start-to-end EE displacement (m): a number for one end-effector, a dict by link name for
    several."""
    paths = ee_paths(traj)
    travel = [float(np.linalg.norm(paths[-1, e] - paths[0, e])) for e in range(paths.shape[1])]
    links = traj.arm.robot.ee_links
    return travel[0] if len(links) == 1 else dict(zip(links, travel))


def plot_ee_path(figures: Figures, job: Job, traj: Trajectory, rows: Rows) -> None:
    """Left: the EE paths with the arm and the bus at the start and the end, to scale. Right: the
    first end-effector's path alone, relative to its start and zoomed."""
    paths = ee_paths(traj)[rows]
    links = traj.arm.robot.ee_links
    path = paths[:, 0]
    fig = figures.plt.figure(figsize=(12, 6.5), layout="constrained")
    fig.suptitle(f"End-effector path, inertial frame (equal axes)\n{figures.caption}", fontsize=11)
    scene = fig.add_subplot(1, 2, 1, projection="3d")
    points = [paths.reshape(-1, 3)]
    for k, colour, when in ((0, "tab:green", "start"), (-1, "tab:red", "end")):
        points += draw_arm(scene, job, traj, k, colour, when)
    for e, link in enumerate(links):
        scene.plot(*paths[:, e].T, color="tab:blue", lw=2, alpha=1.0 if e == 0 else 0.6,
                   label="EE path" if len(links) == 1 else f"{link} path")
    equal_axes(scene, np.vstack(points))
    scene.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title="arm and bus at the start and the end")
    scene.legend(fontsize=8, loc="upper left")
    plot_ee_zoom(fig.add_subplot(1, 2, 2, projection="3d"), traj.t[rows], path,
                 "" if len(links) == 1 else f" ({links[0]})")
    figures.save(fig, "ee_path.png")


def plot_ee_zoom(ax: Any, t: Array, path: Array, which: str = "") -> None:
    """The EE path relative to its start, in m, mm or µm, with a dot every tick interval."""
    shift = path - path[0]
    extent = float(np.ptp(path, axis=0).max())
    factor, unit = next(((f, u) for f, u in ((1.0, "m"), (1e3, "mm")) if extent * f >= 0.5), (1e6, "µm"))
    shift *= factor
    every = tick_interval(float(t[-1]))
    marks = np.minimum(np.searchsorted(t, np.arange(0.0, t[-1] + 1e-9, every)), len(t) - 1)
    ax.plot(*shift.T, color="tab:blue", lw=2, label="EE path")
    ax.scatter(*shift[marks].T, color="tab:blue", s=10, label=f"every {every:g} s")
    ax.scatter(*shift[0], color="tab:green", s=40, label="start (t = 0 s)")
    ax.scatter(*shift[-1], color="tab:red", s=40, label=f"end (t = {t[-1]:.3g} s)")
    equal_axes(ax, shift)
    ax.set(xlabel=f"Δx ({unit})", ylabel=f"Δy ({unit})", zlabel=f"Δz ({unit})")
    x0 = ", ".join(f"{v:.3g}" for v in path[0])
    ax.set_title(f"EE{which} displacement from its start at ({x0}) m\n"
                 f"{np.linalg.norm(shift[-1]):.3g} {unit} from start to end")
    ax.legend(fontsize=8, loc="upper left")


def draw_arm(ax: Any, job: Job, traj: Trajectory, k: int, colour: str, when: str) -> List[Array]:
    """Draws the arm (a line through its bodies, from the first joint to each EE, one per branch)
    and the bus (a cube outline) at row ``k``; returns the points drawn."""
    pose = traj.base_pose[k]
    robot = traj.arm.robot
    rows = robot.body_poses(pose, traj.q[k])[:, :3]
    parents = [-1] + [p + 1 for p in robot.parents]  # by body: 0 is the base
    n = robot.dof
    drawn = []
    for e, body in enumerate(robot.ee_bodies):
        chain = [n + 1 + e]  # the EE row, then its body and the bodies above it, not the base
        while body > 0:
            chain.append(body)
            body = parents[body]
        line = rows[chain[::-1]]
        ax.plot(*line.T, "o-", color=colour, lw=2, ms=3,
                label=f"arm at the {when} (t = {traj.t[k]:.3g} s)" if e == 0 else None)
        drawn.append(line)
    bodies = np.vstack(drawn)
    edges = cube_edges(pose, job.bus_com, job.bus_side)
    for i, edge in enumerate(edges):
        ax.plot(*edge.T, color=colour, lw=0.8, alpha=0.6,
                label=f"bus at the {when} ({job.bus_side:.2g} m cube)" if i == 0 else None)
    return [bodies, *edges]


def tick_interval(duration: float) -> float:
    """1, 2 or 5 times a power of ten, about a tenth of ``duration`` (s)."""
    raw = max(duration, 1e-9) / 10
    decade = 10.0 ** math.floor(math.log10(raw))
    return next(m * decade for m in (1, 2, 5, 10) if m * decade >= raw)


def equal_axes(ax: Any, points: Array) -> None:
    """One scale on the three axes: a cube around ``points``."""
    centre = (points.max(axis=0) + points.min(axis=0)) / 2
    half = max(float(np.ptp(points, axis=0).max()) / 2, 1e-6) * 1.05
    ax.set(xlim=(centre[0] - half, centre[0] + half), ylim=(centre[1] - half, centre[1] + half),
           zlim=(centre[2] - half, centre[2] + half))
    ax.set_box_aspect((1, 1, 1), zoom=0.9)  # zoom < 1 leaves room for the axis labels


def plot_momentum(figures: Figures, traj: Trajectory, rows: Rows) -> None:
    t = traj.t[rows]
    drift = traj.momentum[rows] - traj.momentum[0]
    fig, (top, bottom) = figures.new("Momentum drift h(t) − h(0), inertial frame: conserved by the "
                                     "dynamics (no external wrench)", rows=2, height=6.5, sharex=True)
    panels = ((top, drift[:, :3], "N·m·s", "angular momentum about the inertial origin", r"\Delta H"),
              (bottom, drift[:, 3:], "N·s", "linear momentum", r"\Delta p"))
    for ax, values, unit, title, symbol in panels:
        factor, label = power_of_ten(values, unit)
        for i, axis in enumerate("xyz"):
            ax.plot(t, values[:, i] * factor, lw=1, label=f"${symbol}_{axis}$")
        ax.axhline(0, color="black", lw=0.5)
        ax.set(ylabel=f"${symbol}$ ({label})", title=title)
        ax.legend(fontsize=9, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    bottom.set(xlabel="time (s)")
    figures.save(fig, "momentum_drift.png")


# ---------------------------------------------------------------------------------------------
# planned slews: `orbitflex plan` and the demo's planned-vs-rigid comparison
# ---------------------------------------------------------------------------------------------

# The demo's planned slew (rad), under the built-in URDF's own limits (Limits.from_urdf: its
# <limit effort velocity>): the shoulders' 0.15 rad/s binds.
DEMO_PLAN_GOAL = np.array([0.8, -0.6, 0.5, 1.0, -0.7, 0.6, 0.9])
# The demo's tracking PD (N·m/rad, N·m·s/rad): a stiff motor servo (RK4 limit at rest 7.4 ms).
DEMO_KP, DEMO_KD = 1000.0, 100.0
# Default tracking PD of `orbitflex plan`: each motor a critically damped servo at this
# frequency on its own inertia j: kp = j ω², kd = 2 j ω.
SERVO_HZ = 5.0
# Default RK4 step of the tracking runs (s), lowered to a round value within this share of the
# stability limit when the limit requires it.
TRACK_DT = 1e-3
DT_MARGIN = 0.8

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
    inertia ``j``."""
    _, j, _, _ = arm.parameters
    w = 2 * np.pi * hz
    return j * w**2, 2 * j * w


def round_down(x: float) -> float:
    """The largest 1, 2 or 5 times a power of ten that is at most ``x`` (> 0)."""
    decade = 10.0 ** math.floor(math.log10(x))
    return next(m * decade for m in (5, 2, 1) if m * decade <= x * (1 + 1e-12))


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


def torque_share(plan: Plan, run: Dict[str, Any]) -> Tuple[float, int]:
    """The largest commanded ``peak |u_i| / limit_i`` of a run, and its joint."""
    share = run["peak_motor_torque"] / np.asarray(plan.limits.motor_torque)
    return float(share.max()), int(share.argmax())


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


def gain_range(values: Array) -> str:
    """``= v`` if every joint has it, else ``min … max``."""
    if np.all(values == values[0]):
        return f"= {values[0]:.4g}"
    return f"{values.min():.3g} … {values.max():.3g} per joint"


def gain_text(values: Array) -> str:
    """One number if every joint has it, else the list."""
    if np.all(values == values[0]):
        return f"{values[0]:.4g}"
    return "[" + ", ".join(f"{v:.4g}" for v in values) + "]"


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
    steps = math.ceil((1.01 * plan.duration + args.settle) / dt)
    check_memory(steps, arm.dof, *tracking_steps_flag(args, plan, dt))
    try:
        comparison = compare(job.name, plan, dt, kp, kd, args.settle)
    except ValueError as e:  # a step the runs refuse: longer than a plan that the limits made short
        flag = "--dt" if args.dt is not None else "--motor-torque/--joint-speed"
        raise CliError(flag, re.sub(r"^dt: ", "" if flag == "--dt" else "dt = ", str(e))) from None
    except SimulationError as e:
        print(f"orbitflex: the tracking run failed: {failure_reason(e)}; no outputs written (exit code 1)",
              file=sys.stderr)
        return 1
    summary = {"model": job.name, "joints": robot.joint_names, "base": plan.base,
               "stops": plan.stops.tolist(), "segment_durations_s": plan.segment_durations.tolist(),
               "limits": {**limits_dict(plan.limits), "source": limits_source(args)}, **comparison_summary(comparison)}
    files = write_plan_outputs(comparison, summary, out, args.no_plots)
    print_plan_summary(comparison, limits_source(args))
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


# ---- plots of a plan -------------------------------------------------------------------------


def plan_caption(c: Comparison) -> str:
    return (f"model {c.name}, {c.plan.base} base; plan {c.plan.duration:.3f} s (rigid-joint plan "
            f"{c.rigid.duration:.3f} s); tracking runs: RK4 dt = {seconds(c.dt)}, {c.settle:g} s settling")


def plot_plan(c: Comparison, out: Path) -> List[Path]:
    figures = Figures(out, plan_caption(c))
    plot_plan_angles(figures, c)
    plot_plan_deflection(figures, c)
    plot_plan_torque(figures, c)
    plot_plan_speed(figures, c)
    plot_plan_base(figures, c)
    plot_plan_vs_rigid(figures, c)
    return figures.files


def mark_segments(ax: Any, plan: Plan) -> None:
    """Dotted vertical lines where the arm stops between segments."""
    for end in np.cumsum(plan.segment_durations)[:-1]:
        ax.axvline(end, color="gray", ls=":", lw=1)


def mark_binding(ax: Any, plan: Plan) -> None:
    """A dashed red line where each segment's binding limit peaks."""
    bindings = plan.bindings
    for b in bindings:
        joint = f" on {b['joint_name']}" if b["joint_name"] else ""
        segment = f"segment {b['segment'] + 1} " if len(bindings) > 1 else ""
        ax.axvline(b["time"], color="tab:red", ls="--", lw=0.9,
                   label=f"{segment}binding: {b['limit']}{joint}, t = {b['time']:.3g} s")


def plot_plan_angles(figures: Figures, c: Comparison) -> None:
    plan, names = c.plan, c.plan.arm.robot.joint_names
    fig, ax = figures.new("Planned link angles q(t): rest to rest through the stops", height=5.0)
    ends = np.r_[0.0, np.cumsum(plan.segment_durations)]
    for i, name in enumerate(names):
        ax.plot(plan.t, np.degrees(plan.q[:, i]), lw=1.5, color=f"C{i % 10}", label=name)
        ax.plot(ends, np.degrees(plan.stops[:, i]), "o", color=f"C{i % 10}", ms=4)
    mark_segments(ax, plan)
    mark_binding(ax, plan)
    ax.set(xlabel="time (s)", ylabel="q (deg)",
           title="dots: the stops (start, waypoints, goal), where the arm is at rest")
    ax.title.set_fontsize(9)
    joint_legend(ax, "joint")
    figures.save(fig, "plan_angles.png")


def joint_panels(figures: Figures, title: str, n: int) -> Tuple[Any, Any]:
    cols = 1 if n <= 4 else 2
    rows = math.ceil(n / cols)
    fig, axes = figures.new(title, rows=rows, height=1.6 + 1.5 * rows, cols=cols, sharex=True, squeeze=False)
    for i, ax in enumerate(axes.flat):
        ax.set_visible(i < n)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    if n % cols:
        axes[-2, -1].xaxis.set_tick_params(labelbottom=True)
        axes[-2, -1].set_xlabel("time (s)")
    return fig, axes


def plot_plan_deflection(figures: Figures, c: Comparison) -> None:
    """One panel per joint: the planned deflection and the one of the flexible plan's tracking
    run, which follows it; after the slew the springs relax."""
    plan, names = c.plan, c.plan.arm.robot.joint_names
    traj = c.flexible_run["trajectory"]
    rows = plot_rows(len(traj.t))
    planned, simulated = plan.theta - plan.q, traj.deflection[rows]
    fig, axes = joint_panels(figures, "Planned joint deflection θ − q (spring stretch) and the tracking run's",
                             len(names))
    for i, ax in enumerate(axes.flat[: len(names)]):
        factor, unit = angle_unit(float(max(np.abs(planned[:, i]).max(), np.abs(simulated[:, i]).max())))
        ax.plot(plan.t, planned[:, i] * factor, lw=2.2, color=f"C{i % 10}", alpha=0.6, label="plan")
        ax.plot(traj.t[rows], simulated[:, i] * factor, lw=0.9, color="black", ls="--", label="tracking run")
        ax.axhline(0, color="black", lw=0.5)
        ax.axvline(plan.duration, color="gray", ls=":", lw=1, label="end of the slew")
        ax.set_ylabel(f"θ − q ({unit})")
        ax.set_title(f"{names[i]}: planned peak {np.abs(planned[:, i]).max() * factor:.3g} {unit}", fontsize=8.5)
        if i == 0:
            ax.legend(fontsize=7.5, loc="best")
    figures.save(fig, "plan_deflection.png")


def against_limit(ax: Any, peak: float, limit: Optional[float], unit: str, symmetric: bool = True) -> str:
    """Scales ``ax`` to its data (peak ``|value|``) and draws ``±limit`` (dashed) when it is
    within view; a limit far above the data (the data under half of it) is left off the scale
    rather than flattening every curve. Returns the title's words for it."""
    if limit is None:
        return "no limit given"
    share = peak / limit
    top = 1.15 * (limit if share >= 0.5 else max(peak, 1e-300))
    for sign in ((1, -1) if symmetric else (1,)):
        if share >= 0.5:
            ax.axhline(sign * limit, color="black", ls="--", lw=0.9,
                       label=f"limit {limit:.3g} {unit}" if sign > 0 else None)
    ax.set_ylim(-top if symmetric else 0.0, top)
    text = f"peak {peak:.3g} of {limit:.3g} {unit} ({share:.1%})"
    if share >= 0.5:
        return text
    return text + ", limit off scale"


def plot_plan_limited(figures: Figures, c: Comparison, values: Array, limits: Array, what: str, symbol: str,
                      unit: str, name: str) -> None:
    """One panel per joint: a planned quantity against its limit, each panel scaled to its data
    (the limit dashed when within view, else named in the title); the binding peaks marked."""
    plan, names = c.plan, c.plan.arm.robot.joint_names
    bindings = plan.bindings
    fig, axes = joint_panels(figures, f"Planned {what} {symbol} against its limits (dashed where in view); red "
                                      f"dots: where a limit binds", len(names))
    key = {"u": "motor_torque", "q̇": "joint_speed"}[symbol]
    for i, ax in enumerate(axes.flat[: len(names)]):
        v = values[:, i]
        ax.plot(plan.t, v, lw=1.3, color=f"C{i % 10}")
        ax.axhline(0, color="black", lw=0.4)
        binds = [b for b in bindings if b["limit"] == key and b["joint"] == i]
        for b in binds:
            sign = np.sign(np.interp(b["time"], plan.t, v))
            ax.plot(b["time"], sign * b["value"], "o", color="tab:red", ms=5)
        words = against_limit(ax, float(np.abs(v).max()), float(limits[i]), unit)
        ax.set_ylabel(f"{symbol} ({unit})")
        where = ""
        if binds:
            where = " — binds" + (" in segment " + ", ".join(str(b["segment"] + 1) for b in binds)
                                  if len(bindings) > 1 else "")
        ax.set_title(f"{names[i]}: {words}{where}", fontsize=8.5, color="tab:red" if binds else "black")
        mark_segments(ax, plan)
    figures.save(fig, name)


def plot_plan_torque(figures: Figures, c: Comparison) -> None:
    """The planned motor torques against their limits."""
    plot_plan_limited(figures, c, c.plan.u, np.broadcast_to(c.plan.limits.motor_torque, (c.plan.arm.dof,)),
                      "motor torque", "u", "N·m", "plan_motor_torque.png")


def plot_plan_speed(figures: Figures, c: Comparison) -> None:
    """The planned joint speeds against their limits."""
    plot_plan_limited(figures, c, c.plan.qd, np.broadcast_to(c.plan.limits.joint_speed, (c.plan.arm.dof,)),
                      "joint speed", "q̇", "rad/s", "plan_joint_speed.png")


def plot_plan_base(figures: Figures, c: Comparison) -> None:
    plan = c.plan
    if plan.base == "held":
        fig, axes = figures.new("Held base: the wrench its actuators apply (base frame)", rows=2, height=6.5,
                                sharex=True)
        limits = (plan.limits.base_torque, plan.limits.base_force)
        for ax, k, symbol, unit, bound, what in ((axes[0], 0, "n", "N·m", limits[0], "moment about the base origin"),
                                                 (axes[1], 3, "F", "N", limits[1], "force")):
            values = plan.base_wrench[:, k:k + 3]
            for a, axis in enumerate("xyz"):
                ax.plot(plan.t, values[:, a], lw=1, label=f"${symbol}_{axis}$")
            norm = np.linalg.norm(values, axis=1)
            ax.plot(plan.t, norm, color="black", lw=1.8, label=f"$|{symbol}|$ (peak {norm.max():.3g} {unit})")
            words = against_limit(ax, float(norm.max()), bound, unit, symmetric=False)
            if bound is not None:  # the components are signed: room below zero for them
                ax.set_ylim(bottom=-ax.get_ylim()[1])
            ax.axhline(0, color="black", lw=0.4)
            title = f"{what}: |{symbol}| {words}" if bound is not None else f"{what} (no limit given)"
            ax.set(ylabel=f"${symbol}_B$ ({unit})", title=title)
            ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        axes[1].set(xlabel="time (s)")
        figures.save(fig, "plan_base.png")
        return
    fig, axes = figures.new("Free-floating base: its planned reaction to the slew (zero momentum)", rows=2,
                            height=6.5, sharex=True)
    quat = plan.base_pose[:, 3:]
    yaw, pitch, roll = euler_zyx(quat)
    for angle, label in ((yaw, "yaw (about z)"), (pitch, "pitch (about y′)"), (roll, "roll (about x″)")):
        axes[0].plot(plan.t, np.degrees(angle), lw=1.2, label=label)
    total = rotation_angle_deg(quat[0], quat)
    axes[0].plot(plan.t, total, color="black", lw=2, label=f"total rotation ({total[-1]:.3g}° at the end)")
    axes[0].set(ylabel="attitude (deg)", title="Euler angles, intrinsic z-y′-x″: R = Rz(yaw) · Ry(pitch) · Rx(roll)")
    shift = (plan.base_pose[:, :3] - plan.base_pose[0, :3]) * 1e3
    for a, axis in enumerate("xyz"):
        axes[1].plot(plan.t, shift[:, a], lw=1.2, label=f"$\\Delta r_{axis}$")
    axes[1].set(xlabel="time (s)", ylabel="base origin shift (mm)", title="base origin, inertial frame")
    for ax in axes:
        ax.axhline(0, color="black", lw=0.4)
        ax.title.set_fontsize(9)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    figures.save(fig, "plan_base.png")


def run_series(run: Dict[str, Any]) -> Dict[str, Array]:
    """Per step of a tracking run: the link error, the deflection and the base's departure from
    the plan (NaN where exactly zero, for log axes)."""
    traj, ref = run["trajectory"], run["reference"]
    x_q, x_theta, pose = traj.q, traj.theta, traj.base_pose
    series = {
        "t": ref["t"],
        "tracking": np.abs(x_q - ref["q"]).max(axis=1),
        "deflection": np.abs(x_theta - x_q).max(axis=1),
        "attitude": relative_rotation(ref["base_pose"][:, 3:], pose[:, 3:]),
        "position": np.linalg.norm(pose[:, :3] - ref["base_pose"][:, :3], axis=1),
    }
    for key in ("tracking", "deflection", "attitude", "position"):
        series[key] = np.where(series[key] > 0, series[key], np.nan)
    return series


def relative_rotation(a: Array, b: Array) -> Array:
    """The angle (rad) of the rotation from unit quaternions ``a`` to ``b`` (x, y, z, w), (k, 4)
    each: ``2 atan2(|vec(a* ⊗ b)|, |w(a* ⊗ b)|)``, accurate for small angles too (unlike
    ``arccos`` of the dot product, which bottoms out near 1e-8 rad)."""
    av, aw, bv, bw = a[:, :3], a[:, 3], b[:, :3], b[:, 3]
    w = aw * bw + np.sum(av * bv, axis=1)
    v = aw[:, None] * bv - bw[:, None] * av - np.cross(av, bv)
    angle: Array = 2 * np.arctan2(np.linalg.norm(v, axis=1), np.abs(w))
    return angle


def log_floor(curves: Sequence[Tuple[Array, Array]], start: float) -> float:
    """A lower limit for a log axis of ``(t, values)`` curves that leaves out the first instants
    (where errors grow from exactly zero) but keeps the smallest levels after ``start`` (s)."""
    later = np.concatenate([v[t >= start] for t, v in curves])
    later = later[np.isfinite(later) & (later > 0)]
    if later.size == 0:
        return 1e-16
    return 10.0 ** math.floor(math.log10(0.5 * float(np.percentile(later, 2))))


def plot_plan_vs_rigid(figures: Figures, c: Comparison) -> None:
    """The flexible plan against the rigid-joint plan of the same slew, both run on the flexible
    arm: peak commanded torque against the limit, tracking error, deflection (residual vibration
    after the slew), base disturbance, and the measures."""
    names = c.plan.arm.robot.joint_names
    fig = figures.plt.figure(figsize=(14, 8.6), layout="constrained")
    fig.suptitle("Flexible plan vs rigid-joint plan of the same slew, both run on the flexible arm under a "
                 f"motor PD (kp {gain_range(c.kp)} N·m/rad, kd {gain_range(c.kd)} N·m·s/rad)\n{figures.caption}",
                 fontsize=11)
    grid = fig.add_gridspec(2, 3)
    colours = {"flexible plan": "tab:blue", "rigid-joint plan": "tab:orange"}
    bars = fig.add_subplot(grid[0, 0])
    x = np.arange(len(names))
    top = 0.0
    for k, (label, plan, run) in enumerate(c.runs):
        share = 100 * run["peak_motor_torque"] / np.asarray(plan.limits.motor_torque)
        top = max(top, float(share.max()))
        bars.bar(x + (k - 0.5) * 0.38, share, 0.38, color=colours[label], label=label)
        for i in np.flatnonzero(share > 100 + 1e-7):
            bars.annotate(f"{run['peak_motor_torque'][i]:.3g} N·m", (x[i] + (k - 0.5) * 0.38, share[i]),
                          ha="center", va="bottom", fontsize=7.5, color="tab:red")
    bars.set_xticks(x, names, rotation=35, ha="right", fontsize=8)
    # scaled to the bars: the limit (100 %) is drawn when they come near it, else named
    title = "peak commanded motor torque (feedforward + PD)"
    if top >= 50:
        bars.axhline(100, color="tab:red", ls="--", lw=1, label="limit")
        bars.set_ylim(0, max(145, 1.3 * top))
    else:
        bars.set_ylim(0, 1.45 * top)
        title += f"\nall under {top:.3g} % of their limits (100 %: off this scale)"
    bars.set(ylabel="peak commanded |u| / limit (%)", title=title)
    bars.title.set_fontsize(9.5)
    bars.legend(fontsize=7.5, loc="upper center", ncol=3)
    panels = (
        (fig.add_subplot(grid[0, 1]), "tracking", "rad", "link tracking error max|q − q_plan|"),
        (fig.add_subplot(grid[0, 2]), "deflection", "rad", "joint deflection max|θ − q|: residual vibration"),
        (fig.add_subplot(grid[1, 0]), "attitude", "rad", "base attitude departure from the plan"),
        (fig.add_subplot(grid[1, 1]), "position", "m", "base position departure from the plan"),
    )
    series = {label: run_series(run) for label, _, run in c.runs}
    end = c.plan.duration
    for ax, key, unit, title in panels:
        for label, plan, run in c.runs:
            s = series[label]
            ax.semilogy(s["t"], s[key], lw=1.1, color=colours[label], label=label)
        t = series["flexible plan"]["t"]
        ax.axvspan(end, t[-1], color="0.92", zorder=0, label="after the slew (at rest)")
        ax.set_ylim(bottom=log_floor([(s["t"], s[key]) for s in series.values()], 0.05 * end))
        ax.set(xlabel="time (s)", ylabel=f"{key_label(key)} ({unit})", title=title, xlim=(0, t[-1]))
        ax.title.set_fontsize(9.5)
        ax.legend(fontsize=7.5, loc="lower left" if key == "deflection" else "lower right")
    table = fig.add_subplot(grid[1, 2])
    table.axis("off")
    table.set_title("measures (residual: from the end of the slew on)", fontsize=9.5)
    rows = [["duration", f"{c.plan.duration:.3f} s", f"{c.rigid.duration:.3f} s"]]
    shares = [torque_share(plan, run) for _, plan, run in c.runs]
    rows.append(["peak |u| / limit", *[f"{share:.1%}" + (" OVER" if share > 1 + 1e-9 else "") for share, _ in shares]])
    rows.append(["  on joint", *[names[joint] for _, joint in shares]])
    for label, key, unit in (("tracking error", "tracking_error", "rad"),
                             ("residual deflection", "residual_deflection", "rad"),
                             ("residual link error", "residual_link_error", "rad"),
                             ("base position error", "base_position_error", "m"),
                             ("base attitude error", "base_attitude_error", "rad")):
        rows.append([label, *[f"{run[key]:.2e} {unit}" for _, _, run in c.runs]])
    cell = table.table(cellText=rows, colLabels=["", "flexible plan", "rigid-joint plan"], cellLoc="left",
                       colWidths=[0.34, 0.33, 0.33], bbox=[0.0, 0.08, 1.0, 0.84])
    cell.auto_set_font_size(False)
    cell.set_fontsize(8)
    figures.save(fig, "plan_vs_rigid.png")


def key_label(key: str) -> str:
    return {"tracking": "max|q − q_plan|", "deflection": "max|θ − q|", "attitude": "rotation angle",
            "position": "|r_B − r_B,plan|"}[key]


# ---- the demo's comparison -------------------------------------------------------------------


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


# ---------------------------------------------------------------------------------------------
# the commands
# ---------------------------------------------------------------------------------------------


def demo_job(args: argparse.Namespace) -> Job:
    robot = models.space_arm()
    arm = FlexibleArm(robot, models.space_arm_joints())
    return Job(arm, robot.name, SPACE_ARM_SLEW, BUS_SIDE, np.zeros(3), compare_plans=True)


def joint_list(values: Optional[List[str]]) -> List[str]:
    """``--locked-joints a,b --locked-joints c`` -> ``[a, b, c]``."""
    return [name.strip() for value in values or [] for name in value.split(",") if name.strip()]


def load_robot(args: argparse.Namespace) -> Robot:
    locked = joint_list(args.locked_joints)
    try:
        robot = Robot.from_urdf(args.urdf, ee_link=args.ee_link, locked_joints=locked or None,
                                ee_links=joint_list(args.ee_links) or None)
    except (ValueError, OSError) as e:
        raise urdf_error(e) from None
    if robot.dof == 0:
        held = f"with {', '.join(locked)} locked" if locked else "(every joint is fixed)"
        raise CliError("--locked-joints", f"'{robot.name}' has no moving joints {held}: nothing to "
                                          f"simulate; keep at least one revolute joint unlocked")
    return robot


def mount_on_bus(robot: Robot, args: argparse.Namespace) -> Tuple[Robot, float, Array]:
    """The robot on the bus given by --base-mass/--base-inertia/--base-com, and the side (m) and
    centre of the cube drawn for it."""
    com = np.zeros(3) if args.base_com is None else np.asarray(args.base_com)
    if args.base_mass is None:
        for flag, value in (("--base-inertia", args.base_inertia), ("--base-com", args.base_com)):
            if value is not None:
                raise CliError(flag, "describes the bus given by --base-mass KG; add --base-mass")
        return robot, sketch_side(robot), com
    mass = args.base_mass
    inertia = None if args.base_inertia is None else np.asarray(args.base_inertia)
    try:
        robot = robot.with_base_inertia(mass, inertia, com)  # default: the solid cube of BUS_SIDE
    except ValueError as e:
        message = str(e)
        flag = "--base-com" if message.startswith("com") else "--base-inertia" if "inertia" in message else "--base-mass"
        raise CliError(flag, message) from None
    if inertia is None:
        return robot, BUS_SIDE, com
    # the solid cube with this mass and (mean) inertia: I = m s² / 6
    return robot, max(float(np.sqrt(6 * max(float(inertia.mean()), 0.0) / mass)), 1e-3), com


def sketch_side(robot: Robot) -> float:
    """Edge (m) of the cube drawn for a base of unknown size: twice the distance to the first
    joint's body, at most 30 % of the arm's reach (at q = 0)."""
    bodies = robot.body_poses(np.r_[np.zeros(6), 1.0], np.zeros(robot.dof))[:, :3]
    reach = float(np.linalg.norm(bodies, axis=1).max())
    return max(min(2 * float(np.linalg.norm(bodies[1])), 0.3 * reach), 1e-3)


def load_arm(args: argparse.Namespace) -> Tuple[FlexibleArm, float, Array, Optional[str]]:
    """The URDF's arm on its bus with the joint parameters of --params (or the scaled defaults);
    with the side and centre of the cube drawn for the bus, and a note when the defaults are
    used."""
    robot = load_robot(args)
    robot, side, com = mount_on_bus(robot, args)
    note = None
    try:
        if args.params is None:
            joints, note = FlexibleJoints.defaults_for(robot), DEFAULTS_RULE
        else:
            joints = FlexibleJoints.from_toml(args.params, robot)
        arm = FlexibleArm(robot, joints)
    except (ValueError, OSError) as e:
        raise CliError("--params", cli_words(str(e))) from None
    return arm, side, com, note


def per_joint(values: Optional[Sequence[float]], flag: str, robot: Robot, default: Optional[float] = None) -> Array:
    """``values`` for every joint: one value (for all) or one per joint, in the robot's order."""
    if values is None:
        assert default is not None
        return np.full(robot.dof, default)
    array = np.asarray(values, dtype=float)
    if len(array) == 1:
        return np.full(robot.dof, array[0])
    if len(array) != robot.dof:
        raise CliError(flag, f"expected 1 or {robot.dof} values (one per joint: "
                             f"{', '.join(robot.joint_names)}), given {len(array)}")
    return array


def simulate_job(args: argparse.Namespace) -> Job:
    arm, side, com, note = load_arm(args)
    slew = per_joint(args.slew, "--slew", arm.robot, default=0.3)
    return Job(arm, arm.robot.name, slew, side, com, note)


# ---------------------------------------------------------------------------------------------
# the parser
# ---------------------------------------------------------------------------------------------


def common_options(p: argparse.ArgumentParser, duration: float) -> None:
    p.add_argument("--duration", metavar="S", type=positive, default=duration,
                   help="simulated time, s (default %(default)s)")
    p.add_argument("--dt", metavar="S", type=positive, default=1e-3, help="RK4 step, s (default %(default)s)")
    p.add_argument("--slew-time", metavar="S", type=positive, default=5.0,
                   help="duration of the quintic slew, s (default %(default)s)")
    pd = p.add_argument_group("the motor PD (chosen from the physics, never from --dt)")
    pd.add_argument("--bandwidth", metavar="HZ", type=positive, default=0.25,
                    help="closed-loop bandwidth of each joint, Hz: the gains come from it, the damping "
                         "ratio and each joint's motor inertia, link inertia at q = 0 and spring "
                         "(FlexibleArm.motor_pd_gains; default %(default)s)")
    pd.add_argument("--damping-ratio", metavar="ZETA", type=positive, default=1.0,
                    help="closed-loop damping ratio of each joint (default %(default)s: critical)")
    pd.add_argument("--kp", metavar="NM_PER_RAD", type=non_negative, nargs="+", default=None,
                    help="motor PD stiffness, N·m/rad, one value or one per joint (replaces the "
                         "bandwidth rule's)")
    pd.add_argument("--kd", metavar="NMS_PER_RAD", type=non_negative, nargs="+", default=None,
                    help="motor PD damping, N·m·s/rad, one value or one per joint (replaces the "
                         "bandwidth rule's)")
    pd.add_argument("--force", action="store_true",
                    help="run even when --dt is past the RK4 stability limit of the closed loop "
                         "(refused otherwise); the run then warns and most likely diverges")
    p.add_argument("--out", metavar="DIR", default="orbitflex_out",
                   help="output folder, created if missing (default %(default)s)")
    p.add_argument("--csv", action="store_true", help="also write trajectory.csv (t and x, named columns)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--no-animation", action="store_true",
                   help="skip animation.html (the 3-D view; written when orbitflex[viz] is installed)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--record-every", metavar="K", type=at_least_one, default=1,
                   help="keep every K-th step's state and the last (rows at t = 0, K·dt, 2K·dt, ..., "
                        "and the end): K times less memory and output for long runs; the energy "
                        "balance then is not computed (default %(default)s: every step)")


def at_least_one(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, given {text}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, given {text}")
    return value


def model_options(p: argparse.ArgumentParser, verb: str) -> None:
    """The URDF, its joint parameters and its bus."""
    p.add_argument("urdf", metavar="URDF", help="path to the URDF; the root link is the floating base")
    p.add_argument("--params", metavar="TOML", default=None,
                   help="joint parameters keyed by joint name (keys below; default: scaled to the links)")
    p.add_argument("--ee-link", metavar="LINK", default=None,
                   help="the one end-effector link (default: every leaf link is an end-effector)")
    p.add_argument("--ee-links", metavar="LINKS", action="append", default=None,
                   help="end-effector links of a tree, in order: a comma-separated list; repeatable")
    p.add_argument("--package", metavar="NAME=DIR", type=package_dir, action="append", default=None,
                   help="where the ROS package NAME of package:// meshes is (for animation.html); "
                        "repeatable; ROS_PACKAGE_PATH and the folders above the URDF are searched too")
    p.add_argument("--locked-joints", metavar="NAMES", action="append", default=None,
                   help="joints held at zero (e.g. fingers): a comma-separated list; repeatable")
    if verb == "simulate":
        p.add_argument("--slew", metavar="RAD", type=finite, nargs="+", default=None,
                       help="slew per joint, rad: one value for every joint, or one per joint (default 0.3)")
    p.add_argument("--base-mass", metavar="KG", type=positive, default=None,
                   help="mount the arm on a bus of this mass, replacing the root link's inertia")
    p.add_argument("--base-inertia", metavar=("IXX", "IYY", "IZZ"), type=finite, nargs=3, default=None,
                   help=f"the bus's principal moments about its COM, kg·m² (default: a solid "
                        f"{BUS_SIDE:g} m cube of --base-mass)")
    p.add_argument("--base-com", metavar=("X", "Y", "Z"), type=finite, nargs=3, default=None,
                   help="the bus's COM in the root link's frame, m (default 0 0 0, the root link's "
                        "origin; 0 0 -0.75 puts a 1.5 m bus under an arm that points up z)")


def simulate_options(sim: argparse.ArgumentParser) -> None:
    model_options(sim, "simulate")


def non_negative(text: str) -> float:
    value = finite(text)
    if not value >= 0:
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, given {text}")
    return value


def plan_options(p: argparse.ArgumentParser) -> None:
    model_options(p, "plan")
    slew = p.add_argument_group("the slew (rad, link side; one value for every joint, or one per joint)")
    slew.add_argument("--goal", metavar="RAD", type=finite, nargs="+", required=True, help="where the slew ends")
    slew.add_argument("--start", metavar="RAD", type=finite, nargs="+", default=None,
                      help="where it starts, at rest with relaxed springs (default 0)")
    slew.add_argument("--waypoint", metavar="RAD", type=finite, nargs="+", action="append", default=None,
                      help="a stop on the way, where the arm comes to rest; repeatable, in order")
    slew.add_argument("--base", choices=("held", "free"), default="held",
                      help="held: the bus's actuators hold it inertially still (and --base-force, "
                           "--base-torque bound them); free: free floating from rest (default %(default)s)")
    limits = p.add_argument_group("limits (link side; one value for every joint, or one per joint)")
    limits.add_argument("--motor-torque", metavar="NM", type=positive, nargs="+", default=None,
                        help="|u_i| bound, N·m (motor torque after the gearbox; default: the URDF's "
                             "<limit effort>; more than it warns)")
    limits.add_argument("--joint-speed", metavar="RAD_S", type=positive, nargs="+", default=None,
                        help="|q̇_i| bound, rad/s (default: the URDF's <limit velocity>; more than it warns)")
    limits.add_argument("--base-force", metavar="N", type=positive, default=None,
                        help="bound on the norm of the force holding the bus, N (--base held; default none)")
    limits.add_argument("--base-torque", metavar="NM", type=positive, default=None,
                        help="bound on the norm of the moment holding the bus, about the root link's origin "
                             "(not the bus COM when --base-com moves it), N·m (--base held; default none)")
    runs = p.add_argument_group("the tracking runs (both plans simulated on the flexible arm)")
    runs.add_argument("--dt", metavar="S", type=positive, default=None,
                      help=f"RK4 step, s (default {TRACK_DT:g}, lowered when past {DT_MARGIN * 100:.0f}%% of the "
                           "RK4 stability limit of the arm under the PD; a --dt past the limit is refused)")
    runs.add_argument("--kp", metavar="NM_PER_RAD", type=non_negative, nargs="+", default=None,
                      help=f"motor PD stiffness, N·m/rad (default j·(2π·{SERVO_HZ:g} Hz)², j the motor inertia)")
    runs.add_argument("--kd", metavar="NMS_PER_RAD", type=non_negative, nargs="+", default=None,
                      help=f"motor PD damping, N·m·s/rad (default 2 j·(2π·{SERVO_HZ:g} Hz))")
    runs.add_argument("--settle", metavar="S", type=non_negative, default=2.0,
                      help="time simulated at rest after each slew, to measure the residual vibration, s "
                           "(default %(default)s)")
    p.add_argument("--out", metavar="DIR", default="orbitflex_out",
                   help="output folder, created if missing (default %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")


def build_parser() -> Parser:
    parser = Parser(prog="orbitflex", description="Flexible-joint space manipulator simulation: a "
                    "free-floating slew of an arm on a spacecraft bus.")
    parser.add_argument("--version", action="version", version=f"orbitflex {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="{demo,simulate,plan,campaign,modes,fmu}")
    demo = sub.add_parser("demo", help="simulate the built-in space arm (bus + 7-joint arm), free floating",
                          description="Simulates the built-in space arm (a 500 kg bus with a 7-joint arm) "
                                      "slewing free-floating, and writes the trajectory, a summary and plots.")
    common_options(demo, 20.0)
    sim = sub.add_parser("simulate", help="simulate your URDF, free floating, with the same slew",
                         description="Simulates your URDF slewing free-floating (every joint by --slew\n"
                                     "under a motor PD), and writes the trajectory, a summary and plots.",
                         epilog=SIMULATE_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    simulate_options(sim)
    common_options(sim, 10.0)
    plan = sub.add_parser("plan", help="plan a minimum-time slew of your URDF under limits, beside its "
                          "rigid-joint plan",
                          description="Plans the minimum-time rest-to-rest slew of your URDF under motor-torque,\n"
                                      "joint-speed and base limits with the flexible-joint model, plans the same\n"
                                      "slew as if the joints were rigid, simulates both on the flexible arm, and\n"
                                      "writes the plans, the comparison, a summary and plots.",
                          epilog=PLAN_EPILOG + "\n" + SIMULATE_EPILOG.split("\nexamples:")[0],
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    plan_options(plan)
    camp = sub.add_parser("campaign", help="run a Monte-Carlo campaign file, locally or on a Dask cluster",
                          description="Runs the Monte-Carlo campaign declared in FILE (see examples/campaign.toml):\n"
                                      "many slews with dispersed parameters, locally on every core or on a Dask\n"
                                      "cluster, and writes one row per run to DIR/runs.parquet, percentiles to\n"
                                      "DIR/summary.csv and histograms to DIR/histograms.png. The table is the\n"
                                      "same, bit for bit, wherever it runs.",
                          epilog=CAMPAIGN_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    camp.add_argument("file", metavar="FILE", help="the campaign file (TOML)")
    camp.add_argument("--runs", type=at_least_one, default=None, help="number of runs (default: the file's)")
    camp.add_argument("--scheduler", metavar="ADDRESS", default=None,
                      help="a Dask scheduler (tcp://host:8786); default: run here on every core")
    camp.add_argument("--scheduler-timeout", metavar="S", type=positive, default=10.0,
                      help="how long to wait for the scheduler to answer (default %(default)s s; a refused "
                           "connection fails at once)")
    camp.add_argument("--out", metavar="DIR", default="campaign_out",
                      help="output folder, created if missing (default %(default)s)")
    camp.add_argument("--chunk-runs", type=at_least_one, default=None, metavar="K",
                      help="runs per batch (per Dask task); default 256 here, about 4 tasks per worker thread on Dask")
    camp.add_argument("--threads", type=at_least_one, default=None,
                      help="threads per batch (default: every core here, 1 per Dask task)")
    camp.add_argument("--no-plots", action="store_true", help="skip histograms.png")
    camp.add_argument("--no-progress", action="store_true", help="no progress bar")
    from . import _cli_modes  # `orbitflex modes` lives in its own module

    _cli_modes.add_parser(sub)
    from . import _cli_fmu  # `orbitflex fmu` too

    _cli_fmu.add_parser(sub)
    return parser


CAMPAIGN_EPILOG = """\
examples:
  orbitflex campaign examples/campaign.toml --runs 1000
  orbitflex campaign examples/campaign.toml --runs 1000 --scheduler tcp://127.0.0.1:8786

Start a local Dask cluster in another shell with:
  dask scheduler --host 127.0.0.1 &  dask worker tcp://127.0.0.1:8786 --nworkers 2 --nthreads 1
"""


def campaign_command(args: argparse.Namespace) -> int:
    """``orbitflex campaign FILE``: runs the campaign, writes the table, summary and plots."""
    try:
        from . import campaign as campaigns
        import pandas  # noqa: F401
    except ImportError as e:
        raise CliError("campaign", f"needs pandas and pyarrow ({e}); pip install 'orbitflex[campaign]'") from None
    try:
        campaign = campaigns.Campaign.from_toml(args.file)
    except FileNotFoundError as e:
        raise CliError("FILE", str(e)) from None
    except ModelError as e:
        raise CliError("FILE", f"{args.file}: {e}" if not str(e).startswith(args.file) else str(e)) from None
    runs = args.runs if args.runs is not None else campaign.runs
    if args.scheduler:
        try:
            campaigns.reachable(args.scheduler, args.scheduler_timeout)
        except (ModelError, OSError) as e:  # TimeoutError is an OSError
            message = re.sub(r"^scheduler: ", "", str(e)).replace("a longer timeout", "a longer --scheduler-timeout")
            raise CliError("--scheduler", message) from None
    where = f"on the Dask cluster at {args.scheduler}" if args.scheduler else "here"
    print(f"campaign {campaign.name}: {runs} runs of {campaign.duration:g} s (dt = {campaign.dt:g} s, "
          f"{campaign.steps} steps), {where}")
    bar = None if args.no_progress else ProgressBar(runs, unit="run", desc="campaign")
    progress = None if bar is None else bar.to
    started = time.time()
    try:
        table = campaign.run(runs=runs, scheduler=args.scheduler, chunk_runs=args.chunk_runs,
                             threads=args.threads, progress=progress, timeout=args.scheduler_timeout)
    except ModelError as e:
        flag = "--runs" if str(e).startswith("runs:") and args.runs is not None else "FILE"
        raise CliError(flag, re.sub(r"^runs: ", "", str(e)) if flag == "--runs" else str(e)) from None
    except (OSError, TimeoutError) as e:
        if args.scheduler:
            raise CliError("--scheduler", f"cannot reach the Dask scheduler at {args.scheduler}: {e}") from None
        raise
    finally:
        if bar is not None:
            bar.close()
    seconds_taken = time.time() - started
    files = campaigns.write_outputs(table, campaign, Path(args.out), plots=not args.no_plots)
    failed = int((~table["ok"]).sum())
    print(f"{runs} runs in {seconds_taken:.1f} s, {failed} failed")
    stats = campaigns.summary(table)
    print(f"{'metric':<22}{'unit':>6}{'p5':>12}{'p50':>12}{'p95':>12}{'max':>12}")
    for metric, row in stats.iterrows():
        cells = "".join(f"{row[c]:>12.4g}" if c in row and row[c] == row[c] else f"{'-':>12}"
                        for c in ("p5", "p50", "p95", "max"))
        print(f"{metric:<22}{row['unit']:>6}{cells}")
    print("wrote:")
    for f in files:
        print(f"  {f}")
    return 1 if failed else 0


def reject_extra(args: argparse.Namespace, extra: List[str], parser: Optional[argparse.ArgumentParser] = None) -> NoReturn:
    """Arguments argparse did not place: most likely a list given to --locked-joints with spaces,
    or a flag misspelt (``--base_mass``: did you mean ``--base-mass``?)."""
    if getattr(args, "locked_joints", None) and not any(word.startswith("-") for word in extra):
        fail(f"--locked-joints: takes one name or a comma-separated list per occurrence "
             f"(--locked-joints a,b); unexpected: {' '.join(extra)}")
    known = command_flags(parser, args.command) if parser is not None else []
    hints = [(flag.split("=", 1)[0], match) for flag in extra if flag.startswith("--")
             for match in [closest_flag(flag, known)] if match]
    where = f"(see 'orbitflex {args.command} --help')" if args.command else "(see 'orbitflex --help')"
    if hints:
        flag, match = hints[0]
        fail(f"{flag}: no such flag; did you mean {match}? {where}")
    fail(f"unrecognized arguments: {' '.join(extra)} {where}")


def command_flags(parser: argparse.ArgumentParser, command: Optional[str]) -> List[str]:
    """The long flags of ``orbitflex COMMAND`` (or of ``orbitflex`` itself)."""
    target = parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and command in action.choices:
            target = action.choices[command]
    return [flag for flag in target._option_string_actions if flag.startswith("--")]


def closest_flag(flag: str, known: Sequence[str]) -> Optional[str]:
    """The known flag ``flag`` most likely meant: the same with ``_`` for ``-`` or in another
    case, else the closest spelling (difflib, at least 80 % alike)."""
    import difflib

    name = flag.split("=", 1)[0]
    normal = name.replace("_", "-").lower()
    if normal in known:
        return normal
    close = difflib.get_close_matches(normal, known, n=1, cutoff=0.8)
    return close[0] if close else None


def main(argv: Optional[List[str]] = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:
        reject_extra(args, extra, parser)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        if args.command == "plan":
            return plan_command(args)
        if args.command == "campaign":
            return campaign_command(args)
        if args.command == "modes":
            from . import _cli_modes

            return _cli_modes.command(args)
        if args.command == "fmu":
            from . import _cli_fmu

            return _cli_fmu.command(args)
        if args.dt > args.duration:
            raise CliError("--dt", f"expected at most --duration ({args.duration:g} s), given {args.dt:g}")
        job = demo_job(args) if args.command == "demo" else simulate_job(args)
        return run(job, args)
    except CliError as e:
        print(f"orbitflex: error: {e}", file=sys.stderr)
        return 2
    except MemoryError:
        print("orbitflex: error: --duration/--dt: out of memory; shorten --duration or lengthen --dt",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("orbitflex: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # stdout closed early (`orbitflex demo | head`): the files are written
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1


if __name__ == "__main__":
    sys.exit(main())
