# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
# (pandas, Dask and their stubs come with orbitflex[campaign]: a base install type-checks clean)
"""The outputs of a campaign: the percentile summary, the files and the histograms."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Dict, List, TYPE_CHECKING, Union

import numpy as np

from .dispersion import METRICS, TITLES
from .wheels import WHEEL_METRICS, WHEEL_TITLES

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd
    from .spec import Campaign


def metrics_of(table: "pd.DataFrame") -> Dict[str, str]:
    """The metrics of ``table`` and their units: the arm's, and the wheels' when it has them."""
    return {**METRICS, **{m: u for m, u in WHEEL_METRICS.items() if m in table}}


def summary(table: "pd.DataFrame") -> "pd.DataFrame":
    """Percentiles of each metric over the runs that finished: count, mean, std, min, p5, p50,
    p95, p99, max, one row per metric, with its unit."""
    import pandas as pd

    finished = table[table["ok"]]
    rows = []
    for metric, unit in metrics_of(table).items():
        v = finished[metric].to_numpy(dtype=np.float64)
        v = v[np.isfinite(v)]
        stats: Dict[str, Any] = {"metric": metric, "unit": unit, "count": int(v.size)}
        if v.size:
            stats.update(mean=float(v.mean()), std=float(v.std(ddof=1)) if v.size > 1 else 0.0, min=float(v.min()))
            for p in (5, 50, 95, 99):
                stats[f"p{p}"] = float(np.percentile(v, p))
            stats["max"] = float(v.max())
        rows.append(stats)
    return pd.DataFrame(rows).set_index("metric")


def write_outputs(table: "pd.DataFrame", campaign: Campaign, out: Union[str, "os.PathLike[str]"],
                  plots: bool = True) -> List[Path]:
    """Writes ``runs.parquet`` (the table), ``summary.csv`` (:func:`summary`), ``log.jsonl``
    (where and how long each chunk ran) and, with ``plots``, ``histograms.png`` (one panel per
    metric) into the folder ``out``, created if missing. Returns the files written."""
    import json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = [out / "runs.parquet", out / "summary.csv", out / "log.jsonl"]
    table.to_parquet(files[0], index=False)
    summary(table).to_csv(files[1])
    with open(files[2], "w") as log:
        for entry in sorted(campaign.log, key=lambda e: e["start"]):
            log.write(json.dumps(entry) + "\n")
    if plots:
        files.append(histograms(table, campaign, out / "histograms.png"))
    return files


def histograms(table: "pd.DataFrame", campaign: Campaign, path: Path) -> Path:
    """One histogram per metric over the runs that finished, with its unit, the campaign's name,
    model, dt and number of runs in the caption."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    finished = table[table["ok"]]
    failed = int((~table["ok"]).sum())
    robot = campaign._robot()
    metrics = metrics_of(table)
    panels = (len(metrics) + 2) // 3
    fig, axes = plt.subplots(panels, 3, figsize=(11, 3.25 * panels), layout="constrained")
    caption = (f"campaign {campaign.name}: {len(table)} runs ({failed} failed), model {robot.name}, "
               f"dt = {campaign.dt:g} s, {campaign.duration:g} s each, seed {campaign.seed}")
    fig.suptitle(f"Metrics over the runs that finished\n{caption}", fontsize=11)
    for ax, (metric, unit) in zip(axes.flat, metrics.items()):
        values = finished[metric].to_numpy(dtype=np.float64)
        values = values[np.isfinite(values)]
        if values.size:
            ax.hist(values, bins=min(40, max(5, int(np.sqrt(values.size)) * 2)), color="#4477aa")
            for p, style in ((50, "-"), (95, "--")):
                ax.axvline(np.percentile(values, p), color="#cc3311", ls=style, lw=1, label=f"p{p}")
            if metric in WHEEL_METRICS and unit == "1":  # a fraction of the wheels' limit
                ax.axvline(1.0, color="black", ls=":", lw=1.5, label="limit")
            ax.legend(fontsize=8)
        missing = len(finished) - values.size
        title = {**TITLES, **WHEEL_TITLES}[metric] + (f" ({missing} undefined)" if missing else "")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("fraction of the limit" if metric in WHEEL_METRICS and unit == "1" else unit)
        ax.set_ylabel("runs")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
