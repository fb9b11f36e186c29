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
# # 4. Modes and frequency response
#
# A controller's bandwidth must stay below the first structural mode, and that mode moves: with
# the arm's configuration, with whether the bus floats or is held by its actuators, and with
# whether the motors turn freely, are braked, or are servoed. orbitflex linearises the flexible
# arm on its floating base about any state (with the same analytical derivatives the simulator's
# Jacobians use) and gives its modes, its frequency response and a state-space model.
#
# No time step appears here: these are properties of the linearised continuous-time model.
# Everything runs in milliseconds.

# %%
import matplotlib.pyplot as plt
import numpy as np

import orbitflex
from orbitflex import analysis

robot = orbitflex.models.space_arm()
arm = orbitflex.FlexibleArm(robot, orbitflex.models.space_arm_joints())
q = np.array([0.0, 0.3, 0.0, 1.2, 0.0, 0.0, 0.0])  # rad: shoulder raised, elbow bent
x = arm.state(q=q)  # at rest, springs relaxed
m = arm.modes(x, base="free", motors="clamped")  # brakes on, free floating
print(m.table())

# %% [markdown]
# The table gives each structural mode's damped frequency, natural frequency, damping ratio and
# the spring that stores most of its energy. The 6 rigid-body modes of the free-floating system
# (the whole spacecraft translating and turning) sit at 0 Hz and are separated out.
#
# ## The base and the motors change the modes
#
# The same configuration with the bus free or held inertially still, and the motors clamped
# (brakes on), free (torque held constant) or under a motor PD:

# %%
kp, kd = arm.motor_pd_gains(0.25)
pd = orbitflex.MotorPD(kp, kd, theta_ref=q)
cases = {
    "free base, motors clamped": dict(base="free", motors="clamped"),
    "held base, motors clamped": dict(base="held", motors="clamped"),
    "free base, motors free": dict(base="free", motors="free"),
    "free base, motor PD (0.25 Hz)": dict(base="free", motors="free", u=pd),
}
for label, settings in cases.items():
    mc = arm.modes(x, **settings)
    print(f"{label:30s} rigid-body {mc.rigid_body:2d}, first modes "
          + ", ".join(f"{f:.3g} Hz (ζ {z:.2g})" for f, z in zip(mc.frequency_hz[:4], mc.damping_ratio[:4])))

# %% [markdown]
# Holding the bus lowers the first frequencies (about 0.56 Hz instead of 1.04 Hz here): a free bus
# recoils, so the arm's springs work against a smaller effective inertia. Freeing the motors turns
# the link-side modes into rigid-body motion of the joints (13 rigid-body modes: 6 + 7), and the
# modes left are the motors ringing against the links through the springs. A motor PD turns the
# joints' free motion into slow, well-damped closed-loop modes (near 0.1 Hz here, from the
# 0.25 Hz design) and damps the structural ones strongly.
#
# ## The Campbell diagram: modes against configuration
#
# `analysis.sweep` computes the modes at many configurations in one call, in parallel in Rust.
# Here the elbow sweeps from 0 to 2.5 rad, with the bus free and held:

# %%
elbow = np.linspace(0.0, 2.5, 60)
configurations = np.tile(q, (len(elbow), 1))
configurations[:, 3] = elbow
fig, axes = plt.subplots(1, 2, figsize=(10, 4.5), sharey=True)
for ax, base in zip(axes, ("free", "held")):
    sw = analysis.sweep(arm, configurations, base=base, motors="clamped")
    ax.plot(np.degrees(elbow), sw.frequency_hz[:, :6], lw=1.2)
    ax.set(xlabel="elbow_pitch (deg)", title=f"base {base}, motors clamped")
    ax.grid(alpha=0.3)
axes[0].set_ylabel("damped natural frequency (Hz)")
fig.suptitle("space_arm: the first six structural modes against the elbow angle (linearised, no dt)")
fig.tight_layout()

# %% [markdown]
# The first two modes hardly move with the elbow, and the held base keeps them near 0.6 Hz against
# about 1 Hz free floating. The higher modes change by a factor of two over the sweep (the sixth
# peaks near 27°): a notch filter tuned at one configuration would miss them at another. Where two
# lines meet, the modes are listed by rank (ascending frequency), so the lines swap labels rather
# than follow a mode shape.
#
# ## Frequency response at the end-effector
#
# How does the end-effector move when it is pushed, for instance by a contact during capture?
# `frequency_response` gives `H(j2πf) = C (j2πf I − A)⁻¹ B + D` for named inputs and outputs: here
# the wrench the end-effector exerts (`ee_wrench`: moment then force, EE frame) to its inertial
# position (`ee_position`, m). We take the force along the EE frame's z axis to the three position
# components, with the bus free and held, and mark each case's first modes.

# %%
freqs = np.logspace(-1, 1.7, 800)  # Hz
fig, (mag, phase) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
for base, colour in (("free", "C0"), ("held", "C3")):
    H = arm.frequency_response(x, freqs, inputs="ee_wrench", outputs="ee_position", base=base,
                               motors="clamped")  # (freqs, 3 outputs, 6 inputs), m per N
    h = H[:, :, 5]  # the force along the EE's z axis
    response = np.linalg.norm(h, axis=1)  # the position's amplitude, all three components
    mag.loglog(freqs, response, color=colour, label=f"base {base}")
    phase.semilogx(freqs, np.degrees(np.angle(h[:, 2])), color=colour, label=f"base {base}, z")
    for f in arm.modes(x, base=base, motors="clamped").frequency_hz[:4]:
        mag.axvline(f, color=colour, ls=":", lw=0.8)
mag.set(ylabel="|EE position| per N (m/N)",
        title="space_arm, motors clamped: EE force along its z axis → EE position\n"
              "(linearised about q = [0, 0.3, 0, 1.2, 0, 0, 0] rad; first four modes dotted)")
mag.legend(fontsize=8)
mag.grid(alpha=0.3, which="both")
phase.set(xlabel="frequency (Hz)", ylabel="phase of the z component (deg)")
phase.grid(alpha=0.3, which="both")
fig.tight_layout()

# %% [markdown]
# Below the first mode the free-floating response falls as `1/f²`: the whole spacecraft accelerates
# under the push (a rigid-body mode at 0 Hz). Held, the arm is a spring at low frequency, and the
# response is flat. The peaks are the structural modes, lightly damped (ζ of order 1e-4 with the
# brakes on): a contact force with content near them excites the arm.
#
# ## The model for MATLAB and python-control
#
# `state_space` returns `A, B, C, D` with the names of every state, input and output;
# `.savemat(path)` writes them for MATLAB/Simulink and `.to_control()` gives a python-control
# `StateSpace` (both need `pip install 'orbitflex[analysis]'`).

# %%
ss = arm.state_space(x, inputs="ee_wrench", outputs="ee_position", motors="clamped")
print("A", ss.A.shape, "B", ss.B.shape, "C", ss.C.shape, "D", ss.D.shape)
print("inputs:", ss.inputs)
print("outputs:", ss.outputs)
print("first states:", ss.states[:4], "…")

# %% [markdown]
# [Structural modes and frequency response](../modes.md) gives the equations, the two
# eigenproblems (the damped state matrix and the undamped pencil), the held base and the cost;
# `orbitflex modes` draws the mode shapes, Bode plots and Campbell diagrams from the command line
# (see [the gallery](../gallery.py)).
