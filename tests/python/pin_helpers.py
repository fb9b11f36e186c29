"""Pinocchio as the oracle, put in orbitflex's conventions (docs/model.md, "Relation to Pinocchio").

Everything here is Pinocchio plus index bookkeeping; nothing is taken from orbitflex except the
joint names (used to match joints, so a wrong ordering in orbitflex would show as a mismatch of
names, not be hidden).

Convention map (orbitflex <- Pinocchio):
- base twist ``[ω; v]`` <- Pinocchio's free-flyer velocity ``[v; ω]`` (both base-frame);
- classical base acceleration ``α_B = [ω̇; a_lin + ω × v]`` <- Pinocchio's ``a = [a_lin; ω̇]``;
- base wrench ``f_B = [n; F]`` <- Pinocchio's generalized force ``[F; n]``;
- EE wrench ``f`` (exerted BY the EE, EE frame) -> ``fext[parent joint] = placement.act(-f)``;
- continuous joints take ``(cos q, sin q)`` in Pinocchio's configuration.
"""

from __future__ import annotations

import glob
import os
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
import pinocchio as pin

__all__ = [
    "robots_dir",
    "PinRobot",
    "rel_err",
    "quat_to_matrix",
    "random_quaternion",
]


def rel_err(value, reference) -> float:
    """``‖value − reference‖ / max(1, ‖reference‖)`` (Frobenius for matrices)."""
    value = np.asarray(value, dtype=float)
    reference = np.asarray(reference, dtype=float)
    assert value.shape == reference.shape, (value.shape, reference.shape)
    return float(np.linalg.norm(value - reference) / max(1.0, np.linalg.norm(reference)))


def robots_dir() -> str:
    """The ``robots`` folder of example-robot-data (Python module if present, else cmeel prefix)."""
    try:  # the classic Python module
        import example_robot_data  # type: ignore

        # getModelPath(subpath) returns the folder that holds subpath.
        d = example_robot_data.getModelPath("ur_description/urdf/ur5_robot.urdf")
        if os.path.isdir(os.path.join(d, "ur_description")):
            return d
    except Exception:
        pass
    candidates = []
    # The cmeel wheel installs it under <site-packages>/cmeel.prefix/share/example-robot-data.
    pin_dir = os.path.dirname(os.path.abspath(pin.__file__))
    probe = pin_dir
    for _ in range(6):
        probe = os.path.dirname(probe)
        candidates.append(os.path.join(probe, "share", "example-robot-data", "robots"))
    import sys

    for p in sys.path:
        candidates.append(os.path.join(p, "cmeel.prefix", "share", "example-robot-data", "robots"))
    candidates += glob.glob("/opt/openrobots/share/example-robot-data/robots")
    for c in candidates:
        if os.path.isdir(os.path.join(c, "ur_description")):
            return c
    raise FileNotFoundError("example-robot-data's robots folder not found")


def quat_to_matrix(quat) -> np.ndarray:
    """Rotation of the (x, y, z, w) quaternion, after normalising it."""
    x, y, z, w = np.asarray(quat, dtype=float) / np.linalg.norm(quat)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def random_quaternion(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


@dataclass
class _JointSlot:
    name: str
    idx_q: int
    idx_v: int
    nq: int


class PinRobot:
    """A Pinocchio model of a URDF with a free-flyer root, zero gravity, and orbitflex's ordering.

    ``joint_names``: orbitflex's order of the degrees of freedom (matched by name).
    """

    def __init__(
        self,
        joint_names: Sequence[str],
        ee_link: str,
        path: Optional[str] = None,
        xml: Optional[str] = None,
        locked_joints: Optional[Sequence[str]] = None,
    ):
        if (path is None) == (xml is None):
            raise ValueError("give exactly one of path and xml")
        if path is not None:
            model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())
        else:
            model = pin.buildModelFromXML(xml, pin.JointModelFreeFlyer())
        if locked_joints:
            ids = [model.getJointId(name) for name in locked_joints]
            assert all(i < model.njoints for i in ids), f"unknown locked joint in {locked_joints}"
            model = pin.buildReducedModel(model, ids, pin.neutral(model))
        model.gravity = pin.Motion.Zero()
        self.model = model
        self.data = model.createData()
        assert model.existFrame(ee_link), f"Pinocchio has no frame {ee_link!r}"
        self.ee_frame = model.getFrameId(ee_link)
        self.n = len(joint_names)
        assert model.nv == 6 + self.n, (model.nv, self.n)
        assert model.joints[1].shortname() == "JointModelFreeFlyer"
        self.slots = []
        for name in joint_names:
            jid = model.getJointId(name)
            assert jid < model.njoints, f"Pinocchio has no joint {name!r}"
            j = model.joints[jid]
            assert j.nv == 1 and j.nq in (1, 2), (name, j.shortname())
            self.slots.append(_JointSlot(name, j.idx_q, j.idx_v, j.nq))
        # perm[k] = Pinocchio velocity index of orbitflex's generalized velocity k.
        self.perm = np.array([3, 4, 5, 0, 1, 2] + [s.idx_v for s in self.slots])
        assert sorted(self.perm) == list(range(model.nv))

    # ---------------------------------------------------------------- mapping
    def q_pin(self, q, base_pose=None) -> np.ndarray:
        """Pinocchio configuration: base pose (default identity) then joints (cos/sin if nq = 2)."""
        qp = pin.neutral(self.model)
        if base_pose is not None:
            qp[0:7] = base_pose
        for s, qi in zip(self.slots, np.asarray(q, dtype=float)):
            if s.nq == 1:
                qp[s.idx_q] = qi
            else:
                qp[s.idx_q] = np.cos(qi)
                qp[s.idx_q + 1] = np.sin(qi)
        return qp

    def to_pin_vec(self, x) -> np.ndarray:
        """An orbitflex-ordered (6+n) vector ([angular; linear] base part) in Pinocchio's order."""
        out = np.zeros(self.model.nv)
        out[self.perm] = x
        return out

    def from_pin_vec(self, x) -> np.ndarray:
        return np.asarray(x)[self.perm]

    def from_pin_mat(self, m) -> np.ndarray:
        return np.asarray(m)[np.ix_(self.perm, self.perm)]

    def v_pin(self, base_twist, qd) -> np.ndarray:
        return self.to_pin_vec(np.concatenate([base_twist, qd]))

    def fext(self, ee_wrench) -> list:
        """External forces ON the bodies: ``-f`` at the EE frame, moved to its parent joint."""
        fext = [pin.Force.Zero() for _ in range(self.model.njoints)]
        if ee_wrench is not None:
            f = np.asarray(ee_wrench, dtype=float)
            frame = self.model.frames[self.ee_frame]
            on_body = pin.Force(-f[3:6], -f[0:3])  # Force(linear, angular)
            fext[frame.parentJoint] = frame.placement.act(on_body)
        return fext

    # ---------------------------------------------------------------- quantities
    def mass_matrix(self, q) -> np.ndarray:
        m = pin.crba(self.model, self.data, self.q_pin(q)).copy()
        m = np.triu(m) + np.triu(m, 1).T
        return self.from_pin_mat(m)

    def _a_pin(self, base_twist, base_acc, qdd) -> np.ndarray:
        """Pinocchio acceleration from orbitflex's classical ``α_B`` and ``q̈``."""
        w, v = np.asarray(base_twist[:3]), np.asarray(base_twist[3:])
        alpha = np.asarray(base_acc, dtype=float)
        spatial = np.concatenate([alpha[:3], alpha[3:] - np.cross(w, v)])
        return self.to_pin_vec(np.concatenate([spatial, qdd]))

    def bias_forces(self, q, base_twist, qd) -> np.ndarray:
        a = self._a_pin(base_twist, np.zeros(6), np.zeros(self.n))
        tau = pin.rnea(self.model, self.data, self.q_pin(q), self.v_pin(base_twist, qd), a)
        return self.from_pin_vec(tau)

    def inverse_dynamics(self, q, base_twist, qd, base_acc, qdd, ee_wrench=None) -> np.ndarray:
        """``[f_B; τ]`` with ``f_B = [moment; force]``."""
        a = self._a_pin(base_twist, base_acc, qdd)
        tau = pin.rnea(
            self.model, self.data, self.q_pin(q), self.v_pin(base_twist, qd), a, self.fext(ee_wrench)
        )
        return self.from_pin_vec(tau)

    def pin_acceleration(self, q, base_twist, qd, tau, base_wrench=None, ee_wrench=None, base_pose=None):
        """Pinocchio's ``aba`` output (its own order and meaning: spatial base acceleration)."""
        fb = np.zeros(6) if base_wrench is None else np.asarray(base_wrench, dtype=float)
        gen = self.to_pin_vec(np.concatenate([fb, tau]))
        return pin.aba(
            self.model, self.data, self.q_pin(q, base_pose), self.v_pin(base_twist, qd), gen,
            self.fext(ee_wrench),
        ).copy()

    def forward_dynamics(self, q, base_twist, qd, tau, base_wrench=None, ee_wrench=None) -> np.ndarray:
        """``[α_B (classical); q̈]``."""
        a = self.from_pin_vec(self.pin_acceleration(q, base_twist, qd, tau, base_wrench, ee_wrench))
        w, v = np.asarray(base_twist[:3]), np.asarray(base_twist[3:])
        a[3:6] += np.cross(w, v)
        return a

    def ee_jacobians(self, q):
        """``(J, Φ_{n+1,B})`` from the LOCAL frame Jacobian, rows reordered to ``[ω; v]``."""
        jac = pin.computeFrameJacobian(self.model, self.data, self.q_pin(q), self.ee_frame, pin.LOCAL)
        jac = np.vstack([jac[3:6], jac[0:3]])[:, self.perm]
        return jac[:, 6:], jac[:, :6]

    def ee_placement(self, q, base_pose=None) -> pin.SE3:
        pin.framesForwardKinematics(self.model, self.data, self.q_pin(q, base_pose))
        return self.data.oMf[self.ee_frame].copy()

    def momentum(self, base_pose, q, base_twist, qd) -> np.ndarray:
        """``[angular about the inertial origin; linear]`` in inertial axes."""
        hg = pin.computeCentroidalMomentum(
            self.model, self.data, self.q_pin(q, base_pose), self.v_pin(base_twist, qd)
        )
        c = self.data.com[0].copy()
        lin = hg.linear.copy()
        ang = hg.angular + np.cross(c, lin)
        return np.concatenate([ang, lin])

    def kinetic_energy(self, q, base_twist, qd) -> float:
        return float(
            pin.computeKineticEnergy(self.model, self.data, self.q_pin(q), self.v_pin(base_twist, qd))
        )


def skew(p) -> np.ndarray:
    x, y, z = p
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _joint_columns(robot: PinRobot) -> np.ndarray:
    return robot.perm[6:]


def rnea_derivatives(robot: PinRobot, q, base_twist, qd, base_acc, qdd, ee_wrench=None) -> dict:
    """Pinocchio's ``computeRNEADerivatives`` in orbitflex's conventions: ``q`` (6+n, n),
    ``v`` (6+n, 6+n) with the classical base acceleration held, ``a`` (the mass matrix)."""
    a = robot._a_pin(base_twist, base_acc, qdd)
    dq, dv, da = pin.computeRNEADerivatives(
        robot.model, robot.data, robot.q_pin(q), robot.v_pin(base_twist, qd), a, robot.fext(ee_wrench)
    )
    perm = robot.perm
    da = np.triu(da) + np.triu(da, 1).T
    out_a = da[np.ix_(perm, perm)]
    out_v = np.asarray(dv)[np.ix_(perm, perm)].copy()
    # Pinocchio holds its spatial base acceleration a_lin = α_lin − ω × v fixed; orbitflex holds
    # α_B: d a_lin/dω = [v]×, d a_lin/dv = −[ω]×, through ∂ID/∂a (the mass matrix's columns).
    w, v = np.asarray(base_twist[:3]), np.asarray(base_twist[3:])
    out_v[:, 0:3] += out_a[:, 3:6] @ skew(v)
    out_v[:, 3:6] += out_a[:, 3:6] @ (-skew(w))
    return dict(q=np.asarray(dq)[np.ix_(perm, _joint_columns(robot))], v=out_v, a=out_a)


def aba_derivatives(robot: PinRobot, q, base_twist, qd, tau, base_wrench=None, ee_wrench=None) -> dict:
    """Pinocchio's ``computeABADerivatives`` in orbitflex's conventions: ``q``, ``v`` (with the
    classical base acceleration α_lin = a_lin + ω × v), ``tau`` and ``base_wrench``."""
    fb = np.zeros(6) if base_wrench is None else np.asarray(base_wrench, dtype=float)
    gen = robot.to_pin_vec(np.concatenate([fb, tau]))
    dq, dv, dtau = pin.computeABADerivatives(
        robot.model, robot.data, robot.q_pin(q), robot.v_pin(base_twist, qd), gen, robot.fext(ee_wrench)
    )
    perm = robot.perm
    out_v = np.asarray(dv)[np.ix_(perm, perm)].copy()
    w, v = np.asarray(base_twist[:3]), np.asarray(base_twist[3:])
    out_v[3:6, 0:3] += -skew(v)
    out_v[3:6, 3:6] += skew(w)
    minv = np.asarray(dtau)[np.ix_(perm, perm)]
    return dict(
        q=np.asarray(dq)[np.ix_(perm, _joint_columns(robot))],
        v=out_v,
        tau=minv[:, 6:],
        base_wrench=minv[:, :6],
    )
