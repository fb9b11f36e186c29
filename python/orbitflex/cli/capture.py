# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""``orbitflex capture``: the built-in capture scenario (:func:`orbitflex.models.capture_scenario`)
run, printed as a summary and written to ``capture_summary.json``, ``capture.npz`` (the rows, the
target's rows and the event) and the plots ``capture_bus_rates.png`` (the bus's angular rates,
the kick at the event), ``capture_spring_torques.png`` (every joint's spring torque around the
event) and ``capture_target_rates.png`` (the target's rates, free then joined), and, with
``--animation``, ``capture.html`` (the 3-D view with the target's box). With ``--wheels`` the bus
carries reaction wheels under ``AttitudePD`` that detumble the stack after the capture, and
``capture_wheels.png`` shows their momentum, speeds and torques against their limits.

A self-contained command: :func:`add_parser` adds it to the CLI's subparsers and :func:`command`
runs it. The physics is :mod:`orbitflex.capture` in Rust, the metrics
:func:`orbitflex.detumble_metrics`; this module only formats and draws.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any, Dict, List

import numpy as np

from .. import Trajectory, detumble_metrics, models
from ..wheels_file import WheelsFile, WheelsFileError, read_wheels
from .plots import Figures, plot_rows, seconds

DESCRIPTION = """\
Runs the built-in capture scenario: the space arm (a 500 kg bus, 7 flexible joints) holds a
pre-grasp posture under its motor PD while a 200 kg target spinning at --tumble deg/s about
its major axis drifts onto the end-effector at --drift m/s. The grasp is an instantaneous,
perfectly inelastic impulse when the EE is within 1 cm, 5 cm/s and 5 deg of the handle; the
run goes on with the combined arm. Prints the event and the detumbling metrics and writes
capture_summary.json, capture.npz and three plots. With --wheels the bus's reaction wheels,
driven by AttitudePD, take the stack's momentum and bring it to rest (a fourth plot)."""

EPILOG = """\
examples:
  orbitflex capture                              # 2 deg/s, 2 cm/s, 40 s
  orbitflex capture --tumble 4 --duration 60 --out capture_out --animation
  orbitflex capture --wheels pyramid             # detumbled by the built-in pyramid of wheels
  orbitflex capture --wheels examples/wheels.toml --duration 100
"""

OUTPUTS = ("capture_summary.json", "capture.npz", "capture_bus_rates.png",
           "capture_spring_torques.png", "capture_target_rates.png")


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Adds ``capture`` to the CLI's subparsers."""
    from .errors import positive

    p: argparse.ArgumentParser = subparsers.add_parser(
        "capture", help="capture of a tumbling target by the built-in space arm",
        description=DESCRIPTION, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tumble", metavar="DEG_S", type=positive, default=2.0,
                   help="the target's spin rate about its major axis (default %(default)s deg/s)")
    p.add_argument("--drift", metavar="M_S", type=positive, default=0.02,
                   help="the target's approach speed (default %(default)s m/s)")
    p.add_argument("--meet", metavar="S", type=positive, default=5.0,
                   help="when the handle would reach the EE (default %(default)s s)")
    p.add_argument("--duration", metavar="S", type=positive, default=None,
                   help="simulated time (default 40 s, 150 s with --wheels)")
    p.add_argument("--wheels", metavar="FILE", default=None,
                   help="reaction wheels in the bus and their AttitudePD gains, from a wheels TOML file "
                        "(as simulate --wheels; see examples/wheels.toml), or 'pyramid' for "
                        "orbitflex.models.pyramid_wheels() with gains derived from the stack's inertia")
    p.add_argument("--record-every", metavar="K", type=int, default=5,
                   help="keep every K-th row (default %(default)s)")
    p.add_argument("--bus-rate", metavar="DEG_S", type=positive, default=0.05,
                   help="the bus rate below which the stack counts as detumbled (default %(default)s deg/s)")
    p.add_argument("--out", metavar="DIR", default="capture_out",
                   help="output folder, created if missing (default %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="skip the plots")
    p.add_argument("--animation", action="store_true",
                   help="also write capture.html, the 3-D view (needs orbitflex[viz])")
    return p


def command(args: argparse.Namespace) -> int:
    from .errors import CliError, output_folder

    if args.record_every < 1:
        raise CliError("--record-every", f"expected an integer >= 1, given {args.record_every}")
    out = output_folder(args.out)
    spec = wheels_of(args)
    if args.duration is None:
        args.duration = 40.0 if spec is None else 150.0
    if spec is None:
        scenario = models.capture_scenario(args.tumble, args.drift, args.meet)
    else:
        try:
            scenario = models.capture_scenario(args.tumble, args.drift, args.meet, wheels=spec.wheels,
                                               attitude_pd=spec.controller() if spec.kp.size else None)
        except ValueError as e:
            raise CliError("--wheels", str(e)) from None
    traj = scenario.run(args.duration, record_every=args.record_every)
    metrics = detumble_metrics(traj, bus_rate=args.bus_rate)
    summary = summarise(scenario, traj, metrics, args)
    print_summary(summary)
    (out / "capture_summary.json").write_text(json.dumps(summary, indent=2, allow_nan=True) + "\n")
    save_npz(traj, out / "capture.npz")
    files = [out / "capture_summary.json", out / "capture.npz"]
    if not args.no_plots:
        files += plot(scenario, traj, out, args.record_every, args.bus_rate)
    if args.animation:
        path = out / "capture.html"
        traj.animate(str(path), title=f"capture of a target spinning at {args.tumble:g} deg/s")
        files.append(path)
    print("wrote " + ", ".join(str(f) for f in files))
    return 0


def summarise(scenario: models.CaptureScenario, traj: Trajectory, metrics: Dict[str, Any],
              args: argparse.Namespace) -> Dict[str, Any]:
    t = scenario.target
    summary: Dict[str, Any] = {
        "model": "space_arm (500 kg bus, 7 flexible joints)",
        "dt_s": scenario.dt,
        "duration_s": float(traj.t[-1]),
        "target": {"name": t.name, "mass_kg": t.mass, "principal_inertia_kg_m2": np.diag(t.inertia).tolist(),
                   "tumble_deg_s": args.tumble, "drift_m_s": args.drift},
        "trigger": {"distance_m": scenario.when.distance, "speed_m_s": scenario.when.speed,
                    "angle_deg": math.degrees(scenario.when.angle)},
        "captured": metrics["captured"],
    }
    if traj.events:
        e = traj.events[0]
        summary["event"] = {
            "step": e.step, "time_s": e.time, "distance_m": e.distance, "speed_m_s": e.speed,
            "angle_deg": math.degrees(e.angle), "impulse_moment_N_m_s": e.impulse[:3].tolist(),
            "impulse_force_N_s": e.impulse[3:].tolist(), "energy_loss_J": e.energy_loss,
            "momentum_change": float(np.abs(e.momentum_after - e.momentum_before).max()),
        }
    if scenario.wheel_controller is not None and scenario.arm.wheels is not None:
        pd = scenario.wheel_controller
        summary["wheels"] = {"source": args.wheels_source, "count": len(scenario.arm.wheels.mass),
                             "attitude_pd": {"kp": pd.kp.tolist(), "kd": pd.kd.tolist()},
                             "motor_pd": "tuned for the arm holding the target"}
    summary["metrics"] = metrics
    return summary


def wheels_of(args: argparse.Namespace) -> "WheelsFile | None":
    """The wheels of ``--wheels``: ``pyramid`` (gains left empty: the scenario derives them),
    a wheels file, or None."""
    from .errors import CliError

    args.wheels_source = args.wheels
    if args.wheels is None:
        return None
    if args.wheels == "pyramid":
        args.wheels_source = "orbitflex.models.pyramid_wheels(), detumble gains from the stack's inertia"
        return WheelsFile(models.pyramid_wheels(), np.zeros(0), np.zeros(0), args.wheels_source)
    try:
        return read_wheels(args.wheels)
    except WheelsFileError as e:
        raise CliError("--wheels", str(e)) from None


def print_summary(s: Dict[str, Any]) -> None:
    target = s["target"]
    print(f"capture: {target['mass_kg']:g} kg target spinning at {target['tumble_deg_s']:g} deg/s, "
          f"drifting in at {target['drift_m_s']:g} m/s; model {s['model']}, dt = {seconds(s['dt_s'])}")
    if not s["captured"]:
        print(f"  no capture in {s['duration_s']:g} s: the EE never came within the trigger's tolerances")
        return
    e, m = s["event"], s["metrics"]
    print(f"  captured at t = {e['time_s']:.3f} s (step {e['step']}): {e['distance_m'] * 100:.2f} cm, "
          f"{e['speed_m_s'] * 100:.2f} cm/s, {e['angle_deg']:.2f} deg from the handle")
    print(f"  impulse |F| = {m['impulse_force']:.4g} N·s, |M| = {m['impulse_moment']:.4g} N·m·s; "
          f"energy lost {e['energy_loss_J']:.4g} J; momentum kept to {e['momentum_change']:.1e}")
    print(f"  bus kick {m['bus_kick_deg_s']:.4g} deg/s; peak bus rate after {m['peak_bus_rate_deg_s']:.4g} "
          f"deg/s, at the end {m['final_bus_rate_deg_s']:.4g} deg/s")
    print(f"  after the capture: peak spring torque {m['peak_spring_torque']:.4g} N·m, peak deflection "
          f"{math.degrees(m['peak_deflection']):.4g} deg")
    settle, detumble = m["settle_time"], m["detumble_time"]
    print("  joints settled (rates < 1 mrad/s) " + (f"{settle:.3g} s after the capture" if math.isfinite(settle)
                                                    else "not by the end of the run"))
    w = s.get("wheels")
    if w is not None:
        pd = w["attitude_pd"]
        print(f"  {w['count']} reaction wheels ({w['source']}), AttitudePD kp = {pd['kp'][0]:.4g} N·m/rad, "
              f"kd = {pd['kd'][0]:.4g} N·m·s/rad")
        print(f"  the wheels hold |h| = {m['wheel_momentum_nms']:.4g} N·m·s at the end (peak "
              f"{m['peak_wheel_momentum_nms']:.4g}); peak speed {m['peak_wheel_speed_fraction']:.1%} and torque "
              f"{m['peak_wheel_torque_fraction']:.1%} of their limits"
              + ("; SATURATED: the wheels did not deliver what AttitudePD asked" if m["wheels_saturated"] else ""))
    if math.isfinite(detumble):
        print(f"  stack detumbled (bus and target below {m['bus_rate_threshold_deg_s']:g} deg/s) "
              f"{detumble:.3g} s after the capture")
    elif w is None:
        print(f"  bus rate still above {m['bus_rate_threshold_deg_s']:g} deg/s at the end: the arm's motors "
              "cannot remove the stack's momentum; nulling it needs an attitude actuator (--wheels)")
    else:
        print(f"  the stack still turns faster than {m['bus_rate_threshold_deg_s']:g} deg/s at the end "
              "(a longer --duration, or faster gains)")


def save_npz(traj: Trajectory, path: Path) -> None:
    arrays: Dict[str, Any] = {"t": traj.t, "x": traj.x, "u": traj.u, "target": traj.target,
                              "spring_torque": traj.spring_torque, "momentum": traj.momentum}
    if traj.arm.wheels is not None:
        arrays.update(wheel_speed=traj.wheel_speed, wheel_torque=traj.wheel_torque)
    if traj.events:
        e = traj.events[0]
        arrays.update(event_time=e.time, event_step=e.step, impulse=e.impulse, energy_loss=e.energy_loss,
                      x_before=e.x_before, x_after=e.x_after)
    np.savez(path, **arrays)


def plot(scenario: models.CaptureScenario, traj: Trajectory, out: Path, record_every: int,
         bus_rate: float) -> List[Path]:
    wheels = "" if scenario.arm.wheels is None else f" + {len(scenario.arm.wheels.mass)} reaction wheels (AttitudePD)"
    caption = (f"model space_arm{wheels} + {scenario.target.mass:g} kg target, dt = {seconds(scenario.dt)}, "
               f"a row every {seconds(record_every * scenario.dt)}")
    figures = Figures(out, caption)
    rows = plot_rows(len(traj.t))
    t = traj.t
    event = traj.events[0].time if traj.events else None

    def mark(ax: Any) -> None:
        if event is not None:
            ax.axvline(event, color="crimson", lw=1, ls="--", label=f"capture, t = {event:.3f} s")

    # bus rates, base frame
    fig, ax = figures.new("Bus angular rates ω_B (base frame): the kick of the grasp, then the stack")
    w = np.degrees(np.asarray(traj.base_twist)[:, :3])
    for i, axis in enumerate("xyz"):
        ax.plot(t[rows], w[rows, i], lw=1, label=f"$\\omega_{axis}$")
    ax.plot(t[rows], np.linalg.norm(w, axis=1)[rows], color="black", lw=1.2, label="$|\\omega_B|$")
    ax.axhline(bus_rate, color="gray", lw=1, ls=":", label=f"detumbled below {bus_rate:g} deg/s")
    mark(ax)
    ax.set(xlabel="time (s)", ylabel="rate (deg/s)")
    ax.legend(fontsize=9, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    figures.save(fig, "capture_bus_rates.png")

    # spring torques around the event: 1 s before to 4 s after
    fig, ax = figures.new("Joint spring torques k(θ − q) + d(θ̇ − q̇) around the capture")
    lo, hi = (event - 1.0, event + 4.0) if event is not None else (t[0], t[-1])
    window = np.flatnonzero((t >= lo) & (t <= hi))
    torque = np.asarray(traj.spring_torque)
    names = traj.arm.robot.joint_names
    for i, name in enumerate(names):
        ax.plot(t[window], torque[window, i], lw=1, label=name)
    mark(ax)
    ax.axhline(0, color="black", lw=0.5)
    ax.set(xlabel="time (s)", ylabel="spring torque (N·m)")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), title="joint")
    figures.save(fig, "capture_spring_torques.png")

    # the target's rates, body frame
    fig, ax = figures.new("Target angular rates ω_t (target body frame): free spin, then joined to the arm")
    wt = np.degrees(np.asarray(traj.target)[:, 7:10])
    for i, axis in enumerate("xyz"):
        ax.plot(t[rows], wt[rows, i], lw=1, label=f"$\\omega_{axis}$")
    ax.plot(t[rows], np.linalg.norm(wt, axis=1)[rows], color="black", lw=1.2, label="$|\\omega_t|$")
    mark(ax)
    ax.set(xlabel="time (s)", ylabel="rate (deg/s)")
    ax.legend(fontsize=9, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    figures.save(fig, "capture_target_rates.png")
    if traj.arm.wheels is not None:
        plot_wheels(traj, figures, rows, mark)
    return figures.files


def plot_wheels(traj: Trajectory, figures: Figures, rows: Any, mark: Any) -> None:
    """``capture_wheels.png``: the wheels' spin momentum, speeds and applied torques, against
    their limits (dashed), the capture marked."""
    from ..detumble import wheel_momentum
    from .wheels import limit_lines

    w = traj.arm.wheels
    assert w is not None
    t = traj.t
    fig, (top, middle, bottom) = figures.new("Reaction wheels detumbling the stack", rows=3, height=9.0,
                                             sharex=True)
    h = wheel_momentum(traj.arm, np.asarray(traj.x))
    for i, axis in enumerate("xyz"):
        top.plot(t[rows], h[rows, i], lw=1, label=f"$h_{axis}$")
    top.plot(t[rows], np.linalg.norm(h, axis=1)[rows], color="black", lw=1.2, label="$|h|$")
    mark(top)
    top.set(ylabel="spin momentum h (N·m·s)", title="momentum the wheels hold, base frame: the stack's, handed over")
    top.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    max_speed, max_torque = np.asarray(w.max_speed), np.asarray(w.max_torque)
    colors = [f"C{i}" for i in range(len(max_speed))]
    for i, c in enumerate(colors):
        middle.plot(t[rows], traj.wheel_speed[rows, i], color=c, lw=1.1, label=f"wheel {i}")
    limit_lines(middle, max_speed, colors, "±max_speed")
    mark(middle)
    middle.set(ylabel="wheel speed Ω (rad/s)", yscale="symlog", title="wheel speeds relative to the bus "
               "(log beyond 1 rad/s); dashed: ±max_speed")
    middle.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    u_rows = rows[rows < len(traj.wheel_torque)]
    for i, c in enumerate(colors):
        bottom.plot(t[u_rows], traj.wheel_torque[u_rows, i], color=c, lw=1.0, label=f"wheel {i}")
    limit_lines(bottom, max_torque, colors, "±max_torque")
    mark(bottom)
    finite = max_torque[np.isfinite(max_torque)]
    bottom.set_yscale("symlog", linthresh=float(finite.max()) / 1000 if finite.size else 1.0)
    bottom.set(xlabel="time (s)", ylabel="applied torque u_w (N·m)",
               title="applied wheel torques after saturation (log beyond 0.1 % of the limit); "
                     "dashed: ±max_torque")
    bottom.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    figures.save(fig, "capture_wheels.png")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(command(add_parser(argparse.ArgumentParser().add_subparsers()).parse_args()))
