"""orbitflex's C API (liborbitflex_c, include/orbitflex.h): the C example built with the system
compiler prints the digits of its Python twin; bad calls return a status and a message, per
thread, and never crash the host."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import orbitflex
from orbitflex.fmu import runtime_library

ROOT = Path(__file__).resolve().parents[2]

try:
    LIB_PATH = runtime_library()
except FileNotFoundError as e:  # pragma: no cover - a wheel built without the runtime
    pytest.skip(str(e), allow_module_level=True)

OK, INVALID, MODEL, SIMULATION = 0, 1, 2, 3
P = ctypes.c_void_p
D = ctypes.POINTER(ctypes.c_double)


@pytest.fixture(scope="module")
def lib() -> ctypes.CDLL:
    lib = ctypes.CDLL(str(LIB_PATH))
    lib.ofx_last_error.restype = ctypes.c_char_p
    lib.ofx_version.restype = ctypes.c_char_p
    lib.ofx_simulator_new.argtypes = [P, D, ctypes.c_size_t, ctypes.c_double, ctypes.POINTER(P)]
    lib.ofx_simulator_step.argtypes = [P, ctypes.c_size_t]
    lib.ofx_simulator_set_motor_torque.argtypes = [P, D, ctypes.c_size_t]
    lib.ofx_simulator_state.argtypes = [P, D, ctypes.c_size_t]
    lib.ofx_simulator_output.argtypes = [P, ctypes.c_uint32, D, ctypes.c_size_t]
    lib.ofx_simulator_restore.argtypes = [P, ctypes.c_char_p, ctypes.c_size_t]
    lib.ofx_simulator_free.argtypes = [P]
    lib.ofx_arm_free.argtypes = [P]
    lib.ofx_robot_free.argtypes = [P]
    return lib


def error(lib: ctypes.CDLL) -> str:
    return lib.ofx_last_error().decode()


def doubles(a: np.ndarray) -> "ctypes._Pointer[ctypes.c_double]":
    return a.ctypes.data_as(D)


def test_the_c_example_prints_what_python_prints(tmp_path):
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no system C compiler (cc)")
    exe = tmp_path / "slew"
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", "-ffp-contract=off",
                    str(ROOT / "examples/c/slew.c"), f"-I{ROOT / 'include'}", f"-L{LIB_PATH.parent}",
                    "-l:" + LIB_PATH.name, f"-Wl,-rpath,{LIB_PATH.parent}", "-o", str(exe)], check=True)
    c = subprocess.run([str(exe)], capture_output=True, text=True, check=True)
    py = subprocess.run([sys.executable, str(ROOT / "examples/c/slew.py")], capture_output=True, text=True,
                        check=True, cwd=tmp_path)
    assert c.stdout == py.stdout
    assert "bit-exact" in c.stdout
    assert "u: expected length 7, given 3" in c.stderr


def test_a_simulator_through_the_c_api_equals_simulate(lib):
    arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
    x0 = arm.state(q=np.linspace(-0.5, 0.5, 7))
    u = np.linspace(1, -1, 7)
    traj = arm.simulate(x0, 1e-3, 200, u=u)
    c_arm, sim = P(), P()
    assert lib.ofx_arm_builtin(b"space_arm", ctypes.byref(c_arm)) == OK
    assert lib.ofx_simulator_new(c_arm, doubles(x0), x0.size, 1e-3, ctypes.byref(sim)) == OK
    lib.ofx_arm_free(c_arm)
    assert lib.ofx_simulator_set_motor_torque(sim, doubles(u), 7) == OK
    assert lib.ofx_simulator_step(sim, 200) == OK
    x = np.empty(x0.size)
    assert lib.ofx_simulator_state(sim, doubles(x), x.size) == OK
    assert np.array_equal(x, traj.x[-1])
    lib.ofx_simulator_free(sim)


def test_bad_calls_return_a_status_and_a_message_per_thread(lib):
    out = P()
    assert lib.ofx_robot_builtin(None, ctypes.byref(out)) == INVALID
    assert error(lib) == "ofx_robot_builtin: name is NULL"
    assert lib.ofx_robot_builtin(b"nope", ctypes.byref(out)) == INVALID
    assert "unknown built-in model 'nope'" in error(lib)
    assert lib.ofx_robot_builtin(b"space_arm", None) == INVALID
    assert lib.ofx_robot_from_urdf_file(b"/no/such.urdf", None, None, ctypes.byref(out)) == MODEL
    assert "/no/such.urdf" in error(lib)
    arm, sim = P(), P()
    assert lib.ofx_arm_builtin(b"space_arm", ctypes.byref(arm)) == OK
    x0 = np.zeros(41)
    x0[6] = 1.0
    assert lib.ofx_simulator_new(arm, doubles(x0), 41, -1.0, ctypes.byref(sim)) == INVALID
    assert "dt" in error(lib)
    assert lib.ofx_simulator_new(arm, doubles(x0), 40, 1e-3, ctypes.byref(sim)) == INVALID
    assert "x0: expected length 41, given 40" in error(lib)
    assert lib.ofx_simulator_new(arm, doubles(x0), 41, 1e-3, ctypes.byref(sim)) == OK
    nan = np.full(7, np.nan)
    assert lib.ofx_simulator_set_motor_torque(sim, doubles(nan), 7) == INVALID
    assert "finite" in error(lib)
    assert lib.ofx_simulator_set_motor_torque(sim, None, 7) == INVALID
    buf = np.empty(7)
    assert lib.ofx_simulator_output(sim, 99, doubles(buf), 7) == INVALID
    assert "unknown output 99" in error(lib)
    assert lib.ofx_simulator_output(sim, 0, doubles(buf), 6) == INVALID
    assert lib.ofx_simulator_restore(sim, b"junk", 4) == INVALID
    assert "not a saved orbitflex simulator state" in error(lib)
    assert lib.ofx_simulator_step(None, 1) == INVALID
    # a diverging step: undone, SIMULATION status
    huge = np.full(7, 1e300)
    assert lib.ofx_simulator_set_motor_torque(sim, doubles(huge), 7) == OK
    assert lib.ofx_simulator_step(sim, 5) == SIMULATION
    assert "diverged" in error(lib)
    x = np.empty(41)
    assert lib.ofx_simulator_state(sim, doubles(x), 41) == OK
    assert np.array_equal(x, x0)
    # the last error is per thread
    seen = []
    t = threading.Thread(target=lambda: seen.append(error(lib)))
    t.start()
    t.join()
    assert seen == [""] and "diverged" in error(lib)
    lib.ofx_simulator_free(sim)
    lib.ofx_arm_free(arm)
    lib.ofx_simulator_free(None)  # no-ops
    lib.ofx_arm_free(None)
    assert lib.ofx_version().decode() == orbitflex.__version__


def test_a_c_program_with_reaction_wheels_equals_simulate(tmp_path):
    # capi/tests/wheels.c: the built-in arm with four wheels (ofx_arm_with_wheels), commands
    # beyond the torque limit and a wheel pushed past its speed limit, built with the system
    # compiler; its hex-printed numbers are arm.simulate's, bit for bit
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no system C compiler (cc)")
    exe = tmp_path / "wheels"
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic",
                    str(ROOT / "capi/tests/wheels.c"), f"-I{ROOT / 'include'}", f"-L{LIB_PATH.parent}",
                    "-l:" + LIB_PATH.name, f"-Wl,-rpath,{LIB_PATH.parent}", "-lm", "-o", str(exe)], check=True)
    run = subprocess.run([str(exe)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    lines = {line.split(" ", 1)[0]: line.split(" ", 1)[1] for line in run.stdout.splitlines()
             if not line.startswith(("refused", "plain"))}
    hexes = lambda key: np.array([float.fromhex(v) for v in lines[key].split()])  # noqa: E731
    a, p = 0.5773502691896258, 0.3181980515339464
    sx, sy = np.array([1, -1, -1, 1.0]), np.array([1, 1, -1, -1.0])
    wheels = orbitflex.ReactionWheels(np.column_stack([sx * a, sy * a, np.full(4, a)]),
                                      np.column_stack([sx * p, sy * p, np.full(4, -0.45)]),
                                      12.0, 0.25, 0.15, 60.0, 800.0)
    arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints(), wheels=wheels)
    steps = np.arange(300)
    sign = np.where(steps % 50 < 25, 1.0, -1.0)
    command = sign[:, None] * 70.0 * np.arange(1, 5) / 4.0
    command[:, 2] = 70.0
    u = np.array([1.0, -0.5, 0.25, 2.0, 0.0, -1.0, 0.5])
    traj = arm.simulate(arm.state(wheel_speed=[0.0, 0.0, 799.95, 0.0]), 1e-3, 300, u=u, wheel_torque=command)
    assert lines["wheels"] == "4 state 45" and lines["outputs"] == "4"
    assert np.array_equal(hexes("x"), traj.x[-1])
    assert np.array_equal(hexes("wheel_speed"), traj.wheel_speed[-1])
    assert np.array_equal(hexes("applied"), traj.wheel_torque[-1])
    assert lines["replay"] == "bit-exact"
    # both limits acted: ±60 N·m, and wheel 2 past 800 rad/s gets no torque speeding it up
    assert np.abs(traj.wheel_torque).max() == 60.0 and traj.wheel_speed[:, 2].max() >= 800.0
    assert np.any(traj.wheel_torque[:, 2] == 0.0)
    refusals = {line.split()[1]: line.split(" ", 3)[3] for line in run.stdout.splitlines()
                if line.startswith("refused")}
    codes = {line.split()[1]: int(line.split()[2]) for line in run.stdout.splitlines() if line.startswith("refused")}
    assert set(codes.values()) == {INVALID}
    assert refusals["count"] == "ofx_simulator_set_wheel_torque: torque: expected length 4, given 3"
    assert "finite" in refusals["nan"]
    assert "the arm has no reaction wheels" in refusals["no_wheels"]
    assert "saved from an arm with 4 reaction wheels; this simulator's arm has no reaction wheels" \
        in refusals["restore"]
    assert "spin_inertia[1]" in refusals["bad_wheel"] and "given -0.25" in refusals["bad_wheel"]
    assert "expected at least one wheel, given 0" in refusals["none"]
    assert refusals["null"] == "ofx_arm_with_wheels: wheels is NULL"
    assert "plain outputs 0" in run.stdout
