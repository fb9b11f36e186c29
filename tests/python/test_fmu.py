"""The FMI co-simulation FMUs (``orbitflex fmu``) run by a real FMI master, FMPy, in FMI 3.0 and
2.0: validation, an input table bit for bit ``arm.simulate``, a Python PD as the master's
controller, FMU states, independent instances, and bad calls refused with a logged message."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any, Dict, List

import numpy as np
import pytest

import orbitflex
from orbitflex.fmu import runtime_library, write_fmu

fmpy = pytest.importorskip("fmpy", reason="FMPy (pip install fmpy; Python >= 3.10) runs the FMUs")
from fmpy import extract, read_model_description, simulate_fmu  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE  # noqa: E402
from fmpy.fmi3 import FMU3Slave  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

try:
    runtime_library()
except FileNotFoundError as e:  # pragma: no cover - a wheel built without the runtime
    pytest.skip(str(e), allow_module_level=True)

DT = 1e-3
VERSIONS = (3, 2)


@pytest.fixture(scope="module")
def arm() -> orbitflex.FlexibleArm:
    return orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: Any, arm: orbitflex.FlexibleArm) -> Dict[int, Path]:
    out = tmp_path_factory.mktemp("fmus")
    return {v: write_fmu(out / f"space_arm{v}.fmu", orbitflex.SPACE_ARM_URDF, arm, DT, fmi=v) for v in VERSIONS}


class Master:
    """One FMPy slave of an FMU (either version), with the messages the FMU logged."""

    def __init__(self, path: Path, name: str = "arm"):
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.dir = extract(str(path))
        self.v3 = self.md.fmiVersion.startswith("3")
        self.messages: List[str] = []
        cls = FMU3Slave if self.v3 else FMU2Slave
        self.fmu = cls(guid=self.md.guid, unzipDirectory=self.dir,
                       modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        if self.v3:
            def log3(env: Any, status: int, category: bytes, message: bytes) -> None:
                self.messages.append(message.decode())

            self.fmu.instantiate(logMessage=log3)
        else:
            from fmpy.logging import addLoggerProxy

            def log2(component: Any, name: bytes, status: int, category: bytes, message: bytes) -> None:
                self.messages.append(message.decode())

            self.callbacks = fmi2CallbackFunctions()
            self.callbacks.logger = fmi2CallbackLoggerTYPE(log2)
            addLoggerProxy(ctypes.byref(self.callbacks))  # FMPy formats the printf-like message
            self.fmu.instantiate(callbacks=self.callbacks)
            self.fmu.setupExperiment(startTime=0.0)

    def vrs(self, names: List[str]) -> List[int]:
        return [self.vr[n] for n in names]

    def init(self, **parameters: float) -> None:
        self.fmu.enterInitializationMode() if not self.v3 else self.fmu.enterInitializationMode(startTime=0.0)
        if parameters:
            self.set(list(parameters), list(parameters.values()))
        self.fmu.exitInitializationMode()

    def get(self, names: List[str]) -> np.ndarray:
        vrs = self.vrs(names)
        return np.array(self.fmu.getFloat64(vrs) if self.v3 else self.fmu.getReal(vrs))

    def set(self, names: List[str], values: Any) -> None:
        vrs, values = self.vrs(names), [float(v) for v in values]
        self.fmu.setFloat64(vrs, values) if self.v3 else self.fmu.setReal(vrs, values)

    def step(self, t: float, h: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


def names(arm: orbitflex.FlexibleArm, prefix: str) -> List[str]:
    return [f"{prefix}.{j}" for j in arm.robot.joint_names]


@pytest.mark.parametrize("version", VERSIONS)
def test_fmpy_validates_and_dumps_it(fmus, version, capsys):
    path = str(fmus[version])
    assert validate_fmu(path) == []
    fmpy.dump(path)
    text = capsys.readouterr().out
    assert f"FMI Version        {version}.0" in text
    assert "base_force.x" in text and "q.elbow_pitch" in text  # (dump shortens long names)
    md = read_model_description(path)  # validates again, and parses the flags
    cs = md.coSimulation
    assert cs.modelIdentifier == "space_arm"
    assert cs.canGetAndSetFMUstate is True and cs.canSerializeFMUstate is True
    units = {u.name for u in md.unitDefinitions}
    assert {"N.m", "N", "rad", "rad/s", "m"} <= units
    by_name = {v.name: v for v in md.modelVariables}
    assert by_name["motor_torque.elbow_pitch"].causality == "input"
    assert by_name["q.elbow_pitch"].causality == "output"
    assert by_name["stiffness.elbow_pitch"].causality == "parameter"
    assert by_name["stiffness.elbow_pitch"].variability == "fixed"
    assert float(by_name["stiffness.elbow_pitch"].start) == 5e3
    # no direct feedthrough declared: a master closing a loop sees no algebraic loop
    assert all(not o.dependencies for o in md.outputs)
    if version == 3:
        assert float(cs.fixedInternalStepSize) == DT


@pytest.mark.parametrize("version", VERSIONS)
def test_simulate_fmu_with_an_input_table_equals_simulate(fmus, arm, version):
    # one table row per RK4 step, on the dt grid: FMPy samples the table at the start of each
    # communication step (output_interval = dt), so row k is held over step k, as in simulate
    steps, n = 400, arm.dof
    rng = np.random.default_rng(7)
    u = rng.uniform(-3, 3, (steps, n))
    force = rng.uniform(-2, 2, (steps, 3))
    q0 = rng.uniform(-0.5, 0.5, n)
    t = np.arange(steps) * DT
    columns = [("time", "f8")] + [(c, "f8") for c in names(arm, "motor_torque")] + \
        [(f"base_force.{a}", "f8") for a in "xyz"]
    table = np.zeros(steps, dtype=columns)
    table["time"] = t
    for i, c in enumerate(names(arm, "motor_torque")):
        table[c] = u[:, i]
    for i, a in enumerate("xyz"):
        table[f"base_force.{a}"] = force[:, i]
    outputs = names(arm, "q") + names(arm, "theta_dot") + ["base_position.x", "base_quaternion.w"]
    res = simulate_fmu(str(fmus[version]), start_time=0.0, stop_time=steps * DT, output_interval=DT,
                       input=table, output=outputs, fmi_type="CoSimulation",
                       start_values={f"q0.{j}": q for j, q in zip(arm.robot.joint_names, q0)})
    wrench = np.hstack([np.zeros((steps, 3)), force])
    traj = arm.simulate(arm.state(q=q0), DT, steps, u=u, base_wrench=wrench)
    assert len(res) == steps + 1
    assert np.array_equal(res["time"], traj.t)
    q = np.column_stack([res[c] for c in names(arm, "q")])
    theta_dot = np.column_stack([res[c] for c in names(arm, "theta_dot")])
    assert np.array_equal(q, traj.q)  # bit for bit
    assert np.array_equal(theta_dot, traj.x[:, -n:])
    assert np.array_equal(res["base_position.x"], traj.x[:, 0])
    assert np.array_equal(res["base_quaternion.w"], traj.x[:, 6])


def quintic(t: float, T: float) -> float:
    s = min(max(t / T, 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


@pytest.mark.parametrize("version", VERSIONS)
def test_a_python_pd_as_the_master_tracks_a_slew(fmus, arm, version):
    # the master's controller: a motor PD on a quintic slew of every joint by 0.3 rad in 2 s,
    # computed in Python between communication steps of 2 dt (held over them), gains from the
    # 1 Hz bandwidth rule (kd h / j <= 1.3: inside the sampled loop's stability)
    n, h, k_steps = arm.dof, 2 * DT, 1500
    kp, kd = arm.motor_pd_gains(1.0)
    target, T = 0.3, 2.0
    m = Master(fmus[version])
    m.init()
    sim = orbitflex.Simulator(arm, arm.state(), DT)  # the same loop on the Simulator
    theta, theta_dot = names(arm, "theta"), names(arm, "theta_dot")
    for k in range(k_steps):
        t = k * h
        ref = target * quintic(t, T)
        th, thd = m.get(theta), m.get(theta_dot)
        u = kp * (ref - th) - kd * thd
        m.set(names(arm, "motor_torque"), u)
        m.step(t, h)
        out = sim.outputs()
        assert np.array_equal(out["theta"], th) and np.array_equal(out["theta_dot"], thd)
        sim.step(u=kp * (ref - out["theta"]) - kd * out["theta_dot"], n=2)
    q = m.get(names(arm, "q"))
    assert np.array_equal(q, sim.outputs()["q"])
    # the slew ended 1 s ago (the 1 Hz loop settles in about 0.6 s, the free-floating base
    # still reacting): every joint within 10 % of the target, the springs nearly relaxed
    assert np.abs(q - target).max() < 0.1 * target, q
    assert np.abs(m.get(names(arm, "deflection"))).max() < 1e-3
    assert m.get(["time"])[0] == pytest.approx(k_steps * h, abs=1e-12) if version == 3 else True
    m.close()


@pytest.mark.parametrize("version", VERSIONS)
def test_fmu_state_get_set_serialize_bit_exact(fmus, arm, version):
    m = Master(fmus[version])
    m.init(**{"q0.elbow_pitch": 0.4})
    every = [v.name for v in m.md.modelVariables if v.causality == "output"]
    u = names(arm, "motor_torque")
    m.set(u, np.linspace(-1, 1, arm.dof))
    m.step(0.0, 0.05)
    state = m.fmu.getFMUState()
    blob = m.fmu.serializeFMUState(state)
    mid = m.get(every)
    m.set(u, np.linspace(2, -2, arm.dof))
    m.step(0.05, 0.05)
    end = m.get(every)
    m.fmu.setFMUState(state)  # back to t = 0.05, the first inputs held
    assert np.array_equal(m.get(every), mid)
    m.set(u, np.linspace(2, -2, arm.dof))
    m.step(0.05, 0.05)
    assert np.array_equal(m.get(every), end)  # the replay is bit for bit
    restored = m.fmu.deserializeFMUState(blob)
    m.fmu.setFMUState(restored)
    assert np.array_equal(m.get(every), mid)
    again = m.fmu.getFMUState()
    assert m.fmu.serializeFMUState(again) == blob
    for s in (state, restored, again):
        m.fmu.freeFMUState(s)
    m.close()


@pytest.mark.parametrize("version", VERSIONS)
def test_two_instances_are_independent(fmus, arm, version):
    a, b = Master(fmus[version], "a"), Master(fmus[version], "b")
    a.init(**{"stiffness.shoulder_pitch": 2000.0})
    b.init()
    a.set(["motor_torque.shoulder_pitch"], [5.0])
    for k in range(20):
        a.step(k * 0.01, 0.01)
    b.step(0.0, 0.01)
    assert a.get(["q.shoulder_pitch"])[0] > 1e-3
    assert b.get(["q.shoulder_pitch"])[0] == 0.0  # no torque, at rest: not moved by a
    assert b.get(["stiffness.shoulder_pitch"])[0] == 1e4
    a.close()
    b.close()


@pytest.mark.parametrize("version", VERSIONS)
def test_bad_calls_return_error_with_a_logged_message(fmus, arm, version):
    m = Master(fmus[version])
    u = "motor_torque.elbow_pitch"

    def refused(call: Any, words: str) -> None:
        before = len(m.messages)
        with pytest.raises(FMICallException):
            call()
        logged = " | ".join(m.messages[before:])
        assert words in logged, logged

    refused(lambda: m.step(0.0, DT), "cannot do a step in Instantiated mode")
    m.init()
    refused(lambda: m.set([u], [float("nan")]), "must be finite")
    refused(lambda: m.set(["q.elbow_pitch"], [1.0]), "is an output")
    refused(lambda: m.set(["stiffness.elbow_pitch"], [1.0]), "fixed parameter")
    refused(lambda: m.step(0.0, 1.5 * DT), "not a whole multiple")
    refused(lambda: m.step(0.3, DT), "is not the FMU's time")
    f = m.fmu
    if m.v3:
        refused(lambda: f.getFloat64([99999]), "unknown value reference 99999")
        refused(lambda: f.getInt32([1]), "not supported")
    else:
        refused(lambda: f.getReal([99999]), "unknown value reference 99999")
        refused(lambda: f.getInteger([1]), "not supported")
    # NULL arrays, straight through ctypes
    lib = f.dll
    get = lib.fmi3GetFloat64 if m.v3 else lib.fmi2GetReal
    before = len(m.messages)
    status = get(f.component, None, 2, None, 2) if m.v3 else get(f.component, None, 2, None)
    assert status == 3 and "is NULL" in " ".join(m.messages[before:])
    do_step = lib.fmi3DoStep if m.v3 else lib.fmi2DoStep
    do_step.restype = ctypes.c_int
    assert do_step(None, ctypes.c_double(0.0), ctypes.c_double(DT), 0, None, None, None, None) == 3
    # the instance is still good: a valid step works, the refused ones changed nothing
    m.step(0.0, DT)
    assert m.get(["time"] if m.v3 else ["q.elbow_pitch"]) is not None
    m.close()


def test_instantiation_is_refused_for_a_foreign_token_or_missing_resources(fmus, arm):
    md = read_model_description(str(fmus[3]))
    d = extract(str(fmus[3]))
    messages: List[str] = []
    fmu = FMU3Slave(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=d,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x")
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate(logMessage=lambda env, status, cat, msg: messages.append(msg.decode()))
    assert "instantiation token" in messages[-1]
    (Path(d) / "resources" / "fmu.toml").unlink()
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="y")
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate(logMessage=lambda env, status, cat, msg: messages.append(msg.decode()))
    assert "fmu.toml" in messages[-1]
    shutil.rmtree(d, ignore_errors=True)


def test_every_fmi_function_is_exported():
    # FMPy binds every fmi3 function when it loads a binary; the standard requires all of them
    exported = subprocess.run(["nm", "-D", "--defined-only", str(runtime_library())], capture_output=True,
                              text=True).stdout if shutil.which("nm") else ""
    if not exported:
        pytest.skip("nm is not available")
    functions = {line.split()[-1] for line in exported.splitlines() if " T " in line}
    assert len({f for f in functions if f.startswith("fmi3")}) == 75
    assert len({f for f in functions if f.startswith("fmi2")}) == 44


def test_the_cli_writes_the_builtin_arm_and_a_urdf(tmp_path, arm):
    from orbitflex.cli import main

    assert main(["fmu", "--out", str(tmp_path / "a.fmu")]) == 0
    assert validate_fmu(str(tmp_path / "a.fmu")) == []
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(orbitflex.SPACE_ARM_URDF)
    assert main(["fmu", str(urdf), "--locked-joints", "wrist_roll", "--fmi", "2", "--dt", "5e-4",
                 "--out", str(tmp_path / "b.fmu")]) == 0
    md = read_model_description(str(tmp_path / "b.fmu"))
    assert md.fmiVersion == "2.0" and "q.wrist_roll" not in {v.name for v in md.modelVariables}
    assert md.defaultExperiment.stepSize == "0.0005" or float(md.defaultExperiment.stepSize) == 5e-4
    res = simulate_fmu(str(tmp_path / "b.fmu"), stop_time=0.01, output_interval=5e-4, output=["q.elbow_pitch"])
    assert len(res) == 21
    proc = subprocess.run([sys.executable, "-m", "orbitflex", "fmu", "--dt", "0"], capture_output=True, text=True)
    assert proc.returncode == 2 and "--dt" in proc.stderr
