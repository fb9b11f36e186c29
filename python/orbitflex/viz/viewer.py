# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""The live viewer: a meshcat view served on loopback that a script updates
(:class:`Viewer`, :func:`show`)."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Union

import numpy as np

from .. import _core
from . import DEFAULT_FPS, _Array, _axes, _matrix, _meshcat, _scene
from .animation import _umsgpack, frame_rows, ghost_scale

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
