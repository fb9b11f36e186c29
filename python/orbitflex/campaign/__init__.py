# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
# (pandas, Dask and their stubs come with orbitflex[campaign]: a base install type-checks clean)
"""Monte-Carlo campaigns: many slews of one arm with dispersed parameters, run locally through
:func:`orbitflex.simulate_batch` or on a Dask cluster, with one table row per run.

A campaign is a nominal slew and a list of dispersions. The nominal slew is either a quintic
rest-to-rest motion of the motor references followed by a motor-side PD, or a planned slew
(:meth:`Campaign.from_plan`: a :class:`~orbitflex.Plan`'s per-step motor reference and
feedforward torque, and for a held base the wrench that holds it, under the same PD).
Run ``i`` draws its parameters from its own
random generator, ``numpy.random.default_rng([seed, i])``, in the order the dispersions are
declared, so a run's parameters and results depend only on the campaign and ``i``: the table is
the same, bit for bit, whether the runs go one chunk at a time on a laptop or as tasks on a
cluster, in any order, with any number of threads or workers.

Declare a campaign in TOML (:meth:`Campaign.from_toml`, see ``examples/campaign.toml``) or in
Python, then call :meth:`Campaign.run`::

    from orbitflex.campaign import Campaign, Dispersion
    campaign = Campaign(goal=[0.4, 0.6, -0.5, 0.8, -0.6, 0.5, 1.0], kp=1000.0, kd=100.0,
                        dt=2e-3, duration=8.0, slew_time=4.0, runs=100, seed=1,
                        dispersions=[Dispersion("stiffness", "lognormal", sigma=0.2)])
    table = campaign.run()                        # local, every core
    table = campaign.run(scheduler="tcp://host:8786")   # on a Dask cluster
    worst = campaign.trajectory(int(table["peak_deflection"].idxmax()))   # that run, again

Dispersed parameters (``parameter =``), with their units and nominal values:

========================= ====== ======================================= =====================
parameter                 shape  what                                    nominal
========================= ====== ======================================= =====================
``stiffness``             (n,)   joint stiffness k (N·m/rad)             the joints'
``motor_inertia``         (n,)   reflected motor inertia j (kg·m²)       the joints'
``damping``               (n,)   joint damping d (N·m·s/rad)             the joints'
``motor_damping``         (n,)   motor friction β (N·m·s/rad)            the joints'
``kp``, ``kd``            (n,)   PD gains (N·m/rad, N·m·s/rad)           ``kp``, ``kd``
``goal``                  (n,)   slew goal, link side (rad)              ``goal``
``q0``                    (n,)   initial link and motor angles (rad)     ``q0`` (zeros)
``base_rate``             (3,)   initial base angular rate, base frame   zeros
                                 (rad/s)
``payload_mass``          ()     mass held at the EE (kg), at            ``payload_mass`` (0)
                                 ``payload_com`` in the EE frame (the
                                 end-effector ``payload_ee`` of a robot
                                 with several)
========================= ====== ======================================= =====================

Distributions (``distribution =``): ``normal`` (nominal + ``std`` × N(0, 1), or with
``relative``: nominal × (1 + relative × N(0, 1))), ``lognormal`` (nominal × exp(``sigma`` ×
N(0, 1)), always of the nominal's sign), ``uniform`` (with ``low``/``high``: U(low, high), the
values themselves, *not* an offset from the nominal; with ``relative``: nominal × (1 + U(−r, r))). ``per_joint = true`` (default) draws each element on its own; ``false`` draws one number
for all elements (a common-mode error). ``std``, ``low`` and ``high`` may be per element.

Metrics, one column each (NaN where a run failed before they were defined):

- ``ok`` (bool), ``failed_step`` (the failing step, −1 if the run finished);
- ``peak_deflection`` (rad): max over joints and every step of ``|θ − q|``;
- ``peak_torque`` (N·m): max over joints and every step of ``|u|``;
- ``final_error`` (rad): max over joints of ``|q − goal|`` at the end;
- ``settling_time`` (s): the first kept row from which ``|q − goal| ≤ settle_tolerance`` on
  every joint until the end (NaN if not settled; resolution ``dt × record_every``);
- ``base_attitude_change`` (rad): the bus's rotation angle between the start and the end;
- ``ee_error`` (m): the distance between the EE position at the end and that of the nominal
  run (no dispersion); on a robot with several end-effectors, the largest of their distances.

The table has one row per run, ``run`` (the index) first, then the dispersed parameters
(``stiffness[0]``, …; scalars by name), then the metrics; nothing about where or when a run
went, so that two tables of the same campaign compare equal. That goes to :attr:`Campaign.log`.
"""

from __future__ import annotations

# the concepts of a campaign, one module each; every name of this module is importable from it

from .dispersion import Array, CampaignError, DISTRIBUTIONS, Dispersion, JOINT_PARAMETERS, METRICS, PARAMETERS, POSITIVE, TITLES, UNITS
from .execute import ChunkLog, reachable as reachable
from .outputs import histograms, summary, write_outputs
from .spec import Campaign
from .capture import CAPTURE_METRICS, CAPTURE_PARAMETERS, CaptureCampaign, load_campaign

__all__ = ["Campaign", "CaptureCampaign", "load_campaign", "CAPTURE_PARAMETERS", "CAPTURE_METRICS", "Dispersion", "CampaignError", "ChunkLog", "summary", "write_outputs", "histograms",
           "PARAMETERS", "METRICS"]
