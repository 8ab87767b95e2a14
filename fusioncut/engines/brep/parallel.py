"""Parallel cells: the IPW's cells split among Dask workers, one CL sequence, merged results.

Cells are independent between the CLs they share, so each worker owns a contiguous block of cells
(a Dask *actor* that keeps its B-Rep shapes in its own process) and runs every CL of the program
against them; CLs whose sweep misses its cells cost one bounding-box test. Only floats cross
process boundaries. A CL is done in two phases per batch of CLs:

1. every worker cuts the batch on its cells and reports removed volume, contact areas and the flute
   contact's height range (keeping its contact faces);
2. the driver takes the union of the height ranges, fixes the slice heights exactly as the
   single-process engine would, and asks each worker for the machine arcs of its contact faces at
   those heights; arcs split at a partition's wall are joined again by ``merge_arcs``.

The per-cell Booleans are the same operations on the same shapes as in one process, so the results
equal the single-process engine's (sums may differ in the last bit by their order). One difference:
when a Boolean fails on one worker's cells the others have already cut theirs; the CL is reported
FAILED with the volume that was removed, so volume still adds up.

Dask distributed runs an embedded ``LocalCluster`` (worker processes, one thread each) unless a
scheduler address is given.
"""
from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, field

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.contact import merge_arcs, slice_intervals
from fusioncut.engines.brep.engine import (
    BRepEngine, CutOutcome, cl_base, cl_sequence, engagement_map, slice_heights,
)
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.moves import Toolpath
from fusioncut.model.stock import Stock
from fusioncut.model.tools import MillingTool


class PartitionWorker:
    """Dask actor: the cells ``cell_ids`` of the stock's cell grid and the program's CL sequence."""

    def __init__(self, stock: Stock, options: EngineOptions, cell_ids: list[int], toolpath: Toolpath,
                 default_tool: MillingTool | None) -> None:
        self.engine = BRepEngine(options)
        self.engine.start(stock)
        self.engine.cells = [c for k, c in enumerate(self.engine.cells) if k in set(cell_ids)]
        self.sequence = list(cl_sequence(toolpath, options, default_tool))
        self.contacts: dict[int, list] = {}

    def cells_volume(self) -> float:
        return self.engine.ipw_volume

    def cut_batch(self, start: int, stop: int) -> list[CutOutcome]:
        self.contacts.clear()
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
        return out

    def slice_batch(self, heights: dict[int, list[float]]) -> dict[int, list[list[tuple[float, float]]] | str]:
        """Machine arcs of this worker's contact faces at the given heights; an error message per CL."""
        out: dict[int, list[list[tuple[float, float]]] | str] = {}
        for index, zs in heights.items():
            flute = self.contacts.get(index)
            if flute is None:
                continue
            tip = self.sequence[index][1].end
            try:
                out[index] = [slice_intervals(flute, tip, z) for z in zs]
            except Exception as exc:  # noqa: BLE001
                out[index] = f"contact analysis failed: {exc}"
        return out


def cell_partition(n_cells: int, centres: list[tuple[float, float]], parts: int) -> list[list[int]]:
    """Contiguous blocks of cells along X (then Y), as equal in count as possible."""
    order = sorted(range(n_cells), key=lambda k: (centres[k][0], centres[k][1]))
    size = math.ceil(n_cells / parts)
    return [order[k:k + size] for k in range(0, n_cells, size)]


@dataclass
class ParallelBRepEngine:
    """The exact engine over Dask workers (see the module docstring). Use as a context manager."""

    options: EngineOptions = field(default_factory=EngineOptions)
    workers: int = 2
    scheduler: str | None = None
    batch: int = 200
    stock_volume: float = 0.0
    removed_total: float = 0.0

    def __enter__(self) -> ParallelBRepEngine:
        from distributed import Client, LocalCluster

        if self.scheduler:
            self._cluster = None
            self._client = Client(self.scheduler)
        else:
            self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                         dashboard_address=None)
            self._client = Client(self._cluster)
        return self

    def __exit__(self, *exc: object) -> None:
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()

    def run(self, toolpath: Toolpath, stock: Stock, default_tool: MillingTool | None = None) -> Iterator[EngagementMap]:
        whole = BRepEngine(self.options)
        whole.start(stock)
        self.stock_volume = whole.stock_volume
        centres = [((c.box[0][0] + c.box[1][0]) / 2, (c.box[0][1] + c.box[1][1]) / 2) for c in whole.cells]
        worker_addresses = list(self._client.scheduler_info()["workers"])
        parts = cell_partition(len(whole.cells), centres, max(1, len(worker_addresses)))
        actors = [self._client.submit(PartitionWorker, stock, self.options, ids, toolpath, default_tool,
                                      actor=True, workers=[worker_addresses[k % len(worker_addresses)]]).result()
                  for k, ids in enumerate(parts)]
        self._actors = actors
        sequence = list(cl_sequence(toolpath, self.options, default_tool))
        for start in range(0, len(sequence), self.batch):
            stop = min(len(sequence), start + self.batch)
            t0 = time.perf_counter()
            per_worker = [f.result() for f in [a.cut_batch(start, stop) for a in actors]]
            outcomes = []
            for k in range(stop - start):
                merged = per_worker[0][k]
                for other in per_worker[1:]:
                    merged = merged.merged(other[k])
                outcomes.append(merged)
            plans = {start + k: slice_heights(o.z_range, sequence[start + k][2], self.options.slice_height)
                     for k, o in enumerate(outcomes)}
            asks = {i: [z for z, active in plan if active] for i, plan in plans.items() if plan}
            answers = [f.result() for f in [a.slice_batch(asks) for a in actors]]
            wall = (time.perf_counter() - t0) * 1e3 / (stop - start)
            for k, outcome in enumerate(outcomes):
                index, move, tool, feed_angle = sequence[start + k]
                plan = plans[index]
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
                outcome.timings["total"] = wall  # the batch's wall time shared out over its CLs
                self.removed_total += outcome.removed
                yield engagement_map(cl_base(index, move, tool, feed_angle), tool, move, outcome, plan, arcs)

    @property
    def ipw_volume(self) -> float:
        return sum(a.cells_volume().result() for a in self._actors)
