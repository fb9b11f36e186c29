"""Campaigns with the bus held by reaction wheels (``Campaign(wheels=..., attitude_kp=...,
attitude_kd=...)``): the wheel parameters and the AttitudePD gains disperse; each row's wheel
metrics (peak speed and torque fractions, pointing error) are its run's, and the run is the
single ``arm.simulate`` with the drawn wheels and controller, bit for bit; the table is the same
in any chunking, locally and on a real ``dask.distributed`` LocalCluster; misaligned axes are
tipped by exactly the drawn angle."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import orbitflex
from orbitflex import AttitudePD, MotorPD

pd = pytest.importorskip("pandas")
pytest.importorskip("pyarrow")
from orbitflex.campaign import Campaign, CampaignError, Dispersion, summary  # noqa: E402
from orbitflex.campaign.wheels import tipped  # noqa: E402

GOAL = [0.4, 0.6, -0.5, 0.8, -0.6, 0.5, 1.0]
WHEEL_DISPERSIONS = [Dispersion("wheel_spin_inertia", "lognormal", sigma=0.1),
                     Dispersion("wheel_max_torque", "uniform", relative=0.2),
                     Dispersion("wheel_max_speed", "uniform", low=300.0, high=900.0, per_joint=False),
                     Dispersion("wheel_friction", "uniform", low=0.0, high=0.02),
                     Dispersion("wheel_misalignment", "normal", std=0.01),
                     Dispersion("attitude_kp", "lognormal", sigma=0.3),
                     Dispersion("attitude_kd", "normal", relative=0.1, per_joint=False),
                     Dispersion("stiffness", "lognormal", sigma=0.2)]


def wheeled(**changes):
    kp, kd = orbitflex.models.PYRAMID_GAINS
    spec = dict(goal=np.multiply(GOAL, 0.3), kp=1000.0, kd=100.0, dt=2e-3, duration=1.6, slew_time=1.4, runs=8, seed=3,
                record_every=5, name="wheels", wheels=orbitflex.models.pyramid_wheels(), attitude_kp=kp,
                attitude_kd=kd, dispersions=WHEEL_DISPERSIONS)
    spec.update(changes)
    return Campaign(**spec)


@pytest.fixture(scope="module")
def reference():
    return wheeled().run(threads=1)


def kept(rows, every):
    """The rows a run keeps with ``record_every = every`` (and the final one)."""
    out = rows[::every]
    return out if (len(rows) - 1) % every == 0 else np.concatenate([out, rows[-1:]])


def test_a_row_is_its_single_run_bit_for_bit(reference):
    c = wheeled()
    nominal = orbitflex.models.pyramid_wheels()
    assert {"peak_wheel_speed_fraction", "peak_wheel_torque_fraction", "pointing_error",
            "wheel_spin_inertia[3]", "wheel_misalignment[0]", "attitude_kp[2]", "attitude_kd[0]"} <= set(reference)
    assert reference["ok"].all()
    for run in (0, int(reference["pointing_error"].idxmax())):
        v = c.parameters(run)
        axes = tipped(np.asarray(nominal.axes), v["wheel_misalignment"])
        wheels = orbitflex.ReactionWheels(axes, nominal.positions, nominal.mass, v["wheel_spin_inertia"],
                                          # J_t scales with J_s: a rotor of the same shape
                                          np.asarray(nominal.transverse_inertia) * v["wheel_spin_inertia"]
                                          / np.asarray(nominal.spin_inertia), v["wheel_max_torque"], v["wheel_max_speed"],
                                          v["wheel_friction"])
        robot = orbitflex.models.space_arm()
        joints = orbitflex.FlexibleJoints(v["stiffness"], *(np.asarray(getattr(orbitflex.models.space_arm_joints(), p))
                                                             for p in ("motor_inertia", "damping", "motor_damping")))
        arm = orbitflex.FlexibleArm(robot, joints, wheels=wheels)
        theta_ref, theta_dot_ref = c._reference(7, v["q0"], v["goal"], c.steps)
        # the controller knows the nominal axes, not the misaligned ones
        hold = AttitudePD(v["attitude_kp"], v["attitude_kd"], allocation=np.linalg.pinv(np.asarray(nominal.axes).T))
        single = arm.simulate(arm.state(q=v["q0"]), c.dt, c.steps, u=MotorPD(v["kp"], v["kd"], theta_ref, theta_dot_ref),
                              wheel_torque=hold)
        traj = c.trajectory(run)
        np.testing.assert_array_equal(traj.x, single.x)
        np.testing.assert_array_equal(traj.wheel_torque, single.wheel_torque)
        # the row's wheel metrics, recomputed from the run's kept rows
        speed = kept(np.abs(single.wheel_speed), c.record_every)
        torque = np.abs(single.wheel_torque)[:: c.record_every][: len(speed) - 1]
        q = kept(single.base_pose[:, 3:], c.record_every)
        row = reference.iloc[run]
        assert row["peak_wheel_speed_fraction"] == (speed / v["wheel_max_speed"]).max()
        assert row["peak_wheel_torque_fraction"] == (torque / v["wheel_max_torque"]).max()
        assert row["pointing_error"] == orbitflex.rotation_angle(q[0], q).max()
    # the wheels held the bus: each run's pointing error is under a quarter of the turn of the
    # free bus (0.15 rad) in the nominal slew; this quintic slew asks more than 60 N·m of them,
    # and the table says so (the torque limit is reached in every run)
    free = wheeled(wheels=None, attitude_kp=None, attitude_kd=None, dispersions=[]).run(runs=1, threads=1)
    assert reference["pointing_error"].max() < 0.25 * free["base_attitude_change"][0]
    assert (reference["peak_wheel_torque_fraction"] == 1.0).all()
    assert (reference["peak_wheel_speed_fraction"] < 1.0).all()
    s = summary(reference)
    assert s.loc["pointing_error", "unit"] == "rad" and s.loc["pointing_error", "count"] == 8


def test_the_table_is_the_same_in_chunks_threads_and_on_a_local_cluster(reference):
    distributed = pytest.importorskip("dask.distributed")
    c = wheeled()
    pd.testing.assert_frame_equal(c.run(chunk_runs=3, threads=2), reference, check_exact=True)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        table = c.run(client=client, chunk_runs=3)
    pd.testing.assert_frame_equal(table, reference, check_exact=True)
    assert all(e["worker"].startswith("tcp://127.0.0.1:") for e in c.log)


def test_misalignment_tips_each_axis_by_the_drawn_angle():
    axes = np.vstack([np.asarray(orbitflex.models.pyramid_wheels().axes), [[0.0, 0.0, 1.0]]])
    angles = np.array([0.01, -0.02, 0.0, 0.3, 0.05])
    out = tipped(axes, angles)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, rtol=0, atol=1e-15)
    # the angle between each axis and its tipped self is |angle| (to the round-off of arccos of a
    # dot product near 1: 1e-15 / sin(angle), at most 1e-13 here)
    between = np.arctan2(np.linalg.norm(np.cross(axes, out), axis=1), np.einsum("ij,ij->i", axes, out))
    np.testing.assert_allclose(between, np.abs(angles), rtol=0, atol=1e-14)
    # a positive angle moves the axis away from the bus's z axis
    assert out[0, 2] < axes[0, 2] and out[1, 2] > axes[1, 2]


@pytest.mark.parametrize("changes, message", [
    (dict(wheels=None, attitude_kp=None, attitude_kd=None), "wheel_spin_inertia: applies to a campaign with reaction wheels"),
    (dict(wheels=None, attitude_kp=1.0, attitude_kd=None, dispersions=[]), "attitude_kp: applies to a campaign with reaction wheels"),
    (dict(attitude_kd=None), "attitude_kd: a campaign with wheels holds the bus with an AttitudePD; expected one gain"),
    (dict(attitude_kp=[1.0, 2.0]), "attitude_kp: a campaign with wheels holds the bus"),
    (dict(wheels="pyramid"), "wheels: expected an orbitflex.ReactionWheels, given str"),
    (dict(dispersions=[Dispersion("attitude_kp", "normal", std=[1.0, 2.0])]),
     "dispersion[0].std: expected a scalar or 3 values (attitude_kp), given 2"),
])
def test_declaration_errors_name_the_field(changes, message):
    with pytest.raises(CampaignError) as e:
        wheeled(**changes).check()
    assert message in str(e.value)


def test_a_draw_out_of_the_domain_names_the_run():
    c = wheeled(dispersions=[Dispersion("wheel_max_torque", "normal", std=1e3)])
    with pytest.raises(CampaignError, match=r"wheel_max_torque\[\d\] drew .* N·m \(expected > 0\)"):
        c.run(runs=20)


# -- files and the CLI ---------------------------------------------------------------------------

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def short_file(tmp_path, extra=""):
    """The example campaign, 0.4 s long, with wheel dispersions (and ``extra`` at the top)."""
    spec = tmp_path / "c.toml"
    text = (EXAMPLES / "campaign.toml").read_text().replace("duration = 12.0", "duration = 0.4") \
        .replace("slew_time = 5.0", "slew_time = 0.3")
    spec.write_text(extra + text + '\n[[dispersion]]\nparameter = "wheel_max_torque"\ndistribution = "uniform"\n'
                    'relative = 0.2\n\n[[dispersion]]\nparameter = "attitude_kd"\ndistribution = "lognormal"\n'
                    'sigma = 0.2\n')
    return spec


def test_a_campaign_file_names_its_wheels_file(tmp_path):
    (tmp_path / "w.toml").write_text((EXAMPLES / "wheels.toml").read_text())
    c = Campaign.from_toml(short_file(tmp_path, 'wheels = "w.toml"\n'))
    assert len(c.wheels) == 4 and c.attitude_kp.tolist() == [2.0e5] * 3
    again = Campaign.from_toml(short_file(tmp_path), wheels=EXAMPLES / "wheels.toml")
    pd.testing.assert_frame_equal(c.run(runs=3, threads=1), again.run(runs=3, threads=1), check_exact=True)
    with pytest.raises(CampaignError, match=r"c.toml: wheel_max_torque: applies to a campaign with reaction wheels"):
        Campaign.from_toml(short_file(tmp_path))
    with pytest.raises(CampaignError, match=r"c.toml: wheels: .*nope.toml: cannot read the wheels file"):
        Campaign.from_toml(short_file(tmp_path, 'wheels = "nope.toml"\n'))


def test_cli_campaign_with_wheels(tmp_path):
    spec = short_file(tmp_path)
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "orbitflex", "campaign", str(spec), "--runs", "4", "--out", str(out),
                           "--wheels", str(EXAMPLES / "wheels.toml"), "--no-progress"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "4 runs of 0.4 s (dt = 0.002 s, 200 steps), the bus held by 4 reaction wheels, here" in done.stdout
    for metric in ("pointing_error", "peak_wheel_speed_fraction", "peak_wheel_torque_fraction"):
        assert f"\n{metric}" in done.stdout, done.stdout
    table = pd.read_parquet(out / "runs.parquet")
    expected = Campaign.from_toml(spec, wheels=EXAMPLES / "wheels.toml").run(runs=4)
    pd.testing.assert_frame_equal(table, expected, check_exact=True)
    stats = pd.read_csv(out / "summary.csv", index_col="metric")
    assert stats.loc["pointing_error", "max"] == pytest.approx(table["pointing_error"].max(), rel=1e-15)
    bad = subprocess.run([sys.executable, "-m", "orbitflex", "campaign", str(spec), "--wheels", "nope.toml"],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert bad.returncode == 2 and "orbitflex: error: --wheels: nope.toml: cannot read the wheels file" in bad.stderr, \
        bad.stderr
    assert "Traceback" not in bad.stderr
