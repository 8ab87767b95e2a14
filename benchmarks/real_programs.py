"""Benchmark: the analytic engine on real 3-axis programs, with the B-Rep engine on the same CLs as the ratio.

    python benchmarks/real_programs.py                       # every program, 30 CLs a window
    python benchmarks/real_programs.py --programs bear,wave --cls 60 --windows 3
    python benchmarks/real_programs.py --no-brep --out real.json
    python benchmarks/real_programs.py --programs bear --cls 200 --windows 1 --no-brep --workers 2

The programs are the 3-axis programs of ``../shared/data`` that issue 26 names (CAMotics bear, cameo,
flower_mold, wave, botomata; LinuxCNC 3D_Chips; the Fusion posts), each with its project's tools and
workpiece where it has a CAMotics project, else its own tool comments and the stock the runner
infers (:func:`fusioncut.io.stock.infer_stock`). 3D_Chips names neither in code: its header says "a
100x100x50mm block with the zero point at the center top" and "a 10mm ball nose", so it runs a
10 mm ball end mill (25 mm of flutes: the header gives none) in that block. Then the Titan-like
program (:mod:`titan_program`, full size, its own stock) and a generated 3D finishing set
(``gen_*``, :mod:`finishing_programs`: ball and bull-nose raster, waterline and spiral passes over a
free-form surface with a ramp and helical entries; a flat end mill facing, contouring and slotting a
round bar).

Since the workpiece before a CL follows from the path, the analytic engine starts a window at any
CL (:meth:`AnalyticEngine.process` with ``start_at``: the sweeps before it are only indexed), so its
windows are spread over the program: the first at CL 0, the others evenly up to the last CLs. The
B-Rep engine runs the first window only (a later one would need the whole program replayed before
it); the ratio of the means and the relative difference of the removed volumes are taken there, on
the same CLs.

Per program and window: the first CL, CLs, CLs that removed material, failed CLs, the mean, median
and p95 wall time per CL (ms, over every CL of the window: air moves count, as in a program's total
time), and the volume removed (mm³). ``growth`` is the analytic engine's mean over the last window
divided by its mean over the first. The numba kernels are compiled (or loaded from their cache)
before the clock starts, in every worker too. ``--out`` writes the figures as JSON.

``--workers N`` also runs the first window with the parallel analytic engine on an embedded Dask
cluster of N processes (:mod:`fusioncut.engines.analytic.parallel`): ``parallel_speedup`` is the
single-process mean over the parallel one on the same CLs, ``parallel_serial_fraction`` the share
of the parallel run's wall time the driver worked alone, and the removed volumes must be equal.

``conserv.`` checks each analytic window's volumes (``--no-conservation`` leaves it out): the
workpiece's volume over the box of the window's footprints is integrated in one piece from the
sweeps before the window's first CL and after its last (:meth:`AnalyticEngine.material_volume`);
their difference less the window's removed volume, over the first, is printed.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from finishing_programs import GENERATED  # beside this script, on the path when it runs
from finishing_programs import load as load_generated
from titan_program import STOCK_MAX, STOCK_MIN, titan_program
from fusioncut.engines.analytic.conservation import window_material
from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.base import EngineOptions
from fusioncut.engines.cl_maps import cl_sequence
from fusioncut.io.readers import read_toolpath
from fusioncut.io.stock import infer_stock
from fusioncut.io.tool_library import read_camotics_project
from fusioncut.model import (ArcMove, BallEndMill, BoxStock, CLStatus, FlatEndMill, LinearMove, MillingTool, Stock,
                             Toolpath)

SHARED = Path(os.environ.get("FUSIONCUT_SHARED_DATA") or Path(__file__).resolve().parents[2] / "shared" / "data")


@dataclass(frozen=True)
class Program:
    name: str
    path: str  # the G-code, relative to the shared data folder
    project: str | None = None  # a CAMotics project giving the tools and the workpiece
    tool: MillingTool | None = None  # the tool of moves that name none, where the program says it in prose
    stock: Stock | None = None  # the workpiece, where the program says it in prose


PROGRAMS = (
    Program("bear", "camotics-examples/bear/bear.nc", "camotics-examples/bear/bear.camotics"),
    Program("wave", "camotics-examples/wave/wave.gcode", "camotics-examples/wave/wave.camotics"),
    Program("cameo", "camotics-examples/cameo/cameo.nc", "camotics-examples/cameo/cameo.camotics"),
    Program("flower_mold", "camotics-examples/flower_mold/flower_mold.nc",
            "camotics-examples/flower_mold/flower_mold.camotics"),
    Program("botomata", "camotics-examples/botomata_bottom/botomata_bottom.nc",
            "camotics-examples/botomata_bottom/botomata_bottom.camotics"),
    Program("1055_utab", "fusion-posted/1055_utab_265bit.nc"),
    Program("1110_wall", "fusion-posted/1110_wall_265bit.nc"),
    Program("1117_wall", "fusion-posted/1117_wall_28bit.nc"),
    Program("1072_face", "fusion-posted/1072_face_otherside.nc"),
    Program("3d_chips", "linuxcnc-nc_files/3D_Chips.ngc", tool=BallEndMill(10.0, 25.0),
            stock=BoxStock((-50.0, -50.0, -50.0), (50.0, 50.0, 0.0))),
    Program("titan", ""),
    *(Program(name, "") for name in GENERATED),
)


def load(program: Program) -> tuple[Toolpath, Stock, MillingTool | None]:
    """The program's toolpath, stock (its project's workpiece, else the inferred one) and the tool of
    moves that name none (a project's only tool, as CAMotics takes it; else None)."""
    if program.name in GENERATED:
        return load_generated(program.name)
    if program.name == "titan":
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "titan.nc"
            path.write_text(titan_program())
            return read_toolpath(path), BoxStock(STOCK_MIN, STOCK_MAX), None
    if program.project:
        project = read_camotics_project(SHARED / program.project)
        toolpath = read_toolpath(SHARED / program.path, tools=dict(project.tools))
        default = next(iter(project.tools.values())) if len(project.tools) == 1 else None
        return toolpath, project.stock or infer_stock(toolpath), default
    toolpath = read_toolpath(SHARED / program.path)
    return toolpath, program.stock or infer_stock(toolpath), program.tool


def summary(times: list[float]) -> dict:
    ordered = sorted(times)
    return {"mean_ms": statistics.fmean(times), "median_ms": statistics.median(times),
            "p95_ms": ordered[min(len(ordered) - 1, math.ceil(0.95 * len(ordered)) - 1)]}


def timed(maps, count: int) -> dict:
    """Time ``count`` maps of the iterator ``maps`` (or as many as it has)."""
    times, removed, cut, failed = [], 0.0, 0, 0
    t0 = time.perf_counter()
    for m in maps:
        t1 = time.perf_counter()
        times.append((t1 - t0) * 1e3)
        removed += m.removed_volume
        cut += m.removed_volume > 0
        failed += m.status == CLStatus.FAILED
        if len(times) >= count:
            break
        t0 = time.perf_counter()
    if not times:
        return {"cls": 0}
    return {"cls": len(times), "cut": cut, "failed": failed, "removed_mm3": removed, **summary(times)}


def warm_kernels() -> None:
    """Compile (or load from numba's cache) the analytic engine's kernels in this process: the first
    program's first moves, and a flat end mill's level cut, ramp and helix (the closed forms' kernels,
    :mod:`fusioncut.engines.analytic.flat`, ``.polar``, ``.cylinder``)."""
    toolpath, stock, _ = load(PROGRAMS[0])
    list(AnalyticEngine(EngineOptions()).run(Toolpath(toolpath.moves[:4], toolpath.tools), stock))
    a, b, c = (-4.0, 0.0, -1.0), (4.0, 0.0, -1.0), (4.0, 3.0, -2.0)
    flat = [LinearMove((a[0], a[1], 5.0), a, rapid=True, tool=1), LinearMove(a, b, feed=600.0, tool=1),
            LinearMove(b, c, feed=600.0, tool=1),
            ArcMove(c, (4.0, -3.0, -3.0), feed=600.0, tool=1, center=(4.0, 0.0, -2.0)),
            ArcMove((4.0, -3.0, -3.0), (4.0, 3.0, -4.0), feed=600.0, tool=1, center=(4.0, 0.0, -3.0)),
            LinearMove((4.0, 3.0, -4.0), (4.0, 3.0, 5.0), rapid=True, tool=1),
            LinearMove((4.0, 3.0, 5.0), (-4.0, 6.0, 5.0), rapid=True, tool=1),
            LinearMove((-4.0, 6.0, 5.0), (-4.0, 6.0, 0.5), rapid=True, tool=1)]
    for k in range(3):  # a helix about (-5, 6), half a turn a move
        p, q = (-4.0 if k % 2 == 0 else -6.0), (-6.0 if k % 2 == 0 else -4.0)
        flat.append(ArcMove((p, 6.0, 0.5 - k), (q, 6.0, -0.5 - k), feed=600.0, tool=1, center=(-5.0, 6.0, 0.5 - k)))
    list(AnalyticEngine(EngineOptions()).run(Toolpath(tuple(flat), {1: FlatEndMill(6.0, 20.0)}),
                                             BoxStock((-10.0, -10.0, -10.0), (10.0, 10.0, 0.0))))


def window_conservation(toolpath: Toolpath, stock: Stock, default: MillingTool | None, options: EngineOptions,
                        start: int, row: dict) -> float:
    """|M0 - M1 - V| / M0 for the window of ``row`` (its CLs from ``start``, their removed volume ``V``):
    ``M0`` and ``M1`` the workpiece's volume over the box holding the window's footprints before its
    first CL and after its last, each integrated from the sweeps alone (:mod:`.analytic.conservation`)."""
    m0, m1 = window_material(toolpath, stock, options, start, start + row["cls"], default)
    return abs(m0 - m1 - row["removed_mm3"]) / m0 if m0 > 0 else 0.0


def run_program(program: Program, options: EngineOptions, cls: int, windows: int, brep: bool,
                workers: int = 1, conservation: bool = True) -> dict:
    toolpath, stock, default = load(program)
    total = sum(1 for _ in cl_sequence(toolpath, options, default))
    starts = sorted({0, *(round(k * (total - cls) / max(windows - 1, 1)) for k in range(1, windows))})
    starts = [s for s in starts if 0 <= s < total]
    out: dict = {"program": program.name, "cls_in_program": total, "stock": repr(stock), "windows": []}
    for start in starts:
        engine = AnalyticEngine(options)
        engine.start(stock)
        # the sweeps before the window are indexed while the first CL is asked for: start one CL
        # early and leave that CL off the clock
        maps = engine.process(toolpath, default, start_at=max(start - 1, 0))
        if start > 0:
            next(maps, None)
        row = timed(maps, cls)
        if conservation and row["cls"]:
            row["conservation"] = window_conservation(toolpath, stock, default, options, start, row)
        out["windows"].append({"engine": "analytic", "start": start, **row})
    if workers > 1:
        from fusioncut.engines.analytic.parallel import ParallelAnalyticEngine

        with ParallelAnalyticEngine(options, workers=workers) as engine:
            engine.run_on_workers(warm_kernels)
            engine.start(stock)
            row = timed(engine.process(toolpath, default, stop_at=cls), cls)
            out["windows"].append({"engine": f"analytic x{workers}", "start": 0, **row,
                                   "serial_fraction": engine.serial_fraction})
    if brep:
        from fusioncut.engines.brep.engine import BRepEngine
        row = timed(BRepEngine(options).run(toolpath, stock, default), cls)
        out["windows"].append({"engine": "brep", "start": 0, **row})
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--programs", default=",".join(p.name for p in PROGRAMS),
                        help="comma-separated names (default: all)")
    parser.add_argument("--cls", type=int, default=30, help="CLs per window")
    parser.add_argument("--windows", type=int, default=2, help="analytic windows spread over each program")
    parser.add_argument("--slice-height", type=float, default=1.0, help="mm")
    parser.add_argument("--no-brep", action="store_true", help="time the analytic engine only")
    parser.add_argument("--workers", type=int, default=1,
                        help="also run the first window on this many Dask workers (the parallel analytic engine)")
    parser.add_argument("--no-conservation", action="store_true",
                        help="leave out the analytic windows' conservation (two integrals of the material a window)")
    parser.add_argument("--out", type=Path, help="write the figures as JSON here")
    args = parser.parse_args(argv)
    chosen = [p for p in PROGRAMS if p.name in args.programs.split(",")]
    options = EngineOptions(slice_height=args.slice_height)
    warm_kernels()  # numba: compile or load the kernels before any clock starts
    results = []
    print(f"{'program':12s} {'engine':11s} {'start':>6s} {'CLs':>4s} {'cut':>4s} {'fail':>4s} {'mean ms':>9s} "
          f"{'median':>8s} {'p95':>8s} {'removed mm3':>12s} {'conserv.':>9s}")
    for program in chosen:
        try:
            res = run_program(program, options, args.cls, args.windows, not args.no_brep, args.workers,
                              not args.no_conservation)
        except Exception as exc:  # a program this engine cannot take is reported, not fatal to the others
            print(f"{program.name:12s} not run: {type(exc).__name__}: {exc}")
            results.append({"program": program.name, "error": f"{type(exc).__name__}: {exc}"})
            continue
        for w in res["windows"]:
            if not w["cls"]:
                continue
            conserved = f" {w['conservation']:9.1e}" if "conservation" in w else ""
            print(f"{program.name:12s} {w['engine']:11s} {w['start']:6d} {w['cls']:4d} {w['cut']:4d} {w['failed']:4d} "
                  f"{w['mean_ms']:9.1f} {w['median_ms']:8.1f} {w['p95_ms']:8.1f} {w['removed_mm3']:12.4f}{conserved}")
        ana = [w for w in res["windows"] if w["engine"] == "analytic" and w["cls"]]
        brep = [w for w in res["windows"] if w["engine"] == "brep" and w["cls"]]
        if len(ana) > 1:
            res["growth"] = ana[-1]["mean_ms"] / ana[0]["mean_ms"]
        par = [w for w in res["windows"] if w["engine"].startswith("analytic x") and w["cls"]]
        if par and ana and ana[0]["cls"] == par[0]["cls"]:
            res["parallel_speedup"] = ana[0]["mean_ms"] / par[0]["mean_ms"]
            res["parallel_serial_fraction"] = par[0]["serial_fraction"]
            res["parallel_removed_equal"] = par[0]["removed_mm3"] == ana[0]["removed_mm3"]
        if brep and ana and ana[0]["cls"] == brep[0]["cls"]:
            res["mean_ratio_brep_over_analytic"] = brep[0]["mean_ms"] / ana[0]["mean_ms"]
            res["removed_relative_difference"] = ((ana[0]["removed_mm3"] - brep[0]["removed_mm3"])
                                                  / max(abs(brep[0]["removed_mm3"]), 1e-12))
        facts = [f"{k} {res[k]:.3g}" for k in ("growth", "mean_ratio_brep_over_analytic", "removed_relative_difference",
                                               "parallel_speedup", "parallel_serial_fraction") if k in res]
        if "parallel_removed_equal" in res:
            facts.append(f"parallel removed equal: {res['parallel_removed_equal']}")
        if facts:
            print(f"{'':12s} {', '.join(facts)}")
        results.append(res)
    if args.out:
        args.out.write_text(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
