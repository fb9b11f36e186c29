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
# # Gallery
#
# The figures the command line writes, made again by every build of this site from the installed
# package: `orbitflex demo` (the built-in space arm: a free-floating slew, then a minimum-time plan
# beside the rigid-joint plan) and `orbitflex modes` (structural modes, Bode plot and Campbell
# diagram). Each caption says what the figure shows, for which model, and at which step. The
# [tutorials](tutorials/index.md) make more figures, with the code beside them.
#
# The commands, run in a temporary folder:

# %%
import subprocess
import sys
import tempfile
from pathlib import Path

from IPython.display import Image, Markdown, display

out = Path(tempfile.mkdtemp(prefix="orbitflex_gallery_"))
commands = [
    ["orbitflex", "demo", "--quiet", "--no-animation", "--out", str(out / "demo")],
    ["orbitflex", "modes", "--motors", "clamped", "--q", "0", "0.3", "0", "1.2", "0", "0", "0",
     "--inputs", "ee_wrench", "--outputs", "ee_position",
     "--sweep", "elbow_pitch", "0", "2.5", "40", "--out", str(out / "modes")],
]
for command in commands:
    print("$", " ".join(command).replace(str(out) + "/", ""))
    run = subprocess.run([sys.executable, "-m", "orbitflex", *command[1:]], capture_output=True, text=True)
    if run.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed ({run.returncode}):\n{run.stdout}\n{run.stderr}")

# %% tags=["remove-input"]
DEMO = "the built-in `space_arm` (500 kg bus, 7-joint arm), free floating, 20 s, RK4 dt = 1 ms"
PLAN = ("the built-in `space_arm`, free floating; minimum-time slew under the URDF's limits, "
        "tracked with RK4 dt = 1 ms")
MODES = ("the built-in `space_arm`, free floating, motors clamped, about q = [0, 0.3, 0, 1.2, 0, 0, 0] "
         "rad; a linearisation, so no time step")
FIGURES = [
    ("demo", "joint_vs_motor_angles.png", "Link angles `q` (coloured) and motor angles `θ` (black dotted) "
     "during the slew, which lie on each other at this scale; below, the motor lead `θ − q` in a unit "
     "chosen to read it.", DEMO),
    ("demo", "deflection.png", "Joint deflection `θ − q`, one panel per joint on its own scale (a wrist "
     "deflects far less than a shoulder), with each joint's peak deflection and spring torque.", DEMO),
    ("demo", "base_attitude.png", "The bus's Euler angles, intrinsic z-y′-x″ (yaw, pitch, roll; base to "
     "inertial), and its total rotation since t = 0: the arm's slew turns the free-floating bus.", DEMO),
    ("demo", "ee_path.png", "The end-effector's path, with the arm and the bus at the start and the end "
     "(equal axes); right, the path relative to its start, zoomed, with dots at regular times.", DEMO),
    ("demo", "momentum_drift.png", "Drift of the total momentum `h(t) − h(0)`, angular (N·m·s, about the "
     "inertial origin) and linear (N·s), inertial components: conserved by the dynamics, so the drift is "
     "RK4's truncation error, at round-off level.", DEMO),
    ("demo", "plan_vs_rigid.png", "The minimum-time plan made with the flexible joints against the same "
     "slew planned as if the joints were rigid, both run on the flexible arm: tracking error and the "
     "vibration left after the stop.", PLAN),
    ("demo", "plan_motor_torque.png", "The planned motor torque of each joint against its limit (dashed "
     "when within view, named in the title otherwise), each panel scaled to its data.", PLAN),
    ("demo", "plan_joint_speed.png", "The planned joint speed of each joint against its limit: the "
     "shoulder's speed limit binds and sets the slew's duration.", PLAN),
    ("modes", "modes.png", "The first six structural modes drawn on the arm: at rest (grey) and displaced "
     "by the real part of the mode shape (red), scaled to a tenth of the arm's reach (factor in each "
     "title).", MODES),
    ("modes", "bode.png", "Magnitude and phase of the frequency response from the wrench the "
     "end-effector exerts (moment, N·m, and force, N, in its frame) to its inertial position (m): the "
     "first 12 input–output pairs, with each mode's damped natural frequency dotted and numbered. A line "
     "that rises as 1/f² towards low frequency is the free-floating spacecraft moving as a whole.",
     MODES),
    ("modes", "campbell.png", "Campbell diagram: each structural mode's damped natural frequency against "
     "the elbow angle, 40 configurations from 0 to 2.5 rad.", MODES),
]
for folder, name, what, model in FIGURES:
    path = out / folder / name
    display(Markdown(f"**`{name}`**: {what} *Model:* {model}. "
                     f"*Made by:* `orbitflex {folder}`."))
    display(Image(filename=str(path)))
