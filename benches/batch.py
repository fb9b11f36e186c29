"""Throughput of many runs: ``simulate_batch`` on 1 and 2 threads against ``simulate`` one run at a
time, and a campaign locally against a 2-worker Dask ``LocalCluster`` on loopback.

    python3 benches/batch.py [--rounds R] [--runs B] [--steps S] [--campaign-runs C]

Every comparison is measured side by side in one process, alternating the contenders in each
round (the machines are shared and noisy), and reported as the median of the rounds. Prints a
Markdown table for BENCHMARKS.md ("Batch runs and campaigns").
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import orbitflex

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "pinocchio_cpp"))
from chain_urdf import chain  # noqa: E402


def arm_for(n: int) -> orbitflex.FlexibleArm:
    if n == 7:
        return orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    robot = orbitflex.Robot.from_urdf_string(chain(n, 1), ee_link=f"link{n}")
    return orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints.defaults_for(robot))


def timed(f) -> float:
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


def batch_rows(n: int, runs: int, steps: int, rounds: int) -> list[str]:
    arm = arm_for(n)
    dt = 0.5 * arm.rk4_stability_limit().dt
    x0 = arm.state()
    u = np.stack([np.full(arm.dof, 0.1 * (b + 1)) for b in range(runs)])
    one = lambda: orbitflex.simulate_batch(arm, x0, dt, steps, u=u, threads=1, keep_rows=False)  # noqa: E731
    two = lambda: orbitflex.simulate_batch(arm, x0, dt, steps, u=u, threads=2, keep_rows=False)  # noqa: E731
    single = lambda: [arm.simulate(x0, dt, steps, u=u[b], record_every=steps) for b in range(runs)]  # noqa: E731
    times: dict[str, list[float]] = {"batch, 1 thread": [], "batch, 2 threads": [], "simulate, one by one": []}
    one()  # warm up
    for _ in range(rounds):
        times["batch, 1 thread"].append(timed(one))
        times["batch, 2 threads"].append(timed(two))
        times["simulate, one by one"].append(timed(single))
    med = {k: statistics.median(v) for k, v in times.items()}
    per_step = {k: v / (runs * steps) * 1e6 for k, v in med.items()}
    return [
        f"| n = {n} | {runs} runs × {steps} steps | {per_step['simulate, one by one']:.2f} µs | "
        f"{per_step['batch, 1 thread']:.2f} µs ({per_step['batch, 1 thread'] / per_step['simulate, one by one']:.3f}×) | "
        f"{per_step['batch, 2 threads']:.2f} µs | **{med['batch, 1 thread'] / med['batch, 2 threads']:.2f}×** |"
    ]


def lanes_rows(n: int, runs: int, steps: int, rounds: int) -> list[str]:
    """``simulate_batch`` on one thread with SIMD lanes against the scalar path (``lanes=False``),
    open-loop torques and per-run ``MotorPD`` controllers; the records are checked equal first."""
    arm = arm_for(n)
    dt = 0.5 * arm.rk4_stability_limit().dt
    x0 = arm.state()
    u = np.stack([np.full(arm.dof, 0.1 * (b + 1)) for b in range(runs)])
    pds = [orbitflex.MotorPD(kp=np.full(n, 50.0 + b), kd=np.full(n, 5.0), theta_ref=np.full(n, 0.1))
           for b in range(runs)]
    rows = []
    for label, control in (("torques", u), ("MotorPD per run", pds)):
        run = lambda lanes: orbitflex.simulate_batch(arm, x0, dt, steps, u=control, threads=1,  # noqa: E731
                                                     keep_rows=False, lanes=lanes)
        a, b = run(False), run(None)
        assert np.array_equal(a.final_state, b.final_state), "lanes and scalar records differ"
        scalar, lanes = [], []
        for _ in range(rounds):
            scalar.append(timed(lambda: run(False)))
            lanes.append(timed(lambda: run(None)))
        s, v = statistics.median(scalar), statistics.median(lanes)
        per = lambda t: t / (runs * steps) * 1e6  # noqa: E731
        rows.append(f"| n = {n}, {label} | {runs} runs × {steps} steps | {per(s):.2f} µs | {per(v):.2f} µs | "
                    f"**{s / v:.2f}×** |")
    return rows


def campaign_lanes_row(runs: int, rounds: int) -> list[str]:
    """The example campaign run locally (2 threads) with the lanes and with ``ORBITFLEX_LANES=1``
    (the scalar path), alternating; the tables are checked equal first."""
    from orbitflex.campaign import Campaign

    campaign = Campaign.from_toml(HERE.parent / "examples" / "campaign.toml")
    campaign.duration, campaign.slew_time = 2.0, 1.0

    def run(scalar: bool):
        if scalar:
            os.environ["ORBITFLEX_LANES"] = "1"
        try:
            return campaign.run(runs=runs, threads=2)
        finally:
            os.environ.pop("ORBITFLEX_LANES", None)

    a, b = run(True), run(False)
    assert a.equals(b), "lanes and scalar campaign tables differ"
    scalar, lanes = [], []
    for _ in range(rounds):
        scalar.append(timed(lambda: run(True)))
        lanes.append(timed(lambda: run(False)))
    s, v = statistics.median(scalar), statistics.median(lanes)
    return [f"| {runs} runs × {campaign.steps} steps, 2 threads | {s:.2f} s | {v:.2f} s | **{s / v:.2f}×** |"]


def campaign_row(runs: int, rounds: int) -> list[str]:
    from dask.distributed import Client, LocalCluster

    from orbitflex.campaign import Campaign

    campaign = Campaign.from_toml(HERE.parent / "examples" / "campaign.toml")
    campaign.duration, campaign.slew_time = 2.0, 1.0
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster, Client(cluster) as client:
        campaign.run(runs=8, client=client)  # warm up the workers (imports)
        local, dask = [], []
        for _ in range(rounds):
            local.append(timed(lambda: campaign.run(runs=runs, threads=2)))
            dask.append(timed(lambda: campaign.run(runs=runs, client=client)))
    lm, dm = statistics.median(local), statistics.median(dask)
    return [f"| {runs} runs × {campaign.steps} steps | {lm:.2f} s | {dm:.2f} s | **{dm / lm:.3f}×** |"]


def native_ns(binary: str, calls: str) -> dict[str, float]:
    """Median ns per native Rust call on the built-in arm (``bench_cpp_match``)."""
    import subprocess
    import tempfile

    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(orbitflex.SPACE_ARM_URDF)
    out = subprocess.run([binary, f.name, "-", "--only", calls], capture_output=True, text=True, check=True).stdout
    os.unlink(f.name)
    return {line.split()[0]: float(line.split()[1]) for line in out.splitlines()
            if line.split()[0] in calls.split(",")}


BATCH_CALLS = """
import sys, time, statistics, numpy as np, orbitflex
robot = orbitflex.models.space_arm(); n = robot.dof; B = int(sys.argv[1]); rounds = int(sys.argv[2])
rng = np.random.default_rng(0)
q, v, qd, tau = rng.uniform(-1, 1, (B, n)), rng.normal(size=(B, 6)) * 0.05, rng.normal(size=(B, n)) * 0.2, rng.normal(size=(B, n))
out = np.empty((B, 6 + n))
one = (q[0], v[0], qd[0], tau[0]); out1 = np.empty(6 + n)
def per_call(f, reps):
    t = []
    for _ in range(rounds):
        s = time.perf_counter()
        for _ in range(reps): f()
        t.append((time.perf_counter() - s) / reps * 1e9)
    return statistics.median(t)
batch = per_call(lambda: robot.forward_dynamics(q, v, qd, tau, out=out), 200)
single = per_call(lambda: robot.forward_dynamics(*one), 20000)
single_out = per_call(lambda: robot.forward_dynamics(*one, out=out1), 20000)
print(batch, single, single_out)
"""


def call_rows(binary: str, rounds: int) -> list[str]:
    """256 forward-dynamics calls in one batched Python call (on 2 threads and on 1) against 256
    native calls; one call from Python with and without ``out=`` against one native call."""
    import subprocess

    rows = []
    native = native_ns(binary, "aba")["aba"]
    results = {}
    for threads in ("2", "1"):
        env = {**os.environ, "RAYON_NUM_THREADS": threads}
        out = subprocess.run([sys.executable, "-c", BATCH_CALLS, "256", str(rounds)], capture_output=True,
                             text=True, check=True, env=env).stdout.split()
        results[threads] = [float(v) for v in out]
    native_after = native_ns(binary, "aba")["aba"]
    native = 0.5 * (native + native_after)
    for threads in ("2", "1"):
        batch = results[threads][0]
        rows.append(f"| 256 × `forward_dynamics`, one batched call, {threads} thread{'s' if threads == '2' else ''} | "
                    f"{batch / 1e3:.1f} µs | {256 * native / 1e3:.1f} µs | **{batch / (256 * native):.3f}×** |")
    single, single_out = results["1"][1], results["1"][2]
    rows.append(f"| one `forward_dynamics` call | {single:.0f} ns | {native:.0f} ns | overhead {single - native:.0f} ns |")
    rows.append(f"| one call with `out=` | {single_out:.0f} ns | {native:.0f} ns | overhead {single_out - native:.0f} ns |")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--campaign-runs", type=int, default=1000)
    parser.add_argument("--rust-bin", default=str(HERE.parent / "target" / "release" / "examples" / "bench_cpp_match"),
                        help="bench_cpp_match (cargo build --release --example bench_cpp_match)")
    parser.add_argument("--only", default="batch,calls,lanes,campaign")
    args = parser.parse_args()
    only = args.only.split(",")
    print(f"orbitflex {orbitflex.__version__}, Python {platform.python_version()}, "
          f"{os.cpu_count()} CPUs, {platform.processor() or platform.machine()}")
    if "calls" in only:
        print()
        print("| per-call dynamics, built-in arm | Python | native Rust | ratio |")
        print("|---|---|---|---|")
        for row in call_rows(args.rust_bin, max(5, args.rounds)):
            print(row, flush=True)
    if "batch" not in only:
        print()
    else:
        print()
        print("| model | work | simulate, per step | batch on 1 thread, per step (ratio) | batch on 2 threads, per run-step | 2 threads / 1 |")
        print("|---|---|---|---|---|---|")
        for n in (7, 28):
            for row in batch_rows(n, args.runs, args.steps, args.rounds):
                print(row, flush=True)
    if "lanes" in only:
        print()
        print("| lanes, 1 thread | work | scalar, per run-step | lanes, per run-step | lanes speed-up |")
        print("|---|---|---|---|---|")
        for n in (7, 28):
            for row in lanes_rows(n, args.runs, args.steps, args.rounds):
                print(row, flush=True)
        print()
        print("| campaign (examples/campaign.toml, 2 s runs) | scalar (`ORBITFLEX_LANES=1`) | lanes | speed-up |")
        print("|---|---|---|---|")
        for row in campaign_lanes_row(args.campaign_runs, max(1, args.rounds // 2)):
            print(row, flush=True)
    if "campaign" not in only:
        return
    print()
    print("| campaign (examples/campaign.toml, 2 s runs) | local, 2 threads | Dask LocalCluster, 2 workers × 1 thread | Dask / local |")
    print("|---|---|---|---|")
    for row in campaign_row(args.campaign_runs, max(1, args.rounds // 2)):
        print(row, flush=True)


if __name__ == "__main__":
    main()
