"""``orbitflex fmu [URDF]``: writes an FMI co-simulation FMU (3.0, or 2.0 with ``--fmi 2``) of an
arm, for FMPy, Simulink's FMU Import block or any FMI master.

A self-contained command: :func:`add_parser` adds it to the CLI's subparsers and :func:`command`
runs it. The FMU is made by :func:`orbitflex.fmu.write_fmu` (the files by the Rust core); this
module only reads the flags.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, List

from .. import SPACE_ARM_URDF, FlexibleArm, FlexibleJoints, models
from ..fmu import write_fmu

DESCRIPTION = """\
Writes a co-simulation FMU of your URDF (default: the built-in space arm) with its joint
parameters: FMI 3.0, or FMI 2.0 with --fmi 2 (older Simulink releases and most tools). The FMU
steps the arm with RK4 at --dt; a master's communication step must be a whole multiple of it.
Inputs: motor_torque.<joint> (N.m), base_force.{x,y,z} (N), base_moment.{x,y,z} (N.m, base
frame). Outputs: q, qd, theta, theta_dot, deflection, spring_torque per joint, the base pose and
twist, the end-effector poses, momentum and energy. Parameters: the joint parameters and q0.<joint>,
settable before initialisation. --base-mass mounts the arm on a bus, as for 'simulate'. With
--wheels (the file of 'simulate --wheels'; its [attitude_pd] is not used: the master commands
the wheels) the FMU adds per wheel k the input wheel_torque.<k> (N.m, saturated as in simulate),
the outputs wheel_speed.<k> (rad/s) and applied_wheel_torque.<k> (N.m) and the parameter
wheel_speed0.<k> (rad/s). See docs/cosimulation.md."""

EPILOG = """\
examples:
  orbitflex fmu --out space_arm.fmu                       # the built-in arm, FMI 3.0, dt = 1 ms
  orbitflex fmu --fmi 2 --out space_arm_fmi2.fmu
  orbitflex fmu arm.urdf --params joints.toml --ee-link tool0 --dt 5e-4 --out arm.fmu
  orbitflex fmu --wheels examples/wheels.toml --out space_arm_wheels.fmu   # reaction wheels on the bus
  orbitflex fmu arm.urdf --base-mass 800 --base-com 0 0 -0.75 --out arm.fmu
  python -m fmpy.gui space_arm.fmu   # or: fmpy simulate space_arm.fmu / fmpy validate space_arm.fmu
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Adds ``fmu`` to the CLI's subparsers."""
    from .robots import add_bus_arguments, add_robot_arguments
    from .errors import positive

    p: argparse.ArgumentParser = subparsers.add_parser(
        "fmu", help="write an FMI 3.0 (or 2.0) co-simulation FMU of an arm",
        description=DESCRIPTION, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_robot_arguments(p)
    add_bus_arguments(p)
    p.add_argument("--wheels", metavar="TOML", default=None,
                   help="reaction wheels on the bus: the file of 'simulate --wheels' (see examples/wheels.toml); "
                        "the FMU takes their torque commands as inputs")
    p.add_argument("--dt", metavar="S", type=positive, default=1e-3,
                   help="the FMU's internal RK4 step, s (default %(default)s)")
    p.add_argument("--fmi", type=int, choices=(2, 3), default=3, help="FMI version (default %(default)s)")
    p.add_argument("--model-identifier", metavar="ID", default=None,
                   help="the binary's name, a C identifier (default: the robot's name)")
    p.add_argument("--out", metavar="FILE", default=None,
                   help="the FMU to write (default: <model identifier>.fmu)")
    return p


def command(args: argparse.Namespace) -> int:
    """Writes the FMU and prints what it holds."""
    from .errors import CliError, cli_words
    from .robots import joint_list, load_robot, mount_on_bus

    if args.urdf is None:
        for flag, value in (("--ee-link", args.ee_link), ("--ee-links", args.ee_links),
                            ("--locked-joints", args.locked_joints)):
            if value:
                raise CliError(flag, "applies to a URDF; give the URDF file (the built-in arm has one end-effector, ee)")
        urdf = SPACE_ARM_URDF
        robot = models.space_arm()
        ee_links: List[str] = []
        locked: List[str] = []
    else:
        try:
            urdf = Path(args.urdf).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            raise CliError("URDF", f"cannot read {args.urdf}: {e}") from None
        robot = load_robot(args)
        ee_links = [args.ee_link] if args.ee_link else joint_list(args.ee_links)
        locked = joint_list(args.locked_joints)
    robot = mount_on_bus(robot, args)[0]
    try:
        if args.params is not None:
            joints = FlexibleJoints.from_toml(args.params, robot)
        elif args.urdf is None:
            joints = models.space_arm_joints()
        else:
            joints = FlexibleJoints.defaults_for(robot)
        arm = FlexibleArm(robot, joints)
    except (ValueError, OSError) as e:
        raise CliError("--params", cli_words(str(e))) from None
    if args.wheels is not None:
        from ..wheels_file import WheelsFileError, read_wheels

        try:
            arm = FlexibleArm(robot, joints, wheels=read_wheels(args.wheels).wheels)
        except (WheelsFileError, ValueError) as e:
            raise CliError("--wheels", cli_words(str(e))) from None
    from ..fmu import _identifier

    ident = args.model_identifier if args.model_identifier is not None else _identifier(robot.name)
    out = args.out if args.out is not None else f"{ident}.fmu"
    try:
        path = write_fmu(out, urdf, arm, args.dt, fmi=args.fmi, ee_links=ee_links, locked_joints=locked,
                         model_identifier=ident)
    except FileNotFoundError as e:
        raise CliError("fmu", str(e)) from None
    except ValueError as e:
        flag = "--model-identifier" if "model_identifier" in str(e) else "--dt" if str(e).startswith("dt") else "URDF"
        raise CliError(flag, cli_words(str(e))) from None
    note = "" if args.params is not None or args.urdf is None else " (joint parameters scaled to the links: give --params)"
    k = 0 if arm.wheels is None else len(arm.wheels)
    wheels = f", {k} reaction wheel{'s' if k > 1 else ''} (inputs wheel_torque.0..{k - 1})" if k else ""
    bus = f", on a {args.base_mass:g} kg bus" if args.base_mass is not None else ""
    print(f"wrote {path}: FMI {args.fmi}.0 co-simulation, {robot.name} ({arm.dof} joints){bus}{wheels}, "
          f"dt = {args.dt:g} s{note}")
    print(f"  run it: python -c \"import fmpy; fmpy.dump('{path}')\"  (pip install fmpy)")
    return 0
