# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""The self-contained HTML animation of a run: the frames, the page and its viewer
(:func:`write_animation`, :func:`animation_html`)."""

from __future__ import annotations

import base64
import gzip
import hashlib
import json
import math
import re
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

import numpy as np

from .. import _core
from . import DEFAULT_FPS, _TRAIL, _Array, _axes, _checked_shape, _line, _matrix, _meshcat, _scene

# --------------------------------------------------------------------------------------------
# the animation


def ghost_scale(traj: "_core.Trajectory", visible: float = 0.15) -> float:
    """The factor drawing the largest deflection ``|θ − q|`` of a run as ``visible`` rad
    (about 9°), rounded down to 1, 2 or 5 × 10^k, and at least 1."""
    peak = float(np.max(np.abs(traj.deflection))) if traj.deflection.size else 0.0
    if not peak > 0 or not math.isfinite(peak):
        return 1.0
    raw = visible / peak
    if raw <= 1:
        return 1.0
    k = math.floor(math.log10(raw))
    for m in (5, 2, 1):
        if m * 10**k <= raw:
            return float(m * 10**k)
    return float(10**k)  # pragma: no cover


def frame_rows(t: _Array, fps: float) -> _Array:
    """The rows of a record to show at ``fps`` frames per second of simulated time: the first
    row at or after each frame time, and always the first and the last row."""
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        return np.zeros(0, dtype=np.int64)
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps: expected a positive number of frames per second, given {fps!r}")
    span = float(t[-1] - t[0])
    if not span * fps < t.size:  # as many frames as rows, or more: every row
        return np.arange(t.size)
    frames = t[0] + np.arange(int(span * fps) + 1) / fps
    frames = frames[frames < t[-1]]
    rows = np.searchsorted(t, frames - 1e-9 * max(1.0, abs(t[-1])))
    rows = np.unique(np.concatenate([[0], rows, [t.size - 1]]))
    kept: _Array = rows[rows < t.size]
    return kept


def _packed(command: Dict[str, Any]) -> str:
    return base64.b64encode(gzip.compress(_umsgpack(command), mtime=0)).decode("ascii")


def _f32(a: _Array) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype="<f4").tobytes()).decode("ascii")


TARGET_COLOR = [0.85, 0.55, 0.15, 0.9]
HANDLE_COLOR = [0.9, 0.1, 0.1, 1.0]


def target_box(mass: float, inertia: _Array) -> _Array:
    """The sides (m) of the uniform box with ``mass`` and the principal moments on the diagonal
    of ``inertia`` (about its centre, body axes): ``a² = 6 (I_y + I_z − I_x) / m``, and the same
    for ``b``, ``c``. The box stands for the target in the view; off-diagonal terms are not
    drawn (its axes are the body axes)."""
    ix, iy, iz = np.diag(np.asarray(inertia, dtype=float))
    squares = 6.0 / mass * np.array([iy + iz - ix, ix + iz - iy, ix + iy - iz])
    return np.sqrt(np.maximum(squares, 1e-6))


def target_shapes(traj: "_core.Trajectory", frame: int) -> List[Dict[str, Any]]:
    """The shapes of a run's target on the extra frame ``frame``: its equivalent box
    (:func:`target_box`) at its centre of mass, and its handle (a 5 cm sphere)."""
    target = traj.target_body
    if target is None:
        return []
    com = list(np.asarray(target.com, dtype=float))
    box = {"kind": "box", "frame": frame, "size": target_box(target.mass, target.inertia).tolist(),
           "origin": com + [0.0, 0.0, 0.0, 1.0], "color": TARGET_COLOR, "stand_in": False}
    handle = {"kind": "sphere", "frame": frame, "radius": 0.05, "origin": list(np.asarray(target.grasp, dtype=float)),
              "color": HANDLE_COLOR, "stand_in": False}
    return [box, handle]


def animation_html(
    traj: "_core.Trajectory",
    fps: float = DEFAULT_FPS,
    ghost: Union[bool, float] = False,
    packages: Optional[Mapping[str, Union[str, Path]]] = None,
    title: Optional[str] = None,
    shapes: Sequence[Mapping[str, Any]] = (),
) -> str:
    """The text of the self-contained HTML animation of ``traj`` (see :func:`write_animation`)."""
    mc = _meshcat()
    arm = traj.arm
    robot = arm.robot
    rows = frame_rows(traj.t, fps)
    if rows.size == 0:
        raise ValueError("the trajectory has no rows to show")
    if isinstance(ghost, bool):
        scale = ghost_scale(traj) if ghost else None
    else:
        scale = float(ghost)
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"ghost: expected True, False or a positive factor, given {ghost!r}")
    extra = [_checked_shape(shape, k, len(robot.frame_names)) for k, shape in enumerate(shapes)]
    poses = traj.frame_poses(rows=rows.tolist())
    extra_frames: List[str] = []
    if traj.target is not None:
        # the target as one more body: its box, and its handle as a small sphere
        frame = poses.shape[1]
        poses = np.concatenate([poses, np.asarray(traj.target)[rows, None, :7]], axis=1)
        extra_frames.append("target")
        extra += target_shapes(traj, frame)
    scene = _scene(robot, packages, ghost=scale is not None, share=True, extra=extra, extra_frames=extra_frames)
    ghost_poses = traj.frame_poses(motor_side=scale, rows=rows.tolist()) if scale is not None else None
    # one trail per end-effector (every arm of a tree)
    trails = [poses[:, robot.frame_names.index(link), :3] for link in robot.ee_links]
    t = np.asarray(traj.t)[rows]
    # the region the run covers, for the camera and the axes
    points = poses[:, :, :3].reshape(-1, 3)
    lo, hi = points.min(axis=0), points.max(axis=0)
    for shape in extra:
        # the extra shapes' bounding spheres along the run (at the first and last row)
        reach = (0.5 * float(np.linalg.norm(shape["size"])) if shape["kind"] == "box"
                 else float(shape["radius"]) + 0.5 * float(shape.get("length", 0.0)))
        for pose in (poses[0, shape["frame"]], poses[-1, shape["frame"]]):
            centre = pose[:3] + _matrix(pose)[:3, :3] @ np.asarray(shape["origin"][:3])
            lo, hi = np.minimum(lo, centre - reach), np.maximum(hi, centre + reach)
    extent = float(max(np.max(hi - lo), 0.5))
    commands = list(scene.commands)
    commands.append(_axes(0.4 * extent))
    for e, trail in enumerate(trails):
        commands.append(_line(trail, _TRAIL, ("ee_trail" if e == 0 else f"ee_trail_{e}",)))
    dt = float(np.median(np.diff(np.asarray(traj.t)))) if len(traj.t) > 1 else 0.0
    heading = title or f"{robot.name}: {robot.dof} joints, dt = {_g(dt)} s, {len(traj.t)} rows"
    info: Dict[str, Any] = {
        "model": robot.name,
        "title": heading,
        "names": scene.names,
        "t": _f32(t),
        "poses": _f32(poses),
        "ghost": _f32(ghost_poses) if ghost_poses is not None else None,
        "ghost_scale": scale,
        "frames": int(rows.size),
        "count": len(scene.names),
        "trails": len(trails),
        "center": [float(v) for v in 0.5 * (lo + hi)],
        "extent": extent,
        "commands": [c if "clone" in c else _packed(c) for c in commands],
    }
    viewer_js = (Path(mc.__file__).parent / "viewer" / "dist" / "main.min.js").read_text("utf-8")
    # each placeholder filled once, in one pass, so no value is read as another placeholder;
    # in the script, <, > and & are JSON escapes, so no text can close or comment it out
    fills = {
        "TITLE": _html_escape(heading),
        "VIEWER": viewer_js.replace("</script", "<\\/script"),
        "DATA": json.dumps(info).replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026"),
    }
    page = re.sub(r"__(TITLE|VIEWER|DATA)__", lambda m: fills[m.group(1)], _PAGE)
    return page.replace("__CSP__", _content_security_policy(page), 1)


def _content_security_policy(page: str) -> str:
    """The page's Content-Security-Policy: nothing loads from anywhere. Its two scripts run by
    their hashes (an injected script would not), images and fetches may only be data: and blob:
    URIs made in the page, and everything else is refused."""
    hashes = " ".join(
        "'sha256-" + base64.b64encode(hashlib.sha256(script.encode("utf-8")).digest()).decode("ascii") + "'"
        for script in re.findall(r"<script>(.*?)</script>", page, flags=re.S)
    )
    return ("default-src 'none'; script-src " + hashes + "; style-src 'unsafe-inline'; "
            "img-src data: blob:; connect-src data: blob:; font-src data:; base-uri 'none'; "
            "form-action 'none'")


def _g(value: float) -> str:
    return f"{value:.6g}"


def _html_escape(text: str) -> str:
    return (text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            .replace('"', "&quot;").replace("'", "&#39;"))


def write_animation(
    traj: "_core.Trajectory",
    path: Union[str, Path],
    fps: float = DEFAULT_FPS,
    ghost: Union[bool, float] = False,
    packages: Optional[Mapping[str, Union[str, Path]]] = None,
    title: Optional[str] = None,
    shapes: Sequence[Mapping[str, Any]] = (),
) -> Path:
    """Writes ``traj`` as one self-contained HTML file and returns its path.

    The page plays the run with play/pause, a time slider (s) and speed buttons, shows the
    time, the model, ``dt`` and the rows kept, and draws the bus and links from the URDF's
    visuals, the end-effector's path as a trail (magenta), and the inertial axes at the origin
    (x red, y green, z blue). It opens paused at ``t = 0``; ``file.html#t=SECONDS`` opens it
    at that time. Nothing is fetched from the network or from beside the file.

    - ``fps``: frames per second of simulated time kept (the record is decimated to it; the
      first and last rows are always kept).
    - ``ghost``: ``True`` also draws the motor-side arm at ``q + s (θ − q)`` in translucent
      blue, with ``s`` chosen so the largest deflection shows as about 9° (:func:`ghost_scale`;
      the page shows ``s``); a number sets ``s`` (1 is the true motor side).
    - ``packages``: a dict from ROS package name to its directory, for ``package://`` meshes
      (see :meth:`orbitflex.Robot.scene`).
    - ``title``: the page's heading (default: the model, n, dt and the rows).
    - ``shapes``: more shapes to draw, as dicts like :meth:`orbitflex.Robot.scene`'s: ``kind``
      (``"box"``, ``"sphere"``, ``"cylinder"``, ``"capsule"``), its sizes in m (``size`` for a
      box, ``radius`` and ``length`` for the others), ``frame`` (index into
      ``robot.frame_names``, default 0, the base), ``origin`` (the pose in that frame, default
      identity) and ``color`` (RGBA). The CLI draws the bus of ``--base-mass`` this way.
    """
    text = animation_html(traj, fps=fps, ghost=ghost, packages=packages, title=title, shapes=shapes)
    path = Path(path)
    path.write_text(text, encoding="utf-8")
    return path


def _umsgpack(command: Dict[str, Any]) -> bytes:
    import umsgpack  # type: ignore[import-untyped]

    return bytes(umsgpack.packb(command))


_PAGE = r"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="__CSP__">
<title>__TITLE__</title>
<style>
  html, body { margin: 0; height: 100%; overflow: hidden; background: #0b0e17;
    font: 13px system-ui, sans-serif; color: #e8e8ea; }
  #meshcat-pane { position: absolute; inset: 0; }
  #hud { position: absolute; left: 0; right: 0; bottom: 0; padding: 8px 12px;
    background: rgba(10, 12, 20, 0.82); display: flex; gap: 10px; align-items: center; }
  #hud button { background: #2a3145; color: #fff; border: 1px solid #4a5270; border-radius: 4px;
    padding: 3px 9px; cursor: pointer; font: inherit; }
  #hud button.on { background: #4b6cd8; }
  #slider { flex: 1; }
  #time { font-variant-numeric: tabular-nums; min-width: 150px; text-align: right; }
  #title { position: absolute; left: 12px; top: 10px; font-size: 14px;
    text-shadow: 0 0 4px #000; pointer-events: none; }
  #legend { position: absolute; left: 12px; top: 32px; font-size: 12px; color: #c8c8d0;
    text-shadow: 0 0 4px #000; pointer-events: none; line-height: 1.5; }
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="title">__TITLE__</div>
<div id="legend"></div>
<div id="hud">
  <button id="play" title="play / pause (space)">&#9654;</button>
  <input id="slider" type="range" min="0" max="1" step="any" value="0">
  <span id="time"></span>
  <span>speed</span>
  <span id="speeds"></span>
</div>
<script>__VIEWER__</script>
<script>
"use strict";
const DATA = __DATA__;
const view = { ready: false, time: 0, playing: false, speed: 1 };
window.orbitflexView = view;

function bytes(b64) {
  const s = atob(b64), out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out;
}
function floats(b64) { const b = bytes(b64); return new Float32Array(b.buffer, 0, b.length / 4); }
async function gunzip(b64) {
  const stream = new Blob([bytes(b64)]).stream().pipeThrough(new DecompressionStream("gzip"));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

async function main() {
  const viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
  const THREE = MeshCat.THREE;
  viewer.set_property(["Grid"], "visible", false);
  viewer.set_property(["Axes"], "visible", false);
  viewer.set_property(["Background"], "top_color", [0.02, 0.03, 0.07]);
  viewer.set_property(["Background"], "bottom_color", [0.16, 0.18, 0.26]);
  // one shape that three.js cannot read leaves a gap, not a blank page
  const failures = [];
  for (const c of DATA.commands) {
    try {
      if (typeof c === "string") {
        viewer.handle_command_bytearray(await gunzip(c));
      } else {  // a mesh drawn again: a copy of its first drawing, sharing the geometry
        const copy = viewer.scene_tree.find(c.clone.concat(["<object>"])).object.clone();
        copy.matrix.fromArray(c.matrix);
        copy.matrix.decompose(copy.position, copy.quaternion, copy.scale);
        viewer.scene_tree.find(c.path.concat(["<object>"])).set_object(copy);
      }
    } catch (e) {
      failures.push(String(e));
      console.error("orbitflex: a shape could not be drawn:", e);
    }
  }
  view.failures = failures;

  const times = floats(DATA.t), poses = floats(DATA.poses);
  const ghost = DATA.ghost ? floats(DATA.ghost) : null;
  const F = DATA.count, K = DATA.frames, T0 = times[0], T1 = times[K - 1];
  const trails = [];
  for (let e = 0; e < DATA.trails; e++) {
    trails.push(viewer.scene_tree.find([e === 0 ? "ee_trail" : "ee_trail_" + e, "<object>"]).object);
  }

  // camera: three.js is y-up; the inertial frame z-up maps to (x, z, -y)
  const c = DATA.center, d = 0.8 * DATA.extent + 0.2;
  const target = new THREE.Vector3(c[0], c[2], -c[1]);
  viewer.controls.target.copy(target);
  viewer.camera.position.set(c[0] + 0.75 * d, c[2] + 0.55 * d, -c[1] + 0.9 * d);
  viewer.camera.far = 50 * d;
  viewer.controls.update();

  const m = new THREE.Matrix4(), p = new THREE.Vector3(), qa = new THREE.Quaternion(),
    qb = new THREE.Quaternion(), one = new THREE.Vector3(1, 1, 1);
  function place(root, data, k, f) {
    const k1 = Math.min(k + 1, K - 1);
    for (let i = 0; i < F; i++) {
      const a = 7 * (k * F + i), b = 7 * (k1 * F + i);
      p.set(data[a] + f * (data[b] - data[a]), data[a + 1] + f * (data[b + 1] - data[a + 1]),
            data[a + 2] + f * (data[b + 2] - data[a + 2]));
      qa.set(data[a + 3], data[a + 4], data[a + 5], data[a + 6]);
      qb.set(data[b + 3], data[b + 4], data[b + 5], data[b + 6]);
      qa.slerp(qb, f);
      m.compose(p, qa, one);
      viewer.set_transform([root, DATA.names[i]], m.toArray());
    }
  }

  const slider = document.getElementById("slider"), label = document.getElementById("time");
  const play = document.getElementById("play");
  slider.min = T0; slider.max = T1;
  function setTime(t) {
    t = Math.min(Math.max(Number(t) || 0, T0), T1);
    let lo = 0, hi = K - 1;
    while (lo < hi) { const mid = (lo + hi + 1) >> 1; if (times[mid] <= t) lo = mid; else hi = mid - 1; }
    const k = lo, span = k + 1 < K ? times[k + 1] - times[k] : 0;
    const f = span > 0 ? Math.min(Math.max((t - times[k]) / span, 0), 1) : 0;
    place("robot", poses, k, f);
    if (ghost) place("ghost", ghost, k, f);
    for (const trail of trails) trail.geometry.setDrawRange(0, k + 1);
    view.time = t;
    slider.value = t;
    label.textContent = "t = " + t.toFixed(2) + " s / " + T1.toFixed(2) + " s";
    viewer.set_dirty();
  }
  function setPlaying(on) {
    if (on && view.time >= T1) setTime(T0);
    view.playing = on;
    play.innerHTML = on ? "&#10074;&#10074;" : "&#9654;";
    last = performance.now();
  }
  let last = performance.now();
  function tick(now) {
    if (view.playing) {
      const t = view.time + (now - last) / 1000 * view.speed;
      setTime(t);
      if (t >= T1) setPlaying(false);
    }
    last = now;
    requestAnimationFrame(tick);
  }
  play.onclick = () => setPlaying(!view.playing);
  slider.oninput = () => { setPlaying(false); setTime(slider.value); };
  document.addEventListener("keydown", (e) => {
    if (e.code === "Space") { e.preventDefault(); setPlaying(!view.playing); }
  });
  const speeds = document.getElementById("speeds");
  for (const s of [0.1, 0.25, 0.5, 1, 2, 5, 10]) {
    const b = document.createElement("button");
    b.textContent = s + "\u00d7";
    b.onclick = () => { view.speed = s; for (const o of speeds.children) o.classList.remove("on"); b.classList.add("on"); };
    if (s === 1) b.classList.add("on");
    speeds.appendChild(b);
  }
  const legend = ["<span style='color:#e0409a'>&#9644;</span> end-effector trail",
    "inertial axes: <span style='color:#f33'>x</span> <span style='color:#3c3'>y</span> <span style='color:#48f'>z</span>"];
  if (failures.length) legend.push("&#9888; " + failures.length + " shape(s) could not be drawn (see the browser console)");
  if (ghost) legend.push("<span style='color:#59bfff'>&#9632;</span> motor side (&theta;, stick figure), deflection &times; " + DATA.ghost_scale);
  document.getElementById("legend").innerHTML = legend.join("<br>");

  function fromHash() {
    const match = /(?:^#|&)t=([-+0-9.eE]+)/.exec(location.hash);
    setPlaying(false);
    setTime(match ? parseFloat(match[1]) : T0);
  }
  window.addEventListener("hashchange", fromHash);
  fromHash();
  view.setTime = setTime; view.play = () => setPlaying(true); view.pause = () => setPlaying(false);
  view.start = T0; view.end = T1;
  requestAnimationFrame(tick);
  view.ready = true;
  document.title += " \u2014 ready";
}
main().catch((e) => { document.getElementById("title").textContent = "orbitflex view failed: " + e; view.error = String(e); });
</script>
</body>
</html>
"""
