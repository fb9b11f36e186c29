"""Co-simulation speed, per RK4 step, side by side in one process (space arm, dt = 1 ms):
``arm.simulate`` against ``Simulator.step(n=1000)``, a Python loop of ``Simulator.step()``, the
FMU's DoStep through FMPy (one RK4 step per DoStep, and 1000), and the C example's loop
(benches/cosim_loop.c, built with the system ``cc``).

    python3 benches/cosim.py [--rounds R] [--cpu]

Each round runs every contender once, in turn (the machine is shared and noisy); the table
gives the median over the rounds. Prints Markdown for BENCHMARKS.md ("Co-simulation").
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import orbitflex
from orbitflex.fmu import runtime_library, write_fmu

ROOT = Path(__file__).resolve().parents[1]
DT = 1e-3


CLOCK = time.perf_counter


def per_step(f, steps: int) -> float:
    start = CLOCK()
    f()
    return (CLOCK() - start) / steps


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--cpu", action="store_true",
                        help="CPU time of the process (time.process_time) instead of wall time: steadier "
                             "on a shared machine")
    args = parser.parse_args()
    global CLOCK
    if args.cpu:
        CLOCK = time.process_time
    arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    x0 = arm.state()
    u = np.linspace(0.5, -0.5, arm.dof)
    kp = np.array([300.0, 1250.0, 1250.0, 650.0, 85.0, 42.0, 16.0])
    kd = np.array([100.0, 670.0, 670.0, 300.0, 27.0, 13.0, 4.2])
    pd = orbitflex.MotorPD(kp=kp, kd=kd, theta_ref=np.full(arm.dof, 0.2))

    tmp = Path(tempfile.mkdtemp())
    fmu_path = write_fmu(tmp / "arm.fmu", orbitflex.SPACE_ARM_URDF, arm, DT)
    from fmpy import extract, read_model_description
    from fmpy.fmi3 import FMU3Slave

    md = read_model_description(str(fmu_path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=extract(str(fmu_path), unzipdir=str(tmp / "x")),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    fmu.instantiate()
    u_vrs = [vr[f"motor_torque.{j}"] for j in arm.robot.joint_names]

    exe = tmp / "cosim_loop"
    lib = runtime_library()
    subprocess.run(["cc", "-std=c99", "-O2", "-ffp-contract=off", str(ROOT / "benches/cosim_loop.c"),
                    f"-I{ROOT / 'include'}", f"-L{lib.parent}", "-l:" + lib.name, f"-Wl,-rpath,{lib.parent}",
                    "-o", str(exe)], check=True)

    def fmu_run(h_steps: int, calls: int) -> None:
        fmu.reset()
        fmu.enterInitializationMode(startTime=0.0)
        fmu.exitInitializationMode()
        fmu.setFloat64(u_vrs, list(u))
        h = h_steps * DT
        for k in range(calls):
            fmu.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)

    def python_loop(steps: int) -> None:
        sim = orbitflex.Simulator(arm, x0, DT)
        sim.step(u=u)
        for _ in range(steps - 1):
            sim.step()

    probe = orbitflex.Simulator(arm, x0, DT)

    def python_calls(calls: int) -> None:  # one Python call into orbitflex, doing nothing
        for _ in range(calls):
            probe.steps

    q_vr = [vr["q.shoulder_roll"]]

    def fmpy_calls(calls: int) -> None:  # one FMPy call into the FMU, reading one value
        for _ in range(calls):
            fmu.getFloat64(q_vr)

    def simulator_n(steps: int) -> None:
        sim = orbitflex.Simulator(arm, x0, DT)
        sim.step(u=u, n=1000)
        for _ in range(steps // 1000 - 1):
            sim.step(n=1000)

    contenders = {
        "`arm.simulate`, held torques (10⁴ steps)": lambda: per_step(lambda: arm.simulate(x0, DT, 10_000, u=u), 10_000),
        "`Simulator.step(n=1000)` ×10": lambda: per_step(lambda: simulator_n(10_000), 10_000),
        "Python loop of `Simulator.step()` (2000 calls)": lambda: per_step(lambda: python_loop(2000), 2000),
        "FMU through FMPy, `doStep(h = 1000 dt)` ×10": lambda: per_step(lambda: fmu_run(1000, 10), 10_000),
        "FMU through FMPy, `doStep(h = dt)` (2000 calls)": lambda: per_step(lambda: fmu_run(1, 2000), 2000),
        "for reference: one Python call, `sim.steps` (2000 calls), per call": lambda: per_step(lambda: python_calls(2000), 2000),
        "for reference: one FMPy call, `getFloat64` of one value (2000 calls), per call": lambda: per_step(lambda: fmpy_calls(2000), 2000),
        "`arm.simulate` with `MotorPD` in Rust (10⁴ steps)": lambda: per_step(lambda: arm.simulate(x0, DT, 10_000, u=pd), 10_000),
        "C example's loop: read θ, θ̇, PD, set, step (10⁴ steps)": lambda: float(
            subprocess.run([str(exe), "10000", "1", "cpu" if args.cpu else "wall"], capture_output=True, text=True, check=True).stdout),
    }
    times = {name: [] for name in contenders}
    for _ in range(args.rounds):
        for name, f in contenders.items():
            times[name].append(f())
    med = {name: statistics.median(t) for name, t in times.items()}
    base, base_pd = med["`arm.simulate`, held torques (10⁴ steps)"], med["`arm.simulate` with `MotorPD` in Rust (10⁴ steps)"]
    clock = "CPU time" if args.cpu else "wall time"
    print(f"{args.rounds} rounds, {clock}, median µs per RK4 step (ratio to the `simulate` row it compares with)\n")
    print("| contender | µs per RK4 step | ratio |")
    print("|---|---:|---:|")
    for name, t in med.items():
        ref = base_pd if "C example" in name or "MotorPD" in name else base
        ratio = "" if name.startswith("for reference") else f"{t / ref:.3f}"
        print(f"| {name} | {t * 1e6:.2f} | {ratio} |")
    fmu.terminate()
    fmu.freeInstance()
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
