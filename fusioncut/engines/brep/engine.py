"""The exact B-Rep engagement engine (OpenCASCADE through OCP).

Per CL segment: exact swept volume -> removed = IPW ∩ sweep and IPW = IPW − sweep from one shared
intersection (``BOPAlgo_PaveFiller``) -> contact faces = images of the sweep's faces in the new IPW that
lie on the tool at the end CL and were not already on the IPW's boundary (a wall the tool only grazes
loses nothing, so it is no engagement) -> slicing.

The IPW is kept as a grid of **cells** (``EngineOptions.cell_size`` mm square columns over the full
stock height; ``None``: one cell, the whole IPW). A CL touches only the cells its sweep's bounding box
overlaps, so each Boolean works on a bounded piece whatever the program's length: measured in
../shared/notes, whole-IPW Booleans grow with the faces an adaptive path leaves behind, cells keep
the cost flat. Of those, a cell skips its Booleans when the material's height bounds
(:mod:`fusioncut.engines.ceiling`) prove the sweep removes nothing there: a CL that runs through
material already cut away costs no Boolean. Both tests run on the tool's reach around the path
before the sweep is built, so such a CL does not build one either. Arcs split at a cell wall are
joined again when the slices are merged. Faces of a cell on the same surface are merged whenever
its face count grew by ``merge_growth`` since its last merge (without merging the IPW fragments and
every Boolean slows down).

A cell that only cylindrical tools have cut horizontally or vertically is kept as a stack of 2.5D
layers (``EngineOptions.layers``, :mod:`fusioncut.engines.brep.layers`): the CL's sweep is then a
planar region taken away from the layers above the tip by 2D differences (in closed form,
:mod:`fusioncut.engines.brep.planar`; OCCT's General Fuse where that cannot decide), and the
contact faces are the engaged arcs of each layer extruded over its height, sliced like any other.
A cut the layers cannot take (another tool, a ramp's oblique sweep, too many layers) turns the
cell into a solid; a solid cell whose faces are all horizontal or vertical again takes the layers
back at its next merge or level flat-end-mill cut, and one that such a cut leaves solid is split
into quarter squares (down to a quarter of ``cell_size``), so that only the part near what is not
2.5D stays solid.
Both forms give the same material and the same engagement (tested against an all-solid run).

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

from OCP.TopAbs import TopAbs_SOLID
from OCP.TopoDS import TopoDS, TopoDS_Shape

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.ceiling import MaterialCeiling, footprint, load_kernels, tool_radii
from fusioncut.engines.chip import band_volumes, horizontal_travel, summed, without_rubbing
from fusioncut.engines.brep.contact import arc_contacts, find_contact_faces, slice_intervals
from fusioncut.engines.brep.layers import (
    CuttingRegion, Layer, RegionCutFailure, contact_patches, cut_stack, layer_from_state, solid_layers, stack_box,
    stack_solid, stack_volume,
)
from fusioncut.engines.brep.occ import (
    bounding_box, boxes_overlap, children, compound, count_faces, face_map, faces, fuse_all, halves, intersections,
    on_old_boundary, pieces, quarters, read_binary_brep, solids, split_into_cells, split_pieces, strictly_inside, unify, volume,
    volume_change, without_slivers, write_binary_brep, write_brep,
)
from fusioncut.engines.brep.stock import stock_solid
from fusioncut.engines.brep.sweep import cylinder_region_outline, cylinder_tool, swept_volume
from fusioncut.engines.segments import horizontal_direction, segments_for, step_motion
from fusioncut.errors import InputError
from fusioncut.model.angles import immersion_from_machine
from fusioncut.model.engagement import AngleInterval, CLStatus, EngagementMap, SliceEngagement
from fusioncut.model.moves import ArcMove, Move, Toolpath
from fusioncut.model.stock import Stock
from fusioncut.model.tools import MillingTool, SpindleDirection

log = logging.getLogger("fusioncut.engine")


# a solid cell is split into quarters down to cell_size / MAX_SPLIT (20 mm cells: 5 mm; see _quarter)
MAX_SPLIT = 4


class BooleanFailure(Exception):
    pass


@dataclass
class Cell:
    """One column of the IPW: its material and bounding box (mm).

    The material is either a B-Rep ``solid`` or, while only cylindrical tools have cut it
    horizontally or vertically, a stack of 2.5D ``layers`` (:mod:`fusioncut.engines.brep.layers`);
    then the solid is built only when asked for (``shape``) and kept until the next cut.
    ``square`` is the column ``(x0, y0, size)`` of the grid the cell stands for (None: the whole
    workpiece in one cell); a solid cell may be split into its four quarter squares. ``swept`` maps
    each cutting region the layers took (its ``CuttingRegion.key``) to the lowest tip height (mm)
    it was taken from: above that the cell holds none of it, whatever came later, so a cut along
    the very same path deeper down (the next depth level of an adaptive clearing, the next pass of
    a contour) cuts only the layers below that height.
    """

    solid: TopoDS_Shape | None
    box: tuple[tuple[float, float, float], tuple[float, float, float]] | None
    faces_at_merge: int = 0
    volume: float = 0.0
    layers: tuple[Layer, ...] | None = None
    square: tuple[float, float, float] | None = None
    swept: dict[tuple, float] = field(default_factory=dict, repr=False)

    @property
    def empty(self) -> bool:
        return self.solid is None and not self.layers

    @property
    def shape(self) -> TopoDS_Shape | None:
        if self.solid is None and self.layers:
            self.solid = stack_solid(self.layers)
        return self.solid

    def set(self, shape: TopoDS_Shape | None, shape_volume: float | None = None) -> None:
        """The material as a solid from now on."""
        if shape is not None and not solids(shape):
            shape = None
        self.layers = None
        self.solid = shape
        self.box = bounding_box(shape) if shape is not None else None
        self.volume = 0.0 if shape is None else volume(shape) if shape_volume is None else shape_volume

    def set_layers(self, layers: tuple[Layer, ...]) -> None:
        self.layers = layers or None
        self.solid = None
        self.box = stack_box(layers) if layers else None
        self.volume = stack_volume(layers) if layers else 0.0

    def to_layers(self, max_layers: int) -> None:
        """Take the layered form when the solid is 2.5D (a box stock's cell, or one only flat end
        mills have cut) in at most ``max_layers`` layers."""
        if self.layers is None and self.solid is not None:
            layers = solid_layers(self.solid, max_layers)
            if layers is not None:
                # the solid goes too: built again from the layers when needed, it is the very shape
                # a run resumed from a checkpoint (which keeps the layers) builds, bit for bit
                self.set_layers(layers)

    def to_solid(self) -> None:
        """Leave the layered form (a cut the layers cannot take is coming)."""
        if self.layers is not None:
            self.set(self.shape, self.volume)


@dataclass
class BRepEngine:
    """Exact engine. ``ipw`` is the in-process workpiece after the last processed CL."""

    options: EngineOptions = field(default_factory=EngineOptions)
    cells: list[Cell] = field(default_factory=list)
    stock_volume: float = 0.0
    removed_total: float = 0.0
    # the material's height bounds, and the cell list they were built for: a new list (start,
    # checkpoint, a parallel worker's cells) gets fresh bounds, since old ones may claim too much air
    _ceiling: MaterialCeiling | None = field(default=None, init=False, repr=False)
    _ceiling_cells: list[Cell] | None = field(default=None, init=False, repr=False)
    # squares whose split lost volume: not tried again (a resumed run or a worker may try once more)
    _unsplittable: set[tuple[float, float, float]] = field(default_factory=set, init=False, repr=False)
    # the last CL's sweep and its volume (mm³): see _sweep_volume
    _last_sweep: tuple[TopoDS_Shape, float] | None = field(default=None, init=False, repr=False)
    # where the last CL's tool left no material, or None: (x, y, z_lo, z_hi, radius) mm of the
    # cylinder a cylindrical tool emptied (radius 0 for other tools) and the tool's repr; a cut
    # starting there may leave that tool out of its sweep (see _starts_cleared)
    cleared: tuple[float, float, float, float, float, str] | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        if self.options.ceiling_pixel is not None and self.options.sweep == "exact":
            load_kernels()  # here, not in the first CL's time

    # -- public -------------------------------------------------------------------------------
    def start(self, stock: Stock | TopoDS_Shape) -> None:
        solid = stock if isinstance(stock, TopoDS_Shape) else stock_solid(stock)
        self.stock_volume = volume(solid)
        self.removed_total = 0.0
        self.cleared = None
        self.cells = []
        for piece, square in split_into_cells(solid, self.options.cell_size):
            cell = Cell(None, None, count_faces(piece), square=square)
            cell.set(piece)
            self.cells.append(cell)
        self.adopt_layers()

    def adopt_layers(self) -> None:
        """Cells that are 2.5D take the layered form (when ``options.layers``)."""
        if self.options.layers and self.options.sweep == "exact":
            for cell in self.cells:
                cell.to_layers(self.options.max_layers)

    @property
    def ipw(self) -> TopoDS_Shape:
        """The whole in-process workpiece (a compound of the cells' solids when there are several)."""
        shapes = [c.shape for c in self.cells if not c.empty]
        return shapes[0] if len(shapes) == 1 else compound(shapes)

    @property
    def ipw_volume(self) -> float:
        return sum(volume(c.shape) for c in self.cells if not c.empty)

    def run(self, toolpath: Toolpath, stock: Stock, default_tool: MillingTool | None = None) -> Iterator[EngagementMap]:
        self.start(stock)
        yield from self.process(toolpath, default_tool)

    def process(self, toolpath: Toolpath, default_tool: MillingTool | None = None,
                start_at: int = 0) -> Iterator[EngagementMap]:
        """Run the CL segments of ``toolpath`` on the current IPW, from CL index ``start_at`` on.

        The CLs before ``start_at`` are taken as done (a resumed run whose IPW comes from
        :meth:`load_checkpoint`); they only carry the feed direction forward.
        """
        for index, move, tool, feed_angle in cl_sequence(toolpath, self.options, default_tool, start_at):
            yield self.step(index, move, tool, feed_angle)

    def save_checkpoint(self, folder: Path, next_cl: int) -> None:
        """Write the engine state atomically into ``folder`` (IPW as .brep, counters as JSON).

        ``next_cl`` is the index of the first CL not yet processed. The BRep text format keeps
        doubles exactly, so a run resumed from here gives the same results as one never stopped.
        """
        folder.mkdir(parents=True, exist_ok=True)
        name = f"ipw-{next_cl:07d}.bbrep"
        # one compound child per cell, in cell order: an empty compound for a cell cut away, the
        # solid, or a layered cell's regions (their heights go in the state): kept as layers, not
        # as their solid, so that the resumed run cuts the very same regions
        write_binary_brep(compound(compound([]) if c.empty else compound(la.region for la in c.layers) if c.layers
                                   else c.shape for c in self.cells),
                          str(folder / (name + ".tmp")))
        os.replace(folder / (name + ".tmp"), folder / name)
        state = {"next_cl": next_cl, "ipw": name, "stock_volume": self.stock_volume,
                 "removed_total": self.removed_total, "faces_at_merge": [c.faces_at_merge for c in self.cells],
                 "layers": [[la.state() for la in c.layers] if c.layers else None for c in self.cells],
                 "squares": [c.square for c in self.cells], "cleared": self.cleared}
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
        self.cells = []
        heights = state.get("layers") or [None] * len(state["faces_at_merge"])
        squares = state.get("squares") or [None] * len(state["faces_at_merge"])
        for child, merged, saved, square in zip(children(ipw), state["faces_at_merge"], heights, squares):
            cell = Cell(None, None, merged, square=tuple(square) if square else None)
            if saved:
                cell.set_layers(tuple(layer_from_state(region, la) for region, la in zip(children(child), saved)))
            else:
                cell.set(child)
            self.cells.append(cell)
        self.stock_volume = state["stock_volume"]
        self.removed_total = state["removed_total"]
        self.cleared = tuple(state["cleared"]) if state.get("cleared") else None
        return int(state["next_cl"])

    def step(self, index: int, move: Move, tool: MillingTool, feed_angle: float) -> EngagementMap:
        """Process one CL segment; never raises for kernel trouble (the map says FAILED).

        ``timings_ms`` holds the wall time of each stage and their ``total`` (ms).
        """
        t0 = time.perf_counter()
        try:
            m = self._step(index, move, tool, feed_angle)
        except Exception as exc:  # noqa: BLE001 - the last net: a kernel surprise fails this CL, not the run
            log.error("CL %d (%s): %s", index, move.source, exc)
            m = EngagementMap(**cl_base(index, move, tool, feed_angle), status=CLStatus.FAILED,
                              reason=f"kernel error: {exc}")
        timings = dict(m.timings_ms)
        timings["total"] = (time.perf_counter() - t0) * 1e3
        return replace(m, timings_ms=tuple(timings.items()))

    def _step(self, index: int, move: Move, tool: MillingTool, feed_angle: float) -> EngagementMap:
        outcome, contacts = self.cut(index, move, tool, feed_angle)
        t0 = time.perf_counter()
        heights = slice_heights(outcome.z_range, tool, self.options.slice_height)
        flute = [c for c in contacts if c.surface.zone == "flute"]
        try:
            arcs = [slice_intervals(flute, move.end, z) if active else [] for z, active in heights]
        except Exception as exc:  # noqa: BLE001 - a kernel surprise becomes a FAILED CL
            outcome = replace(outcome, status=CLStatus.FAILED, reason=f"contact analysis failed: {exc}")
            arcs = []
        outcome.timings["slicing"] = (time.perf_counter() - t0) * 1e3
        return engagement_map(cl_base(index, move, tool, feed_angle), tool, move, outcome, heights, arcs,
                              self.options.slice_height, self.options.min_chip_thickness)

    def cut(self, index: int, move: Move, tool: MillingTool, feed_angle: float) -> tuple[CutOutcome, list]:
        """Phase 1 of a CL on this engine's cells: sweep, Booleans, contact faces.

        Returns the picklable outcome and the contact faces (kernel objects, they stay here).
        """
        cleared, self.cleared = self.cleared, None  # a CL that raises or fails leaves nothing proven
        outcome, contacts = self._cut(index, move, tool, feed_angle, cleared)
        if outcome.status != CLStatus.FAILED and self.options.sweep == "exact":
            # the exact sweep holds the tool at the motion's end: every cell lost what lay in it
            end = step_motion(move).end
            cyl = cylinder_tool(tool)
            height = cyl[1] if cyl else tool_radii(tool)[2]
            self.cleared = (end[0], end[1], end[2], end[2] + height, cyl[0] if cyl else 0.0, repr(tool))
        return outcome, contacts

    def _cut(self, index: int, move: Move, tool: MillingTool, feed_angle: float,
             cleared: tuple[float, float, float, float, float] | None) -> tuple[CutOutcome, list]:
        timings: dict[str, float] = {}
        t0 = time.perf_counter()
        seam = math.radians(feed_angle) + math.pi  # seams behind the tool, away from the engaged side
        # a piece of a ramp or helix is swept as a step (see fusioncut.engines.segments); the
        # published method's sampled copies follow the move itself
        exact = self.options.sweep == "exact"
        motion = step_motion(move) if exact else move
        idle = CLStatus.RAPID if move.is_rapid else CLStatus.AIR
        ceiling = self._material_ceiling()
        fp = footprint(motion, tool) if exact else None
        # before the sweep is built (a ball end mill's costs 5 ms): the cells within the tool's reach
        # of the path that may hold material the sweep could remove
        candidates = [c for c in self.cells if not c.empty]
        open_start = _starts_cleared(motion, tool, cleared)
        if fp is not None:
            reach = _reach_box(fp, motion, tool)
            candidates = [c for c in candidates if boxes_overlap(reach, c.box)
                          and not _column_clear_of(c.square, motion, fp.reach, open_start)]
            if candidates and ceiling is not None:
                candidates = [c for c, may in zip(candidates, ceiling.may_cut(fp, [c.box for c in candidates])) if may]
        t1 = time.perf_counter()
        timings["ceiling"] = (t1 - t0) * 1e3
        if fp is not None and not candidates:
            if ceiling is not None:
                ceiling.clear(fp)  # the exact sweep holds no material, so nothing is left in it either
            return CutOutcome(idle, timings=timings), []  # no sweep built: no method to report
        region = self._cutting_region(motion, tool, open_start) if any(c.layers for c in candidates) else None
        flat, solid = [], []  # the cells cut as layers, and those cut as solids
        for c in candidates:
            if (c.layers is not None and region is not None and len(c.layers) <= self.options.max_layers
                    and c.layers[-1].z_hi <= region.z_top):
                flat.append(c)
            else:
                solid.append(c)
        method = "step" if motion is not move else "exact"
        touched: list[Cell] = []
        sweep = None
        if solid:
            try:
                sweep = swept_volume(tool, motion, self.options.sweep, seam, open_start)
            except Exception as exc:  # noqa: BLE001 - kernel failures become a FAILED CL, never a crash
                return CutOutcome(CLStatus.FAILED, reason=f"sweep construction failed: {exc}", timings=timings), []
            if motion is not move and sweep.method == "exact":
                sweep = replace(sweep, method="step")
            method = sweep.method
            if fp is not None and sweep.method == "sampled":
                fp = replace(fp, r_clear=None)  # a sampled sweep's scallops prove nothing removed
            sweep_box = bounding_box(sweep.shape)
            touched = [c for c in solid if boxes_overlap(sweep_box, c.box)]
            for c in touched:
                c.to_solid()
        t2 = time.perf_counter()
        timings["sweep"] = (t2 - t1) * 1e3
        if not touched and not flat:
            if fp is not None and ceiling is not None:
                ceiling.clear(fp)
            return CutOutcome(idle, method=method, timings=timings), []
        t1 = t2
        probes = _end_probes(motion, tool)
        # all cells are cut before any is changed: a failure leaves the IPW as it was
        try:
            try:
                results = self._cut_solids(touched, sweep.shape, probes) if touched else []
            except BooleanFailure:
                results = None
                # once more with the sweep's seams a quarter turn on: the kernel's failures seen came
                # where a sweep's cylinder met the IPW near its own seam and the old cylinder's (a
                # ball plunge beside the last one failed with every fuzzy value, and was right so);
                # then, for a sweep that left the tool at its start out, with that tool in (a line
                # out of a plunge's hole tangent to the stock's wall found nothing removed)
                for turn, start_left_out in ((0.5 * math.pi, open_start), *(((0.0, False),) if open_start else ())):
                    try:
                        other = swept_volume(tool, motion, self.options.sweep, seam + turn, start_left_out)
                        results = self._cut_solids(touched, other.shape, probes)
                    except Exception:  # noqa: BLE001 - a sweep not built, or its Booleans failed too
                        continue
                    sweep = replace(other, method=sweep.method)
                    break
                if results is None:
                    # and then a failing cell joined with a neighbour: its walls are ours, not the part's
                    results = self._cut_solids(touched, sweep.shape, probes, join_avoiding=flat)
        except BooleanFailure as exc:
            saved = self._save_failure(index, sweep.shape)
            log.error("CL %d (%s): Boolean failed: %s; shapes saved to %s", index, move.source, exc, saved)
            return CutOutcome(CLStatus.FAILED, method=method, timings=timings,
                              reason=f"Boolean failed after retries: {exc}; shapes saved to {saved}"), []
        try:
            fuzzies = (self.options.fuzzy or 0.0, *self.options.fuzzy_retries)
            layered = [(c, *cut_stack(c.layers, region.outline, region.z_tip, region.z_top, fuzzies,
                                      c.swept.get(region.key))) for c in flat]
        except RegionCutFailure as exc:
            log.error("CL %d (%s): layered Boolean failed: %s", index, move.source, exc)
            return CutOutcome(CLStatus.FAILED, method=method, timings=timings,
                              reason=f"Boolean of the layers failed after retries: {exc}"), []
        t2 = time.perf_counter()
        timings["boolean"] = (t2 - t1) * 1e3
        if fp is not None and ceiling is not None:  # the cells are cut (below) or lose nothing: the sweep is gone
            ceiling.clear(fp)
        for c in flat:
            c.swept[region.key] = min(region.z_tip, c.swept.get(region.key, math.inf))
        results = [r for r in results if r.shape is not None]
        layered = [r for r in layered if r[3]]
        if not results and not layered:  # nothing removed: the tool only touches or misses the material
            return CutOutcome(idle, method=method, timings=timings), []
        removed = sum(r.removed for r in results) + sum(r[2] for r in layered)
        for r in results:
            for cell, new_shape, new_volume in r.parts:
                cell.set(new_shape, new_volume)
        for cell, layers, *_ in layered:
            cell.set_layers(layers)
        self.removed_total += removed
        # the volume per slice band is known where every cell that lost material was layered
        lost = [(c.z_lo, c.z_hi, c.lost) for *_, cuts in layered for c in cuts]
        bands = None if results else band_volumes(lost, move.end[2], self.options.slice_height,
                                                  min(max(p[1] for p in lost) - move.end[2], tool.flute_length))
        outcome = CutOutcome(CLStatus.RAPID if move.is_rapid else CLStatus.ENGAGED, removed=removed,
                             method=method, timings=timings, band_volumes=bands)
        contacts = []
        try:
            arcs = [p for _, _, _, cuts in layered for p in contact_patches(cuts, move.end[:2], region.radius)]
            candidates = []
            if results:
                sweep_faces = list(faces(sweep.shape))
                own = face_map(sweep.shape)
            for r in results:
                kept = face_map(r.shape)  # the split also holds the sweep's pieces out of the IPW
                origins = r.split.Origins()
                for f in sweep_faces:
                    candidates.extend(g for g in map(TopoDS.Face, pieces(r.split, f))
                                      if kept.Contains(g) and not on_old_boundary(g, origins, own))
            contacts = arc_contacts(arcs, tool, move.end) + find_contact_faces(candidates, tool, move.end)
            flute = [c for c in contacts if c.surface.zone == "flute"]
            outcome.flute_area = sum(c.area for c in flute)
            outcome.shank_area = sum(c.area for c in contacts if c.surface.zone == "shank")
            if flute:
                outcome.z_range = (min(c.z_range[0] for c in flute), max(c.z_range[1] for c in flute))
        except Exception as exc:  # noqa: BLE001
            outcome.status, outcome.reason = CLStatus.FAILED, f"contact analysis failed: {exc}"
        timings["contact"] = (time.perf_counter() - t2) * 1e3
        level_flat_cut = motion is move and cylinder_tool(tool) is not None
        for r in results:
            for cell, *_ in r.parts:
                self._maybe_merge(cell, level_flat_cut)
        return outcome, contacts

    # -- internals ----------------------------------------------------------------------------
    def _material_ceiling(self) -> MaterialCeiling | None:
        """The height bounds of this engine's cells (None when switched off or no material is left)."""
        if self.options.ceiling_pixel is None or self.options.sweep != "exact":
            return None
        if self._ceiling_cells is not self.cells:
            boxes = [c.box for c in self.cells if c.box is not None]
            self._ceiling_cells = self.cells
            self._ceiling = None if not boxes else MaterialCeiling(
                (min(b[0][0] for b in boxes), min(b[0][1] for b in boxes)),
                (max(b[1][0] for b in boxes), max(b[1][1] for b in boxes)),
                max(b[1][2] for b in boxes), self.options.ceiling_pixel)
        return self._ceiling

    def _cut_solids(self, cells: list[Cell], sweep: TopoDS_Shape, probes: tuple[tuple[float, float, float], ...],
                    join_avoiding: list[Cell] | None = None) -> list[SolidCut]:
        """The Boolean of each solid cell with ``sweep``; raises :class:`BooleanFailure`.

        ``join_avoiding`` (a list, maybe empty): a cell whose Boolean fails is tried once more joined
        with a neighbour that is not in that list (see :meth:`_subtract_joined`).
        """
        out: list[SolidCut] = []
        joined: set[int] = set()
        for c in cells:
            if id(c) in joined:
                continue
            try:
                removed, new, split = self._subtract(c.shape, sweep, c.volume, probes)
            except BooleanFailure:
                if join_avoiding is None:
                    raise
                busy = {id(x) for x in join_avoiding} | joined
                cut = self._subtract_joined(c, sweep, probes, busy)
                joined.update(id(cell) for cell, *_ in cut.parts)
                out = [r for r in out if not any(id(cell) in joined for cell, *_ in r.parts)]
                out.append(cut)
                continue
            out.append(SolidCut([(c, new, c.volume - removed)], removed, new, split))
        return out

    def _subtract_joined(self, cell: Cell, sweep: TopoDS_Shape, probes: tuple[tuple[float, float, float], ...],
                         busy: set[int]) -> SolidCut:
        """The Boolean of ``cell`` joined with a neighbour sharing one of its walls, split back at
        that wall; the first neighbour (not in ``busy``, by id) for which that works.

        A cell's walls are where the grid put them, and a part's faces may meet them tangentially:
        a slot's side on a column's wall, tangent to the hole a plunge left, made the General Fuse
        find nothing inside the sweep and rebuild the cell 25 mm³ larger, at every fuzzy value and
        with the seams turned. Joined with the cell beside it, the wall is gone and the Boolean
        right (the layered cells, which cut in 2D, agree CL by CL); splitting back along the wall
        is a plain Common with a box. The two parts must hold the joined result's volume (1e-9
        relative + 1e-6 mm³) and neither more than its cell held.
        """
        last = "no neighbour shares a wall with the cell"
        for n, axis, at in self._neighbours(cell):
            if id(n) in busy:
                continue
            try:
                joint = unify(fuse_all([cell.shape, n.shape]), cell.volume + n.volume)
                removed, new, split = self._subtract(joint, sweep, cell.volume + n.volume, probes)
                if new is None:
                    return SolidCut([], 0.0, None, None)
                below, above = halves(new, axis, at)
            except (BooleanFailure, RuntimeError) as exc:
                last = f"joined with the cell at {n.square}: {exc}"
                continue
            mine, theirs = (below, above) if cell.square[axis] < n.square[axis] else (above, below)
            v_mine, v_theirs = (volume(p) if p is not None else 0.0 for p in (mine, theirs))
            tol = 1e-9 * (cell.volume + n.volume) + 1e-6
            if abs(v_mine + v_theirs - volume(new)) > tol or v_mine > cell.volume + tol or v_theirs > n.volume + tol:
                last = f"joined with the cell at {n.square}: the parts split back do not hold its volume"
                continue
            return SolidCut([(cell, mine, v_mine), (n, theirs, v_theirs)], removed, new, split)
        raise BooleanFailure(f"{last} (the cell alone failed)")

    def _neighbours(self, cell: Cell) -> Iterator[tuple[Cell, int, float]]:
        """(neighbour, axis, wall) for each cell with material whose column shares a wall (a
        segment of positive length) with ``cell``'s: the wall is the plane ``x = wall`` (axis 0)
        or ``y = wall`` (axis 1), mm."""
        if cell.square is None:
            return
        x0, y0, size = cell.square
        for n in self.cells:
            if n is cell or n.empty or n.square is None:
                continue
            a0, b0, other = n.square
            for axis, (lo, hi, nlo, nhi), (olo, ohi, onlo, onhi) in (
                    (0, (x0, x0 + size, a0, a0 + other), (y0, y0 + size, b0, b0 + other)),
                    (1, (y0, y0 + size, b0, b0 + other), (x0, x0 + size, a0, a0 + other))):
                overlap = min(ohi, onhi) - max(olo, onlo)
                if overlap <= 1e-9:
                    continue
                if abs(hi - nlo) <= 1e-9 * size:
                    yield n, axis, hi
                elif abs(nhi - lo) <= 1e-9 * size:
                    yield n, axis, lo

    def _sweep_volume(self, sweep: TopoDS_Shape) -> float:
        """The volume of ``sweep`` (mm³), integrated once for all the cells a CL cuts."""
        if self._last_sweep is None or not self._last_sweep[0].IsSame(sweep):
            self._last_sweep = (sweep, volume(sweep))
        return self._last_sweep[1]

    def _subtract(self, ipw: TopoDS_Shape, sweep: TopoDS_Shape, ipw_volume: float,
                  probes: tuple[tuple[float, float, float], ...] = ()):
        """(removed volume, new IPW or None when nothing is removed, the split with its history).

        One General Fuse (:func:`~fusioncut.engines.brep.occ.split_pieces`) gives the pieces of the
        IPW inside the sweep (removed) and outside it (the new IPW). The two must add up to the old
        IPW (old volume − new volume = removed): on nearly tangent faces, such as the floors a
        helical entry leaves, OCCT can build a wrong shape without reporting an error (measured with
        a Common and a Cut: 90 mm³ apart on a 10 mm³ cut). Such a result is treated as a failure
        and retried with the next fuzzy value. That holds when nothing is removed too: a ball's
        plunge 0.4 mm beside its last one, its cylinder meeting the old one's near both seams, came
        out as no piece inside and the IPW rebuilt 9.3 mm³ larger (the kernel only warned of an
        acquired self-intersection); taken as nothing removed, that CL was reported as air. And
        nothing removed while one of ``probes`` (mm, points inside the sweep) lies inside the IPW is
        a failure as well: a slot whose sides were tangent to the last plunge's hole split nothing
        and was reported as air.
        """
        last = "unknown"
        first = self._first_fuzzy
        threads = self.options.kernel_threads
        for fuzzy in (first, *self.options.fuzzy_retries):
            pf = intersections(ipw, sweep, fuzzy, threads)
            split = None if pf is None else split_pieces(ipw, sweep, pf, TopAbs_SOLID, threads)
            if split is None:
                last = f"intersection or split reported errors (fuzzy={fuzzy})"
                continue
            op, inside, outside = split
            removed = volume(compound(inside)) if inside else 0.0
            # GProp's volume of a large, many-faced IPW is good to about 1e-7 of it, and fuzzy
            # noise stayed below 0.007 mm³; the wrong shapes seen were 2–600 mm³ off
            allowed = 0.01 + 0.05 * removed + 1e-6 * ipw_volume
            if removed <= 1e-12 * max(1.0, self.stock_volume):
                change = volume_change(ipw, compound(outside))  # 0 without a face changed
                if abs(change) > allowed:
                    last = f"nothing removed, yet the split changed the IPW by {change:.4g} mm³ (fuzzy={fuzzy})"
                    continue
                inside = next((p for p in probes if strictly_inside(ipw, p)), None)
                if inside is not None:
                    last = f"nothing removed, yet the IPW holds the point {inside} of the tool at its end (fuzzy={fuzzy})"
                    continue
                return 0.0, None, None
            sweep_volume = self._sweep_volume(sweep)
            if removed > sweep_volume * (1 + 1e-6) + 1e-9:
                # more material than the tool swept: the intersection went wrong, not the physics
                last = f"removed {removed:.6g} mm³ > swept {sweep_volume:.6g} mm³ (fuzzy={fuzzy})"
                continue
            new = compound(outside)
            mismatch = -volume_change(ipw, new) - removed
            if abs(mismatch) > allowed:
                last = f"the pieces in and out of the sweep disagree by {mismatch:.4g} mm³ (fuzzy={fuzzy})"
                continue
            return removed, without_slivers(ipw, new), op
        raise BooleanFailure(last)

    @staticmethod
    def _cutting_region(motion: Move, tool: MillingTool, open_start: bool = False) -> CuttingRegion | None:
        """What the layers take from this cut, when they can: a tool that is one cylinder, on a
        horizontal line, an XY arc of up to half a turn or a vertical move; None otherwise
        (``open_start``: see :func:`~fusioncut.engines.brep.sweep.cylinder_region`)."""
        cyl = cylinder_tool(tool)
        z_tip, z_end = sorted((motion.start[2], motion.end[2]))
        if cyl is None or (z_end - z_tip > 1e-9 and math.dist(motion.start[:2], motion.end[:2]) > 1e-9):
            return None
        at_zero = motion.translated((0.0, 0.0, -z_tip))
        region = cylinder_region_outline(cyl[0], at_zero, open_start)  # the region at z = 0
        if region is None:
            return None
        # everything the region is built from: equal keys, the same region
        key = (cyl[0], open_start, type(at_zero).__name__, at_zero.start, at_zero.end,
               getattr(at_zero, "center", None), getattr(at_zero, "clockwise", None), getattr(at_zero, "turns", None))
        return CuttingRegion(region, cyl[0], z_tip, z_end + cyl[1], key)

    def _maybe_merge(self, cell: Cell, level_flat_cut: bool) -> None:
        """After a solid cell was cut: merge its faces when they grew by ``merge_growth``; then,
        after a merge or a level cut of a cylindrical tool (``level_flat_cut``: no ramp or helix
        step), let it take the layers when it is 2.5D again, or else split it into quarters."""
        if cell.empty or cell.layers is not None:
            return
        n = count_faces(cell.shape)
        merged = n > (1 + self.options.merge_growth) * cell.faces_at_merge
        if merged:
            try:
                cell.set(unify(cell.shape, cell.volume, gap=self._first_fuzzy), cell.volume)
            except Exception as exc:  # noqa: BLE001 - merging is an optimisation: keep the cell as it is
                log.debug("face merge skipped: %s", exc)
            cell.faces_at_merge = count_faces(cell.shape) if cell.shape is not None else 0
        if not (self.options.layers and self.options.sweep == "exact") or not (merged or level_flat_cut):
            return
        cell.to_layers(self.options.max_layers)  # back to layers once a helical entry's floor steps are gone
        # not while a helix is stepping down (quarters multiply its Booleans: the full benchmark's
        # first helix, CLs 1000-1250, took 11.9 s in 20 mm cells and 17.4 s split down to 5 mm), and
        # not for ball end mills (their scallops are everywhere they went: quick benchmark's finish
        # 11.7 -> 17.9 s)
        if (cell.layers is None and level_flat_cut and cell.square is not None
                and cell.square[2] > self._smallest_square and cell.square not in self._unsplittable):
            self._quarter(cell)

    @property
    def _first_fuzzy(self) -> float:
        """The fuzzy value (mm) a 3D Boolean tries first."""
        return self.options.fuzzy if self.options.fuzzy is not None else (1e-6 if self.options.cell_size else 0.0)

    @property
    def _smallest_square(self) -> float:
        return (self.options.cell_size or 0.0) / MAX_SPLIT * (1 + 1e-9)

    def _quarter(self, cell: Cell) -> None:
        """Put the cell's four quarter squares in its place; those that are 2.5D take the layers.

        A solid cell stays solid where any of its material is not 2.5D (the ledges a helical entry
        leaves on its bore, a ball end mill's scallops), and every Boolean of every CL near it pays
        for all its faces; its quarters away from such material go back to the cheap layered cuts.
        Quarters stay quarters, and a ball end mill's finish over them pays a Boolean per quarter it
        reaches. Two full benchmark runs on one day (20 mm cells) favoured 5 mm over 10 mm: adaptive
        p95 18.5 against 26.2 ms, contours 8.3 against 9.2 s, the finish 60.8 against 61.3 s (the
        10 mm run also had the open start sweeps in solid cells). The quick benchmark, whose finish
        runs where its helices were, preferred 10 mm: 73.4 s against 77.5 s, unsplit 80.0 s.
        A split that loses volume (1e-9 relative) is not taken, and the cell is not split again.
        """
        x0, y0, size = cell.square
        half = 0.5 * size
        try:
            pieces = quarters(cell.shape, x0 + half, y0 + half)
        except Exception as exc:  # noqa: BLE001 - splitting is an optimisation: keep the cell as it is
            pieces, reason = None, str(exc)
        else:
            volumes = [volume(p) if p is not None else 0.0 for p in pieces]
            reason = f"the quarters hold {sum(volumes) - cell.volume:.3g} mm³ more than the cell"
            if abs(sum(volumes) - cell.volume) > 1e-9 * abs(cell.volume) + 1e-6:
                pieces = None
        if pieces is None:
            log.debug("cell at %s not split: %s", cell.square, reason)
            self._unsplittable.add(cell.square)
            return
        new = []
        for (i, j), piece, piece_volume in zip(((0, 0), (1, 0), (0, 1), (1, 1)), pieces, volumes):
            if piece is None:
                continue
            quarter = Cell(None, None, count_faces(piece), square=(x0 + i * half, y0 + j * half, half),
                           swept=dict(cell.swept))
            quarter.set(piece, piece_volume)
            if self.options.layers and self.options.sweep == "exact":
                quarter.to_layers(self.options.max_layers)
            new.append(quarter)
        k = next(k for k, c in enumerate(self.cells) if c is cell)
        self.cells[k:k + 1] = new

    def _save_failure(self, index: int, sweep: TopoDS_Shape) -> str:
        folder = Path(self.options.failure_dir or "fusioncut-failures")
        folder.mkdir(parents=True, exist_ok=True)
        write_brep(self.ipw, str(folder / f"cl{index:06d}_ipw.brep"))
        write_brep(sweep, str(folder / f"cl{index:06d}_sweep.brep"))
        return str(folder / f"cl{index:06d}_*.brep")


def _starts_cleared(motion: Move, tool: MillingTool, cleared: tuple | None) -> bool:
    """Whether the tool the previous CL left empty (``BRepEngine.cleared``) holds this tool at the
    start of ``motion``: for a cylindrical tool, a disk as wide over the whole height its sweep
    reaches; for another tool, the very same tool at the very same point. Then the sweep (and the
    layers' region) may leave the tool at the start out: same material, cheaper Booleans."""
    if cleared is None or (cleared[0], cleared[1]) != motion.start[:2]:
        return False
    cyl = cylinder_tool(tool)
    if cyl is None:
        return cleared[5:] == (repr(tool),) and cleared[2] == motion.start[2]
    z_tip, z_end = sorted((motion.start[2], motion.end[2]))
    return cleared[2] <= z_tip and z_end + cyl[1] <= cleared[3] and cyl[0] <= cleared[4]


def _end_probes(motion: Move, tool: MillingTool) -> tuple[tuple[float, float, float], ...]:
    """Points (mm) inside the tool at the end of ``motion``, where material must go if the IPW holds
    them: on the axis half the tool's reach (or length) up, and, for a motion with a horizontal
    direction at its end, 0.9 of the tool's radius at that height ahead of the axis. The front
    point is where a slot's new material lies when the end point on the axis is already in a hole
    (a line leaving a plunge's hole was once reported as air)."""
    end, (reach, _, length) = motion.end, tool_radii(tool)
    h = 0.5 * min(reach, length)
    axis = (end[0], end[1], end[2] + h)
    d = horizontal_direction(motion)
    if d is None:
        return (axis,)
    r = 0.9 * tool.profile().radius_at(h)
    return axis, (axis[0] + r * d[0], axis[1] + r * d[1], axis[2])


def _column_clear_of(square: tuple[float, float, float] | None, motion: Move, reach: float, open_start: bool) -> bool:
    """Whether the grid column ``square`` (x0, y0, size; mm) meets the exact sweep along a line
    ``motion`` in zero volume: the column lies ``reach`` mm or more from the line's XY path, or, for a
    level line whose sweep leaves the tool at its start out (``open_start``), wholly behind the start.

    A cell's material stands in its column (an outer column's reaches past it by at most 1e-9 of
    the grid), the sweep within ``reach`` of its path and, left open, ahead of its start; where the
    two only touch along a cell's wall their boxes, widened by the edges' tolerance, still overlap,
    and the Boolean proves nothing removed at full cost: on the benchmark's ball finish, 243 of 1459
    Booleans (1.2 of 21 s).
    """
    if square is None or isinstance(motion, ArcMove):
        return False
    x0, y0, size = square
    x1, y1 = x0 + size, y0 + size
    (ax, ay, az), (bx, by, bz) = motion.start, motion.end
    dx, dy = bx - ax, by - ay
    if open_start and az == bz and (dx or dy) and all(
            (cx - ax) * dx + (cy - ay) * dy <= 0.0 for cx in (x0, x1) for cy in (y0, y1)):
        return True
    return _segment_box_distance((ax, ay), (bx, by), (x0, y0, x1, y1)) >= reach


def _segment_box_distance(a: tuple[float, float], b: tuple[float, float], box: tuple[float, float, float, float]) -> float:
    """The distance (mm) between the segment ``a``-``b`` and the rectangle ``box`` (x0, y0, x1, y1)."""
    x0, y0, x1, y1 = box
    # Liang-Barsky: the part of the segment inside the rectangle, if any
    lo, hi = 0.0, 1.0
    for p, q in ((a[0] - b[0], a[0] - x0), (b[0] - a[0], x1 - a[0]), (a[1] - b[1], a[1] - y0), (b[1] - a[1], y1 - a[1])):
        if p == 0.0:
            if q < 0.0:
                lo, hi = 1.0, 0.0
                break
        elif p < 0.0:
            lo = max(lo, q / p)
        else:
            hi = min(hi, q / p)
    if lo <= hi:
        return 0.0

    def to_box(p):
        return math.hypot(max(x0 - p[0], 0.0, p[0] - x1), max(y0 - p[1], 0.0, p[1] - y1))

    def to_segment(p):
        # ceiling's segment distance in scalars: its numpy form costs 10 µs more a call, and this
        # runs for each candidate cell of each CL
        ux, uy = b[0] - a[0], b[1] - a[1]
        L2 = ux * ux + uy * uy
        t = 0.0 if L2 == 0.0 else min(1.0, max(0.0, ((p[0] - a[0]) * ux + (p[1] - a[1]) * uy) / L2))
        return math.hypot(p[0] - a[0] - t * ux, p[1] - a[1] - t * uy)

    # apart, the nearest points are an end of the segment and a point of the rectangle, or a corner
    return min(to_box(a), to_box(b), *(to_segment((cx, cy)) for cx in (x0, x1) for cy in (y0, y1)))


def _reach_box(fp, motion: Move, tool: MillingTool) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """A box (mm) around everything the tool's sweep along ``motion`` can reach, with 1e-6 mm to spare."""
    x0, y0, x1, y1 = fp.box(fp.reach + 1e-6)
    top = max(motion.start[2], motion.end[2]) + tool_radii(tool)[2]
    return (x0, y0, fp.z_low - 1e-6), (x1, y1, top + 1e-6)


def cl_sequence(toolpath: Toolpath, options: EngineOptions, default_tool: MillingTool | None = None,
                start_at: int = 0) -> Iterator[tuple[int, Move, MillingTool, float]]:
    """(CL index, segment, tool, feed angle in degrees) of every CL segment from ``start_at`` on."""
    feed_angle = 0.0
    for index, move in enumerate(segments_for(toolpath.moves, options)):
        d = horizontal_direction(move)
        if d is not None:
            feed_angle = math.degrees(math.atan2(d[1], d[0])) % 360.0
        if index < start_at:
            continue
        tool = toolpath.tools.get(move.tool) if move.tool is not None else None
        tool = tool or default_tool
        if tool is None:
            raise InputError(f"no tool definition for T{move.tool}", move.source)
        yield index, move, tool, feed_angle


@dataclass
class SolidCut:
    """What one 3D Boolean did: the cells it changes with their new material (None: all gone) and
    volume (mm³), the volume it removed (mm³), and the new shape with the split's history, where
    the contact faces are found (None when nothing was removed)."""

    parts: list[tuple[Cell, TopoDS_Shape | None, float]]
    removed: float
    shape: TopoDS_Shape | None
    split: object | None


@dataclass
class CutOutcome:
    """What one CL did to a set of cells, without kernel objects (so it can cross processes).

    ``removed`` mm³, areas mm², ``z_range`` (mm above the tip) of the flute contact, ``timings`` ms.
    ``band_volumes``: the volume (mm³) removed in each slice band above the tip at the CL's end
    (:func:`fusioncut.engines.chip.band_volumes`; () where nothing was removed), known where every
    cell that lost material was layered (a layer's cut knows its lost area and heights); a solid
    cell's Boolean gives only its total, so where one lost material they are None (unknown: no band
    of that CL is called rubbing).
    """

    status: CLStatus
    removed: float = 0.0
    method: str = ""
    reason: str = ""
    flute_area: float = 0.0
    shank_area: float = 0.0
    z_range: tuple[float, float] | None = None
    timings: dict[str, float] = field(default_factory=dict)
    band_volumes: tuple[float, ...] | None = ()

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
                          summed(self.band_volumes, other.band_volumes))


def cl_base(index: int, move: Move, tool: MillingTool, feed_angle: float) -> dict:
    return dict(cl_index=index, position=move.end, start=move.start, tool=tool.label, spindle=tool.spindle,
                feed_angle=feed_angle, source=move.source, feed=move.feed, operation=move.operation)


def slice_heights(z_range: tuple[float, float] | None, tool: MillingTool, dz: float) -> list[tuple[float, bool]]:
    """(height above the tip, in contact?) of each slice band [k, k+1)*dz up to the flute contact top.

    A band is evaluated in the middle of its part in contact, so a shallow cut (ap < dz/2) still gets
    its slice and the height never sits on the material's edge.
    """
    if z_range is None:
        return []
    z_lo, z_hi = z_range
    out = []
    for k in range(math.ceil(min(z_hi, tool.flute_length) / dz - 1e-9)):
        lo, hi = max(k * dz, z_lo), min((k + 1) * dz, z_hi)
        out.append((0.5 * (lo + hi), True) if hi > lo else ((k + 0.5) * dz, False))
    return out


def engagement_map(base: dict, tool: MillingTool, move: Move, outcome: CutOutcome,
                   heights: list[tuple[float, bool]], arcs: list[list[tuple[float, float]]],
                   slice_height: float = 1.0, min_chip_thickness: float = 0.0) -> EngagementMap:
    """Assemble the map of a CL from its cut outcome and the machine arcs (rad) of each slice.

    ``heights`` and ``arcs`` hold one entry per slice band of ``slice_height`` (mm) from the tip up.
    A band whose removed width across the path is under ``min_chip_thickness`` (mm,
    :mod:`fusioncut.engines.chip`) only rubs: its arcs are left out, counted in ``rubbing_slices``
    and warned about, and ``axial_range`` is clamped to the bands that cut (``contact_area`` still
    holds the whole flute contact).
    """
    warnings = []
    if outcome.status == CLStatus.RAPID and outcome.removed > 0:
        warnings.append(f"rapid move cuts {outcome.removed:.4g} mm³ of material")
    if outcome.shank_area > 0:
        warnings.append("the shank touches the material")
    common = dict(status=outcome.status, removed_volume=outcome.removed, sweep_method=outcome.method,
                  reason=outcome.reason, warnings=tuple(warnings), timings_ms=tuple(outcome.timings.items()),
                  shank_contact_area=outcome.shank_area)
    if outcome.status == CLStatus.FAILED or outcome.z_range is None:
        return EngagementMap(**base, **common)
    arcs, axial_range, rubbing = without_rubbing(arcs, outcome.band_volumes, outcome.z_range, slice_height,
                                                 horizontal_travel(move), min_chip_thickness)
    if rubbing:
        warnings.append(f"{rubbing} slice(s) only rub (removed width under the minimum chip thickness "
                        f"{min_chip_thickness:g} mm): left out of the engagement")
        common["warnings"] = tuple(warnings)
    profile = tool.profile()
    slices = []
    for (z, _), slice_arcs in zip(heights, arcs):
        intervals = sorted(_immersion(a, w, base["feed_angle"], tool.spindle) for a, w in slice_arcs)
        slices.append(SliceEngagement(z=z, z_machine=move.end[2] + z, radius=profile.radius_at(z),
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
    if abs(entry - 360.0) < 1e-9:
        entry = 0.0
    return entry, entry + w
