"""``orbitflex capture`` in a subprocess, as a user runs it: the summary, the files, the event in
them, and usage errors."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def run_cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "orbitflex", *args], capture_output=True, text=True,
                          timeout=300, cwd=cwd)


def test_capture_writes_the_summary_and_the_plots(tmp_path):
    r = run_cli("capture", "--duration", "8", "--out", "out", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "captured at t = 4.500 s" in r.stdout
    assert "impulse |F| =" in r.stdout and "peak spring torque" in r.stdout
    out = tmp_path / "out"
    for name in ("capture_summary.json", "capture.npz", "capture_bus_rates.png",
                 "capture_spring_torques.png", "capture_target_rates.png"):
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "capture_summary.json").read_text())
    event = summary["event"]
    assert event["step"] == 4500 and math.isclose(event["time_s"], 4.5)
    assert event["momentum_change"] < 1e-10
    m = summary["metrics"]
    assert m["captured"] and m["peak_spring_torque"] > 0 and m["bus_kick_deg_s"] > 0
    # without an attitude actuator the stack keeps turning: not detumbled
    assert math.isnan(m["detumble_time"])
    data = np.load(out / "capture.npz")
    assert data["target"].shape == (data["x"].shape[0], 13)
    np.testing.assert_array_equal(data["x_before"], data["x"][900])  # row 900 = t 4.5 s (every 5th)


def test_a_target_drifting_too_slowly_is_not_captured(tmp_path):
    # 2 cm/s would reach the EE at 5 s; at --meet 20 the handle is still 0.3 m away at 5 s
    r = run_cli("capture", "--duration", "5", "--meet", "20", "--no-plots", "--out", "out", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "no capture in 5 s" in r.stdout
    assert json.loads((tmp_path / "out" / "capture_summary.json").read_text())["captured"] is False


def test_usage_errors(tmp_path):
    r = run_cli("capture", "--tumble", "-1", cwd=tmp_path)
    assert r.returncode == 2 and "--tumble" in r.stderr
    r = run_cli("capture", "--record-every", "0", cwd=tmp_path)
    assert r.returncode == 2 and "--record-every" in r.stderr


def test_capture_with_wheels_detumbles_the_stack(tmp_path):
    r = run_cli("capture", "--wheels", "pyramid", "--duration", "60", "--record-every", "10", "--out", "out",
                cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "4 reaction wheels" in r.stdout and "stack detumbled" in r.stdout
    out = tmp_path / "out"
    assert (out / "capture_wheels.png").stat().st_size > 0
    summary = json.loads((out / "capture_summary.json").read_text())
    m = summary["metrics"]
    assert m["wheels"] == 4 and math.isfinite(m["detumble_time"]) and not m["wheels_saturated"]
    assert 0 < m["peak_wheel_torque_fraction"] < 1 and 0 < m["peak_wheel_speed_fraction"] < 1
    assert summary["wheels"]["attitude_pd"]["kp"][0] > 0
    data = np.load(out / "capture.npz")
    assert data["wheel_speed"].shape == (data["x"].shape[0], 4)


def test_capture_with_a_wheels_file_uses_its_gains(tmp_path):
    # the example file's wheels and gains (2e5, 2e4: a stiff bus): the summary reports them, and
    # tiny motors saturate, which the summary says
    text = (EXAMPLES / "wheels.toml").read_text().replace("max_torque = 60.0", "max_torque = 0.05")
    (tmp_path / "small.toml").write_text(text)
    r = run_cli("capture", "--wheels", "small.toml", "--duration", "8", "--no-plots", "--out", "out",
                cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "SATURATED" in r.stdout
    summary = json.loads((tmp_path / "out" / "capture_summary.json").read_text())
    assert summary["wheels"]["attitude_pd"]["kp"] == [2.0e5] * 3
    assert summary["metrics"]["wheels_saturated"] is True


def test_a_bad_wheels_file_is_a_usage_error(tmp_path):
    (tmp_path / "bad.toml").write_text("[defaults]\nmass = -1\n")
    r = run_cli("capture", "--wheels", "bad.toml", cwd=tmp_path)
    assert r.returncode == 2 and "--wheels" in r.stderr and "bad.toml" in r.stderr
    r = run_cli("capture", "--wheels", "missing.toml", cwd=tmp_path)
    assert r.returncode == 2 and "cannot read" in r.stderr
