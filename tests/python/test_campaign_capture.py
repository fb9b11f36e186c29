"""Capture campaigns: dispersed target mass, inertia, tumble rate and grasp timing; the table is
the same here and on a real Dask LocalCluster, each row is the single run's metrics, and bad
declarations are named."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import orbitflex as of
from orbitflex.campaign import CAPTURE_METRICS, CampaignError, CaptureCampaign, Dispersion, load_campaign

DISPERSIONS = [Dispersion("tumble_rate", "uniform", low=0.5, high=4.0),
               Dispersion("target_mass", "lognormal", sigma=0.3),
               Dispersion("target_inertia", "normal", relative=0.05),
               Dispersion("grasp_time", "uniform", low=1.0, high=1.5)]


@pytest.fixture(scope="module")
def campaign():
    return CaptureCampaign(runs=6, seed=5, duration=2.5, record_every=5, dispersions=DISPERSIONS)


@pytest.fixture(scope="module")
def table(campaign):
    return campaign.run(chunk_runs=4, threads=2)


def test_each_row_is_the_single_run(campaign, table):
    assert list(table["run"]) == list(range(6))
    assert set(CAPTURE_METRICS) <= set(table.columns)
    assert table["ok"].all() and table["captured"].all()
    assert table["tumble_rate"].between(0.5, 4.0).all() and table["tumble_rate"].nunique() == 6
    for run in (0, 5):
        traj = campaign.trajectory(run)
        m = of.detumble_metrics(traj)
        assert table.loc[run, "peak_spring_torque"] == m["peak_spring_torque"]
        assert table.loc[run, "capture_time"] == m["capture_time"] == traj.events[0].time
        # the handle reaches the EE at grasp_time drifting at 2 cm/s: within 1 cm 0.5 s before
        assert abs(m["capture_time"] - (table.loc[run, "grasp_time"] - 0.5)) < 0.01


def test_the_table_is_the_same_on_a_dask_cluster(campaign, table):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        remote = campaign.run(client=client, chunk_runs=2)
    pd.testing.assert_frame_equal(remote, table)


def test_a_non_physical_draw_is_a_failed_row():
    # a huge relative spread breaks the triangle inequality of the moments in some runs
    c = CaptureCampaign(runs=12, seed=1, duration=0.05,
                        dispersions=[Dispersion("target_inertia", "normal", relative=0.9)])
    t = c.run()
    assert (~t["ok"]).any() and t["ok"].any()
    assert t.loc[~t["ok"], "peak_spring_torque"].isna().all()


def test_bad_declarations_are_named():
    with pytest.raises(CampaignError, match=r"dispersion\[0\].parameter: expected one of target_mass"):
        CaptureCampaign(dispersions=[Dispersion("stiffness", "normal", relative=0.1)])
    with pytest.raises(CampaignError, match=r"dispersion\[0\]: a lognormal dispersion takes sigma"):
        CaptureCampaign(dispersions=[Dispersion("tumble_rate", "lognormal", std=1.0)])
    with pytest.raises(CampaignError, match="runs"):
        CaptureCampaign(runs=0)


EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture(scope="module")
def wheeled():
    return CaptureCampaign(runs=4, seed=3, duration=20.0, record_every=10, wheels=of.models.pyramid_wheels(),
                           dispersions=[Dispersion("tumble_rate", "uniform", low=0.5, high=4.0)])


def test_a_campaign_with_wheels_detumbles_every_run(wheeled):
    table = wheeled.run(chunk_runs=2, threads=2)
    assert table["captured"].all() and not table["wheels_saturated"].any()
    assert table["detumble_time"].notna().all() and (table["wheel_momentum"] > 1.0).all()
    # every run uses the nominal stack's gains (the controller is tuned once, not per catch)
    s = wheeled.scenario(3)
    assert s.wheel_controller.kp.tobytes() == of.models.capture_scenario(
        wheels=of.models.pyramid_wheels()).wheel_controller.kp.tobytes()
    # a row is the single run, bit for bit
    traj = wheeled.trajectory(3)
    m = of.detumble_metrics(traj)
    assert table.loc[3, "wheel_momentum"] == m["wheel_momentum_nms"]
    assert table.loc[3, "detumble_time"] == m["detumble_time"]
    assert [e["start"] for e in sorted(wheeled.log, key=lambda e: e["start"])] == [0, 2]


def test_a_campaign_with_wheels_is_the_same_on_a_dask_cluster(wheeled):
    # the campaign (wheels, gains and all) is shipped to worker processes by pickle
    distributed = pytest.importorskip("dask.distributed")
    local = wheeled.run(chunk_runs=4)
    done = []
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        workers = set(client.scheduler_info()["workers"])
        remote = wheeled.run(scheduler=cluster.scheduler_address, chunk_runs=1,
                             progress=lambda d, n: done.append((d, n)))
        assert {e["worker"] for e in wheeled.log} <= workers and len(wheeled.log) == 4
    pd.testing.assert_frame_equal(remote, local)
    assert done[-1] == (4, 4) and len(done) == 4


def test_the_example_file_reads_and_runs_from_the_cli(tmp_path):
    c = load_campaign(EXAMPLES / "capture_campaign.toml")
    assert isinstance(c, CaptureCampaign) and c.name == "capture-tumble" and c.wheels is not None
    assert [d.parameter for d in c.dispersions] == ["tumble_rate", "target_mass", "grasp_time"]
    # a slew campaign file still reads as a slew campaign
    assert type(load_campaign(EXAMPLES / "campaign.toml")).__name__ == "Campaign"
    text = (EXAMPLES / "capture_campaign.toml").read_text().replace("duration = 40.0", "duration = 8.0")
    (tmp_path / "c.toml").write_text(text)
    r = subprocess.run([sys.executable, "-m", "orbitflex", "campaign", "c.toml", "--runs", "3", "--out", "out",
                        "--no-progress"], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "campaign capture-tumble: 3 runs of 8 s" in r.stdout and "peak_spring_torque" in r.stdout
    table = pd.read_parquet(tmp_path / "out" / "runs.parquet")
    assert list(table["run"]) == [0, 1, 2] and table["captured"].all()
    for name in ("summary.csv", "log.jsonl", "histograms.png"):
        assert (tmp_path / "out" / name).stat().st_size > 0
    # the same table as in Python, bit for bit
    again = CaptureCampaign.from_toml(tmp_path / "c.toml").run(runs=3)
    pd.testing.assert_frame_equal(table, again)


@pytest.mark.parametrize("text, message", [
    ("[capture]\nspeed = 1\n", r"\[capture\] 'speed' is not a known key"),
    ("[capture]\nduration = -1\n", r"duration: expected a finite number > 0, given -1"),
    ("[capture]\nwheels = 3\n", r"wheels: expected \"pyramid\" or a wheels file path"),
    ("[capture]\nwheels = \"nope.toml\"\n", r"wheels: .*nope.toml: cannot read the wheels file"),
    ("[capture]\nmotor_pd = \"loose\"\n", r"motor_pd: expected 'arm' or 'stack'"),
    ("[capture]\n[slew]\nkp = 1\n", r"unknown key 'slew' in a capture campaign"),
    ("[capture]\n[[dispersion]]\nparameter = \"stiffness\"\ndistribution = \"normal\"\nrelative = 0.1\n",
     r"dispersion\[0\].parameter: expected one of target_mass"),
])
def test_bad_capture_files_are_named(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(CampaignError, match=message) as e:
        load_campaign(path)
    assert str(path) in str(e.value)
