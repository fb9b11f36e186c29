"""Command line: ``orbitflex demo`` and ``orbitflex simulate URDF``.

Both run the same job: a free-floating slew of the arm under the built-in motor-side PD
controller, long enough to show the base's reaction and the joints' vibration, then print a
summary and write the trajectory, ``summary.json`` and plots into an output folder.

Exit codes: 0 for a completed run, 1 when the run diverged (the outputs then describe the
finite part before the failure), 2 for a usage error (one line ``orbitflex: error: FLAG: ...``).
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

from . import FlexibleArm, FlexibleJoints, MotorPD, Robot, SimulationError, Trajectory, __version__, models

Array = npt.NDArray[np.float64]
Rows = npt.NDArray[np.intp]  # indices of the rows drawn in a plot

# Default slew for the built-in arm (rad, link side), one entry per joint.
SPACE_ARM_SLEW = np.array([0.4, 0.6, -0.5, 0.8, -0.6, 0.5, 1.0])
# Side (m) of the built-in arm's bus, and of the solid cube that --base-mass alone stands for.
BUS_SIDE = 1.5

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

    message = re.sub(r"locked_joints=\[([^\]]*)\]", locked, message)
    message = re.sub(r"(?<![\w-])locked_joints\b", "--locked-joints", message)
    return re.sub(r"(?<![\w-])ee_link\b", "--ee-link", message)


def urdf_error(error: Exception) -> CliError:
    """A URDF-loading error, under the flag it points to: ``--ee-link`` or ``--locked-joints``
    if it names one (the first one it names), else ``URDF``."""
    message = cli_words(str(error))
    named = [(message.find(flag), flag) for flag in ("--ee-link", "--locked-joints") if flag in message]
    if not named:
        return CliError("URDF", message)
    flag = min(named)[1]
    # "unknown link (--ee-link) 'x'" reads "unknown link 'x'" once the flag leads the line
    return CliError(flag, re.sub(rf" \((?:in )?{flag}\)", "", message))


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``orbitflex: error: --dt: ...`` (exit code 2)."""

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


def pd_gains(arm: FlexibleArm, q0: Array, bandwidth_hz: float, dt: float,
             damping_ratio: float = 1.0) -> Tuple[Array, Array]:
    """Motor-side PD gains that place each joint's slow (rigid) mode near ``bandwidth_hz``:
    ``kp = w^2 (m_i + j_i)``, ``kd = 2 zeta w (m_i + j_i)``, with ``m_i`` the diagonal of ``M_r``.

    The derivative gain also creates a fast motor pole near ``-kd / j``; RK4 is stable on the real
    axis only for ``|lambda dt| < 2.78``, so ``kd`` is capped at ``0.5 j / dt``."""
    _, j, _, _ = arm.parameters
    m = np.diag(arm.robot.mass_matrix(q0))[6:]
    w = 2 * np.pi * np.float64(bandwidth_hz)
    with np.errstate(over="ignore", invalid="ignore"):
        kp, kd = w**2 * (m + j), np.minimum(2 * damping_ratio * w * (m + j), 0.5 * j / dt)
    if not (np.isfinite(kp).all() and np.isfinite(kd).all()):
        raise CliError("--bandwidth", f"{bandwidth_hz:g} Hz makes the PD gains overflow "
                                      f"(kp = w² (m + j) is not finite); the default is 0.25 Hz")
    return kp, kd


def slew_controller(arm: FlexibleArm, slew: Array, steps: int, dt: float, slew_time: float,
                    bandwidth_hz: float) -> MotorPD:
    """The motor PD that follows a quintic slew of ``slew`` (rad per joint) over ``slew_time``
    seconds, tabulated for ``steps`` steps of ``dt``."""
    kp, kd = pd_gains(arm, np.zeros(arm.dof), bandwidth_hz, dt)
    t = np.arange(steps, dtype=np.float64) * dt
    shape, dshape = quintic(t / slew_time)
    theta_ref = np.outer(shape, slew)
    theta_dot_ref = np.outer(dshape / slew_time, slew)
    return MotorPD(kp, kd, theta_ref, theta_dot_ref)


# ---------------------------------------------------------------------------------------------
# memory: refuse a run that cannot fit before allocating it
# ---------------------------------------------------------------------------------------------


def run_bytes(steps: int, n: int) -> Dict[str, int]:
    """Bytes a run of ``steps`` steps of an ``n``-joint arm allocates, by part."""
    rows = steps + 1
    return {
        "reference tables": 2 * steps * n * 8,  # theta_ref, theta_dot_ref
        "record": rows * (14 + 4 * n) * 8 + steps * n * 8,  # t and x per row, u per step
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


def check_memory(steps: int, n: int) -> None:
    parts = run_bytes(steps, n)
    need, free = sum(parts.values()), free_memory()
    if free is not None and need > free:
        sizes = ", ".join(f"{name} {gb(size)}" for name, size in parts.items())
        raise CliError("--duration/--dt", f"{steps:,} steps of {n} joints need about {gb(need)} "
                                          f"({sizes}) but {gb(free)} of memory is free; shorten "
                                          f"--duration or lengthen --dt")


def gb(size: int) -> str:
    """A size in GB, or TB from 1000 GB."""
    return f"{size / 1e9:.3g} GB" if size < 1e12 else f"{size / 1e12:,.0f} TB"


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


@dataclass
class Outcome:
    traj: Trajectory
    elapsed: float  # s of wall time
    failure: Optional[SimulationError] = None
    warnings: int = 0  # how many warnings simulate emitted (dt past the RK4 stability limit)


class ProgressBar:
    """A tqdm bar driven by ``simulate``'s ``progress(done, total)`` callback, opened at the
    first call (after any warning ``simulate`` prints before it starts)."""

    def __init__(self, total: int):
        self.total = total
        self.bar: Any = None

    def to(self, done: int, total: int) -> None:
        if self.bar is None:
            try:
                from tqdm import tqdm
            except ImportError:  # tqdm is a dependency, but keep the simulator usable without it
                return
            self.bar = tqdm(total=self.total, unit="step", desc="simulating", file=sys.stderr,
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


def simulate(arm: FlexibleArm, pd: MotorPD, steps: int, dt: float, progress: bool) -> Outcome:
    """Simulates ``steps`` steps under ``pd`` in one ``simulate`` call. A run that diverges keeps
    the steps computed before the failure."""
    bar = ProgressBar(steps) if progress else None
    printer = WarningPrinter()
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = printer
        try:
            traj = arm.simulate(arm.state(), dt, steps, u=pd, progress=bar.to if bar else None)
            outcome = Outcome(traj, time.perf_counter() - start)
        except SimulationError as e:
            outcome = Outcome(e.trajectory, time.perf_counter() - start, e)
    if bar is not None:
        bar.close()
    outcome.warnings = printer.count
    if outcome.failure is not None:
        kept = len(outcome.traj) - 1
        print(f"orbitflex: the run failed: {failure_reason(outcome.failure)}; the outputs describe "
              f"the {kept} steps before the failure (exit code 1)", file=sys.stderr)
    return outcome


def failure_reason(e: SimulationError) -> str:
    """``step N (t = T s): why``, from the library's message."""
    reason = str(e).split("): ", 1)[-1]
    return f"step {e.step} (t = {e.time:.6g} s): {cli_words(reason)}"


def run(job: Job, args: argparse.Namespace) -> int:
    steps = int(round(args.duration / args.dt))
    check_memory(steps, job.arm.dof)
    pd = slew_controller(job.arm, job.slew, steps, args.dt, args.slew_time, args.bandwidth)
    out = output_folder(args.out)
    limit = job.arm.rk4_stability_limit(u=pd)
    print(f"{job.name}: {job.arm.dof} joints, total mass {job.arm.robot.total_mass:.1f} kg, "
          f"dt = {args.dt:g} s (RK4 limit of the closed loop at rest: {limit:.3g} s)")
    if job.note:
        print(job.note)
    outcome = simulate(job.arm, pd, steps, args.dt, progress=not args.quiet)
    with np.errstate(all="ignore"):  # a diverged run's finite part may overflow in the summary
        summary = summarise(job.name, outcome, steps)
        files = write_outputs(job, outcome, summary, out, args)
    print_summary(summary, job.arm.dof)
    width = max(len(str(f)) for f in files)
    print(f"\nwrote {len(files)} files:")
    for f in files:
        print(f"  {str(f):<{width}}  {OUTPUTS[f.name]}")
    return 0 if outcome.failure is None else 1


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
                  args: argparse.Namespace) -> List[Path]:
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
    except OSError as e:
        raise CliError("--out", f"cannot write {files[-1]}: {e.strerror or e}") from None
    return files


# ---------------------------------------------------------------------------------------------
# summary
# ---------------------------------------------------------------------------------------------


def rotation_angle_deg(q0: Array, q1: Array) -> Array:
    """Angle (deg) of the rotation between unit quaternions (x, y, z, w): ``q0`` (4,) and ``q1``
    (4,) or (k, 4)."""
    angle: Array = np.degrees(2 * np.arccos(np.clip(np.abs(q1 @ q0), 0.0, 1.0)))
    return angle


def energy_balance(traj: Trajectory) -> Tuple[float, float, float]:
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
    traj = outcome.traj
    steps = len(traj.t) - 1
    h = traj.momentum
    h_drift = np.abs(h - h[0]).max(axis=0)
    de, work, dissipated = energy_balance(traj)
    flow = float(np.sum(np.abs(np.diff(traj.energy))))
    deflection = np.abs(traj.deflection).max(axis=0)
    summary: Dict[str, Any] = {
        "model": name,
        "completed": outcome.failure is None,
        "warnings": outcome.warnings,
        "steps_requested": steps_asked,
        "steps": steps,
        "simulated_s": float(traj.t[-1]),
        "steps_per_second": steps / outcome.elapsed if outcome.elapsed > 0 else float("inf"),
        "base_attitude_change_deg": float(rotation_angle_deg(traj.base_pose[0, 3:], traj.base_pose[-1, 3:])),
        "base_displacement_m": float(np.linalg.norm(traj.base_pose[-1, :3] - traj.base_pose[0, :3])),
        "max_deflection_deg": float(np.degrees(deflection.max())),
        "max_deflection_joint": traj.arm.robot.joint_names[int(deflection.argmax())],
        "momentum_drift_angular": float(h_drift[:3].max()),
        "momentum_drift_linear": float(h_drift[3:].max()),
        "energy_change_J": de,
        "motor_work_J": work,
        "dissipated_J": dissipated,
        "energy_balance_residual_J": de - (work - dissipated),
        "energy_flow_J": flow,
        "ee_travel_m": float(np.linalg.norm(traj.ee_pose[-1, :3] - traj.ee_pose[0, :3])),
    }
    if outcome.failure is not None:
        summary.update(failure_step=outcome.failure.step, failure_time_s=outcome.failure.time,
                       failure=failure_reason(outcome.failure))
    return summary


def print_summary(s: Dict[str, Any], dof: int) -> None:
    status = "" if s["completed"] else " FAILED"
    print(f"\norbitflex: free-floating slew of '{s['model']}' ({dof} flexible joints){status}")
    if not s["completed"]:
        print(f"  FAILED at           {s['failure']}")
        print(f"                      the numbers below describe the finite part before the failure "
              f"(t = 0 to {s['simulated_s']:.6g} s, {s['steps']} of {s['steps_requested']} steps)")
    print(f"  simulated           {s['simulated_s']:.6g} s in {s['steps']} RK4 steps, "
          f"{s['steps_per_second']:,.0f} steps/s")
    print(f"  base attitude       rotated by {s['base_attitude_change_deg']:.3f} deg "
          f"(origin moved {s['base_displacement_m'] * 1e3:.3g} mm)")
    largest = np.radians(s["max_deflection_deg"])
    factor, unit = angle_unit(largest)
    in_deg = "" if unit == "deg" else f" ({s['max_deflection_deg']:.3g} deg)"
    print(f"  joint deflection    max {largest * factor:.3g} {unit}{in_deg} at {s['max_deflection_joint']}")
    print(f"  EE travel           {s['ee_travel_m']:.3g} m")
    if not s["completed"]:
        cause = "growth of the diverging run"
    elif s["warnings"]:
        cause = "dt is past the RK4 stability limit (see the warning): not to be trusted"
    else:
        cause = "RK4 truncation and round-off"
    print(f"  momentum drift      {s['momentum_drift_angular']:.2e} N·m·s (angular), "
          f"{s['momentum_drift_linear']:.2e} N·s (linear): {cause}")
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
    return np.unique(np.r_[np.arange(0, k, stride), k - 1])


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
    traj = outcome.traj
    caption = f"model {job.name}, dt = {seconds(dt)}, {traj.t[-1]:.6g} s free-floating slew"
    if outcome.failure is not None:
        caption += f", diverged at t = {outcome.failure.time:.6g} s (finite part shown)"
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
    ax.legend(fontsize=8, loc="best")
    figures.save(fig, "base_attitude.png")


def plot_ee_path(figures: Figures, job: Job, traj: Trajectory, rows: Rows) -> None:
    """Left: the EE path with the arm and the bus at the start and the end, to scale. Right: the
    path alone, relative to its start and zoomed."""
    path = traj.ee_pose[rows, :3]
    fig = figures.plt.figure(figsize=(12, 6.5), layout="constrained")
    fig.suptitle(f"End-effector path, inertial frame (equal axes)\n{figures.caption}", fontsize=11)
    scene = fig.add_subplot(1, 2, 1, projection="3d")
    points = [path]
    for k, colour, when in ((0, "tab:green", "start"), (-1, "tab:red", "end")):
        points += draw_arm(scene, job, traj, k, colour, when)
    scene.plot(*path.T, color="tab:blue", lw=2, label="EE path")
    equal_axes(scene, np.vstack(points))
    scene.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title="arm and bus at the start and the end")
    scene.legend(fontsize=8, loc="upper left")
    plot_ee_zoom(fig.add_subplot(1, 2, 2, projection="3d"), traj.t[rows], path)
    figures.save(fig, "ee_path.png")


def plot_ee_zoom(ax: Any, t: Array, path: Array) -> None:
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
    ax.set_title(f"EE displacement from its start at ({x0}) m\n"
                 f"{np.linalg.norm(shift[-1]):.3g} {unit} from start to end")
    ax.legend(fontsize=8, loc="upper left")


def draw_arm(ax: Any, job: Job, traj: Trajectory, k: int, colour: str, when: str) -> List[Array]:
    """Draws the arm (a line through its bodies, from the first joint to the EE) and the bus (a
    cube outline) at row ``k``; returns the points drawn."""
    pose = traj.base_pose[k]
    bodies = traj.arm.robot.body_poses(pose, traj.q[k])[1:, :3]
    ax.plot(*bodies.T, "o-", color=colour, lw=2, ms=3, label=f"arm at the {when} (t = {traj.t[k]:.3g} s)")
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
# the two commands
# ---------------------------------------------------------------------------------------------


def demo_job(args: argparse.Namespace) -> Job:
    robot = models.space_arm()
    arm = FlexibleArm(robot, models.space_arm_joints())
    return Job(arm, robot.name, SPACE_ARM_SLEW, BUS_SIDE, np.zeros(3))


def joint_list(values: Optional[List[str]]) -> List[str]:
    """``--locked-joints a,b --locked-joints c`` -> ``[a, b, c]``."""
    return [name.strip() for value in values or [] for name in value.split(",") if name.strip()]


def load_robot(args: argparse.Namespace) -> Robot:
    locked = joint_list(args.locked_joints)
    try:
        robot = Robot.from_urdf(args.urdf, ee_link=args.ee_link, locked_joints=locked or None)
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
    inertia = np.full(3, mass * BUS_SIDE**2 / 6) if args.base_inertia is None else np.asarray(args.base_inertia)
    try:
        robot = robot.with_base_inertia(mass, inertia, com)
    except ValueError as e:
        message = str(e)
        flag = "--base-com" if message.startswith("com") else "--base-inertia" if "inertia" in message else "--base-mass"
        raise CliError(flag, message) from None
    # the solid cube with this mass and (mean) inertia: I = m s² / 6
    return robot, max(float(np.sqrt(6 * max(float(inertia.mean()), 0.0) / mass)), 1e-3), com


def sketch_side(robot: Robot) -> float:
    """Edge (m) of the cube drawn for a base of unknown size: twice the distance to the first
    joint's body, at most 30 % of the arm's reach (at q = 0)."""
    bodies = robot.body_poses(np.r_[np.zeros(6), 1.0], np.zeros(robot.dof))[:, :3]
    reach = float(np.linalg.norm(bodies, axis=1).max())
    return max(min(2 * float(np.linalg.norm(bodies[1])), 0.3 * reach), 1e-3)


def simulate_job(args: argparse.Namespace) -> Job:
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
    slew = np.full(robot.dof, 0.3) if args.slew is None else np.asarray(args.slew, dtype=float)
    if len(slew) == 1:
        slew = np.full(robot.dof, slew[0])
    if len(slew) != robot.dof:
        raise CliError("--slew", f"expected 1 or {robot.dof} values (one per joint: "
                                 f"{', '.join(robot.joint_names)}), given {len(slew)}")
    return Job(arm, robot.name, slew, side, com, note)


# ---------------------------------------------------------------------------------------------
# the parser
# ---------------------------------------------------------------------------------------------


def common_options(p: argparse.ArgumentParser, duration: float) -> None:
    p.add_argument("--duration", metavar="S", type=positive, default=duration,
                   help="simulated time, s (default %(default)s)")
    p.add_argument("--dt", metavar="S", type=positive, default=1e-3, help="RK4 step, s (default %(default)s)")
    p.add_argument("--slew-time", metavar="S", type=positive, default=5.0,
                   help="duration of the quintic slew, s (default %(default)s)")
    p.add_argument("--bandwidth", metavar="HZ", type=positive, default=0.25,
                   help="PD bandwidth per joint, Hz (default %(default)s)")
    p.add_argument("--out", metavar="DIR", default="orbitflex_out",
                   help="output folder, created if missing (default %(default)s)")
    p.add_argument("--csv", action="store_true", help="also write trajectory.csv (t and x, named columns)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def simulate_options(sim: argparse.ArgumentParser) -> None:
    sim.add_argument("urdf", metavar="URDF", help="path to the URDF; the root link is the floating base")
    sim.add_argument("--params", metavar="TOML", default=None,
                     help="joint parameters keyed by joint name (keys below; default: scaled to the links)")
    sim.add_argument("--ee-link", metavar="LINK", default=None, help="EE link (default: the unique leaf)")
    sim.add_argument("--locked-joints", metavar="NAMES", action="append", default=None,
                     help="joints held at zero (e.g. fingers): a comma-separated list; repeatable")
    sim.add_argument("--slew", metavar="RAD", type=finite, nargs="+", default=None,
                     help="slew per joint, rad: one value for every joint, or one per joint (default 0.3)")
    sim.add_argument("--base-mass", metavar="KG", type=positive, default=None,
                     help="mount the arm on a bus of this mass, replacing the root link's inertia")
    sim.add_argument("--base-inertia", metavar=("IXX", "IYY", "IZZ"), type=finite, nargs=3, default=None,
                     help=f"the bus's principal moments about its COM, kg·m² (default: a solid "
                          f"{BUS_SIDE:g} m cube of --base-mass)")
    sim.add_argument("--base-com", metavar=("X", "Y", "Z"), type=finite, nargs=3, default=None,
                     help="the bus's COM in the root link's frame, m (default 0 0 0, the root link's "
                          "origin; 0 0 -0.75 puts a 1.5 m bus under an arm that points up z)")


def build_parser() -> Parser:
    parser = Parser(prog="orbitflex", description="Flexible-joint space manipulator simulation: a "
                    "free-floating slew of an arm on a spacecraft bus.")
    parser.add_argument("--version", action="version", version=f"orbitflex {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="{demo,simulate}")
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
    return parser


def reject_extra(args: argparse.Namespace, extra: List[str]) -> NoReturn:
    """Arguments argparse did not place: most likely a list given to --locked-joints with spaces."""
    if getattr(args, "locked_joints", None):
        fail(f"--locked-joints: takes one name or a comma-separated list per occurrence "
             f"(--locked-joints a,b); unexpected: {' '.join(extra)}")
    fail(f"unrecognized arguments: {' '.join(extra)} (see 'orbitflex --help')")


def main(argv: Optional[List[str]] = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:
        reject_extra(args, extra)
    if args.command is None:
        parser.print_help()
        return 0
    try:
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
