"""The command line: ``orbitflex demo`` and ``orbitflex simulate URDF --params TOML``.

Each test runs the CLI in a subprocess (``python -m orbitflex``), as a user would, with a time
limit so that a hang fails the test instead of stalling the suite. Outputs are checked against
each other (the summary against the saved trajectory), not against recorded numbers.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

PNGS = {
    "joint_vs_motor_angles.png",
    "deflection.png",
    "base_attitude.png",
    "ee_path.png",
    "momentum_drift.png",
}

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


def assert_clean_error(result, *words):
    """Exit code 2, a one-line ``orbitflex: error: ...`` message, no traceback."""
    assert result.returncode == 2, (result.returncode, result.stdout[-500:], result.stderr[-1500:])
    assert "Traceback" not in result.stderr, result.stderr[-1500:]
    assert "error" in result.stderr
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
    result = run_cli("demo", "--duration", "0.5", "--out", out, "--quiet", cwd=out.parent)
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


def test_demo_writes_trajectory_summary_and_plots(demo_run):
    result, out = demo_run
    assert result.returncode == 0, result.stderr[-2000:]
    assert (out / "trajectory.npz").is_file()
    assert (out / "summary.json").is_file()
    pngs = {p.name for p in out.glob("*.png")}
    assert pngs == PNGS
    for name in PNGS:
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 1000, name


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
    for option in ["--duration", "--dt", "--out", "--quiet", "--no-plots"]:
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
    assert_clean_error(result, str(missing))


def test_missing_params_file(model_files, tmp_path):
    urdf, _ = model_files
    missing = tmp_path / "absent.toml"
    result = run_cli("simulate", urdf, "--params", missing, "--locked-joints", "finger_slide",
                     "--duration", "0.1", "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, str(missing))


def test_unlocked_prismatic_joint_is_a_clean_error(model_files, tmp_path):
    urdf, params = model_files
    result = run_cli("simulate", urdf, "--params", params, "--duration", "0.1",
                     "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, "finger_slide", "prismatic")


def test_malformed_urdf(tmp_path, model_files):
    _, params = model_files
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot>")
    result = run_cli("simulate", bad, "--params", params, "--duration", "0.1",
                     "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, str(bad))


def test_unknown_ee_link(model_files, tmp_path):
    urdf, params = model_files
    result = run_cli("simulate", urdf, "--params", params, "--ee-link", "gripper",
                     "--duration", "0.1", "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, "gripper")


def test_missing_params_option(model_files, tmp_path):
    urdf, _ = model_files
    result = run_cli("simulate", urdf, "--duration", "0.1", cwd=tmp_path)
    assert_clean_error(result, "--params")


def test_wrong_slew_count(model_files, tmp_path):
    urdf, params = model_files
    result = run_cli("simulate", urdf, "--params", params, "--locked-joints", "finger_slide",
                     "--slew", "0.1", "0.2", "0.3", "--duration", "0.1",
                     "--out", tmp_path / "o", "--quiet", cwd=tmp_path)
    assert_clean_error(result, "--slew")


@pytest.mark.parametrize("dt", ["0", "-0.001", "nan"])
def test_invalid_dt_is_a_clean_error(dt, tmp_path):
    # dt = 0 used to raise ZeroDivisionError with a traceback; a negative dt silently ran zero
    # steps and exited 0.
    result = run_cli("demo", "--duration", "0.2", "--dt", dt, "--out", tmp_path / "o",
                     "--quiet", "--no-plots", cwd=tmp_path)
    assert_clean_error(result, "dt")


@pytest.mark.parametrize("duration", ["-1", "-0.5"])
def test_invalid_duration_is_a_clean_error(duration, tmp_path):
    # A run that simulates nothing must say why instead of printing a summary of zero steps.
    result = run_cli("demo", "--duration", duration, "--out", tmp_path / "o",
                     "--quiet", "--no-plots", cwd=tmp_path)
    assert_clean_error(result, "duration")


@pytest.mark.parametrize("dt", [0.03, 0.05])
def test_diverging_run_reports_where_it_stopped(tmp_path, dt):
    # dt far past the RK4 limit (~0.01 s): the CLI must warn, say the run diverged, report the
    # step and time of the whole run (not of an internal chunk), keep the finite part (valid
    # states) and exit non-zero.
    out = tmp_path / "div"
    result = run_cli("demo", "--duration", "2", "--dt", dt, "--out", out, "--quiet",
                     "--no-plots", cwd=tmp_path, timeout=60.0)
    assert result.returncode != 0
    assert "Traceback" not in result.stderr, result.stderr[-1500:]
    assert "stability limit" in result.stderr  # the RuntimeWarning
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
