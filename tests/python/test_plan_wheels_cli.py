"""``orbitflex plan --wheels wheels.toml``: the wheels' demand of a held-base plan and the plan
tracked with the wheels holding the bus, printed and in ``plan_summary.json``, equal to
``Plan.wheel_demand`` and ``Plan.track(..., wheel_torque=AttitudePD)`` made by hand; a free base
or a bad file is a one-line error naming ``--wheels``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import orbitflex as of
from orbitflex.wheels_file import read_wheels

ROOT = Path(__file__).resolve().parents[2]
URDF = ROOT / "models" / "space_arm.urdf"
WHEELS = ROOT / "examples" / "wheels.toml"
GOAL = ["0.24", "-0.18", "0.15", "0.3", "-0.21", "0.18", "0.27"]


def plan_cli(tmp_path, *extra):
    return subprocess.run([sys.executable, "-m", "orbitflex", "plan", str(URDF), "--goal", *GOAL, "--out",
                           str(tmp_path / "out"), "--no-plots", *extra], capture_output=True, text=True, timeout=300,
                          cwd=tmp_path)


def test_plan_with_wheels_reports_the_demand_and_the_tracked_run(tmp_path):
    done = plan_cli(tmp_path, "--wheels", str(WHEELS))
    assert done.returncode == 0, done.stderr
    summary = json.loads((tmp_path / "out" / "plan_summary.json").read_text())
    wheels = summary["wheels"]
    # by hand: the same arm (the CLI's default joints), plan and gains, with the file's wheels
    spec = read_wheels(WHEELS)
    robot = of.Robot.from_urdf(str(URDF))
    arm = of.FlexibleArm(robot, of.FlexibleJoints.defaults_for(robot), wheels=spec.wheels)
    plan = of.plan_slew(arm, np.array(GOAL, dtype=float), limits=of.Limits.from_urdf(robot), base="held")
    demand = plan.wheel_demand(spec.wheels)
    assert wheels["demand"]["peak_torque_Nm"] == demand["peak_torque"].tolist()
    assert wheels["demand"]["binding"]["limit"] == demand["binding"]["limit"] == "max_torque"
    kp, kd = np.array(summary["kp"]), np.array(summary["kd"])
    run = plan.track(summary["dt_s"], kp, kd, summary["settle_s"], wheel_torque=spec.controller())
    traj = run["trajectory"]
    quat = traj.base_pose[:, 3:]
    tracked = wheels["tracked"]
    assert tracked["max_bus_attitude_error_rad"] == float(np.max(of.rotation_angle(quat[0], quat)))
    assert tracked["peak_wheel_torque_fraction"] == (np.abs(traj.wheel_torque).max(axis=0) / spec.wheels.max_torque).tolist()
    assert tracked["peak_wheel_speed_fraction"] == (np.abs(traj.wheel_speed).max(axis=0) / spec.wheels.max_speed).tolist()
    # printed: the binding limit, the pointing error and the fractions
    out = done.stdout
    assert "binding           max_torque of wheel 2" in out and "these wheels cannot hold the bus" in out
    assert f"bus pointing error at most {tracked['max_bus_attitude_error_rad']:.3e} rad" in out
    assert f"torque {max(tracked['peak_wheel_torque_fraction']):.3f} of max_torque" in out
    # the rest of the summary is the run without --wheels
    plain = plan_cli(tmp_path)
    assert plain.returncode == 0
    assert plain.stdout.split("wall time")[1].split("\n\nwrote")[0] == \
        out.split("wall time")[1].split("\n\n  wheels")[0]
    assert "wheels" not in json.loads((tmp_path / "out" / "plan_summary.json").read_text())


@pytest.mark.parametrize("extra, message", [
    (["--wheels", str(WHEELS), "--base", "free"], "orbitflex: error: --wheels: the wheels hold the bus of a held-base plan"),
    (["--wheels", "nope.toml"], "orbitflex: error: --wheels: nope.toml: cannot read the wheels file"),
])
def test_plan_wheels_errors_are_one_line(tmp_path, extra, message):
    done = plan_cli(tmp_path, *extra)
    assert done.returncode == 2, done.stdout
    assert message in done.stderr and "Traceback" not in done.stderr, done.stderr
