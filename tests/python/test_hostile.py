"""Hostile and careless input: every defect found by the attack has a test named after
it. Inputs that could crash or hang the interpreter run in a subprocess with a time limit, so a
regression fails the test instead of killing the suite."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, FlexibleJoints, ModelError, MotorPD, Robot
from urdf_gen import random_chain

LINK = ('<link name="{0}"><inertial><origin xyz="{1}" rpy="0 0 0"/><mass value="{2}"/>'
        '<inertia ixx="{3}" iyy="{3}" izz="{3}" ixy="0" ixz="0" iyz="0"/></inertial></link>')


def chain_urdf(n, mass="1", origin="0.5 0 0", com="0.1 0 0", inertia="0.1", axis="0 0 1"):
    parts = ['<robot name="chain">', LINK.format("l0", "0 0 0", "10", "1")]
    for i in range(1, n + 1):
        parts.append(LINK.format(f"l{i}", com, mass, inertia))
        parts.append(f'<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>'
                     f'<origin xyz="{origin}" rpy="0 0 0"/><axis xyz="{axis}"/></joint>')
    parts.append("</robot>")
    return "".join(parts)


def run_python(code: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    env = dict(os.environ, RUST_BACKTRACE="0")
    try:
        return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                              text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        pytest.fail(f"did not finish in {timeout} s:\n{code}")


# ---- 1, 2: deeply nested XML ---------------------------------------------------------------------


def test_regression_deep_nesting_is_an_error_not_a_crash():
    # 140 KB of nested <a> crashed the process (SIGSEGV) in urdf-rs's recursive converter.
    result = run_python("""
        import orbitflex
        xml = '<robot name="r"><link name="b"/>' + '<a>' * 20000 + '</a>' * 20000 + '</robot>'
        try:
            orbitflex.Robot.from_urdf_string(xml)
        except orbitflex.ModelError as e:
            print("ModelError:", e)
        """)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "ModelError" in result.stdout and "nested" in result.stdout and "64" in result.stdout


@pytest.mark.parametrize("count", [80_000, 1_000_000])
def test_regression_unclosed_nesting_is_refused_in_linear_time(count):
    # 80k unclosed <a> took 9.9 s (quadratic, with the GIL held); 10^6 would take 25 minutes.
    result = run_python(f"""
        import orbitflex
        try:
            orbitflex.Robot.from_urdf_string('<robot name="r">' + '<a>' * {count})
        except orbitflex.ModelError as e:
            print("ModelError:", e)
        """, timeout=20.0)
    assert "ModelError" in result.stdout and "deep" in result.stdout, result.stdout + result.stderr


def test_malformed_xml_names_the_line():
    xml = '<robot name="r">\n  <link name="a">\n  </lnk>\n</robot>'
    with pytest.raises(ModelError, match="line 3"):
        Robot.from_urdf_string(xml)


# ---- 3: memory -----------------------------------------------------------------------------------


def test_regression_a_ten_thousand_joint_chain_loads_in_linear_memory(tmp_path):
    # Data::new built a dense (6+n)^2 mass matrix per Robot: 8,000 joints took 1.4 GB.
    path = tmp_path / "long.urdf"
    path.write_text(chain_urdf(10_000))
    result = run_python(f"""
        import re, time, orbitflex
        start = time.perf_counter()
        robot = orbitflex.Robot.from_urdf({str(path)!r})
        seconds = time.perf_counter() - start
        arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints(1e4, 1.0))
        # this process's own peak (VmHWM): ru_maxrss would carry over the parent's peak from
        # before the exec (Linux keeps it in the signal struct)
        status = open("/proc/self/status").read()
        print(robot.dof, seconds, int(re.search(r"VmHWM:\\s+(\\d+) kB", status).group(1)) / 1024)
        """)
    dof, seconds, megabytes = result.stdout.split()
    assert dof == "10000", result.stderr
    assert float(megabytes) < 200, f"peak {megabytes} MB"


@pytest.mark.parametrize("call", ["operators", "mass_matrix"])
def test_regression_dense_requests_are_refused_before_allocating(call):
    # robot.operators() on 3,000 joints aborted the process on a 2.6 GB allocation.
    n = 3000 if call == "operators" else 12_000
    robot = Robot.from_urdf_string(chain_urdf(n))
    q = np.zeros(n)
    with pytest.raises(ModelError) as e:
        robot.operators(q, np.zeros(6), q) if call == "operators" else robot.mass_matrix(q)
    assert "GB" in str(e.value) and "recursive" in str(e.value)


def test_simulate_refuses_a_record_larger_than_memory():
    arm = FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    with pytest.raises(ModelError, match=r"steps: the record of 10000000000 steps .* needs"):
        arm.simulate(arm.state(), 1e-3, 10**10)


# ---- 6, 7: what a file is ----------------------------------------------------------------------


def latin1_urdf():
    return ('<?xml version="1.0" encoding="ISO-8859-1"?>' + chain_urdf(2).replace('name="chain"', 'name="Gr\xfc\xdfe"'))


def test_regression_latin1_urdf_with_its_declaration_loads(tmp_path):
    path = tmp_path / "latin1.urdf"
    path.write_bytes(latin1_urdf().encode("latin-1"))
    assert Robot.from_urdf(path).name == "Grüße"


def test_regression_non_utf8_files_say_so(tmp_path):
    urdf = tmp_path / "bad.urdf"
    urdf.write_bytes(chain_urdf(2).encode().replace(b'name="chain"', b'name="\xff"'))
    with pytest.raises(ModelError, match="not UTF-8"):
        Robot.from_urdf(urdf)
    toml = tmp_path / "bad.toml"
    toml.write_bytes(b"[defaults]\nstiffness = 1e4 # \xff\n")
    with pytest.raises(ModelError, match="not UTF-8"):
        FlexibleJoints.from_toml(toml, Robot.from_urdf_string(chain_urdf(2)))


def test_regression_a_directory_is_is_a_directory_error(tmp_path):
    with pytest.raises(IsADirectoryError):
        Robot.from_urdf(tmp_path)
    with pytest.raises(IsADirectoryError):
        FlexibleJoints.from_toml(tmp_path, Robot.from_urdf_string(chain_urdf(2)))


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_regression_a_fifo_is_refused_not_read_for_ever(tmp_path):
    fifo = tmp_path / "pipe.urdf"
    os.mkfifo(fifo)
    result = run_python(f"""
        import orbitflex
        try:
            orbitflex.Robot.from_urdf({str(fifo)!r})
        except orbitflex.ModelError as e:
            print("ModelError:", e)
        """, timeout=20.0)
    assert "not a regular file" in result.stdout, result.stdout + result.stderr


# ---- 8, 9: numbers that overflow -----------------------------------------------------------------


@pytest.mark.parametrize("kwargs,words", [
    (dict(mass="1e308"), ["link 'l1'", "mass", "larger than"]),
    (dict(origin="1e200 0 0"), ["joint 'j1'", "origin", "farther than"]),
    (dict(com="1e200 0 0"), ["link 'l1'", "centre of mass", "farther than"]),
    (dict(inertia="1e308"), ["link 'l1'", "inertia", "larger than"]),
], ids=["mass", "origin", "com", "inertia"])
def test_regression_overflowing_numbers_say_what_overflowed(kwargs, words):
    # They were reported as "the base has no mass" or "moves links with no inertia".
    with pytest.raises(ModelError) as e:
        Robot.from_urdf_string(chain_urdf(2, **kwargs))
    for word in words:
        assert word in str(e.value), str(e.value)
    assert "no mass" not in str(e.value) and "no inertia" not in str(e.value)


def test_regression_a_huge_but_valid_axis_is_a_direction():
    big = Robot.from_urdf_string(chain_urdf(2, axis="1e200 1e200 0"))
    unit = Robot.from_urdf_string(chain_urdf(2, axis="1 1 0"))
    q = np.array([0.3, -0.2])
    np.testing.assert_allclose(big.mass_matrix(q), unit.mass_matrix(q), rtol=1e-15, atol=1e-15)


def test_regression_step_on_an_overflowing_state_says_so():
    # It said "links moved by joint 'wrist_yaw' have no inertia (D = NaN)".
    arm = FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    x = arm.state(qd=np.full(7, 1e200))
    with pytest.raises(ModelError) as e:
        arm.step(x, 1e-3)
    assert "overflow" in str(e.value) and "no inertia" not in str(e.value)


# ---- 10, 11: pickling ------------------------------------------------------------------------------


def test_regression_pickled_robot_with_rotated_inertial_frames_is_bit_exact():
    # The mass matrix differed by 1.8e-15 after a round trip: the axes were normalised again.
    for seed in range(6):
        chain = random_chain(seed)
        robot = Robot.from_urdf_string(chain.xml, ee_link=chain.ee_link)
        again = pickle.loads(pickle.dumps(robot))
        q = np.random.default_rng(seed).normal(size=robot.dof)
        np.testing.assert_array_equal(again.mass_matrix(q), robot.mass_matrix(q))
        v, qd = np.full(6, 0.3), np.full(robot.dof, -0.4)
        np.testing.assert_array_equal(again.bias_forces(q, v, qd), robot.bias_forces(q, v, qd))


# ---- 12: minor ------------------------------------------------------------------------------------


def test_regression_huge_gear_ratio_names_the_overflow():
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_gear(1e4, 1e200, 1e-5)
    assert "gear_ratio" in str(e.value) and "not a finite" in str(e.value)


@pytest.mark.parametrize("value", [True, "1e4", [1e4, "a"]], ids=["bool", "text", "mixed"])
def test_regression_parameters_that_are_not_numbers_are_refused(value):
    with pytest.raises(ModelError, match="stiffness"):
        FlexibleJoints(value, 1.0)


def test_regression_dt_none_names_dt():
    arm = FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    with pytest.raises(ModelError, match="dt"):
        arm.step(arm.state(), None)
