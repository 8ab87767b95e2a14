"""Engagement maps rebuilt from saved result tables, for the force model and feed advice.

A results folder (:func:`fusioncut.io.results.load_results`) keeps every engaged arc of every slice,
the slice height the engine ran with, and each slice's band ``[z_lo_mm, z_hi_mm]`` (mm above the tip:
the engine's band ``[k, k+1) * dz`` clipped to the flute contact). :func:`engagement_maps_from_results`
turns the rows back into :class:`~fusioncut.model.engagement.EngagementMap` s whose axial contact range
spans the recorded bands, so :func:`fusioncut.analysis.forces.compute_cl_forces` with the recorded slice
height (:func:`results_slice_height`) rebuilds the engine's bands exactly. Folders written before the
slice height and bands were recorded need the slice height given (nothing is guessed); their bands
come from the engine's slice rule inverted.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from fusioncut.errors import InputError, SourceLocation
from fusioncut.model.engagement import AngleInterval, CLStatus, EngagementMap, SliceEngagement
from fusioncut.model.tools import SpindleDirection

if TYPE_CHECKING:  # the tables' reader brings pandas; the maps need only what it loaded
    from fusioncut.io.results import Results


def results_slice_height(results: Results, dz: float | None = None) -> float:
    """The engine's slice height (mm) of ``results``: the recorded one (:attr:`Results.slice_height`).
    ``dz`` (mm) is for folders written before it was recorded; given where it is recorded, it must
    agree. An older folder without ``dz`` is an :class:`InputError` asking for it."""
    if dz is not None and not (dz > 0 and math.isfinite(dz)):
        raise InputError(f"slice height must be > 0 mm, got {dz}", results.path)
    if results.slice_height is None:
        return results.require_slice_height() if dz is None else float(dz)
    if dz is not None and abs(dz - results.slice_height) > 1e-9 * max(1.0, dz):
        raise InputError(f"the results were computed with slice height {results.slice_height:g} mm, not {dz:g} mm "
                         "(leave --slice-height out)", results.path)
    return results.slice_height


def _axial_range(bands: np.ndarray, zs: list[float], ap: float, dz: float) -> tuple[float, float]:
    """A CL's flute contact range (mm above the tip) from its slices' recorded bands (rows
    ``[z_lo, z_hi]``: the range runs from the lowest band's bottom to the highest band's top, which
    gives the engine's bands back exactly), or, for folders written before bands were recorded, from
    the engine's slice rule inverted: the lowest slice ``z0`` of cell ``k0`` sits in the middle of
    ``[max(k0 dz, a0), ...]``, so ``a0 = 2 z0 - (k0+1) dz`` when clipped, and alike at the top; a single
    slice gives ``z -/+ ap/2``."""
    if len(bands) and not np.isnan(bands).any():
        return float(bands[:, 0].min()), float(bands[:, 1].max())
    z0, z1 = zs[0], zs[-1]
    if len(zs) == 1:
        return z0 - 0.5 * ap, z0 + 0.5 * ap
    k0, k1 = math.floor(z0 / dz + 1e-9), math.floor(z1 / dz + 1e-9)
    return max(k0 * dz, 2 * z0 - (k0 + 1) * dz), min((k1 + 1) * dz, 2 * z1 - k1 * dz)


def engagement_maps_from_results(results: Results, dz: float | None = None) -> list[EngagementMap]:
    """Engagement maps rebuilt from loaded result tables (:func:`fusioncut.io.results.load_results`),
    one per ``cl`` row, in table order, for the force model (pass the same slice height, see
    :func:`results_slice_height`, to :func:`compute_cl_forces` to get the engine's bands back).

    Each map's ``axial_range`` is rebuilt from its slices' recorded bands (:func:`_axial_range`; from
    the slice rule and ``dz`` for older folders). Timings and non-engaged slices are not in the
    tables and are left out.
    """
    cl = results.cl
    sl = results.slices
    dz = results_slice_height(results, dz)
    by_cl: dict[int, list[SliceEngagement]] = {}
    bands: dict[int, list[tuple[float, float]]] = {}
    if len(sl):
        sl = sl.sort_values(["cl", "z_tool_mm", "interval"], kind="stable")
        for (c, z), g in sl.groupby(["cl", "z_tool_mm"], sort=False):
            ivs = tuple(AngleInterval(float(a), float(b)) for a, b in zip(g["entry_deg"], g["exit_deg"]))
            first = g.iloc[0]
            by_cl.setdefault(int(c), []).append(SliceEngagement(
                z=float(z), z_machine=float(first["z_machine_mm"]), radius=float(first["radius_mm"]), intervals=ivs))
            bands.setdefault(int(c), []).append((float(first["z_lo_mm"]), float(first["z_hi_mm"])))
    out = []
    for row in cl.itertuples(index=False):
        slices = tuple(by_cl.get(int(row.cl), ()))
        axial = (0.0, 0.0)
        if slices:
            axial = _axial_range(np.array(bands[int(row.cl)], dtype=float), [s.z for s in slices], float(row.ap_mm), dz)
        feed = None if math.isnan(row.feed_mm_min) else float(row.feed_mm_min)
        out.append(EngagementMap(
            cl_index=int(row.cl), position=(float(row.x), float(row.y), float(row.z)),
            start=(float(row.x0), float(row.y0), float(row.z0)), tool=str(row.tool),
            spindle=SpindleDirection(str(row.spindle)), feed_angle=float(row.feed_angle_machine_deg),
            status=CLStatus(str(row.status)), source=SourceLocation(str(row.file), int(row.line)), feed=feed,
            operation=str(row.operation), slices=slices, contact_area=float(row.contact_area_mm2),
            shank_contact_area=float(row.shank_contact_area_mm2), removed_volume=float(row.removed_volume_mm3),
            reason=str(row.reason), warnings=tuple(w for w in str(row.warnings).split(" | ") if w),
            sweep_method=str(row.sweep_method), axial_range=axial, rubbing_slices=int(row.rubbing_slices),
        ))
    return out
