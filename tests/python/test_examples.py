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
