# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""The robot of a command: the built-in arm or a URDF, mounted on a bus if asked, with its joint
parameters."""

from __future__ import annotations

import argparse
from typing import List, Optional, TYPE_CHECKING, Tuple

import numpy as np

from .. import FlexibleArm, FlexibleJoints, Robot, models
from .errors import CliError, cli_words, finite, positive, urdf_error

if TYPE_CHECKING:
    from .slew import Array


# Side (m) of the built-in arm's bus, and of the solid cube that --base-mass alone stands for
# (Robot.with_base_inertia's default).
BUS_SIDE = models.DEFAULT_BUS_SIDE


DEFAULTS_SCALING = ("each joint rings at 5 Hz with its motor held, motor inertia = the link-side "
                    "inertia it sees at q = 0, damping 5 % of critical, no motor friction")


DEFAULTS_RULE = (f"joint parameters: FlexibleJoints.defaults_for(robot), scaled to the links "
                 f"({DEFAULTS_SCALING}); give your actuator data with --params joints.toml")


def joint_list(values: Optional[List[str]]) -> List[str]:
    """``--locked-joints a,b --locked-joints c`` -> ``[a, b, c]``."""
    return [name.strip() for value in values or [] for name in value.split(",") if name.strip()]


def load_robot(args: argparse.Namespace) -> Robot:
    locked = joint_list(args.locked_joints)
    try:
        robot = Robot.from_urdf(args.urdf, ee_link=args.ee_link, locked_joints=locked or None,
                                ee_links=joint_list(args.ee_links) or None)
    except (ValueError, OSError) as e:
        raise urdf_error(e) from None
    if robot.dof == 0:
        held = f"with {', '.join(locked)} locked" if locked else "(every joint is fixed)"
        raise CliError("--locked-joints", f"'{robot.name}' has no moving joints {held}: nothing to "
                                          f"simulate; keep at least one revolute joint unlocked")
    return robot


def mount_on_bus(robot: Robot, args: argparse.Namespace) -> Tuple[Robot, float, Array]:
    """The robot on the bus given by --base-mass/--base-inertia/--base-com, and the side (m) and
    centre of the cube drawn for it."""
    com = np.zeros(3) if args.base_com is None else np.asarray(args.base_com)
    if args.base_mass is None:
        for flag, value in (("--base-inertia", args.base_inertia), ("--base-com", args.base_com)):
            if value is not None:
                raise CliError(flag, "describes the bus given by --base-mass KG; add --base-mass")
        return robot, sketch_side(robot), com
    mass = args.base_mass
    inertia = None if args.base_inertia is None else np.asarray(args.base_inertia)
    try:
        robot = robot.with_base_inertia(mass, inertia, com)  # default: the solid cube of BUS_SIDE
    except ValueError as e:
        message = str(e)
        flag = "--base-com" if message.startswith("com") else "--base-inertia" if "inertia" in message else "--base-mass"
        raise CliError(flag, message) from None
    if inertia is None:
        return robot, BUS_SIDE, com
    # the solid cube with this mass and (mean) inertia: I = m s² / 6
    return robot, max(float(np.sqrt(6 * max(float(inertia.mean()), 0.0) / mass)), 1e-3), com


def sketch_side(robot: Robot) -> float:
    """Edge (m) of the cube drawn for a base of unknown size: twice the distance to the first
    joint's body, at most 30 % of the arm's reach (at q = 0)."""
    bodies = robot.body_poses(np.r_[np.zeros(6), 1.0], np.zeros(robot.dof))[:, :3]
    reach = float(np.linalg.norm(bodies, axis=1).max())
    return max(min(2 * float(np.linalg.norm(bodies[1])), 0.3 * reach), 1e-3)


def load_arm(args: argparse.Namespace) -> Tuple[FlexibleArm, float, Array, Optional[str]]:
    """The URDF's arm on its bus with the joint parameters of --params (or the scaled defaults);
    with the side and centre of the cube drawn for the bus, and a note when the defaults are
    used."""
    robot = load_robot(args)
    robot, side, com = mount_on_bus(robot, args)
    note = None
    try:
        if args.params is None:
            joints, note = FlexibleJoints.defaults_for(robot), DEFAULTS_RULE
        else:
            joints = FlexibleJoints.from_toml(args.params, robot)
        arm = FlexibleArm(robot, joints)
    except (ValueError, OSError) as e:
        raise CliError("--params", cli_words(str(e))) from None
    return arm, side, com, note


def add_robot_arguments(p: argparse.ArgumentParser) -> None:
    """The arm a command reads (``modes``, ``fmu``): an optional URDF (default: the built-in space
    arm), ``--params``, ``--ee-link``/``--ee-links`` and ``--locked-joints``, read by
    :func:`load_robot` and :func:`joint_list`."""
    p.add_argument("urdf", metavar="URDF", nargs="?", default=None,
                   help="path to the URDF; the root link is the floating base (default: the built-in space arm)")
    p.add_argument("--params", metavar="TOML", default=None,
                   help="joint parameters keyed by joint name, as for 'orbitflex simulate' (default: "
                        "the built-in arm's, or scaled to the links)")
    p.add_argument("--ee-link", metavar="LINK", default=None, help="the one end-effector link")
    p.add_argument("--ee-links", metavar="LINKS", action="append", default=None,
                   help="end-effector links of a tree: a comma-separated list; repeatable")
    p.add_argument("--locked-joints", metavar="NAMES", action="append", default=None,
                   help="joints held at zero: a comma-separated list; repeatable")


def add_bus_arguments(p: argparse.ArgumentParser) -> None:
    """The bus the arm is mounted on (``simulate``, ``plan``, ``fmu``): ``--base-mass``,
    ``--base-inertia`` and ``--base-com``, read by :func:`mount_on_bus`."""
    p.add_argument("--base-mass", metavar="KG", type=positive, default=None,
                   help="mount the arm on a bus of this mass, replacing the root link's inertia")
    p.add_argument("--base-inertia", metavar=("IXX", "IYY", "IZZ"), type=finite, nargs=3, default=None,
                   help=f"the bus's principal moments about its COM, kg·m² (default: a solid "
                        f"{BUS_SIDE:g} m cube of --base-mass)")
    p.add_argument("--base-com", metavar=("X", "Y", "Z"), type=finite, nargs=3, default=None,
                   help="the bus's COM in the root link's frame, m (default 0 0 0, the root link's "
                        "origin; 0 0 -0.75 puts a 1.5 m bus under an arm that points up z)")
