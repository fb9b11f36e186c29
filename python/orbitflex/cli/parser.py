# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""The parser: the commands, their flags, their help."""

from __future__ import annotations

import argparse
from typing import List, NoReturn, Optional, Sequence

from .. import __version__
from .errors import Parser, at_least_one, fail, finite, non_negative, package_dir, positive
from .plan import PLAN_EPILOG, SERVO_HZ, TRACK_DT
from .robots import add_bus_arguments
from .simulate import SIMULATE_EPILOG
from .slew import DT_MARGIN


def common_options(p: argparse.ArgumentParser, duration: float) -> None:
    p.add_argument("--duration", metavar="S", type=positive, default=duration,
                   help="simulated time, s (default %(default)s)")
    p.add_argument("--dt", metavar="S", type=positive, default=1e-3, help="RK4 step, s (default %(default)s)")
    p.add_argument("--slew-time", metavar="S", type=positive, default=5.0,
                   help="duration of the quintic slew, s (default %(default)s)")
    pd = p.add_argument_group("the motor PD (chosen from the physics, never from --dt)")
    pd.add_argument("--bandwidth", metavar="HZ", type=positive, default=0.25,
                    help="closed-loop bandwidth of each joint, Hz: the gains come from it, the damping "
                         "ratio and each joint's motor inertia, link inertia at q = 0 and spring "
                         "(FlexibleArm.motor_pd_gains; default %(default)s)")
    pd.add_argument("--damping-ratio", metavar="ZETA", type=positive, default=1.0,
                    help="closed-loop damping ratio of each joint (default %(default)s: critical)")
    pd.add_argument("--kp", metavar="NM_PER_RAD", type=non_negative, nargs="+", default=None,
                    help="motor PD stiffness, N·m/rad, one value or one per joint (replaces the "
                         "bandwidth rule's)")
    pd.add_argument("--kd", metavar="NMS_PER_RAD", type=non_negative, nargs="+", default=None,
                    help="motor PD damping, N·m·s/rad, one value or one per joint (replaces the "
                         "bandwidth rule's)")
    pd.add_argument("--force", action="store_true",
                    help="run even when --dt is past the RK4 stability limit of the closed loop "
                         "(refused otherwise); the run then warns and most likely diverges")
    p.add_argument("--wheels", metavar="TOML", default=None,
                   help="reaction wheels on the bus and the AttitudePD holding it (keys: "
                        "examples/wheels.toml): the slew is run again with them; the demo does so "
                        "with orbitflex.models.pyramid_wheels() when not given")
    p.add_argument("--out", metavar="DIR", default="orbitflex_out",
                   help="output folder, created if missing (default %(default)s)")
    p.add_argument("--csv", action="store_true", help="also write trajectory.csv (t and x, named columns)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--no-animation", action="store_true",
                   help="skip animation.html (the 3-D view; written when orbitflex[viz] is installed)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--record-every", metavar="K", type=at_least_one, default=1,
                   help="keep every K-th step's state and the last (rows at t = 0, K·dt, 2K·dt, ..., "
                        "and the end): K times less memory and output for long runs; the energy "
                        "balance then is not computed (default %(default)s: every step)")


def model_options(p: argparse.ArgumentParser, verb: str) -> None:
    """The URDF, its joint parameters and its bus."""
    p.add_argument("urdf", metavar="URDF", help="path to the URDF; the root link is the floating base")
    p.add_argument("--params", metavar="TOML", default=None,
                   help="joint parameters keyed by joint name (keys below; default: scaled to the links)")
    p.add_argument("--ee-link", metavar="LINK", default=None,
                   help="the one end-effector link (default: every leaf link is an end-effector)")
    p.add_argument("--ee-links", metavar="LINKS", action="append", default=None,
                   help="end-effector links of a tree, in order: a comma-separated list; repeatable")
    p.add_argument("--package", metavar="NAME=DIR", type=package_dir, action="append", default=None,
                   help="where the ROS package NAME of package:// meshes is (for animation.html); "
                        "repeatable; ROS_PACKAGE_PATH and the folders above the URDF are searched too")
    p.add_argument("--locked-joints", metavar="NAMES", action="append", default=None,
                   help="joints held at zero (e.g. fingers): a comma-separated list; repeatable")
    if verb == "simulate":
        p.add_argument("--slew", metavar="RAD", type=finite, nargs="+", default=None,
                       help="slew per joint, rad: one value for every joint, or one per joint (default 0.3)")
    add_bus_arguments(p)


def simulate_options(sim: argparse.ArgumentParser) -> None:
    model_options(sim, "simulate")


def plan_options(p: argparse.ArgumentParser) -> None:
    model_options(p, "plan")
    slew = p.add_argument_group("the slew (rad, link side; one value for every joint, or one per joint)")
    slew.add_argument("--goal", metavar="RAD", type=finite, nargs="+", required=True, help="where the slew ends")
    slew.add_argument("--start", metavar="RAD", type=finite, nargs="+", default=None,
                      help="where it starts, at rest with relaxed springs (default 0)")
    slew.add_argument("--waypoint", metavar="RAD", type=finite, nargs="+", action="append", default=None,
                      help="a stop on the way, where the arm comes to rest; repeatable, in order")
    slew.add_argument("--base", choices=("held", "free"), default="held",
                      help="held: the bus's actuators hold it inertially still (and --base-force, "
                           "--base-torque bound them); free: free floating from rest (default %(default)s)")
    limits = p.add_argument_group("limits (link side; one value for every joint, or one per joint)")
    limits.add_argument("--motor-torque", metavar="NM", type=positive, nargs="+", default=None,
                        help="|u_i| bound, N·m (motor torque after the gearbox; default: the URDF's "
                             "<limit effort>; more than it warns)")
    limits.add_argument("--joint-speed", metavar="RAD_S", type=positive, nargs="+", default=None,
                        help="|q̇_i| bound, rad/s (default: the URDF's <limit velocity>; more than it warns)")
    limits.add_argument("--base-force", metavar="N", type=positive, default=None,
                        help="bound on the norm of the force holding the bus, N (--base held; default none)")
    limits.add_argument("--base-torque", metavar="NM", type=positive, default=None,
                        help="bound on the norm of the moment holding the bus, about the root link's origin "
                             "(not the bus COM when --base-com moves it), N·m (--base held; default none)")
    runs = p.add_argument_group("the tracking runs (both plans simulated on the flexible arm)")
    runs.add_argument("--dt", metavar="S", type=positive, default=None,
                      help=f"RK4 step, s (default {TRACK_DT:g}, lowered when past {DT_MARGIN * 100:.0f}%% of the "
                           "RK4 stability limit of the arm under the PD; a --dt past the limit is refused)")
    runs.add_argument("--kp", metavar="NM_PER_RAD", type=non_negative, nargs="+", default=None,
                      help=f"motor PD stiffness, N·m/rad (default j·(2π·{SERVO_HZ:g} Hz)², j the motor inertia)")
    runs.add_argument("--kd", metavar="NMS_PER_RAD", type=non_negative, nargs="+", default=None,
                      help=f"motor PD damping, N·m·s/rad (default 2 j·(2π·{SERVO_HZ:g} Hz))")
    runs.add_argument("--settle", metavar="S", type=non_negative, default=2.0,
                      help="time simulated at rest after each slew, to measure the residual vibration, s "
                           "(default %(default)s)")
    runs.add_argument("--wheels", metavar="TOML", default=None,
                      help="reaction wheels on the bus and their AttitudePD (keys: examples/wheels.toml; "
                           "--base held): reports what holding the bus asks of them (Plan.wheel_demand) "
                           "and tracks the plan with them holding it, printing the pointing error and "
                           "the wheels' peak speed and torque against their limits")
    p.add_argument("--out", metavar="DIR", default="orbitflex_out",
                   help="output folder, created if missing (default %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")


def build_parser() -> Parser:
    parser = Parser(prog="orbitflex", description="Flexible-joint space manipulator simulation: a "
                    "free-floating slew of an arm on a spacecraft bus.")
    parser.add_argument("--version", action="version", version=f"orbitflex {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="{demo,simulate,plan,campaign,modes,fmu,capture}")
    demo = sub.add_parser("demo", help="simulate the built-in space arm (bus + 7-joint arm), free floating",
                          description="Simulates the built-in space arm (a 500 kg bus with a 7-joint arm) "
                                      "slewing free-floating, and writes the trajectory, a summary and plots.")
    common_options(demo, 20.0)
    sim = sub.add_parser("simulate", help="simulate your URDF, free floating, with the same slew",
                         description="Simulates your URDF slewing free-floating (every joint by --slew\n"
                                     "under a motor PD), and writes the trajectory, a summary and plots.",
                         epilog=SIMULATE_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    simulate_options(sim)
    common_options(sim, 10.0)
    plan = sub.add_parser("plan", help="plan a minimum-time slew of your URDF under limits, beside its "
                          "rigid-joint plan",
                          description="Plans the minimum-time rest-to-rest slew of your URDF under motor-torque,\n"
                                      "joint-speed and base limits with the flexible-joint model, plans the same\n"
                                      "slew as if the joints were rigid, simulates both on the flexible arm, and\n"
                                      "writes the plans, the comparison, a summary and plots.",
                          epilog=PLAN_EPILOG + "\n" + SIMULATE_EPILOG.split("\nexamples:")[0],
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    plan_options(plan)
    camp = sub.add_parser("campaign", help="run a Monte-Carlo campaign file, locally or on a Dask cluster",
                          description="Runs the Monte-Carlo campaign declared in FILE (see examples/campaign.toml):\n"
                                      "many slews with dispersed parameters, locally on every core or on a Dask\n"
                                      "cluster, and writes one row per run to DIR/runs.parquet, percentiles to\n"
                                      "DIR/summary.csv and histograms to DIR/histograms.png. The table is the\n"
                                      "same, bit for bit, wherever it runs.",
                          epilog=CAMPAIGN_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    camp.add_argument("file", metavar="FILE", help="the campaign file (TOML)")
    camp.add_argument("--runs", type=at_least_one, default=None, help="number of runs (default: the file's)")
    camp.add_argument("--scheduler", metavar="ADDRESS", default=None,
                      help="a Dask scheduler (tcp://host:8786); default: run here on every core")
    camp.add_argument("--scheduler-timeout", metavar="S", type=positive, default=10.0,
                      help="how long to wait for the scheduler to answer (default %(default)s s; a refused "
                           "connection fails at once)")
    camp.add_argument("--out", metavar="DIR", default="campaign_out",
                      help="output folder, created if missing (default %(default)s)")
    camp.add_argument("--chunk-runs", type=at_least_one, default=None, metavar="K",
                      help="runs per batch (per Dask task); default 256 here, about 4 tasks per worker thread on Dask")
    camp.add_argument("--threads", type=at_least_one, default=None,
                      help="threads per batch (default: every core here, 1 per Dask task)")
    camp.add_argument("--wheels", metavar="TOML", default=None,
                      help="reaction wheels holding every run's bus under their AttitudePD (keys: "
                           "examples/wheels.toml); replaces the file's wheels = PATH. Adds the wheel "
                           "metrics and lets the file disperse wheel_* and attitude_kp/kd")
    camp.add_argument("--no-plots", action="store_true", help="skip histograms.png")
    camp.add_argument("--no-progress", action="store_true", help="no progress bar")
    from . import modes  # `orbitflex modes` lives in its own module

    modes.add_parser(sub)
    from . import fmu  # `orbitflex fmu` too

    fmu.add_parser(sub)
    from . import capture  # `orbitflex capture` too

    capture.add_parser(sub)
    return parser


CAMPAIGN_EPILOG = """\
examples:
  orbitflex campaign examples/campaign.toml --runs 1000
  orbitflex campaign examples/campaign.toml --runs 1000 --scheduler tcp://127.0.0.1:8786

Start a local Dask cluster in another shell with:
  dask scheduler --host 127.0.0.1 &  dask worker tcp://127.0.0.1:8786 --nworkers 2 --nthreads 1
"""


def reject_extra(args: argparse.Namespace, extra: List[str], parser: Optional[argparse.ArgumentParser] = None) -> NoReturn:
    """Arguments argparse did not place: most likely a list given to --locked-joints with spaces,
    or a flag misspelt (``--base_mass``: did you mean ``--base-mass``?)."""
    if getattr(args, "locked_joints", None) and not any(word.startswith("-") for word in extra):
        fail(f"--locked-joints: takes one name or a comma-separated list per occurrence "
             f"(--locked-joints a,b); unexpected: {' '.join(extra)}")
    known = command_flags(parser, args.command) if parser is not None else []
    hints = [(flag.split("=", 1)[0], match) for flag in extra if flag.startswith("--")
             for match in [closest_flag(flag, known)] if match]
    where = f"(see 'orbitflex {args.command} --help')" if args.command else "(see 'orbitflex --help')"
    if hints:
        flag, match = hints[0]
        fail(f"{flag}: no such flag; did you mean {match}? {where}")
    fail(f"unrecognized arguments: {' '.join(extra)} {where}")


def command_flags(parser: argparse.ArgumentParser, command: Optional[str]) -> List[str]:
    """The long flags of ``orbitflex COMMAND`` (or of ``orbitflex`` itself)."""
    target = parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and command in action.choices:
            target = action.choices[command]
    return [flag for flag in target._option_string_actions if flag.startswith("--")]


def closest_flag(flag: str, known: Sequence[str]) -> Optional[str]:
    """The known flag ``flag`` most likely meant: the same with ``_`` for ``-`` or in another
    case, else the closest spelling (difflib, at least 80 % alike)."""
    import difflib

    name = flag.split("=", 1)[0]
    normal = name.replace("_", "-").lower()
    if normal in known:
        return normal
    close = difflib.get_close_matches(normal, known, n=1, cutoff=0.8)
    return close[0] if close else None
