"""Calls whose buffers do not fit in memory raise ``MemoryError`` with the size, instead of
aborting the interpreter. Each case runs in a subprocess under an address-space limit
(``RLIMIT_AS``), where a failed allocation in Rust would abort the process (rc −6)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

SETUP = r"""
import resource, sys
import numpy as np, orbitflex

def chain(n):
    parts = ['<link name="l0"><inertial><mass value="50"/><inertia ixx="5" iyy="5" izz="5" ixy="0" ixz="0" iyz="0"/></inertial></link>']
    for i in range(n):
        parts.append(f'<link name="l{i+1}"><inertial><origin xyz="0.1 0 0"/><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>')
        parts.append(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i+1}"/><origin xyz="0.2 0 0"/><axis xyz="0 0 1"/></joint>')
    return orbitflex.Robot.from_urdf_string('<robot name="long">' + "".join(parts) + '</robot>')

def limit(gigabytes):
    size = int(gigabytes * 1e9)
    resource.setrlimit(resource.RLIMIT_AS, (size, size))

def attempt(call):
    try:
        call()
        print("OK")
    except MemoryError as e:
        print("MemoryError:", e)
"""


def run(body: str) -> str:
    result = subprocess.run([sys.executable, "-c", textwrap.dedent(SETUP) + textwrap.dedent(body)],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"rc {result.returncode}: {result.stderr[-2000:]}"
    return result.stdout


def test_step_jacobians_of_a_1500_joint_arm_under_3_gb_is_a_memory_error():
    # Issue 24: "memory allocation of 289153152 bytes failed", rc −6. The step's buffers are six
    # blocks of (13 + 4n) × (13 + 5n + 12) numbers: 2.2 GB.
    out = run("""
        arm = orbitflex.FlexibleArm(chain(1500), orbitflex.FlexibleJoints(1e3, 0.1))
        limit(3.0)
        attempt(lambda: arm.step_jacobians(arm.state(), 1e-3))
        # the arm still works afterwards
        print(arm.derivative(arm.state()).shape)
        """)
    assert out.startswith("MemoryError: step_jacobians: needs 2.2 GB"), out
    assert "6013 × 7525 numbers" in out and "(6013,)" in out


@pytest.mark.parametrize("call", ["derivative_jacobians", "linearize"])
def test_jacobians_too_large_for_memory_are_a_memory_error(call):
    out = run(f"""
        arm = orbitflex.FlexibleArm(chain(1500), orbitflex.FlexibleJoints(1e3, 0.1))
        limit(1.2)
        attempt(lambda: arm.{call}(arm.state()))
        """)
    assert out.startswith("MemoryError:") and " MB" in out, out


def test_trajectory_frame_poses_too_large_for_memory_are_a_memory_error():
    # 20,000 rows of a 1500-joint arm's 1501 frames: 1.7 GB
    out = run("""
        arm = orbitflex.FlexibleArm(chain(1500), orbitflex.FlexibleJoints(1e3, 0.1))
        traj = arm.simulate(arm.state(), 1e-4, 2)
        limit(1.5)
        attempt(lambda: traj.frame_poses(rows=[0] * 20000))
        """)
    assert out.startswith("MemoryError: the result, 20000 rows of 10507 numbers, needs 1.7 GB"), out


def test_a_batched_result_too_large_for_memory_is_a_memory_error():
    out = run("""
        robot = chain(1500)
        limit(1.5)
        attempt(lambda: robot.mass_matrix(np.zeros((200, 1500))))
        """)
    assert out.startswith("MemoryError: the result: needs 3.6 GB"), out
    assert "200 rows of 2268036 numbers" in out
