"""Structural modes, frequency response and state-space models of the flexible arm on its
floating base, about a state (the docs' ``modes.md`` page).

The computations run in Rust (``orbitflex::analysis``); this module gives them their Python
shape. It adds three methods to :class:`orbitflex.FlexibleArm` (the class lives in the compiled
module; the methods are defined here and attached when ``orbitflex`` is imported):

- ``arm.modes(x, u=None, base="free", motors="free", *, damping=True)`` -> :class:`Modes`;
- ``arm.frequency_response(x, freqs_hz, inputs="motor_torque", outputs="q", u=None,
  base="free", motors="free")`` -> complex array (frequencies, outputs, inputs);
- ``arm.state_space(x, u=None, inputs="motor_torque", outputs="q", base="free",
  motors="free")`` -> :class:`StateSpace`, with ``.to_control()`` (python-control) and
  ``.savemat(path)`` (scipy), both from the optional extra ``orbitflex[analysis]``;

and :func:`sweep`, the modes across many configurations in one call, in parallel.

Conventions. ``base="free"`` floats, ``"held"`` is clamped inertially (the state must have a zero
base twist). ``motors="free"`` keeps the motor torques at their values (or closes the loop with
``u=MotorPD(...)``); ``"clamped"`` holds ``θ`` (brakes on; ``θ̇`` must be zero). ``u`` may also be
None or an (n,) torque array, which do not change the linear model (torques enter linearly).
Inputs by name: ``motor_torque`` (N·m, link side), ``theta_ref`` (rad, the PD's reference),
``base_wrench`` (``[moment (N·m); force (N)]``, base frame), ``ee_wrench`` (the same, exerted by
each end-effector, in its frame). Outputs by name: ``q``, ``theta``, ``deflection`` (rad),
``spring_torque`` (N·m), ``ee_position`` (m, inertial), ``base_attitude`` (rad, small angles about
the base axes), ``base_position`` (m, inertial), ``base_rate`` (rad/s, the bus's angular velocity,
base frame).

Reaction wheels. On an arm built with ``wheels=ReactionWheels(...)`` the states end with the k
wheel speeds ``δΩ`` (rad/s relative to the bus, as ``arm.state_slices["wheel_speed"]``), the input
``wheel_torque`` (k, N·m commanded to each wheel about its axis; the bus feels the opposite) and
the output ``wheel_speed`` (k, rad/s) exist, and an ``AttitudePD`` closes the bus's attitude loop:
``u=AttitudePD(...)``, ``u=(MotorPD(...), AttitudePD(...))``, or ``wheel_torque=AttitudePD(...)``
as in :meth:`FlexibleArm.simulate`. The linear model leaves the wheels' torque and speed limits
out; a state with a wheel at its speed limit is refused.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import _core
from ._core import AttitudePD, FlexibleArm, MotorPD

Array = npt.NDArray[np.float64]
ComplexArray = npt.NDArray[np.complex128]
Names = Union[str, Sequence[str]]

__all__ = ["Modes", "StateSpace", "Sweep", "SampledLoop", "sweep", "closed_loop_modes", "sampled_loop"]


def _names(value: Names, what: str) -> List[str]:
    if isinstance(value, str):
        return [value]
    names = list(value)
    if not all(isinstance(v, str) for v in names):
        raise _core.ModelError(f"{what}: expected a name or a list of names, given {value!r}")
    return names


def _spec(u: Any, base: str, motors: str, inputs: Names = (), outputs: Names = (),
          damping: bool = True, wheel_torque: Any = None) -> Dict[str, Any]:
    return {"u": u, "wheel_torque": wheel_torque, "base": base, "motors": motors,
            "inputs": _names(inputs, "inputs"), "outputs": _names(outputs, "outputs"),
            "damping": bool(damping)}


def _closed(u: Any, wheel_torque: Any) -> bool:
    """Whether a feedback closes the loop: a MotorPD or an AttitudePD, alone or in a pair."""
    items = list(u) if isinstance(u, (tuple, list)) else [u]
    return any(isinstance(c, (MotorPD, AttitudePD)) for c in items + [wheel_torque])


@dataclass(frozen=True)
class Modes:
    """The structural modes of the arm about a state (rigid-body modes separated out).

    ``frequency_hz`` (m,): damped natural frequencies ``Im λ / 2π`` of the oscillatory modes,
    ascending; ``natural_frequency_hz``: ``|λ| / 2π``; ``damping_ratio``: ``−Re λ / |λ|``.
    ``shapes`` (tangent_size, m), complex, in the tangent layout ``[δr_B | δφ_B | δq | δθ | δω_B |
    δv_B | δq̇ | δθ̇]``: the displacement part has unit modal mass, its heaviest component is real
    and positive, and the rates are ``λ`` times the displacements. ``rigid_body``: the number of
    rigid-body modes (the null space of the stiffness). ``eigenvalues``: every eigenvalue of the
    model's state matrix (1/s). ``wheel_spin``: the number of reaction wheels' free spins separated
    out (k: a wheel speed has no angle in the state, so each adds one eigenvalue, zero or its
    friction's decay, not a pair). ``overdamped``: real eigenvalues (1/s) of structural modes damped
    past critical. ``damped``: True for the state matrix's modes, False for the undamped pencil
    ``(K, M)``. ``spring_energy`` (m, n): each spring's share ``k_i |δθ_i − δq_i|²`` of the mode's
    spring energy.
    """

    frequency_hz: Array
    natural_frequency_hz: Array
    damping_ratio: Array
    shapes: ComplexArray
    rigid_body: int
    eigenvalues: ComplexArray
    overdamped: Array
    damped: bool
    spring_energy: Array
    joint_names: List[str]
    base: str
    motors: str
    closed_loop: bool
    wheel_spin: int = 0

    def __len__(self) -> int:
        return len(self.frequency_hz)

    @property
    def dominant_joints(self) -> List[str]:
        """For each mode, the joint whose spring holds most of its energy."""
        return [self.joint_names[int(i)] for i in np.argmax(self.spring_energy, axis=1)] if len(self) else []

    def table(self, count: Optional[int] = None) -> str:
        """The modes as a text table: frequency, damping ratio and the dominant spring."""
        loop = ", closed loop" if self.closed_loop else ""
        kind = "damped" if self.damped else "undamped"
        lines = [f"{len(self)} structural modes ({kind}; base {self.base}, motors {self.motors}{loop}); "
                 f"{self.rigid_body} rigid-body modes separated out"
                 + (f", and {self.wheel_spin} wheel spins" if self.wheel_spin else ""),
                 f"{'mode':>4}  {'f (Hz)':>10}  {'f_n (Hz)':>10}  {'zeta':>7}  dominant spring"]
        shown = len(self) if count is None else min(count, len(self))
        for i in range(shown):
            share = self.spring_energy[i].max() * 100
            lines.append(f"{i + 1:>4}  {self.frequency_hz[i]:>10.4g}  {self.natural_frequency_hz[i]:>10.4g}  "
                         f"{self.damping_ratio[i]:>7.4f}  {self.dominant_joints[i]} ({share:.0f} %)")
        if len(self.overdamped):
            lines.append(f"and {len(self.overdamped)} overdamped (real) eigenvalues: "
                         + ", ".join(f"{v:.4g}" for v in self.overdamped) + " 1/s")
        return "\n".join(lines)


def _modes_from(d: Dict[str, Any], arm: FlexibleArm, base: str, motors: str, closed: bool) -> Modes:
    n = arm.dof
    shapes = d["shapes"]
    deflection = shapes[6 + n:6 + 2 * n] - shapes[6:6 + n]
    energy = arm.parameters[0][:, None] * np.abs(deflection) ** 2
    total = energy.sum(axis=0)
    share = (energy / np.where(total > 0, total, 1.0)).T
    return Modes(frequency_hz=d["frequency_hz"], natural_frequency_hz=d["natural_frequency_hz"],
                 damping_ratio=d["damping_ratio"], shapes=shapes, rigid_body=int(d["rigid_body"]),
                 eigenvalues=d["eigenvalues"], overdamped=d["overdamped"], damped=bool(d["damped"]),
                 spring_energy=share, joint_names=list(arm.robot.joint_names), base=base, motors=motors,
                 closed_loop=closed, wheel_spin=int(d["wheel_spin"]))


def _modes(self: FlexibleArm, x: npt.ArrayLike, u: Any = None, base: str = "free", motors: str = "free",
           *, damping: bool = True, wheel_torque: Any = None) -> Modes:
    """The structural modes about the state ``x`` (13+4n,): see :class:`Modes`.

    ``damping=True`` (default): eigenvalues and eigenvectors of the linear model's state matrix,
    with the joints' damping, motor friction and a ``MotorPD``'s gains (``u``): valid at any
    state. ``damping=False``: the undamped modes ``K φ = ω² M φ`` at ``x``'s configuration (springs
    and a PD's ``kp``; damping, velocities and preload ignored), real shapes. Without damping, at
    rest, both give the same modes. ``base``: ``"free"`` or ``"held"``; ``motors``: ``"free"`` or
    ``"clamped"`` (brakes on). ``u``: None, torques, a ``MotorPD``, an ``AttitudePD`` (arm with
    wheels) or a pair of them; ``wheel_torque``: an ``AttitudePD`` or None (see the module docs).
    An attitude loop's ``kp`` holds the bus's rotation: its three rigid-body modes become the
    attitude loop's modes, reported with the structural ones.
    """
    d = _core._modes(self, x, _spec(u, base, motors, damping=damping, wheel_torque=wheel_torque))
    return _modes_from(d, self, base, motors, _closed(u, wheel_torque))


def _frequency_response(self: FlexibleArm, x: npt.ArrayLike, freqs_hz: npt.ArrayLike, inputs: Names = "motor_torque",
                        outputs: Names = "q", u: Any = None, base: str = "free",
                        motors: str = "free", *, wheel_torque: Any = None) -> ComplexArray:
    """``H(j 2π f) = C (j 2π f I − A)⁻¹ B`` at each frequency of ``freqs_hz`` (Hz, ≥ 0): a complex
    array (len(freqs_hz), n_out, n_in), in the units of the outputs per unit of the inputs (e.g.
    rad/(N·m)). ``inputs``/``outputs``: a group name or a list of them (see the module docs; the
    channels' names are ``arm.state_space(...).inputs``/``.outputs``). By Laub's method: one
    Hessenberg reduction, then one Hessenberg solve per frequency, without the GIL. A frequency
    at a pole on the imaginary axis (0 Hz with a floating base or free motors) is an error.
    """
    return _core._frequency_response(self, x, freqs_hz,
                                     _spec(u, base, motors, inputs, outputs, wheel_torque=wheel_torque))


def _state_space(self: FlexibleArm, x: npt.ArrayLike, u: Any = None, inputs: Names = "motor_torque",
                 outputs: Names = "q", base: str = "free", motors: str = "free", *,
                 wheel_torque: Any = None) -> StateSpace:
    """The linear model ``d(dx)/dt = A dx + B du``, ``dy = C dx + D du`` about ``x``, with named
    states, inputs and outputs (:class:`StateSpace`). The states are the tangent's elements the
    model keeps (12+4n+k free/free, k wheels; no ``θ, θ̇`` clamped; no base pose and twist held).
    """
    d = _core._state_space(self, x, _spec(u, base, motors, inputs, outputs, wheel_torque=wheel_torque))
    return StateSpace(A=d["A"], B=d["B"], C=d["C"], D=d["D"], states=d["states"], inputs=d["inputs"],
                      outputs=d["outputs"], tangent_index=np.asarray(d["tangent_index"], dtype=np.intp),
                      x=np.array(x, dtype=float), model=self.robot.name, base=base, motors=motors)


@dataclass(frozen=True)
class StateSpace:
    """A linear model about the state ``x``: ``A`` (s×s), ``B`` (s×m), ``C`` (p×s), ``D`` (p×m),
    with the names of its ``states``, ``inputs`` and ``outputs``; ``tangent_index[i]`` is where
    state ``i`` sits in the tangent (12+4n+k)."""

    A: Array
    B: Array
    C: Array
    D: Array
    states: List[str]
    inputs: List[str]
    outputs: List[str]
    tangent_index: npt.NDArray[np.intp]
    x: Array
    model: str
    base: str
    motors: str
    name: str = field(default="")

    def to_control(self) -> Any:
        """A python-control ``StateSpace`` with the same names (``pip install 'orbitflex[analysis]'``)."""
        try:
            import control  # type: ignore[import-untyped,import-not-found,unused-ignore]
        except ImportError as e:
            raise ImportError(f"StateSpace.to_control needs python-control ({e}); "
                              "pip install 'orbitflex[analysis]'") from None
        return control.ss(self.A, self.B, self.C, self.D, states=self.states, inputs=self.inputs,
                          outputs=self.outputs, name=self.name or f"{self.model}_{self.base}_{self.motors}")

    def savemat(self, path: Union[str, Path]) -> Path:
        """Writes a MATLAB ``.mat`` file (scipy; ``pip install 'orbitflex[analysis]'``) with ``A``,
        ``B``, ``C``, ``D``, the names as cell arrays (``StateName``, ``InputName``, ``OutputName``),
        the operating point ``x0`` and ``model``, ``base``, ``motors``. In MATLAB:
        ``s = load(path); sys = ss(s.A, s.B, s.C, s.D, 'StateName', s.StateName, 'InputName',
        s.InputName, 'OutputName', s.OutputName)``. Returns the path."""
        try:
            from scipy.io import savemat  # type: ignore[import-untyped,import-not-found,unused-ignore]
        except ImportError as e:
            raise ImportError(f"StateSpace.savemat needs scipy ({e}); pip install 'orbitflex[analysis]'") from None
        path = Path(path)

        def cell(names: List[str]) -> npt.NDArray[np.object_]:
            out = np.empty((len(names), 1), dtype=object)
            out[:, 0] = names
            return out

        savemat(str(path), {"A": self.A, "B": self.B, "C": self.C, "D": self.D,
                            "StateName": cell(self.states), "InputName": cell(self.inputs),
                            "OutputName": cell(self.outputs), "x0": self.x, "model": self.model,
                            "base": self.base, "motors": self.motors}, do_compression=True)
        return path


@dataclass(frozen=True)
class Sweep:
    """The modes across configurations: ``frequency_hz``, ``natural_frequency_hz`` and
    ``damping_ratio`` are (N, count), NaN where a configuration has fewer oscillatory modes;
    ``rigid_body`` (N,); ``modes`` the full :class:`Modes` of each configuration."""

    configurations: Array
    frequency_hz: Array
    natural_frequency_hz: Array
    damping_ratio: Array
    rigid_body: npt.NDArray[np.int64]
    modes: List[Modes]


def sweep(arm: FlexibleArm, configurations: npt.ArrayLike, *, u: Any = None, base: str = "free",
          motors: str = "free", damping: bool = True, count: Optional[int] = None,
          threads: Optional[int] = None, wheel_torque: Any = None) -> Sweep:
    """The first ``count`` modes (default: all) at each of ``configurations``, in one call,
    in parallel over ``threads`` threads (default every core) without the GIL.

    ``configurations``: (N, n) link angles (rad; each at rest with relaxed springs, base at the
    origin) or (N, 13+4n) full states. The rest as :meth:`FlexibleArm.modes`.
    """
    n = arm.dof
    q = np.asarray(configurations, dtype=float)
    if q.ndim != 2 or q.shape[1] not in (n, arm.state_size):
        raise _core.ModelError(f"configurations: expected shape (N, {n}) (angles) or (N, {arm.state_size}) "
                               f"(states), given shape {q.shape}")
    states = q if q.shape[1] == arm.state_size else np.array([arm.state(q=row) for row in q]).reshape(-1, arm.state_size)
    if threads is not None and (not isinstance(threads, int) or threads < 1):
        raise _core.ModelError(f"threads: expected an integer >= 1 or None, given {threads!r}")
    rows = _core._sweep(arm, states, _spec(u, base, motors, damping=damping, wheel_torque=wheel_torque), threads)
    modes = [_modes_from(d, arm, base, motors, _closed(u, wheel_torque)) for d in rows]
    width = max([len(m) for m in modes] + [0]) if count is None else count

    def table(name: str) -> Array:
        out = np.full((len(modes), width), np.nan)
        for i, m in enumerate(modes):
            values = getattr(m, name)[:width]
            out[i, :len(values)] = values
        return out

    return Sweep(configurations=q, frequency_hz=table("frequency_hz"),
                 natural_frequency_hz=table("natural_frequency_hz"), damping_ratio=table("damping_ratio"),
                 rigid_body=np.array([m.rigid_body for m in modes], dtype=np.int64), modes=modes)


def closed_loop_modes(arm: FlexibleArm, x: npt.ArrayLike, pd: Any, count: int = 3,
                      base: str = "free") -> Tuple[Modes, str]:
    """The closed-loop modes of ``arm`` under ``pd`` at ``x`` (a ``MotorPD``, an ``AttitudePD`` on
    the wheels, or a pair of them), and a line naming the first ``count`` of them, e.g.
    ``"first closed-loop modes: 0.46 Hz (ζ 0.13, shoulder_pitch), …"`` (for a summary such as the
    demo's)."""
    modes = arm.modes(x, u=pd, base=base)
    parts = [f"{f:.3g} Hz (ζ {z:.2f}, {j})" for f, z, j in
             zip(modes.frequency_hz[:count], modes.damping_ratio[:count], modes.dominant_joints[:count])]
    return modes, f"first closed-loop modes ({base} base): " + ", ".join(parts)


@dataclass(frozen=True)
class SampledLoop:
    """A controller run at its own rate, closed around the linear model (:func:`sampled_loop`).

    ``spectral_radius``: of the loop's one-period matrix (plant discretised with zero-order hold
    at the period, the delay's samples in flight as extra states); ``threshold``: the largest
    stable value (1 plus 1e-6, times the continuous loop's own growth at a moving state);
    ``unstable``: ``spectral_radius > threshold``; ``eigenvalues`` (complex); ``period`` (s),
    ``rate_hz``, ``delay`` (samples) and ``controller`` (``"MotorPD"`` or ``"AttitudePD"``)."""

    spectral_radius: float
    threshold: float
    unstable: bool
    eigenvalues: ComplexArray
    period: float
    rate_hz: float
    delay: int
    controller: str


def sampled_loop(arm: FlexibleArm, x: npt.ArrayLike, controller: Any, u: Any = None, base: str = "free",
                 motors: str = "free", *, wheel_torque: Any = None) -> SampledLoop:
    """The discrete loop of ``controller``, a ``Sampled(MotorPD(...) | AttitudePD(...), rate_hz,
    delay)``, about the state ``x``: the linear model (``base``, ``motors``; ``u`` and
    ``wheel_torque``: the loops that run at every RK4 step, closed in, as in
    :meth:`FlexibleArm.modes`) discretised with zero-order hold at ``1/rate_hz``, the controller's
    gain applied ``delay`` samples late. ``simulate`` warns when this loop is unstable.
    """
    d = _core._sampled_loop(arm, x, _spec(u, base, motors, wheel_torque=wheel_torque), controller)
    return SampledLoop(spectral_radius=float(d["spectral_radius"]), threshold=float(d["threshold"]),
                       unstable=bool(d["unstable"]), eigenvalues=d["eigenvalues"], period=float(d["period"]),
                       rate_hz=float(d["rate_hz"]), delay=int(d["delay"]), controller=str(d["controller"]))


FlexibleArm.modes = _modes  # type: ignore[method-assign]
FlexibleArm.frequency_response = _frequency_response  # type: ignore[method-assign]
FlexibleArm.state_space = _state_space  # type: ignore[method-assign]
