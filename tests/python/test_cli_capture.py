"""``orbitflex capture`` in a subprocess, as a user runs it: the summary, the files, the event in
them, and usage errors."""

import json
import math
import subprocess
import sys

import numpy as np


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
