# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""Capture campaigns: the built-in capture scenario (:func:`orbitflex.models.capture_scenario`)
many times with the target's mass, inertia and tumble rate and the grasp timing dispersed, run
through :func:`orbitflex.simulate_capture_batch` locally or as chunks on a Dask cluster, one
table row per run.

Dispersed parameters (``Dispersion(parameter, ...)``, the distributions of
:class:`~orbitflex.campaign.Dispersion`), with their nominal values:

=================== ====== =============================================== ====================
parameter           shape  what                                            nominal
=================== ====== =============================================== ====================
``target_mass``     ()     the target's mass (kg)                          200
``target_inertia``  (3,)   its principal moments about its centre (kg·m²)  the 1.0 × 1.2 × 1.4 m
                                                                           box's: 56.7, 49.3,
                                                                           40.7
``tumble_rate``     ()     its spin about its major axis (deg/s)           2
``grasp_time``      ()     when its handle would reach the EE (s): the     5
                           grasp's timing against the arm's motion
=================== ====== =============================================== ====================

A draw that is not a physical target (a moment breaking the triangle inequality, a mass ≤ 0)
is a row with ``ok`` false and the metrics NaN. Run ``i`` draws from
``numpy.random.default_rng([seed, i])`` in the order the dispersions are declared, so the table
is the same, bit for bit, in chunks or on a cluster.

Metrics (:func:`orbitflex.detumble_metrics`; NaN where not defined): ``ok``, ``captured``,
``capture_time`` (s), ``energy_loss`` (J), ``impulse_force`` (N·s), ``bus_kick`` (deg/s),
``peak_bus_rate`` (deg/s, after the capture), ``peak_spring_torque`` (N·m, after the capture),
``peak_deflection`` (rad, after the capture), ``settle_time`` and ``detumble_time`` (s after the
capture).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .. import Target, Trajectory, detumble_metrics, simulate_capture_batch
from ..models import CaptureScenario, capture_scenario
from .dispersion import CampaignError, Dispersion

CAPTURE_PARAMETERS = ("target_mass", "target_inertia", "tumble_rate", "grasp_time")
CAPTURE_METRICS = ("ok", "captured", "capture_time", "energy_loss", "impulse_force", "bus_kick",
                   "peak_bus_rate", "peak_spring_torque", "peak_deflection", "settle_time",
                   "detumble_time")
_FROM_METRICS = {"capture_time": "capture_time", "energy_loss": "energy_loss",
                 "impulse_force": "impulse_force", "bus_kick": "bus_kick_deg_s",
                 "peak_bus_rate": "peak_bus_rate_deg_s", "peak_spring_torque": "peak_spring_torque",
                 "peak_deflection": "peak_deflection", "settle_time": "settle_time",
                 "detumble_time": "detumble_time"}


@dataclass(frozen=True)
class CaptureCampaign:
    """A capture campaign (module docs): ``runs`` runs of ``duration`` s of the built-in capture
    scenario (the target drifting in at ``drift`` m/s), one row kept in ``record_every``, with
    ``dispersions`` drawn from ``seed``; ``bus_rate`` (deg/s) and ``joint_rate`` (rad/s) are the
    thresholds of :func:`orbitflex.detumble_metrics`."""

    runs: int = 100
    seed: int = 0
    dispersions: Sequence[Dispersion] = field(default_factory=tuple)
    duration: float = 20.0
    drift: float = 0.02
    record_every: int = 10
    bus_rate: float = 0.05
    joint_rate: float = 1e-3

    def __post_init__(self) -> None:
        if not (isinstance(self.runs, int) and self.runs >= 1):
            raise CampaignError(f"runs: expected an integer >= 1, given {self.runs!r}")
        if not (self.duration > 0 and self.drift > 0 and self.record_every >= 1):
            raise CampaignError("duration, drift: expected > 0; record_every: expected >= 1; given "
                                f"{self.duration!r}, {self.drift!r}, {self.record_every!r}")
        for k, d in enumerate(self.dispersions):
            where = f"dispersion[{k}]"
            if d.parameter not in CAPTURE_PARAMETERS:
                raise CampaignError(f"{where}.parameter: expected one of {', '.join(CAPTURE_PARAMETERS)}, "
                                    f"given {d.parameter!r}")
            # the distribution's own checks (they know the slew's parameter names only)
            dataclasses.replace(d, parameter="stiffness").check(where)

    def nominal(self) -> Dict[str, np.ndarray]:
        """The nominal value of each parameter."""
        s = capture_scenario(drift=self.drift)
        return {"target_mass": np.array(s.target.mass), "target_inertia": np.diag(s.target.inertia).copy(),
                "tumble_rate": np.array(2.0), "grasp_time": np.array(s.meet)}

    def parameters(self, run: int) -> Dict[str, np.ndarray]:
        """Run ``run``'s parameters, drawn from ``default_rng([seed, run])``."""
        values = self.nominal()
        rng = np.random.default_rng([self.seed, run])
        for d in self.dispersions:
            values[d.parameter] = np.asarray(d.sample(rng, values[d.parameter]), dtype=np.float64)
        return values

    def scenario(self, run: int) -> CaptureScenario:
        """Run ``run`` as a :class:`~orbitflex.models.CaptureScenario` (raises ``ModelError`` for
        a draw that is not a physical target)."""
        p = self.parameters(run)
        s = capture_scenario(float(p["tumble_rate"]), self.drift, float(p["grasp_time"]))
        t = s.target
        target = Target(float(p["target_mass"]), p["target_inertia"], t.pose, t.twist, t.grasp, name=t.name)
        return dataclasses.replace(s, target=target, duration=self.duration)

    def trajectory(self, run: int) -> Trajectory:
        """Run ``run`` again, alone: the same rows as in the campaign."""
        s = self.scenario(run)
        return s.run(record_every=self.record_every)

    def run_chunk(self, start: int, stop: int, threads: Optional[int] = None) -> Any:
        """Runs ``start`` to ``stop`` (one batch) and returns their table rows (a DataFrame)."""
        import pandas as pd

        rows: List[Dict[str, Any]] = []
        cases: List[Tuple[int, CaptureScenario]] = []
        for run in range(start, stop):
            p = self.parameters(run)
            row: Dict[str, Any] = {"run": run}
            for name, value in p.items():
                if value.ndim == 0:
                    row[name] = float(value)
                else:
                    row.update({f"{name}[{i}]": float(v) for i, v in enumerate(value)})
            try:
                cases.append((len(rows), self.scenario(run)))
                row["ok"] = True
            except Exception:  # a non-physical draw: a row of NaN metrics
                row["ok"] = False
            rows.append(row)
        if cases:
            scenarios = [s for _, s in cases]
            s0 = scenarios[0]
            trajectories = simulate_capture_batch(
                [s.arm for s in scenarios], np.array([s.x0 for s in scenarios]), s0.dt,
                int(round(self.duration / s0.dt)), [s.controller for s in scenarios],
                [s.target for s in scenarios], s0.when, record_every=self.record_every, threads=threads)
            for (k, _), traj in zip(cases, trajectories):
                m = detumble_metrics(traj, joint_rate=self.joint_rate, bus_rate=self.bus_rate)
                rows[k]["captured"] = m["captured"]
                rows[k].update({col: float(m[key]) for col, key in _FROM_METRICS.items()})
        table = pd.DataFrame(rows)
        for col in CAPTURE_METRICS:
            if col not in table:
                table[col] = math.nan
        return table

    def run(self, runs: Optional[int] = None, scheduler: Optional[str] = None, client: Any = None,
            chunk_runs: int = 25, threads: Optional[int] = None) -> Any:
        """Runs the campaign (``runs`` overrides ``self.runs``) here, or as chunks of
        ``chunk_runs`` on the Dask cluster at ``scheduler`` (or ``client``), one thread per task;
        returns the table, one row per run, sorted by run: the same either way."""
        import pandas as pd

        total = self.runs if runs is None else runs
        chunks = [(a, min(a + chunk_runs, total)) for a in range(0, total, chunk_runs)]
        if scheduler is None and client is None:
            pieces = [self.run_chunk(a, b, threads) for a, b in chunks]
        else:
            from dask.distributed import Client

            own = client is None
            client = Client(scheduler) if own else client  # type: ignore[no-untyped-call]
            try:
                futures = [client.submit(_chunk_task, self, a, b, pure=False) for a, b in chunks]
                pieces = client.gather(futures)
            finally:
                if own:
                    client.close()
        return pd.concat(pieces, ignore_index=True).sort_values("run", ignore_index=True)


def _chunk_task(campaign: CaptureCampaign, start: int, stop: int) -> Any:
    """One chunk on a Dask worker, one thread."""
    return campaign.run_chunk(start, stop, threads=1)


__all__ = ["CaptureCampaign", "CAPTURE_PARAMETERS", "CAPTURE_METRICS"]
