# mypy: disable-error-code="import-not-found,import-untyped,unused-ignore", no-implicit-reexport
# (pandas, Dask and their stubs come with orbitflex[campaign]: a base install type-checks clean)
"""Running the chunks of a campaign: the per-run table, the memory check, the log of chunks
(:class:`ChunkLog`), the reachability of a Dask scheduler and the task a worker runs."""

from __future__ import annotations

import array
import os
import re
import socket
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, TYPE_CHECKING, Tuple

import numpy as np

from .. import FlexibleArm, available_memory
from .dispersion import CampaignError

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd
    from .dispersion import Array
    from .spec import Campaign


class _Table:
    """A campaign's table, filled in place as chunks come (in any order): one array per column,
    ``runs`` rows, row ``i`` for run ``i``."""

    def __init__(self, runs: int) -> None:
        self.runs = runs
        self.columns: Dict[str, Any] = {}

    def add(self, piece: "pd.DataFrame") -> None:
        rows = piece["run"].to_numpy()
        if not self.columns:
            row = 0
            for name in piece.columns:
                row += piece[name].to_numpy().itemsize
            need = self.runs * row
            free = available_memory()
            if free is not None and need > free:
                raise CampaignError(f"runs: the table of {self.runs} runs needs {need / 1e9:.3g} GB, more than the "
                                    f"{free / 1e9:.3g} GB of memory free; run fewer runs at a time")
            self.columns = {name: np.empty(self.runs, dtype=piece[name].dtype) for name in piece.columns}
        for name, column in self.columns.items():
            column[rows] = piece[name].to_numpy()

    def frame(self) -> "pd.DataFrame":
        import pandas as pd

        return pd.DataFrame(self.columns, copy=False)


class ChunkLog(Sequence[Dict[str, Any]]):
    """Where and how long each chunk of a campaign ran (:attr:`Campaign.log`): a sequence of
    dicts ``{"start", "stop", "worker", "host", "seconds"}`` (and ``"pid"`` on Dask), in the order
    the chunks finished. Kept as arrays, 28 bytes per chunk (the places a chunk ran at are few and
    kept once), so that a campaign of a million one-run chunks does not hold a million dicts."""

    def __init__(self) -> None:
        self._start = array.array("q")
        self._stop = array.array("q")
        self._seconds = array.array("d")
        self._place = array.array("I")
        self._places: List[Tuple[Tuple[str, Any], ...]] = []
        self._index: Dict[Tuple[Tuple[str, Any], ...], int] = {}

    def append(self, entry: Mapping[str, Any]) -> None:
        place = tuple(sorted((k, v) for k, v in entry.items() if k not in ("start", "stop", "seconds")))
        if place not in self._index:
            self._index[place] = len(self._places)
            self._places.append(place)
        self._start.append(int(entry["start"]))
        self._stop.append(int(entry["stop"]))
        self._seconds.append(float(entry["seconds"]))
        self._place.append(self._index[place])

    def __len__(self) -> int:
        return len(self._start)

    def _entry(self, k: int) -> Dict[str, Any]:
        entry: Dict[str, Any] = {"start": self._start[k], "stop": self._stop[k]}
        entry.update(self._places[self._place[k]])
        entry["seconds"] = self._seconds[k]
        return entry

    def __getitem__(self, k: Any) -> Any:
        if isinstance(k, slice):
            return [self._entry(i) for i in range(*k.indices(len(self)))]
        if k < 0:
            k += len(self)
        if not 0 <= k < len(self):
            raise IndexError("chunk log index out of range")
        return self._entry(k)

    def __repr__(self) -> str:
        return f"ChunkLog({len(self)} chunks)"


def reachable(address: str, timeout: float) -> None:
    """Checks that a Dask scheduler answers at ``address`` (``tcp://host:port``, or
    ``host:port``) within ``timeout`` seconds, so that a refused connection fails at once rather
    than after Dask's retries, and a server that is not a Dask scheduler (a web server, say,
    which Dask's client would wait for forever, or whose bytes it would take for a frame size)
    fails clearly. A scheduler greets each connection with a message whose first eight bytes
    count its frames. A malformed address is a :class:`CampaignError`; a refused connection or
    another kind of server an ``OSError``; no answer a ``TimeoutError``. Other protocols
    (``tls://``, ``ucx://``, ``inproc://``) are left to Dask."""
    text = address if "://" in address else "tcp://" + address
    scheme, _, location = text.partition("://")
    if scheme != "tcp":
        return
    host, colon, port = location.rpartition(":")
    host = host.strip("[]")
    if not colon or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise CampaignError(f"scheduler: expected an address like tcp://host:8786, given {address!r}")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout) as connection:
            greeting = connection.recv(8, socket.MSG_WAITALL)
    except socket.timeout:
        raise TimeoutError(f"cannot reach the Dask scheduler at {address}: no answer within {timeout:g} s (for a "
                           "slow cluster, give a longer timeout)") from None
    except OSError as e:
        raise OSError(f"cannot reach the Dask scheduler at {address}: {e.strerror or e}") from None
    frames = int.from_bytes(greeting, "little") if len(greeting) == 8 else 0
    if not 0 < frames < 1000:
        raise OSError(f"cannot reach the Dask scheduler at {address}: the server there accepts connections "
                      "but does not answer as a Dask scheduler")


def _campaign_numbers(message: str, start: int) -> str:
    """A batch's stability warning for a chunk that starts at run ``start``, its runs named as
    the campaign numbers them (the batch counts from 0)."""
    def shift(m: "re.Match[str]") -> str:
        return ", ".join(str(int(i) + start) if i.strip().isdigit() else i.strip() for i in m.group(1).split(","))

    message = message.replace(" of the run (", f" of run {start} (", 1)
    message = re.sub(r"(?<= of run )(\d+) of \d+(?= \()", lambda m: str(int(m.group(1)) + start), message, count=1)
    message = re.sub(r"(?<=\(runs )([\d, …]+)(?=;)", shift, message, count=1)
    return re.sub(r" of (all \d+|\d+ of \d+) runs \(", r" of \1 runs of this chunk (", message, count=1)


def _offset(progress: Callable[[int, int], Any], start: int, total: int) -> Callable[[int, int], Any]:
    """A batch's ``progress(done, runs)`` as the campaign's, for a chunk from run ``start``."""
    return lambda done, _runs: progress(start + done, total)


def _ee_positions(arm: FlexibleArm, x: Array) -> Array:
    """Every end-effector's position (m, inertial frame) at state ``x``, (k, 3)."""
    return np.stack([np.asarray(arm.ee_pose(x, ee=e)[:3]) for e in range(len(arm.robot.ee_links))])


def _run_chunk_task(campaign: Campaign, start: int, stop: int, nominal_ee: Array,
                    threads: int) -> Tuple[Any, Dict[str, Any]]:
    """A Dask task: one chunk of runs, with where and how long it ran."""
    began = time.time()
    piece = campaign.run_chunk(start, stop, nominal_ee, threads)
    try:
        from dask.distributed import get_worker

        worker = get_worker().address
    except (ImportError, ValueError):  # pragma: no cover
        worker = "?"
    return piece, {"start": start, "stop": stop, "worker": worker, "host": socket.gethostname(),
                   "pid": os.getpid(), "seconds": time.time() - began}
