"""FMUs of an arm with reaction wheels on its bus (``orbitflex fmu --wheels``), run by FMPy in FMI
3.0 and 2.0: the wheel variables in the model description, an input table on ``wheel_torque.<k>``
bit for bit ``arm.simulate(..., wheel_torque=...)`` (both limits reached), an ``AttitudePD``
written as the master's controller bit for bit the same loop on a ``Simulator``, FMU states with
the wheel speeds, and states of another wheel count refused."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, List

import numpy as np
import pytest

import orbitflex
from orbitflex.fmu import write_fmu

pytest.importorskip("fmpy", reason="FMPy (pip install fmpy; Python >= 3.10) runs the FMUs")
from fmpy import read_model_description, simulate_fmu  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402
from test_fmu import Master, names  # noqa: E402  (skips this module too without the runtime)

DT = 1e-3
VERSIONS = (3, 2)
ROOT = Path(__file__).resolve().parents[2]


def wheel_names(prefix: str, k: int) -> List[str]:
    return [f"{prefix}.{w}" for w in range(k)]


@pytest.fixture(scope="module")
def wheels() -> orbitflex.ReactionWheels:
    return orbitflex.models.pyramid_wheels()


@pytest.fixture(scope="module")
def arm(wheels: orbitflex.ReactionWheels) -> orbitflex.FlexibleArm:
    return orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints(), wheels=wheels)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: Any, arm: orbitflex.FlexibleArm) -> Dict[int, Path]:
    out = tmp_path_factory.mktemp("wheel_fmus")
    return {v: write_fmu(out / f"wheels{v}.fmu", orbitflex.SPACE_ARM_URDF, arm, DT, fmi=v) for v in VERSIONS}


@pytest.mark.parametrize("version", VERSIONS)
def test_the_wheel_variables_are_declared_with_units(fmus, version):
    path = str(fmus[version])
    assert validate_fmu(path) == []
    md = read_model_description(path)
    by_name = {v.name: v for v in md.modelVariables}
    for w in range(4):
        torque, speed = by_name[f"wheel_torque.{w}"], by_name[f"wheel_speed.{w}"]
        applied, speed0 = by_name[f"applied_wheel_torque.{w}"], by_name[f"wheel_speed0.{w}"]
        assert (torque.causality, torque.unit, float(torque.start)) == ("input", "N.m", 0.0)
        assert "clipped to its max_torque" in torque.description
        assert (speed.causality, speed.unit) == ("output", "rad/s")
        assert (applied.causality, applied.unit) == ("output", "N.m")
        assert (speed0.causality, speed0.variability, speed0.unit) == ("parameter", "fixed", "rad/s")
    assert "4 reaction wheels" in md.description
    assert all(not o.dependencies for o in md.outputs)  # still no direct feedthrough


@pytest.mark.parametrize("version", VERSIONS)
def test_an_input_table_on_the_wheels_equals_simulate(fmus, arm, wheels, version):
    # commands beyond max_torque (60 N·m) on every wheel, wheel 2 started just under max_speed
    # (800 rad/s) and pushed faster: both limits act, as in simulate
    steps, n, k = 300, arm.dof, 4
    rng = np.random.default_rng(11)
    u = rng.uniform(-2, 2, (steps, n))
    w = rng.uniform(-90, 90, (steps, k))
    w[:, 2] = 70.0
    speed0 = np.array([10.0, -20.0, 799.95, 0.0])
    t = np.arange(steps) * DT
    inputs = names(arm, "motor_torque") + wheel_names("wheel_torque", k)
    table = np.zeros(steps, dtype=[("time", "f8")] + [(c, "f8") for c in inputs])
    table["time"] = t
    for i, c in enumerate(inputs):
        table[c] = np.hstack([u, w])[:, i]
    outputs = wheel_names("wheel_speed", k) + wheel_names("applied_wheel_torque", k) + \
        names(arm, "q") + ["base_angular_velocity.x"]
    start = {f"wheel_speed0.{i}": s for i, s in enumerate(speed0)}
    res = simulate_fmu(str(fmus[version]), stop_time=steps * DT, output_interval=DT, input=table,
                       output=outputs, fmi_type="CoSimulation", start_values=start)
    x0 = arm.state(wheel_speed=speed0)
    traj = arm.simulate(x0, DT, steps, u=u, wheel_torque=w)
    col = lambda prefix, m: np.column_stack([res[c] for c in wheel_names(prefix, m)])  # noqa: E731
    assert np.array_equal(col("wheel_speed", k), traj.wheel_speed)  # bit for bit
    applied = col("applied_wheel_torque", k)
    assert np.array_equal(applied[1:], traj.wheel_torque)  # row j+1: what step j applied
    assert np.array_equal(applied[0], np.zeros(k))
    assert np.array_equal(np.column_stack([res[c] for c in names(arm, "q")]), traj.q)
    assert np.array_equal(res["base_angular_velocity.x"], traj.x[:, 7 + 2 * n])
    # both limits were reached: clipped at ±60 N·m, and no torque speeding wheel 2 past 800 rad/s
    assert np.abs(applied).max() == 60.0 and np.any(np.abs(w) > 60.0)
    assert np.any(applied[1:, 2] == 0.0) and traj.wheel_speed[:, 2].max() >= 800.0


def attitude_master(m: Master, arm: orbitflex.FlexibleArm) -> np.ndarray:
    """The state, read back from the FMU's outputs (every part of it is one)."""
    n = arm.robot.joint_names
    parts = [[f"base_position.{a}" for a in "xyz"], [f"base_quaternion.{a}" for a in "xyzw"],
             [f"q.{j}" for j in n], [f"theta.{j}" for j in n],
             [f"base_angular_velocity.{a}" for a in "xyz"], [f"base_velocity.{a}" for a in "xyz"],
             [f"qd.{j}" for j in n], [f"theta_dot.{j}" for j in n], wheel_names("wheel_speed", 4)]
    return m.get([name for part in parts for name in part])


@pytest.mark.parametrize("version", VERSIONS)
def test_an_attitude_pd_master_holds_the_bus_as_a_simulator_loop_does(fmus, arm, version):
    # the master runs AttitudePD on the state it reads from the FMU and a motor PD slewing every
    # joint by 0.15 rad in 2 s, both every 2 dt; the same loop on a Simulator takes the same
    # steps, bit for bit. Without wheels (free floating) the same slew turns the bus.
    from test_fmu import quintic

    kp, kd = arm.motor_pd_gains(1.0)
    pd = orbitflex.AttitudePD(*orbitflex.models.PYRAMID_GAINS, attitude=[0.0, 0.0, 0.0, 1.0])
    bare = orbitflex.FlexibleArm(arm.robot, arm.joints)
    m = Master(fmus[version])
    m.init()
    sim, free = orbitflex.Simulator(arm, arm.state(), DT), orbitflex.Simulator(bare, bare.state(), DT)
    n, h, periods = arm.dof, 2 * DT, 1250
    theta, theta_dot = slice(7 + n, 7 + 2 * n), slice(13 + 3 * n, 13 + 4 * n)
    for k in range(periods):
        ref = 0.15 * quintic(k * h, 2.0)
        x = attitude_master(m, arm)
        assert np.array_equal(x, sim.x)
        wheel = np.asarray(pd.command(arm, x))
        motor = kp * (ref - x[theta]) - kd * x[theta_dot]
        m.set(wheel_names("wheel_torque", 4) + names(arm, "motor_torque"), np.r_[wheel, motor])
        m.step(k * h, h)
        sim.step(u=kp * (ref - sim.x[theta]) - kd * sim.x[theta_dot], wheel_torque=pd.command(arm, sim.x), n=2)
        xf = free.x
        free.step(u=kp * (ref - xf[theta]) - kd * xf[theta_dot], n=2)
    x = attitude_master(m, arm)
    assert np.array_equal(x, sim.x)
    assert np.array_equal(m.get(wheel_names("applied_wheel_torque", 4)), sim.outputs()["applied_wheel_torque"])
    # the arm slewed and the wheels took its reaction: the bus turned < 1 % of the free-floating
    # rotation, and the wheels hold the momentum (spinning)
    turned = lambda quat: 2 * np.arcsin(min(np.linalg.norm(quat[:3]), 1.0))  # noqa: E731
    assert np.abs(x[7:7 + n] - 0.15).max() < 0.05
    assert turned(x[3:7]) < 0.01 * turned(free.x[3:7])
    assert np.abs(x[-4:]).max() > 10.0
    m.close()


@pytest.mark.parametrize("version", VERSIONS)
def test_fmu_state_carries_the_wheel_speeds_bit_exact(fmus, arm, version):
    m = Master(fmus[version])
    m.init(**{"wheel_speed0.1": 150.0})
    every = [v.name for v in m.md.modelVariables if v.causality == "output"]
    torque = wheel_names("wheel_torque", 4)
    m.set(torque, [5.0, -70.0, 1.0, 0.5])
    m.step(0.0, 0.02)
    state = m.fmu.getFMUState()
    blob = m.fmu.serializeFMUState(state)
    mid = m.get(every)
    m.set(torque, [-5.0, 3.0, 2.0, 0.0])
    m.step(0.02, 0.02)
    end = m.get(every)
    m.fmu.setFMUState(m.fmu.deserializeFMUState(blob))
    assert np.array_equal(m.get(every), mid)
    assert np.array_equal(m.get(torque), [5.0, -70.0, 1.0, 0.5])  # the held commands came back
    m.set(torque, [-5.0, 3.0, 2.0, 0.0])
    m.step(0.02, 0.02)
    assert np.array_equal(m.get(every), end)
    m.fmu.freeFMUState(state)
    m.close()


@pytest.mark.parametrize("version", VERSIONS)
def test_a_state_of_another_wheel_count_is_refused(tmp_path, fmus, arm, wheels, version):
    three = orbitflex.ReactionWheels(wheels.axes[:3], wheels.positions[:3], 12.0, 0.25, 0.15, 60.0, 800.0)
    other = orbitflex.FlexibleArm(arm.robot, arm.joints, wheels=three)
    bare = orbitflex.FlexibleArm(arm.robot, arm.joints)
    blobs = {}
    # "three" instantiated last: FMPy's FMI 2.0 logger proxy serves the last instance made
    for name, a in (("four", arm), ("none", bare), ("three", other)):
        path = fmus[version] if a is arm else write_fmu(tmp_path / f"{name}.fmu", orbitflex.SPACE_ARM_URDF, a, DT,
                                                        fmi=version)
        m = Master(path, name)
        m.init()
        m.step(0.0, DT)
        blobs[name] = (m, m.fmu.serializeFMUState(m.fmu.getFMUState()))
    m = blobs["three"][0]
    for name, words in (("four", "saved from an arm with 4 reaction wheels; this simulator's arm has 3"),
                        ("none", "saved from an arm with no reaction wheels; this simulator's arm has 3")):
        before = len(m.messages)
        with pytest.raises(FMICallException):
            m.fmu.setFMUState(m.fmu.deserializeFMUState(blobs[name][1]))
        assert words in " | ".join(m.messages[before:])
    # a state of format version 1 (before the wheels) is refused, saying so
    old = bytearray(blobs["three"][1])
    old[8:12] = (1).to_bytes(4, "little")
    before = len(m.messages)
    with pytest.raises(FMICallException):
        m.fmu.setFMUState(m.fmu.deserializeFMUState(bytes(old)))
    assert "format version 1; this runtime reads version 2" in " | ".join(m.messages[before:])
    for mm, _ in blobs.values():
        mm.close()


def test_the_cli_writes_wheels_and_a_bus(tmp_path, arm):
    from orbitflex.cli import main

    out = tmp_path / "w.fmu"
    assert main(["fmu", "--wheels", str(ROOT / "examples/wheels.toml"), "--out", str(out)]) == 0
    assert validate_fmu(str(out)) == []
    md = read_model_description(str(out))
    assert {f"wheel_torque.{w}" for w in range(4)} <= {v.name for v in md.modelVariables}
    # a URDF on an 800 kg bus, with wheels: the FMU steps that arm, bit for bit
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(orbitflex.SPACE_ARM_URDF)
    out2 = tmp_path / "bus.fmu"
    assert main(["fmu", str(urdf), "--base-mass", "800", "--base-com", "0", "0", "-0.75", "--wheels",
                 str(ROOT / "examples/wheels.toml"), "--fmi", "2", "--out", str(out2)]) == 0
    robot = orbitflex.Robot.from_urdf(str(urdf)).with_base_inertia(800.0, com=[0, 0, -0.75])
    bus = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints.defaults_for(robot),
                                wheels=orbitflex.models.pyramid_wheels())
    table = np.zeros(50, dtype=[("time", "f8"), ("wheel_torque.0", "f8"), ("motor_torque.elbow_pitch", "f8")])
    table["time"] = np.arange(50) * DT
    table["wheel_torque.0"], table["motor_torque.elbow_pitch"] = 3.0, 1.0
    res = simulate_fmu(str(out2), stop_time=50 * DT, output_interval=DT, input=table,
                       output=["base_angular_velocity.z", "wheel_speed.0"])
    w = np.zeros((50, 4))
    w[:, 0] = 3.0
    u = np.zeros((50, bus.dof))
    u[:, bus.robot.joint_names.index("elbow_pitch")] = 1.0
    traj = bus.simulate(bus.state(), DT, 50, u=u, wheel_torque=w)
    assert np.array_equal(res["wheel_speed.0"], traj.wheel_speed[:, 0])
    assert np.array_equal(res["base_angular_velocity.z"], traj.x[:, 7 + 2 * bus.dof + 2])
    # a wheels file that is not one: a clear error naming the flag
    bad = tmp_path / "bad.toml"
    bad.write_text("[defaults]\nmass = -1\n")
    assert main(["fmu", "--wheels", str(bad), "--out", str(tmp_path / "x.fmu")]) == 2
