"""Benchmark: chatter stability per CL (ZOA) over a program and SD lobes of one CL, against a baseline
version of :mod:`fusioncut.analysis.stability` in the same run.

    OPENBLAS_NUM_THREADS=1 python benchmarks/stability_speed.py                 # synthetic program
    OPENBLAS_NUM_THREADS=1 python benchmarks/stability_speed.py --results DIR --rpm 10000 --flutes 3

* **ZOA per CL**: :func:`~fusioncut.analysis.stability_table.stability_table` without SD (ZOA limit, margin
  and nearest stable speed of every CL) over ``--cls`` synthetic CLs whose engagements all differ (no
  two share a computation: the worst case) or over the maps of a results folder (``--results``, rebuilt
  at the slice height the folder records; ``--slice-height`` for older folders), every CL at ``--rpm``
  with one 10 mm tool of ``--flutes``. CPU ms per CL, the best of two runs after a warm-up.
* **SD lobes**: :func:`~fusioncut.analysis.stability.sd_a_lim` at ``--speeds`` speeds (200) for one
  CL, the ZOA limits as reference depths, on two systems: the 1-DOF milling benchmark of Insperger &
  Stepan (922 Hz, a/D 0.1 down-milling, 2 flutes) and the three modes of
  ``docs/stability_modes_example.json`` with a 4 mm deep, 3-flute 30 deg helix half-immersion cut.
  CPU seconds, after a warm-up at two of the speeds (loading the compiled kernels, a one-time cost per
  process).
* **Baseline**: the same calls on ``fusioncut/analysis/stability.py`` as of ``--baseline`` (a git
  revision, read with ``git show``), so that the ratio holds on a loaded machine where the absolute
  times do not. Set ``OPENBLAS_NUM_THREADS=1``: on a shared machine OpenBLAS threads slow the batched
  eigenvalues down by orders of magnitude.
"""
from __future__ import annotations

import argparse
import importlib.util
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fusioncut.analysis import stability as current  # noqa: E402
from fusioncut.analysis import stability_table as current_table  # noqa: E402
from fusioncut.analysis.dynamics import Mode, ToolDynamics, read_modes_json  # noqa: E402
from fusioncut.analysis.forces import CuttingCoefficients  # noqa: E402
from fusioncut.analysis.materials import AL7075_T6_CARBIDE  # noqa: E402
from fusioncut.model import (AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement,  # noqa: E402
                             SpindleDirection)

BASELINE = "473aa9f"  # stability.py as before the compiled ZOA table pass and the reduced SD spectral radius


def _load(rev: str, path: str, name: str, imports: tuple[str, str] = ("", "")):
    """The module ``path`` as of git revision ``rev``, loaded as ``name`` (``imports``: a text to
    replace in its source, so that it imports another baseline module); None where it did not exist."""
    shown = subprocess.run(["git", "show", f"{rev}:{path}"], cwd=ROOT, capture_output=True, text=True)
    if shown.returncode != 0:
        return None
    file = Path(tempfile.mkdtemp()) / f"{name}.py"
    file.write_text(shown.stdout.replace(*imports) if imports[0] else shown.stdout)
    spec = importlib.util.spec_from_file_location(name, file)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def load_baseline(rev: str):
    """(stability.py, the module with its per-CL table) as of ``rev``: the table moved to
    stability_table.py in 0fe49a2; before that it was in stability.py."""
    module = _load(rev, "fusioncut/analysis/stability.py", "stability_baseline")
    if module is None:
        raise SystemExit(f"no fusioncut/analysis/stability.py at {rev}")
    table = _load(rev, "fusioncut/analysis/stability_table.py", "stability_table_baseline",
                  ("from fusioncut.analysis.stability import", "from stability_baseline import"))
    return module, table or module


def synthetic_maps(count: int, seed: int = 0) -> list[EngagementMap]:
    """``count`` engaged CLs of a 10 mm tool, each 1 to 8 slices of 0.5 mm with one or two random arcs and
    a random feed direction: no two alike."""
    rng = np.random.default_rng(seed)
    maps = []
    for i in range(count):
        n = int(rng.integers(1, 9))
        slices = []
        for k in range(n):
            a = np.sort(rng.uniform(0.0, 180.0, 2 if rng.random() < 0.8 else 4))
            arcs = tuple(AngleInterval(float(a[j]), float(a[j + 1])) for j in range(0, len(a), 2))
            slices.append(SliceEngagement(0.25 + 0.5 * k, 0.25 + 0.5 * k, 5.0, arcs))
        maps.append(EngagementMap(i, (1, 0, 0), (0, 0, 0), "T1", SpindleDirection.CW, float(rng.uniform(0, 360)),
                                  CLStatus.ENGAGED, feed=1000.0, slices=tuple(slices), axial_range=(0.0, 0.5 * n)))
    return maps


def results_maps(folder: Path, dz: float | None = None) -> tuple[list[EngagementMap], float]:
    """The engagement maps of a results folder and the slice height (mm) they were computed with: the
    recorded one (:func:`~fusioncut.analysis.result_maps.results_slice_height`), ``dz`` only for a
    folder written before it was recorded (an :class:`~fusioncut.errors.InputError` naming the folder
    asks for it otherwise)."""
    from fusioncut.analysis.result_maps import engagement_maps_from_results, results_slice_height
    from fusioncut.io.results import load_results

    results = load_results(folder)
    dz = results_slice_height(results, dz)
    return engagement_maps_from_results(results, dz), dz


def cpu(fn, repeat: int = 1) -> float:
    best = math.inf
    for _ in range(repeat):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def bench_zoa(mod, maps, tool, coefficients, dynamics, rpm, dz) -> float:
    """Best of two runs after a warm-up on a few CLs (imports, compiled kernels)."""
    mod.stability_table(maps[:5], tool, coefficients, dynamics, rpm[:5], dz=dz, sd=False)
    return cpu(lambda: mod.stability_table(maps, tool, coefficients, dynamics, rpm, dz=dz, sd=False), repeat=2)


def sd_cases():
    fn, zeta, mass = 922.0, 0.011, 0.03993
    one = ToolDynamics((Mode(fn, zeta, mass * (2 * math.pi * fn) ** 2),), ())
    entry = 180.0 - math.degrees(math.acos(1 - 2 * 0.1))
    bench = EngagementMap(0, (1, 0, 0), (0, 0, 0), "T1", SpindleDirection.CW, 0.0, CLStatus.ENGAGED, feed=1.0,
                          slices=(SliceEngagement(0.5, 0.0, 5.0, (AngleInterval(entry, 180.0),)),),
                          axial_range=(0.0, 1.0))
    half = EngagementMap(0, (1, 0, 0), (0, 0, 0), "T1", SpindleDirection.CW, 0.0, CLStatus.ENGAGED, feed=1.0,
                         slices=tuple(SliceEngagement(0.25 + 0.5 * k, 0.0, 5.0, (AngleInterval(90.0, 180.0),))
                                      for k in range(8)), axial_range=(0.0, 4.0))
    return [
        ("1-DOF benchmark, a/D 0.1, 2 flutes", bench, FlatEndMill(diameter=10.0, flute_length=20.0, flutes=2),
         CuttingCoefficients(600.0, 200.0, 0.0, 0.0, 0.0, 0.0), one, (5000.0, 25000.0)),
        ("3 modes (docs example), half immersion, 3 flutes 30 deg", half,
         FlatEndMill(diameter=10.0, flute_length=20.0, flutes=3, helix_angle=30.0), AL7075_T6_CARBIDE,
         read_modes_json(ROOT / "docs" / "stability_modes_example.json"), (5000.0, 20000.0)),
    ]


def bench_sd(mod, case, speeds: int) -> tuple[float, np.ndarray]:
    _, emap, tool, k, dyn, (lo, hi) = case
    cd = mod.cl_directional(emap, tool, k, 0.5 if len(emap.slices) > 1 else 1.0)
    grid, system = mod.chatter_grid(dyn), mod.ModalSystem.from_dynamics(dyn)
    rpm, zoa = mod.zoa_lobes(cd.alpha0, grid, k.ktc, cd.flutes, lo, hi, speeds)
    ref = np.where(np.isfinite(zoa), zoa, cd.ap)
    mod.sd_a_lim(cd, system, k.ktc, rpm[::max(1, speeds // 2)], ref[::max(1, speeds // 2)], max_steps=120)  # warm-up
    out = {}
    t = cpu(lambda: out.setdefault("lim", mod.sd_a_lim(cd, system, k.ktc, rpm, ref, max_steps=120)))
    return t, out["lim"]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cls", type=int, default=1000, help="synthetic CLs (default 1000)")
    ap.add_argument("--results", type=Path, help="a results folder instead of synthetic CLs")
    ap.add_argument("--slice-height", type=float, help="with --results: the slice height (mm) of a folder "
                    "written before it was recorded")
    ap.add_argument("--rpm", type=float, default=10000.0)
    ap.add_argument("--flutes", type=int, default=3)
    ap.add_argument("--speeds", type=int, default=200)
    ap.add_argument("--baseline", default=BASELINE, help=f"git revision of the baseline (default {BASELINE})")
    args = ap.parse_args(argv)
    base, base_table = load_baseline(args.baseline)
    dyn = read_modes_json(ROOT / "docs" / "stability_modes_example.json")
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=args.flutes, helix_angle=30.0)
    if args.results:
        maps, dz = results_maps(args.results, args.slice_height)
        label = f"{args.results} ({len(maps)} CLs)"
    else:
        maps, dz = synthetic_maps(args.cls), 0.5
        label = f"{len(maps)} synthetic CLs, all different"
    rpm = [args.rpm] * len(maps)
    new = bench_zoa(current_table, maps, tool, AL7075_T6_CARBIDE, dyn, rpm, dz)
    old = bench_zoa(base_table, maps, tool, AL7075_T6_CARBIDE, dyn, rpm, dz)
    print(f"ZOA per CL, {label}, {args.rpm:g} rev/min:")
    print(f"  current {1e3 * new / len(maps):.3f} ms/CL   baseline {1e3 * old / len(maps):.3f} ms/CL   "
          f"ratio {old / new:.2f}x")
    for case in sd_cases():
        t_new, lim_new = bench_sd(current, case, args.speeds)
        t_old, lim_old = bench_sd(base, case, args.speeds)
        diff = np.nanmax(np.abs(lim_new / lim_old - 1))
        print(f"SD lobes, {args.speeds} speeds, {case[0]}:")
        print(f"  current {t_new:.3f} s   baseline {t_old:.3f} s   ratio {t_old / t_new:.2f}x   "
              f"largest relative difference of the limits {diff:.1e}")


if __name__ == "__main__":
    main()
