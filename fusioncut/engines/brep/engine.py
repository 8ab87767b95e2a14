"""The exact B-Rep engagement engine (OpenCASCADE through OCP).

Per CL segment: exact swept volume -> removed = IPW ∩ sweep and IPW = IPW − sweep from one shared
intersection (``BOPAlgo_PaveFiller``) -> contact faces = images of the sweep's faces in the new IPW that
lie on the tool at the end CL -> slicing. Whole-IPW Booleans; faces on the same surface are merged
whenever the IPW's face count grew by ``merge_growth`` since the last merge (measured in
../shared/notes: without merging the IPW fragments and every Boolean slows down).

A failed Boolean is retried with fuzzy values; if it still fails the CL is reported FAILED with the
reason, both shapes are written as .brep for reproduction, the IPW stays as it was and the run goes
on. Removed volume is checked against the IPW's volume change on every CL.
"""
from __future__ import annotations

import json
import logging
import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

from OCP.BOPAlgo import BOPAlgo_PaveFiller
from OCP.BRepAlgoAPI import BRepAlgoAPI_Common, BRepAlgoAPI_Cut
from OCP.TopoDS import TopoDS, TopoDS_Shape

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.contact import find_contact_faces, slice_intervals
from fusioncut.engines.brep.occ import (
    bounding_box, boxes_overlap, count_faces, faces, read_binary_brep, shape_list, unify, volume, write_binary_brep, write_brep,
)
from fusioncut.engines.brep.stock import stock_solid
from fusioncut.engines.brep.sweep import swept_volume
from fusioncut.engines.segments import cl_segments, horizontal_direction
from fusioncut.errors import InputError
from fusioncut.model.angles import immersion_from_machine
from fusioncut.model.engagement import AngleInterval, CLStatus, EngagementMap, SliceEngagement
from fusioncut.model.moves import Move, Toolpath
from fusioncut.model.stock import Stock
from fusioncut.model.tools import MillingTool, SpindleDirection

log = logging.getLogger("fusioncut.engine")


class BooleanFailure(Exception):
    pass


@dataclass
class BRepEngine:
    """Exact engine. ``ipw`` is the in-process workpiece after the last processed CL."""

    options: EngineOptions = field(default_factory=EngineOptions)
    ipw: TopoDS_Shape | None = None
    stock_volume: float = 0.0
    removed_total: float = 0.0
    _faces_at_merge: int = 0

    # -- public -------------------------------------------------------------------------------
    def start(self, stock: Stock | TopoDS_Shape) -> None:
        self.ipw = stock if isinstance(stock, TopoDS_Shape) else stock_solid(stock)
        self.stock_volume = volume(self.ipw)
        self.removed_total = 0.0
        self._faces_at_merge = count_faces(self.ipw)

    @property
    def ipw_volume(self) -> float:
        return volume(self.ipw)

    def run(self, toolpath: Toolpath, stock: Stock, default_tool: MillingTool | None = None) -> Iterator[EngagementMap]:
        self.start(stock)
        yield from self.process(toolpath, default_tool)

    def process(self, toolpath: Toolpath, default_tool: MillingTool | None = None,
                start_at: int = 0) -> Iterator[EngagementMap]:
        """Run the CL segments of ``toolpath`` on the current IPW, from CL index ``start_at`` on.

        The CLs before ``start_at`` are taken as done (a resumed run whose IPW comes from
        :meth:`load_checkpoint`); they only carry the feed direction forward.
        """
        opts = self.options
        feed_angle = 0.0
        for index, move in enumerate(cl_segments(toolpath.moves, opts.max_segment_length, opts.chord_tolerance)):
            d = horizontal_direction(move)
            if d is not None:
                feed_angle = math.degrees(math.atan2(d[1], d[0])) % 360.0
            if index < start_at:
                continue
            tool = toolpath.tools.get(move.tool) if move.tool is not None else None
            tool = tool or default_tool
            if tool is None:
                raise InputError(f"no tool definition for T{move.tool}", move.source)
            yield self.step(index, move, tool, feed_angle)

    def save_checkpoint(self, folder: Path, next_cl: int) -> None:
        """Write the engine state atomically into ``folder`` (IPW as .brep, counters as JSON).

        ``next_cl`` is the index of the first CL not yet processed. The BRep text format keeps
        doubles exactly, so a run resumed from here gives the same results as one never stopped.
        """
        folder.mkdir(parents=True, exist_ok=True)
        name = f"ipw-{next_cl:07d}.bbrep"
        write_binary_brep(self.ipw, str(folder / (name + ".tmp")))
        os.replace(folder / (name + ".tmp"), folder / name)
        state = {"next_cl": next_cl, "ipw": name, "stock_volume": self.stock_volume,
                 "removed_total": self.removed_total, "faces_at_merge": self._faces_at_merge}
        (folder / "state.json.tmp").write_text(json.dumps(state))
        os.replace(folder / "state.json.tmp", folder / "state.json")
        for old in folder.glob("ipw-*.bbrep"):
            if old.name != name:
                old.unlink(missing_ok=True)

    def load_checkpoint(self, folder: Path) -> int | None:
        """Restore the state saved by :meth:`save_checkpoint`; the next CL index, or None if none."""
        try:
            state = json.loads((folder / "state.json").read_text())
            ipw = read_binary_brep(str(folder / state["ipw"]))
        except (OSError, ValueError, KeyError):
            return None
        if ipw.IsNull():
            return None
        self.ipw = ipw
        self.stock_volume = state["stock_volume"]
        self.removed_total = state["removed_total"]
        self._faces_at_merge = state["faces_at_merge"]
        return int(state["next_cl"])

    def step(self, index: int, move: Move, tool: MillingTool, feed_angle: float) -> EngagementMap:
        """Process one CL segment; never raises for kernel trouble (the map says FAILED)."""
        base = dict(cl_index=index, position=move.end, start=move.start, tool=tool.label, spindle=tool.spindle,
                    feed_angle=feed_angle, source=move.source, feed=move.feed, operation=move.operation)
        timings: dict[str, float] = {}
        t0 = time.perf_counter()
        seam = math.radians(feed_angle) + math.pi  # seams behind the tool, away from the engaged side
        try:
            sweep = swept_volume(tool, move, self.options.sweep, seam)
        except Exception as exc:  # noqa: BLE001 - kernel failures become a FAILED CL, never a crash
            return EngagementMap(**base, status=CLStatus.FAILED, reason=f"sweep construction failed: {exc}")
        t1 = time.perf_counter()
        timings["sweep"] = (t1 - t0) * 1e3
        status_if_cut = CLStatus.RAPID if move.is_rapid else CLStatus.ENGAGED
        if not boxes_overlap(bounding_box(sweep.shape), bounding_box(self.ipw)):
            return EngagementMap(**base, status=CLStatus.RAPID if move.is_rapid else CLStatus.AIR,
                                 sweep_method=sweep.method, timings_ms=tuple(timings.items()))
        try:
            removed, new_ipw, cut = self._subtract(sweep.shape)
        except BooleanFailure as exc:
            saved = self._save_failure(index, sweep.shape)
            log.error("CL %d (%s): Boolean failed: %s; shapes saved to %s", index, move.source, exc, saved)
            return EngagementMap(**base, status=CLStatus.FAILED, sweep_method=sweep.method,
                                 reason=f"Boolean failed after retries: {exc}; shapes saved to {saved}")
        t2 = time.perf_counter()
        timings["boolean"] = (t2 - t1) * 1e3
        warnings: list[str] = []
        if new_ipw is None:  # nothing removed: the tool only touches or misses the material
            return EngagementMap(**base, status=CLStatus.RAPID if move.is_rapid else CLStatus.AIR,
                                 sweep_method=sweep.method, timings_ms=tuple(timings.items()))
        self.ipw = new_ipw
        self.removed_total += removed
        if move.is_rapid:
            warnings.append(f"rapid move cuts {removed:.4g} mm³ of material")
        try:
            candidates = []
            for f in faces(sweep.shape):
                images = cut.Modified(f)
                if images.Size():
                    candidates.extend(TopoDS.Face(s) for s in images)
                elif not cut.IsDeleted(f):
                    candidates.append(f)
            contacts = find_contact_faces(candidates, tool, move.end)
            t3 = time.perf_counter()
            timings["contact"] = (t3 - t2) * 1e3
            result = self._engagement(base, tool, move, contacts, removed, warnings, sweep.method, status_if_cut)
            timings["slicing"] = (time.perf_counter() - t3) * 1e3
        except Exception as exc:  # noqa: BLE001
            result = EngagementMap(**base, status=CLStatus.FAILED, removed_volume=removed, sweep_method=sweep.method,
                                   reason=f"contact analysis failed: {exc}")
        self._maybe_merge()
        timings["total"] = (time.perf_counter() - t0) * 1e3
        return replace(result, timings_ms=tuple(timings.items()))

    # -- internals ----------------------------------------------------------------------------
    def _subtract(self, sweep: TopoDS_Shape):
        """(removed volume, new IPW or None when nothing is removed, the Cut with its history)."""
        last = "unknown"
        for fuzzy in (0.0, *self.options.fuzzy_retries):
            pf = BOPAlgo_PaveFiller()
            pf.SetArguments(shape_list([self.ipw, sweep]))
            if fuzzy:
                pf.SetFuzzyValue(fuzzy)
            pf.Perform()
            if pf.HasErrors():
                last = f"intersection reported errors (fuzzy={fuzzy})"
                continue
            common = BRepAlgoAPI_Common(self.ipw, sweep, pf)
            if not common.IsDone():
                last = f"common failed (fuzzy={fuzzy})"
                continue
            removed = volume(common.Shape())
            if removed <= 1e-12 * max(1.0, self.stock_volume):
                return 0.0, None, None
            cut = BRepAlgoAPI_Cut(self.ipw, sweep, pf)
            if not cut.IsDone():
                last = f"cut failed (fuzzy={fuzzy})"
                continue
            return removed, cut.Shape(), cut
        raise BooleanFailure(last)

    def _maybe_merge(self) -> None:
        n = count_faces(self.ipw)
        if n > (1 + self.options.merge_growth) * self._faces_at_merge:
            self.ipw = unify(self.ipw)
            self._faces_at_merge = count_faces(self.ipw)

    def _save_failure(self, index: int, sweep: TopoDS_Shape) -> str:
        folder = self.options.failure_dir or Path("fusioncut-failures")
        folder.mkdir(parents=True, exist_ok=True)
        write_brep(self.ipw, str(folder / f"cl{index:06d}_ipw.brep"))
        write_brep(sweep, str(folder / f"cl{index:06d}_sweep.brep"))
        return str(folder / f"cl{index:06d}_*.brep")

    def _engagement(self, base, tool, move, contacts, removed, warnings, method, status) -> EngagementMap:
        flute = [c for c in contacts if c.surface.zone == "flute"]
        shank = [c for c in contacts if c.surface.zone == "shank"]
        if shank:
            warnings.append("the shank touches the material")
        if not flute:
            return EngagementMap(**base, status=status, removed_volume=removed, sweep_method=method,
                                 shank_contact_area=sum(c.area for c in shank), warnings=tuple(warnings))
        dz = self.options.slice_height
        z_lo = min(c.z_range[0] for c in flute)
        z_hi = max(c.z_range[1] for c in flute)
        profile = tool.profile()
        n_slices = math.ceil(min(z_hi, tool.flute_length) / dz - 1e-9)
        slices = []
        for k in range(n_slices):
            # a band [k, k+1)*dz is evaluated in the middle of its part in contact, so a shallow cut
            # (ap < dz/2) still gets its slice and the height never sits on the material's edge
            lo, hi = max(k * dz, z_lo), min((k + 1) * dz, z_hi)
            z = 0.5 * (lo + hi) if hi > lo else (k + 0.5) * dz
            arcs = slice_intervals(flute, move.end, z) if hi > lo else []
            intervals = tuple(sorted(_immersion(a, w, base["feed_angle"], tool.spindle) for a, w in arcs))
            slices.append(SliceEngagement(z=z, z_machine=move.end[2] + z, radius=profile.radius_at(z),
                                          intervals=tuple(AngleInterval(e, x) for e, x in intervals)))
        return EngagementMap(**base, status=status, slices=tuple(slices), removed_volume=removed,
                             contact_area=sum(c.area for c in flute), shank_contact_area=sum(c.area for c in shank),
                             axial_range=(z_lo, z_hi), warnings=tuple(warnings), sweep_method=method)


def _immersion(start: float, span: float, feed_angle: float, spindle: SpindleDirection) -> tuple[float, float]:
    """Machine arc (rad, counter-clockwise from ``start``) -> immersion (entry, exit) in degrees."""
    a, w = math.degrees(start), math.degrees(span)
    if w >= 360.0 - 1e-9:
        return 0.0, 360.0  # engaged all round (plunge): no entry or exit
    # the teeth of a clockwise spindle meet the counter-clockwise end of the arc first
    first = a + w if spindle == SpindleDirection.CW else a
    entry = immersion_from_machine(first, feed_angle, spindle)
    if abs(entry - 360.0) < 1e-9:
        entry = 0.0
    return entry, entry + w
