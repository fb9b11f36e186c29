# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""``orbitflex campaign``: run a campaign file locally or on a Dask cluster."""

from __future__ import annotations

import argparse
import re
import time
from pathlib import Path

from .. import ModelError
from .errors import CliError
from .jobs import ProgressBar


def campaign_command(args: argparse.Namespace) -> int:
    """``orbitflex campaign FILE``: runs the campaign, writes the table, summary and plots."""
    try:
        from .. import campaign as campaigns
        import pandas  # noqa: F401
    except ImportError as e:
        raise CliError("campaign", f"needs pandas and pyarrow ({e}); pip install 'orbitflex[campaign]'") from None
    try:
        # a slew Campaign, or a CaptureCampaign when the file has a [capture] table
        campaign = campaigns.load_campaign(args.file, wheels=args.wheels)
    except FileNotFoundError as e:
        raise CliError("FILE", str(e)) from None
    except ModelError as e:
        if args.wheels is not None and ": wheels: " in str(e):
            raise CliError("--wheels", str(e).split(": wheels: ", 1)[1]) from None
        raise CliError("FILE", f"{args.file}: {e}" if not str(e).startswith(args.file) else str(e)) from None
    runs = args.runs if args.runs is not None else campaign.runs
    if args.scheduler:
        try:
            campaigns.reachable(args.scheduler, args.scheduler_timeout)
        except (ModelError, OSError) as e:  # TimeoutError is an OSError
            message = re.sub(r"^scheduler: ", "", str(e)).replace("a longer timeout", "a longer --scheduler-timeout")
            raise CliError("--scheduler", message) from None
    where = f"on the Dask cluster at {args.scheduler}" if args.scheduler else "here"
    held = "" if campaign.wheels is None else f", the bus held by {len(campaign.wheels)} reaction wheels"
    print(f"campaign {campaign.name}: {runs} runs of {campaign.duration:g} s (dt = {campaign.dt:g} s, "
          f"{campaign.steps} steps){held}, {where}")
    bar = None if args.no_progress else ProgressBar(runs, unit="run", desc="campaign")
    progress = None if bar is None else bar.to
    started = time.time()
    try:
        table = campaign.run(runs=runs, scheduler=args.scheduler, chunk_runs=args.chunk_runs,
                             threads=args.threads, progress=progress, timeout=args.scheduler_timeout)
    except ModelError as e:
        flag = "--runs" if str(e).startswith("runs:") and args.runs is not None else "FILE"
        raise CliError(flag, re.sub(r"^runs: ", "", str(e)) if flag == "--runs" else str(e)) from None
    except (OSError, TimeoutError) as e:
        if args.scheduler:
            raise CliError("--scheduler", f"cannot reach the Dask scheduler at {args.scheduler}: {e}") from None
        raise
    finally:
        if bar is not None:
            bar.close()
    seconds_taken = time.time() - started
    capture = isinstance(campaign, campaigns.CaptureCampaign)
    if capture:
        files = campaign.write_outputs(table, Path(args.out), plots=not args.no_plots)
    else:
        files = campaigns.write_outputs(table, campaign, Path(args.out), plots=not args.no_plots)
    failed = int((~table["ok"]).sum())
    print(f"{runs} runs in {seconds_taken:.1f} s, {failed} failed")
    stats = campaign.summary(table) if capture else campaigns.summary(table)
    print(f"{'metric':<22}{'unit':>6}{'p5':>12}{'p50':>12}{'p95':>12}{'max':>12}")
    for metric, row in stats.iterrows():
        cells = "".join(f"{row[c]:>12.4g}" if c in row and row[c] == row[c] else f"{'-':>12}"
                        for c in ("p5", "p50", "p95", "max"))
        print(f"{metric:<22}{row['unit']:>6}{cells}")
    print("wrote:")
    for f in files:
        print(f"  {f}")
    return 1 if failed else 0
