"""The runnable examples in examples/ run as the README says, and show what they claim."""

from __future__ import annotations

import pathlib
import re
import subprocess
import sys

import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"


@pytest.mark.skipif(not (EXAMPLES / "lqr_hold.py").exists(), reason="needs the source tree")
def test_lqr_example_holds_the_pose_better_than_a_motor_pd(tmp_path):
    out = tmp_path / "lqr.png"
    result = subprocess.run([sys.executable, str(EXAMPLES / "lqr_hold.py"), "--duration", "2", "--out", str(out)],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    rows = {m.group(1): [float(v) for v in m.group(2).split()]
            for m in re.finditer(r"^(none|motor PD|LQR)\s+([-0-9. ]+)$", result.stdout, re.M)}
    assert set(rows) == {"none", "motor PD", "LQR"}, result.stdout
    # peak and final EE errors (mm): the LQR holds best, leaving the motors free holds nothing
    assert rows["LQR"][0] < rows["motor PD"][0] < rows["none"][0]
    assert rows["LQR"][1] < 0.2 * rows["motor PD"][1]
    assert rows["none"][2] == 0.0
    assert out.stat().st_size > 10_000


@pytest.mark.skipif(not (EXAMPLES / "dual_arm.py").exists(), reason="needs the source tree")
def test_dual_arm_example_shows_the_slew_disturbing_the_holding_arm(tmp_path):
    out = tmp_path / "dual.png"
    result = subprocess.run([sys.executable, str(EXAMPLES / "dual_arm.py"), "--out", str(out)],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    text = result.stdout
    assert "end-effectors ['left_ee', 'right_ee']" in text
    number = lambda pattern: float(re.search(pattern, text).group(1))  # noqa: E731
    bus_deg = number(r"bus: turned up to ([0-9.]+) deg")
    inertial = number(r"right EE: moved up to ([0-9.]+) mm in the inertial frame")
    on_bus = number(r", ([0-9.]+) mm relative to the bus")
    deflection = number(r"joint deflection up to ([0-9.]+) mrad")
    momentum = number(r"\|h\| ≤ ([0-9.e+-]+)")
    # the slew turns the bus by degrees, which carries the holding arm's EE by metres; its own
    # joints give way by millimetres to centimetres; momentum stays at round-off
    assert 5.0 < bus_deg < 45.0
    assert inertial > 10 * on_bus > 0
    assert 0.1 < deflection < 50
    assert momentum < 1e-8
    assert out.stat().st_size > 10_000
