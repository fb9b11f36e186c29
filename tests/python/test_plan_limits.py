"""Planning with absurd numbers (issue 24): plans stay within the durations the planner covers
(1 ns to 1e9 s per segment), and every message names what is at fault truthfully, in the CLI
as one short line naming the flag."""

from __future__ import annotations

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, LimitWarning, Limits, ModelError, cli, plan_slew

ARM = FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
# the same arm on continuous joints: no position limits, which would refuse a goal of 1e100 rad
# before the inverse dynamics could overflow
CONTINUOUS_URDF = orbitflex.models.space_arm_urdf().replace('type="revolute"', 'type="continuous"')
FREE_ARM = FlexibleArm(orbitflex.Robot.from_urdf_string(CONTINUOUS_URDF), orbitflex.models.space_arm_joints())
GOAL = np.full(7, 0.3)


def test_limits_that_need_more_than_1e9_s_are_refused():
    # Limits(1e-10, 1e-10) gave a plan of 2.46e10 s, though the docs say no segment over 1e9 s
    with pytest.raises(ModelError, match=r"^limits: no duration up to 1e9 s meets them: \w+\[\d\] still needs "
                                         r"\S+ at 1e9 s, over its limit of 1e-10$"):
        plan_slew(ARM, GOAL, limits=Limits(1e-10, 1e-10))
    # a hundred times both limits: the speed limit alone asks for 100 times less, 7.4e7 s
    plan = plan_slew(ARM, GOAL, limits=Limits(1e-8, 1e-8))
    assert 1e7 < plan.duration <= 1e9


def test_limits_too_loose_to_bind_are_not_reported_as_binding():
    # Limits(1e300) reported motor_torque "binding" at 3.9e32 of 1e300, when the 1 ns floor
    # of the search was what set the duration
    with pytest.raises(ModelError) as e, pytest.warns(LimitWarning, match="motor_torque"):
        plan_slew(ARM, GOAL, limits=Limits(1e300, 1e300))
    message = str(e.value)
    assert message.startswith("limits: every limit holds even at 1e-9 s, the shortest segment duration planned, "
                              "so none of them binds (at 1e-9 s motor_torque["), message
    assert message.endswith("against its limit of 1e300); give the hardware's limits")
    # a huge speed limit with a real torque limit still plans: the torque binds
    with pytest.warns(LimitWarning, match="joint_speed"):
        assert plan_slew(ARM, GOAL, limits=Limits(50.0, 1e300)).binding["limit"] == "motor_torque"


@pytest.mark.parametrize("waypoints,frm", [(None, "q_start"), ([np.full(7, 0.2)], "waypoints[0]")])
def test_a_goal_too_large_for_floating_point_is_named(waypoints, frm):
    # a goal of 1e100 said "motor_torque[0] still needs NaN"
    with pytest.raises(ModelError) as e, pytest.warns(LimitWarning, match="joint_speed"):
        plan_slew(FREE_ARM, np.full(7, 1e100), limits=Limits(50.0, 1.0), waypoints=waypoints)
    assert str(e.value) == (f"q_goal: too large for floating point: the slew from {frm} to it, 1e100 rad on joint "
                            "6, makes the inverse dynamics overflow at every duration up to 1e9 s")


def test_a_deflection_too_large_is_blamed_on_the_deflection():
    # it was blamed on "motion: ... q, qd, qdd, qddd, qdddd overflowed"
    z = np.zeros(7)
    with pytest.raises(ModelError, match=r"^deflection: too large for floating point: .* with deflection\[\d\] = "
                                         r"1e308$"):
        ARM.inverse_dynamics(z, z, z, z, z, deflection=np.full(7, 1e308))


# ---- the plan CLI: one short line, naming the flag at fault ------------------------------------


@pytest.fixture(scope="module")
def arm_urdf(tmp_path_factory):
    path = tmp_path_factory.mktemp("plan_limits") / "arm.urdf"
    path.write_text(CONTINUOUS_URDF)  # no position limits: --goal 1e100 reaches the planner
    return path


def cli_line(argv, capsys) -> str:
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as e:
        code = e.code
    # limits past the URDF's are warned about first (a line of its own): the error is one line
    err = [line for line in capsys.readouterr().err.strip().splitlines()
           if not line.startswith("orbitflex: warning: ")]
    assert code == 2 and len(err) == 1 and err[0].startswith("orbitflex: error: "), (code, err)
    return err[0][len("orbitflex: error: "):]


@pytest.mark.parametrize("extra,flag,words", [
    (["--motor-torque", 1e-300, "--joint-speed", 1], "--motor-torque", "no duration up to 1e9 s"),
    (["--motor-torque", 50, "--joint-speed", 1e-300], "--joint-speed", "no duration up to 1e9 s"),
    (["--motor-torque", 1e300, "--joint-speed", 1e300], "--motor-torque", "none of them binds"),
    (["--motor-torque", 1e14, "--joint-speed", 1e8], "--motor-torque/--joint-speed", "longer than the plan"),
    (["--motor-torque", 50, "--joint-speed", 1, "--settle", 1e300], "--settle", "shorten --settle"),
    (["--motor-torque", 50, "--joint-speed", 1, "--kp", 1e300], "--kp", "lower --kp"),
    (["--motor-torque", 50, "--joint-speed", 1, "--kd", 1e300], "--kd", "cannot be computed"),
    (["--motor-torque", 50, "--joint-speed", 1, "--dt", 1e-300], "--dt", "lengthen --dt"),
    (["--motor-torque", 50, "--joint-speed", 1, "--goal", 1e100], "--goal", "too large for floating point"),
], ids=["tiny-torque", "tiny-speed", "huge-limits", "plan-shorter-than-dt", "settle", "kp", "kd", "dt", "goal"])
def test_plan_cli_absurd_numbers_are_one_short_line_naming_the_flag(arm_urdf, tmp_path, capsys, extra, flag, words):
    # Issue 24: 1,100-2,100-character errors full of digits, most naming --dt; huge limits and
    # huge --kd were tracebacks
    argv = ["plan", arm_urdf, "--goal", 0.3, *extra, "--out", tmp_path / "out", "--no-plots"]
    line = cli_line(argv, capsys)
    assert line.startswith(flag + ": "), line
    assert words in line and len(line) < 400, line
    assert ",000," not in line  # no runs of digits
