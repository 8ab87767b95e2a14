"""Spindle speed advice from chatter stability: per operation, the margin at the programmed speed and the
nearest speed at which every CL of the operation keeps a given margin.

A CL's margin is ``ap / a_lim`` with the ZOA limit of :mod:`fusioncut.analysis.stability` (< 1 stable).
Holding ``margin <= max_margin`` means ``a_lim > ap / max_margin`` for every engaged CL of the operation
at one spindle speed (an operation runs at one speed): the suggested speed is the nearest one to the
programmed speed, within the searched range, where all CLs do (:func:`~fusioncut.analysis.stability.
nearest_speed_for_all` of the CLs' distinct engagements). The ZOA limit does not depend on the feed:
lowering the feed cannot remove chatter, only the speed (or the depth) can.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from fusioncut.analysis.dynamics import ToolDynamics
from fusioncut.analysis.forces import CuttingCoefficients
from fusioncut.analysis.stability import (DepthNeed, chatter_grid, cl_directional, nearest_speed_for_all,
                                          zoa_a_lim_many, zoa_curves)
from fusioncut.errors import InputError
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.tools import MillingTool

SPEED_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("operation", "", "operation"),
    ("tool", "", "tool label"),
    ("spindle_rpm", "1/min", "programmed spindle speed"),
    ("engaged_cls", "", "engaged CLs of the operation at that speed"),
    ("margin_max", "", "largest margin ap / a_lim (ZOA) at the programmed speed"),
    ("worst_cl", "", "CL with that margin"),
    ("suggested_rpm", "1/min", "nearest speed where every CL's margin is at most max_margin (the programmed "
                               "speed when it holds; NaN: no speed in the searched range)"),
    ("margin_max_suggested", "", "largest margin at the suggested speed"),
)
"""Columns of :func:`advise_speeds`: (name, unit, meaning)."""


def advise_speeds(
    maps: Sequence[EngagementMap],
    tool: MillingTool,
    coefficients: CuttingCoefficients,
    dynamics: ToolDynamics,
    rpm: Sequence[float | None],
    *,
    max_margin: float,
    dz: float | None = None,
    rpm_range: tuple[float, float] | None = None,
):  # -> pandas.DataFrame
    """One row per (operation, programmed speed) of one tool (columns :data:`SPEED_COLUMNS`).

    ``rpm``: each map's spindle speed (None: the CL is left out, as are rapids, failed and unengaged
    CLs). ``max_margin`` (> 0): the largest margin to hold. ``rpm_range`` (rev/min): where to search;
    by default 0.5 to 1.5 times the programmed speed.
    """
    import pandas as pd

    if not (max_margin > 0 and math.isfinite(max_margin)):
        raise InputError(f"the largest margin must be > 0, got {max_margin}")
    if len(rpm) != len(maps):
        raise InputError(f"{len(rpm)} spindle speeds for {len(maps)} CLs")
    grid = chatter_grid(dynamics)
    ktc, flutes = coefficients.ktc, tool.flutes
    groups: dict[tuple[str, float], list] = {}
    for emap, n in zip(maps, rpm):
        if emap.status != CLStatus.ENGAGED or not n:
            continue
        cd = cl_directional(emap, tool, coefficients, dz)
        if cd.engaged:
            groups.setdefault((emap.operation or "", float(n)), []).append(cd)
    rows = []
    for (operation, n), cds in groups.items():
        distinct: dict[tuple[bytes, float], object] = {}
        for cd in cds:  # the ZOA limit depends on the directional factors and the depth alone
            distinct.setdefault((np.round(cd.alpha0, 12).tobytes(), round(cd.ap, 9)), cd)
        cls_ = list(distinct.values())
        alphas = np.array([cd.alpha0 for cd in cls_])
        ap = np.array([cd.ap for cd in cls_])
        margin = ap / zoa_a_lim_many(alphas, grid, ktc, flutes, np.full(len(cls_), n))
        worst = int(np.argmax(margin))
        suggested, at_suggested = n, float(margin.max())
        if margin.max() > max_margin:
            lo, hi = rpm_range if rpm_range is not None else (0.5 * n, 1.5 * n)
            needs = [DepthNeed.of(grid, zoa_curves(cd.alpha0, grid, ktc, flutes), flutes, cd.ap / max_margin, lo, hi)
                     for cd in cls_]
            suggested = nearest_speed_for_all(needs, flutes, n, lo, hi)
            at_suggested = (float((ap / zoa_a_lim_many(alphas, grid, ktc, flutes, np.full(len(cls_), suggested))).max())
                            if math.isfinite(suggested) else math.nan)
        rows.append(dict(operation=operation, tool=tool.label, spindle_rpm=n, engaged_cls=len(cds),
                         margin_max=float(margin.max()), worst_cl=int(cls_[worst].cl_index),
                         suggested_rpm=float(suggested), margin_max_suggested=at_suggested))
    df = pd.DataFrame(rows, columns=[c[0] for c in SPEED_COLUMNS])
    return df.astype({"operation": "string", "tool": "string", "engaged_cls": "int64", "worst_cl": "int64"})
