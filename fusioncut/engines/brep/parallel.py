"""Parallel cells: the IPW's cells split among Dask workers, one CL sequence, merged results.

Cells are independent between the CLs they share, so each worker owns some of the cells, dealt out
in turn so that neighbours belong to different workers (a Dask *actor* that keeps its B-Rep shapes
in its own process), and runs every CL of the program against them; CLs whose sweep misses its
cells cost one bounding-box test. Per CL only floats cross process boundaries. A CL is done in two
phases per batch of CLs:

1. every worker cuts the batch on its cells and reports removed volume, contact areas and the flute
   contact's height range (keeping its contact faces);
2. the driver takes the union of the height ranges, fixes the slice heights exactly as the
   single-process engine would, and asks each worker for the machine arcs of its contact faces at
   those heights; arcs split at a partition's wall are joined again by ``merge_arcs``.

Workers do not wait for each other: each has one call in flight, which slices a batch the driver
has merged and cuts its own next batch, up to ``ahead`` batches beyond the one being handed out.

The per-cell Booleans are the same operations on the same shapes as in one process, so the results
equal the single-process engine's (sums may differ in the last bit by their order). One difference:
when a Boolean fails on one worker's cells the others have already cut theirs; the CL is reported
FAILED with the volume that was removed, so volume still adds up.

The engine implements :class:`~fusioncut.engines.base.Engine` as :class:`BRepEngine` does, with
checkpoints in the same files (so a checkpoint of either engine resumes in the other). Shapes cross
processes as binary BRep bytes, only when the workers are seeded and when the driver asks for the
workpiece. Workers run batches ahead of the CLs the driver has handed out, so they keep the
state of their cells after every CL of the batches since the one being handed out: a checkpoint,
snapshot or Ctrl-C in the middle of a batch gets the workpiece as it was after the last CL handed
out, never a later one.

Dask distributed runs an embedded ``LocalCluster`` (worker processes, one thread each) unless a
scheduler address is given; then the cells are split among all of that scheduler's workers.
"""
from __future__ import annotations

import asyncio
import io
import logging
import os
import time
from collections import Counter, deque
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from OCP.BinTools import BinTools
from OCP.TopoDS import TopoDS_Shape

from fusioncut.engines.base import EngineKind, EngineOptions
from fusioncut.engines.dask_cluster import close_quietly, open_client
from fusioncut.engines.brep.cells import Cell, Square
from fusioncut.engines.brep.contact import merge_arcs, slice_intervals
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.brep.occ import children, compound, volume
from fusioncut.engines.cl_maps import CL, CutOutcome, SliceHeight, cl_sequence, engagement_map, slice_heights
from fusioncut.errors import EngineStateError
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.moves import Toolpath
from fusioncut.model.stock import Stock
from fusioncut.model.tools import MillingTool

log = logging.getLogger("fusioncut.parallel")



# -- cells as bytes ---------------------------------------------------------------------------------


def pack_cells(cells: list[Cell]) -> tuple[bytes, list[tuple[int, Square | None]]]:
    """Cells as the checkpoint writes them (one compound child per cell, an empty compound for a
    cell cut away, binary BRep: doubles kept exactly) and per cell its face count at the last merge
    and its grid square."""
    stream = io.BytesIO()
    BinTools.Write_s(compound(c.shape if c.shape is not None else compound([]) for c in cells), stream)
    return stream.getvalue(), [(c.faces_at_merge, c.square) for c in cells]


def unpack_cells(data: bytes, records: list[tuple[int, Square | None]]) -> list[Cell]:
    """The cells of :func:`pack_cells`, rebuilt as :meth:`BRepEngine.load_checkpoint` rebuilds them."""
    shape = TopoDS_Shape()
    BinTools.Read_s(shape, io.BytesIO(data))
    return [Cell.of_solid(child, square, merged) for child, (merged, square) in zip(children(shape), records, strict=True)]


def cell_records(cells: list[Cell], previous: list[Cell] | None = None) -> list[Cell]:
    """Copies of the cells' records, not of their shapes (a cut replaces a cell's shape, never edits
    it); a cell whose material and merge count are those of its record in ``previous`` keeps that
    record: a CL changes a few of a worker's cells, and copying them all after every CL adds up over
    a program."""
    if previous is None or len(previous) != len(cells):
        return [replace(c) for c in cells]
    return [p if (c.solid is p.solid and c.layers is p.layers and c.faces_at_merge == p.faces_at_merge
                  and c.square == p.square) else replace(c) for c, p in zip(cells, previous, strict=True)]


# -- the workers --------------------------------------------------------------------------------------


class PartitionWorker:
    """Dask actor: some cells of the IPW (as of CL ``position``) and the program's CL sequence."""

    def __init__(self, cells: bytes, records: list, stock_volume: float, options: EngineOptions,
                 toolpath: Toolpath, default_tool: MillingTool | None, position: int,
                 workers_on_host: int = 1, kept_batches: int = 1) -> None:
        # the kernel's own threads only where this host has cores the workers leave free: with a
        # worker per core they would compete with the other workers (EngineOptions.kernel_threads)
        spare_cores = (os.cpu_count() or 1) > workers_on_host
        self.engine = BRepEngine(replace(options, kernel_threads=options.kernel_threads and spare_cores))
        self.engine.cells = unpack_cells(cells, records)
        self.engine.adopt_layers()
        # the whole stock's: the engine's "nothing removed" threshold is relative to it
        self.engine.stock_volume = stock_volume
        self.sequence: list[CL] = list(cl_sequence(toolpath, options, default_tool))
        self.contacts: dict[int, list] = {}  # CL index -> flute contact faces, until sliced
        self.position = position  # the first CL these cells have not seen
        # CL index -> the cells before that CL, over the last ``kept_batches`` batches cut
        self.history: dict[int, list[Cell]] = {}
        self.kept_batches = kept_batches
        self._starts: deque[int] = deque()

    def cut_batch(self, start: int, stop: int) -> list[CutOutcome]:
        if start != self.position:
            raise EngineStateError(f"the worker's cells are at CL {self.position}, not {start}")
        self._starts.append(start)
        if len(self._starts) > self.kept_batches:
            self._starts.popleft()
            self.history = {i: cells for i, cells in self.history.items() if i >= self._starts[0]}
        records = self.history.get(start) or cell_records(self.engine.cells)
        self.history[start] = records
        out = []
        for index, move, tool, feed_angle in self.sequence[start:stop]:
            try:
                outcome, contacts = self.engine.cut(index, move, tool, feed_angle)
            except Exception as exc:  # noqa: BLE001 - a kernel surprise fails this CL, not the run
                outcome, contacts = CutOutcome(CLStatus.FAILED, reason=f"kernel error: {exc}"), []
            flute = [c for c in contacts if c.surface.zone == "flute"]
            if flute:
                self.contacts[index] = flute
            out.append(outcome)
            records = self.history[index + 1] = cell_records(self.engine.cells, records)
        self.position = stop
        return out

    def work(self, slicing: tuple[dict[int, list[float]], int] | None,
             cutting: tuple[int, int] | None) -> tuple[dict | None, list[CutOutcome] | None]:
        """:meth:`slice_batch` of a batch cut before, then :meth:`cut_batch` of the next one, in one
        call: Dask may run an actor's calls in another order than they were made."""
        return (None if slicing is None else self.slice_batch(*slicing),
                None if cutting is None else self.cut_batch(*cutting))

    def slice_batch(self, heights: dict[int, list[float]],
                    stop: int) -> dict[int, list[list[tuple[float, float]]] | str]:
        """Machine arcs of this worker's contact faces at the given heights; an error message per CL.
        The contact faces of CLs before ``stop`` are dropped afterwards (their batch is sliced)."""
        out: dict[int, list[list[tuple[float, float]]] | str] = {}
        for index, zs in heights.items():
            flute = self.contacts.get(index)
            if flute is None:
                continue
            tip = self.sequence[index].move.end
            try:
                out[index] = [slice_intervals(flute, tip, z) for z in zs]
            except Exception as exc:  # noqa: BLE001
                out[index] = f"contact analysis failed: {exc}"
        self.contacts = {i: faces for i, faces in self.contacts.items() if i >= stop}
        return out

    def _cells_at(self, next_cl: int) -> list[Cell]:
        if next_cl == self.position:
            return self.engine.cells
        if next_cl in self.history:
            return self.history[next_cl]
        raise EngineStateError(f"the worker keeps its cells at CL {self.position} and within its last "
                         f"{self.kept_batches} batches, not at {next_cl}")

    def cells_at(self, next_cl: int) -> tuple[bytes, list[int]]:
        """The cells before CL ``next_cl`` (see :func:`pack_cells`)."""
        return pack_cells(self._cells_at(next_cl))

    def volume_at(self, next_cl: int) -> float:
        return sum(volume(c.shape) for c in self._cells_at(next_cl) if c.shape is not None)


def cell_partition(n_cells: int, parts: int) -> list[list[int]]:
    """Cells dealt out in turn: cell k goes to part k mod ``parts`` (empty parts left out).

    The cells are listed column by column, so neighbours mostly belong to different parts and every
    worker has cells wherever the tool is. Contiguous blocks left one worker idle while the tool
    cleared the other's side (``docs/decisions/engine-measurements.md``).
    """
    return [ids for ids in (list(range(k, n_cells, parts)) for k in range(parts)) if ids]


def peak_rss_mb() -> float:
    """The peak resident memory (MB) of this process so far."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


# -- the driver ---------------------------------------------------------------------------------------


@dataclass
class ParallelBRepEngine:
    """The exact engine over Dask workers (see the module docstring). Use as a context manager, or
    call :meth:`open` and :meth:`close`."""

    options: EngineOptions = field(default_factory=EngineOptions)
    workers: int = 2
    scheduler: str | None = None
    batch: int = 100
    ahead: int = 3  # batches the workers cut ahead of the one handed out (see process)
    stock_volume: float = 0.0
    removed_total: float = 0.0
    _client: Any = field(default=None, init=False, repr=False)
    _cluster: Any = field(default=None, init=False, repr=False)
    # the cells while no worker holds them; None while the workers do (or took them along on close)
    _cells: list[Cell] | None = field(default_factory=list, init=False, repr=False)
    _actors: list[Any] = field(default_factory=list, init=False, repr=False)
    _parts: list[list[int]] = field(default_factory=list, init=False, repr=False)
    _next: int = field(default=0, init=False, repr=False)  # the first CL the state does not include

    def __post_init__(self) -> None:
        if self.batch < 1 or self.ahead < 1:
            raise ValueError(f"batch and ahead must be at least 1 (got {self.batch} and {self.ahead})")

    def __enter__(self) -> ParallelBRepEngine:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def open(self) -> None:
        """Start the embedded cluster, or connect to the scheduler
        (:func:`fusioncut.engines.dask_cluster.open_client`)."""
        if self._client is None:
            self._client, self._cluster = open_client(self.workers, self.scheduler)

    def close(self) -> None:
        """Close the client (and the embedded cluster). The workers' cells go with them: ask for
        ``ipw`` or ``ipw_volume`` before."""
        self._drop_actors()
        client, cluster = self._client, self._cluster
        self._client = self._cluster = None
        close_quietly(client, cluster)

    # -- the Engine protocol ------------------------------------------------------------------------------
    @property
    def kind(self) -> EngineKind:
        return EngineKind.PARALLEL_BREP

    @property
    def shares_cells(self) -> bool:
        """The workers share the workpiece out by cells: without cells one worker would do it all."""
        return True

    def start(self, stock: Stock | TopoDS_Shape) -> None:
        """Cut the stock into cells here (the runner checks the stock before writing anything)."""
        whole = BRepEngine(self.options)
        whole.start(stock)
        self._drop_actors()
        self.stock_volume, self.removed_total = whole.stock_volume, 0.0
        self._cells, self._next = whole.cells, 0

    def load_checkpoint(self, folder: Path) -> int | None:
        """Restore a checkpoint of either engine; the next CL index, or None if none."""
        whole = BRepEngine(self.options)
        next_cl = whole.load_checkpoint(folder)
        if next_cl is None:
            return None
        self._drop_actors()
        self.stock_volume, self.removed_total = whole.stock_volume, whole.removed_total
        self._cells, self._next = whole.cells, next_cl
        return next_cl

    def save_checkpoint(self, folder: Path, next_cl: int) -> None:
        """:meth:`BRepEngine.save_checkpoint` of the workpiece after the last CL handed out."""
        if next_cl != self._next:
            raise EngineStateError(f"the engine state is at CL {self._next}, a checkpoint at CL {next_cl} would lie")
        BRepEngine(self.options, self._gather(), self.stock_volume, self.removed_total).save_checkpoint(folder, next_cl)

    @property
    def ipw(self) -> TopoDS_Shape:
        """The whole workpiece after the last CL handed out (a compound of the cells' solids)."""
        return BRepEngine(self.options, self._gather()).ipw

    @property
    def ipw_volume(self) -> float:
        if not self._actors:
            return sum(volume(c.shape) for c in self._gather() if c.shape is not None)
        return sum(f.result() for f in [a.volume_at(self._next) for a in self._actors])

    @property
    def cells(self) -> list[Cell]:
        return self._gather()

    def workers_peak_rss_mb(self) -> dict[str, float]:
        """The peak resident memory (MB) of each worker process so far, by worker address."""
        if self._client is None:
            return {}
        return self._client.run(peak_rss_mb)

    def run(self, toolpath: Toolpath, stock: Stock, default_tool: MillingTool | None = None) -> Iterator[EngagementMap]:
        self.start(stock)
        yield from self.process(toolpath, default_tool)

    def process(self, toolpath: Toolpath, default_tool: MillingTool | None = None,
                start_at: int = 0) -> Iterator[EngagementMap]:
        """Run the CL segments of ``toolpath`` from CL ``start_at`` on the current workpiece (from
        :meth:`start` or :meth:`load_checkpoint`), as :meth:`BRepEngine.process` does."""
        sequence = list(cl_sequence(toolpath, self.options, default_tool))
        if start_at >= len(sequence):
            return
        self._seed(toolpath, default_tool, start_at)
        actors = self._actors
        batches = [(start, min(len(sequence), start + self.batch))
                   for start in range(start_at, len(sequence), self.batch)]
        # Each worker has one call in flight at a time (Dask may deliver an actor's calls out of
        # order), which slices a batch merged before and cuts its next one. A worker cuts up to
        # ``ahead`` batches beyond the one being handed out, without waiting for the others: waiting
        # for the slowest after each batch leaves every other worker idle meanwhile.
        cut: list[dict[int, list[CutOutcome]]] = [{} for _ in actors]  # per worker: batch -> outcomes
        arcs: list[dict[int, dict]] = [{} for _ in actors]  # per worker: batch -> its answer
        to_slice: list[deque[int]] = [deque() for _ in actors]  # merged batches a worker has not sliced
        next_cut = [0] * len(actors)
        running: dict[Any, tuple[int, int | None, int | None]] = {}  # future -> worker, sliced, cut
        merged: dict[int, tuple[list[CutOutcome], dict, dict]] = {}  # batch -> outcomes, plans, asks
        n_merged = handed = 0

        def submit(k: int) -> None:
            sliced = to_slice[k].popleft() if to_slice[k] else None
            cutting = next_cut[k] if next_cut[k] < min(len(batches), handed + self.ahead) else None
            if sliced is None and cutting is None:
                return
            if cutting is not None:
                next_cut[k] += 1
            future = actors[k].work(None if sliced is None else (merged[sliced][2], batches[sliced][1]),
                                    None if cutting is None else batches[cutting])
            running[future] = (k, sliced, cutting)

        for k in range(len(actors)):
            submit(k)
        mark = time.perf_counter()
        while handed < len(batches):
            if not running:
                raise EngineStateError(f"the parallel engine stalled at batch {handed} of {len(batches)}")
            self._wait_any(list(running))
            for future in [f for f in running if f.done()]:
                k, sliced, cutting = running.pop(future)
                answer, outcomes = future.result()
                if sliced is not None:
                    arcs[k][sliced] = answer
                if cutting is not None:
                    cut[k][cutting] = outcomes
            while n_merged < len(batches) and all(n_merged in c for c in cut):
                merged[n_merged] = self._merge(sequence, batches[n_merged][0], [c.pop(n_merged) for c in cut])
                for queue in to_slice:
                    queue.append(n_merged)
                n_merged += 1
            while handed < n_merged and all(handed in a for a in arcs):
                answers = [a.pop(handed) for a in arcs]
                outcomes, plans, asks = merged.pop(handed)
                start, stop = batches[handed]
                handed += 1
                # the wall time since the last batch was handed out, shared out over this one's CLs
                wall = (time.perf_counter() - mark) * 1e3 / (stop - start)
                yield from self._hand_out(sequence, start, outcomes, plans, asks, answers, wall)
                mark = time.perf_counter()
            busy = {k for k, *_ in running.values()}
            for k in range(len(actors)):
                if k not in busy:
                    submit(k)

    def _wait_any(self, futures: list) -> None:
        """Until one of the actor calls ``futures`` is answered (``distributed.wait`` takes task
        futures only)."""
        async def first() -> None:
            waiting = [asyncio.ensure_future(f) for f in futures]
            try:
                await asyncio.wait(waiting, return_when=asyncio.FIRST_COMPLETED)
            finally:
                for w in waiting:
                    w.cancel()

        self._client.sync(first)

    def _merge(self, sequence: list[CL], start: int,
               per_worker: list[list[CutOutcome]]) -> tuple[list[CutOutcome], dict, dict]:
        """A batch's outcomes merged over the workers, its slice plans and the heights to ask for."""
        outcomes = []
        for k in range(len(per_worker[0])):
            outcome = per_worker[0][k]
            for other in per_worker[1:]:
                outcome = outcome.merged(other[k])
            outcomes.append(outcome)
        plans = {start + k: slice_heights(o.z_range, sequence[start + k].tool, self.options.slice_height)
                 for k, o in enumerate(outcomes)}
        asks = {i: [z for z, active in plan if active] for i, plan in plans.items() if plan}
        return outcomes, plans, asks

    def _hand_out(self, sequence: list[CL], start: int, outcomes: list[CutOutcome],
                  plans: dict[int, list[SliceHeight]], asks: dict, answers: list[dict],
                  wall: float) -> Iterator[EngagementMap]:
        """The engagement maps of a batch, from the merged outcomes and the workers' arcs."""
        for k, outcome in enumerate(outcomes):
            cl = sequence[start + k]
            index, plan = cl.index, plans[cl.index]
            active_arcs: list[list[tuple[float, float]]] = [[] for _ in asks.get(index, [])]
            for answer in answers:
                got = answer.get(index, [])
                if isinstance(got, str):
                    outcome.status, outcome.reason = CLStatus.FAILED, got
                    continue
                for j, arcs in enumerate(got):
                    active_arcs[j].extend(arcs)
            merged_arcs = iter([merge_arcs(a) for a in active_arcs])
            arcs = [next(merged_arcs) if active else [] for _, active in plan]
            outcome.timings["total"] = wall
            self.removed_total += outcome.removed
            # before the yield: whoever gets this CL sees the workpiece after it
            self._next = index + 1
            yield replace(engagement_map(cl, outcome, plan, arcs, self.options.slice_height,
                                         self.options.min_chip_thickness), engine=EngineKind.BREP.value)

    # -- internals --------------------------------------------------------------------------------------
    def _seed(self, toolpath: Toolpath, default_tool: MillingTool | None, start_at: int) -> None:
        """Give each worker its share of the current cells, as of CL ``start_at``."""
        if self._client is None:
            self.open()
        cells = self._gather()
        self._drop_actors()
        self._next = start_at
        workers = self._client.scheduler_info()["workers"]
        addresses = sorted(workers)
        parts = cell_partition(len(cells), max(1, len(addresses)))
        placed = [addresses[k % len(addresses)] for k in range(len(parts))]
        hosts = Counter(workers[a]["host"] for a in placed)
        futures = [self._client.submit(PartitionWorker, *pack_cells([cells[i] for i in ids]), self.stock_volume,
                                       self.options, toolpath, default_tool, start_at, hosts[workers[a]["host"]],
                                       # the batch being handed out and those cut ahead of it
                                       self.ahead + 1, actor=True, workers=[a], allow_other_workers=False)
                   for ids, a in zip(parts, placed)]
        self._actors = [f.result() for f in futures]
        self._parts = parts
        self._cells = None
        if len(parts) < len(addresses):
            log.info("%d workpiece cells for %d workers: %d of them get cells", len(cells), len(addresses), len(parts))

    def _gather(self) -> list[Cell]:
        """The cells after the last CL handed out, in cell order (fetched from the workers)."""
        if not self._actors:
            if self._cells is None:
                raise EngineStateError("the workers that held the workpiece are closed")
            return self._cells
        answers = [unpack_cells(*f.result()) for f in [a.cells_at(self._next) for a in self._actors]]
        if any(len(ids) != len(got) for ids, got in zip(self._parts, answers)):
            # a worker split cells into quarters: its cells follow each other, in its own order
            return [cell for got in answers for cell in got]
        cells: list[Cell | None] = [None] * sum(len(ids) for ids in self._parts)
        for ids, got in zip(self._parts, answers):
            for i, cell in zip(ids, got, strict=True):
                cells[i] = cell
        return cells  # type: ignore[return-value]

    def _drop_actors(self) -> None:
        """Forget the workers' cells (Dask ends an actor once no future refers to it)."""
        if self._actors:
            self._cells = None
        self._actors, self._parts = [], []
