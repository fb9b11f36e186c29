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
# # 3. Holding the bus with reaction wheels
#
# When the arm slews, a free-floating bus turns the other way: the total angular momentum stays
# zero. For the demo's slew of the built-in arm, the turn is almost 20°. A servicer's
# attitude-control system must prevent that with its reaction wheels. Three questions follow:
#
# - how well does it hold the bus?
# - do the wheels saturate?
# - how much momentum do they take on?
#
# This tutorial puts four wheels in a pyramid on the bus, holds it with `AttitudePD` through the
# slew, and compares the result with the free bus. It then asks a held-base plan what it demands
# of the wheels, and runs the controller at 50 Hz with a delay. It runs in a few seconds.

# %%
import argparse

import matplotlib.pyplot as plt
import numpy as np

import orbitflex
from orbitflex.cli.slew import SPACE_ARM_SLEW, choose_gains, slew_controller

robot = orbitflex.models.space_arm()
joints = orbitflex.models.space_arm_joints()
free = orbitflex.FlexibleArm(robot, joints)
wheels = orbitflex.models.pyramid_wheels()
arm = orbitflex.FlexibleArm(robot, joints, wheels=wheels)
print("wheel axes (base frame):\n", np.round(wheels.axes, 4))
print(f"J_s = {wheels.spin_inertia[0]} kg·m², max torque {wheels.max_torque[0]} N·m, "
      f"max speed {wheels.max_speed[0]} rad/s")

# the demo's slew: each joint by SPACE_ARM_SLEW (rad) along a 5 s quintic, motor PD at 0.25 Hz
dt, steps = 1e-3, 20000
gains = choose_gains(free, argparse.Namespace(kp=None, kd=None, bandwidth=0.25, damping_ratio=1.0))
motor_pd = slew_controller(free, SPACE_ARM_SLEW, steps, dt, 5.0, gains)

# %% [markdown]
# ## The free bus, and the bus held by its wheels
#
# `AttitudePD(kp, kd)` holds the bus at its initial attitude. It feeds back the quaternion error
# `e = 2 vec(q_ref* ⊗ q_B)` and the rate, and gives the wheels the minimum-norm torques that
# push the bus with `T = −kp e − kd ω`. The gains `PYRAMID_GAINS` (2e5 N·m/rad, 2e4 N·m·s/rad)
# close the loop at about 3.7 Hz on the bus's 190 kg·m².

# %%
free_run = free.simulate(free.state(), dt, steps, u=motor_pd)
held_run = arm.simulate(arm.state(), dt, steps, u=motor_pd,
                        wheel_torque=orbitflex.AttitudePD(*orbitflex.models.PYRAMID_GAINS))


def bus_turn(traj):
    q = traj.base_pose[:, 3:]
    return np.asarray(orbitflex.rotation_angle(q[0], q))


print(f"free bus: turned {np.degrees(bus_turn(free_run)[-1]):.2f}° by the end")
print(f"held bus: at most {bus_turn(held_run).max():.2e} rad from its initial attitude")
print(f"peak wheel torque {np.abs(held_run.wheel_torque).max():.1f} N·m, "
      f"peak wheel speed {np.abs(held_run.wheel_speed).max():.0f} rad/s")
momentum = arm.momentum(held_run.x[-1]) - arm.momentum(held_run.x[0])
print(f"total momentum (bus, arm and wheels, spin included) drifts by {np.abs(momentum).max():.1e}")

# %% [markdown]
# The arm's motion now ends up in the wheels and not in the bus. The speeds rise while the arm
# accelerates, then fall back as it stops. Both the torques and the speeds stay within their
# limits (dashed).

# %%
fig, (top, middle, bottom) = plt.subplots(3, 1, figsize=(9, 8), sharex=True, layout="constrained")
t = held_run.t
top.plot(t, bus_turn(held_run) * 1e3, color="black")
top.set(ylabel="bus error (mrad)",
        title=f"space_arm, dt = 1 ms: the held bus (the free one turns {np.degrees(bus_turn(free_run)[-1]):.1f}°)")
for i in range(4):
    middle.plot(t, held_run.wheel_speed[:, i], label=f"wheel {i}")
    bottom.plot(t[:-1], held_run.wheel_torque[:, i], label=f"wheel {i}")
for ax, limit, label in ((middle, wheels.max_speed[0], "Ω (rad/s)"), (bottom, wheels.max_torque[0], "u_w (N·m)")):
    for sign in (1, -1):
        ax.axhline(sign * limit, color="black", ls="--", lw=0.8)
    ax.set(ylabel=label)
middle.legend(fontsize=8, loc="upper right")
bottom.set(xlabel="time (s)")
plt.show()

# %% [markdown]
# ## What a plan asks of the wheels
#
# A plan with a *held* base comes with the wrench that holds the bus. `plan.wheel_demand(wheels)`
# allocates the moment of that wrench to the wheels and integrates their speeds from rest. It
# returns the peak torque and the peak stored momentum, and says which limit binds. Smaller wheels
# show where the sizing stops being enough.

# %%
plan = orbitflex.plan_slew(arm, SPACE_ARM_SLEW, base="held")
demand = plan.wheel_demand(wheels)
b = demand["binding"]
print(f"plan {plan.duration:.2f} s; peak stored momentum {demand['peak_momentum']:.0f} N·m·s; "
      f"{b['limit']} binds on wheel {b['wheel']} at {b['ratio']:.0%} of its bound")
small = orbitflex.models.pyramid_wheels(spin_inertia=0.05, transverse_inertia=0.03, max_speed=600.0)
b = plan.wheel_demand(small)["binding"]
print(f"with J_s = 0.05 kg·m²: {b['limit']} binds at {b['ratio']:.0%}: the wheels cannot hold the bus")

# tracked with the wheels in place of the open-loop wrench
run = plan.track(1e-3, 1000.0, 100.0, wheel_torque=orbitflex.AttitudePD(*orbitflex.models.PYRAMID_GAINS))
print(f"tracked with the wheels: bus attitude within {run['base_attitude_error']:.1e} rad; "
      f"its position drifts {run['base_position_error'] * 100:.0f} cm (the wheels do not hold translation)")

# %% [markdown]
# ## Flight software at 50 Hz, one sample late
#
# `Sampled(controller, rate_hz, delay)` runs any controller at its own rate, holding its output
# between samples. The same hold at 50 Hz with a delay of one sample (20 ms) is an unstable
# discrete loop: `orbitflex.analysis.sampled_loop` gives its spectral radius ρ (above 1:
# unstable), and `simulate` warns before it starts. The wheels then ride at their torque limit
# and the pointing error grows tenfold.

# %%
import warnings

from orbitflex import analysis

for rate, delay in ((1000.0, 0), (50.0, 0), (50.0, 1)):
    acs = orbitflex.Sampled(orbitflex.AttitudePD(*orbitflex.models.PYRAMID_GAINS), rate, delay=delay)
    rho = analysis.sampled_loop(arm, arm.state(), acs, u=motor_pd).spectral_radius
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = arm.simulate(arm.state(), dt, steps, u=motor_pd, wheel_torque=acs)
    warned = "  (simulate warned: unstable sampled loop)" if caught else ""
    print(f"{rate:6.0f} Hz, delay {delay}: ρ = {rho:.3f}, bus within {bus_turn(r).max():.2e} rad, "
          f"wheel torque up to {np.abs(r.wheel_torque).max():.0f} N·m{warned}")
