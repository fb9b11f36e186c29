"""Checks an installed orbitflex wheel: what it ships, and that its compiled core computes.

Run it from outside the source tree (so that ``import orbitflex`` finds the installed package)
after ``pip install orbitflex-*.whl``. It needs only the wheel's own dependencies (numpy), takes
about a second, and exits non-zero on the first failure. `.ci/wheel_check.sh` runs it in a fresh
virtual environment without a Rust toolchain; the release workflow runs it on every platform's
wheel (docs/install.md).
"""

import importlib.metadata
import site
import sys
from pathlib import Path

import numpy as np

import orbitflex
from orbitflex import _core


def check(condition: bool, what: str) -> None:
    if not condition:
        sys.exit(f"wheel_smoke: FAILED: {what}")
    print(f"  ok  {what}")


package = Path(orbitflex.__file__).resolve().parent
installed = {Path(p).resolve() for p in site.getsitepackages()}
check(package.parent in installed, f"orbitflex is imported from site-packages, not a source tree ({package})")

core = Path(_core.__file__).name
check(core.endswith((".abi3.so", ".pyd")), f"the core is a stable-ABI (abi3) extension ({core})")
check(importlib.metadata.version("orbitflex") == orbitflex.__version__,
      f"wheel metadata and compiled core agree on the version ({orbitflex.__version__})")
check((package / "_core.pyi").is_file() and (package / "py.typed").is_file(),
      "the type stub and py.typed are shipped")

# The FMU / C API runtime ships beside the extension (`orbitflex fmu` packs it into every FMU), and
# it is the same release as the core.
import ctypes  # noqa: E402

runtimes = [package / "_runtime" / name for name in ("liborbitflex_c.so", "liborbitflex_c.dylib", "orbitflex_c.dll")]
runtime = next((r for r in runtimes if r.is_file()), None)
check(runtime is not None, f"the FMU runtime is shipped in {package / '_runtime'}")
assert runtime is not None
library = ctypes.CDLL(str(runtime))
library.ofx_version.restype = ctypes.c_char_p
check(library.ofx_version().decode() == orbitflex.__version__,
      f"the runtime's ofx_version() is the core's version ({orbitflex.__version__})")

# The built-in model goes through the URDF reader compiled into the core.
robot = orbitflex.Robot.from_urdf_string(orbitflex.SPACE_ARM_URDF)
n = robot.dof
check(n == 7 and robot.name == "space_arm", f"the built-in URDF parses ({robot.name}, {n} joints)")

# Inverse after forward dynamics gives back the torque (README, "Python"): both recursive
# algorithms run, and a wrong link or ABI would not reproduce it. The forward solve is backward
# stable, so the residual is a small multiple of eps·(‖M‖‖acc‖ + ‖b‖ + ‖τ‖), the size of the
# largest force summed (‖M‖‖acc‖ ≈ 3e5 here, from the 500 kg bus; observed residual 2e-14).
rng = np.random.default_rng(0)
q, twist, qd, tau = rng.uniform(-1, 1, n), rng.uniform(-0.1, 0.1, 6), rng.uniform(-0.5, 0.5, n), rng.uniform(-5, 5, n)
acc = robot.forward_dynamics(q, twist, qd, tau)
gen = robot.inverse_dynamics(q, twist, qd, acc[:6], acc[6:])
M, b = robot.mass_matrix(q), robot.bias_forces(q, twist, qd)
scale = np.abs(M).sum(axis=1).max() * np.abs(acc).max() + np.abs(b).max() + np.abs(tau).max()
error = np.abs(gen - np.r_[np.zeros(6), tau]).max()
check(error <= 64 * np.finfo(float).eps * scale, f"inverse_dynamics(forward_dynamics(tau)) == tau ({error:.1e} N·m)")

# A free-floating run conserves momentum up to RK4's truncation error (README, "Python"); the
# drift is truncation, not round-off (1.3e-6 on x86-64), so other platforms' libm cannot move it
# near the bound.
arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints.space_arm())
pd = orbitflex.MotorPD(kp=1000.0, kd=100.0, theta_ref=np.full(n, 0.2))
traj = arm.simulate(arm.state(), dt=1e-3, steps=1000, u=pd)
drift = np.abs(traj.momentum - traj.momentum[0]).max()
check(traj.x.shape == (1001, arm.state_size) and drift < 1e-5, f"a 1 s free-floating run keeps momentum ({drift:.1e})")

# The thread pool (rayon) in the wheel: a batch reproduces the single run bit for bit.
batch = orbitflex.simulate_batch(arm, np.stack([arm.state()] * 4), dt=1e-3, steps=1000, u=pd, threads=2)
check(all(np.array_equal(batch.x[i], traj.x) for i in range(4)), "simulate_batch on 2 threads == simulate, bit for bit")

# Errors cross the boundary as Python exceptions, not as a crash.
try:
    orbitflex.Robot.from_urdf_string("<robot name='broken'><link name='a'></robot>")
except orbitflex.ModelError as error:
    check("broken" in str(error) or "link" in str(error), f"a malformed URDF raises ModelError ({error})")
else:
    check(False, "a malformed URDF raises ModelError")

print(f"wheel_smoke: orbitflex {orbitflex.__version__} from {package}, Python {sys.version.split()[0]}: all checks passed")
