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
# # 5. A Monte-Carlo campaign on a local Dask cluster
#
# A GNC team qualifies a manoeuvre over dispersions, not on the nominal case: joint stiffness
# known to ±20 %, a payload somewhere between 0 and 40 kg. A `Campaign` declares the nominal slew,
# the dispersions and the metrics, and returns one table row per run. Run `i` draws its parameters
# from its own generator, `numpy.random.default_rng([seed, i])`, so the table is the same, bit for
# bit, on one machine or on any Dask cluster, in any order.
#
# This tutorial starts a real `dask.distributed.LocalCluster` of two worker processes on
# 127.0.0.1, runs a small campaign of a planned slew on it, checks that the table equals the one
# computed in this process, and reads the results. It needs the `campaign` extra
# (`pip install 'orbitflex[campaign]'`: pandas, pyarrow, Dask) and takes well under a minute.

# %%
import matplotlib.pyplot as plt
import numpy as np
from dask.distributed import Client, LocalCluster

import orbitflex
from orbitflex.campaign import Campaign, Dispersion, summary

arm = orbitflex.FlexibleArm(orbitflex.models.space_arm(), orbitflex.models.space_arm_joints())
goal = [0.4, 0.6, -0.5, 0.8, -0.6, 0.5, 1.0]  # rad
plan = orbitflex.plan_slew(arm, goal, base="free")  # minimum time under the URDF's limits
print(f"nominal plan: {plan.duration:.2f} s, bound by {plan.binding['limit']} on {plan.binding['joint_name']}")

dt = 2e-3
campaign = Campaign.from_plan(
    plan, kp=1000.0, kd=100.0, dt=dt, runs=24, seed=7, name="tutorial 5",
    dispersions=[Dispersion("stiffness", "lognormal", sigma=0.2),          # ±20 % per joint
                 Dispersion("payload_mass", "uniform", low=0.0, high=40.0)])  # kg at the EE
print(f"{campaign.runs} runs of {campaign.duration:.2f} s at dt = {dt * 1e3:g} ms")

# %% [markdown]
# ## On the cluster
#
# Two worker processes with one thread each, on the loopback interface, without the dashboard.
# (In a script, a `LocalCluster` must be started under `if __name__ == "__main__":`, since its
# worker processes import the script again.) Each Dask task is a chunk of runs; `campaign.log`
# says which worker ran which chunk, and how long it took.

# %%
with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                  dashboard_address=None) as cluster, Client(cluster) as client:
    print("scheduler at", cluster.scheduler_address)
    table = campaign.run(client=client)
    log = list(campaign.log)
workers = sorted({entry["worker"] for entry in log})
print(f"{len(log)} chunks on {len(workers)} workers")

# %% [markdown]
# The same campaign in this process alone (through `simulate_batch`, on every core) gives the same
# table, bit for bit: no column depends on where or when a run went.

# %%
local = campaign.run()
assert table.equals(local)
print("cluster table == local table:", table.equals(local))
table.head()

# %% [markdown]
# ## The results
#
# `summary` gives each metric's percentiles with its unit. Following the plan's feedforward and
# motor reference, every run ends within a fraction of a milliradian of the goal in joint space
# (`final_error`). Where the end-effector ends up in inertial space is another matter: `ee_error`,
# its distance from the nominal run's final position, reaches tens of centimetres, because a
# payload changes how far the free-floating bus turns during the slew (`base_attitude_change`).
# A free-floating slew planned for one mass distribution points the arm elsewhere for another.

# %%
print(summary(table)[["unit", "p50", "p95", "max"]])
assert table["ok"].all()

# %%
payload = table["payload_mass"]
mean_k = table[[f"stiffness[{i}]" for i in range(arm.dof)]].mean(axis=1)
fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
sc = a1.scatter(payload, table["peak_deflection"] * 1e3, c=mean_k, cmap="viridis")
fig.colorbar(sc, ax=a1, label="mean joint stiffness (N·m/rad)")
a1.set(xlabel="payload mass (kg)", ylabel="peak deflection |θ − q| (mrad)",
       title="peak deflection against the payload")
a2.scatter(payload, table["peak_torque"], color="C1")
a2.set(xlabel="payload mass (kg)", ylabel="peak motor torque |u| (N·m)",
       title="peak motor torque against the payload")
fig.suptitle(f"{campaign.name}: space_arm, planned free-floating slew, {campaign.runs} runs, "
             f"RK4 dt = {dt * 1e3:g} ms")
fig.tight_layout()

# %% [markdown]
# The peak motor torque grows in proportion to the payload: the feedforward carries the plan's
# nominal torque and the PD adds what the extra mass needs. The peak deflection depends on both
# dispersions: it tends to grow with the payload, and it is highest where the joints came out soft
# (the dark points). The worst run can be run again, bit for bit, as a `Trajectory`, to look at it
# in detail (or animate it with `worst.animate("worst.html")`):

# %%
worst_run = int(table["peak_deflection"].idxmax())
worst = campaign.trajectory(worst_run)
assert np.abs(worst.deflection).max() == table["peak_deflection"].max()
fig, ax = plt.subplots(figsize=(8, 3.5))
ax.plot(worst.t, worst.deflection * 1e3, lw=1)
ax.set(xlabel="t (s)", ylabel="θ − q (mrad)",
       title=f"the worst run (run {worst_run}: payload {payload[worst_run]:.1f} kg): joint deflection\n"
             f"space_arm, free floating, RK4 dt = {dt * 1e3:g} ms")
ax.legend(arm.robot.joint_names, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
fig.tight_layout()

# %% [markdown]
# `orbitflex campaign examples/campaign.toml --runs 200 --out campaign_out` runs a campaign
# declared in TOML and writes the table (Parquet), the percentiles (CSV), the histograms and the
# chunk log; `--scheduler tcp://HOST:8786` sends it to a running cluster.
# [Batches and campaigns](../batches.md) describes the dispersions, the metrics, Slurm and
# Kubernetes clusters, and what a campaign keeps in memory.
