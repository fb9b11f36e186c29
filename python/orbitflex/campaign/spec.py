# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
# (pandas, Dask and their stubs come with orbitflex[campaign]: a base install type-checks clean)
"""The campaign as a value: :class:`Campaign`, its nominal slew and dispersions, and how its runs
are set up and run, locally and on Dask."""

from __future__ import annotations

import math
import os
import socket
import time
import uuid
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, TYPE_CHECKING, Tuple, Union

import numpy as np

from .. import (AttitudePD, FlexibleArm, FlexibleJoints, ModelError, MotorPD, Plan, ReactionWheels, Robot, Trajectory,
                models, quintic_reference, simulate_batch)
from . import wheels as bus
from .dispersion import CampaignError, Dispersion, JOINT_PARAMETERS, POSITIVE, UNITS, _vector
from .files import campaign_from_dict, read_campaign_toml
from .execute import ChunkLog, _Table, _campaign_numbers, _ee_positions, _offset, _run_chunk_task, reachable

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd
    from .dispersion import Array


@dataclass
class Campaign:
    """A Monte-Carlo campaign: the nominal slew, the dispersions and the number of runs (module
    docs). ``robot`` is a ``Robot`` or a URDF path (with ``ee_link``, ``ee_links``,
    ``locked_joints``), default
    the built-in space arm; ``joints`` a ``FlexibleJoints``, default the built-in arm's (for the
    built-in arm) or ``FlexibleJoints.defaults_for(robot)``. ``goal`` (rad, link side), ``kp``
    (N·m/rad), ``kd`` (N·m·s/rad) and ``q0`` (rad) are scalars or per joint; the reference moves
    from ``q0`` to ``goal`` on a quintic over ``slew_time`` seconds, then holds. The runs last
    ``duration`` seconds in steps of ``dt``, and keep every ``record_every``-th row for the
    settling time. With ``plan`` (see :meth:`from_plan`) the runs follow that plan instead.
    With ``wheels`` (a ``ReactionWheels``) every run's bus is held at its initial attitude by
    ``AttitudePD(attitude_kp, attitude_kd)`` (N·m/rad, N·m·s/rad; one number or three) in place of
    any open-loop base wrench; the wheel parameters and gains can be dispersed and the table gets
    the wheel metrics (``orbitflex.campaign.wheels``)."""

    goal: Any
    kp: Any
    kd: Any
    dt: float
    duration: float
    slew_time: float
    runs: int = 100
    seed: int = 0
    dispersions: Sequence[Dispersion] = ()
    name: str = "campaign"
    robot: Union[None, str, Robot] = None
    ee_link: Optional[str] = None
    locked_joints: Sequence[str] = ()
    ee_links: Sequence[str] = ()
    joints: Optional[FlexibleJoints] = None
    q0: Any = 0.0
    payload_mass: float = 0.0
    payload_com: Any = (0.0, 0.0, 0.0)
    payload_ee: Union[None, str, int] = None
    record_every: int = 10
    settle_tolerance: float = 5e-3
    plan: Optional[Plan] = None
    wheels: Optional[ReactionWheels] = None
    attitude_kp: Any = None
    attitude_kd: Any = None
    log: "ChunkLog" = field(default_factory=lambda: ChunkLog(), compare=False, repr=False)
    # the plan's per-step tables at (dt, steps), made once per process (not sent to workers)
    _tables: Optional[Dict[str, Array]] = field(default=None, init=False, compare=False, repr=False)

    # -- declaration ---------------------------------------------------------------------------

    @classmethod
    def from_plan(cls, plan: Plan, kp: Any, kd: Any, dt: float, duration: Optional[float] = None,
                  **fields: Any) -> "Campaign":
        """A campaign whose nominal is ``plan`` (from :func:`~orbitflex.plan_slew`): every run
        follows the plan's per-step tables at ``dt`` (:meth:`Plan.reference`: the motor reference
        ``θ_ref``, ``θ̇_ref`` at each step's start and the feedforward torque ``u`` averaged over
        it; for a held base, the base wrench that holds it, open loop) under the motor PD
        ``kp``, ``kd`` (N·m/rad, N·m·s/rad; scalars or per joint), as :meth:`Plan.track` runs it.
        The robot and the nominal joints are the plan's arm's; the runs start at the plan's start
        (``q0``, at rest) and are judged against its goal. ``duration`` (s, default: the plan
        and 2 s at rest) must cover the plan. The other ``fields`` are the constructor's
        (``runs``, ``seed``, ``dispersions``, ``payload_mass``, ``record_every``, …); every
        dispersion applies but ``goal``, which the plan fixes (``q0`` disperses the start away
        from the reference)."""
        stops = np.asarray(plan.stops)
        for key in ("goal", "slew_time", "robot", "joints", "ee_link", "ee_links", "locked_joints"):
            if key in fields:
                raise CampaignError(f"{key}: a campaign on a plan takes it from the plan; leave it out")
        return cls(goal=stops[-1].copy(), kp=kp, kd=kd, dt=dt,
                   duration=plan.duration + 2.0 if duration is None else duration,
                   slew_time=plan.duration, q0=fields.pop("q0", stops[0].copy()), plan=plan, **fields)

    @classmethod
    def from_toml(cls, path: Union[str, "os.PathLike[str]"], wheels: Any = None) -> "Campaign":
        """Reads a campaign file (see ``examples/campaign.toml``). A relative ``urdf`` (or
        ``wheels``) path is taken from the file's folder. ``wheels``, a wheels file (its path, or
        a ``WheelsFile``), replaces the file's ``wheels = "PATH"``: the bus held by those wheels
        under the file's ``AttitudePD`` gains."""
        path = Path(path)
        spec = read_campaign_toml(path)
        return cls.from_dict(spec, base=path.parent, source=str(path), wheels=wheels)

    @classmethod
    def from_dict(cls, spec: Mapping[str, Any], base: Optional[Path] = None,
                  source: str = "campaign", wheels: Any = None) -> "Campaign":
        """A campaign from the tables of a campaign file: top-level ``name``, ``runs``, ``seed``,
        ``wheels`` (a wheels file's path); ``[robot]``, ``[joints]``, ``[simulation]``,
        ``[slew]`` and ``[[dispersion]]``. ``wheels`` as in :meth:`from_toml`."""
        return campaign_from_dict(cls, spec, base, source, wheels)

    def check(self) -> None:
        """Checks the declaration (raises :class:`CampaignError` naming the field)."""
        if not isinstance(self.name, str):
            raise CampaignError(f"name: expected a string, given {self.name!r}")
        self._check_robot_options()
        for name in ("dt", "duration", "slew_time", "settle_tolerance"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 \
                    or not math.isfinite(value):
                raise CampaignError(f"{name}: expected a finite number > 0, given {value!r}")
        for name in ("runs", "record_every"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise CampaignError(f"{name}: expected an integer >= 1, given {value!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise CampaignError(f"seed: expected an integer >= 0, given {self.seed!r}")
        if self.dt > self.duration:
            raise CampaignError(f"dt: expected at most the duration ({self.duration:g} s), given {self.dt:g} s "
                                f"(the runs would last one step of {self.dt:g} s)")
        for k, d in enumerate(self.dispersions):
            d.check(f"dispersion[{k}]")
        seen = [d.parameter for d in self.dispersions]
        for p in set(seen):
            if seen.count(p) > 1:
                raise CampaignError(f"dispersion: {p!r} is dispersed {seen.count(p)} times; give it once")
        if self.plan is not None:
            self._check_plan()
        self._check_wheels()
        robot = self._robot()
        n = robot.dof
        for name in ("goal", "kp", "kd", "q0"):
            value = _vector(getattr(self, name), name)
            assert value is not None
            if value.ndim == 1 and value.shape != (n,):
                raise CampaignError(f"{name}: expected a scalar or {n} values (one per joint), given {value.size}")
        if not (math.isfinite(self.payload_mass) and self.payload_mass >= 0):
            raise CampaignError(f"payload_mass: expected a mass >= 0 kg, given {self.payload_mass!r}")
        com = _vector(self.payload_com, "payload_com")
        if com is None or com.shape != (3,):
            raise CampaignError(f"payload_com: expected 3 numbers (m, EE frame), given {self.payload_com!r}")
        for k, d in enumerate(self.dispersions):
            shape = self._nominal(robot)[d.parameter].shape
            for name in ("std", "low", "high"):
                value = getattr(d, name)
                if value is not None and np.ndim(value) == 1 and np.shape(value) != shape:
                    raise CampaignError(f"dispersion[{k}].{name}: expected a scalar or {shape[0] if shape else 1} "
                                        f"values ({d.parameter}), given {np.size(value)}")

    def _check_robot_options(self) -> None:
        """``ee_link``, ``ee_links`` and ``locked_joints`` are options of loading a URDF: their
        types, and that they apply (a built-in model or a ``Robot`` is loaded already)."""
        if self.ee_link is not None and not isinstance(self.ee_link, str):
            raise CampaignError(f"ee_link: expected a link name, given {self.ee_link!r}")
        for name in ("locked_joints", "ee_links"):
            value = getattr(self, name)
            if isinstance(value, str) or not all(isinstance(v, str) for v in value):
                raise CampaignError(f"{name}: expected a list of names, given {value!r}")
        if isinstance(self.payload_ee, bool) or not isinstance(self.payload_ee, (type(None), str, int)):
            raise CampaignError(f"payload_ee: expected an end-effector link name or index, given {self.payload_ee!r}")
        if isinstance(self.robot, str):
            return
        given = [name for name in ("ee_link", "ee_links", "locked_joints") if getattr(self, name)]
        if given:
            what = "the built-in space_arm" if self.robot is None else "a Robot given as such"
            raise CampaignError(f"{given[0]}: applies when the robot is read from a URDF file (urdf = PATH); "
                                f"{what} is loaded already")

    def _check_wheels(self) -> None:
        """Wheels come with the gains of their ``AttitudePD``; wheel dispersions need wheels."""
        if self.wheels is None:
            wheel = [d.parameter for d in self.dispersions if d.parameter in bus.WHEEL_PARAMETERS]
            given = [n for n in ("attitude_kp", "attitude_kd") if getattr(self, n) is not None]
            if wheel or given:
                raise CampaignError(f"{(wheel + given)[0]}: applies to a campaign with reaction wheels; give "
                                    "wheels (a ReactionWheels, or --wheels wheels.toml)")
            return
        if not isinstance(self.wheels, ReactionWheels):
            raise CampaignError(f"wheels: expected an orbitflex.ReactionWheels, given {type(self.wheels).__name__}")
        for name in ("attitude_kp", "attitude_kd"):
            value = _vector(getattr(self, name), name)
            if value is None or value.shape not in ((), (3,)) or (value < 0).any():
                raise CampaignError(f"{name}: a campaign with wheels holds the bus with an AttitudePD; expected "
                                    f"one gain >= 0 or three (x, y, z), given {getattr(self, name)!r}")

    def _check_plan(self) -> None:
        """A campaign on a plan: the plan's robot, joints and goal, a duration that covers it,
        and no dispersion of the goal."""
        plan = self.plan
        assert plan is not None
        if not isinstance(plan, Plan):
            raise CampaignError(f"plan: expected an orbitflex.Plan, given {type(plan).__name__}")
        if self.robot is not None or self.joints is not None:
            raise CampaignError("robot, joints: a campaign on a plan takes them from the plan's arm; leave them out")
        goal = np.broadcast_to(np.asarray(self.goal, dtype=np.float64), (plan.arm.dof,))
        if not np.array_equal(goal, np.asarray(plan.stops)[-1]):
            raise CampaignError("goal: a campaign on a plan ends at the plan's goal; build it with "
                                "Campaign.from_plan(plan, ...)")
        if any(d.parameter == "goal" for d in self.dispersions):
            raise CampaignError("dispersion: the goal of a campaign on a plan is the plan's; disperse q0 "
                                "for a start away from the reference")
        if self.steps * self.dt < plan.duration * (1 - 1e-12):
            raise CampaignError(f"duration: {self.duration:g} s ends before the plan does "
                                f"({plan.duration:.6g} s); give at least that")

    def _plan_tables(self) -> Dict[str, Array]:
        """The plan's per-step tables for this campaign's runs (:meth:`Plan.reference` at ``dt``
        over ``steps``), made once."""
        assert self.plan is not None
        if self._tables is None:
            self._tables = {k: np.asarray(v) for k, v in self.plan.reference(self.dt, self.steps).items()}
        return self._tables

    def _base_wrench(self) -> Optional[Array]:
        """The base wrench of every run, (1, steps, 6): a held base's plan holds it (unless the
        wheels do); else none."""
        if self.plan is None or self.plan.base != "held" or self.wheels is not None:
            return None
        return self._plan_tables()["base_wrench"][None]

    # -- the model and the runs ----------------------------------------------------------------

    def _robot(self) -> Robot:
        if self.plan is not None:
            return self.plan.arm.robot
        if isinstance(self.robot, Robot):
            return self.robot
        if self.robot is None:
            return models.space_arm()
        kwargs: Dict[str, Any] = {}
        if self.ee_link is not None:
            kwargs["ee_link"] = self.ee_link
        if self.locked_joints:
            kwargs["locked_joints"] = list(self.locked_joints)
        if self.ee_links:
            kwargs["ee_links"] = list(self.ee_links)
        return Robot.from_urdf(self.robot, **kwargs)

    def _joints(self, robot: Robot) -> FlexibleJoints:
        if self.plan is not None:
            return self.plan.arm.joints
        if self.joints is not None:
            return self.joints
        if self.robot is None:
            return models.space_arm_joints()
        return FlexibleJoints.defaults_for(robot)

    def _nominal(self, robot: Robot) -> Dict[str, Array]:
        n = robot.dof
        joints = self._joints(robot)
        k, j, d, b = joints.stiffness, joints.motor_inertia, joints.damping, joints.motor_damping

        def full(v: Any) -> Array:
            return np.broadcast_to(np.asarray(v, dtype=np.float64), (n,)).copy()

        return {"stiffness": full(k), "motor_inertia": full(j), "damping": full(d), "motor_damping": full(b),
                "kp": full(self.kp), "kd": full(self.kd), "goal": full(self.goal), "q0": full(self.q0),
                "base_rate": np.zeros(3), "payload_mass": np.asarray(float(self.payload_mass)),
                **bus.nominal(self.wheels, self.attitude_kp, self.attitude_kd)}

    def parameters(self, run: int, robot: Optional[Robot] = None) -> Dict[str, Array]:
        """Every parameter of run ``run``: the nominal values, with the dispersed ones drawn from
        ``default_rng([seed, run])`` in declaration order."""
        robot = robot if robot is not None else self._robot()
        return self._draw(run, self._nominal(robot))

    def _draw(self, run: int, nominal: Dict[str, Array]) -> Dict[str, Array]:
        """:meth:`parameters` of run ``run`` from the nominal values ``nominal`` (made once per
        chunk; a draw replaces a value, never writes into it, so the runs may share them)."""
        values = dict(nominal)
        rng = np.random.default_rng([self.seed, run])
        for d in self.dispersions:
            with np.errstate(over="ignore"):  # a draw that overflows is named below
                drawn = d.sample(rng, values[d.parameter])
            bound = POSITIVE.get(d.parameter)
            bad = ~np.isfinite(drawn)
            if bound is not None:
                bad |= drawn <= 0 if bound == "> 0" else drawn < 0
            if np.any(bad):
                where = int(np.argmax(bad)) if drawn.ndim else None
                label = d.parameter + (f"[{where}]" if where is not None else "")
                k = self.dispersions.index(d)
                advice = (f"the sigma of dispersion[{k}], {d.sigma:g}, is so wide that exp(sigma z) "
                          "overflows or underflows; narrow it"
                          if d.distribution == "lognormal" else
                          f"narrow the {d.distribution} dispersion or use a lognormal one (dispersion[{k}]; "
                          "a lognormal draw keeps the nominal's sign)")
                value = float(drawn.flat[where or 0])
                expected = bound if bound and math.isfinite(value) else "finite" + (f" and {bound}" if bound else "")
                raise CampaignError(f"run {run}: {label} drew {value:.6g} {UNITS[d.parameter]} (expected {expected}); "
                                    f"{advice}")
            values[d.parameter] = drawn
        return values

    def _columns(self, robot: Robot) -> List[str]:
        names = []
        nominal = self._nominal(robot)
        for d in self.dispersions:
            shape = nominal[d.parameter].shape
            names += [d.parameter] if not shape else [f"{d.parameter}[{i}]" for i in range(shape[0])]
        return names

    def _reference(self, n: int, q0: Array, goal: Array, steps: int) -> Tuple[Array, Array]:
        return quintic_reference(q0, goal, self.slew_time, self.dt, steps)

    @property
    def steps(self) -> int:
        """Steps per run: ``round(duration / dt)``."""
        return max(1, int(round(self.duration / self.dt)))

    def _setup(self, robot: Robot, values: Dict[str, Array], arms: Dict[Tuple[float, ...], FlexibleArm],
               references: Optional[Dict[bytes, Tuple[Array, Array]]] = None) -> Tuple[FlexibleArm, Array, MotorPD]:
        """The arm, start and controller of one run. Arms are shared between runs with the same
        joint parameters and payload (``arms`` caches them), the quintic reference tables between
        runs with the same start and goal (``references``, keyed by their bytes)."""
        key = tuple(np.concatenate([values[p].ravel() for p in (*JOINT_PARAMETERS, "payload_mass")]).tolist())
        key += bus.key(values)
        arm = arms.get(key)
        if arm is None:
            loaded = robot
            if float(values["payload_mass"]) > 0:
                loaded = robot.with_payload(float(values["payload_mass"]), com=np.asarray(self.payload_com, float),
                                            ee=self.payload_ee)
            joints = FlexibleJoints(*(values[p] for p in JOINT_PARAMETERS))
            wheels = None if self.wheels is None else bus.run_wheels(self.wheels, values)
            arm = arms[key] = FlexibleArm(loaded, joints, wheels=wheels)
        x0 = arm.state(q=values["q0"], base_twist=np.r_[values["base_rate"], 0.0, 0.0, 0.0])
        if self.plan is not None:
            tables = self._plan_tables()
            pd = MotorPD(values["kp"], values["kd"], tables["theta_ref"], tables["theta_dot_ref"], tables["u"])
            return arm, x0, pd
        ends = values["q0"].tobytes() + values["goal"].tobytes()
        table = references.get(ends) if references is not None else None
        if table is None:
            table = self._reference(robot.dof, values["q0"], values["goal"], self.steps)
            if references is not None:
                references[ends] = table
        theta_ref, theta_dot_ref = table
        pd = MotorPD(values["kp"], values["kd"], theta_ref, theta_dot_ref)
        return arm, x0, pd

    def _wheel_torque(self, values: Sequence[Dict[str, Array]]) -> Optional[List[AttitudePD]]:
        """The ``AttitudePD`` of each run (``values``: their parameters), or None without wheels."""
        if self.wheels is None:
            return None
        return [bus.controller(self.wheels, v) for v in values]

    def _invalid_draw(self, run: int, values: Dict[str, Array], error: Exception) -> str:
        """Why run ``run`` cannot be set up: the model's error, and the dispersions whose draws
        went into the model (the payload, the joint parameters)."""
        drawn = []
        for k, d in enumerate(self.dispersions):
            if d.parameter in (*JOINT_PARAMETERS, "payload_mass", "kp", "kd", *bus.WHEEL_PARAMETERS):
                v = np.asarray(values[d.parameter])
                shown = f"{float(v):.6g} {UNITS[d.parameter]}" if v.ndim == 0 else \
                    f"{np.abs(v).min():.3g} to {np.abs(v).max():.3g} {UNITS[d.parameter]}"
                drawn.append(f"{d.parameter} = {shown} from dispersion[{k}] ({d.distribution})")
        if not drawn:
            return f"run {run}: the model is invalid: {error}"
        return f"run {run}: {'; '.join(drawn)}: the model is invalid with it: {error}"

    def nominal_ee(self) -> Array:
        """The EE positions (m, inertial frame) at the end of the nominal run (no dispersion),
        (k, 3), one row per end-effector in ``robot.ee_links`` order."""
        robot = self._robot()
        values = self._nominal(robot)
        arm, x0, pd = self._setup(robot, values, {})
        batch = simulate_batch(arm, x0, self.dt, self.steps, u=pd, base_wrench=self._base_wrench(), threads=1,
                               keep_rows=False, wheel_torque=self._wheel_torque([values]))
        if not batch.ok[0]:
            raise CampaignError(f"the nominal run (no dispersion) failed: {batch.messages[0]}")
        return _ee_positions(arm, batch.final_state[0])

    def run_chunk(self, start: int, stop: int, nominal_ee: Array, threads: Optional[int] = None,
                  progress: Optional[Callable[[int, int], Any]] = None) -> "pd.DataFrame":
        """Runs ``start`` to ``stop - 1`` in one :func:`~orbitflex.simulate_batch` and returns
        their rows of the table; ``progress(done, runs)`` is the batch's."""
        import pandas as pd

        robot = self._robot()
        runs = list(range(start, stop))
        nominal = self._nominal(robot)
        values = [self._draw(i, nominal) for i in runs]
        arms: Dict[Tuple[float, ...], FlexibleArm] = {}
        references: Dict[bytes, Tuple[Array, Array]] = {}
        setups = []
        for run, v in zip(runs, values):
            try:
                setups.append(self._setup(robot, v, arms, references))
            except ModelError as e:
                raise CampaignError(self._invalid_draw(run, v, e)) from None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RuntimeWarning)
            batch = simulate_batch([s[0] for s in setups], np.stack([s[1] for s in setups]), self.dt,
                                   self.steps, u=[s[2] for s in setups], base_wrench=self._base_wrench(),
                                   threads=threads, record_every=self.record_every, progress=progress,
                                   wheel_torque=self._wheel_torque(values))
        for w in caught:
            warnings.warn(_campaign_numbers(str(w.message), start), w.category, stacklevel=2)
        n = robot.dof
        columns: Dict[str, Any] = {"run": np.asarray(runs, dtype=np.int64)}
        for d in self.dispersions:
            drawn = np.stack([v[d.parameter] for v in values])
            if drawn.ndim == 1:
                columns[d.parameter] = drawn
            else:
                for i in range(drawn.shape[1]):
                    columns[f"{d.parameter}[{i}]"] = drawn[:, i]
        columns["ok"] = np.asarray(batch.ok)
        columns["failed_step"] = np.asarray(batch.failed_step)
        columns.update(self._metrics(batch, setups, values, nominal_ee, n))
        return pd.DataFrame(columns)

    def _metrics(self, batch: Any, setups: Sequence[Tuple[FlexibleArm, Array, MotorPD]],
                 values: Sequence[Dict[str, Array]], nominal_ee: Array, n: int) -> Dict[str, Array]:
        ok = np.asarray(batch.ok)
        goal = np.stack([v["goal"] for v in values])                      # (B, n)
        final = np.asarray(batch.final_state)
        layout = setups[0][0].state_slices
        q_final = final[:, layout["q"]]
        final_error = np.abs(q_final - goal).max(axis=1)
        # settling: from the first kept row after which every later kept row is within tolerance
        error = np.abs(np.asarray(batch.q) - goal[:, None, :]).max(axis=2)  # (B, rows)
        outside = error > self.settle_tolerance
        t = np.asarray(batch.t)
        last_outside = np.where(outside.any(axis=1), outside.shape[1] - 1 - np.argmax(outside[:, ::-1], axis=1), -1)
        settled = (~outside[:, -1]) & ok
        index = np.minimum(last_outside + 1, len(t) - 1)
        settling = np.where(settled, t[index], np.nan)
        # the bus's rotation angle between the start and the end
        quat0 = np.stack([s[1][3:7] for s in setups])
        quat1 = final[:, 3:7]
        dot = np.abs(np.einsum("bi,bi->b", quat0, quat1))
        attitude = 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))
        ee = np.stack([_ee_positions(s[0], x) for s, x in zip(setups, final)])   # (B, k, 3)
        ee_error = np.linalg.norm(ee - nominal_ee, axis=2).max(axis=1)

        def nan_if_failed(v: Array) -> Array:
            return np.where(ok, v, np.nan)

        return {"peak_deflection": np.asarray(batch.peak_deflection).max(axis=1),
                "peak_torque": np.asarray(batch.peak_torque).max(axis=1),
                "final_error": nan_if_failed(final_error),
                "settling_time": settling,
                "base_attitude_change": nan_if_failed(attitude),
                "ee_error": nan_if_failed(ee_error),
                **({} if self.wheels is None else bus.metrics(batch, [s[0] for s in setups]))}

    def trajectory(self, run: int, record_every: int = 1) -> Trajectory:
        """Run ``run`` again, alone, as a :class:`~orbitflex.Trajectory` keeping one row in
        ``record_every`` (default: every step) and the final row: the same parameters, arm,
        start, controller and wrenches as its row of the table, through the same
        :func:`~orbitflex.simulate_batch`, so its states are the ones the row was computed from,
        bit for bit (a failed run ends on its last good state). The worst run animates in one
        line: ``campaign.trajectory(int(table["peak_deflection"].idxmax())).animate("worst.html")``."""
        if isinstance(run, bool) or not isinstance(run, (int, np.integer)) or run < 0:
            raise CampaignError(f"run: expected an integer >= 0 (a run's index), given {run!r}")
        self.check()
        robot = self._robot()
        values = self.parameters(int(run), robot)
        arm, x0, pd = self._setup(robot, values, {})
        batch = simulate_batch(arm, x0, self.dt, self.steps, u=pd, base_wrench=self._base_wrench(), threads=1,
                               record_every=record_every, wheel_torque=self._wheel_torque([values]))
        traj: Trajectory = batch.run(0)
        return traj

    # -- running -------------------------------------------------------------------------------

    def run(self, runs: Optional[int] = None, scheduler: Optional[str] = None, client: Any = None,
            chunk_runs: Optional[int] = None, threads: Optional[int] = None,
            progress: Optional[Callable[[int, int], Any]] = None, timeout: float = 10.0) -> "pd.DataFrame":
        """Runs the campaign and returns its table (a pandas DataFrame, one row per run, sorted
        by ``run``). ``runs`` overrides the declared number.

        Locally (no ``scheduler`` or ``client``), chunks of ``chunk_runs`` runs (default 256)
        go through :func:`~orbitflex.simulate_batch` on ``threads`` threads (default every
        core). On Dask, each chunk (default: about four per worker thread, at most 256 runs) is a
        task on the cluster at ``scheduler`` (an address) or of ``client`` (a
        ``dask.distributed.Client``), run with ``threads`` threads (default 1, since Dask runs
        one task per worker thread); a task lost with its worker is run again by Dask. The
        table is the same either way, bit for bit. ``progress(done, runs)`` is called after
        each chunk. Where and how long each chunk ran goes to :attr:`log`.

        ``timeout`` (s) bounds the connection to ``scheduler``: a scheduler that refuses it
        fails at once, one that does not answer after ``timeout``; raise it for a slow cluster.

        Memory: the table (one row per run, about 120 bytes with the example's dispersions) is
        filled in place as chunks finish, and :attr:`log` keeps 28 bytes per chunk; whatever the
        chunking, nothing else grows with the runs (on Dask, at most four tasks per worker
        thread are in flight)."""
        self.check()
        total = self.runs if runs is None else runs
        if isinstance(total, bool) or not isinstance(total, int) or total < 1:
            raise CampaignError(f"runs: expected an integer >= 1, given {total!r}")
        if chunk_runs is not None and (isinstance(chunk_runs, bool) or not isinstance(chunk_runs, int)
                                       or chunk_runs < 1):
            raise CampaignError(f"chunk_runs: expected an integer >= 1, given {chunk_runs!r}")
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not timeout > 0 \
                or not math.isfinite(timeout):
            raise CampaignError(f"timeout: expected a finite time > 0 (s), given {timeout!r}")
        distributed = scheduler is not None or client is not None
        if scheduler is not None and client is None:
            reachable(scheduler, timeout)
        nominal_ee = self.nominal_ee()
        self.log = ChunkLog()
        table = _Table(total)
        if not distributed:
            size = chunk_runs or 256
            for start in range(0, total, size):
                stop = min(start + size, total)
                began = time.time()
                within = None if progress is None else _offset(progress, start, total)
                table.add(self.run_chunk(start, stop, nominal_ee, threads, within))
                self.log.append({"start": start, "stop": stop, "worker": "local", "host": socket.gethostname(),
                                 "seconds": time.time() - began})
                if progress is not None:
                    progress(stop, total)
        else:
            self._run_on_dask(total, scheduler, client, chunk_runs, threads or 1, nominal_ee, progress, table,
                              timeout)
        return table.frame()

    def _portable(self) -> "Campaign":
        """This campaign with its URDF read into memory, so that a worker without the file can
        build the model."""
        if isinstance(self.robot, str):
            return replace(self, robot=self._robot(), log=ChunkLog())
        return replace(self, log=ChunkLog())

    def _run_on_dask(self, total: int, scheduler: Optional[str], client: Any, chunk_runs: Optional[int],
                     threads: int, nominal_ee: Array, progress: Optional[Callable[[int, int], Any]],
                     table: "_Table", timeout: float) -> None:
        from dask.distributed import Client, as_completed

        own = client is None
        if own:
            client = Client(scheduler, timeout=timeout)  # type: ignore[no-untyped-call]
        try:
            slots = max(1, sum(client.nthreads().values()))
            if chunk_runs is None:
                chunk_runs = max(1, min(256, math.ceil(total / (4 * slots))))
            portable = self._portable()
            token = uuid.uuid4().hex[:8]
            chunks = ((start, min(start + chunk_runs, total)) for start in range(0, total, chunk_runs))

            def submit(start: int, stop: int) -> Any:
                return client.submit(_run_chunk_task, portable, start, stop, nominal_ee, threads,
                                     key=f"orbitflex-{self.name}-{token}-{start}-{stop}", pure=False, retries=2)

            # a bounded number of tasks in flight, so that a campaign of a million one-run chunks
            # does not hold a million futures
            running = as_completed([submit(*chunk) for _, chunk in zip(range(4 * slots), chunks)])  # type: ignore[no-untyped-call]
            done = 0
            for future in running:
                piece, meta = future.result()
                table.add(piece)
                self.log.append(meta)
                done += meta["stop"] - meta["start"]
                if progress is not None:
                    progress(done, total)
                following = next(chunks, None)
                if following is not None:
                    running.add(submit(*following))  # type: ignore[no-untyped-call]
        finally:
            if own:
                client.close()
