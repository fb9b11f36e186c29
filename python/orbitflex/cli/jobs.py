# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
"""What a command runs (``Job``), what came out (``Outcome``), the progress bar and the one-line
warnings."""

from __future__ import annotations

import sys
import warnings
from dataclasses import dataclass
from typing import Any, Optional, TYPE_CHECKING, TextIO, Type, Union

from .. import FlexibleArm, SimulationError, Trajectory
from .errors import cli_words

if TYPE_CHECKING:
    from .slew import Array


@dataclass
class Job:
    """What to simulate: the arm, its slew (rad per joint) and how to draw its bus."""

    arm: FlexibleArm
    name: str
    slew: Array
    bus_side: float  # m, edge of the cube drawn for the bus in ee_path.png
    bus_com: Array  # m, base frame: the cube's centre
    note: Optional[str] = None  # printed under the header
    compare_plans: bool = False  # also plan the demo's slew and compare it with its rigid-joint plan


@dataclass
class Outcome:
    traj: Trajectory
    elapsed: float  # s of wall time
    failure: Optional[SimulationError] = None
    warnings: int = 0  # how many warnings simulate emitted (dt past the RK4 stability limit)
    record_every: int = 1  # the run kept rows 0, k, 2k, ... and the final row
    onset: Optional[int] = None  # a diverged run: the last row before the divergence set in

    def steps_done(self, steps: int) -> int:
        """Steps completed: all ``steps``, or those before the failure."""
        return steps if self.failure is None else self.failure.step

    def meaningful(self) -> Trajectory:
        """The rows the summary and the plots describe: every row, or for a diverged run those
        up to the onset of the divergence (the files keep every finite row)."""
        if self.onset is None or self.onset == len(self.traj.t) - 1:
            return self.traj
        k = self.onset
        return Trajectory(self.traj.arm, self.traj.t[: k + 1], self.traj.x[: k + 1], self.traj.u[:k])


class ProgressBar:
    """A tqdm bar driven by ``simulate``'s ``progress(done, total)`` callback, opened at the
    first call (after any warning ``simulate`` prints before it starts)."""

    def __init__(self, total: int, unit: str = "step", desc: str = "simulating"):
        self.total = total
        self.unit, self.desc = unit, desc
        self.bar: Any = None

    def to(self, done: int, total: int) -> None:
        if self.bar is None:
            try:
                from tqdm import tqdm
            except ImportError:  # tqdm is a dependency, but keep the simulator usable without it
                return
            self.bar = tqdm(total=self.total, unit=self.unit, desc=self.desc, file=sys.stderr,
                            mininterval=0.25)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


class WarningPrinter:
    """Prints the library's warnings as one line ``orbitflex: warning: ...`` and counts them
    (a ``warnings.showwarning`` replacement)."""

    def __init__(self) -> None:
        self.count = 0

    def __call__(self, message: Union[Warning, str], category: Type[Warning], filename: str,
                 lineno: int, file: Optional[TextIO] = None, line: Optional[str] = None) -> None:
        self.count += 1
        sys.stdout.flush()
        print(f"orbitflex: warning: {cli_words(str(message))}", file=sys.stderr)


def failure_reason(e: SimulationError) -> str:
    """``step N (t = T s): why``, from the library's message."""
    reason = str(e).split("): ", 1)[-1]
    return f"step {e.step} (t = {e.time:.6g} s): {cli_words(reason)}"
