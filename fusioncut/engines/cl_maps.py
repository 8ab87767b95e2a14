"""The kernel-free half of a CL: its place in the program, its slice bands, and the assembly of its
:class:`~fusioncut.model.engagement.EngagementMap` from what the kernel reported.

An engine cuts a CL (kernel work, :class:`CutOutcome` out), lays out the slice bands over the flute
contact (:func:`slice_heights`), asks the kernel for the machine arcs of each band, and assembles
the map here (:func:`engagement_map`). Nothing here holds a kernel object, so a parallel driver
assembles maps from what its workers sent back exactly as the single-process engine does.
"""
from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import NamedTuple

from fusioncut.engines.base import EngineOptions, SweepMethod
from fusioncut.engines.chip import horizontal_travel, summed, without_rubbing
from fusioncut.engines.segments import horizontal_direction, segments_for
from fusioncut.errors import InputError
from fusioncut.model.angles import immersion_from_machine
from fusioncut.model.engagement import AngleInterval, CLStatus, EngagementMap, SliceEngagement
from fusioncut.model.moves import Move, Toolpath
from fusioncut.model.tools import MillingTool, SpindleDirection

__all__ = ["CL", "CutOutcome", "SliceHeight", "cl_base", "cl_sequence", "engagement_map", "slice_heights"]


class CL(NamedTuple):
    """One CL segment as an engine runs it: its index, the segment, its tool and the feed angle
    (degrees, counter-clockwise from +X, of the last horizontal motion up to it)."""

    index: int
    move: Move
    tool: MillingTool
    feed_angle: float


class SliceHeight(NamedTuple):
    """A slice band [k, k+1) * dz above the tip: the height (mm above the tip) it is evaluated at, and
    whether the flute contact reaches into it (``in_contact``)."""

    z: float
    in_contact: bool


@dataclass
class CutOutcome:
    """What one CL did to a set of cells, without kernel objects (so it can cross processes).

    ``removed`` mm³, areas mm², ``z_range`` (mm above the tip) of the flute contact, ``timings`` ms.
    ``method``: how the sweep was built (None: no sweep was built). ``band_volumes``: the volume
    (mm³) removed in each slice band above the tip at the CL's end
    (:func:`fusioncut.engines.chip.band_volumes`; () where nothing was removed), known where every
    cell that lost material was layered (a layer's cut knows its lost area and heights); a solid
    cell's Boolean gives only its total, so where one lost material they are None (unknown: no band
    of that CL is called rubbing). ``warnings``: what the engine knows to be approximate in the cut.
    """

    status: CLStatus
    removed: float = 0.0
    method: SweepMethod | None = None
    reason: str = ""
    flute_area: float = 0.0
    shank_area: float = 0.0
    z_range: tuple[float, float] | None = None
    timings: dict[str, float] = field(default_factory=dict)
    band_volumes: tuple[float, ...] | None = ()
    warnings: tuple[str, ...] = ()

    def merged(self, other: CutOutcome) -> CutOutcome:
        """The outcome over both sets of cells (parallel partitions of one IPW)."""
        order = [CLStatus.FAILED, CLStatus.ENGAGED, CLStatus.RAPID, CLStatus.AIR]
        status = min(self.status, other.status, key=order.index)
        zr = [r for r in (self.z_range, other.z_range) if r is not None]
        timings = {k: max(self.timings.get(k, 0.0), other.timings.get(k, 0.0)) for k in {*self.timings, *other.timings}}
        return CutOutcome(status, self.removed + other.removed, self.method or other.method,
                          "; ".join(r for r in (self.reason, other.reason) if r),
                          self.flute_area + other.flute_area, self.shank_area + other.shank_area,
                          (min(r[0] for r in zr), max(r[1] for r in zr)) if zr else None, timings,
                          summed(self.band_volumes, other.band_volumes),
                          tuple(dict.fromkeys(self.warnings + other.warnings)))


def cl_sequence(toolpath: Toolpath, options: EngineOptions, default_tool: MillingTool | None = None,
                start_at: int = 0, exact_arcs: bool = False) -> Iterator[CL]:
    """Every CL segment of ``toolpath`` from ``start_at`` on; the CLs before it only carry the feed
    direction forward. A move without a tool of its own takes ``default_tool``; a move with neither
    is an :class:`~fusioncut.errors.InputError` naming its source line. ``exact_arcs``: as
    :func:`~fusioncut.engines.segments.cl_segments` takes it."""
    feed_angle = 0.0
    for index, move in enumerate(segments_for(toolpath.moves, options, exact_arcs)):
        d = horizontal_direction(move)
        if d is not None:
            feed_angle = math.degrees(math.atan2(d[1], d[0])) % 360.0
        if index < start_at:
            continue
        tool = toolpath.tools.get(move.tool) if move.tool is not None else None
        tool = tool or default_tool
        if tool is None:
            raise InputError(f"no tool definition for T{move.tool}", move.source)
        yield CL(index, move, tool, feed_angle)


def cl_base(cl: CL) -> dict:
    """The fields of a CL's map that come from the program, not from the cut."""
    move, tool = cl.move, cl.tool
    return dict(cl_index=cl.index, position=move.end, start=move.start, tool=tool.label, spindle=tool.spindle,
                feed_angle=cl.feed_angle, source=move.source, feed=move.feed, operation=move.operation)


def slice_heights(z_range: tuple[float, float] | None, tool: MillingTool, dz: float) -> list[SliceHeight]:
    """Each slice band [k, k+1) * dz (mm) up to the flute contact's top, ``z_range`` (mm above the tip).

    A band is evaluated in the middle of its part in contact, so a shallow cut (ap < dz/2) still gets
    its slice and the height never sits on the material's edge.

    >>> from fusioncut.model.tools import FlatEndMill
    >>> slice_heights((0.0, 1.5), FlatEndMill(6, 15), 1.0)
    [SliceHeight(z=0.5, in_contact=True), SliceHeight(z=1.25, in_contact=True)]
    """
    if z_range is None:
        return []
    z_lo, z_hi = z_range
    out = []
    for k in range(math.ceil(min(z_hi, tool.flute_length) / dz - 1e-9)):
        lo, hi = max(k * dz, z_lo), min((k + 1) * dz, z_hi)
        out.append(SliceHeight(0.5 * (lo + hi), True) if hi > lo else SliceHeight((k + 0.5) * dz, False))
    return out


def engagement_map(cl: CL, outcome: CutOutcome, heights: list[SliceHeight], arcs: list[list[tuple[float, float]]],
                   slice_height: float = 1.0, min_chip_thickness: float = 0.0) -> EngagementMap:
    """Assemble the map of a CL from its cut outcome and the machine arcs (rad) of each slice.

    ``heights`` and ``arcs`` hold one entry per slice band of ``slice_height`` (mm) from the tip up.
    A band whose removed width across the path is under ``min_chip_thickness`` (mm,
    :mod:`fusioncut.engines.chip`) only rubs: its arcs are left out, counted in ``rubbing_slices``
    and warned about, and ``axial_range`` is clamped to the bands that cut (``contact_area`` still
    holds the whole flute contact).
    """
    base = cl_base(cl)
    warnings = list(outcome.warnings)
    if outcome.status == CLStatus.RAPID and outcome.removed > 0:
        warnings.append(f"rapid move cuts {outcome.removed:.4g} mm³ of material")
    if outcome.shank_area > 0:
        warnings.append("the shank touches the material")
    if outcome.status == CLStatus.ENGAGED and outcome.z_range is None and outcome.removed > 0:
        # Engagement is the contact of the tool at the CL's end; a segment that leaves the material
        # (an exit, a ramp out of a pocket) removes material on its way and may end with none there.
        warnings.append(f"removes {outcome.removed:.4g} mm³ along the segment but ends clear of the material: "
                        "no engagement at the CL's end")
    common = dict(status=outcome.status, removed_volume=outcome.removed,
                  sweep_method=outcome.method.value if outcome.method else "",
                  reason=outcome.reason, warnings=tuple(warnings), timings_ms=tuple(outcome.timings.items()),
                  shank_contact_area=outcome.shank_area)
    if outcome.status == CLStatus.FAILED or outcome.z_range is None:
        return EngagementMap(**base, **common)
    arcs, axial_range, rubbing = without_rubbing(arcs, outcome.band_volumes, outcome.z_range, slice_height,
                                                 horizontal_travel(cl.move), min_chip_thickness)
    if rubbing:
        warnings.append(f"{rubbing} slice(s) only rub (removed width under the minimum chip thickness "
                        f"{min_chip_thickness:g} mm): left out of the engagement")
        common["warnings"] = tuple(warnings)
    profile = cl.tool.profile()
    slices = []
    for (z, _), slice_arcs in zip(heights, arcs):
        intervals = sorted(_immersion(a, w, cl.feed_angle, cl.tool.spindle) for a, w in slice_arcs)
        slices.append(SliceEngagement(z=z, z_machine=cl.move.end[2] + z, radius=profile.radius_at(z),
                                      intervals=tuple(AngleInterval(e, x) for e, x in intervals)))
    return EngagementMap(**base, **common, slices=tuple(slices), contact_area=outcome.flute_area,
                         axial_range=axial_range, rubbing_slices=rubbing)


def _immersion(start: float, span: float, feed_angle: float, spindle: SpindleDirection) -> tuple[float, float]:
    """Machine arc (rad, counter-clockwise from ``start``) -> immersion (entry, exit) in degrees."""
    a, w = math.degrees(start), math.degrees(span)
    if w >= 360.0 - 1e-9:
        return 0.0, 360.0  # engaged all round (plunge): no entry or exit
    # the teeth of a clockwise spindle meet the counter-clockwise end of the arc first
    first = a + w if spindle == SpindleDirection.CW else a
    entry = immersion_from_machine(first, feed_angle, spindle)
    if abs(entry - 360.0) < 1e-7:  # 0 by another name; the analytic engine's arc ends are found to 1e-10 rad
        entry = 0.0
    return entry, entry + w
