# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
# (pandas, Dask and their stubs come with orbitflex[campaign]: a base install type-checks clean)
"""Campaign files: the tables of a TOML campaign file read into a :class:`Campaign`'s fields."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, Mapping, Optional, Sequence, Type, Union

from .. import FlexibleJoints, ModelError, Robot, models
from ..wheels_file import WheelsFile, WheelsFileError, read_wheels
from .dispersion import JOINT_PARAMETERS, CampaignError, Dispersion

if TYPE_CHECKING:
    from .spec import Campaign


def _wheels_file(spec: Mapping[str, Any], base: Optional[Path], source: str,
                 wheels: Union[None, str, "os.PathLike[str]", WheelsFile]) -> Optional[WheelsFile]:
    """The wheels of a campaign: ``wheels`` (a :class:`WheelsFile` or its path) if given, else the
    file's ``wheels = "PATH"`` (relative to the campaign file's folder), else none."""
    if isinstance(wheels, WheelsFile):
        return wheels
    if wheels is None:
        given = spec.get("wheels")
        if given is None:
            return None
        if not isinstance(given, str):
            raise CampaignError(f"{source}: wheels: expected the path of a wheels file (examples/wheels.toml), "
                                f"given {given!r}")
        path = Path(given)
        wheels = path if path.is_absolute() or base is None else base / path
    try:
        return read_wheels(Path(wheels))
    except (WheelsFileError, FileNotFoundError) as e:
        raise CampaignError(f"{source}: wheels: {e}") from None


def read_campaign_toml(path: Path) -> Dict[str, Any]:
    """The tables of a campaign file (slew or capture): ``FileNotFoundError`` when it cannot be
    read, ``CampaignError`` for malformed TOML, each naming the file."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    try:
        text = path.read_text()
    except OSError as e:
        raise FileNotFoundError(f"{path}: cannot read the campaign file ({e.strerror})") from None
    try:
        spec: Dict[str, Any] = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise CampaignError(f"{path}: malformed TOML: {e}") from None
    return spec


def campaign_from_dict(cls: Type[Campaign], spec: Mapping[str, Any], base: Optional[Path],
                       source: str, wheels: Union[None, str, "os.PathLike[str]", WheelsFile] = None) -> Campaign:
    """:meth:`Campaign.from_dict`: reads the tables of a campaign file into ``cls``'s fields;
    ``wheels`` (a wheels file or its path) replaces the file's ``wheels`` key."""
    known = {"name", "runs", "seed", "robot", "joints", "simulation", "slew", "dispersion", "wheels"}
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
    wheels_file = _wheels_file(spec, base, source, wheels)
    bus: Dict[str, Any] = {} if wheels_file is None else dict(
        wheels=wheels_file.wheels, attitude_kp=wheels_file.kp, attitude_kd=wheels_file.kd)
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
                   settle_tolerance=slew_t.get("settle_tolerance", 5e-3), **bus)
    try:
        campaign.check()
    except CampaignError as e:
        raise CampaignError(f"{source}: {e}") from None
    return campaign
