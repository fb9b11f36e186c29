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
capture), and with reaction wheels ``wheel_momentum`` (N·m·s, at the end),
``peak_wheel_speed_fraction``, ``peak_wheel_torque_fraction`` and ``wheels_saturated``.

With ``wheels`` (a ``ReactionWheels``) every run carries them in the bus, driven by
``attitude_pd`` (default: :func:`orbitflex.detumble.detumble_gains` of the nominal stack), as
:func:`orbitflex.models.capture_scenario` does.

A campaign file (``orbitflex campaign capture.toml``, :meth:`CaptureCampaign.from_toml`; see
``examples/capture_campaign.toml``) declares one with a ``[capture]`` table::

    name = "capture-tumble"
    runs = 100
    seed = 1

    [capture]
    duration = 60.0        # s per run
    drift = 0.02           # m/s, the approach speed
    record_every = 10
    bus_rate = 0.05        # deg/s, the detumble threshold
    joint_rate = 1e-3      # rad/s, the settle threshold
    wheels = "pyramid"     # or a wheels file (relative to this one), as capture --wheels; or leave out
    motor_pd = "stack"     # "arm" or "stack" (default: "stack" with wheels, "arm" without)

    [[dispersion]]
    parameter = "tumble_rate"
    distribution = "uniform"
    low = 0.5
    high = 4.0

``orbitflex campaign`` writes ``runs.parquet``, ``summary.csv``, ``log.jsonl`` and
``histograms.png`` as for a slew campaign, with these metrics.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import socket
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from .. import AttitudePD, ReactionWheels, Target, Trajectory, detumble_metrics, simulate_capture_batch
from ..models import CaptureScenario, capture_scenario
from .dispersion import CampaignError, Dispersion
from .execute import ChunkLog
from .files import read_campaign_toml

CAPTURE_PARAMETERS = ("target_mass", "target_inertia", "tumble_rate", "grasp_time")
CAPTURE_METRICS = ("ok", "captured", "capture_time", "energy_loss", "impulse_force", "bus_kick",
                   "peak_bus_rate", "peak_spring_torque", "peak_deflection", "settle_time",
                   "detumble_time", "wheel_momentum", "peak_wheel_speed_fraction",
                   "peak_wheel_torque_fraction", "wheels_saturated")
# the numeric metrics with their units and titles (summary.csv, histograms.png)
CAPTURE_UNITS = {"capture_time": "s", "energy_loss": "J", "impulse_force": "N·s", "bus_kick": "deg/s",
                 "peak_bus_rate": "deg/s", "peak_spring_torque": "N·m", "peak_deflection": "rad",
                 "settle_time": "s", "detumble_time": "s", "wheel_momentum": "N·m·s",
                 "peak_wheel_speed_fraction": "1", "peak_wheel_torque_fraction": "1"}
CAPTURE_TITLES = {"capture_time": "capture time", "energy_loss": "energy lost in the grasp",
                  "impulse_force": "grasp impulse |F|", "bus_kick": "bus kick |Δω_B|",
                  "peak_bus_rate": "peak bus rate after", "peak_spring_torque": "peak spring torque after",
                  "peak_deflection": "peak deflection after", "settle_time": "joints settled, after",
                  "detumble_time": "stack detumbled, after", "wheel_momentum": "wheel momentum at the end",
                  "peak_wheel_speed_fraction": "peak |Ω| / max_speed",
                  "peak_wheel_torque_fraction": "peak |u| / max_torque"}
_FROM_METRICS = {"capture_time": "capture_time", "energy_loss": "energy_loss",
                 "impulse_force": "impulse_force", "bus_kick": "bus_kick_deg_s",
                 "peak_bus_rate": "peak_bus_rate_deg_s", "peak_spring_torque": "peak_spring_torque",
                 "peak_deflection": "peak_deflection", "settle_time": "settle_time",
                 "detumble_time": "detumble_time", "wheel_momentum": "wheel_momentum_nms",
                 "peak_wheel_speed_fraction": "peak_wheel_speed_fraction",
                 "peak_wheel_torque_fraction": "peak_wheel_torque_fraction"}
CAPTURE_KEYS = ("duration", "drift", "record_every", "bus_rate", "joint_rate", "wheels", "motor_pd")


@dataclass(frozen=True)
class CaptureCampaign:
    """A capture campaign (module docs): ``runs`` runs of ``duration`` s of the built-in capture
    scenario (the target drifting in at ``drift`` m/s), one row kept in ``record_every``, with
    ``dispersions`` drawn from ``seed``; ``bus_rate`` (deg/s) and ``joint_rate`` (rad/s) are the
    thresholds of :func:`orbitflex.detumble_metrics`. ``wheels``, ``attitude_pd`` and
    ``motor_pd`` are those of :func:`orbitflex.models.capture_scenario`. ``name`` names it in
    the outputs; :attr:`log` holds where and how long each chunk ran."""

    runs: int = 100
    seed: int = 0
    dispersions: Sequence[Dispersion] = field(default_factory=tuple)
    duration: float = 20.0
    drift: float = 0.02
    record_every: int = 10
    bus_rate: float = 0.05
    joint_rate: float = 1e-3
    wheels: Optional[ReactionWheels] = None
    attitude_pd: Optional[AttitudePD] = None
    motor_pd: Optional[str] = None
    name: str = "capture"
    log: ChunkLog = field(default_factory=ChunkLog, compare=False, repr=False)

    def __post_init__(self) -> None:
        if not (isinstance(self.runs, int) and not isinstance(self.runs, bool) and self.runs >= 1):
            raise CampaignError(f"runs: expected an integer >= 1, given {self.runs!r}")
        if not (isinstance(self.seed, int) and not isinstance(self.seed, bool) and self.seed >= 0):
            raise CampaignError(f"seed: expected an integer >= 0, given {self.seed!r}")
        if not isinstance(self.name, str):
            raise CampaignError(f"name: expected a string, given {self.name!r}")
        for what in ("duration", "drift", "bus_rate", "joint_rate"):
            value = getattr(self, what)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or not value > 0:
                raise CampaignError(f"{what}: expected a finite number > 0, given {value!r}")
        if isinstance(self.record_every, bool) or not isinstance(self.record_every, int) or self.record_every < 1:
            raise CampaignError(f"record_every: expected an integer >= 1, given {self.record_every!r}")
        try:  # the scenario's own checks: wheels, attitude_pd, motor_pd
            capture_scenario(drift=self.drift, wheels=self.wheels, attitude_pd=self.attitude_pd,
                             motor_pd=self.motor_pd)
        except (TypeError, ValueError) as e:
            raise CampaignError(str(e)) from None
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
        s = self._scenario(float(p["tumble_rate"]), float(p["grasp_time"]))
        t = s.target
        target = Target(float(p["target_mass"]), p["target_inertia"], t.pose, t.twist, t.grasp, name=t.name)
        return dataclasses.replace(s, target=target, duration=self.duration)

    def _scenario(self, tumble: float = 2.0, meet: float = 5.0) -> CaptureScenario:
        """The scenario with this campaign's wheels and controllers. The gains are the nominal
        stack's for every run (a flight controller is tuned once, not per catch)."""
        attitude_pd = self.attitude_pd
        if self.wheels is not None and attitude_pd is None:
            attitude_pd = self._nominal_gains
        return capture_scenario(tumble, self.drift, meet, wheels=self.wheels, attitude_pd=attitude_pd,
                                motor_pd=self.motor_pd)

    @functools.cached_property
    def _nominal_gains(self) -> Optional[AttitudePD]:
        return self.nominal_scenario().wheel_controller

    def nominal_scenario(self) -> CaptureScenario:
        """The nominal run's scenario (no dispersion)."""
        return capture_scenario(drift=self.drift, wheels=self.wheels, attitude_pd=self.attitude_pd,
                                motor_pd=self.motor_pd)

    @property
    def dt(self) -> float:
        """The scenario's step (s)."""
        return float(self.nominal_scenario().dt)

    @property
    def steps(self) -> int:
        """Steps per run."""
        return int(round(self.duration / self.dt))

    # -- files -----------------------------------------------------------------------------------

    @classmethod
    def from_toml(cls, path: Union[str, "os.PathLike[str]"]) -> "CaptureCampaign":
        """Reads a capture campaign file (module docs; ``examples/capture_campaign.toml``)."""
        path = Path(path)
        return cls.from_dict(read_campaign_toml(path), base=path.parent, source=str(path))

    @classmethod
    def from_dict(cls, spec: Mapping[str, Any], base: Optional[Path] = None,
                  source: str = "campaign") -> "CaptureCampaign":
        """A capture campaign from the tables of a campaign file: top-level ``name``, ``runs``,
        ``seed``; ``[capture]`` and ``[[dispersion]]`` (module docs). A relative wheels file is
        taken from ``base``."""
        from ..models import pyramid_wheels
        from ..wheels_file import WheelsFileError, read_wheels

        known = {"name", "runs", "seed", "capture", "dispersion"}
        for key in spec:
            if key not in known:
                raise CampaignError(f"{source}: unknown key {key!r} in a capture campaign; expected "
                                    f"{', '.join(sorted(known))}")
        table = spec.get("capture", {})
        if not isinstance(table, Mapping):
            raise CampaignError(f"{source}: [capture]: expected a table, given {table!r}")
        for key in table:
            if key not in CAPTURE_KEYS:
                raise CampaignError(f"{source}: [capture] {key!r} is not a known key; expected "
                                    f"{', '.join(CAPTURE_KEYS)}")
        fields: Dict[str, Any] = {k: table[k] for k in CAPTURE_KEYS if k in table and k != "wheels"}
        wheels = table.get("wheels")
        if wheels is not None:
            if not isinstance(wheels, str):
                raise CampaignError(f"{source}: [capture] wheels: expected \"pyramid\" or a wheels file "
                                    f"path, given {wheels!r}")
            if wheels == "pyramid":
                fields["wheels"] = pyramid_wheels()
            else:
                file = Path(wheels)
                file = file if file.is_absolute() or base is None else base / file
                try:
                    w = read_wheels(file)
                except WheelsFileError as e:
                    raise CampaignError(f"{source}: [capture] wheels: {e}") from None
                fields.update(wheels=w.wheels, attitude_pd=w.controller())
        declared = spec.get("dispersion", [])
        if not isinstance(declared, list):
            raise CampaignError(f"{source}: dispersion: expected tables ([[dispersion]]), given {declared!r}")
        dispersions = []
        names = {"parameter", "distribution", "std", "relative", "sigma", "low", "high", "per_joint"}
        for k, d in enumerate(declared):
            if not isinstance(d, Mapping):
                raise CampaignError(f"{source}: dispersion[{k}]: expected a table ([[dispersion]]), given {d!r}")
            for key in d:
                if key not in names:
                    raise CampaignError(f"{source}: dispersion[{k}]: {key!r} is not a known key; expected "
                                        f"{', '.join(sorted(names))}")
            if "parameter" not in d:
                raise CampaignError(f"{source}: dispersion[{k}]: parameter is required")
            dispersions.append(Dispersion(**d))
        try:
            return cls(runs=spec.get("runs", 100), seed=spec.get("seed", 0), name=spec.get("name", "capture"),
                       dispersions=tuple(dispersions), **fields)
        except CampaignError as e:
            raise CampaignError(f"{source}: {e}") from None

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
                [s.target for s in scenarios], s0.when, record_every=self.record_every, threads=threads,
                wheel_torque=None if s0.wheel_controller is None else [
                    s.wheel_controller for s in scenarios if s.wheel_controller is not None])
            for (k, _), traj in zip(cases, trajectories):
                m = detumble_metrics(traj, joint_rate=self.joint_rate, bus_rate=self.bus_rate)
                rows[k]["captured"] = m["captured"]
                rows[k]["wheels_saturated"] = m["wheels_saturated"]
                rows[k].update({col: float(m[key]) for col, key in _FROM_METRICS.items()})
        table = pd.DataFrame(rows)
        for col in CAPTURE_METRICS:
            if col not in table:
                table[col] = math.nan
        return table

    def run(self, runs: Optional[int] = None, scheduler: Optional[str] = None, client: Any = None,
            chunk_runs: Optional[int] = 25, threads: Optional[int] = None,
            progress: Optional[Callable[[int, int], Any]] = None, timeout: float = 10.0) -> Any:
        """Runs the campaign (``runs`` overrides ``self.runs``) here, or as chunks of
        ``chunk_runs`` (None: 25) on the Dask cluster at ``scheduler`` (or ``client``; ``timeout`` s to
        connect), one thread per task; returns the table, one row per run, sorted by run: the
        same either way. ``progress(done, runs)`` is called as chunks finish; :attr:`log`
        records where and how long each ran."""
        import pandas as pd

        total = self.runs if runs is None else runs
        if isinstance(total, bool) or not isinstance(total, int) or total < 1:
            raise CampaignError(f"runs: expected an integer >= 1, given {total!r}")
        chunk_runs = 25 if chunk_runs is None else chunk_runs
        if isinstance(chunk_runs, bool) or not isinstance(chunk_runs, int) or chunk_runs < 1:
            raise CampaignError(f"chunk_runs: expected an integer >= 1, given {chunk_runs!r}")
        chunks = [(a, min(a + chunk_runs, total)) for a in range(0, total, chunk_runs)]
        object.__setattr__(self, "log", ChunkLog())
        pieces: List[Any] = []
        done = 0

        def finished(piece: Any, entry: Dict[str, Any]) -> None:
            nonlocal done
            pieces.append(piece)
            self.log.append(entry)
            done += int(entry["stop"] - entry["start"])
            if progress is not None:
                progress(done, total)

        if scheduler is None and client is None:
            for a, b in chunks:
                finished(*_timed_chunk(self, a, b, threads))
        else:
            from dask.distributed import Client, as_completed

            own = client is None
            client = Client(scheduler, timeout=timeout) if own else client  # type: ignore[no-untyped-call]
            try:
                futures = [client.submit(_chunk_task, self, a, b, pure=False) for a, b in chunks]
                for future in as_completed(futures):  # type: ignore[no-untyped-call]
                    finished(*future.result())
            finally:
                if own:
                    client.close()
        return pd.concat(pieces, ignore_index=True).sort_values("run", ignore_index=True)

    # -- outputs ---------------------------------------------------------------------------------

    def summary(self, table: Any) -> Any:
        """Percentiles of each numeric metric over the captured runs: count, mean, std, min, p5,
        p50, p95, p99, max, one row per metric with its unit."""
        import pandas as pd

        finished = table[table["ok"].astype(bool) & table["captured"].fillna(False).astype(bool)]
        rows = []
        for metric, unit in CAPTURE_UNITS.items():
            v = finished[metric].to_numpy(dtype=np.float64)
            v = v[np.isfinite(v)]
            stats: Dict[str, Any] = {"metric": metric, "unit": unit, "count": int(v.size)}
            if v.size:
                stats.update(mean=float(v.mean()), std=float(v.std(ddof=1)) if v.size > 1 else 0.0,
                             min=float(v.min()))
                for p in (5, 50, 95, 99):
                    stats[f"p{p}"] = float(np.percentile(v, p))
                stats["max"] = float(v.max())
            rows.append(stats)
        return pd.DataFrame(rows).set_index("metric")

    def write_outputs(self, table: Any, out: Union[str, "os.PathLike[str]"], plots: bool = True) -> List[Path]:
        """Writes ``runs.parquet``, ``summary.csv`` (:meth:`summary`), ``log.jsonl`` and, with
        ``plots``, ``histograms.png`` into ``out`` (created if missing), as a slew campaign does.
        Returns the files written."""
        import json

        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        files = [out / "runs.parquet", out / "summary.csv", out / "log.jsonl"]
        table.to_parquet(files[0], index=False)
        self.summary(table).to_csv(files[1])
        with open(files[2], "w") as log:
            for entry in sorted(self.log, key=lambda e: e["start"]):
                log.write(json.dumps(entry) + "\n")
        if plots:
            files.append(self.histograms(table, out / "histograms.png"))
        return files

    def histograms(self, table: Any, path: Path) -> Path:
        """One histogram per metric over the captured runs (p50 and p95 marked), the campaign's
        name, model, dt, duration and seed in the caption."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        finished = table[table["ok"].astype(bool) & table["captured"].fillna(False).astype(bool)]
        metrics = [m for m in CAPTURE_UNITS if self.wheels is not None or "wheel" not in m]
        cols = 3
        rows = (len(metrics) + cols - 1) // cols
        fig, axes = plt.subplots(rows, cols, figsize=(11, 2.9 * rows + 0.8), layout="constrained")
        wheels = "" if self.wheels is None else f" + {len(self.wheels.mass)} reaction wheels"
        caption = (f"campaign {self.name}: {len(table)} runs ({len(table) - len(finished)} not captured or "
                   f"failed), seed {self.seed}\nmodel space_arm{wheels} + target, dt = {self.dt:g} s, "
                   f"{self.duration:g} s each")
        fig.suptitle(f"Capture metrics over the runs that captured\n{caption}", fontsize=11)
        for ax, metric in zip(axes.flat, metrics):
            values = finished[metric].to_numpy(dtype=np.float64)
            values = values[np.isfinite(values)]
            if values.size:
                ax.hist(values, bins=min(40, max(5, int(np.sqrt(values.size)) * 2)), color="#4477aa")
                for p, style in ((50, "-"), (95, "--")):
                    ax.axvline(np.percentile(values, p), color="#cc3311", ls=style, lw=1, label=f"p{p}")
                ax.legend(fontsize=8)
            if metric.endswith("_fraction"):
                ax.axvline(1.0, color="black", ls=":", lw=1, label="limit")
                ax.legend(fontsize=8)
            missing = len(finished) - values.size
            ax.set_title(CAPTURE_TITLES[metric] + (f" ({missing} undefined)" if missing else ""), fontsize=10)
            ax.set_xlabel(CAPTURE_UNITS[metric] if CAPTURE_UNITS[metric] != "1" else "fraction of the limit")
            ax.set_ylabel("runs")
        for ax in list(axes.flat)[len(metrics):]:
            ax.set_visible(False)
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return path


def load_campaign(path: Union[str, "os.PathLike[str]"], wheels: Any = None) -> Any:
    """Reads a campaign file: a :class:`CaptureCampaign` if it has a ``[capture]`` table, else a
    slew :class:`~orbitflex.campaign.Campaign` (``Campaign.from_toml``). ``wheels``, a wheels
    file's path (``orbitflex campaign --wheels``), replaces the file's own: ``[capture] wheels``
    for a capture campaign, ``wheels`` for a slew campaign (where a ``WheelsFile`` is also
    accepted)."""
    from .spec import Campaign

    path = Path(path)
    spec = read_campaign_toml(path)
    if "capture" in spec:
        if wheels is not None:
            if not isinstance(wheels, (str, os.PathLike)):
                raise CampaignError(f"{path}: wheels: expected a wheels file's path for a capture campaign, "
                                    f"given {wheels!r}")
            table = spec["capture"]
            if not isinstance(table, dict):
                raise CampaignError(f"{path}: [capture]: expected a table, given {table!r}")
            given = Path(wheels)
            named = "pyramid" if str(wheels) == "pyramid" else str(given if given.is_absolute() else given.resolve())
            spec = {**spec, "capture": {**table, "wheels": named}}
        return CaptureCampaign.from_dict(spec, base=path.parent, source=str(path))
    return Campaign.from_dict(spec, base=path.parent, source=str(path), wheels=wheels)


def _timed_chunk(campaign: CaptureCampaign, start: int, stop: int, threads: Optional[int]) -> Tuple[Any, Dict[str, Any]]:
    began = time.perf_counter()
    piece = campaign.run_chunk(start, stop, threads)
    entry = {"start": start, "stop": stop, "seconds": time.perf_counter() - began,
             "host": socket.gethostname(), "pid": os.getpid()}
    return piece, entry


def _chunk_task(campaign: CaptureCampaign, start: int, stop: int) -> Tuple[Any, Dict[str, Any]]:
    """One chunk on a Dask worker, one thread, with where and how long it ran."""
    piece, entry = _timed_chunk(campaign, start, stop, 1)
    try:
        from dask.distributed import get_worker

        entry["worker"] = get_worker().address
    except (ImportError, ValueError):  # pragma: no cover - not on a worker
        pass
    return piece, entry


__all__ = ["CaptureCampaign", "CAPTURE_PARAMETERS", "CAPTURE_METRICS", "CAPTURE_UNITS", "load_campaign"]
