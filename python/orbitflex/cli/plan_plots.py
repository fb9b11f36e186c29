# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""The plots of a plan and of its comparison with the rigid-joint plan."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, TYPE_CHECKING, Tuple

import numpy as np

from .. import Plan, rotation_angle
from .plots import Figures, euler_zyx, joint_legend, plot_rows, seconds
from .summary import angle_unit, gain_range, rotation_angle_deg, torque_share

if TYPE_CHECKING:
    from .plan import Comparison
    from .slew import Array


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
    each (:func:`orbitflex.rotation_angle`, accurate for small angles too)."""
    angle: Array = rotation_angle(a, b)
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
