"""The analytic engine over Dask workers: CLs in chunks, in any order, results in program order.

The workpiece before CL k follows from the path alone (the stock less the sweeps of CLs 0..k-1,
:mod:`.engine`), so a chunk of CLs ``[a, b)`` is computed by any worker that knows the toolpath:
it indexes the sweeps of the CLs before ``a`` and steps through the chunk. Nothing but the chunk's
bounds goes out and its :class:`~fusioncut.model.engagement.EngagementMap` rows come back; the
toolpath is sent to every worker once.

* **Identical results.** A worker's engine sees the same sweeps, indexed in the same order, as the
  single-process engine at every CL, so the maps are the same, bit for bit (tested).
* **Worker state.** Each worker thread keeps its engine and its place in the CL sequence between chunks
  (:func:`_compute_chunk`); chunks are handed out in program order, so a worker's next chunk lies
  ahead of its last one and it only indexes the CLs in between. A chunk behind its place, or of
  another run, starts a fresh engine.
* **The driver** keeps the run's state as the single-process engine does (the sweeps of the CLs
  handed out, the removed total), so a checkpoint, a resume and ``ipw_volume`` are
  :class:`~.engine.AnalyticEngine`'s own: a checkpoint of a parallel run resumes in one process and
  the other way round. At most ``ahead`` chunks per worker are in flight.
* **Serial fraction.** The driver's own work (listing the CLs, indexing each CL handed out, and
  what the caller does with each map before it asks for the next) is timed against the run's wall
  time: ``serial_fraction`` after a run, the share of
  the work Amdahl's law leaves to one process (the speed-up on N workers is at most
  ``1 / (s + (1 - s) / N)``).
"""
from __future__ import annotations

import itertools
import logging
import threading
import time
import uuid
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.base import EngineKind, EngineOptions
from fusioncut.engines.cl_maps import CL
from fusioncut.engines.dask_cluster import close_quietly, open_client
from fusioncut.model.engagement import EngagementMap
from fusioncut.model.moves import Toolpath
from fusioncut.model.stock import Stock
from fusioncut.model.tools import MillingTool

log = logging.getLogger("fusioncut.parallel")


@dataclass
class _WorkerState:
    """A worker's engine for one run, its CL sequence and the first CL it has not passed."""

    run: str
    engine: AnalyticEngine
    cls: Iterator[CL]
    next_cl: int = 0


# per worker thread (a scheduler's workers may run several): the latest run's state; an engine is
# not shared between threads
_STATE: dict[int, _WorkerState] = {}


def _compute_chunk(run: str, toolpath: Toolpath, stock: Stock, options: EngineOptions,
                   default_tool: MillingTool | None, start: int, stop: int) -> list[EngagementMap]:
    """The maps of CLs ``[start, stop)`` (runs on a worker; see the module docstring)."""
    thread = threading.get_ident()
    state = _STATE.get(thread)
    if state is None or state.run != run or state.next_cl > start:
        engine = AnalyticEngine(options)
        engine.start(stock)
        state = _WorkerState(run, engine, engine.cl_sequence(toolpath, default_tool))
        _STATE[thread] = state
    maps = []
    for cl in state.cls:
        state.next_cl = cl.index + 1
        if cl.index < start:
            state.engine.index_only(cl)
            continue
        maps.append(state.engine.step(cl))
        if cl.index + 1 >= stop:
            break
    return maps


@dataclass
class ParallelAnalyticEngine:
    """:class:`~.engine.AnalyticEngine` with its CLs computed on Dask workers, in chunks of at most
    ``chunk`` CLs and at least 16 chunks per worker (see the module docstring). Use as a context
    manager, or call :meth:`open` and :meth:`close`."""

    options: EngineOptions = field(default_factory=EngineOptions)
    workers: int = 2
    scheduler: str | None = None
    chunk: int = 32
    ahead: int = 3  # chunks in flight per worker
    serial_fraction: float | None = None
    _local: AnalyticEngine = field(init=False, repr=False)
    _client: Any = field(default=None, init=False, repr=False)
    _cluster: Any = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.chunk < 1 or self.ahead < 1:
            raise ValueError(f"chunk and ahead must be at least 1 (got {self.chunk} and {self.ahead})")
        self._local = AnalyticEngine(self.options)

    def __enter__(self) -> ParallelAnalyticEngine:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def open(self) -> None:
        if self._client is None:
            self._client, self._cluster = open_client(self.workers, self.scheduler)

    def close(self) -> None:
        client, cluster = self._client, self._cluster
        self._client = self._cluster = None
        close_quietly(client, cluster)

    # -- the Engine protocol: the state is the local engine's ---------------------------------------
    @property
    def kind(self) -> EngineKind:
        return EngineKind.ANALYTIC

    @property
    def shares_cells(self) -> bool:
        return False

    @property
    def stock_volume(self) -> float:
        return self._local.stock_volume

    @property
    def removed_total(self) -> float:
        return self._local.removed_total

    @property
    def ipw(self) -> None:
        return None

    @property
    def ipw_volume(self) -> float:
        return self._local.ipw_volume

    def material_volume(self, box: tuple[float, float, float, float] | None = None) -> float:
        """:meth:`AnalyticEngine.material_volume` of the local engine, which indexes every CL the workers did."""
        return self._local.material_volume(box)

    def ipw_mesh(self, step: float | None = None) -> Any:
        """:meth:`AnalyticEngine.ipw_mesh` of the local engine, which indexes every CL the workers did."""
        return self._local.ipw_mesh(step)

    def start(self, stock: Stock) -> None:
        self._local.options = self.options
        self._local.start(stock)

    def save_checkpoint(self, folder: Path, next_cl: int) -> None:
        self._local.save_checkpoint(folder, next_cl)

    def load_checkpoint(self, folder: Path) -> int | None:
        self._local.options = self.options
        return self._local.load_checkpoint(folder)

    def check_tools(self, toolpath: Toolpath, default_tool: MillingTool | None = None) -> None:
        self._local.check_tools(toolpath, default_tool)

    def run(self, toolpath: Toolpath, stock: Stock, default_tool: MillingTool | None = None) -> Iterator[EngagementMap]:
        self.start(stock)
        yield from self.process(toolpath, default_tool)

    def process(self, toolpath: Toolpath, default_tool: MillingTool | None = None,
                start_at: int = 0, stop_at: int | None = None) -> Iterator[EngagementMap]:
        """One map per CL segment from ``start_at`` on (up to ``stop_at``, excluded, when given), in
        order, computed on the workers."""
        self.open()
        t_run = time.perf_counter()
        serial = 0.0
        t = time.perf_counter()
        cls = list(self._local.cl_sequence(toolpath, default_tool))
        for cl in cls[:start_at]:
            self._local.index_only(cl)
        if start_at < len(cls):
            self._local.check_saved_sweeps(toolpath)
        client = self._client
        n_workers = max(1, len(client.scheduler_info()["workers"]))
        run = uuid.uuid4().hex
        # a key of its own (hash=False): dask's default key is a token of the whole toolpath, which walks
        # every move in the driver
        shared = client.scatter(toolpath, broadcast=True, hash=False)
        stock = self._local.stock_model()  # the workers start from the run's stock, as the local engine did
        # chunks of at most ``chunk`` CLs, and at least 16 per worker, so that the last ones to finish
        # leave a worker idle only briefly
        stop = len(cls) if stop_at is None else min(stop_at, len(cls))
        size = max(1, min(self.chunk, (stop - start_at) // (16 * n_workers)))
        bounds = iter((a, min(a + size, stop)) for a in range(start_at, stop, size))
        pending: deque = deque()
        done = 0

        def submit() -> None:
            for a, b in itertools.islice(bounds, n_workers * self.ahead - len(pending)):
                pending.append(client.submit(_compute_chunk, run, shared, stock, self.options, default_tool,
                                             a, b, pure=False))

        serial += time.perf_counter() - t
        try:
            submit()
            while pending:
                maps = pending.popleft().result()
                t = time.perf_counter()
                submit()
                serial += time.perf_counter() - t
                for m in maps:
                    t = time.perf_counter()
                    self._local.record(cls[m.cl_index], m)
                    done += 1
                    yield m  # what the caller does with the map (writing it) is serial work too
                    serial += time.perf_counter() - t
        finally:
            for f in pending:
                f.cancel()
            wall = time.perf_counter() - t_run
            self.serial_fraction = serial / wall if wall > 0 else None
            log.info("analytic engine on %d workers: %d CLs in %.1f s, serial fraction %.3f", n_workers,
                     done, wall, self.serial_fraction or 0.0)

    def run_on_workers(self, fn: Any) -> dict[str, Any]:
        """``fn()`` on every worker (e.g. to load the kernels before a timed run); results by worker."""
        self.open()
        return self._client.run(fn)
