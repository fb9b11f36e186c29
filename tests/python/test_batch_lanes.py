"""``simulate_batch(..., lanes=...)``: every choice gives the same record, bit for bit (SIMD lanes
of 4 and 8, automatic, the scalar path, and ``ORBITFLEX_LANES=1``), for dispersed arms of one
structure with diverging runs, with and without reaction wheels (tables, AttitudePD, Sampled); a campaign's table is the same with and without lanes; a bad
``lanes`` names itself."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import orbitflex
from orbitflex import AttitudePD, FlexibleArm, FlexibleJoints, ModelError, MotorPD, Sampled

pd = pytest.importorskip("pandas")

N = 7
DT = 1e-3
STEPS = 45


def _same(a, b):
    for name in ("x", "u", "final_state", "peak_deflection", "peak_torque", "failed_step", "ok"):
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        assert x.shape == y.shape, name
        # bit for bit, NaN rows after a failure included
        assert np.array_equal(x.view(np.uint64) if x.dtype == np.float64 else x,
                              y.view(np.uint64) if y.dtype == np.float64 else y), name
    assert a.messages == b.messages


@pytest.fixture(scope="module")
def dispersed():
    """11 runs of one structure (two lane groups of 4 and one of 3, or one of 8 and one of 3):
    dispersed stiffness and damping, payloads on runs 3 and 7, per-run PD gains (runs 2 and 9
    far past the RK4 limit: they diverge), base wrench tables."""
    robot = orbitflex.models.space_arm()
    joints = orbitflex.models.space_arm_joints()
    arms = []
    for r in range(11):
        k = np.asarray(joints.stiffness) * (1 + 0.03 * r)
        d = np.asarray(joints.damping) + 0.01 * r
        j = FlexibleJoints(k, joints.motor_inertia, damping=d, motor_damping=joints.motor_damping)
        rob = robot.with_payload(2.0 * r, com=[0, 0, 0.1]) if r in (3, 7) else robot
        arms.append(FlexibleArm(rob, j))
    x0s = np.array([arms[r].state(qd=0.02 * r - 0.01 * np.arange(N), base_twist=[0, 0, 0.01 * r, 0, 0, 0])
                    for r in range(11)])
    pds = [MotorPD(kp=np.full(N, 1e12 if r in (2, 9) else 300.0 + r), kd=np.full(N, 30.0),
                   theta_ref=np.full(N, 0.05 * r)) for r in range(11)]
    rng = np.random.default_rng(3)
    fb = rng.normal(size=(11, STEPS, 6))
    return arms, x0s, pds, fb


@pytest.mark.parametrize("record_every,keep_rows", [(1, True), (4, True), (4, False)])
def test_every_lanes_choice_gives_the_scalar_record(dispersed, record_every, keep_rows, monkeypatch):
    arms, x0s, pds, fb = dispersed

    def run(lanes):
        with pytest.warns(RuntimeWarning):  # runs 2 and 9 are past their stability limit
            return orbitflex.simulate_batch(arms, x0s, DT, STEPS, u=pds, base_wrench=fb, threads=2,
                                            record_every=record_every, keep_rows=keep_rows, lanes=lanes)

    scalar = run(False)
    assert not scalar.ok[2] and not scalar.ok[9] and scalar.ok.sum() == 9
    for lanes in (None, True, 4, 8, 1):
        _same(run(lanes), scalar)
    monkeypatch.setenv("ORBITFLEX_LANES", "1")
    _same(run(None), scalar)
    # and a run is its arm.simulate
    if keep_rows and record_every == 1:
        traj = arms[7].simulate(x0s[7], DT, STEPS, u=pds[7], base_wrench=fb[7])
        assert np.array_equal(traj.x, scalar.x[7])


def test_open_loop_tables_in_lanes_equal_the_scalar_path():
    arm = FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    u = np.sin(np.arange(9 * STEPS * N) * 0.37).reshape(9, STEPS, N)
    a = orbitflex.simulate_batch(arm, arm.state(), DT, STEPS, u=u, record_every=3, lanes=False)
    for lanes in (4, 8, None):
        _same(orbitflex.simulate_batch(arm, arm.state(), DT, STEPS, u=u, record_every=3, lanes=lanes), a)


def _wheels(r):
    """Run ``r``'s four wheels in a pyramid, dispersed: axes tipped by 0.01 r rad, inertias,
    friction and limits of its own."""
    phi = np.pi / 2 * np.arange(4) + 0.3 + 0.02 * r
    tilt = np.arccos(np.sqrt(1 / 3)) + 0.01 * r
    axes = np.column_stack([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), np.full(4, np.cos(tilt))])
    positions = np.column_stack([0.3 * np.cos(phi), 0.3 * np.sin(phi), np.full(4, -0.4)])
    return orbitflex.ReactionWheels(axes, positions, 4.0 + 0.1 * r, 0.04 * (1 + 0.02 * r), 0.025,
                                    0.2 + 0.01 * r, 600.0 - 5.0 * r, friction=1e-4 * r)


@pytest.fixture(scope="module")
def wheeled():
    """11 arms of one structure with dispersed joints and wheels; starts with the bus turning and
    the wheels at their speed limits (0 and 2 just below, 1 just beyond); per-run MotorPD (runs 2
    and 9 diverge) and AttitudePD."""
    joints = orbitflex.models.space_arm_joints()
    arms, x0s = [], []
    for r in range(11):
        j = FlexibleJoints(np.asarray(joints.stiffness) * (1 + 0.03 * r), joints.motor_inertia,
                           damping=joints.damping, motor_damping=joints.motor_damping)
        arm = FlexibleArm(orbitflex.models.space_arm(), j, wheels=_wheels(r))
        limit = 600.0 - 5.0 * r
        arms.append(arm)
        x0s.append(arm.state(qd=0.02 * r - 0.01 * np.arange(N), base_twist=[0.01, -0.02, 0.01 * r, 0, 0, 0],
                             wheel_speed=[limit - 1e-3, -(limit + 0.5), limit - 0.3, 40.0 * r - 200]))
    pds = [MotorPD(kp=np.full(N, 1e12 if r in (2, 9) else 300.0 + r), kd=np.full(N, 30.0),
                   theta_ref=np.full(N, 0.05 * r)) for r in range(11)]
    atts = [AttitudePD([0.5 + 0.1 * r, 0.6, 0.7], [1.5, 1.5 + 0.2 * r, 1.0]) for r in range(11)]
    return arms, np.array(x0s), pds, atts


@pytest.mark.parametrize("case,record_every", [("tables", 1), ("tables", 4), ("shared", 1), ("per_run", 3),
                                               ("sampled", 1)])
def test_wheel_batches_in_lanes_give_the_scalar_record(wheeled, case, record_every, monkeypatch):
    """Arms with reaction wheels in lanes (dispersed wheels share a group): wheel torque tables
    past the torque limit, an AttitudePD shared or per run, Sampled MotorPD and AttitudePD with
    delays; the record of every lanes choice is the scalar one, bit for bit."""
    arms, x0s, pds, atts = wheeled
    rng = np.random.default_rng(5)
    kwargs = {
        "tables": dict(u=rng.normal(size=(11, STEPS, N)), wheel_torque=0.6 * rng.normal(size=(11, STEPS, 4))),
        "shared": dict(u=pds, wheel_torque=atts[1]),
        "per_run": dict(u=pds, wheel_torque=atts),
        "sampled": dict(u=Sampled(pds, 1 / (3 * DT), delay=1), wheel_torque=Sampled(atts, 170.0, delay=2)),
    }[case]
    if case == "tables":
        kwargs["u"][3, 13, 0] = 1e308  # run 3 fails at step 13

    def run(lanes):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # runs past their stability limit
            return orbitflex.simulate_batch(arms, x0s, DT, STEPS, threads=2, record_every=record_every,
                                            base_wrench=rng_fb, lanes=lanes, **kwargs)

    rng_fb = np.random.default_rng(3).normal(size=(11, STEPS, 6))
    scalar = run(False)
    failing = [3] if case == "tables" else [2, 9]
    assert [r for r in range(11) if not scalar.ok[r]] == failing
    for lanes in (None, True, 4, 8, 1):
        _same(run(lanes), scalar)
    monkeypatch.setenv("ORBITFLEX_LANES", "1")
    _same(run(None), scalar)
    if record_every == 1:
        applied = scalar.wheel_torque[~np.isnan(scalar.wheel_torque[:, :, 0])]
        assert np.abs(applied).max() > 1e-3
        if case == "tables":
            # the limits act: commands clipped to the torque limit and cut at the speed limit
            commanded = kwargs["wheel_torque"][0]
            assert np.any(np.abs(scalar.wheel_torque[0]) == 0.2)
            assert np.any((scalar.wheel_torque[0] == 0.0) & (commanded != 0.0))
        # and a run is its arm.simulate
        single = {
            "tables": lambda: dict(u=kwargs["u"][7], wheel_torque=kwargs["wheel_torque"][7]),
            "shared": lambda: dict(u=pds[7], wheel_torque=atts[1]),
            "sampled": lambda: dict(u=Sampled(pds[7], 1 / (3 * DT), delay=1),
                                    wheel_torque=Sampled(atts[7], 170.0, delay=2)),
        }[case]()
        traj = arms[7].simulate(x0s[7], DT, STEPS, base_wrench=rng_fb[7], **single)
        assert np.array_equal(traj.x, scalar.x[7]) and np.array_equal(traj.wheel_torque, scalar.wheel_torque[7])


@pytest.mark.parametrize("bad", [2, 0, "4", 4.0, [4]])
def test_a_bad_lanes_value_names_itself(bad):
    arm = FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    with pytest.raises(ModelError, match=r"lanes: expected None, True, False, 1, 4 or 8, given"):
        orbitflex.simulate_batch(arm, arm.state(), DT, 3, lanes=bad)


def test_a_campaign_table_is_the_same_with_and_without_lanes(monkeypatch):
    from orbitflex.campaign import Campaign, Dispersion

    c = Campaign(goal=[0.4, 0.6, -0.5, 0.8, -0.6, 0.5, 1.0], kp=1000.0, kd=100.0, dt=2e-3, duration=0.4,
                 slew_time=0.3, runs=10, seed=7, record_every=5, settle_tolerance=0.02, payload_mass=5.0,
                 payload_com=[0, 0, 0.1], name="lanes",
                 dispersions=[Dispersion("stiffness", "lognormal", sigma=0.2),
                              Dispersion("payload_mass", "uniform", low=0.0, high=20.0),
                              Dispersion("kp", "normal", relative=0.05, per_joint=False)])
    lanes = c.run(threads=2)
    monkeypatch.setenv("ORBITFLEX_LANES", "1")
    scalar = c.run(threads=2)
    pd.testing.assert_frame_equal(lanes, scalar, check_exact=True)
