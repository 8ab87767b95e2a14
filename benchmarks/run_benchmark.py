"""Benchmark: FusionCut's fast path against the published method, in the same run on the same CLs.

    python benchmarks/run_benchmark.py --quick --slicing 1 --workers ''   # under a minute on 2 cores
    python benchmarks/run_benchmark.py --quick          # ~1 min: 1 and 0.2 mm, 1 and 2 Dask workers
    python benchmarks/run_benchmark.py                  # the full Titan-like program, ~4.5 min

* **Program**: the Titan-like part of :mod:`titan_program`, written as G-code and read back through
  FusionCut's G-code reader (tools from the Fusion-style tool comments); moves are split into CL
  segments of at most 2 mm, helices into chords within 10 µm.
* **Ours**: the exact B-Rep engine with its default options (the IPW in 20 mm cells; ``--whole``:
  one piece), at each slice height asked for.
* **Baseline** (the published method reproduced in our engine): sampled tool copies every R/4 and
  Booleans on the whole IPW. It is far too slow for the whole program, so it times ``--baseline-cls``
  processed CLs of every operation in five windows that start at 0, 20, 40, 60 and 80% of its CLs,
  each from our IPW just before it joined into one solid. ``ratio`` compares the two medians over
  exactly those CLs, ``sum ratio`` their total times (the wall-time speedup on them). Spreading the
  windows matters: the published method's cost grows as the workpiece fills with faces, so windows
  at the start alone would flatter it. Starting from our merged IPW still flatters it (its own IPW
  would carry the sampled copies' scallops).
* **Parallel**: the same program at 1 mm on Dask with 1 and 2 workers (``--workers``), and the largest
  peak RSS of a worker process (``peak RSS`` is this process's: the driver's and the single-process runs').

A *processed* CL is one whose sweep reached a Boolean: not skipped as an air cut by bounding boxes or
by the material's height bounds. ``ms/CL`` is an operation's total time over all its CLs.
Growth is the median time of the last 10% of an operation's processed CLs over its first 10%.
``program seconds`` leave out the time spent building the baseline's snapshots of the IPW.
Prints a table and writes ``benchmark.json`` in ``--out``.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from titan_program import FULL, QUICK, STOCK_MAX, STOCK_MIN, ProgramSize, titan_program  # noqa: E402

from fusioncut.engines.base import EngineOptions  # noqa: E402
from fusioncut.engines.brep.engine import BRepEngine  # noqa: E402
from fusioncut.engines.cl_maps import cl_sequence  # noqa: E402
from fusioncut.engines.brep.export import whole_ipw  # noqa: E402
from fusioncut.engines.brep.parallel import ParallelBRepEngine, peak_rss_mb  # noqa: E402
from fusioncut.io.gcode import read_gcode  # noqa: E402
from fusioncut.model import BoxStock, CLStatus  # noqa: E402

TINY = ProgramSize(slot_length=4.0, slots=1, depths=(-4.0,), finish_rows=1, contours=1)
SEGMENT = dict(max_segment_length=2.0, chord_tolerance=0.01)
# ours and the parallel runs: the engine's defaults (20 mm cells); --whole: ours in one piece
OURS = dict(SEGMENT)
WHOLE = dict(SEGMENT, cell_size=None)


def stats(times: list[float]) -> dict:
    if not times:
        return {"processed": 0, "median_ms": None, "p95_ms": None, "growth": None}
    q = max(1, len(times) // 10)
    first, last = statistics.median(times[:q]), statistics.median(times[-q:])
    return {"processed": len(times), "median_ms": statistics.median(times),
            "p95_ms": sorted(times)[min(len(times) - 1, int(0.95 * len(times)))],
            "growth": last / first if first > 0 else None}


def processed(m) -> bool:
    return "boolean" in dict(m.timings_ms)


BASELINE_WINDOWS = (0.0, 0.2, 0.4, 0.6, 0.8)  # where the baseline's windows start in each operation


def window_starts(toolpath) -> set[int]:
    """CL indices where the baseline's windows start (see the module docstring)."""
    ops: dict[str, list[int]] = {}
    for index, move, _, _ in cl_sequence(toolpath, EngineOptions(**SEGMENT)):
        ops.setdefault(move.operation, []).append(index)
    return {cls[int(f * len(cls))] for cls in ops.values() for f in BASELINE_WINDOWS}


def run_ours(toolpath, stock, slice_height: float, snapshots: dict | None = None, whole: bool = False) -> dict:
    """Our engine over the program; ``snapshots`` (CL index -> None) gets the IPW before each of its CLs."""
    engine = BRepEngine(EngineOptions(slice_height=slice_height, **(WHOLE if whole else OURS)))
    engine.start(stock)
    per_op: dict[str, dict] = {}
    t0 = time.perf_counter()
    failed = 0
    aside = 0.0  # seconds spent on the baseline's snapshots (the whole IPW built from the cells): not ours
    for index, move, tool, feed_angle in cl_sequence(toolpath, engine.options):
        if snapshots is not None and index in snapshots:
            t_snap = time.perf_counter()
            snapshots[index] = engine.ipw
            aside += time.perf_counter() - t_snap
        m = engine.step(index, move, tool, feed_angle)
        if m.operation not in per_op:
            print(f"[{slice_height:g} mm] {m.operation} from CL {index} at {time.perf_counter() - t0:.0f} s",
                  file=sys.stderr, flush=True)
        op = per_op.setdefault(m.operation, {"cls": 0, "times": [], "all": {}, "seconds": 0.0})
        op["cls"] += 1
        total = dict(m.timings_ms)["total"]
        op["seconds"] += total / 1e3
        op["all"][index] = total
        if processed(m):
            op["times"].append(total)
        failed += m.status == CLStatus.FAILED
    seconds = time.perf_counter() - t0 - aside
    conservation = abs(engine.stock_volume - engine.ipw_volume - engine.removed_total) / engine.stock_volume
    return {"seconds": seconds, "failed": failed, "conservation": conservation, "ops": per_op}


def run_baseline(toolpath, snapshots: dict, n: int, slice_height: float) -> dict:
    """The published method on ``n`` processed CLs per operation: ``n / 5`` from each snapshot on."""
    opts = EngineOptions(slice_height=slice_height, sweep="sampled", cell_size=None, **SEGMENT)
    sequence = list(cl_sequence(toolpath, opts))
    per_window = max(1, round(n / len(BASELINE_WINDOWS)))
    out: dict[str, dict] = {}
    for first, ipw in sorted(snapshots.items()):
        op = sequence[first][1].operation
        engine = BRepEngine(opts)
        # one solid, as the published method keeps it: our cells' compound would add their walls
        engine.start(whole_ipw(ipw))
        times = out.setdefault(op, {})
        timed = 0
        # a window counts processed CLs: one that starts on a link through the air runs on to the cut
        for index, move, tool, feed_angle in sequence[first:]:
            if move.operation != op or timed == per_window:
                break
            m = engine.step(index, move, tool, feed_angle)
            if processed(m):
                times[index] = dict(m.timings_ms)["total"]
                timed += 1
    return out


def run_parallel(toolpath, stock, workers: int) -> tuple[float, float]:
    """(seconds, the largest peak RSS of a worker process in MB) of the program on Dask workers."""
    with ParallelBRepEngine(EngineOptions(**OURS), workers=workers) as engine:
        t0 = time.perf_counter()
        for _ in engine.run(toolpath, stock):
            pass
        seconds = time.perf_counter() - t0
        return seconds, max(engine.workers_peak_rss_mb().values())


def fmt(x, spec=".1f") -> str:
    return "-" if x is None else format(x, spec)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="a reduced program (~1 min; less with --slicing 1 --workers '')")
    ap.add_argument("--tiny", action="store_true", help="a smoke-test size (seconds)")
    ap.add_argument("--slicing", default="1,0.2", help="slice heights in mm, comma separated")
    ap.add_argument("--baseline-cls", type=int, default=None, help="CLs per operation for the baseline")
    ap.add_argument("--workers", default="1,2", help="Dask worker counts to time ('' to skip)")
    ap.add_argument("--whole", action="store_true", help="ours with the IPW in one piece (no cells)")
    ap.add_argument("--out", type=Path, default=Path("benchmark-results"))
    args = ap.parse_args(argv)
    size = TINY if args.tiny else QUICK if args.quick else FULL
    n_base = args.baseline_cls or (5 if args.tiny else 25 if args.quick else 50)
    args.out.mkdir(parents=True, exist_ok=True)
    program = args.out / "titan.nc"
    program.write_text(titan_program(size))
    toolpath = read_gcode(program)
    stock = BoxStock(STOCK_MIN, STOCK_MAX)
    heights = [float(h) for h in args.slicing.split(",") if h]

    t_start = time.perf_counter()
    snapshots: dict = dict.fromkeys(window_starts(toolpath))
    ours = {h: run_ours(toolpath, stock, h, snapshots if k == 0 else None, args.whole) for k, h in enumerate(heights)}
    baseline = run_baseline(toolpath, snapshots, n_base, heights[0])
    runs = {int(w): run_parallel(toolpath, stock, int(w)) for w in args.workers.split(",") if w}
    parallel = {w: seconds for w, (seconds, _) in runs.items()}
    report = {"size": "tiny" if args.tiny else "quick" if args.quick else "full", "whole": args.whole,
              "program": str(program), "slice_heights_mm": heights, "baseline_cls_per_op": n_base,
              "peak_rss_mb": peak_rss_mb(), "wall_s": time.perf_counter() - t_start, "operations": {}}
    first = ours[heights[0]]
    for op, data in first["ops"].items():
        row = {"cls": data["cls"], "seconds_1": data["seconds"], "ms_per_cl": 1e3 * data["seconds"] / data["cls"]}
        for h in heights:
            row[f"slice_{h:g}"] = stats(ours[h]["ops"][op]["times"])
            row[f"slice_{h:g}"]["seconds"] = ours[h]["ops"][op]["seconds"]
        base = baseline.get(op, {})
        same = [data["all"][i] for i in base if i in data["all"]]
        row["baseline_median_ms"] = statistics.median(base.values()) if base else None
        row["ours_same_cls_median_ms"] = statistics.median(same) if same else None
        row["ratio"] = (row["baseline_median_ms"] / row["ours_same_cls_median_ms"]
                        if base and same and row["ours_same_cls_median_ms"] > 0 else None)
        row["sum_ratio"] = sum(base.values()) / sum(same) if base and same and sum(same) > 0 else None
        report["operations"][op] = row
    report["program_seconds"] = {f"{h:g}": ours[h]["seconds"] for h in heights}
    report["failed_cls"] = {f"{h:g}": ours[h]["failed"] for h in heights}
    report["conservation"] = {f"{h:g}": ours[h]["conservation"] for h in heights}
    report["parallel_seconds"] = parallel
    report["worker_peak_rss_mb"] = {w: rss for w, (_, rss) in runs.items()}
    if 1 in parallel and 2 in parallel:
        report["parallel_speedup_2_over_1"] = parallel[1] / parallel[2]
    (args.out / "benchmark.json").write_text(json.dumps(report, indent=2))
    _print(report, heights)
    return report


def _print(report: dict, heights: list[float]) -> None:
    """The report as tables of at most 80 columns: one per slice height, then the baseline's."""
    for h in heights:
        print(f"slice height {h:g} mm: {report['program_seconds'][f'{h:g}']:.1f} s, "
              f"{report['failed_cls'][f'{h:g}']} failed CLs, conservation {report['conservation'][f'{h:g}']:.2e}")
        print(f"  {'operation':<12} {'CLs':>6} {'done':>6} {'total s':>8} {'median ms':>9} {'p95 ms':>8} {'growth':>6}")
        for op, row in report["operations"].items():
            r = row[f"slice_{h:g}"]
            print(f"  {op:<12} {row['cls']:>6} {r['processed']:>6} {r['seconds']:>8.1f} {fmt(r['median_ms']):>9} "
                  f"{fmt(r['p95_ms']):>8} {fmt(r['growth'], '.2f'):>6}")
    print(f"against the baseline (the published method: sampled tool copies, whole IPW) at {heights[0]:g} mm:")
    print(f"  {'operation':<12} {'base ms':>8} {'ours ms':>8} {'ratio':>6} {'sum ratio':>9}")
    for op, row in report["operations"].items():
        print(f"  {op:<12} {fmt(row['baseline_median_ms']):>8} {fmt(row['ours_same_cls_median_ms']):>8} "
              f"{fmt(row['ratio']):>6} {fmt(row['sum_ratio']):>9}")
    parallel = ", ".join(f"{w}: {t:.1f} s" for w, t in report["parallel_seconds"].items())
    speedup = report.get("parallel_speedup_2_over_1")
    print(f"peak RSS {report['peak_rss_mb']:.0f} MB; parallel seconds by workers: {parallel or '-'}"
          + (f"; speedup 2/1 {speedup:.2f}" if speedup is not None else ""))
    if report["worker_peak_rss_mb"]:
        rss = ", ".join(f"{w}: {m:.0f} MB" for w, m in report["worker_peak_rss_mb"].items())
        print(f"worker peak RSS by workers: {rss}")

if __name__ == "__main__":
    main()
