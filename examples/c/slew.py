"""The run of examples/c/slew.c in Python (orbitflex.Simulator): the same motor PD, the same
slew, the same printed digits. `.ci/run` diffs the two outputs."""

import numpy as np

import orbitflex

kp = np.array([300.0, 1250.0, 1250.0, 650.0, 85.0, 42.0, 16.0])
kd = np.array([100.0, 670.0, 670.0, 300.0, 27.0, 13.0, 4.2])
dt, T, target, steps = 1e-3, 2.0, 0.3, 3000


def quintic(t: float, T: float) -> float:
    s = min(max(t / T, 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
sim = orbitflex.Simulator(arm, arm.state(), dt)
saved = b""
for k in range(steps):
    ref = target * quintic(k * dt, T)
    out = sim.outputs()
    sim.step(u=kp * (ref - out["theta"]) - kd * out["theta_dot"])
    if (k + 1) % 500 == 0:
        print(f"t = {sim.t:.3f} s  q =" + "".join(f" {v:.12e}" for v in sim.outputs()["q"]))
    if k + 1 == 2500:
        saved = sim.save()
out = sim.outputs()
print("base quaternion (x, y, z, w) = " + " ".join(f"{v:.12e}" for v in out["base_pose"][3:]))
print("momentum (angular; linear) =" + "".join(f" {v:.12e}" for v in out["momentum"]))
print(f"energy = {out['energy']:.12e} J")
sim.restore(saved)
sim.step(n=500)
end = sim.x
sim.restore(saved)
sim.step(n=500)
print(f"replay from the saved state: {'bit-exact' if np.array_equal(sim.x, end) else 'DIFFERENT'}")
