"""Benchmark: the analytic engine against the B-Rep engine, on the same small program in the same run.

    python benchmarks/analytic_bench.py                 # both engines
    python benchmarks/analytic_bench.py --no-brep       # the analytic engine only

The program (:func:`program`) mixes what issue 26 is about on a 60 x 40 mm block: a 10 mm flat end
mill's slot with side passes and an XY arc, a helical entry (helix radius 3 mm, 1.5 turns, swept
exactly by the analytic engine, in level steps by the B-Rep engine), and two passes of a 6 mm ball
end mill, each a ramp down then a level pass. The removed totals differ by what the steps cut below
the exact ramps and helix. Both engines get the same CL segments (2 mm at most) and
1 mm slices. The analytic engine's numba kernels are compiled (or loaded from their cache) before
the clock starts, on a CL of its own.

Per engine: CLs, mean, median and p95 ms/CL, the total removed volume (mm³), and the ratio of the
means. Prints a table; ``--out`` writes the figures as JSON.
"""
from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.base import EngineOptions
from fusioncut.model import ArcMove, BallEndMill, BoxStock, FlatEndMill, LinearMove, Toolpath

STOCK = BoxStock((0.0, 0.0, -15.0), (60.0, 40.0, 0.0))


def program() -> Toolpath:
    def f(a, b, tool=1):
        return LinearMove(a, b, feed=800.0, tool=tool)

    moves = [f((-6, 8, -2), (66, 8, -2)), f((66, 8, -2), (66, 14, -2)), f((66, 14, -2), (-6, 14, -2)),
             ArcMove((-6, 14, -2), (-6, 26, -2), center=(-6, 20, -2), clockwise=False, feed=800.0, tool=1),
             f((-6, 26, -2), (40, 26, -2))]
    # a helical entry at (30, 20): 1.5 turns from 0.5 above the top down to 3 mm deep, then a level turn
    top, depth = 0.5, 3.0  # the helix radius is 3 mm: centre (30, 20), start (33, 20)
    moves += [f((40, 26, -2), (40, 26, 2)), f((40, 26, 2), (33, 20, 2)), f((33, 20, 2), (33, 20, top)),
              ArcMove((33, 20, top), (27, 20, -depth), center=(30, 20, top), clockwise=True, turns=1,
                      feed=600.0, tool=1),
              ArcMove((27, 20, -depth), (27, 20, -depth), center=(30, 20, -depth), clockwise=True, feed=600.0,
                      tool=1)]
    # the ball: ramps down and level passes across the block, 2 mm apart
    y, z = 4.0, -1.0
    moves.append(LinearMove((-4, y, 5), (-4, y, z), feed=600.0, tool=2))
    for k in range(2):
        x0, x1 = (-4, 64) if k % 2 == 0 else (64, -4)
        moves += [f((x0, y, z), (0.5 * (x0 + x1), y, z - 1.5), 2), f((0.5 * (x0 + x1), y, z - 1.5), (x1, y, z - 1.5), 2),
                  f((x1, y, z - 1.5), (x1, y + 2, z), 2)]
        y += 2
    return Toolpath(tuple(moves), {1: FlatEndMill(10, 20, number=1), 2: BallEndMill(6, 20, number=2)})


def timed(engine, toolpath: Toolpath) -> tuple[list[float], float]:
    times, removed = [], 0.0
    t0 = time.perf_counter()
    for m in engine.run(toolpath, STOCK):
        t1 = time.perf_counter()
        times.append((t1 - t0) * 1e3)
        removed += m.removed_volume
        t0 = t1
    return times, removed


def summary(times: list[float]) -> dict:
    ordered = sorted(times)
    return {"cls": len(times), "mean_ms": statistics.fmean(times), "median_ms": statistics.median(times),
            "p95_ms": ordered[min(len(ordered) - 1, math.ceil(0.95 * len(ordered)) - 1)]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-brep", action="store_true", help="time the analytic engine only")
    parser.add_argument("--out", type=Path, help="write the figures as JSON here")
    args = parser.parse_args(argv)
    options = EngineOptions(max_segment_length=2.0, slice_height=1.0)
    toolpath = program()
    warm = Toolpath(toolpath.moves[:2], toolpath.tools)
    list(AnalyticEngine(options).run(warm, STOCK))  # numba: compile or load the kernels
    rows = {}
    times, removed = timed(AnalyticEngine(options), toolpath)
    rows["analytic"] = {**summary(times), "removed_mm3": removed}
    if not args.no_brep:
        from fusioncut.engines.brep.engine import BRepEngine
        times, removed = timed(BRepEngine(options), toolpath)
        rows["brep"] = {**summary(times), "removed_mm3": removed}
    print(f"{'engine':10s} {'CLs':>5s} {'mean ms':>9s} {'median ms':>10s} {'p95 ms':>9s} {'removed mm3':>13s}")
    for name, r in rows.items():
        print(f"{name:10s} {r['cls']:5d} {r['mean_ms']:9.2f} {r['median_ms']:10.2f} {r['p95_ms']:9.2f} "
              f"{r['removed_mm3']:13.6f}")
    if "brep" in rows:
        print(f"mean ratio brep / analytic: {rows['brep']['mean_ms'] / rows['analytic']['mean_ms']:.2f}")
    if args.out:
        args.out.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
