# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
# (meshcat and umsgpack come with orbitflex[viz], without stubs: a base install type-checks clean)
"""3-D views of a model and its runs: a self-contained HTML animation and a live viewer.

Everything here draws with `meshcat <https://github.com/meshcat-dev/meshcat-python>`_, the
three.js viewer Pinocchio and Drake use; install it with ``pip install 'orbitflex[viz]'``.

- :func:`write_animation` (``traj.animate(path)``) writes one HTML file that plays a run
  offline in any browser: the bus, the links, the end-effector's trail, the inertial axes and,
  optionally, the motor-side "ghost" arm at angles ``θ`` with its deflection exaggerated. The
  page holds the viewer's JavaScript, the shapes and meshes (compressed) and the frame poses;
  it fetches nothing. It opens at ``t = 0``, paused; ``page.html#t=12.5`` opens it at 12.5 s.
- :func:`show` / :class:`Viewer` open a live view served on loopback (127.0.0.1), which a
  script updates: ``viewer.display(x)``, ``viewer.play(traj)``, or
  ``arm.simulate(..., on_rows=viewer.on_rows)`` to watch a run as it is computed.

Poses come from the Rust core (:meth:`orbitflex.Robot.frame_poses`,
:meth:`orbitflex.Trajectory.frame_poses`); the shapes from the URDF's ``<visual>`` elements
(:meth:`orbitflex.Robot.scene`). A missing or bad mesh gives a :class:`VisualWarning` naming
the link and the file, and an orange stand-in; a link without visuals is drawn as a grey
capsule from its joint to each child's joint.

Frames: the inertial frame is z-up in the view; lengths in metres, times in seconds.
"""

from __future__ import annotations

import base64
import gzip
import hashlib
import html
import json
import math
import re
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import _core

# any ndarray (numpy 1.x's stubs need the type arguments that 2.x defaults)
_Array = npt.NDArray[Any]

__all__ = [
    "VisualWarning",
    "write_animation",
    "animation_html",
    "show",
    "Viewer",
    "ghost_scale",
]

#: Frame rate of the animation written by the CLI (frames per second of simulated time).
DEFAULT_FPS = 30.0

_GREY = (0.7, 0.7, 0.72, 1.0)
_GHOST = (0.35, 0.75, 1.0, 0.35)
_TRAIL = 0xE0409A


class VisualWarning(UserWarning):
    """A visual that could not be drawn as written (a missing or bad mesh, a malformed
    ``<visual>``); a stand-in is drawn instead."""


def _meshcat() -> Any:
    try:
        with warnings.catch_warnings():
            # meshcat's server module imports a pyzmq name deprecated since pyzmq 17
            warnings.simplefilter("ignore", DeprecationWarning)
            import meshcat  # type: ignore[import-untyped]
            import meshcat.commands  # type: ignore[import-untyped]
            import meshcat.geometry  # type: ignore[import-untyped]
            import meshcat.visualizer  # type: ignore[import-untyped]
    except ImportError as e:  # pragma: no cover - exercised only without the extra
        raise ImportError(
            "orbitflex.viz needs meshcat: pip install 'orbitflex[viz]'"
        ) from e
    return meshcat


# --------------------------------------------------------------------------------------------
# shapes


def _matrix(pose: Sequence[float]) -> _Array:
    """4×4 homogeneous matrix of ``[position; quat (x, y, z, w)]`` (shape axes to parent)."""
    x, y, z, w = (float(v) for v in pose[3:7])
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    m = np.eye(4)
    m[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    m[:3, 3] = pose[:3]
    return m


# three.js cylinders run along y; URDF's along z: turn y onto z
_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])


def _color(rgba: Optional[Sequence[float]]) -> Tuple[int, float]:
    r, g, b, a = rgba if rgba is not None else _GREY
    return (int(round(r * 255)) << 16) | (int(round(g * 255)) << 8) | int(round(b * 255)), a


def _material(rgba: Optional[Sequence[float]]) -> Any:
    g = _meshcat().geometry
    color, opacity = _color(rgba)
    return g.MeshPhongMaterial(color=color, opacity=opacity, transparent=opacity < 1)


@dataclass
class _MeshData:
    """A mesh file read once: its contents for meshcat (a DAE's texture references rewritten to
    keys of ``resources``), and for a DAE its textures as data URIs (``resources``), with a note
    for each one not embedded."""

    contents: Union[bytes, str]
    resources: Dict[str, str]
    missing: List[str]

    @property
    def size(self) -> int:
        """Bytes embedded: the file and its textures."""
        return len(self.contents) + sum(len(r) for r in self.resources.values())


_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".gif": "image/gif",
         ".bmp": "image/bmp", ".webp": "image/webp", ".tga": "image/x-tga"}

#: The largest texture embedded (bytes).
MAX_TEXTURE_BYTES = 16_000_000

#: The most mesh bytes (files and their textures) one page or viewer embeds, counting each copy
#: embedded: a mesh drawn again with the same colour is copied by the page, not embedded again.
MAX_PAGE_MESH_BYTES = 256_000_000

#: What a texture that is not embedded becomes: one white pixel, so the mesh keeps its own
#: colours and nothing is fetched.
_BLANK_TEXTURE = ("data:image/png;base64,"
                  "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAIAAACQd1PeAAAADElEQVR4nGP4//8/AAX+Av4N70a4AAAAAElFTkSuQmCC")

# a URL scheme (http:, https:, ftp:, blob:, ...) or a network-path reference (//host/...); one
# letter before the colon is a Windows drive
_NETWORK = re.compile(r"^(?:[A-Za-z][A-Za-z0-9+.\-]+:|//)")


def _texture(mesh: Path, name: str, missing: List[str]) -> str:
    """The data URI of the texture a DAE names (``name``, beside the mesh), or a blank one with
    a note in ``missing``."""
    if name.startswith("data:"):
        return name  # already inline
    if _NETWORK.match(name) and not name.startswith("file:"):
        missing.append(f"texture '{name}': a network address; the page loads nothing, so it is not embedded")
        return _BLANK_TEXTURE
    image = mesh.parent / re.sub(r"^file://(?:localhost)?", "", name)
    mime = _MIME.get(image.suffix.lower())
    try:
        if mime is None or not image.is_file() or image.stat().st_size > MAX_TEXTURE_BYTES:
            raise OSError("not found, or not a PNG/JPEG/GIF/BMP/WebP/TGA image under 16 MB")
        encoded = base64.b64encode(image.read_bytes()).decode("ascii")
    except OSError as e:
        missing.append(f"texture '{name}': {e}")
        return _BLANK_TEXTURE
    return f"data:{mime};base64,{encoded}"


def _xml_text(markup: str) -> str:
    """The text an XML parser gives for an element's content: comments dropped, CDATA
    unwrapped, tags (COLLADA 1.5's ``<ref>``) dropped, entities decoded, whitespace trimmed."""
    markup = re.sub(r"<!--.*?-->", "", markup, flags=re.S)
    parts = re.split(r"<!\[CDATA\[(.*?)\]\]>", markup, flags=re.S)
    return "".join(part if k % 2 else html.unescape(re.sub(r"<[^>]*>", "", part))
                   for k, part in enumerate(parts)).strip()


def _mesh_data(path: Path, fmt: str) -> _MeshData:
    data = path.read_bytes()
    if fmt == "stl":
        return _MeshData(data, {}, [])
    text = data.decode("utf-8", "replace")
    resources: Dict[str, str] = {}
    missing: List[str] = []
    if fmt == "dae":
        # Each <image>'s <init_from> names its file (COLLADA 1.4; 1.5 wraps it in <ref>); other
        # <init_from>s name an image by id. Every file reference is rewritten to a key of
        # `resources`, the texture embedded or a blank one, so that three.js (which reads the
        # element's text) asks for nothing that is not in the page, whatever whitespace, scheme,
        # CDATA, comments or entities the name is written with.
        keys: Dict[str, str] = {}

        def reference(match: "re.Match[str]") -> str:
            name = _xml_text(match.group(1))
            if not name or name.startswith("#"):
                return match.group(0)
            if name not in keys:
                keys[name] = f"orbitflex-texture-{len(keys)}"
                resources[keys[name]] = _texture(path, name, missing)
            return f"<init_from>{keys[name]}</init_from>"

        def image(match: "re.Match[str]") -> str:
            return re.sub(r"<init_from>(.*?)</init_from>", reference, match.group(0), flags=re.S)

        text = re.sub(r"<image\b[^>]*/>|<image\b.*?</image>", image, text, flags=re.S)
    return _MeshData(text, resources, missing)


class _OverBudget(Exception):
    """A mesh that would take the meshes embedded past :data:`MAX_PAGE_MESH_BYTES`."""


class _Budget:
    """The mesh bytes embedded so far, against :data:`MAX_PAGE_MESH_BYTES`."""

    def __init__(self) -> None:
        self.spent = 0

    def spend(self, size: int) -> None:
        if self.spent + size > MAX_PAGE_MESH_BYTES:
            raise _OverBudget(f"not drawn: with it the meshes embedded would pass {MAX_PAGE_MESH_BYTES:,} "
                              f"bytes ({self.spent:,} embedded, {size:,} more)")
        self.spent += size


def _objects(
    shape: Mapping[str, Any], rgba: Optional[Sequence[float]], meshes: Dict[Path, _MeshData],
    budget: Optional[_Budget] = None,
) -> List[Tuple[Any, _Array]]:
    """The meshcat objects of one shape of :meth:`Robot.scene`, each with its matrix in the
    frame. Mesh files are read once into ``meshes``; each copy of a mesh drawn is counted in
    ``budget``."""
    g = _meshcat().geometry
    origin = _matrix(shape["origin"])
    kind = shape["kind"]
    material = _material(rgba)
    if kind == "box":
        return [(g.Mesh(g.Box(shape["size"]), material), origin)]
    if kind == "sphere":
        return [(g.Mesh(g.Sphere(shape["radius"]), material), origin)]
    if kind == "cylinder":
        cylinder = g.Cylinder(shape["length"], shape["radius"])
        return [(g.Mesh(cylinder, material), origin @ _Y_TO_Z)]
    if kind == "capsule":
        r, h = shape["radius"], shape["length"]
        out = [(g.Mesh(g.Cylinder(h, r), material), origin @ _Y_TO_Z)]
        for end in (-0.5 * h, 0.5 * h):
            shift = np.eye(4)
            shift[2, 3] = end
            out.append((g.Mesh(g.Sphere(r), _material(rgba)), origin @ shift))
        return out
    # a mesh: the file's bytes, in its own colours (and textures) unless the URDF gives one
    scale = np.diag([*shape["scale"], 1.0])
    path, fmt = Path(shape["path"]), shape["format"]
    if path not in meshes:
        meshes[path] = _mesh_data(path, fmt)
    mesh = meshes[path]
    if budget is not None:
        budget.spend(mesh.size)
    if rgba is None and fmt in ("dae", "obj"):
        return [(_MeshFile(mesh.contents, fmt, mesh.resources), origin @ scale)]
    return [(g.Mesh(g.MeshGeometry(mesh.contents, fmt), material), origin @ scale)]


class _MeshFile:
    """A mesh file drawn with its own materials (meshcat's ``_meshfile_object``)."""

    def __init__(self, contents: Union[bytes, str], fmt: str, resources: Dict[str, str]) -> None:
        import uuid

        self.contents, self.format, self.resources = contents, fmt, resources
        self.uuid = str(uuid.uuid1())

    def lower(self) -> Dict[str, Any]:
        return {
            "metadata": {"version": 4.5, "type": "Object"},
            "object": {
                "uuid": self.uuid,
                "type": "_meshfile_object",
                "format": self.format,
                "data": self.contents,
                "resources": self.resources,
            },
        }


def _safe(name: str) -> str:
    """A scene-tree name: letters, digits, ``_``, ``.`` and ``-`` (meshcat's panel shows it)."""
    return re.sub(r"[^A-Za-z0-9_.\-]", "_", name) or "_"


@dataclass
class _Scene:
    """The set-object commands of a model's shapes, by frame path. With ``share``, a mesh drawn
    again (same file and colour; the matrix carries its scale) is a ``{"clone": path, "path":
    path, "matrix": …}`` item that the page copies from its first drawing instead of a second
    copy of the file."""

    names: List[str]
    commands: List[Dict[str, Any]] = field(default_factory=list)
    warnings: List[str] = field(default_factory=list)


def _scene(
    robot: "_core.Robot",
    packages: Optional[Mapping[str, Union[str, Path]]],
    ghost: bool,
    share: bool = False,
    extra: Sequence[Dict[str, Any]] = (),
) -> _Scene:
    """Set-object commands drawing every shape of ``robot`` under the path ``robot`` and, with
    ``ghost``, its stick figure under ``ghost`` in translucent blue. Bad meshes warn and get a
    stand-in."""
    mc = _meshcat()
    shapes, problems = robot.scene({k: str(v) for k, v in (packages or {}).items()})
    shapes = list(shapes) + list(extra)  # already checked (_checked_shape)
    roots: List[Tuple[str, Any, Optional[Sequence[float]]]] = [("robot", shapes, None)]
    if ghost:
        roots.append(("ghost", robot.scene(skeleton=True)[0], _GHOST))
    names: List[str] = []
    for name in robot.frame_names:
        safe = _safe(name)
        while safe in names:
            safe += "_"
        names.append(safe)
    scene = _Scene(names=names, warnings=list(problems))
    meshes: Dict[Path, _MeshData] = {}
    drawn_meshes: Dict[Tuple[Any, ...], List[str]] = {}
    budget = _Budget()
    for root, drawn, override in roots:
        count: Dict[int, int] = {}
        for shape in drawn:
            rgba = override if override is not None else shape["color"]
            link = robot.frame_names[shape["frame"]]
            # a mesh drawn again in the same colour is a copy of its first drawing (the copy's
            # matrix carries its own scale), embedded once
            key = (shape["path"], tuple(rgba or ())) if shape["kind"] == "mesh" else None
            shared = share and key in drawn_meshes
            try:
                objects = _objects(shape, rgba, meshes, None if shared else budget)
            except OSError as e:  # the file went away or cannot be read since it was checked
                scene.warnings.append(f"link '{link}', mesh '{shape.get('path')}': {e}")
                continue
            except _OverBudget as e:
                scene.warnings.append(f"link '{link}', mesh '{shape.get('path')}': {e}")
                continue
            for obj, matrix in objects:
                k = count.get(shape["frame"], 0)
                count[shape["frame"]] = k + 1
                parts = [root, names[shape["frame"]], f"shape{k}"]
                column_major = [float(v) for v in matrix.T.flatten()]
                if key is not None:
                    if shared:
                        scene.commands.append({"clone": drawn_meshes[key], "path": parts, "matrix": column_major})
                        continue
                    drawn_meshes[key] = parts
                path = mc.commands.Path(tuple(parts))
                if isinstance(obj, _MeshFile):
                    lowered = {"type": "set_object", "object": obj.lower(), "path": path.lower()}
                else:
                    lowered = mc.commands.SetObject(obj, path=path).lower()
                lowered["object"]["object"]["matrix"] = column_major
                scene.commands.append(lowered)
    for path, mesh in meshes.items():
        scene.warnings += [f"mesh '{path}': {note}; drawn without it" for note in mesh.missing]
    for message in scene.warnings:
        warnings.warn(message, VisualWarning, stacklevel=3)
    return scene


_SIZES = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length"), "capsule": ("radius", "length")}


def _checked_shape(shape: Mapping[str, Any], k: int, frames: int) -> Dict[str, Any]:
    """An extra shape (``shapes=`` of :func:`write_animation`), checked, with defaults filled."""
    where = f"shapes[{k}]"
    kind = shape.get("kind")
    if kind not in _SIZES:
        raise ValueError(f"{where}: kind: expected one of {', '.join(_SIZES)}, given {kind!r}")
    frame = shape.get("frame", 0)
    if not isinstance(frame, int) or not 0 <= frame < frames:
        raise ValueError(f"{where}: frame: expected an index into robot.frame_names (0..{frames - 1}), given {frame!r}")
    out: Dict[str, Any] = {"kind": kind, "frame": frame, "stand_in": False}
    origin = np.asarray(shape.get("origin", [0, 0, 0, 0, 0, 0, 1]), dtype=float)
    if origin.shape != (7,) or not np.all(np.isfinite(origin)) or not np.linalg.norm(origin[3:]) > 0:
        raise ValueError(f"{where}: origin: expected [x, y, z, qx, qy, qz, qw] with a non-zero quaternion")
    out["origin"] = origin.tolist()
    for key in _SIZES[kind]:
        value = np.asarray(shape.get(key, np.nan), dtype=float)
        if key == "size":
            ok = value.shape == (3,) and bool(np.all(value > 0)) and bool(np.all(np.isfinite(value)))
        else:
            ok = value.shape == () and bool(value > 0) and bool(np.isfinite(value))
        if not ok:
            raise ValueError(f"{where}: {key}: expected {'three positive lengths' if key == 'size' else 'a positive length'} (m), given {shape.get(key)!r}")
        out[key] = value.tolist()
    color = shape.get("color")
    if color is not None:
        c = np.asarray(color, dtype=float)
        if c.shape != (4,) or not np.all((c >= 0) & (c <= 1)):
            raise ValueError(f"{where}: color: expected RGBA, four numbers in 0..1, given {color!r}")
        color = c.tolist()
    out["color"] = color
    return out


def _line(points: _Array, color: int, path: Tuple[str, ...], segments: bool = False) -> Dict[str, Any]:
    mc = _meshcat()
    g = mc.geometry
    geometry = g.PointsGeometry(np.ascontiguousarray(points.T, dtype=np.float32))
    kind = g.LineSegments if segments else g.Line
    lowered: Dict[str, Any] = mc.commands.SetObject(
        kind(geometry, g.LineBasicMaterial(color=color, linewidth=2)), path=mc.commands.Path(path)
    ).lower()
    return lowered


def _axes(length: float) -> Dict[str, Any]:
    """The inertial axes: x red, y green, z blue, ``length`` m, at the inertial origin."""
    mc = _meshcat()
    lowered: Dict[str, Any] = mc.commands.SetObject(
        mc.geometry.triad(length), path=mc.commands.Path(("inertial_axes",))
    ).lower()
    return lowered


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
    scene = _scene(robot, packages, ghost=scale is not None, share=True, extra=extra)
    poses = traj.frame_poses(rows=rows.tolist())
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


# --------------------------------------------------------------------------------------------
# the live viewer


class Viewer:
    """A live 3-D view of ``robot`` in the browser, served by meshcat on loopback.

    ``Viewer(robot)`` starts a meshcat server on 127.0.0.1 (or connects to ``zmq_url``),
    draws the robot's shapes, and prints nothing; open :attr:`url` in a browser. Then:

    - ``display(x)`` poses it at a state ``x`` (13+4n) or, with ``q``, at a base pose;
    - ``play(traj, speed=1.0)`` plays a run in real time (times ``speed``);
    - ``on_rows`` is a callback for ``arm.simulate(..., on_rows=viewer.on_rows)`` that shows the
      newest row of each chunk while the run is computed.

    ``ghost=True`` also draws the motor-side arm (at ``θ``, deflection drawn ``ghost_scale``
    times larger). ``close()`` stops a server this viewer started.
    """

    def __init__(
        self,
        robot: "_core.Robot",
        packages: Optional[Mapping[str, Union[str, Path]]] = None,
        zmq_url: Optional[str] = None,
        ghost: bool = False,
        ghost_scale: float = 1.0,
    ) -> None:
        mc = _meshcat()
        self.robot = robot
        import contextlib
        import io

        with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints its URL; `url` has it
            self._vis = mc.visualizer.Visualizer(zmq_url=zmq_url)
        self._ghost = bool(ghost)
        self.ghost_scale = float(ghost_scale)
        scene = _scene(robot, packages, ghost=self._ghost)
        self._names = scene.names
        self._n = robot.dof
        # the model at rest, for the camera and the axes
        rest = robot.frame_poses([0.0, 0, 0, 0, 0, 0, 1], np.zeros(robot.dof))[:, :3]
        center = 0.5 * (rest.min(axis=0) + rest.max(axis=0))
        extent = float(max(np.ptp(rest, axis=0).max(), 0.5))
        d = 1.2 * extent + 0.5
        eye = center + d * np.array([0.75, -0.9, 0.55])
        window = self._vis.window
        settings = [
            ("Grid", "visible", False),
            ("Background", "top_color", [0.02, 0.03, 0.07]),
            ("Background", "bottom_color", [0.16, 0.18, 0.26]),
            # inside the camera's frame three.js is y-up: the inertial (x, y, z) is (x, z, -y)
            ("Cameras/default/rotated/<object>", "position", [eye[0], eye[2], -eye[1]]),
        ]
        for path, name, value in settings:
            window.send(mc.commands.SetProperty(name, value, mc.commands.Path(tuple(path.split("/")))))
        for command in [*scene.commands, _axes(0.4 * extent)]:
            window.zmq_socket.send_multipart(
                [command["type"].encode("utf-8"), command["path"].encode("utf-8"), _umsgpack(command)]
            )
            window.zmq_socket.recv()

    @property
    def url(self) -> str:
        """The page to open: ``http://127.0.0.1:PORT/static/``."""
        return str(self._vis.url())

    def _send(self, root: str, poses: _Array) -> None:
        for name, pose in zip(self._names, poses):
            self._vis[root][name].set_transform(_matrix(pose))

    def display(self, x: Any, q: Any = None) -> None:
        """Poses the robot at state ``x`` (13+4n; the ghost at its ``θ``), or at base pose
        ``x`` (7,) and joint angles ``q``."""
        x = np.asarray(x, dtype=float)
        n = self._n
        if q is not None:
            self._send("robot", self.robot.frame_poses(x, q))
            return
        if x.shape != (13 + 4 * n,):
            raise ValueError(
                f"x: expected a state of length {13 + 4 * n} (13 + 4n), or a base pose (7,) and q, "
                f"given shape {x.shape}"
            )
        base, qs, theta = x[:7], x[7 : 7 + n], x[7 + n : 7 + 2 * n]
        self._send("robot", self.robot.frame_poses(base, qs))
        if self._ghost:
            self._send("ghost", self.robot.frame_poses(base, qs + self.ghost_scale * (theta - qs)))

    def on_rows(self, t: Any, x: Any, u: Any) -> None:
        """A ``simulate(..., on_rows=...)`` callback: shows the newest row."""
        x = np.asarray(x)
        if x.shape[0]:
            self.display(x[-1])

    def play(self, traj: "_core.Trajectory", speed: float = 1.0, fps: float = DEFAULT_FPS) -> None:
        """Plays ``traj`` in real time times ``speed`` (blocks until the end)."""
        if not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"speed: expected a positive number, given {speed!r}")
        rows = frame_rows(traj.t, fps)
        poses = traj.frame_poses()[rows]
        ghost = traj.frame_poses(motor_side=self.ghost_scale)[rows] if self._ghost else None
        t = np.asarray(traj.t)[rows]
        start = time.monotonic()
        for k, row_t in enumerate(t):
            wait = (row_t - t[0]) / speed - (time.monotonic() - start)
            if wait > 0:
                time.sleep(wait)
            self._send("robot", poses[k])
            if ghost is not None:
                self._send("ghost", ghost[k])

    def close(self) -> None:
        """Stops the meshcat server this viewer started (one given by ``zmq_url`` keeps
        running)."""
        process = getattr(self._vis.window, "server_proc", None)
        if process is not None and process.poll() is None:
            process.terminate()
            try:
                process.wait(timeout=10)
            except Exception:  # pragma: no cover - a server that ignores SIGTERM
                process.kill()

    def __enter__(self) -> "Viewer":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _umsgpack(command: Dict[str, Any]) -> bytes:
    import umsgpack  # type: ignore[import-untyped]

    return bytes(umsgpack.packb(command))


def show(
    traj: Optional["_core.Trajectory"] = None,
    robot: Optional["_core.Robot"] = None,
    packages: Optional[Mapping[str, Union[str, Path]]] = None,
    ghost: bool = False,
    speed: float = 1.0,
    zmq_url: Optional[str] = None,
    wait: bool = True,
) -> Viewer:
    """Opens a live viewer on loopback and returns it; prints its URL. With ``traj``, shows its
    first row and plays it (``speed`` × real time), after a browser has opened the page when
    ``wait`` (the default). ``robot`` defaults to ``traj``'s."""
    if robot is None:
        if traj is None:
            raise ValueError("show: give a trajectory, a robot, or both")
        robot = traj.arm.robot
    viewer = Viewer(
        robot,
        packages=packages,
        zmq_url=zmq_url,
        ghost=ghost,
        ghost_scale=ghost_scale(traj) if (ghost and traj is not None) else 1.0,
    )
    print(f"orbitflex viewer: open {viewer.url}", flush=True)
    if traj is not None:
        viewer.display(np.asarray(traj.x)[0])
        if wait:
            viewer._vis.wait()  # until a browser is connected
        viewer.play(traj, speed=speed)
    return viewer


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
