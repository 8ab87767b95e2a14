"""The cost of the kernel budget (EngineOptions.kernel_budget_s, engines/brep/budget.py): the same
CLs with the 3D Booleans and the sweeps' fuses in this process (with and without the
kernel's threads) and in the kept, killable child; results compared bit for bit. Numbers:
docs/kernel-budget.md.

    .venv/bin/python benchmarks/kernel_budget.py [repeats]
"""
from __future__ import annotations

import statistics
import sys
import time

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep import occ, solid_cut
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.model import BallEndMill, BoxStock, FlatEndMill, LinearMove, Toolpath

STOCK = BoxStock((0, 0, -20), (40, 40, 0))


def raster(tool) -> Toolpath:
    """30 passes 1.2 mm apart across the stock, each 0.02 mm deeper (150 CLs of 10 mm)."""
    moves = tuple(LinearMove((-5, 1 + 1.2 * i, -2 - 0.02 * i), (45, 1 + 1.2 * i, -2 - 0.02 * i), feed=600, tool=1)
                  for i in range(30))
    return Toolpath(moves, {1: tool})


def measure(tool, repeats: int) -> None:
    calls = [0]
    real = solid_cut.guarded

    def counting(*args):
        calls[0] += 1
        return real(*args)

    solid_cut.guarded = occ.guarded = counting
    rows = {}
    for name, kw in (("in process, kernel threads", dict(kernel_budget_s=None)),
                     ("in process, one thread", dict(kernel_budget_s=None, kernel_threads=False)),
                     ("kept child (budget 60 s)", dict(kernel_budget_s=60.0))):
        times, keys = [], []
        for _ in range(repeats):
            calls[0] = 0
            engine = BRepEngine(EngineOptions(max_segment_length=10.0, layers=False, **kw))
            t0 = time.perf_counter()
            maps = list(engine.run(raster(tool), STOCK))
            times.append(time.perf_counter() - t0)
            keys.append([(m.status, m.removed_volume, [(s.z, s.intervals) for s in m.slices]) for m in maps])
        rows[name] = (statistics.median(times), min(times), calls[0], keys[0])
    solid_cut.guarded = occ.guarded = real
    base = rows["in process, one thread"]
    for name, (median, best, n, key) in rows.items():
        extra = (median - base[0]) / n * 1e3 if n else float("nan")
        print(f"{type(tool).__name__:12s} {name:28s} median {median:6.2f} s  min {best:6.2f} s  guarded calls {n:4d}  "
              f"per call vs one thread {extra:+6.1f} ms  same results: {key == rows['in process, kernel threads'][3]}")


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    for t in (FlatEndMill(6, 15), BallEndMill(diameter=6, flute_length=20)):
        measure(t, n)
