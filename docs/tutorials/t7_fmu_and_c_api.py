# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 7. The FMU in FMPy, and the C API
#
# A GNC team closes its loops in Simulink, in a C or C++ test bench, or in a co-simulation
# master. orbitflex reaches all three through one C runtime (`liborbitflex_c`): an FMI 3.0 or 2.0
# co-simulation FMU for any FMI master, and a C API with opaque handles. Both step the same RK4
# as `arm.simulate`, so a loop closed outside Python gives the numbers a Python run gives.
#
# This tutorial writes an FMU of the built-in space arm, checks it with
# [FMPy](https://github.com/CATIA-Systems/FMPy) (a real FMI master: `pip install fmpy`), runs it
# against `arm.simulate` with an input table, closes a motor PD around it from Python as the
# master, and then builds and runs the C example with the system compiler.
# [Co-simulation](../cosimulation.md) documents every variable and call.

# %%
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import fmpy
import matplotlib.pyplot as plt
import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

import orbitflex
from orbitflex.fmu import runtime_library, write_fmu

work = Path(tempfile.mkdtemp(prefix="orbitflex_t7_"))
arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
dt = 1e-3  # s: the FMU's internal RK4 step
fmu_path = write_fmu(work / "space_arm.fmu", orbitflex.SPACE_ARM_URDF, arm, dt)  # as `orbitflex fmu`
print(fmu_path.name, f"{fmu_path.stat().st_size / 1e6:.2f} MB; FMPy's validation:",
      validate_fmu(str(fmu_path)) or "no problems")

md = read_model_description(str(fmu_path))
kinds: dict = {}
for v in md.modelVariables:
    kinds.setdefault(v.causality, []).append(v.name)
for causality, names in kinds.items():
    print(f"{causality:10s} {len(names):3d}  e.g. {', '.join(names[:4])}")

# %% [markdown]
# The inputs are the motor torques (N·m, one per joint), the base wrench in the base frame and,
# for arms with end-effector loads, the EE wrench; the outputs are the link and motor angles and
# rates, the deflections and spring torques, the base pose and twist, the EE positions and the
# momentum; the parameters (joint stiffness, damping, the initial q, …) can be changed before
# the FMU is initialised. Every variable carries its unit in the model description.
#
# ## An input table, bit for bit `arm.simulate`
#
# FMPy's `simulate_fmu` drives the FMU with a table of inputs on the communication grid. Given
# the same torques, the FMU's outputs equal `arm.simulate`'s, bit for bit: it is the same RK4 on
# the same state.

# %%
steps = 1500
t = np.arange(steps) * dt
u = np.zeros((steps, arm.dof))
u[:, 1] = 40.0 * np.sin(2 * np.pi * 0.8 * t)  # N·m on shoulder_yaw
inputs = [v.name for v in md.modelVariables if v.causality == "input"]
table = np.zeros(steps, dtype=[("time", "f8")] + [(n, "f8") for n in inputs])  # every input, zero
table["time"] = t
table["motor_torque.shoulder_yaw"] = u[:, 1]
res = fmpy.simulate_fmu(str(fmu_path), stop_time=steps * dt, output_interval=dt, input=table,
                        output=["q.shoulder_yaw", "deflection.shoulder_yaw"])
traj = arm.simulate(arm.state(), dt, steps, u=u)
same = np.array_equal(res["q.shoulder_yaw"], traj.q[:, 1])
print("FMU through FMPy equals arm.simulate bit for bit:", same)
assert same

# %% [markdown]
# ## Python as the master: a motor PD around the FMU
#
# A master of our own, with FMPy's `FMU3Slave`: every 2 ms (two internal steps of 1 ms) it reads
# the elbow's motor angle and rate and sets the elbow torque of a PD that follows a 0.5 rad slew
# (the other motors get no torque).
# The same loop on an `orbitflex.Simulator` gives the same numbers, bit for bit.

# %%
vr = {v.name: v.valueReference for v in md.modelVariables}
comm = 2 * dt  # s: the communication step, a whole multiple of dt
kp, kd = 300.0, 100.0  # the elbow's motor PD (N·m/rad, N·m·s/rad)
j = 3  # elbow_pitch
name = arm.robot.joint_names[j]


def reference(time: float) -> float:
    s = min(time / 2.0, 1.0)  # a quintic rest-to-rest slew of 0.5 rad over 2 s
    return 0.5 * s**3 * (10 - 15 * s + 6 * s * s)


fmu = FMU3Slave(guid=md.guid, unzipDirectory=extract(str(fmu_path)),
                modelIdentifier=md.coSimulation.modelIdentifier, instanceName="arm")
fmu.instantiate()
fmu.enterInitializationMode(startTime=0.0)
fmu.exitInitializationMode()
sim = orbitflex.Simulator(arm, arm.state(), dt)
rows = []
for k in range(1500):
    time = k * comm
    theta, theta_dot, q = fmu.getFloat64([vr[f"theta.{name}"], vr[f"theta_dot.{name}"], vr[f"q.{name}"]])
    torque = kp * (reference(time) - theta) - kd * theta_dot
    fmu.setFloat64([vr[f"motor_torque.{name}"]], [torque])
    fmu.doStep(currentCommunicationPoint=time, communicationStepSize=comm)
    out = sim.outputs()
    u_sim = np.zeros(arm.dof)
    u_sim[j] = kp * (reference(time) - out["theta"][j]) - kd * out["theta_dot"][j]
    sim.step(u=u_sim, n=2)
    rows.append((time, reference(time), q, theta, torque))
final = fmu.getFloat64([vr[f"q.{name}"]])[0]
fmu.terminate()
fmu.freeInstance()
print(f"after {1500 * comm:.1f} s: elbow q = {final:.6f} rad (reference 0.5); the Simulator's:"
      f" {sim.outputs()['q'][j]:.6f}, equal bit for bit: {final == sim.outputs()['q'][j]}")
assert final == sim.outputs()["q"][j]

rows_a = np.array(rows)
fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
ax1.plot(rows_a[:, 0], rows_a[:, 1], "k--", label="reference")
ax1.plot(rows_a[:, 0], rows_a[:, 2], label="link angle q")
ax1.plot(rows_a[:, 0], rows_a[:, 3], ":", label="motor angle θ")
ax1.set_ylabel("elbow angle (rad)")
ax1.legend()
ax2.plot(rows_a[:, 0], rows_a[:, 4])
ax2.set_ylabel("elbow torque (N·m)")
ax2.set_xlabel("time (s)")
fig.suptitle(f"space_arm FMU (FMI 3.0) in FMPy, a Python PD as master: dt = {dt * 1e3:g} ms, "
             f"communication step {comm * 1e3:g} ms")
fig.tight_layout()
plt.show()

# %% [markdown]
# The torque is held over each communication step (zero-order hold, as any FMI master holds its
# inputs), so a slower master sees a delayed loop: with these gains, a 10 ms communication step
# already makes this loop diverge (the FMU then returns an error from `doStep`, keeping its last
# good state), so choose the step against the loop's bandwidth. The communication step must be a whole multiple of the FMU's dt; any other is refused
# with a logged message, as are NaN inputs and unknown value references.
#
# ## The C API: the same run from C
#
# `examples/c/slew.c` steps the built-in arm from C: a motor PD written in C tracks a slew of
# every joint, with the header `include/orbitflex.h` and the runtime library (installed with the
# Python package; `orbitflex.fmu.runtime_library()` finds it). Its Python twin,
# `examples/c/slew.py`, prints the same digits. Built here with the system C compiler:

# %%
# the repository holds the example and the header: the docs build names it (it runs the notebooks
# in a temporary folder); otherwise look upwards from here
repo = Path(os.environ.get("ORBITFLEX_SOURCE", Path.cwd()))
while not (repo / "include" / "orbitflex.h").is_file() and repo != repo.parent:
    repo = repo.parent
library = runtime_library()
cc = shutil.which("cc") or shutil.which("gcc")
print("runtime:", library.name, "| compiler:", cc)
exe = work / "slew"
subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-ffp-contract=off",
                str(repo / "examples" / "c" / "slew.c"), f"-I{repo / 'include'}",
                str(library), f"-Wl,-rpath,{library.parent}", "-o", str(exe)], check=True)
from_c = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
from_python = subprocess.run([sys.executable, str(repo / "examples" / "c" / "slew.py")], check=True,
                             capture_output=True, text=True).stdout
print(from_c)
print("the C and Python runs print the same digits:", from_c == from_python)
assert from_c == from_python

# %% [markdown]
# Every C call returns a status code, `ofx_last_error()` gives the message (per thread), and no
# Rust panic crosses the boundary. The header documents ownership, thread safety, units and the
# layouts of the buffers; `pkg-config` and CMake files come with it (see
# [Co-simulation](../cosimulation.md#the-c-api)).

# %%
shutil.rmtree(work)
