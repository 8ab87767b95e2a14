"""Chatter stability of a whole program, CL by CL (issue 27): the table ``fusioncut stability``
writes, from the per-CL limits of :mod:`fusioncut.analysis.stability` (ZOA, SD, the nearest stable
speed). CLs with equal engagement, speed and flute count share one computation."""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from fusioncut.analysis.dynamics import ToolDynamics
from fusioncut.analysis.forces import CuttingCoefficients
from fusioncut.analysis.stability import (ChatterGrid, CLDirectional, ModalSystem, chatter_grid, cl_directional,
                                          sd_a_lim, zoa_limit_and_nearest_many)
from fusioncut.errors import InputError
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.tools import MillingTool


STABILITY_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("cl", "", "CL index"),
    ("file", "", "source file of the move"),
    ("line", "", "1-based source line"),
    ("operation", "", "operation"),
    ("status", "", "engagement status of the CL (engaged, air, rapid, failed)"),
    ("spindle_rpm", "1/min", "spindle speed"),
    ("ap_mm", "mm", "axial depth of cut of the CL"),
    ("a_lim_zoa_mm", "mm", "limiting axial depth, zero-order approximation (inf: no engaged edge)"),
    ("a_lim_sd_mm", "mm", "limiting axial depth, semi-discretization (NaN: not computed)"),
    ("margin", "", "ap / the smaller limit (ZOA's where SD is NaN): below 1 stable, 1 or more chatter "
                   "predicted"),
    ("nearest_stable_rpm", "1/min", "nearest speed in the searched range where the ZOA limit exceeds ap "
                                     "(the CL's own speed when stable; NaN: none)"),
)
"""Columns of :func:`stability_table`: (name, unit, meaning)."""


def _key(*arrays: np.ndarray) -> bytes:
    """Cache key of arrays rounded to 1e-9 (equal engagements of a program's CLs share their limits): the
    arrays' sizes, then their values, rounded in one call."""
    flat = [np.asarray(a, dtype=float).ravel() for a in arrays]
    sizes = np.array([len(a) for a in flat], dtype=float)
    return np.round(np.concatenate([sizes, *flat]), 9).tobytes()


def _limits(todo: list[tuple[bytes, tuple[CLDirectional, float]]], grid: ChatterGrid, system: ModalSystem,
            ktc: float, sd: bool, sd_steps: int, sd_max_steps: int | None,
            rpm_range: tuple[float, float] | None) -> dict[bytes, tuple[float, float, float]]:
    """ZOA limit (:func:`zoa_a_lim_many`), SD limit (NaN without ``sd``) and nearest stable speed (for the
    CLs unstable by ZOA) of each distinct engagement of one tool."""
    out: dict[bytes, tuple[float, float, float]] = {}
    if not todo:
        return out
    flutes = todo[0][1][0].flutes  # one tool
    speed = np.array([n for _, (_, n) in todo])
    lo, hi = rpm_range if rpm_range is not None else (0.5 * speed, 1.5 * speed)
    zoa, near = zoa_limit_and_nearest_many(np.array([cd.alpha0 for _, (cd, _) in todo]), grid, ktc, flutes, speed,
                                           np.array([cd.ap for _, (cd, _) in todo]), lo, hi)
    for j, (key, (cd, n)) in enumerate(todo):
        sdl = math.nan
        if sd:
            ref = zoa[j] if math.isfinite(zoa[j]) else cd.ap
            sdl = float(sd_a_lim(cd, system, ktc, n, ref, steps=sd_steps, max_steps=sd_max_steps)[0])
        out[key] = (float(zoa[j]), sdl, float(near[j]))
    return out


def stability_table(
    maps: Sequence[EngagementMap],
    tool: MillingTool,
    coefficients: CuttingCoefficients,
    dynamics: ToolDynamics,
    rpm: Sequence[float | None],
    *,
    dz: float | None = None,
    sd: bool = True,
    sd_steps: int = 30,
    sd_max_steps: int | None = 120,
    rpm_range: tuple[float, float] | None = None,
):  # -> pandas.DataFrame
    """Per-CL stability (columns :data:`STABILITY_COLUMNS`), one row per map, for one tool.

    ``rpm``: the spindle speed of each map (None: unknown, the row's limits are NaN, as for rapids and
    failed CLs). ``sd_max_steps``: see :func:`sd_a_lim` (its NaN rows take the ZOA limit alone for
    the margin). ``rpm_range`` (rev/min): where :func:`nearest_stable_rpm` searches; by default 0.5 to
    1.5 times the CL's speed. CLs with equal bands, speed and flute count share one computation.
    """
    import pandas as pd

    if len(rpm) != len(maps):
        raise InputError(f"{len(rpm)} spindle speeds for {len(maps)} CLs")
    grid = chatter_grid(dynamics)
    system = ModalSystem.from_dynamics(dynamics)
    ktc = coefficients.ktc
    names = [c[0] for c in STABILITY_COLUMNS]
    rows = []
    pending: dict[bytes, tuple[CLDirectional, float]] = {}  # one computation per distinct engagement
    keys: list[tuple[int, bytes, float]] = []  # (row, key, ap)
    for emap, n in zip(maps, rpm):
        row: dict[str, object] = dict.fromkeys(names, math.nan)
        row.update(cl=emap.cl_index, file=str(emap.source.file), line=int(emap.source.line),
                   operation=emap.operation, status=emap.status.value, spindle_rpm=math.nan if not n else float(n),
                   ap_mm=float(emap.ap))
        rows.append(row)
        if emap.status in (CLStatus.FAILED, CLStatus.RAPID) or not n:
            continue
        if not (n > 0 and math.isfinite(n)):
            raise InputError(f"CL {emap.cl_index}: spindle speed must be > 0 rev/min, got {n}", emap.source)
        cd = cl_directional(emap, tool, coefficients, dz)
        if not cd.engaged:
            row.update(a_lim_zoa_mm=math.inf, a_lim_sd_mm=math.inf if sd else math.nan, margin=0.0,
                       nearest_stable_rpm=float(n))
            continue
        b = cd.bands
        key = _key(cd.alpha0, cd.frame, cd.lag, b.area, b.sk, b.ck, b.entry, b.span, np.array([n, cd.flutes, cd.ap]))
        pending.setdefault(key, (cd, float(n)))
        keys.append((len(rows) - 1, key, cd.ap))
    done = _limits(list(pending.items()), grid, system, ktc, sd, sd_steps, sd_max_steps, rpm_range)
    for i, key, ap in keys:
        zoa, sdl, near = done[key]
        limit = zoa if math.isnan(sdl) else min(zoa, sdl)
        rows[i].update(a_lim_zoa_mm=zoa, a_lim_sd_mm=sdl, margin=ap / limit, nearest_stable_rpm=near)
    df = pd.DataFrame(rows, columns=names)
    return df.astype({"cl": "int64", "line": "int64", "file": "string", "operation": "string", "status": "string"})
