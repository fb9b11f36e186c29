"""Campaigns declared carelessly or hostilely (issue 24): a campaign file's types are checked
and keys that do not apply are errors, the CLI answers in one line naming the key or the flag,
a Dask scheduler that refuses or is not one fails fast, messages name the dispersion at fault,
and memory does not grow with the chunking."""

from __future__ import annotations

import gc
import http.server
import os
import subprocess
import sys
import threading
import time
import tracemalloc
from pathlib import Path

import pytest

pytest.importorskip("pandas")

from orbitflex import campaign as campaigns  # noqa: E402
from orbitflex.campaign import Campaign, CampaignError, Dispersion  # noqa: E402

BASE = """name = "hostile"
runs = 4
seed = 1
{extra}
[simulation]
dt = {dt}
duration = 0.2
[slew]
goal = 0.1
slew_time = 0.1
kp = 1000.0
kd = 100.0
{tail}
"""


def write(tmp_path: Path, extra: str = "", tail: str = "", dt: str = "2e-3") -> Path:
    path = tmp_path / "c.toml"
    path.write_text(BASE.format(extra=extra, tail=tail, dt=dt))
    return path


def cli(*args: object, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "orbitflex", "campaign", *map(str, args), "--no-progress",
                           "--no-plots"], capture_output=True, text=True, timeout=timeout)


def one_line(result: subprocess.CompletedProcess, start: str) -> str:
    assert result.returncode == 2, (result.stdout, result.stderr[-2000:])
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr[-2000:]
    assert lines[0].startswith("orbitflex: error: " + start), lines[0]
    return lines[0]


DISPERSION = '[[dispersion]]\nparameter = "stiffness"\ndistribution = "lognormal"\nsigma = {sigma}\n{more}'


@pytest.mark.parametrize("extra,tail,words", [
    ("robot = 5", "", "[robot]: expected a table, given 5"),
    ("dispersion = [1, 2]", "", "dispersion[0]: expected a table ([[dispersion]]), given 1"),
    ("[joints]\nstiffness = 1000.0", "", "[joints] motor_inertia is required"),
    ("", DISPERSION.format(sigma="[0.1, 0.2]", more=""), "dispersion[0].sigma: expected one number"),
    ("", DISPERSION.format(sigma="0.1", more='per_joint = "no"'), "dispersion[0].per_joint: expected true or false, given 'no'"),
    ('[robot]\nlocked_joints = ["wrist_roll"]', "", "locked_joints: applies when the robot is read from a URDF file"),
    ('[robot]\nee_link = "no_such_link"', "", "ee_link: applies when the robot is read from a URDF file"),
    ('[robot]\nurdf = 5', "", "[robot] urdf: expected a string, given 5"),
], ids=["robot-not-a-table", "dispersions-not-tables", "joints-without-motor-inertia", "sigma-list",
        "per-joint-text", "locked-joints-built-in", "ee-link-built-in", "urdf-not-text"])
def test_campaign_file_errors_are_one_line_naming_the_key(tmp_path, extra, tail, words):
    # Issue 24: tracebacks (TypeError) for the first four; "no" read as true; locked_joints and
    # ee_link ignored for the built-in model
    line = one_line(cli(write(tmp_path, extra, tail), "--out", tmp_path / "out"), "FILE: ")
    assert words in line, line


def test_a_step_longer_than_the_run_is_refused(tmp_path):
    # dt = 1 s with duration = 0.1 s ran one step of 1 s, every run "ok"
    line = one_line(cli(write(tmp_path, dt="1.0"), "--out", tmp_path / "out"), "FILE: ")
    assert "dt: expected at most the duration (0.2 s), given 1 s" in line


def test_a_table_too_large_for_memory_names_runs(tmp_path):
    # found trying: numpy's MemoryError was reported as "--duration/--dt: out of memory"
    line = one_line(cli(write(tmp_path), "--runs", 10**10, "--out", tmp_path / "out"), "--runs: ")
    assert "the table of 10000000000 runs needs" in line and "GB of memory free" in line


def test_a_malformed_scheduler_address_names_the_flag(tmp_path):
    line = one_line(cli(write(tmp_path), "--scheduler", "not-an-address", "--out", tmp_path / "out"), "--scheduler: ")
    assert "expected an address like tcp://host:8786, given 'not-an-address'" in line


def test_a_refused_scheduler_fails_fast(tmp_path):
    # it took 30.8 s (Dask's connection retries) to say so
    started = time.perf_counter()
    line = one_line(cli(write(tmp_path), "--scheduler", "tcp://127.0.0.1:1", "--out", tmp_path / "out"),
                    "--scheduler: ")
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:1" in line
    assert time.perf_counter() - started < 15  # a process start and a refused connection; was over 30 s


def test_a_server_that_is_not_a_dask_scheduler_is_named_within_the_timeout(tmp_path):
    # found trying: a web server at the address made Dask's client wait forever (or take its
    # bytes for a frame size and run out of memory: "--duration/--dt: out of memory")
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        address = f"tcp://127.0.0.1:{server.server_address[1]}"
        line = one_line(cli(write(tmp_path), "--scheduler", address, "--scheduler-timeout", 1,
                            "--out", tmp_path / "out", timeout=60), "--scheduler: ")
        assert f"cannot reach the Dask scheduler at {address}: no answer within 1 s" in line, line
        assert "--scheduler-timeout" in line
    finally:
        server.shutdown()
        server.server_close()


def small(**kw) -> Campaign:
    args = dict(goal=0.1, kp=1000.0, kd=100.0, dt=5e-3, duration=0.02, slew_time=0.01, runs=4, seed=1)
    args.update(kw)
    return Campaign(**args)


def test_the_python_api_checks_the_same(tmp_path):
    with pytest.raises(CampaignError, match=r"^scheduler: expected an address like tcp://host:8786"):
        small().run(scheduler="not-an-address")
    with pytest.raises(OSError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:1"):
        small().run(scheduler="tcp://127.0.0.1:1", timeout=2.0)
    with pytest.raises(CampaignError, match=r"^timeout: expected a finite time > 0"):
        small().run(scheduler="tcp://127.0.0.1:1", timeout=0)
    with pytest.raises(CampaignError, match=r"^ee_link: applies when the robot is read from a URDF file"):
        small(ee_link="ee").run()
    with pytest.raises(CampaignError, match=r"^locked_joints: expected a list of names, given 'a,b'"):
        small(robot=str(tmp_path / "x.urdf"), locked_joints="a,b").check()


def test_an_invalid_model_from_a_draw_names_the_dispersion():
    # "<urdf string>: link 'wrist_roll_link': mass 5.6e30 kg": the cause was the payload
    # dispersion
    c = small(dispersions=[Dispersion("payload_mass", "uniform", low=1e30, high=1e31)])
    with pytest.raises(CampaignError, match=r"^run 0: payload_mass = [\d.e+]+ kg from dispersion\[0\] \(uniform\): "
                                            r"the model is invalid with it: .*mass"):
        c.run()


def test_a_lognormal_draw_out_of_the_domain_does_not_advise_a_lognormal():
    # "narrow the lognormal dispersion or use a lognormal one"
    c = small(dispersions=[Dispersion("stiffness", "lognormal", sigma=1e3)])
    with pytest.raises(CampaignError) as e:
        c.run()
    assert "the sigma of dispersion[0], 1000, is so wide that exp(sigma z) overflows or underflows" in str(e.value)
    assert "use a lognormal" not in str(e.value)


def test_memory_does_not_grow_with_the_chunking():
    # chunk_runs=1 kept 7.5 kB per run (a DataFrame and a dict per chunk): 7.5 GB for 10^6 runs
    c = small(runs=600, dispersions=[Dispersion("stiffness", "lognormal", sigma=0.1)])
    c.run(runs=2, chunk_runs=1)  # imports and caches
    gc.collect()
    tracemalloc.start()
    try:
        table = c.run(chunk_runs=1, threads=1)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    row = table.memory_usage(deep=True).sum() / len(table)
    assert len(c.log) == 600 and isinstance(c.log, campaigns.ChunkLog)
    assert c.log[0]["start"] == 0 and c.log[-1]["stop"] == 600 and c.log[5]["worker"] == "local"
    # the table (twice, while the frame is made) and 28 bytes of log per chunk; it was 75 rows
    assert peak / len(table) < 5 * row, (peak / len(table), row)
    # the same table, whatever the chunking
    assert table.equals(c.run(chunk_runs=600))


def test_the_chunk_log_reads_as_a_list_of_dicts():
    log = campaigns.ChunkLog()
    for k in range(3):
        log.append({"start": 2 * k, "stop": 2 * k + 2, "worker": f"w{k % 2}", "host": "h", "seconds": 0.5 * k})
    assert len(log) == 3 and log[-1] == {"start": 4, "stop": 6, "worker": "w0", "host": "h", "seconds": 1.0}
    assert [e["worker"] for e in log] == ["w0", "w1", "w0"] and log[1:] == list(log)[1:]
    with pytest.raises(IndexError):
        log[3]


def test_example_campaign_still_reads(tmp_path):
    example = Path(__file__).resolve().parents[2] / "examples" / "campaign.toml"
    c = Campaign.from_toml(example)
    assert c.dt <= c.duration and os.path.basename(str(example)) == "campaign.toml"
