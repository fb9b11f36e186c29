"""``orbitflex modes [URDF]``: the structural modes of an arm about a configuration, printed as a
table and written to ``modes.json``, ``modes.png`` (the shapes drawn on the arm),
``bode.png`` (frequency response, resonances marked), ``campbell.png`` (with ``--sweep``: the
frequencies against a joint's angle) and ``state_space.mat`` (the linear model, with scipy).

A self-contained command: :func:`add_parser` adds it to the CLI's subparsers and :func:`command`
runs it. The physics is :mod:`orbitflex.analysis`; this module only formats and draws.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple

import numpy as np
import numpy.typing as npt

from .. import AttitudePD, FlexibleArm, FlexibleJoints, MotorPD, analysis, models

Array = npt.NDArray[np.float64]

DESCRIPTION = """\
Prints the structural modes of your URDF (default: the built-in space arm) about a
configuration, and writes modes.json, modes.png (the shapes drawn on the arm), bode.png
(magnitude and phase of the frequency response, resonances marked), campbell.png (with
--sweep: the frequencies against a joint's angle) and state_space.mat (A, B, C, D with
names, for MATLAB; needs scipy: pip install 'orbitflex[analysis]')."""

EPILOG = """\
examples:
  orbitflex modes                                   # the built-in arm, free floating, at q = 0
  orbitflex modes --motors clamped --q 0 0.3 0 1.2 0 0 0
  orbitflex modes --sweep elbow_pitch 0 2.5 40      # Campbell diagram over the elbow angle
  orbitflex modes arm.urdf --params joints.toml --base held --kp 200 --kd 20
  orbitflex modes --wheels wheels.toml --kp 800 --kd 300   # bus held by its wheels' AttitudePD
  orbitflex modes --wheels wheels.toml --attitude-kp 0 --attitude-kd 0   # wheels, open loop
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Adds ``modes`` to the CLI's subparsers."""
    from .robots import add_robot_arguments
    from .errors import finite, non_negative, positive

    p: argparse.ArgumentParser = subparsers.add_parser(
        "modes", help="structural modes, frequency response and Campbell diagram of an arm",
        description=DESCRIPTION, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_robot_arguments(p)
    p.add_argument("--base-mass", metavar="KG", type=positive, default=None,
                   help="mount the arm on a bus of this mass (as for 'orbitflex simulate')")
    p.add_argument("--base-inertia", metavar=("IXX", "IYY", "IZZ"), type=finite, nargs=3, default=None,
                   help="the bus's principal moments about its COM, kg·m²")
    p.add_argument("--base-com", metavar=("X", "Y", "Z"), type=finite, nargs=3, default=None,
                   help="the bus's COM in the root link's frame, m")
    p.add_argument("--q", metavar="RAD", type=finite, nargs="+", default=None,
                   help="the configuration: one angle for every joint, or one per joint (default 0)")
    p.add_argument("--base", choices=("free", "held"), default="free",
                   help="free floating, or held inertially still (default %(default)s)")
    p.add_argument("--motors", choices=("free", "clamped"), default="free",
                   help="free, or clamped: brakes on, motor angles held (default %(default)s)")
    p.add_argument("--kp", metavar="NM_PER_RAD", type=non_negative, nargs="+", default=None,
                   help="close the loop with a motor PD of this stiffness (one value, or one per joint)")
    p.add_argument("--kd", metavar="NMS_PER_RAD", type=non_negative, nargs="+", default=None,
                   help="the motor PD's damping (default 0; needs --kp)")
    p.add_argument("--wheels", metavar="TOML", default=None,
                   help="reaction wheels on the bus (keys: examples/wheels.toml); its [attitude_pd] "
                        "closes the bus's attitude loop through them")
    p.add_argument("--attitude-kp", metavar="NM_PER_RAD", type=non_negative, nargs="+", default=None,
                   help="the AttitudePD's stiffness instead of the file's (one value, or x y z; 0: open loop)")
    p.add_argument("--attitude-kd", metavar="NMS_PER_RAD", type=non_negative, nargs="+", default=None,
                   help="the AttitudePD's damping instead of the file's (one value, or x y z)")
    p.add_argument("--undamped", action="store_true",
                   help="undamped modes (K φ = ω² M φ) instead of the state matrix's damped ones")
    p.add_argument("--sweep", metavar=("JOINT", "FROM", "TO", "N"), nargs=4, default=None,
                   help="sweep JOINT's angle from FROM to TO rad in N steps: campbell.png")
    p.add_argument("--inputs", default=None,
                   help="inputs of bode.png and the .mat: motor_torque, base_wrench, ee_wrench, "
                        "theta_ref, wheel_torque (default motor_torque, or ee_wrench with --motors "
                        "clamped; comma-separated for several)")
    p.add_argument("--outputs", default="q",
                   help="outputs: q, theta, deflection, spring_torque, ee_position, base_attitude, "
                        "base_position, base_rate, wheel_speed (default %(default)s; comma-separated "
                        "for several)")
    p.add_argument("--freqs", metavar=("FROM", "TO", "N"), type=positive, nargs=3, default=None,
                   help="bode.png's frequencies, Hz, log-spaced (default: a decade around the modes)")
    p.add_argument("--count", metavar="K", type=int, default=6, help="modes drawn in modes.png (default %(default)s)")
    p.add_argument("--out", metavar="DIR", default="orbitflex_modes",
                   help="output folder, created if missing (default %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    return p


def load(args: argparse.Namespace) -> Tuple[FlexibleArm, Optional[str]]:
    """The arm: the URDF's with --params (or scaled defaults), or the built-in space arm."""
    from .errors import CliError, cli_words
    from .robots import load_arm

    if args.urdf is not None:
        arm, _, _, note = load_arm(args)
        return arm, note
    robot = models.space_arm()
    if args.params is None:
        return FlexibleArm(robot, models.space_arm_joints()), None
    try:
        return FlexibleArm(robot, FlexibleJoints.from_toml(args.params, robot)), None
    except (ValueError, OSError) as e:
        raise CliError("--params", cli_words(str(e))) from None


def controller(arm: FlexibleArm, args: argparse.Namespace) -> Optional[MotorPD]:
    from .errors import CliError
    from .slew import per_joint

    if args.kp is None:
        if args.kd is not None:
            raise CliError("--kd", "is the motor PD's damping; give its stiffness with --kp too")
        return None
    kp = per_joint(args.kp, "--kp", arm.robot)
    kd = per_joint(args.kd, "--kd", arm.robot, default=0.0)
    return MotorPD(kp=kp, kd=kd, theta_ref=np.zeros(arm.dof))


def with_wheels(arm: FlexibleArm, pd: Optional[MotorPD], args: argparse.Namespace) -> Tuple[FlexibleArm, Any]:
    """The arm with ``--wheels``' wheels and the controllers closing the loops: the motor PD, the
    file's ``AttitudePD`` (gains from ``--attitude-kp/--attitude-kd`` when given), or both."""
    from .errors import CliError
    from ..wheels_file import WheelsFileError, read_wheels

    if args.wheels is None:
        for flag in ("attitude_kp", "attitude_kd"):
            if getattr(args, flag) is not None:
                raise CliError("--" + flag.replace("_", "-"), "tunes the wheels' AttitudePD; give --wheels too")
        return arm, pd
    try:
        spec = read_wheels(args.wheels)
    except WheelsFileError as e:
        raise CliError("--wheels", str(e)) from None

    def three(values: Optional[List[float]], default: Any, flag: str) -> Any:
        if values is None:
            return default
        if len(values) not in (1, 3):
            raise CliError(flag, f"expected one value or three (x y z), given {len(values)}")
        return np.resize(np.asarray(values, dtype=float), 3)

    kp = three(args.attitude_kp, spec.kp, "--attitude-kp")
    kd = three(args.attitude_kd, spec.kd, "--attitude-kd")
    try:
        wheeled = FlexibleArm(arm.robot, arm.joints, wheels=spec.wheels)
        attitude = AttitudePD(kp, kd)
    except ValueError as e:
        raise CliError("--wheels", str(e)) from None
    return wheeled, attitude if pd is None else (pd, attitude)


def has_attitude(u: Any) -> bool:
    """Whether an AttitudePD with some gain closes the bus's loop."""
    items = u if isinstance(u, tuple) else (u,)
    return any(isinstance(c, AttitudePD) and (np.any(c.kp) or np.any(c.kd)) for c in items)


def command(args: argparse.Namespace) -> int:
    """Runs ``orbitflex modes``; returns the exit code."""
    from .errors import CliError, output_folder
    from .slew import per_joint

    arm, note = load(args)
    robot = arm.robot
    q = per_joint(args.q, "--q", robot, default=0.0)
    arm, pd = with_wheels(arm, controller(arm, args), args)
    if args.inputs is None:
        args.inputs = "ee_wrench" if args.motors == "clamped" else "motor_torque"
    inputs = [s.strip() for s in args.inputs.split(",") if s.strip()]
    outputs = [s.strip() for s in args.outputs.split(",") if s.strip()]
    x = arm.state(q=q)
    try:
        modes = arm.modes(x, u=pd, base=args.base, motors=args.motors, damping=not args.undamped)
        ss = arm.state_space(x, u=pd, inputs=inputs, outputs=outputs, base=args.base, motors=args.motors)
    except ValueError as e:
        flag = "--inputs" if str(e).startswith("inputs") else "--outputs" if str(e).startswith("outputs") else \
            "--motors" if "clamped" in str(e) else "--wheels" if "wheel" in str(e) or "AttitudePD" in str(e) \
            else "--base"
        raise CliError(flag, str(e)) from None
    sweep = None
    if args.sweep is not None:
        sweep, angles, joint = run_sweep(arm, q, pd, args)
    out = output_folder(args.out)
    if note:
        print(note)
    print(f"{robot.name}: {modes.table()}")
    files = [write_json(out / "modes.json", arm, q, modes, args, sweep)]
    mat = write_mat(out / "state_space.mat", ss)
    if mat is not None:
        files.append(mat)
    if not args.no_plots:
        loops = [name for name, on in (("motor PD", isinstance(pd, (MotorPD, tuple))),
                                       ("AttitudePD on the wheels", has_attitude(pd))) if on]
        caption = f"{robot.name}; base {args.base}, motors {args.motors}" + "".join(", " + n for n in loops)
        files.append(plot_shapes(out / "modes.png", arm, x, modes, args.count, caption))
        files.append(plot_bode(out / "bode.png", arm, x, modes, ss, pd, args, caption))
        if sweep is not None:
            files.append(plot_campbell(out / "campbell.png", sweep, angles, joint, caption))
    print("wrote:")
    for f in files:
        print(f"  {f}")
    return 0


def run_sweep(arm: FlexibleArm, q: Array, pd: Any,
              args: argparse.Namespace) -> Tuple[analysis.Sweep, Array, str]:
    from .errors import CliError

    joint, low, high, count = args.sweep
    names = arm.robot.joint_names
    if joint not in names:
        raise CliError("--sweep", f"unknown joint {joint!r}; the arm has: {', '.join(names)}")
    try:
        low_rad, high_rad, steps = float(low), float(high), int(count)
    except ValueError:
        raise CliError("--sweep", f"expected JOINT FROM TO N (rad, rad, an integer), given {' '.join(args.sweep)}") from None
    if not (math.isfinite(low_rad) and math.isfinite(high_rad)) or steps < 2:
        raise CliError("--sweep", f"expected finite angles and N >= 2, given {' '.join(args.sweep)}")
    angles = np.linspace(low_rad, high_rad, steps)
    configurations = np.tile(q, (steps, 1))
    configurations[:, names.index(joint)] = angles
    sweep = analysis.sweep(arm, configurations, u=pd, base=args.base, motors=args.motors,
                           damping=not args.undamped)
    return sweep, angles, joint


def write_json(path: Path, arm: FlexibleArm, q: Array, modes: analysis.Modes, args: argparse.Namespace,
               sweep: Optional[analysis.Sweep]) -> Path:
    doc: Dict[str, Any] = {
        "model": arm.robot.name, "joint_names": arm.robot.joint_names, "q_rad": q.tolist(),
        "base": args.base, "motors": args.motors, "closed_loop": modes.closed_loop, "damped": modes.damped,
        "rigid_body_modes": modes.rigid_body, "wheel_spin_modes": modes.wheel_spin,
        "modes": [{"frequency_hz": float(f), "natural_frequency_hz": float(fn), "damping_ratio": float(z),
                   "dominant_joint": j, "spring_energy_share": [float(v) for v in e]}
                  for f, fn, z, j, e in zip(modes.frequency_hz, modes.natural_frequency_hz, modes.damping_ratio,
                                            modes.dominant_joints, modes.spring_energy)],
        "overdamped_eigenvalues_per_s": [float(v) for v in modes.overdamped],
    }
    if sweep is not None:
        column = arm.robot.joint_names.index(args.sweep[0])
        doc["sweep"] = {"joint": args.sweep[0], "angle_rad": sweep.configurations[:, column].tolist(),
                        "frequency_hz": [[None if math.isnan(v) else float(v) for v in row]
                                         for row in sweep.frequency_hz]}
    path.write_text(json.dumps(doc, indent=2))
    return path


def write_mat(path: Path, ss: analysis.StateSpace) -> Optional[Path]:
    try:
        return ss.savemat(path)
    except ImportError as e:
        print(f"{path.name} not written: {e}")
        return None


def figure(rows: int, cols: int, title: str, caption: str, **kw: Any) -> Tuple[Any, Any]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(rows, cols, figsize=(10, 3.3 * rows + 1.0), layout="constrained", squeeze=False, **kw)
    fig.suptitle(f"{title}\n{caption}", fontsize=11)
    return fig, axes


def save(fig: Any, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def skeleton(arm: FlexibleArm, x: Array) -> List[Array]:
    """Line segments (2, 3) from each body to its parent and from the last bodies to their
    end-effectors, inertial frame (m)."""
    s = arm.state_slices
    bodies = arm.robot.body_poses(x[s["base_pose"]], x[s["q"]])[:, :3]
    segments = [np.array([bodies[p + 1], bodies[i + 1]]) for i, p in enumerate(arm.robot.parents)]
    for e, body in enumerate(arm.robot.ee_bodies):
        segments.append(np.array([bodies[body], arm.ee_pose(x, ee=e)[:3]]))
    return segments


def plot_shapes(path: Path, arm: FlexibleArm, x: Array, modes: analysis.Modes, count: int, caption: str) -> Path:
    """Each mode's shape on the arm: the links displaced by the real part of the shape (scaled to
    a tenth of the arm's reach; the factor in the title), over the arm at rest (grey)."""
    shown = max(0, min(count, len(modes)))
    cols = min(3, max(shown, 1))
    rows = max(1, math.ceil(shown / cols))
    fig, axes = figure(rows, cols, "Mode shapes (link side)", caption, subplot_kw={"projection": "3d"})
    rest = skeleton(arm, x)
    points = np.concatenate(rest)
    reach = float(np.ptp(points, axis=0).max()) or 1.0
    for k, ax in enumerate(axes.flat):
        if k >= shown:
            ax.set_axis_off()
            continue
        shape = np.real(modes.shapes[:, k])
        probe = 1e-6 / max(float(np.abs(shape[: 6 + 2 * arm.dof]).max()), 1e-300)
        moved = np.concatenate(skeleton(arm, arm.integrate(x, probe * shape)))
        largest = float(np.linalg.norm(moved - points, axis=1).max()) / probe
        scale = 0.1 * reach / largest if largest > 0 else 0.0
        for seg in rest:
            ax.plot(*seg.T, color="0.7", lw=3)
        for seg in skeleton(arm, arm.integrate(x, scale * shape)):
            ax.plot(*seg.T, color="C3", lw=2, marker="o", ms=3)
        ax.set_title(f"mode {k + 1}: {modes.frequency_hz[k]:.3g} Hz, ζ {modes.damping_ratio[k]:.3f}\n"
                     f"{modes.dominant_joints[k]}; shape × {scale:.3g}", fontsize=9)
        ax.set_xlabel("x (m)", fontsize=8)
        ax.set_ylabel("y (m)", fontsize=8)
        ax.set_zlabel("z (m)", fontsize=8)
        ax.tick_params(labelsize=7)
        lo, hi = points.min(axis=0), points.max(axis=0)
        centre, half = (lo + hi) / 2, 0.6 * reach
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_zlim(centre[2] - half, centre[2] + half)
    return save(fig, path)


def channels(ss: analysis.StateSpace) -> List[Tuple[int, int]]:
    """The (output, input) pairs drawn: the diagonal when there are as many outputs as inputs
    (u_i to q_i: collocated), else every pair, at most 12."""
    if len(ss.inputs) == len(ss.outputs):
        return [(i, i) for i in range(len(ss.inputs))]
    return [(o, i) for o in range(len(ss.outputs)) for i in range(len(ss.inputs))][:12]


def plot_bode(path: Path, arm: FlexibleArm, x: Array, modes: analysis.Modes, ss: analysis.StateSpace,
              pd: Any, args: argparse.Namespace, caption: str) -> Path:
    """Magnitude and phase of ``H(j 2π f)`` for the channels of :func:`channels`, with the modes'
    damped natural frequencies marked."""
    if args.freqs is not None:
        low, high, count = args.freqs
        freqs = np.logspace(np.log10(low), np.log10(high), max(int(count), 2))
    else:
        f = modes.frequency_hz if len(modes) else np.array([1.0])
        freqs = np.logspace(np.log10(f.min() / 5), np.log10(f.max() * 5), 800)
    h = arm.frequency_response(x, freqs, inputs=[g.strip() for g in args.inputs.split(",")],
                               outputs=[g.strip() for g in args.outputs.split(",")], u=pd,
                               base=args.base, motors=args.motors)
    fig, axes = figure(2, 1, f"Frequency response ({args.inputs} to {args.outputs})", caption, sharex=True)
    mag_ax, phase_ax = axes[0, 0], axes[1, 0]
    for o, i in channels(ss):
        label = ss.outputs[o] if len(ss.inputs) == len(ss.outputs) else f"{ss.inputs[i]} → {ss.outputs[o]}"
        mag_ax.loglog(freqs, np.abs(h[:, o, i]), lw=1.2, label=label)
        phase_ax.semilogx(freqs, np.degrees(np.unwrap(np.angle(h[:, o, i]))), lw=1.2)
    for k, f in enumerate(modes.frequency_hz):
        if freqs[0] <= f <= freqs[-1]:
            for ax in (mag_ax, phase_ax):
                ax.axvline(f, color="0.5", ls=":", lw=0.8)
            mag_ax.annotate(f"{k + 1}", (f, 1.0), xycoords=("data", "axes fraction"), fontsize=7,
                            ha="center", va="bottom", color="0.3")
    mag_ax.set_ylabel(f"|H| ({units(ss)})")
    phase_ax.set_ylabel("phase (deg)")
    phase_ax.set_xlabel("frequency (Hz); dotted: the modes' damped natural frequencies, numbered")
    mag_ax.legend(fontsize=7, ncol=2, loc="lower left")
    mag_ax.grid(True, which="both", alpha=0.3)
    phase_ax.grid(True, which="both", alpha=0.3)
    return save(fig, path)


def units(ss: analysis.StateSpace) -> str:
    """The unit of the drawn channels: output unit per input unit."""
    out = {"q": "rad", "theta": "rad", "deflection": "rad", "spring_torque": "N·m", "ee": "m",
           "base_attitude": "rad", "base_position": "m", "base_rate": "rad/s", "wheel_speed": "rad/s"}
    inp = {"u": "N·m", "theta_ref": "rad", "base_moment": "N·m", "base_force": "N", "ee_moment": "N·m",
           "ee_force": "N", "wheel_torque": "N·m"}

    def unit(name: str, table: Dict[str, str]) -> str:
        head = name.split("[")[0]
        for key in sorted(table, key=len, reverse=True):
            if head.startswith(key):
                return table[key]
        return "?"

    outs = sorted({unit(n, out) for n in ss.outputs})
    ins = sorted({unit(n, inp) for n in ss.inputs})
    return f"{'|'.join(outs)} per {'|'.join(ins)}"


def plot_campbell(path: Path, sweep: analysis.Sweep, angles: Array, joint: str, caption: str) -> Path:
    """Each mode's frequency (by rank, ascending) against the swept joint's angle."""
    fig, axes = figure(1, 1, f"Campbell diagram over {joint}", caption)
    ax = axes[0, 0]
    for k in range(sweep.frequency_hz.shape[1]):
        ax.plot(np.degrees(angles), sweep.frequency_hz[:, k], marker=".", ms=3, lw=1.2, label=f"mode {k + 1}")
    ax.set_ylim(bottom=0)
    ax.set_xlabel(f"{joint} angle (deg)")
    ax.set_ylabel("damped natural frequency (Hz)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    return save(fig, path)
