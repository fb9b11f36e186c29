"""``orbitflex.campaign``: the table is the same bit for bit locally, in any chunks and thread
counts, and on a real ``dask.distributed`` cluster on loopback (also when a worker is killed
mid-campaign); each run's row equals that run made by hand; declarations name their mistakes;
the CLI writes the table, summary and plots."""

from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, FlexibleJoints, ModelError, MotorPD

pd = pytest.importorskip("pandas")
pytest.importorskip("pyarrow")
from orbitflex.campaign import Campaign, CampaignError, Dispersion, summary  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "campaign.toml"
GOAL = [0.4, 0.6, -0.5, 0.8, -0.6, 0.5, 1.0]


def small(**changes):
    """A short campaign (1.2 s runs) with every kind of dispersion."""
    spec = dict(goal=GOAL, kp=1000.0, kd=100.0, dt=2e-3, duration=1.2, slew_time=0.8, runs=24,
                seed=7, record_every=5, settle_tolerance=0.02, payload_mass=5.0, payload_com=[0, 0, 0.1],
                name="small",
                dispersions=[Dispersion("stiffness", "lognormal", sigma=0.2),
                             Dispersion("motor_inertia", "uniform", relative=0.1),
                             Dispersion("damping", "normal", std=0.05, per_joint=False),
                             Dispersion("payload_mass", "uniform", low=0.0, high=20.0),
                             Dispersion("kp", "normal", relative=0.05, per_joint=False),
                             Dispersion("goal", "normal", std=[0.01] * 7),
                             Dispersion("q0", "uniform", low=-0.02, high=0.02),
                             Dispersion("base_rate", "normal", std=0.002)])
    spec.update(changes)
    return Campaign(**spec)


@pytest.fixture(scope="module")
def reference():
    return small().run(threads=1)


def test_the_table_does_not_depend_on_chunks_or_threads(reference):
    c = small()
    assert reference["run"].tolist() == list(range(24))
    for kwargs in (dict(chunk_runs=5, threads=2), dict(chunk_runs=1), dict(chunk_runs=24, threads=None)):
        pd.testing.assert_frame_equal(c.run(**kwargs), reference, check_exact=True)
    # run i depends on (seed, i) only: fewer runs are the first rows of more
    pd.testing.assert_frame_equal(c.run(runs=10), reference.iloc[:10], check_exact=True)
    other = small(seed=8).run(runs=3)
    assert not np.array_equal(other["stiffness[0]"], reference["stiffness[0]"][:3])


def test_columns_and_a_row_made_by_hand(reference):
    c = small()
    names = list(reference.columns)
    assert names[:8] == ["run"] + [f"stiffness[{i}]" for i in range(7)]
    assert "damping[0]" in names and "payload_mass" in names and "base_rate[2]" in names
    assert names[-8:] == ["ok", "failed_step", "peak_deflection", "peak_torque", "final_error",
                          "settling_time", "base_attitude_change", "ee_error"]
    assert reference["ok"].all() and (reference["failed_step"] == -1).all()
    # run 5, by hand: its parameters, its arm, its controller, arm.simulate
    run = 5
    p = c.parameters(run)
    row = reference.iloc[run]
    for i in range(7):
        assert row[f"stiffness[{i}]"] == p["stiffness"][i]
    assert row["payload_mass"] == p["payload_mass"]
    assert len(set(p["damping"])) == 1 and len(set(p["kp"])) == 1  # one draw for all joints
    robot = orbitflex.models.space_arm().with_payload(float(p["payload_mass"]), com=[0, 0, 0.1])
    arm = FlexibleArm(robot, FlexibleJoints(p["stiffness"], p["motor_inertia"], p["damping"], p["motor_damping"]))
    # the quintic slew from q0 to goal (its values against the closed form: test_quintic.py)
    theta_ref, theta_dot_ref = orbitflex.quintic_reference(p["q0"], p["goal"], c.slew_time, c.dt, c.steps)
    pd_ = MotorPD(p["kp"], p["kd"], theta_ref, theta_dot_ref)
    x0 = arm.state(q=p["q0"], base_twist=np.r_[p["base_rate"], 0, 0, 0])
    traj = arm.simulate(x0, c.dt, c.steps, u=pd_)
    assert row["peak_deflection"] == np.abs(traj.deflection).max()
    assert row["peak_torque"] == np.abs(traj.u).max()
    assert row["final_error"] == np.abs(traj.q[-1] - p["goal"]).max()
    err = np.abs(traj.q[::c.record_every] - p["goal"]).max(axis=1)
    outside = np.nonzero(err > c.settle_tolerance)[0]
    first_settled = outside[-1] + 1 if outside.size else 0
    expected = traj.t[::c.record_every][first_settled] if err[-1] <= c.settle_tolerance else np.nan
    assert row["settling_time"] == pytest.approx(expected, abs=0, nan_ok=True)
    q0, q1 = traj.base_pose[0, 3:], traj.base_pose[-1, 3:]
    assert row["base_attitude_change"] == pytest.approx(2 * np.arccos(min(1.0, abs(q0 @ q1))), rel=1e-12)
    assert row["ee_error"] == pytest.approx(np.linalg.norm(arm.ee_pose(traj.x[-1])[:3] - c.nominal_ee()[0]), rel=1e-12)


def test_a_failing_run_is_a_row_not_a_crash():
    # some runs of this seed draw a stiffness high enough to diverge at this dt
    c = small(dt=4e-3, dispersions=[Dispersion("stiffness", "lognormal", sigma=4.0)], runs=6)
    with pytest.warns(RuntimeWarning, match="exceeds the RK4 stability limit") as caught:
        table = c.run(chunk_runs=3)
    # the warnings name the campaign's runs, not the chunk's
    named = set()
    for w in caught:
        message = str(w.message)
        listed = message.split("(runs ")[1].split(";")[0] if "(runs " in message else \
            message.split(" of run ")[1].split(" ")[0]  # one run: "… of run 4 (linearised …"
        named |= {int(i) for i in listed.split(", ")}
        assert " of 1 of " not in message and "this chunk" in message or " of run " in message
    assert named == set(table.loc[~table["ok"], "run"]), (named, table[["run", "ok"]])
    assert not table["ok"].all() and table["ok"].any()
    failed = table[~table["ok"]]
    assert (failed["failed_step"] >= 0).all()
    assert failed["final_error"].isna().all() and failed["settling_time"].isna().all()
    stats = summary(table)
    assert stats.loc["peak_deflection", "count"] == int(table["ok"].sum())


def test_summary_percentiles(reference):
    stats = summary(reference)
    v = reference["peak_deflection"].to_numpy()
    assert stats.loc["peak_deflection", "p50"] == np.percentile(v, 50)
    assert stats.loc["peak_deflection", "max"] == v.max()
    assert stats.loc["peak_deflection", "unit"] == "rad"
    assert stats.loc["settling_time", "unit"] == "s"


@pytest.mark.parametrize("changes,message", [
    (dict(dispersions=[Dispersion("stifness", "normal", std=1.0)]),
     "dispersion[0].parameter: expected one of stiffness, motor_inertia"),
    (dict(dispersions=[Dispersion("kp", "gaussian", std=1.0)]),
     "dispersion[0].distribution: expected one of normal, lognormal, uniform, given 'gaussian'"),
    (dict(dispersions=[Dispersion("kp", "normal", sigma=1.0)]),
     "dispersion[0]: a normal dispersion takes std or relative, given sigma"),
    (dict(dispersions=[Dispersion("kp", "uniform", low=2.0, high=1.0)]),
     "dispersion[0]: expected low <= high, given low=2.0, high=1.0"),
    (dict(dispersions=[Dispersion("kp", "normal", std=[1.0, 2.0])]),
     "dispersion[0].std: expected a scalar or 7 values (kp), given 2"),
    (dict(dispersions=[Dispersion("kp", "normal", std=1.0), Dispersion("kp", "normal", std=2.0)]),
     "dispersion: 'kp' is dispersed 2 times; give it once"),
    (dict(goal=[0.1, 0.2]), "goal: expected a scalar or 7 values (one per joint), given 2"),
    (dict(dt=0.0), "dt: expected a finite number > 0, given 0.0"),
    (dict(runs=0), "runs: expected an integer >= 1, given 0"),
])
def test_declaration_errors_name_the_field(changes, message):
    with pytest.raises(CampaignError) as e:
        small(**changes).run(runs=1)
    assert str(e.value).startswith(message), str(e.value)
    assert isinstance(e.value, ModelError)


def test_a_draw_out_of_the_domain_names_the_run():
    c = small(dispersions=[Dispersion("stiffness", "normal", relative=2.0)], runs=50)
    with pytest.raises(CampaignError, match=r"^run \d+: stiffness\[\d\] drew -[\d.e+-]+ N·m/rad \(expected > 0\); "
                                            r"narrow the normal dispersion or use a lognormal one"):
        c.run()


def test_toml_file_and_its_errors(tmp_path):
    c = Campaign.from_toml(EXAMPLE)
    assert c.name == "space-arm-slew" and c.runs == 200 and len(c.dispersions) == 5
    # the example a user runs first settles, every run, and stays settled (at 10 s some runs had
    # settled only at the last row)
    table = c.run(runs=16)
    assert table["ok"].all() and table["settling_time"].notna().all()
    assert (table["settling_time"] < c.duration - 1.0).all() and (table["final_error"] < c.settle_tolerance).all()
    bad = tmp_path / "bad.toml"
    bad.write_text(EXAMPLE.read_text().replace('parameter = "kp"', 'parameter = "kp"\nscale = 2'))
    with pytest.raises(CampaignError, match=r"dispersion\[3\]: 'scale' is not a known key"):
        Campaign.from_toml(bad)
    bad.write_text("[slew]\ngoal = 0.1\n")
    with pytest.raises(CampaignError, match=r"\[simulation\] dt is required"):
        Campaign.from_toml(bad)
    bad.write_text("runs = [")
    with pytest.raises(CampaignError, match=r"malformed TOML"):
        Campaign.from_toml(bad)
    with pytest.raises(FileNotFoundError, match=r"missing.toml: cannot read the campaign file"):
        Campaign.from_toml(tmp_path / "missing.toml")
    # a URDF path is taken from the file's folder, and shipped to workers as a model
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(orbitflex.SPACE_ARM_URDF)
    spec = tmp_path / "urdf.toml"
    spec.write_text(textwrap.dedent("""\
        runs = 2
        [robot]
        urdf = "arm.urdf"
        [simulation]
        dt = 2e-3
        duration = 0.2
        [slew]
        goal = 0.1
        slew_time = 0.1
        kp = 100.0
        kd = 10.0
        """))
    c = Campaign.from_toml(spec)
    assert c.robot == str(urdf)
    assert isinstance(c._portable().robot, orbitflex.Robot)
    assert len(c.run()) == 2


def test_joints_model_in_the_file(tmp_path):
    text = EXAMPLE.read_text()
    spec = tmp_path / "c.toml"
    spec.write_text(text.replace('[joints]\nmodel = "space_arm"', '[joints]\nmodel = "defaults"'))
    defaults = FlexibleJoints.defaults_for(orbitflex.models.space_arm())
    assert Campaign.from_toml(spec).joints.stiffness.tolist() == np.broadcast_to(defaults.stiffness, 7).tolist()
    assert Campaign.from_toml(EXAMPLE).joints.stiffness.tolist() == \
        np.broadcast_to(orbitflex.models.space_arm_joints().stiffness, 7).tolist()
    spec.write_text(text.replace('[joints]\nmodel = "space_arm"', '[joints]\nmodel = "stiff"'))
    with pytest.raises(CampaignError, match=r"\[joints\] model: expected \"space_arm\""):
        Campaign.from_toml(spec)


def test_payload_equals_a_merged_fixed_link():
    """``with_payload`` joins the payload to the last link as a fixed URDF link would be."""
    robot = orbitflex.models.space_arm()
    mass, com, inertia = 12.0, [0.05, -0.02, 0.1], [0.3, 0.2, 0.1]
    loaded = robot.with_payload(mass, inertia=inertia, com=com)
    xml = orbitflex.SPACE_ARM_URDF.replace("</robot>", f"""
      <link name="payload"><inertial><origin xyz="{com[0]} {com[1]} {com[2]}"/><mass value="{mass}"/>
        <inertia ixx="{inertia[0]}" iyy="{inertia[1]}" izz="{inertia[2]}" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <joint name="grasp" type="fixed"><parent link="{robot.ee_link}"/><child link="payload"/></joint>
    </robot>""")
    merged = orbitflex.Robot.from_urdf_string(xml, ee_link=robot.ee_link)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q = rng.uniform(-2, 2, 7)
        np.testing.assert_allclose(loaded.mass_matrix(q), merged.mass_matrix(q), rtol=1e-13, atol=1e-10)
    assert loaded.total_mass == pytest.approx(robot.total_mass + mass, rel=1e-15)
    with pytest.raises(ModelError, match=r"mass: expected a payload mass >= 0 kg, given -1"):
        robot.with_payload(-1.0)


def test_objects_sent_to_workers_come_back_bit_identical():
    c = small()
    back = pickle.loads(pickle.dumps(c._portable()))
    assert back.parameters(3)["stiffness"].tolist() == c.parameters(3)["stiffness"].tolist()
    p = c.parameters(3)
    for robot in (orbitflex.models.space_arm().with_payload(7.0, com=[0.1, 0, 0]),
                  orbitflex.Robot.from_urdf_string(orbitflex.SPACE_ARM_URDF)):
        arm = FlexibleArm(robot, FlexibleJoints(p["stiffness"], p["motor_inertia"]))
        twin = pickle.loads(pickle.dumps(arm))
        x = arm.state(q=np.linspace(-1, 1, 7), qd=np.linspace(1, -1, 7))
        assert arm.derivative(x, u=np.ones(7)).tobytes() == twin.derivative(x, u=np.ones(7)).tobytes()
        q = np.linspace(-1, 1, 7)
        assert robot.mass_matrix(q).tobytes() == pickle.loads(pickle.dumps(robot)).mass_matrix(q).tobytes()


# -- Dask ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        yield cluster


def test_dask_cluster_gives_the_same_table(cluster, reference):
    from dask.distributed import Client

    c = small()
    with Client(cluster) as client:
        table = c.run(client=client, chunk_runs=5)
    pd.testing.assert_frame_equal(table, reference, check_exact=True)
    workers = {entry["worker"] for entry in c.log}
    assert len(c.log) == 5 and all(w.startswith("tcp://127.0.0.1:") for w in workers)
    assert {(e["start"], e["stop"]) for e in c.log} == {(0, 5), (5, 10), (10, 15), (15, 20), (20, 24)}
    # by address, as the CLI does
    again = c.run(scheduler=cluster.scheduler_address)
    pd.testing.assert_frame_equal(again, reference, check_exact=True)


def test_killing_a_worker_mid_campaign_still_completes_every_run(cluster, reference):
    from dask.distributed import Client

    c = small()
    with Client(cluster) as client:
        pids = set(client.run(os.getpid).values())
        killed = []

        def kill_one(done, total):
            if not killed:
                victim = sorted(client.scheduler_info()["workers"])[0]
                pid = client.run(os.getpid, workers=[victim])[victim]
                killed.append(pid)
                os.kill(pid, signal.SIGKILL)

        table = c.run(client=client, chunk_runs=1, progress=kill_one)
        client.wait_for_workers(2, timeout=60)
        after = set(client.run(os.getpid).values())
    assert killed and len(c.log) == 24
    # the worker died mid-campaign: its nanny started a new process
    assert len(after - pids) == 1, (pids, after)
    pd.testing.assert_frame_equal(table, reference, check_exact=True)


# -- CLI ----------------------------------------------------------------------------------------


def test_cli_writes_the_table_summary_and_plots(tmp_path):
    spec = tmp_path / "c.toml"
    spec.write_text(EXAMPLE.read_text().replace("duration = 12.0", "duration = 0.4")
                    .replace("slew_time = 5.0", "slew_time = 0.3"))
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "orbitflex", "campaign", str(spec), "--runs", "12",
                           "--out", str(out), "--chunk-runs", "5"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "campaign space-arm-slew: 12 runs of 0.4 s (dt = 0.002 s, 200 steps), here" in done.stdout
    assert "12 runs in" in done.stdout and "0 failed" in done.stdout
    for name in ("runs.parquet", "summary.csv", "log.jsonl", "histograms.png"):
        assert (out / name).stat().st_size > 0, name
    table = pd.read_parquet(out / "runs.parquet")
    expected = Campaign.from_toml(spec).run(runs=12)
    pd.testing.assert_frame_equal(table, expected, check_exact=True)
    assert [json.loads(line)["start"] for line in (out / "log.jsonl").read_text().splitlines()] == [0, 5, 10]
    stats = pd.read_csv(out / "summary.csv", index_col="metric")
    assert stats.loc["peak_torque", "max"] == pytest.approx(table["peak_torque"].max(), rel=1e-15)


@pytest.mark.parametrize("args,message", [
    (["missing.toml"], "orbitflex: error: FILE: missing.toml: cannot read the campaign file"),
    (["{bad}"], "orbitflex: error: FILE: "),
    (["{example}", "--runs", "0"], "orbitflex: error: --runs: expected an integer >= 1, given 0"),
    (["{example}", "--scheduler", "tcp://127.0.0.1:1", "--runs", "1"],
     "orbitflex: error: --scheduler: cannot reach the Dask scheduler at tcp://127.0.0.1:1"),
])
def test_cli_errors_are_one_line(tmp_path, args, message):
    bad = tmp_path / "bad.toml"
    bad.write_text("[slew]\ngoal = 0.1\n")
    args = [a.format(bad=bad, example=EXAMPLE) for a in args]
    done = subprocess.run([sys.executable, "-m", "orbitflex", "campaign", *args], capture_output=True,
                          text=True, timeout=120, cwd=tmp_path, env={**os.environ, "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "3s"})
    assert done.returncode == 2, (done.stdout, done.stderr)
    assert message in done.stderr, done.stderr
    assert "Traceback" not in done.stderr


def test_campaign_on_the_dual_arm_with_a_payload_on_one_arm():
    # a tree: the payload goes to the end-effector named by payload_ee, and ee_error covers both
    c = Campaign(goal=[0.2] * 7 + [0.0] * 7, kp=800.0, kd=80.0, dt=1e-3, duration=0.2, slew_time=0.1,
                 runs=3, robot=orbitflex.models.dual_arm(), joints=orbitflex.models.dual_arm_joints(),
                 payload_mass=20.0, payload_ee="right_ee",
                 dispersions=[Dispersion("payload_mass", "uniform", low=10.0, high=30.0)])
    assert c.nominal_ee().shape == (2, 3)
    table = c.run()
    assert list(table["ok"]) == [True] * 3
    assert (table["ee_error"] > 0).all()
    # without payload_ee, which end-effector holds it is ambiguous: a clear error
    bad = Campaign(goal=0.1, kp=800.0, kd=80.0, dt=1e-3, duration=0.05, slew_time=0.02, runs=1,
                   robot=orbitflex.models.dual_arm(), joints=orbitflex.models.dual_arm_joints(),
                   payload_mass=20.0)
    with pytest.raises(orbitflex.ModelError, match="2 end-effectors"):
        bad.run()


# -- a run again, and a planned slew as the nominal ---------------------------------------------


def row_from(trajectory, campaign, goal, nominal_ee):
    """The table's metrics, recomputed from a run's full trajectory (every step kept)."""
    q = trajectory.q
    kept = q[:: campaign.record_every]
    if (len(q) - 1) % campaign.record_every:
        kept = np.vstack([kept, q[-1]])  # simulate keeps the final row too
    error = np.abs(kept - goal).max(axis=1)
    outside = np.nonzero(error > campaign.settle_tolerance)[0]
    times = np.r_[trajectory.t[:: campaign.record_every], trajectory.t[-1]][: len(kept)]
    settled = times[outside[-1] + 1 if outside.size else 0] if error[-1] <= campaign.settle_tolerance else np.nan
    quat0, quat1 = trajectory.base_pose[0, 3:], trajectory.base_pose[-1, 3:]
    ee = np.stack([np.asarray(trajectory.arm.ee_pose(trajectory.x[-1], ee=e)[:3])
                   for e in range(len(trajectory.arm.robot.ee_links))])
    return {"peak_deflection": np.abs(trajectory.deflection).max(), "peak_torque": np.abs(trajectory.u).max(),
            "final_error": np.abs(q[-1] - goal).max(), "settling_time": settled,
            "base_attitude_change": 2.0 * np.arccos(np.clip(abs(quat0 @ quat1), 0.0, 1.0)),
            "ee_error": np.linalg.norm(ee - nominal_ee, axis=1).max()}


def test_a_run_comes_back_as_its_trajectory_bit_for_bit(reference):
    # Campaign could not give run i back: the worst run could not be animated
    c = small()
    for run in (int(reference["peak_deflection"].idxmax()), 0, 23):
        traj = c.trajectory(run)
        assert isinstance(traj, orbitflex.Trajectory) and len(traj) == c.steps + 1
        row = reference.iloc[run]
        recomputed = row_from(traj, c, c.parameters(run)["goal"], c.nominal_ee())
        for metric, value in recomputed.items():
            assert row[metric] == value or (np.isnan(row[metric]) and np.isnan(value)), (run, metric)
        # kept rows as the campaign keeps them: the same states, bit for bit
        thin = c.trajectory(run, record_every=c.record_every)
        np.testing.assert_array_equal(thin.x[:-1], traj.x[:: c.record_every][: len(thin.x) - 1])
        np.testing.assert_array_equal(thin.x[-1], traj.x[-1])
    with pytest.raises(CampaignError, match=r"^run: expected an integer >= 0 \(a run's index\), given -1$"):
        c.trajectory(-1)


@pytest.fixture(scope="module")
def planned():
    """The demo's slew planned under the URDF's limits, held base (with its wrench table) and free."""
    arm = FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    return {base: orbitflex.plan_slew(arm, np.asarray(GOAL) * 0.3, base=base) for base in ("held", "free")}


def plan_campaign(plan, **changes):
    spec = dict(kp=1000.0, kd=100.0, dt=2e-3, runs=10, seed=4, record_every=5,
                dispersions=[Dispersion("stiffness", "lognormal", sigma=0.2),
                             Dispersion("payload_mass", "uniform", low=0.0, high=10.0),
                             Dispersion("kd", "normal", relative=0.05),
                             Dispersion("q0", "normal", std=1e-3)])
    spec.update(changes)
    return Campaign.from_plan(plan, **spec)


@pytest.mark.parametrize("base", ["held", "free"])
def test_a_planned_slew_is_a_nominal(planned, base):
    # Campaign knew only a quintic reference under a PD, with no feedforward: the paper's planned
    # slew could not be dispersed without hand work. Each run now follows the plan's per-step
    # reference and feedforward (and, held, its base wrench), as plan.track does.
    plan = planned[base]
    c = plan_campaign(plan)
    assert c.duration == pytest.approx(plan.duration + 2.0) and c.slew_time == plan.duration
    assert c.goal.tolist() == np.asarray(plan.stops)[-1].tolist()
    table = c.run(threads=1)
    pd.testing.assert_frame_equal(c.run(chunk_runs=3, threads=2), table, check_exact=True)
    assert table["ok"].all()
    if base == "free":  # held, the plan's open-loop base wrench no longer holds a heavier arm
        assert (table["final_error"] < c.settle_tolerance).all() and table["settling_time"].notna().all()
    # the nominal run is plan.track's run, bit for bit
    nominal = plan_campaign(plan, dispersions=[]).trajectory(0)
    ref = plan.reference(c.dt, c.steps)
    by_hand = plan.arm.simulate(plan.initial_state(), c.dt, c.steps,
                                u=MotorPD(1000.0, 100.0, ref["theta_ref"], ref["theta_dot_ref"], ref["u"]),
                                base_wrench=ref["base_wrench"] if base == "held" else None)
    np.testing.assert_array_equal(nominal.x, by_hand.x)
    # and each row is its trajectory's, bit for bit
    for run in (0, int(table["peak_torque"].idxmax())):
        traj = c.trajectory(run)
        recomputed = row_from(traj, c, c.goal, c.nominal_ee())
        for metric, value in recomputed.items():
            row = table.iloc[run][metric]
            assert row == value or (np.isnan(row) and np.isnan(value)), (run, metric)


def test_a_campaign_on_a_plan_refuses_what_the_plan_fixes(planned):
    plan = planned["free"]
    with pytest.raises(CampaignError, match=r"^dispersion: the goal of a campaign on a plan is the plan's"):
        plan_campaign(plan, dispersions=[Dispersion("goal", "normal", std=0.01)]).check()
    with pytest.raises(CampaignError, match=r"^duration: 1 s ends before the plan does \(\d"):
        plan_campaign(plan, duration=1.0).check()
    with pytest.raises(CampaignError, match=r"^robot: a campaign on a plan takes it from the plan; leave it out$"):
        plan_campaign(plan, robot=orbitflex.models.space_arm())
    with pytest.raises(CampaignError, match=r"^goal: a campaign on a plan ends at the plan's goal"):
        Campaign(goal=0.1, kp=1.0, kd=1.0, dt=1e-3, duration=10.0, slew_time=1.0, plan=plan).check()
    with pytest.raises(CampaignError, match=r"^plan: expected an orbitflex.Plan, given str$"):
        Campaign(goal=0.1, kp=1.0, kd=1.0, dt=1e-3, duration=10.0, slew_time=1.0, plan="plan").check()


def test_a_campaign_on_a_plan_runs_on_dask_with_the_same_table(cluster, planned):
    from dask.distributed import Client

    c = plan_campaign(planned["held"], runs=6)
    local = c.run(threads=1)
    with Client(cluster) as client:
        pd.testing.assert_frame_equal(c.run(client=client, chunk_runs=2), local, check_exact=True)
