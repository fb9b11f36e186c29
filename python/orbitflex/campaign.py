# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
# (pandas, Dask and their stubs come with orbitflex[campaign]: a base install type-checks clean)
"""Monte-Carlo campaigns: many slews of one arm with dispersed parameters, run locally through
:func:`orbitflex.simulate_batch` or on a Dask cluster, with one table row per run.

A campaign is a nominal slew and a list of dispersions. The nominal slew is either a quintic
rest-to-rest motion of the motor references followed by a motor-side PD, or a planned slew
(:meth:`Campaign.from_plan`: a :class:`~orbitflex.Plan`'s per-step motor reference and
feedforward torque, and for a held base the wrench that holds it, under the same PD).
Run ``i`` draws its parameters from its own
random generator, ``numpy.random.default_rng([seed, i])``, in the order the dispersions are
declared, so a run's parameters and results depend only on the campaign and ``i``: the table is
the same, bit for bit, whether the runs go one chunk at a time on a laptop or as tasks on a
cluster, in any order, with any number of threads or workers.

Declare a campaign in TOML (:meth:`Campaign.from_toml`, see ``examples/campaign.toml``) or in
Python, then call :meth:`Campaign.run`::

    from orbitflex.campaign import Campaign, Dispersion
    campaign = Campaign(goal=[0.4, 0.6, -0.5, 0.8, -0.6, 0.5, 1.0], kp=1000.0, kd=100.0,
                        dt=2e-3, duration=8.0, slew_time=4.0, runs=100, seed=1,
                        dispersions=[Dispersion("stiffness", "lognormal", sigma=0.2)])
    table = campaign.run()                        # local, every core
    table = campaign.run(scheduler="tcp://host:8786")   # on a Dask cluster
    worst = campaign.trajectory(int(table["peak_deflection"].idxmax()))   # that run, again

Dispersed parameters (``parameter =``), with their units and nominal values:

========================= ====== ======================================= =====================
parameter                 shape  what                                    nominal
========================= ====== ======================================= =====================
``stiffness``             (n,)   joint stiffness k (N·m/rad)             the joints'
``motor_inertia``         (n,)   reflected motor inertia j (kg·m²)       the joints'
``damping``               (n,)   joint damping d (N·m·s/rad)             the joints'
``motor_damping``         (n,)   motor friction β (N·m·s/rad)            the joints'
``kp``, ``kd``            (n,)   PD gains (N·m/rad, N·m·s/rad)           ``kp``, ``kd``
``goal``                  (n,)   slew goal, link side (rad)              ``goal``
``q0``                    (n,)   initial link and motor angles (rad)     ``q0`` (zeros)
``base_rate``             (3,)   initial base angular rate, base frame   zeros
                                 (rad/s)
``payload_mass``          ()     mass held at the EE (kg), at            ``payload_mass`` (0)
                                 ``payload_com`` in the EE frame (the
                                 end-effector ``payload_ee`` of a robot
                                 with several)
========================= ====== ======================================= =====================

Distributions (``distribution =``): ``normal`` (nominal + ``std`` × N(0, 1), or with
``relative``: nominal × (1 + relative × N(0, 1))), ``lognormal`` (nominal × exp(``sigma`` ×
N(0, 1)), always of the nominal's sign), ``uniform`` (with ``low``/``high``: U(low, high), the
values themselves, *not* an offset from the nominal; with ``relative``: nominal × (1 + U(−r, r))). ``per_joint = true`` (default) draws each element on its own; ``false`` draws one number
for all elements (a common-mode error). ``std``, ``low`` and ``high`` may be per element.

Metrics, one column each (NaN where a run failed before they were defined):

- ``ok`` (bool), ``failed_step`` (the failing step, −1 if the run finished);
- ``peak_deflection`` (rad): max over joints and every step of ``|θ − q|``;
- ``peak_torque`` (N·m): max over joints and every step of ``|u|``;
- ``final_error`` (rad): max over joints of ``|q − goal|`` at the end;
- ``settling_time`` (s): the first kept row from which ``|q − goal| ≤ settle_tolerance`` on
  every joint until the end (NaN if not settled; resolution ``dt × record_every``);
- ``base_attitude_change`` (rad): the bus's rotation angle between the start and the end;
- ``ee_error`` (m): the distance between the EE position at the end and that of the nominal
  run (no dispersion); on a robot with several end-effectors, the largest of their distances.

The table has one row per run, ``run`` (the index) first, then the dispersed parameters
(``stiffness[0]``, …; scalars by name), then the metrics; nothing about where or when a run
went, so that two tables of the same campaign compare equal. That goes to :attr:`Campaign.log`.
"""

from __future__ import annotations

import array
import math
import os
import re
import socket
import sys
import time
import uuid
import warnings
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import FlexibleArm, FlexibleJoints, ModelError, MotorPD, Plan, Robot, Trajectory, models, simulate_batch

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

Array = npt.NDArray[np.float64]

PARAMETERS = ("stiffness", "motor_inertia", "damping", "motor_damping", "kp", "kd", "goal", "q0",
              "base_rate", "payload_mass")
JOINT_PARAMETERS = ("stiffness", "motor_inertia", "damping", "motor_damping")
POSITIVE = {"stiffness": "> 0", "motor_inertia": "> 0", "damping": ">= 0", "motor_damping": ">= 0",
            "kp": ">= 0", "kd": ">= 0", "payload_mass": ">= 0"}
UNITS = {"stiffness": "N·m/rad", "motor_inertia": "kg·m²", "damping": "N·m·s/rad",
         "motor_damping": "N·m·s/rad", "kp": "N·m/rad", "kd": "N·m·s/rad", "goal": "rad",
         "q0": "rad", "base_rate": "rad/s", "payload_mass": "kg"}
DISTRIBUTIONS = ("normal", "lognormal", "uniform")
TITLES = {"peak_deflection": "peak deflection |θ − q|", "peak_torque": "peak motor torque |u|",
          "final_error": "final error |q − goal|", "settling_time": "settling time",
          "base_attitude_change": "bus rotation, start to end", "ee_error": "EE distance from the nominal end"}
METRICS = {"peak_deflection": "rad", "peak_torque": "N·m", "final_error": "rad",
           "settling_time": "s", "base_attitude_change": "rad", "ee_error": "m"}


class CampaignError(ModelError):
    """A campaign that cannot run as declared: the message names the field (``dispersion[1].std``),
    what was expected and what was given."""


def _vector(value: Any, what: str) -> Optional[Array]:
    if value is None:
        return None
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise CampaignError(f"{what}: expected a number or a list of numbers, given {value!r}") from None
    if a.ndim > 1 or not np.isfinite(a).all():
        raise CampaignError(f"{what}: expected finite numbers (a scalar or a list), given {value!r}")
    return a


@dataclass(frozen=True)
class Dispersion:
    """One dispersed parameter: ``parameter`` (see the module docs), ``distribution``
    (``"normal"``, ``"lognormal"`` or ``"uniform"``) and its width: ``std`` (normal, absolute),
    ``relative`` (normal or uniform, a fraction of the nominal), ``sigma`` (lognormal),
    ``low``/``high`` (uniform: the drawn values themselves, not offsets from the nominal).
    ``per_joint=False`` draws one number for every element."""

    parameter: str
    distribution: str = "normal"
    std: Any = None
    relative: Optional[float] = None
    sigma: Optional[float] = None
    low: Any = None
    high: Any = None
    per_joint: bool = True

    def check(self, where: str) -> None:
        """Checks the declaration; ``where`` names it in errors (``dispersion[2]``)."""
        if not isinstance(self.per_joint, bool):
            raise CampaignError(f"{where}.per_joint: expected true or false, given {self.per_joint!r}")
        if self.parameter not in PARAMETERS:
            raise CampaignError(f"{where}.parameter: expected one of {', '.join(PARAMETERS)}, "
                                f"given {self.parameter!r}")
        if self.distribution not in DISTRIBUTIONS:
            raise CampaignError(f"{where}.distribution: expected one of {', '.join(DISTRIBUTIONS)}, "
                                f"given {self.distribution!r}")
        given = {k for k in ("std", "relative", "sigma", "low", "high") if getattr(self, k) is not None}
        allowed = {"normal": [{"std"}, {"relative"}], "lognormal": [{"sigma"}],
                   "uniform": [{"low", "high"}, {"relative"}]}[self.distribution]
        if given not in allowed:
            options = " or ".join("/".join(sorted(a)) for a in allowed)
            raise CampaignError(f"{where}: a {self.distribution} dispersion takes {options}, given "
                                f"{', '.join(sorted(given)) or 'none'}")
        for name in given:
            values = _vector(getattr(self, name), f"{where}.{name}")
            assert values is not None
            if name in ("relative", "sigma") and values.ndim != 0:
                raise CampaignError(f"{where}.{name}: expected one number (for every element), given "
                                    f"{getattr(self, name)!r}; std, low and high may be per element")
            if name in ("std", "relative", "sigma") and (values < 0).any():
                raise CampaignError(f"{where}.{name}: expected >= 0, given {getattr(self, name)!r}")
        if self.low is not None and (np.asarray(self.low) > np.asarray(self.high)).any():
            raise CampaignError(f"{where}: expected low <= high, given low={self.low!r}, high={self.high!r}")

    def sample(self, rng: np.random.Generator, nominal: Array) -> Array:
        """Draws this parameter for one run around ``nominal`` (its nominal value, of the
        parameter's shape)."""
        size = nominal.shape if self.per_joint else ()
        if self.distribution == "normal":
            z = rng.standard_normal(size)
            if self.relative is not None:
                return nominal * (1.0 + float(self.relative) * z)
            return nominal + np.asarray(self.std, dtype=np.float64) * z
        if self.distribution == "lognormal":
            return nominal * np.exp(float(self.sigma) * rng.standard_normal(size))  # type: ignore[arg-type]
        s = rng.random(size)
        if self.relative is not None:
            r = float(self.relative)
            return nominal * (1.0 + r * (2.0 * s - 1.0))
        low, high = np.asarray(self.low, dtype=np.float64), np.asarray(self.high, dtype=np.float64)
        return np.broadcast_to(low + (high - low) * s, nominal.shape).copy()


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
    settling time. With ``plan`` (see :meth:`from_plan`) the runs follow that plan instead."""

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
    def from_toml(cls, path: Union[str, "os.PathLike[str]"]) -> "Campaign":
        """Reads a campaign file (see ``examples/campaign.toml``). A relative ``urdf`` path is
        taken from the file's folder."""
        if sys.version_info >= (3, 11):
            import tomllib
        else:  # pragma: no cover
            import tomli as tomllib
        path = Path(path)
        try:
            text = path.read_text()
        except OSError as e:
            raise FileNotFoundError(f"{path}: cannot read the campaign file ({e.strerror})") from None
        try:
            spec = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise CampaignError(f"{path}: malformed TOML: {e}") from None
        return cls.from_dict(spec, base=path.parent, source=str(path))

    @classmethod
    def from_dict(cls, spec: Mapping[str, Any], base: Optional[Path] = None,
                  source: str = "campaign") -> "Campaign":
        """A campaign from the tables of a campaign file: top-level ``name``, ``runs``, ``seed``;
        ``[robot]``, ``[joints]``, ``[simulation]``, ``[slew]`` and ``[[dispersion]]``."""
        known = {"name", "runs", "seed", "robot", "joints", "simulation", "slew", "dispersion"}
        for key in spec:
            if key not in known:
                raise CampaignError(f"{source}: unknown key {key!r}; expected {', '.join(sorted(known))}")

        def table(name: str, keys: Sequence[str]) -> Dict[str, Any]:
            given = spec.get(name, {})
            if not isinstance(given, Mapping):
                raise CampaignError(f"{source}: [{name}]: expected a table, given {given!r}")
            t = dict(given)
            for key in t:
                if key not in keys:
                    raise CampaignError(f"{source}: [{name}] {key!r} is not a known key; expected "
                                        f"{', '.join(keys)}")
            return t

        robot_t = table("robot", ["model", "urdf", "ee_link", "ee_links", "locked_joints", "payload_mass",
                                  "payload_com", "payload_ee"])
        joints_t = table("joints", ["model", *JOINT_PARAMETERS])
        sim_t = table("simulation", ["dt", "duration", "record_every"])
        slew_t = table("slew", ["goal", "q0", "slew_time", "kp", "kd", "settle_tolerance"])
        for name, value in (("[robot] model", robot_t.get("model", "")), ("[robot] urdf", robot_t.get("urdf", "")),
                            ("[joints] model", joints_t.get("model", ""))):
            if not isinstance(value, str):
                raise CampaignError(f"{source}: {name}: expected a string, given {value!r}")
        for t, name, keys in ((sim_t, "simulation", ["dt", "duration"]),
                              (slew_t, "slew", ["goal", "slew_time", "kp", "kd"])):
            for key in keys:
                if key not in t:
                    raise CampaignError(f"{source}: [{name}] {key} is required")
        robot: Union[None, str] = None
        if "urdf" in robot_t:
            urdf = Path(robot_t["urdf"])
            robot = str(urdf if urdf.is_absolute() or base is None else base / urdf)
        elif robot_t.get("model", "space_arm") != "space_arm":
            raise CampaignError(f"{source}: [robot] model: expected \"space_arm\" (or give urdf = PATH), "
                                f"given {robot_t['model']!r}")
        joints = None
        model = joints_t.get("model")
        if any(k in joints_t for k in JOINT_PARAMETERS):
            if model is not None:
                raise CampaignError(f"{source}: [joints] give model or the parameters "
                                    f"({', '.join(JOINT_PARAMETERS)}), not both")
            for key in ("stiffness", "motor_inertia"):
                if key not in joints_t:
                    raise CampaignError(f"{source}: [joints] {key} is required with the joint parameters "
                                        f"(or give model = \"space_arm\" or \"defaults\")")
            params = {k: joints_t[k] for k in JOINT_PARAMETERS if k in joints_t}
            try:
                joints = FlexibleJoints(**params)
            except ModelError as e:
                raise CampaignError(f"{source}: [joints] {e}") from None
        elif model == "space_arm":
            joints = models.space_arm_joints()
        elif model == "defaults":
            kwargs: Dict[str, Any] = {}
            if robot_t.get("ee_link") is not None:
                kwargs["ee_link"] = robot_t["ee_link"]
            if robot_t.get("locked_joints"):
                kwargs["locked_joints"] = list(robot_t["locked_joints"])
            if robot_t.get("ee_links"):
                kwargs["ee_links"] = list(robot_t["ee_links"])
            loaded = models.space_arm() if robot is None else Robot.from_urdf(robot, **kwargs)
            joints = FlexibleJoints.defaults_for(loaded)
        elif model is not None:
            raise CampaignError(f"{source}: [joints] model: expected \"space_arm\" (the built-in arm's "
                                f"joints) or \"defaults\" (FlexibleJoints.defaults_for the robot), given {model!r}")
        dispersions = []
        declared = spec.get("dispersion", [])
        if not isinstance(declared, list):
            raise CampaignError(f"{source}: dispersion: expected tables ([[dispersion]]), given {declared!r}")
        for k, d in enumerate(declared):
            if not isinstance(d, Mapping):
                raise CampaignError(f"{source}: dispersion[{k}]: expected a table ([[dispersion]]), given {d!r}")
            fields = {"parameter", "distribution", "std", "relative", "sigma", "low", "high", "per_joint"}
            for key in d:
                if key not in fields:
                    raise CampaignError(f"{source}: dispersion[{k}]: {key!r} is not a known key; expected "
                                        f"{', '.join(sorted(fields))}")
            if "parameter" not in d:
                raise CampaignError(f"{source}: dispersion[{k}]: parameter is required")
            dispersions.append(Dispersion(**d))
        campaign = cls(goal=slew_t["goal"], kp=slew_t["kp"], kd=slew_t["kd"], dt=sim_t["dt"],
                       duration=sim_t["duration"], slew_time=slew_t["slew_time"],
                       runs=spec.get("runs", 100), seed=spec.get("seed", 0), dispersions=dispersions,
                       name=spec.get("name", "campaign"), robot=robot, ee_link=robot_t.get("ee_link"),
                       locked_joints=tuple(robot_t.get("locked_joints", ())),
                       ee_links=tuple(robot_t.get("ee_links", ())), payload_ee=robot_t.get("payload_ee"),
                       joints=joints,
                       q0=slew_t.get("q0", 0.0), payload_mass=robot_t.get("payload_mass", 0.0),
                       payload_com=robot_t.get("payload_com", (0.0, 0.0, 0.0)),
                       record_every=sim_t.get("record_every", 10),
                       settle_tolerance=slew_t.get("settle_tolerance", 5e-3))
        try:
            campaign.check()
        except CampaignError as e:
            raise CampaignError(f"{source}: {e}") from None
        return campaign

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
        """The base wrench of every run, (1, steps, 6): a held base's plan holds it; else none."""
        if self.plan is None or self.plan.base != "held":
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
                "base_rate": np.zeros(3), "payload_mass": np.asarray(float(self.payload_mass))}

    def parameters(self, run: int, robot: Optional[Robot] = None) -> Dict[str, Array]:
        """Every parameter of run ``run``: the nominal values, with the dispersed ones drawn from
        ``default_rng([seed, run])`` in declaration order."""
        robot = robot if robot is not None else self._robot()
        values = self._nominal(robot)
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
        from .cli import quintic

        t = np.arange(steps, dtype=np.float64) * self.dt
        shape, dshape = quintic(t / self.slew_time)
        delta = goal - q0
        return q0 + np.outer(shape, delta), np.outer(dshape / self.slew_time, delta)

    @property
    def steps(self) -> int:
        """Steps per run: ``round(duration / dt)``."""
        return max(1, int(round(self.duration / self.dt)))

    def _setup(self, robot: Robot, values: Dict[str, Array],
               arms: Dict[Tuple[float, ...], FlexibleArm]) -> Tuple[FlexibleArm, Array, MotorPD]:
        """The arm, start and controller of one run. Arms are shared between runs with the same
        joint parameters and payload (``arms`` caches them)."""
        key = tuple(np.concatenate([values[p].ravel() for p in (*JOINT_PARAMETERS, "payload_mass")]).tolist())
        arm = arms.get(key)
        if arm is None:
            loaded = robot
            if float(values["payload_mass"]) > 0:
                loaded = robot.with_payload(float(values["payload_mass"]), com=np.asarray(self.payload_com, float),
                                            ee=self.payload_ee)
            joints = FlexibleJoints(*(values[p] for p in JOINT_PARAMETERS))
            arm = arms[key] = FlexibleArm(loaded, joints)
        x0 = arm.state(q=values["q0"], base_twist=np.r_[values["base_rate"], 0.0, 0.0, 0.0])
        if self.plan is not None:
            tables = self._plan_tables()
            pd = MotorPD(values["kp"], values["kd"], tables["theta_ref"], tables["theta_dot_ref"], tables["u"])
            return arm, x0, pd
        theta_ref, theta_dot_ref = self._reference(robot.dof, values["q0"], values["goal"], self.steps)
        pd = MotorPD(values["kp"], values["kd"], theta_ref, theta_dot_ref)
        return arm, x0, pd

    def _invalid_draw(self, run: int, values: Dict[str, Array], error: Exception) -> str:
        """Why run ``run`` cannot be set up: the model's error, and the dispersions whose draws
        went into the model (the payload, the joint parameters)."""
        drawn = []
        for k, d in enumerate(self.dispersions):
            if d.parameter in (*JOINT_PARAMETERS, "payload_mass", "kp", "kd"):
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
        arm, x0, pd = self._setup(robot, self._nominal(robot), {})
        batch = simulate_batch(arm, x0, self.dt, self.steps, u=pd, base_wrench=self._base_wrench(), threads=1,
                               keep_rows=False)
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
        values = [self.parameters(i, robot) for i in runs]
        arms: Dict[Tuple[float, ...], FlexibleArm] = {}
        setups = []
        for run, v in zip(runs, values):
            try:
                setups.append(self._setup(robot, v, arms))
            except ModelError as e:
                raise CampaignError(self._invalid_draw(run, v, e)) from None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RuntimeWarning)
            batch = simulate_batch([s[0] for s in setups], np.stack([s[1] for s in setups]), self.dt,
                                   self.steps, u=[s[2] for s in setups], base_wrench=self._base_wrench(),
                                   threads=threads, record_every=self.record_every, progress=progress)
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
                "ee_error": nan_if_failed(ee_error)}

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
        arm, x0, pd = self._setup(robot, self.parameters(int(run), robot), {})
        batch = simulate_batch(arm, x0, self.dt, self.steps, u=pd, base_wrench=self._base_wrench(), threads=1,
                               record_every=record_every)
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


class _Table:
    """A campaign's table, filled in place as chunks come (in any order): one array per column,
    ``runs`` rows, row ``i`` for run ``i``."""

    def __init__(self, runs: int) -> None:
        self.runs = runs
        self.columns: Dict[str, Any] = {}

    def add(self, piece: "pd.DataFrame") -> None:
        rows = piece["run"].to_numpy()
        if not self.columns:
            row = 0
            for name in piece.columns:
                row += piece[name].to_numpy().itemsize
            need = self.runs * row
            free = _free_memory()
            if free is not None and need > free:
                raise CampaignError(f"runs: the table of {self.runs} runs needs {need / 1e9:.3g} GB, more than the "
                                    f"{free / 1e9:.3g} GB of memory free; run fewer runs at a time")
            self.columns = {name: np.empty(self.runs, dtype=piece[name].dtype) for name in piece.columns}
        for name, column in self.columns.items():
            column[rows] = piece[name].to_numpy()

    def frame(self) -> "pd.DataFrame":
        import pandas as pd

        return pd.DataFrame(self.columns, copy=False)


def _free_memory() -> Optional[int]:
    """Bytes of free physical memory, or None where the system does not say."""
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


class ChunkLog(Sequence[Dict[str, Any]]):
    """Where and how long each chunk of a campaign ran (:attr:`Campaign.log`): a sequence of
    dicts ``{"start", "stop", "worker", "host", "seconds"}`` (and ``"pid"`` on Dask), in the order
    the chunks finished. Kept as arrays, 28 bytes per chunk (the places a chunk ran at are few and
    kept once), so that a campaign of a million one-run chunks does not hold a million dicts."""

    def __init__(self) -> None:
        self._start = array.array("q")
        self._stop = array.array("q")
        self._seconds = array.array("d")
        self._place = array.array("I")
        self._places: List[Tuple[Tuple[str, Any], ...]] = []
        self._index: Dict[Tuple[Tuple[str, Any], ...], int] = {}

    def append(self, entry: Mapping[str, Any]) -> None:
        place = tuple(sorted((k, v) for k, v in entry.items() if k not in ("start", "stop", "seconds")))
        if place not in self._index:
            self._index[place] = len(self._places)
            self._places.append(place)
        self._start.append(int(entry["start"]))
        self._stop.append(int(entry["stop"]))
        self._seconds.append(float(entry["seconds"]))
        self._place.append(self._index[place])

    def __len__(self) -> int:
        return len(self._start)

    def _entry(self, k: int) -> Dict[str, Any]:
        entry: Dict[str, Any] = {"start": self._start[k], "stop": self._stop[k]}
        entry.update(self._places[self._place[k]])
        entry["seconds"] = self._seconds[k]
        return entry

    def __getitem__(self, k: Any) -> Any:
        if isinstance(k, slice):
            return [self._entry(i) for i in range(*k.indices(len(self)))]
        if k < 0:
            k += len(self)
        if not 0 <= k < len(self):
            raise IndexError("chunk log index out of range")
        return self._entry(k)

    def __repr__(self) -> str:
        return f"ChunkLog({len(self)} chunks)"


def reachable(address: str, timeout: float) -> None:
    """Checks that a Dask scheduler answers at ``address`` (``tcp://host:port``, or
    ``host:port``) within ``timeout`` seconds, so that a refused connection fails at once rather
    than after Dask's retries, and a server that is not a Dask scheduler (a web server, say,
    which Dask's client would wait for forever, or whose bytes it would take for a frame size)
    fails clearly. A scheduler greets each connection with a message whose first eight bytes
    count its frames. A malformed address is a :class:`CampaignError`; a refused connection or
    another kind of server an ``OSError``; no answer a ``TimeoutError``. Other protocols
    (``tls://``, ``ucx://``, ``inproc://``) are left to Dask."""
    text = address if "://" in address else "tcp://" + address
    scheme, _, location = text.partition("://")
    if scheme != "tcp":
        return
    host, colon, port = location.rpartition(":")
    host = host.strip("[]")
    if not colon or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise CampaignError(f"scheduler: expected an address like tcp://host:8786, given {address!r}")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout) as connection:
            greeting = connection.recv(8, socket.MSG_WAITALL)
    except socket.timeout:
        raise TimeoutError(f"cannot reach the Dask scheduler at {address}: no answer within {timeout:g} s (for a "
                           "slow cluster, give a longer timeout)") from None
    except OSError as e:
        raise OSError(f"cannot reach the Dask scheduler at {address}: {e.strerror or e}") from None
    frames = int.from_bytes(greeting, "little") if len(greeting) == 8 else 0
    if not 0 < frames < 1000:
        raise OSError(f"cannot reach the Dask scheduler at {address}: the server there accepts connections "
                      "but does not answer as a Dask scheduler")

def _campaign_numbers(message: str, start: int) -> str:
    """A batch's stability warning for a chunk that starts at run ``start``, its runs named as
    the campaign numbers them (the batch counts from 0)."""
    def shift(m: "re.Match[str]") -> str:
        return ", ".join(str(int(i) + start) if i.strip().isdigit() else i.strip() for i in m.group(1).split(","))

    message = message.replace(" of the run (", f" of run {start} (", 1)
    message = re.sub(r"(?<= of run )(\d+) of \d+(?= \()", lambda m: str(int(m.group(1)) + start), message, count=1)
    message = re.sub(r"(?<=\(runs )([\d, …]+)(?=;)", shift, message, count=1)
    return re.sub(r" of (all \d+|\d+ of \d+) runs \(", r" of \1 runs of this chunk (", message, count=1)


def _offset(progress: Callable[[int, int], Any], start: int, total: int) -> Callable[[int, int], Any]:
    """A batch's ``progress(done, runs)`` as the campaign's, for a chunk from run ``start``."""
    return lambda done, _runs: progress(start + done, total)


def _ee_positions(arm: FlexibleArm, x: Array) -> Array:
    """Every end-effector's position (m, inertial frame) at state ``x``, (k, 3)."""
    return np.stack([np.asarray(arm.ee_pose(x, ee=e)[:3]) for e in range(len(arm.robot.ee_links))])


def _run_chunk_task(campaign: Campaign, start: int, stop: int, nominal_ee: Array,
                    threads: int) -> Tuple[Any, Dict[str, Any]]:
    """A Dask task: one chunk of runs, with where and how long it ran."""
    began = time.time()
    piece = campaign.run_chunk(start, stop, nominal_ee, threads)
    try:
        from dask.distributed import get_worker

        worker = get_worker().address
    except (ImportError, ValueError):  # pragma: no cover
        worker = "?"
    return piece, {"start": start, "stop": stop, "worker": worker, "host": socket.gethostname(),
                   "pid": os.getpid(), "seconds": time.time() - began}


def summary(table: "pd.DataFrame") -> "pd.DataFrame":
    """Percentiles of each metric over the runs that finished: count, mean, std, min, p5, p50,
    p95, p99, max, one row per metric, with its unit."""
    import pandas as pd

    finished = table[table["ok"]]
    rows = []
    for metric, unit in METRICS.items():
        v = finished[metric].to_numpy(dtype=np.float64)
        v = v[np.isfinite(v)]
        stats: Dict[str, Any] = {"metric": metric, "unit": unit, "count": int(v.size)}
        if v.size:
            stats.update(mean=float(v.mean()), std=float(v.std(ddof=1)) if v.size > 1 else 0.0, min=float(v.min()))
            for p in (5, 50, 95, 99):
                stats[f"p{p}"] = float(np.percentile(v, p))
            stats["max"] = float(v.max())
        rows.append(stats)
    return pd.DataFrame(rows).set_index("metric")


def write_outputs(table: "pd.DataFrame", campaign: Campaign, out: Union[str, "os.PathLike[str]"],
                  plots: bool = True) -> List[Path]:
    """Writes ``runs.parquet`` (the table), ``summary.csv`` (:func:`summary`), ``log.jsonl``
    (where and how long each chunk ran) and, with ``plots``, ``histograms.png`` (one panel per
    metric) into the folder ``out``, created if missing. Returns the files written."""
    import json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = [out / "runs.parquet", out / "summary.csv", out / "log.jsonl"]
    table.to_parquet(files[0], index=False)
    summary(table).to_csv(files[1])
    with open(files[2], "w") as log:
        for entry in sorted(campaign.log, key=lambda e: e["start"]):
            log.write(json.dumps(entry) + "\n")
    if plots:
        files.append(histograms(table, campaign, out / "histograms.png"))
    return files


def histograms(table: "pd.DataFrame", campaign: Campaign, path: Path) -> Path:
    """One histogram per metric over the runs that finished, with its unit, the campaign's name,
    model, dt and number of runs in the caption."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    finished = table[table["ok"]]
    failed = int((~table["ok"]).sum())
    robot = campaign._robot()
    fig, axes = plt.subplots(2, 3, figsize=(11, 6.5), layout="constrained")
    caption = (f"campaign {campaign.name}: {len(table)} runs ({failed} failed), model {robot.name}, "
               f"dt = {campaign.dt:g} s, {campaign.duration:g} s each, seed {campaign.seed}")
    fig.suptitle(f"Metrics over the runs that finished\n{caption}", fontsize=11)
    for ax, (metric, unit) in zip(axes.flat, METRICS.items()):
        values = finished[metric].to_numpy(dtype=np.float64)
        values = values[np.isfinite(values)]
        if values.size:
            ax.hist(values, bins=min(40, max(5, int(np.sqrt(values.size)) * 2)), color="#4477aa")
            for p, style in ((50, "-"), (95, "--")):
                ax.axvline(np.percentile(values, p), color="#cc3311", ls=style, lw=1, label=f"p{p}")
            ax.legend(fontsize=8)
        missing = len(finished) - values.size
        title = TITLES[metric] + (f" ({missing} undefined)" if missing else "")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(unit)
        ax.set_ylabel("runs")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


__all__ = ["Campaign", "Dispersion", "CampaignError", "ChunkLog", "summary", "write_outputs", "histograms",
           "PARAMETERS", "METRICS"]
