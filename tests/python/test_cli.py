"""The command line: ``orbitflex demo`` and ``orbitflex simulate URDF [--params TOML]``.

Each test runs the CLI in a subprocess (``python -m orbitflex``), as a user would, with a time
limit so that a hang fails the test instead of stalling the suite. Outputs are checked against
each other (the summary against the saved trajectory), not against recorded numbers. The plots
are checked in process, on the figures themselves (titles, labels, legends, axis limits).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys

from pathlib import Path

import numpy as np
import pytest

import orbitflex
from orbitflex import cli

PNGS = {
    "joint_vs_motor_angles.png",
    "deflection.png",
    "base_attitude.png",
    "ee_path.png",
    "momentum_drift.png",
}
# the demo adds its planned slew beside the rigid-joint plan (tests/python/test_planning.py)
DEMO_PNGS = PNGS | {"plan_vs_rigid.png", "plan_motor_torque.png", "plan_joint_speed.png", "wheels.png"}

URDF = """<?xml version="1.0"?>
<robot name="two_link_sat">
  <link name="bus">
    <inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="80"/>
      <inertia ixx="8" ixy="0" ixz="0" iyy="8" iyz="0" izz="8"/></inertial>
  </link>
  <link name="upper">
    <inertial><origin xyz="0.4 0 0" rpy="0 0 0"/><mass value="4"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.2"/></inertial>
  </link>
  <link name="fore">
    <inertial><origin xyz="0.3 0 0" rpy="0 0 0"/><mass value="2"/>
      <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.06" iyz="0" izz="0.06"/></inertial>
  </link>
  <link name="finger">
    <inertial><origin xyz="0.02 0 0" rpy="0 0 0"/><mass value="0.1"/>
      <inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="bus"/><child link="upper"/>
    <origin xyz="0.6 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="50" velocity="1"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="fore"/>
    <origin xyz="0.8 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="50" velocity="1"/>
  </joint>
  <joint name="finger_slide" type="prismatic">
    <parent link="fore"/><child link="finger"/>
    <origin xyz="0.6 0 0" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.05" effort="5" velocity="0.1"/>
  </joint>
</robot>
"""

PARAMS = """
[defaults]
stiffness = 800.0
gear_ratio = 100.0
rotor_inertia = 2.0e-5
damping = 0.5
motor_damping = 0.05

[joints.elbow]
stiffness = 500.0
"""


def run_cli(*args, cwd, timeout=120.0):
    env = dict(os.environ, MPLBACKEND="Agg", RUST_BACKTRACE="0")
    try:
        return subprocess.run(
            [sys.executable, "-m", "orbitflex", *map(str, args)],
            capture_output=True, text=True, cwd=cwd, env=env, timeout=timeout,
        )
    except subprocess.TimeoutExpired as e:
        pytest.fail(f"orbitflex {' '.join(map(str, args))} did not finish in {timeout} s "
                    f"(stdout: {e.stdout!r})")


def assert_clean_error(result, *words, flag=None):
    """Exit code 2, one line ``orbitflex: error: FLAG: ...`` (naming ``flag`` if given), no
    traceback."""
    assert result.returncode == 2, (result.returncode, result.stdout[-500:], result.stderr[-1500:])
    assert "Traceback" not in result.stderr, result.stderr[-1500:]
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("orbitflex: error: "), result.stderr[-1500:]
    if flag is not None:
        assert lines[0].startswith(f"orbitflex: error: {flag}: "), lines[0]
    for word in words:
        assert word in result.stderr, result.stderr[-1500:]


@pytest.fixture()
def model_files(tmp_path):
    urdf = tmp_path / "two_link_sat.urdf"
    urdf.write_text(URDF)
    params = tmp_path / "two_link_sat.toml"
    params.write_text(PARAMS)
    return urdf, params


# ---------------------------------------------------------------------------------------------
# demo
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "out"
    result = run_cli("demo", "--duration", "0.5", "--out", out, "--quiet", "--csv", cwd=out.parent)
    return result, out


def test_demo_exits_zero_and_prints_summary(demo_run):
    result, _ = demo_run
    assert result.returncode == 0, result.stderr[-2000:]
    out = result.stdout
    assert "Traceback" not in result.stderr
    for line in ["steps/s", "base attitude", "deflection", "momentum drift", "energy balance"]:
        assert line in out, f"summary lacks {line!r}:\n{out}"
    assert "space_arm" in out
    assert "500 RK4 steps" in out


def test_demo_prints_the_first_three_closed_loop_modes_of_its_arm(demo_run):
    # the demo's line and summary.json hold what orbitflex.analysis computes for the same arm,
    # controller and start state (the demo's PD at the default gains, free floating)
    import json

    import orbitflex
    from orbitflex import analysis, models

    result, out = demo_run
    assert result.returncode == 0, result.stderr[-2000:]
    line = next(l for l in result.stdout.splitlines() if l.startswith("first closed-loop modes"))
    summary = json.loads((out / "summary.json").read_text())
    saved = summary["closed_loop_modes"]
    assert len(saved) == 3
    arm = orbitflex.FlexibleArm(models.space_arm(), models.space_arm_joints())
    # the PD's reference does not enter the linearisation: only its gains do
    pd = orbitflex.MotorPD(summary["controller"]["kp"], summary["controller"]["kd"], np.zeros(arm.dof))
    modes, expected = analysis.closed_loop_modes(arm, arm.state(), pd, count=3)
    assert line == expected
    for i, m in enumerate(saved):
        assert m["frequency_hz"] == pytest.approx(modes.frequency_hz[i], rel=1e-9)
        assert m["damping_ratio"] == pytest.approx(modes.damping_ratio[i], rel=1e-9, abs=1e-12)
        assert m["dominant_joint"] == modes.dominant_joints[i]
    # ascending, structural (not rigid-body) modes
    assert 0 < saved[0]["frequency_hz"] <= saved[1]["frequency_hz"] <= saved[2]["frequency_hz"]


def test_demo_writes_trajectory_summary_and_plots(demo_run):
    result, out = demo_run
    assert result.returncode == 0, result.stderr[-2000:]
    assert (out / "trajectory.npz").is_file()
    assert (out / "summary.json").is_file()
    pngs = {p.name for p in out.glob("*.png")}
    assert pngs == DEMO_PNGS
    for name in DEMO_PNGS:
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 1000, name


def test_demo_lists_every_file_it_wrote(demo_run):
    # every file in the output folder is listed, with the full path and a description
    result, out = demo_run
    assert result.returncode == 0, result.stderr[-2000:]
    written = {p.name for p in out.iterdir()}
    assert written == DEMO_PNGS | {"trajectory.npz", "trajectory.csv", "summary.json", "animation.html"}
    listed = [line.split() for line in result.stdout.splitlines() if str(out) in line]
    assert {Path(words[0]).name for words in listed} == written
    assert all(len(words) > 2 for words in listed)  # a description follows each path
    assert f"wrote {len(written)} files" in result.stdout


def test_csv_has_the_trajectory_with_named_columns(demo_run):
    result, out = demo_run
    assert result.returncode == 0, result.stderr[-2000:]
    with np.load(out / "trajectory.npz") as data:
        t, x, columns = data["t"], data["x"], list(data["columns"])
    header = (out / "trajectory.csv").read_text().splitlines()[0].split(",")
    assert header[1:] == columns
    table = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 0], t, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(table[:, 1:], x, rtol=1e-9, atol=1e-12)


def test_energy_line_explains_its_residual(demo_run):
    # "residual" = E(T) - E(0) - (motor work - damping loss); "flowed" = sum of |dE| per step
    result, out = demo_run
    assert result.returncode == 0, result.stderr[-2000:]
    lines = result.stdout[result.stdout.index("energy balance"):].splitlines()[:2]
    text = " ".join(lines)
    for words in ["E(T) − E(0)", "motor work", "damping loss", "residual", "trapezoid rule",
                  "that flowed", "Σ|ΔE| over the steps"]:
        assert words in text, text
    summary = json.loads((out / "summary.json").read_text())
    with np.load(out / "trajectory.npz") as data:
        energy = data["energy"]
    assert summary["energy_change_J"] == pytest.approx(energy[-1] - energy[0], rel=1e-12)
    assert summary["energy_balance_residual_J"] == pytest.approx(
        summary["energy_change_J"] - (summary["motor_work_J"] - summary["dissipated_J"]), rel=1e-9, abs=1e-15)
    assert summary["energy_flow_J"] == pytest.approx(np.abs(np.diff(energy)).sum(), rel=1e-12)


def test_demo_outputs_agree_with_each_other(demo_run):
    result, out = demo_run
    assert result.returncode == 0, result.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    with np.load(out / "trajectory.npz") as data:
        t, x, h, columns = data["t"], data["x"], data["momentum"], list(data["columns"])
    n = 7
    assert summary["model"] == "space_arm"
    assert summary["steps"] == 500 == len(t) - 1
    assert x.shape == (501, 13 + 4 * n)
    assert len(columns) == x.shape[1] and columns[7] == "q[shoulder_roll]"
    np.testing.assert_allclose(t, np.arange(501) * 1e-3, rtol=1e-12, atol=1e-15)
    assert summary["simulated_s"] == pytest.approx(0.5)
    assert summary["steps_per_second"] > 0
    # the summary's momentum drift is that of the saved trajectory, and it is tiny (free floating)
    drift = np.abs(h - h[0]).max(axis=0)
    assert summary["momentum_drift_angular"] == pytest.approx(drift[:3].max(), rel=1e-9, abs=1e-300)
    assert summary["momentum_drift_linear"] == pytest.approx(drift[3:].max(), rel=1e-9, abs=1e-300)
    assert drift.max() < 1e-9 * max(1.0, np.abs(h).max())  # RK4 truncation, round-off here
    # base attitude change: the rotation angle between the first and last quaternions
    q0, q1 = x[0, 3:7], x[-1, 3:7]
    angle = np.degrees(2 * np.arccos(min(1.0, abs(q0 @ q1))))
    assert summary["base_attitude_change_deg"] == pytest.approx(angle, rel=1e-6, abs=1e-9)
    # the arm moved and the base reacted
    assert np.abs(x[-1, 7:7 + n]).max() > 0
    assert angle > 0
    # deflection: max |theta - q| over the run
    defl = np.degrees(np.abs(x[:, 7 + n:7 + 2 * n] - x[:, 7:7 + n]).max())
    assert summary["max_deflection_deg"] == pytest.approx(defl, rel=1e-9)


def test_console_script_is_installed(tmp_path):
    exe = shutil.which("orbitflex")
    if exe is None:
        pytest.skip("the `orbitflex` console script is not on PATH")
    result = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert result.returncode == 0
    assert "demo" in result.stdout and "simulate" in result.stdout


# ---------------------------------------------------------------------------------------------
# simulate
# ---------------------------------------------------------------------------------------------


def test_simulate_small_urdf(model_files, tmp_path):
    urdf, params = model_files
    out = tmp_path / "sim_out"
    result = run_cli("simulate", urdf, "--params", params, "--locked-joints", "finger_slide",
                     "--duration", "0.2", "--out", out, "--quiet", "--no-plots", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "Traceback" not in result.stderr
    for line in ["steps/s", "base attitude", "deflection", "momentum drift", "energy balance"]:
        assert line in result.stdout
    assert "two_link_sat" in result.stdout
    summary = json.loads((out / "summary.json").read_text())
    with np.load(out / "trajectory.npz") as data:
        t, x, columns = data["t"], data["x"], list(data["columns"])
    assert summary["model"] == "two_link_sat"
    assert summary["steps"] == 200 == len(t) - 1
    assert x.shape == (201, 13 + 4 * 2)
    assert "q[shoulder]" in columns and "theta_dot[elbow]" in columns
    assert not any("finger" in c for c in columns)
    assert np.isfinite(x).all()
    assert not list(out.glob("*.png"))  # --no-plots
    assert summary["max_deflection_joint"] in ("shoulder", "elbow")


def test_simulate_with_plots_and_single_slew(model_files, tmp_path):
    urdf, params = model_files
    out = tmp_path / "sim_plots"
    result = run_cli("simulate", urdf, "--params", params, "--locked-joints", "finger_slide",
                     "--slew", "0.5", "--duration", "0.2", "--out", out, "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert {p.name for p in out.glob("*.png")} == PNGS


@pytest.mark.parametrize("sub", ["demo", "simulate"])
def test_help(sub, tmp_path):
    result = run_cli(sub, "--help", cwd=tmp_path)
    assert result.returncode == 0
    assert "usage" in result.stdout.lower()
    for option in ["--duration", "--dt", "--out", "--quiet", "--no-plots", "--csv"]:
        assert option in result.stdout
    if sub == "simulate":
        assert "--params" in result.stdout and "urdf" in result.stdout.lower()


def test_top_level_help(tmp_path):
    result = run_cli("--help", cwd=tmp_path)
    assert result.returncode == 0
    assert "demo" in result.stdout and "simulate" in result.stdout


# ---------------------------------------------------------------------------------------------
# errors: exit code 2 and a clean message
# ---------------------------------------------------------------------------------------------


def test_missing_urdf(model_files, tmp_path):
    _, params = model_files
    missing = tmp_path / "nowhere" / "robot.urdf"
    result = run_cli("simulate", missing, "--params", params, "--duration", "0.1",
                     "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, str(missing), flag="URDF")


def test_missing_params_file(model_files, tmp_path):
    urdf, _ = model_files
    missing = tmp_path / "absent.toml"
    result = run_cli("simulate", urdf, "--params", missing, "--locked-joints", "finger_slide",
                     "--duration", "0.1", "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, str(missing), flag="--params")


def test_unlocked_prismatic_joint_is_a_clean_error(model_files, tmp_path):
    urdf, params = model_files
    result = run_cli("simulate", urdf, "--params", params, "--duration", "0.1",
                     "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    # the library's hint, locked_joints=["finger_slide"], in the CLI's words; blamed on the URDF,
    # not on --locked-joints, which was not given
    assert_clean_error(result, "finger_slide", "prismatic", "--locked-joints finger_slide",
                       flag="URDF")


def test_malformed_urdf(tmp_path, model_files):
    _, params = model_files
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot>")
    result = run_cli("simulate", bad, "--params", params, "--duration", "0.1",
                     "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, str(bad), flag="URDF")


def test_unknown_ee_link(model_files, tmp_path):
    urdf, params = model_files
    result = run_cli("simulate", urdf, "--params", params, "--ee-link", "gripper",
                     "--duration", "0.1", "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, "gripper", flag="--ee-link")


def test_simulate_without_params_uses_the_scaled_defaults(model_files, tmp_path):
    # no --params: FlexibleJoints.defaults_for(robot), and one line of output says so
    urdf, _ = model_files
    out = tmp_path / "defaults"
    result = run_cli("simulate", urdf, "--locked-joints", "finger_slide", "--duration", "0.2",
                     "--out", out, "--quiet", "--no-plots", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    lines = [line for line in result.stdout.splitlines() if "defaults_for" in line]
    assert len(lines) == 1, result.stdout
    for words in ["FlexibleJoints.defaults_for(robot)", "5 Hz", "--params"]:
        assert words in lines[0]
    assert json.loads((out / "summary.json").read_text())["steps"] == 200
    # with --params the line is absent
    result = run_cli("simulate", urdf, "--params", model_files[1], "--locked-joints", "finger_slide",
                     "--duration", "0.1", "--out", out, "--quiet", "--no-plots", cwd=tmp_path)
    assert result.returncode == 0 and "defaults_for" not in result.stdout


def test_wrong_slew_count(model_files, tmp_path):
    urdf, params = model_files
    result = run_cli("simulate", urdf, "--params", params, "--locked-joints", "finger_slide",
                     "--slew", "0.1", "0.2", "0.3", "--duration", "0.1",
                     "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, "--slew", flag="--slew")


@pytest.mark.parametrize("dt", ["0", "-0.001", "nan"])
def test_invalid_dt_is_a_clean_error(dt, tmp_path):
    # dt = 0 used to raise ZeroDivisionError with a traceback; a negative dt silently ran zero
    # steps and exited 0.
    result = run_cli("demo", "--duration", "0.2", "--dt", dt, "--out", tmp_path / "o",
                     "--quiet", "--no-plots", cwd=tmp_path)
    assert_clean_error(result, "dt", flag="--dt")


@pytest.mark.parametrize("duration", ["-1", "-0.5"])
def test_invalid_duration_is_a_clean_error(duration, tmp_path):
    # A run that simulates nothing must say why instead of printing a summary of zero steps.
    result = run_cli("demo", "--duration", duration, "--out", tmp_path / "o",
                     "--quiet", "--no-plots", cwd=tmp_path)
    assert_clean_error(result, "duration", flag="--duration")


@pytest.mark.parametrize("dt", [0.03, 0.05])
def test_diverging_run_reports_where_it_stopped(tmp_path, dt):
    # dt far past the RK4 limit (6.2 ms): refused without --force; with it the CLI must warn,
    # say the run diverged, report the step and time of the whole run (not of an internal
    # chunk), keep the finite part (valid states) and exit non-zero.
    out = tmp_path / "div"
    result = run_cli("demo", "--duration", "2", "--dt", dt, "--out", out, "--quiet",
                     "--no-plots", "--force", cwd=tmp_path, timeout=60.0)
    assert result.returncode == 1
    assert "Traceback" not in result.stderr, result.stderr[-1500:]
    # the RuntimeWarning, as one line in the CLI's format (not Python's, pointing into cli.py)
    warned = [line for line in result.stderr.splitlines() if "stability limit" in line]
    assert warned and warned[0].startswith("orbitflex: warning: dt = "), result.stderr[-1500:]
    assert "RuntimeWarning" not in result.stderr and "cli.py" not in result.stderr
    assert "diverged" in result.stderr, result.stderr[-1500:]
    found = re.search(r"step (\d+) \(t = ([0-9.eE+-]+) s\)", result.stderr)
    assert found, result.stderr[-1500:]
    step, time = int(found.group(1)), float(found.group(2))
    assert time == pytest.approx(step * dt)
    with np.load(out / "trajectory.npz") as data:
        t, x = data["t"], data["x"]
    assert np.isfinite(x).all()
    np.testing.assert_allclose(np.linalg.norm(x[:, 3:7], axis=1), 1.0, atol=1e-9)
    # the reported failure is at or after the last kept state of the whole run
    assert time >= t[-1] - 1e-12, (time, t[-1])
    assert step >= len(t) - 1


# ---------------------------------------------------------------------------------------------
# the command line itself
# ---------------------------------------------------------------------------------------------


def test_bare_orbitflex_prints_the_help(tmp_path):
    # it used to run the demo silently
    result = run_cli(cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-1500:]
    assert "usage" in result.stdout.lower()
    assert "demo" in result.stdout and "simulate" in result.stdout
    assert not list(tmp_path.iterdir())  # nothing simulated, nothing written


def test_version(tmp_path):
    result = run_cli("--version", cwd=tmp_path)
    assert result.returncode == 0
    assert result.stdout.strip() == f"orbitflex {orbitflex.__version__}"


def test_unknown_option_is_a_one_line_error(tmp_path):
    result = run_cli("demo", "--bogus", cwd=tmp_path)
    assert_clean_error(result, "--bogus")


def test_simulate_help_describes_the_toml_keys(tmp_path):
    result = run_cli("simulate", "--help", cwd=tmp_path)
    assert result.returncode == 0
    help_text = result.stdout
    for words in ["[defaults]", "[joints.<name>]", "stiffness", "N·m/rad", "motor_inertia", "kg·m²",
                  "link-side", "gear_ratio", "rotor_inertia", "motor_inertia = gear_ratio² · rotor_inertia",
                  "damping", "motor_damping", "N·m·s/rad", "defaults_for",
                  "--base-mass", "--base-inertia", "--base-com", "--locked-joints", "--csv"]:
        assert words in help_text, words


def toml_example(help_text):
    """The example TOML file of ``orbitflex simulate --help``."""
    lines = help_text.split("example joints.toml:\n", 1)[1].splitlines()
    block = []
    for line in lines:
        if line and not line.startswith("  "):
            break
        block.append(line.strip())
    return "\n".join(block)


def test_the_help_toml_example_is_valid(model_files, tmp_path):
    # two_link_sat has a joint named "elbow", as the example does
    urdf, _ = model_files
    example = toml_example(run_cli("simulate", "--help", cwd=tmp_path).stdout)
    assert "[defaults]" in example and "[joints.elbow]" in example
    params = tmp_path / "example.toml"
    params.write_text(example)
    robot = orbitflex.Robot.from_urdf(urdf, locked_joints=["finger_slide"])
    joints = orbitflex.FlexibleJoints.from_toml(params, robot)
    np.testing.assert_allclose(joints.motor_inertia, [100.0**2 * 5e-5, 0.5])  # gear, then own
    result = run_cli("simulate", urdf, "--params", params, "--locked-joints", "finger_slide",
                     "--duration", "0.05", "--out", tmp_path / "o", "--quiet", "--no-plots", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-1500:]


@pytest.mark.parametrize("locked", [["--locked-joints", "finger_slide,shoulder"],
                                    ["--locked-joints", "finger_slide", "--locked-joints", "shoulder"],
                                    ["--locked-joints", " finger_slide , shoulder "]])
def test_locked_joints_take_a_list_or_repeat(model_files, tmp_path, locked):
    urdf, params = model_files
    out = tmp_path / "locked"
    # the URDF after the option: it must not be taken for a joint name
    result = run_cli("simulate", *locked, urdf, "--params", params, "--duration", "0.05",
                     "--out", out, "--quiet", "--no-plots", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-1500:]
    with np.load(out / "trajectory.npz") as data:
        columns = list(data["columns"])
    assert "q[elbow]" in columns and "q[shoulder]" not in columns


def test_locked_joints_with_spaces_is_a_clean_error(model_files, tmp_path):
    # `--locked-joints a b robot.urdf` used to take robot.urdf for a joint name
    urdf, params = model_files
    result = run_cli("simulate", "--locked-joints", "finger_slide", "shoulder", urdf, "--params", params,
                     "--duration", "0.05", "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, "comma-separated", str(urdf), flag="--locked-joints")
    assert not (tmp_path / "o").exists()


BRANCHED_URDF = URDF.replace("</robot>", """
  <link name="antenna"/>
  <joint name="antenna_hinge" type="revolute">
    <parent link="bus"/><child link="antenna"/>
    <origin xyz="-0.6 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="5" velocity="1"/>
  </joint>
</robot>""")


@pytest.mark.parametrize("case", ["unknown_ee_link", "unknown_locked", "prismatic", "unknown_ee_links", "both"])
def test_messages_name_the_flags_not_python_keywords(model_files, tmp_path, case):
    urdf, params = model_files
    branched = tmp_path / "branched.urdf"
    branched.write_text(BRANCHED_URDF)
    args, flag = {
        "unknown_ee_link": ([urdf, "--ee-link", "gripper"], "--ee-link"),
        "unknown_locked": ([urdf, "--locked-joints", "finger_slide,nope"], "--locked-joints"),
        "prismatic": ([urdf], "URDF"),  # the advice names --locked-joints; the blame is the file's
        "unknown_ee_links": ([branched, "--locked-joints", "finger_slide", "--ee-links", "fore,nope"],
                             "--ee-links"),
        "both": ([branched, "--locked-joints", "finger_slide", "--ee-link", "fore", "--ee-links", "fore"],
                 "--ee-link"),
    }[case]
    result = run_cli("simulate", *args, "--params", params, "--duration", "0.05",
                     "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, flag=flag)
    assert "ee_link" not in result.stderr and "locked_joints" not in result.stderr, result.stderr


def test_flags_are_not_abbreviated(model_files, tmp_path):
    # `--dur` is not `--duration`: a later flag starting with the same letters would change it
    urdf, params = model_files
    result = run_cli("simulate", urdf, "--params", params, "--dur", "0.05", "--out", tmp_path / "o",
                     "--quiet", cwd=tmp_path)
    assert_clean_error(result, "unrecognized arguments: --dur 0.05")
    assert not (tmp_path / "o").exists()


def test_a_toml_syntax_error_is_one_line_with_its_position(model_files, tmp_path):
    urdf, _ = model_files
    bad = tmp_path / "bad.toml"
    bad.write_text("[defaults]\nstiffness = [1,\n")
    result = run_cli("simulate", urdf, "--params", bad, "--locked-joints", "finger_slide", "--duration", "0.05",
                     "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, "malformed joint-parameter TOML: line 2, column 16: invalid array, expected `]`",
                       flag="--params")


def test_links_named_like_keywords_keep_their_names(model_files, tmp_path):
    # UR5 names its flange 'ee_link': a message listing links must show that name, not a flag
    urdf, params = model_files
    branched = tmp_path / "branched.urdf"
    branched.write_text(BRANCHED_URDF.replace('"antenna"', '"ee_link"'))
    result = run_cli("simulate", branched, "--locked-joints", "finger_slide", "--ee-link", "gripper",
                     "--params", params, "--duration", "0.05", "--out", tmp_path / "o", "--quiet",
                     cwd=tmp_path)
    assert_clean_error(result, flag="--ee-link")
    # the listing of the file's links keeps the link's own name
    assert "unknown link 'gripper'; the file has: " in result.stderr, result.stderr
    assert result.stderr.rstrip().endswith(", ee_link"), result.stderr


# ---------------------------------------------------------------------------------------------
# a real arm on a spacecraft bus: --base-mass, --base-inertia, --base-com
# ---------------------------------------------------------------------------------------------


def run_on_bus(model_files, tmp_path, name, *bus):
    urdf, params = model_files
    out = tmp_path / name
    result = run_cli("simulate", urdf, "--params", params, "--locked-joints", "finger_slide", *bus,
                     "--duration", "0.3", "--out", out, "--quiet", "--no-plots", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-1500:]
    with np.load(out / "trajectory.npz") as data:
        return result, data["x"], json.loads((out / "summary.json").read_text())


def test_base_mass_mounts_the_arm_on_a_bus(model_files, tmp_path):
    _, x_own, own = run_on_bus(model_files, tmp_path, "own")
    result, x_cube, cube = run_on_bus(model_files, tmp_path, "cube", "--base-mass", "500")
    # the arm (upper 4 kg, fore 2 kg, finger 0.1 kg) on a 500 kg bus
    assert "total mass 506.1 kg" in result.stdout
    # a heavier bus turns less than the URDF's 80 kg one
    assert 0 < cube["base_attitude_change_deg"] < own["base_attitude_change_deg"]
    # --base-mass alone is a solid 1.5 m cube: I = m s² / 6 = 187.5 kg·m² on each axis
    _, x_explicit, _ = run_on_bus(model_files, tmp_path, "explicit", "--base-mass", "500",
                                  "--base-inertia", "187.5", "187.5", "187.5")
    np.testing.assert_array_equal(x_explicit, x_cube)
    # the COM and the inertia are used
    _, x_com, _ = run_on_bus(model_files, tmp_path, "com", "--base-mass", "500", "--base-com", "0.2", "0", "0")
    _, x_thin, _ = run_on_bus(model_files, tmp_path, "thin", "--base-mass", "500",
                              "--base-inertia", "20", "20", "30")
    assert np.abs(x_com - x_cube).max() > 1e-9 and np.abs(x_thin - x_cube).max() > 1e-9


def test_python_and_the_cli_share_one_default_bus(model_files):
    # Python had no default bus inertia while the CLI defaulted to a solid 1.5 m cube: both now
    # take Robot.with_base_inertia(mass)'s, a solid cube of models.DEFAULT_BUS_SIDE
    urdf, params = model_files
    args = cli.build_parser().parse_args(["simulate", str(urdf), "--locked-joints", "finger_slide",
                                          "--base-mass", "500"])
    robot = cli.load_robot(args)
    mounted, side, _ = cli.mount_on_bus(robot, args)
    assert orbitflex.models.DEFAULT_BUS_SIDE == side == 1.5
    q = np.array([0.3, -0.2])
    default = robot.with_base_inertia(500.0)
    cube = robot.with_base_inertia(500.0, np.full(3, 500.0 * 1.5**2 / 6))
    np.testing.assert_array_equal(mounted.mass_matrix(q), default.mass_matrix(q))
    np.testing.assert_array_equal(default.mass_matrix(q), cube.mass_matrix(q))
    assert default.total_mass == pytest.approx(506.1)


@pytest.mark.parametrize("bus, flag", [
    (["--base-inertia", "1", "1", "1"], "--base-inertia"),  # without --base-mass
    (["--base-com", "0", "0", "0"], "--base-com"),  # without --base-mass
    (["--base-mass", "500", "--base-inertia", "1", "1", "5"], "--base-inertia"),  # triangle inequality
    (["--base-mass", "500", "--base-inertia", "1", "1"], "--base-inertia"),
    (["--base-mass", "-1"], "--base-mass"),
    (["--base-mass", "500", "--base-com", "0", "0", "nan"], "--base-com"),
])
def test_bad_bus_is_a_clean_error(model_files, tmp_path, bus, flag):
    urdf, params = model_files
    result = run_cli("simulate", urdf, "--params", params, "--locked-joints", "finger_slide", *bus,
                     "--duration", "0.05", "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, flag=flag)


# ---------------------------------------------------------------------------------------------
# errors that used to end in a traceback (or in the machine swapping)
# ---------------------------------------------------------------------------------------------


def test_a_bandwidth_the_springs_cannot_carry_is_a_clean_error(tmp_path):
    for bandwidth, words in (("3", ["1.547 Hz for joint 1 ('shoulder_yaw'", "ask for well below"]),
                             ("1e300", ["5.84 Hz for joint 0 ('shoulder_roll'", "41.27 Hz for joint 6 ('wrist_roll'"])):
        result = run_cli("demo", "--bandwidth", bandwidth, "--duration", "0.1", "--out", tmp_path / "o",
                         "--quiet", cwd=tmp_path)
        assert_clean_error(result, *words, flag="--bandwidth")
        assert not (tmp_path / "o").exists()


def test_out_naming_a_file_is_a_clean_error(tmp_path):
    existing = tmp_path / "results.txt"
    existing.write_text("keep me")
    for out in (existing, existing / "sub"):
        result = run_cli("demo", "--duration", "0.1", "--out", out, "--quiet", cwd=tmp_path)
        assert_clean_error(result, str(existing), flag="--out")
    assert existing.read_text() == "keep me"


@pytest.mark.parametrize("locked", ["finger_slide,shoulder,elbow", None])
def test_no_moving_joints_is_a_clean_error(model_files, tmp_path, locked):
    urdf, params = model_files
    if locked is None:  # every joint fixed in the URDF
        urdf = tmp_path / "rigid.urdf"
        urdf.write_text(URDF.replace('type="revolute"', 'type="fixed"').replace('type="prismatic"', 'type="fixed"'))
        args = []
    else:
        args = ["--locked-joints", locked]
    result = run_cli("simulate", urdf, *args, "--duration", "0.1", "--out", tmp_path / "o",
                     "--quiet", cwd=tmp_path)
    assert_clean_error(result, "no moving joints", flag="--locked-joints")


@pytest.mark.parametrize("duration, dt", [("2e5", "1e-5"), ("1e9", "1e-3")])
def test_a_run_too_big_for_memory_is_refused_up_front(tmp_path, duration, dt):
    # 2e10 and 1e12 steps: terabytes, past any machine; refused before anything is allocated
    out = tmp_path / "o"
    result = run_cli("demo", "--duration", duration, "--dt", dt, "--out", out, "--quiet",
                     cwd=tmp_path, timeout=60.0)
    assert_clean_error(result, "--dt", "TB", "free", flag="--duration/--dt")
    assert not out.exists()


def test_memory_estimate_counts_tables_record_and_diagnostics():
    steps, n = 1000, 7
    parts = cli.run_bytes(steps, n)
    assert parts["reference tables"] == 2 * steps * n * 8
    assert parts["record"] == (steps + 1) * (14 + 4 * n) * 8 + steps * n * 8
    assert parts["diagnostics"] > 0
    free = cli.free_memory()
    assert free is None or free > 0


def test_simulate_with_a_bus_draws_it_in_the_animation(model_files, tmp_path):
    urdf, params = model_files
    out = tmp_path / "bus"
    result = run_cli("simulate", urdf, "--params", params, "--locked-joints", "finger_slide", "--duration", "0.05",
                     "--base-mass", "300", "--out", out, "--quiet", "--no-plots", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-1500:]
    text = (out / "animation.html").read_text()
    plain = tmp_path / "plain"
    result = run_cli("simulate", urdf, "--params", params, "--locked-joints", "finger_slide", "--duration", "0.05",
                     "--out", plain, "--quiet", "--no-plots", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-1500:]
    # one more drawing command: the bus cube
    count = lambda page: page.count('"H4sI')  # each gzip-compressed command starts so in base64
    assert count(text) == count((plain / "animation.html").read_text()) + 1


def test_animation_write_error_names_the_file(tmp_path):
    out = tmp_path / "out"
    (out / "animation.html").mkdir(parents=True)
    result = run_cli("demo", "--duration", "0.05", "--out", out, "--quiet", "--no-plots", cwd=tmp_path)
    assert result.returncode == 2, result.stderr[-1500:]
    assert f"--out: cannot write {out / 'animation.html'}: Is a directory" in result.stderr


def test_diverged_run_summary_describes_the_finite_part(tmp_path):
    out = tmp_path / "div"
    result = run_cli("demo", "--duration", "2", "--dt", "0.03", "--out", out, "--quiet", "--force", cwd=tmp_path)
    assert result.returncode == 1, result.stderr[-1500:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["completed"] is False
    assert summary["steps"] < summary["steps_requested"] == 67
    step, time = summary["failure_step"], summary["failure_time_s"]
    assert time == pytest.approx(step * 0.03)
    text = result.stdout
    assert "FAILED" in text and f"step {step} (t = {time:g} s)" in text
    assert "RK4 truncation" not in text  # the drift of a diverging run is no truncation error
    # the outputs of the finite part are written all the same (not the wheel case, which is
    # compared with a run that failed)
    assert {p.name for p in out.iterdir()} == (DEMO_PNGS - {"wheels.png"}) | {"trajectory.npz", "summary.json",
                                                                             "animation.html"}
    assert "the wheel case is not run" in result.stderr
    with np.load(out / "trajectory.npz") as data:
        assert len(data["t"]) == step + 1 and np.isfinite(data["x"]).all()


def test_a_diverged_run_is_summarised_up_to_the_onset_of_its_divergence(tmp_path):
    # `simulate ur5 --dt 0.1` printed "origin moved 4.84e+131 mm" and "max 4.72e+131 deg" as the
    # finite part: finite is not meaningful. The summary now stops where the energy balance stops
    # holding (the integrator making energy), and says where that is. 6 % past the demo's limit,
    # the divergence takes 119 quiet steps to set in, then grows ×1.25 per step.
    out = tmp_path / "marginal"
    result = run_cli("demo", "--dt", "0.0066", "--out", out, "--quiet", "--no-plots", "--no-animation", "--force",
                     cwd=tmp_path)
    assert result.returncode == 1, result.stderr[-1500:]
    summary = json.loads((out / "summary.json").read_text())
    onset, failed = summary["divergence_onset_step"], summary["failure_step"]
    assert 100 <= onset < failed == 232, (onset, failed)
    assert summary["divergence_onset_time_s"] == pytest.approx(onset * 0.0066, rel=1e-12)
    assert summary["simulated_s"] == pytest.approx(failed * 0.0066, rel=1e-12)
    assert f"divergence          set in after step {onset} (t = {onset * 0.0066:.6g} s)" in result.stdout
    assert f"the numbers below describe t = 0 to {onset * 0.0066:.6g} s" in result.stdout
    # the numbers are those of the rows up to the onset, and physical: the demo peaks at 1.6 mrad
    with np.load(out / "trajectory.npz") as data:
        deflection, energy, u = data["deflection"], data["energy"], data["u"]
    assert summary["max_deflection_deg"] == pytest.approx(np.degrees(np.abs(deflection[: onset + 1]).max()), rel=1e-12)
    assert np.radians(summary["max_deflection_deg"]) < 1.7e-3 < np.abs(deflection).max()
    assert summary["energy_change_J"] == pytest.approx(energy[onset] - energy[0], rel=1e-12)
    assert abs(summary["energy_balance_residual_J"]) <= 0.01 * summary["energy_flow_J"]
    # far past the limit the divergence sets in at once: nothing but the start is meaningful
    result = run_cli("demo", "--dt", "0.05", "--duration", "2", "--out", tmp_path / "far", "--quiet", "--no-plots",
                     "--no-animation", "--force", cwd=tmp_path)
    far = json.loads((tmp_path / "far" / "summary.json").read_text())
    assert far["divergence_onset_step"] <= 2 < far["failure_step"]
    numbers = result.stdout.split("motor PD")[1].split("orbitflex: minimum-time")[0]
    assert all(int(e) <= 3 for e in re.findall(r"e\+(\d+)", numbers)), numbers  # no 1e131 anywhere


# ---------------------------------------------------------------------------------------------
# plots: checked in process, on the figures (text, units, legends, limits)
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def figures(tmp_path_factory):
    """``{png name: figure}`` of a 0.4 s slew of two_link_sat (1 ms steps), and its trajectory."""
    import matplotlib

    matplotlib.use("Agg")
    robot = orbitflex.Robot.from_urdf_string(URDF, locked_joints=["finger_slide"])
    arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints.defaults_for(robot))
    slew = np.full(2, 0.3)
    pd = cli.slew_controller(arm, slew, 400, 1e-3, 5.0, cli.Gains(*arm.motor_pd_gains(0.25), 0.25, 1.0))
    traj = arm.simulate(arm.state(), 1e-3, 400, u=pd)
    job = cli.Job(arm, robot.name, slew, cli.sketch_side(robot), np.zeros(3))
    kept = {}
    original = cli.Figures.save
    cli.Figures.save = lambda self, fig, name: kept.__setitem__(name, fig)
    try:
        cli.plot(job, cli.Outcome(traj, 1.0), 1e-3, tmp_path_factory.mktemp("plots"))
    finally:
        cli.Figures.save = original
    yield kept, traj
    import matplotlib.pyplot as plt

    for fig in kept.values():
        plt.close(fig)


def texts(ax):
    legend = ax.get_legend()
    return [t.get_text() for t in legend.get_texts()] if legend else []


def test_every_plot_names_model_and_dt_with_units_on_every_axis(figures):
    kept, _ = figures
    assert set(kept) == PNGS
    unit = re.compile(r"\((s|deg|mrad|µrad|nrad|N·m·s|N·s|m|mm|µm|.*10\^\{-?\d+\}\$ N·m·s|.*10\^\{-?\d+\}\$ N·s)\)$")
    for name, fig in kept.items():
        suptitle = fig._suptitle.get_text()
        assert "two_link_sat" in suptitle and "dt = 1 ms" in suptitle, (name, suptitle)
        for ax in fig.axes:
            if not ax.get_visible():
                continue
            labels = [ax.get_ylabel()] + ([ax.get_zlabel()] if hasattr(ax, "get_zlabel") else [])
            if ax.get_xlabel():
                labels.append(ax.get_xlabel())
            for label in labels:
                assert unit.search(label) or label in {"deg", "mrad", "µrad", "nrad"}, (name, label)
        assert any(ax.get_xlabel() for ax in fig.axes), name


def test_joint_vs_motor_plot_shows_the_motor_lead(figures):
    kept, traj = figures
    top, bottom = kept["joint_vs_motor_angles.png"].axes
    legend = texts(top)
    assert {"shoulder", "elbow", "q, link", "θ, motor"} <= set(legend), legend
    # theta is drawn, and the lead theta - q has its own panel in a unit that makes it readable
    assert len(top.get_lines()) >= 4
    factor, unit = cli.angle_unit(float(np.abs(traj.deflection).max()))
    assert bottom.get_ylabel() == f"θ − q ({unit})"
    lead = np.concatenate([line.get_ydata() for line in bottom.get_lines()[:2]])
    assert 1.0 <= np.abs(lead).max() < 1000.0
    assert {"shoulder", "elbow"} <= set(texts(bottom))


def test_deflection_plot_has_readable_units_per_joint(figures):
    kept, traj = figures
    axes = [ax for ax in kept["deflection.png"].axes if ax.get_visible()]
    assert len(axes) == 2  # one panel per joint
    for i, ax in enumerate(axes):
        peak = np.abs(ax.get_lines()[0].get_ydata()).max()
        assert 1.0 <= peak < 1000.0, (ax.get_ylabel(), peak)  # never 0.00015 deg
        assert traj.arm.robot.joint_names[i] in ax.get_title() and "N·m" in ax.get_title()


def test_momentum_plot_separates_angular_and_linear(figures):
    kept, _ = figures
    top, bottom = kept["momentum_drift.png"].axes
    assert "N·m·s" in top.get_ylabel() and "N·m·s" not in bottom.get_ylabel() and "N·s" in bottom.get_ylabel()
    assert texts(top) == ["$\\Delta H_x$", "$\\Delta H_y$", "$\\Delta H_z$"]
    assert texts(bottom) == ["$\\Delta p_x$", "$\\Delta p_y$", "$\\Delta p_z$"]


def test_attitude_plot_states_the_sequence_and_the_total_rotation(figures):
    kept, traj = figures
    (ax,) = kept["base_attitude.png"].axes
    assert "z-y′-x″" in ax.get_title() and "Rz(yaw) · Ry(pitch) · Rx(roll)" in ax.get_title()
    total = [line for line in ax.get_lines() if line.get_label().startswith("total rotation")]
    assert len(total) == 1
    q0, q1 = traj.base_pose[0, 3:], traj.base_pose[-1, 3:]
    # the angle of q0* ⊗ q1 by atan2 (arccos(|q0 · q1|) is no reference here: at this 1e-4 rad
    # its rounding, about eps / (θ/2)² relative, is near 1e-8, ten times the bound)
    w = q0[3] * q1[3] + q0[:3] @ q1[:3]
    v = q0[3] * q1[:3] - q1[3] * q0[:3] - np.cross(q0[:3], q1[:3])
    expected = np.degrees(2 * np.arctan2(np.linalg.norm(v), abs(w)))
    assert total[0].get_ydata()[-1] == pytest.approx(expected, rel=1e-9, abs=1e-12)


def test_euler_angles_are_intrinsic_zyx():
    # R(q) == Rz(yaw) Ry(pitch) Rx(roll) for random attitudes
    rng = np.random.default_rng(7)
    quat = rng.normal(size=(50, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    yaw, pitch, roll = cli.euler_zyx(quat)

    def rot(axis, a):
        c, s = np.cos(a), np.sin(a)
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        r = np.eye(3)
        r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
        return r

    for k in range(len(quat)):
        expected = rot(2, yaw[k]) @ rot(1, pitch[k]) @ rot(0, roll[k])
        np.testing.assert_allclose(cli.rotation_matrix(quat[k]), expected, atol=1e-12)


def test_ee_path_plot_has_equal_axes_the_arm_and_the_bus(figures):
    kept, traj = figures
    scene, zoom = kept["ee_path.png"].axes
    for ax in (scene, zoom):
        spans = [np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim()), np.ptp(ax.get_zlim())]
        np.testing.assert_allclose(spans, spans[0], rtol=1e-9)
    labels = [line.get_label() for line in scene.get_lines()]
    for when in ("start", "end"):
        assert any(label.startswith(f"arm at the {when}") for label in labels), labels
        assert any(label.startswith(f"bus at the {when}") for label in labels), labels
    # the arm is drawn through the bodies from robot.body_poses
    arm = next(line for line in scene.get_lines() if line.get_label().startswith("arm at the start"))
    bodies = traj.arm.robot.body_poses(traj.base_pose[0], traj.q[0])[1:, :3]
    np.testing.assert_allclose(np.array(arm.get_data_3d()).T, bodies, atol=1e-12)


@pytest.mark.parametrize("radians, unit", [(0.5, "deg"), (2e-3, "mrad"), (2.6e-6, "µrad"), (3e-9, "nrad")])
def test_angle_unit(radians, unit):
    factor, chosen = cli.angle_unit(radians)
    assert chosen == unit
    assert 1.0 <= radians * factor < 1000.0 or unit == "deg"


def test_readme_table_describes_every_output():
    # the README's section moved to the docs' command-line page (issue 30)
    page = (Path(__file__).resolve().parents[2] / "docs" / "cli.md").read_text()
    section = page.split("## What the demo shows", 1)[1]
    for name in cli.OUTPUTS:
        assert f"| `{name}` |" in section, name
    for words in ["residual", "Σ|ΔE|", "trapezoid", "z-y′-x″", "--base-mass", "--locked-joints a,b"]:
        assert words in section, words


# ---------------------------------------------------------------------------------------------
# --record-every
# ---------------------------------------------------------------------------------------------


def test_record_every_keeps_the_full_runs_rows(model_files, tmp_path):
    urdf, params = model_files
    common = ("simulate", urdf, "--params", params, "--locked-joints", "finger_slide",
              "--duration", "0.2", "--quiet")
    full = run_cli(*common, "--no-plots", "--out", tmp_path / "full", cwd=tmp_path)
    thin = run_cli(*common, "--record-every", "30", "--out", tmp_path / "thin", cwd=tmp_path)
    assert full.returncode == thin.returncode == 0, thin.stderr[-2000:]
    with np.load(tmp_path / "full" / "trajectory.npz") as f, np.load(tmp_path / "thin" / "trajectory.npz") as g:
        rows = [0, 30, 60, 90, 120, 150, 180, 200]  # 200 steps: every 30th row and the last
        for key in ("t", "x", "momentum", "energy"):
            np.testing.assert_array_equal(g[key], f[key][rows])
        np.testing.assert_array_equal(g["u"], f["u"][rows[:-1]])
    summary = json.loads((tmp_path / "thin" / "summary.json").read_text())
    assert (summary["steps"], summary["record_every"], summary["rows"]) == (200, 30, 8)
    assert summary["motor_work_J"] is None and summary["energy_balance_residual_J"] is None
    assert "8 rows: one step in 30 and the last (--record-every)" in thin.stdout
    assert "not computed: they need every step's torque (--record-every 1)" in thin.stdout
    assert {p.name for p in (tmp_path / "thin").glob("*.png")} == PNGS


def test_record_every_is_in_the_plot_caption(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    robot = orbitflex.Robot.from_urdf_string(URDF, locked_joints=["finger_slide"])
    arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints.defaults_for(robot))
    slew = np.full(2, 0.3)
    pd = cli.slew_controller(arm, slew, 400, 1e-3, 5.0, cli.Gains(*arm.motor_pd_gains(0.25), 0.25, 1.0))
    traj = arm.simulate(arm.state(), 1e-3, 400, u=pd, record_every=25)
    job = cli.Job(arm, robot.name, slew, cli.sketch_side(robot), np.zeros(3))
    captions = []
    original = cli.Figures.save

    def keep(self, fig, name):
        captions.append(fig._suptitle.get_text())
        matplotlib.pyplot.close(fig)

    cli.Figures.save = keep
    try:
        cli.plot(job, cli.Outcome(traj, 1.0, record_every=25), 1e-3, tmp_path)
    finally:
        cli.Figures.save = original
    assert len(captions) == len(PNGS)
    for caption in captions:
        assert "model two_link_sat, dt = 1 ms, 0.4 s free-floating slew, a row every 25 ms (--record-every 25)" in caption


@pytest.mark.parametrize("value", ["0", "-2", "1.5", "x"])
def test_bad_record_every_is_a_clean_error(tmp_path, value):
    result = run_cli("demo", "--duration", "0.1", "--record-every", value, "--out", tmp_path / "o", "--quiet",
                     cwd=tmp_path)
    assert_clean_error(result, f"expected an integer >= 1, given {value}", flag="--record-every")


def test_memory_estimate_counts_the_kept_rows():
    parts = cli.run_bytes(1000, 7, record_every=10)
    assert parts["reference tables"] == 2 * 1000 * 7 * 8  # per step, whatever is kept
    assert parts["record"] == 101 * (14 + 28) * 8 + 100 * 7 * 8
    assert [cli.recorded_rows(s, k) for s, k in ((1000, 10), (1001, 10), (5, 9), (0, 3))] == [101, 102, 2, 1]


def test_simulate_a_branched_urdf_reports_every_end_effector(tmp_path):
    # the dual-arm servicer's URDF, loaded from the file: two arms, two end-effectors
    urdf = Path(__file__).resolve().parents[2] / "models" / "dual_arm.urdf"
    if not urdf.exists():
        pytest.skip("needs the source tree")
    out = tmp_path / "o"
    result = run_cli("simulate", urdf, "--duration", "0.2", "--out", out, "--no-animation", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["ee_travel_m"]) == {"left_ee", "right_ee"}
    assert all(v >= 0 for v in summary["ee_travel_m"].values())
    assert (out / "ee_path.png").stat().st_size > 10_000
    # --ee-links picks and orders them
    result = run_cli("simulate", urdf, "--ee-links", "right_ee", "--duration", "0.05", "--out", out,
                     "--no-animation", "--no-plots", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert isinstance(summary["ee_travel_m"], float)


# ---------------------------------------------------------------------------------------------
# the slew's controller: chosen from the physics, never from dt
# ---------------------------------------------------------------------------------------------


def test_the_demo_controller_and_its_deflection_do_not_change_with_dt():
    # The CLI used to cap kd at 0.5 j/dt, so the controller changed with the step: the demo's
    # peak deflection was 1.50, 1.54 and 1.60 mrad at dt = 0.5, 1 and 2 ms. The gains now come
    # from FlexibleArm.motor_pd_gains; what remains is the torque held over each step, an O(dt)
    # effect (docs/model.md §5.3): 1.64123, 1.64147, 1.64191 mrad, 0.04 % apart.
    args = cli.build_parser().parse_args(["demo"])
    job = cli.demo_job(args)
    arm = job.arm
    gains = cli.choose_gains(arm, args)
    np.testing.assert_array_equal(np.c_[gains.kp, gains.kd], np.c_[arm.motor_pd_gains(0.25, 1.0)])
    peaks = []
    for dt in (5e-4, 1e-3, 2e-3):
        steps = round(args.duration / dt)
        pd = cli.slew_controller(arm, job.slew, steps, dt, args.slew_time, gains)
        np.testing.assert_array_equal(pd.kp, gains.kp)
        batch = orbitflex.simulate_batch(arm, arm.state(), dt, steps, u=pd, keep_rows=False, threads=1)
        peaks.append(float(np.asarray(batch.peak_deflection).max()))
    assert max(peaks) / min(peaks) - 1 < 5e-3, peaks
    # monotone in dt, as a first-order hold effect is
    assert peaks[0] < peaks[1] < peaks[2]
    assert peaks == pytest.approx([1.64123e-3, 1.64147e-3, 1.64191e-3], rel=1e-4)


def test_the_summary_names_the_gains_and_a_dt_past_the_limit_is_refused(tmp_path):
    result = run_cli("demo", "--duration", "0.05", "--out", tmp_path / "o", "--quiet", "--no-plots",
                     "--no-animation", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert re.search(r"motor PD +kp = \[20\.75, 244\.2, .*\] N·m/rad, kd = \[25\.46, 318\.1, .*\] N·m·s/rad "
                     r"\(bandwidth 0\.25 Hz, damping ratio 1\)", result.stdout), result.stdout
    assert "RK4 stability limit of the closed loop 0.00624 s" in result.stdout
    controller = json.loads((tmp_path / "o" / "summary.json").read_text())["controller"]
    arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    kp, kd = arm.motor_pd_gains(0.25)
    assert controller == {"kp": kp.tolist(), "kd": kd.tolist(), "bandwidth_hz": 0.25, "damping_ratio": 1.0,
                          "given": [], "rk4_stability_limit_s": pytest.approx(0.0062392, rel=1e-3)}
    # past the limit: refused, one line, the controller untouched
    result = run_cli("demo", "--dt", "0.01", "--duration", "0.05", "--out", tmp_path / "p", "--quiet", cwd=tmp_path)
    assert_clean_error(result, "0.01 s is past the RK4 stability limit 0.00624 s of the closed loop",
                       "use --dt 0.002 or less, or a lower --bandwidth, or --force", flag="--dt")
    assert not (tmp_path / "p").exists()
    # --force runs it anyway, with the simulator's warning
    result = run_cli("demo", "--dt", "0.01", "--duration", "0.05", "--out", tmp_path / "p", "--quiet",
                     "--no-plots", "--no-animation", "--force", cwd=tmp_path)
    assert result.returncode in (0, 1), result.stderr[-2000:]
    assert "orbitflex: warning:" in result.stderr and "stability limit" in result.stderr
    assert json.loads((tmp_path / "p" / "summary.json").read_text())["controller"]["kp"] == kp.tolist()


def test_gains_given_by_flag_replace_the_bandwidth_rule(tmp_path, model_files):
    urdf, params = model_files
    common = [urdf, "--params", params, "--locked-joints", "finger_slide", "--duration", "0.05", "--quiet",
              "--no-plots", "--no-animation"]
    result = run_cli("simulate", *common, "--kp", "40", "30", "--kd", "4", "--out", tmp_path / "a", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "kp = [40, 30] N·m/rad, kd = 4 N·m·s/rad (as given by --kp/--kd)" in result.stdout
    controller = json.loads((tmp_path / "a" / "summary.json").read_text())["controller"]
    assert controller["kp"] == [40.0, 30.0] and controller["kd"] == [4.0, 4.0]
    assert controller["bandwidth_hz"] is None and controller["given"] == ["--kp", "--kd"]
    # one of them: the other from the bandwidth rule at --bandwidth and --damping-ratio
    result = run_cli("simulate", *common, "--kd", "4", "--bandwidth", "0.5", "--damping-ratio", "0.7",
                     "--out", tmp_path / "b", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    controller = json.loads((tmp_path / "b" / "summary.json").read_text())["controller"]
    robot = orbitflex.Robot.from_urdf(urdf, locked_joints=["finger_slide"])
    arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints.from_toml(params, robot))
    assert controller["kp"] == arm.motor_pd_gains(0.5, 0.7)[0].tolist() and controller["kd"] == [4.0, 4.0]
    assert (controller["bandwidth_hz"], controller["damping_ratio"], controller["given"]) == (0.5, 0.7, ["--kd"])
    assert "bandwidth 0.5 Hz, damping ratio 0.7; --kd as given" in result.stdout


def test_every_unsupported_joint_is_named_with_the_flag_that_locks_them_all(tmp_path):
    # panda's two prismatic fingers: the CLI named the first under --locked-joints, a flag never
    # given, and following its advice gave the same error for the second
    from conftest import erd_case

    panda = erd_case("panda").path
    common = ["--duration", "0.02", "--quiet", "--no-plots", "--no-animation"]
    result = run_cli("simulate", panda, *common, "--out", tmp_path / "a", cwd=tmp_path)
    assert_clean_error(result, "2 joints have types orbitflex does not model: 'panda_finger_joint1' (prismatic), "
                               "'panda_finger_joint2' (prismatic)",
                       "lock them with --locked-joints panda_finger_joint1,panda_finger_joint2 to treat them "
                       "as fixed", flag="URDF")
    flag = re.search(r"--locked-joints (\S+)", result.stderr).group(1)
    result = run_cli("simulate", panda, "--locked-joints", flag, *common, "--out", tmp_path / "b", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-1500:]


def test_the_attitude_legend_sits_beside_the_curves(figures):
    # it covered the yaw curve over the whole transient (2.5 s to 5.5 s of the demo)
    kept, _ = figures
    fig = kept["base_attitude.png"]
    fig.canvas.draw()
    ax = fig.axes[0]
    legend = ax.get_legend().get_window_extent()
    assert legend.x0 >= ax.get_window_extent().x1, (legend, ax.get_window_extent())



def test_a_misspelt_flag_gets_the_flag_it_meant(model_files, tmp_path):
    # `--base_mass` was only "unrecognized arguments"
    urdf, params = model_files
    for typed, meant in (("--base_mass", "--base-mass"), ("--Duration", "--duration"), ("--record_every", "--record-every")):
        result = run_cli("simulate", urdf, "--params", params, typed, "5", "--out", tmp_path / "o", "--quiet",
                         cwd=tmp_path)
        assert_clean_error(result, f"no such flag; did you mean {meant}? (see 'orbitflex simulate --help')",
                           flag=typed)
    # nothing close: no guess
    result = run_cli("demo", "--base-mass", "5", cwd=tmp_path)  # demo has no bus option
    assert_clean_error(result, "unrecognized arguments: --base-mass 5 (see 'orbitflex demo --help')")
    assert not (tmp_path / "o").exists()
