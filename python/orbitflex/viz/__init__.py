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

from .. import _core

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
    m = np.eye(4)
    m[:3, :3] = _core.rotation_matrix(np.asarray(pose[3:7], dtype=float))
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
    extra_frames: Sequence[str] = (),
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
    frame_names = list(robot.frame_names) + list(extra_frames)  # bodies beside the robot (a target)
    for name in frame_names:
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
            link = frame_names[shape["frame"]]
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


# the animation and the live viewer (they use the scene above)
from .animation import (  # noqa: E402
    _PAGE,
    animation_html,
    frame_rows,
    ghost_scale,
    write_animation,
)
from .viewer import Viewer, show  # noqa: E402
