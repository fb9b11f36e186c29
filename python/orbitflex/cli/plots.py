# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""The plots of a run (matplotlib): angles, deflection, attitude, EE path, momentum drift."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, List, Optional, Sequence, TYPE_CHECKING, Tuple

import numpy as np

from .. import euler_zyx as orbitflex_euler_zyx, rotation_matrix as orbitflex_rotation_matrix, Trajectory
from .summary import angle_unit, ee_paths, rotation_angle_deg

if TYPE_CHECKING:
    from .jobs import Job, Outcome
    from .slew import Array, Rows


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
    z-y'-x'' sequence, ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (:func:`orbitflex.euler_zyx`); yaw and
    roll unwrapped in time."""
    yaw, pitch, roll = orbitflex_euler_zyx(quat).T
    return np.unwrap(yaw), pitch, np.unwrap(roll)


def rotation_matrix(quat: Array) -> Array:
    """The rotation matrix of a unit quaternion (x, y, z, w) (:func:`orbitflex.rotation_matrix`)."""
    matrix: Array = orbitflex_rotation_matrix(quat)
    return matrix


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
