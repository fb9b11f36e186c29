"""``FlexibleArm.simulate`` and the ``Trajectory`` it returns."""

from __future__ import annotations

import csv
import warnings
from functools import cached_property
from typing import Any, Callable, Optional, Union

import numpy as np

from . import _core

__all__ = ["FlexibleArm", "Trajectory", "SimulationError"]


class SimulationError(RuntimeError):
    """A run that stopped early: the state diverged, or the controller failed.

    ``step`` is the index k of the step that failed (from ``t = k dt`` to ``(k+1) dt``) and
    ``time = k dt``; ``trajectory`` holds the k + 1 valid states computed before it.
    """

    def __init__(self, message: str, trajectory: "Trajectory", step: int, time: float):
        super().__init__(message)
        self.trajectory = trajectory
        self.step = step
        self.time = time

    def __reduce__(self):
        # picklable, e.g. to cross multiprocessing in a Monte-Carlo campaign
        return (type(self), (str(self), self.trajectory, self.step, self.time))


class FlexibleArm(_core.FlexibleArm):
    """A floating-base arm with Spong flexible joints (SPEC sections 3-5).

    ``FlexibleArm(robot, joints, method="recursive")``; ``method="operator"`` uses the seed's
    dense operator form (slow; for validation).

    State ``x`` (13+4n): ``[r_B | quat_B (x,y,z,w) | q | theta | omega_B | v_B | qd | theta_dot]``.
    Inputs: motor torques ``u`` (n, link side, N m), base wrench ``f_B`` (6, base frame) and EE
    wrench ``f`` (6, EE frame, the force the EE exerts on its environment).
    """

    def simulate(
        self,
        x0: Any,
        dt: float,
        steps: int,
        u: Union[None, Any, Callable[[float, np.ndarray], Any], _core.MotorPD] = None,
        base_wrench: Optional[Any] = None,
        ee_wrench: Optional[Any] = None,
    ) -> "Trajectory":
        """Integrates ``steps`` RK4 steps of ``dt`` seconds from ``x0``.

        ``u``: None (zero), a constant (n,), a table (steps, n) with one row per step, a callable
        ``u(t, x) -> (n,)`` called once per step, or an ``orbitflex.MotorPD`` (runs entirely in
        Rust without the GIL). ``base_wrench``/``ee_wrench``: None, (6,) or (steps, 6).

        Warns (``RuntimeWarning``) when ``dt`` exceeds the RK4 stability limit of the stiffest
        joint mode. Raises ``SimulationError`` (with ``.trajectory``, the finite part) when the
        state turns non-finite or the controller raises or returns non-finite torques.
        """
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 0:
            raise _core.ModelError(f"steps: expected an integer >= 0, given {steps!r}")
        dt = float(dt)
        if not (np.isfinite(dt) and dt > 0):
            raise _core.ModelError(f"dt: expected a finite step > 0 s, given {dt}")
        x0 = np.asarray(x0, dtype=np.float64)
        if x0.shape != (self.state_size,):
            raise _core.ModelError(f"x0: expected shape ({self.state_size},), given shape {x0.shape}")
        bad = np.flatnonzero(~np.isfinite(x0))
        if bad.size:
            raise _core.ModelError(f"x0: element {bad[0]} is not finite ({x0[bad[0]]})")
        limit, cause = self.rk4_stability_limit(x0[7 : 7 + self.dof]), "stiffest joint mode"
        if isinstance(u, _core.MotorPD) and u.dof == self.dof:
            pd_limit = self._pd_stability_limit(u, x0[7 : 7 + self.dof])
            if pd_limit < limit:
                limit, cause = pd_limit, "motor PD loop (kp stiffens, kd adds a fast pole near -kd/j)"
        if dt > limit:
            warnings.warn(
                f"dt = {dt:g} s exceeds the RK4 stability limit {limit:.4g} s of the {cause}; "
                f"the run will likely diverge",
                RuntimeWarning,
                stacklevel=2,
            )
        t, x, error = self._simulate(x0, dt, int(steps), u, base_wrench, ee_wrench)
        traj = Trajectory(self, t, x)
        if error is not None:
            message, step, time, cause = error
            raise SimulationError(message, traj, step, time) from cause
        return traj


    def __reduce__(self):
        # picklable (with its Robot and FlexibleJoints), e.g. to return trajectories from
        # multiprocessing workers
        return (type(self), (self.robot, self.joints, self.method))

    def _pd_stability_limit(self, pd: _core.MotorPD, q: np.ndarray) -> float:
        """RK4 step limit with the motor PD closed: joint modes stiffened by ``kp`` (SPEC 5's
        estimate with ``k/j`` raised by ``kp/j``) and the real pole ``-(kd + beta)/j``, stable while
        ``|lambda dt| < 2.785``."""
        k, j, _, beta = self.parameters
        m = np.diag(self.robot.mass_matrix(q))[6:]
        omega = np.sqrt(k * (1 / j + 1 / m) + pd.kp / j).max()
        fast = ((pd.kd + beta) / j).max()
        limits = [2 * np.sqrt(2) / omega if omega > 0 else np.inf, 2.785 / fast if fast > 0 else np.inf]
        return float(min(limits))


class Trajectory:
    """States of a run: ``t`` (k,) and ``x`` (k, 13+4n), k = steps + 1 for a complete run.

    Views (no copy): ``base_pose``, ``q``, ``theta``, ``base_twist``, ``qd``, ``theta_dot``.
    Derived: ``deflection`` (theta - q), ``spring_torque``. Diagnostics computed in Rust on first
    access: ``momentum`` (k, 6), ``energy`` (k,), ``ee_pose`` (k, 7).
    """

    def __init__(self, arm: FlexibleArm, t: np.ndarray, x: np.ndarray):
        self.arm = arm
        self.t = t
        self.x = x
        self._n = arm.dof

    def __len__(self) -> int:
        return len(self.t)

    def __reduce__(self):
        return (type(self), (self.arm, self.t, self.x))

    def __repr__(self) -> str:
        return f"Trajectory(states={len(self)}, t_end={self.t[-1] if len(self) else 0.0:g} s, dof={self._n})"

    @property
    def base_pose(self) -> np.ndarray:
        """``[r_B (3); quat_B (x, y, z, w)]`` per state, (k, 7)."""
        return self.x[:, 0:7]

    @property
    def q(self) -> np.ndarray:
        """Link angles (rad), (k, n)."""
        return self.x[:, 7 : 7 + self._n]

    @property
    def theta(self) -> np.ndarray:
        """Motor angles, link side (rad), (k, n)."""
        return self.x[:, 7 + self._n : 7 + 2 * self._n]

    @property
    def base_twist(self) -> np.ndarray:
        """``[omega_B; v_B]`` in base-frame components, (k, 6)."""
        return self.x[:, 7 + 2 * self._n : 13 + 2 * self._n]

    @property
    def qd(self) -> np.ndarray:
        """Link rates (rad/s), (k, n)."""
        return self.x[:, 13 + 2 * self._n : 13 + 3 * self._n]

    @property
    def theta_dot(self) -> np.ndarray:
        """Motor rates (rad/s), (k, n)."""
        return self.x[:, 13 + 3 * self._n : 13 + 4 * self._n]

    @property
    def deflection(self) -> np.ndarray:
        """Joint deflection ``theta - q`` (rad), (k, n)."""
        return self.theta - self.q

    @property
    def spring_torque(self) -> np.ndarray:
        """``k (theta - q) + d (theta_dot - qd)`` (N m), (k, n)."""
        k, _, d, _ = self.arm.parameters
        return self.deflection * k + (self.theta_dot - self.qd) * d

    @cached_property
    def momentum(self) -> np.ndarray:
        """Total momentum ``[angular; linear]`` in the inertial frame about its origin, (k, 6)."""
        return self.arm._along(self.x, "momentum")

    @cached_property
    def energy(self) -> np.ndarray:
        """Total energy (SPEC 6.2): rigid kinetic + motor kinetic + spring (J), (k,)."""
        return self.arm._along(self.x, "energy")

    @cached_property
    def ee_pose(self) -> np.ndarray:
        """EE ``[position; quaternion (x, y, z, w)]`` in the inertial frame, (k, 7)."""
        return self.arm._along(self.x, "ee_pose")

    def column_names(self) -> list:
        """Names of the columns of ``x``, in order."""
        joints = self.arm.robot.joint_names
        return (
            ["r_x", "r_y", "r_z", "quat_x", "quat_y", "quat_z", "quat_w"]
            + [f"q[{j}]" for j in joints]
            + [f"theta[{j}]" for j in joints]
            + ["omega_x", "omega_y", "omega_z", "v_x", "v_y", "v_z"]
            + [f"qd[{j}]" for j in joints]
            + [f"theta_dot[{j}]" for j in joints]
        )

    def save_npz(self, path) -> None:
        """Writes ``t``, ``x``, ``columns``, ``momentum``, ``energy`` and ``ee_pose`` to ``.npz``."""
        np.savez(
            path,
            t=self.t,
            x=self.x,
            columns=np.array(self.column_names()),
            momentum=self.momentum,
            energy=self.energy,
            ee_pose=self.ee_pose,
        )

    def save_csv(self, path) -> None:
        """Writes one row per state, with a header naming each column (``t`` then ``x``)."""
        with open(path, "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(["t"] + self.column_names())
            for t, row in zip(self.t, self.x):
                writer.writerow([repr(float(t))] + [repr(float(v)) for v in row])
