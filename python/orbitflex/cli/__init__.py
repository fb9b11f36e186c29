# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""Command line: ``orbitflex demo``, ``orbitflex simulate URDF``, ``orbitflex plan URDF`` and
``orbitflex campaign FILE``.

``demo`` and ``simulate`` run the same job: a free-floating slew of the arm under the built-in
motor-side PD controller, long enough to show the base's reaction and the joints' vibration, then
print a summary and write the trajectory, ``summary.json`` and plots into an output folder. The
PD's gains come from ``--bandwidth`` and ``--damping-ratio`` (:meth:`FlexibleArm.motor_pd_gains`)
or from ``--kp``/``--kd``, never from ``--dt``; a ``--dt`` past the closed loop's RK4 stability
limit is refused unless ``--force``. The
demo then plans a minimum-time slew of the built-in arm under limits, with the flexible joints
and as if they were rigid, runs both plans on the flexible arm and compares them.

``plan`` does that for a URDF: it plans the minimum-time slew to ``--goal`` under
``--motor-torque``, ``--joint-speed`` (and, for a held base, ``--base-force``, ``--base-torque``)
limits, plans it again as if the joints were rigid, tracks both on the flexible arm, and writes
the plans, the comparison, ``plan_summary.json`` and plots.

``capture`` runs the built-in capture of a tumbling target (:mod:`orbitflex.cli.capture`).

``modes`` prints the structural modes of an arm and draws them (:mod:`orbitflex.cli.modes`).
``fmu`` writes an FMI co-simulation FMU of an arm (:mod:`orbitflex.cli.fmu`).

``campaign`` runs a Monte-Carlo campaign file (:mod:`orbitflex.campaign`) locally or on a Dask
cluster (``--scheduler``) and writes the per-run table ``runs.parquet``, ``summary.csv``
(percentiles), ``log.jsonl`` and ``histograms.png``.

Exit codes: 0 for a completed run, 1 when a run diverged (the outputs then describe the finite
part before the failure; ``plan`` writes none; ``campaign``: when any run did, the table marks
it), 2 for a usage error (one line ``orbitflex: error: FLAG: ...``).

The package holds one module per command (``simulate`` for ``demo`` and ``simulate``, ``plan``,
``campaign``, ``modes``), their plots (``plots``, ``plan_plots``), the summaries (``summary``), the
parser (``parser``), the errors and argument types (``errors``), and what the commands share
(``jobs``, ``robots``, ``slew``, ``memory``). Every name this module has always had is importable
from it.
"""

from __future__ import annotations

import os
import sys
from typing import List, Optional

# the commands' modules, and every name ``orbitflex.cli`` has always had
from .campaign import campaign_command
from .errors import (
    CliError, Parser, at_least_one, cli_words, fail, finite, non_negative, output_folder,
    package_dir, positive, urdf_error,
)
from .jobs import Job, Outcome, ProgressBar, WarningPrinter, failure_reason
from .memory import check_memory, free_memory, gb, recorded_rows, run_bytes
from .parser import (
    CAMPAIGN_EPILOG, build_parser, closest_flag, command_flags, common_options, model_options,
    plan_options, reject_extra, simulate_options,
)
from .plan import (
    Comparison, DEMO_PLAN_GOAL, MEASURES, PLAN_EPILOG, PLAN_ERROR_FLAGS, PLAN_OUTPUTS, SAMPLED,
    SERVO_HZ, TRACK_DT, check_stops, compare, comparison_summary, demo_comparison, describe,
    describe_binding, limits_dict, limits_source, plan_arrays, plan_command, plan_error, plan_job,
    plan_limits, print_comparison, print_plan_summary, servo_gains, tracking_dt, tracking_limit,
    tracking_setup, tracking_steps_flag, write_plan_outputs,
)
from .plan_plots import (
    against_limit, joint_panels, key_label, log_floor, mark_binding, mark_segments, plan_caption,
    plot_plan, plot_plan_angles, plot_plan_base, plot_plan_deflection, plot_plan_limited,
    plot_plan_speed, plot_plan_torque, plot_plan_vs_rigid, relative_rotation, run_series,
)
from .plots import (
    Figures, PLOT_POINTS, cube_edges, draw_arm, equal_axes, euler_zyx, joint_legend, plot,
    plot_angles, plot_attitude, plot_deflection, plot_ee_path, plot_ee_zoom, plot_momentum,
    plot_rows, power_of_ten, rotation_matrix, seconds, tick_interval,
)
from .robots import (
    BUS_SIDE, DEFAULTS_RULE, DEFAULTS_SCALING, joint_list, load_arm, load_robot, mount_on_bus,
    sketch_side,
)
from .simulate import (
    OUTPUTS, SIMULATE_EPILOG, animation, demo_job, print_demo_comparison, run, simulate,
    simulate_job, write_outputs,
)
from .slew import (
    Array, DT_MARGIN, Gains, Rows, SPACE_ARM_SLEW, check_step, choose_gains, per_joint, round_down,
    slew_controller,
)
from .summary import (
    DIVERGED_BALANCE, angle_unit, divergence_onset, ee_paths, ee_travel, energy_balance,
    energy_steps, gain_range, gain_text, print_summary, rotation_angle_deg, summarise, torque_share,
)
from .._reference import quintic

__all__ = [
    "Array",
    "BUS_SIDE",
    "CAMPAIGN_EPILOG",
    "CliError",
    "Comparison",
    "DEFAULTS_RULE",
    "DEFAULTS_SCALING",
    "DEMO_PLAN_GOAL",
    "DIVERGED_BALANCE",
    "DT_MARGIN",
    "Figures",
    "Gains",
    "Job",
    "MEASURES",
    "OUTPUTS",
    "Outcome",
    "PLAN_EPILOG",
    "PLAN_ERROR_FLAGS",
    "PLAN_OUTPUTS",
    "PLOT_POINTS",
    "Parser",
    "ProgressBar",
    "Rows",
    "SAMPLED",
    "SERVO_HZ",
    "SIMULATE_EPILOG",
    "SPACE_ARM_SLEW",
    "TRACK_DT",
    "WarningPrinter",
    "against_limit",
    "angle_unit",
    "animation",
    "at_least_one",
    "build_parser",
    "campaign_command",
    "check_memory",
    "check_step",
    "check_stops",
    "choose_gains",
    "cli_words",
    "closest_flag",
    "command_flags",
    "common_options",
    "compare",
    "comparison_summary",
    "cube_edges",
    "demo_comparison",
    "demo_job",
    "describe",
    "describe_binding",
    "divergence_onset",
    "draw_arm",
    "ee_paths",
    "ee_travel",
    "energy_balance",
    "energy_steps",
    "equal_axes",
    "euler_zyx",
    "fail",
    "failure_reason",
    "finite",
    "free_memory",
    "gain_range",
    "gain_text",
    "gb",
    "joint_legend",
    "joint_list",
    "joint_panels",
    "key_label",
    "limits_dict",
    "limits_source",
    "load_arm",
    "load_robot",
    "log_floor",
    "main",
    "mark_binding",
    "mark_segments",
    "model_options",
    "mount_on_bus",
    "non_negative",
    "output_folder",
    "package_dir",
    "per_joint",
    "plan_arrays",
    "plan_caption",
    "plan_command",
    "plan_error",
    "plan_job",
    "plan_limits",
    "plan_options",
    "plot",
    "plot_angles",
    "plot_attitude",
    "plot_deflection",
    "plot_ee_path",
    "plot_ee_zoom",
    "plot_momentum",
    "plot_plan",
    "plot_plan_angles",
    "plot_plan_base",
    "plot_plan_deflection",
    "plot_plan_limited",
    "plot_plan_speed",
    "plot_plan_torque",
    "plot_plan_vs_rigid",
    "plot_rows",
    "positive",
    "power_of_ten",
    "print_comparison",
    "print_demo_comparison",
    "print_plan_summary",
    "print_summary",
    "quintic",
    "recorded_rows",
    "reject_extra",
    "relative_rotation",
    "rotation_angle_deg",
    "rotation_matrix",
    "round_down",
    "run",
    "run_bytes",
    "run_series",
    "seconds",
    "servo_gains",
    "simulate",
    "simulate_job",
    "simulate_options",
    "sketch_side",
    "slew_controller",
    "summarise",
    "tick_interval",
    "torque_share",
    "tracking_dt",
    "tracking_limit",
    "tracking_setup",
    "tracking_steps_flag",
    "urdf_error",
    "write_outputs",
    "write_plan_outputs",
]


def main(argv: Optional[List[str]] = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:
        reject_extra(args, extra, parser)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        if args.command == "plan":
            return plan_command(args)
        if args.command == "campaign":
            return campaign_command(args)
        if args.command == "modes":
            from . import modes

            return modes.command(args)
        if args.command == "fmu":
            from . import fmu

            return fmu.command(args)
        if args.command == "capture":
            from . import capture

            return capture.command(args)
        if args.dt > args.duration:
            raise CliError("--dt", f"expected at most --duration ({args.duration:g} s), given {args.dt:g}")
        job = demo_job(args) if args.command == "demo" else simulate_job(args)
        return run(job, args)
    except CliError as e:
        print(f"orbitflex: error: {e}", file=sys.stderr)
        return 2
    except MemoryError:
        print("orbitflex: error: --duration/--dt: out of memory; shorten --duration or lengthen --dt",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("orbitflex: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # stdout closed early (`orbitflex demo | head`): the files are written
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1


if __name__ == "__main__":
    sys.exit(main())
