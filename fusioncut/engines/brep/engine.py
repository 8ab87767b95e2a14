"""The exact B-Rep engagement engine (OpenCASCADE through OCP): the orchestrator of a CL.

Per CL segment: exact swept volume -> removed = IPW ∩ sweep and IPW = IPW − sweep from one shared
intersection (``BOPAlgo_PaveFiller``) -> contact faces = images of the sweep's faces in the new IPW that
lie on the tool at the end CL and were not already on the IPW's boundary (a wall the tool only grazes
loses nothing, so it is no engagement) -> slicing.

The rooms it sends a CL through:

* :mod:`~fusioncut.engines.brep.cells`: the IPW as a quadtree of **cells**
  (``EngineOptions.cell_size`` mm square columns over the full stock height; ``None``: one cell, the
  whole IPW). A CL touches only the cells its sweep's reach overlaps, so each Boolean works on a
  bounded piece whatever the program's length (whole-IPW Booleans grow with the faces an adaptive
  path leaves behind). Of those, a cell skips its Booleans when the material's height map
  (:mod:`fusioncut.engines.ceiling`) proves the sweep removes nothing there. Both tests run on the
  tool's reach around the path before the sweep is built, so a CL through material already cut away
  builds no sweep and costs no Boolean. Arcs split at a cell wall are joined again when the slices
  are merged. Faces of a cell on the same surface are merged whenever its face count grew by
  ``merge_growth`` since its last merge (without merging the IPW fragments and every Boolean slows).
* :mod:`~fusioncut.engines.brep.layers`: a cell that only cylindrical tools have cut horizontally or
  vertically is kept as a stack of 2.5D layers (``EngineOptions.layers``): the CL's sweep is then a
  planar region taken away from the layers above the tip by 2D differences, and the contact faces
  are the engaged arcs of each layer extruded over its height. A cut the layers cannot take (another
  tool, a ramp's oblique sweep, too many layers) turns the cell into a solid; a solid cell whose
  faces are all horizontal or vertical again takes the layers back at its next merge or level
  flat-end-mill cut, and one that such a cut leaves solid is split into quarter squares. Both forms
  give the same material and the same engagement (tested against an all-solid run).
* :mod:`~fusioncut.engines.brep.solid_cut`: the 3D Booleans of the solid cells, their checks and
  their ladder of retries. A CL that fails them all is reported FAILED with the reason, both shapes
  are written as .brep for reproduction, the IPW stays as it was and the run goes on.
* :mod:`~fusioncut.engines.brep.budget`: those Booleans run in a killable child process, so a CL
  whose Booleans run past ``EngineOptions.kernel_budget_s`` is FAILED the same way (the budget and
  the CL named) and Ctrl-C stops the run at once; the child ends with the run (:meth:`close`, and
  when :meth:`process` ends).
* :mod:`~fusioncut.engines.brep.checkpoint`: the state on disk.
* :mod:`fusioncut.engines.cl_maps`: the kernel-free assembly of the CL's map.

Removed volume is checked against the IPW's volume change on every CL.
"""
from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import NamedTuple

from OCP.TopoDS import TopoDS_Shape

from fusioncut.engines.base import EngineKind, EngineOptions, SweepMethod
from fusioncut.engines.brep.budget import Deadline, KernelBudgetExceeded, stop_worker, within
from fusioncut.engines.brep.cells import (
    Cell, ClearedTool, Square, column_clear_of, quarter_cells, reach_box, smallest_square, split_into_cells,
    starts_cleared,
)
from fusioncut.engines.brep.checkpoint import EngineState, load_checkpoint, save_checkpoint
from fusioncut.engines.brep.contact import ContactFace, arc_contacts, find_contact_faces, slice_intervals
from fusioncut.engines.brep.layers import CuttingRegion, StackCut, contact_patches, cut_stack, outline_faces
from fusioncut.engines.brep.occ import (
    bounding_box, boxes_overlap, compound, count_faces, unify, volume, write_brep,
)
from fusioncut.engines.brep.solid_cut import SolidCut, SolidCutter, end_probes
from fusioncut.engines.brep.stock import stock_solid
from fusioncut.engines.brep.sweep import (SweptVolume, cylinder_region_outline, cylinder_tool, sampled_ridge,
                                         swept_volume)
from fusioncut.engines.ceiling import MaterialCeiling, SweepFootprint, footprint, load_kernels
from fusioncut.engines.chip import band_volumes
from fusioncut.engines.cl_maps import CL, CutOutcome, cl_base, cl_sequence, engagement_map, slice_heights
from fusioncut.engines.segments import step_motion
from fusioncut.errors import BooleanFailure, InputError, RegionCutFailure
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.moves import Move, Toolpath
from fusioncut.model.stock import Stock
from fusioncut.model.tools import MillingTool

__all__ = ["BRepEngine"]

log = logging.getLogger("fusioncut.engine")


class LayeredCut(NamedTuple):
    """A layered cell and what one CL's region did to its stack."""

    cell: Cell
    cut: StackCut


@dataclass
class BRepEngine:
    """Exact engine in this process (implements :class:`~fusioncut.engines.base.Engine`). ``ipw`` is
    the in-process workpiece after the last processed CL."""

    options: EngineOptions = field(default_factory=EngineOptions)
    cells: list[Cell] = field(default_factory=list)
    stock_volume: float = 0.0
    removed_total: float = 0.0
    # the material's height map, and the cell list it was built for: a new list (start,
    # checkpoint, a parallel worker's cells) gets a fresh map, since an old one may claim too much air
    _ceiling: MaterialCeiling | None = field(default=None, init=False, repr=False)
    _ceiling_cells: list[Cell] | None = field(default=None, init=False, repr=False)
    # squares whose split lost volume: not tried again (a resumed run or a worker may try once more)
    _unsplittable: set[Square] = field(default_factory=set, init=False, repr=False)
    # where the last CL's tool left no material, or None; a cut starting there may leave that tool
    # out of its sweep (see cells.starts_cleared)
    cleared: ClearedTool | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        budget = self.options.kernel_budget_s
        if budget is not None and not 0.0 < budget < math.inf:
            raise InputError(f"options.kernel_budget_s: {budget!r} s is not a positive number of seconds "
                             "(None: no budget)")
        if self.options.ceiling_pixel is not None and self.options.exact:
            load_kernels()  # here, not in the first CL's time

    # -- the Engine protocol ----------------------------------------------------------------------
    @property
    def kind(self) -> EngineKind:
        return EngineKind.BREP

    @property
    def shares_cells(self) -> bool:
        return False

    def close(self) -> None:
        """End the kernel's child process, if one runs (:mod:`~fusioncut.engines.brep.budget`)."""
        stop_worker()

    def start(self, stock: Stock | TopoDS_Shape) -> None:
        solid = stock if isinstance(stock, TopoDS_Shape) else stock_solid(stock)
        self.stock_volume = volume(solid)
        self.removed_total = 0.0
        self.cleared = None
        self.cells = [Cell.of_solid(piece, square) for piece, square in split_into_cells(solid, self.options.cell_size)]
        self.adopt_layers()

    def adopt_layers(self) -> None:
        """Cells that are 2.5D take the layered form (when ``options.layers``)."""
        if self._max_layers is not None:
            for cell in self.cells:
                cell.to_layers(self._max_layers)

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
        try:
            for cl in cl_sequence(toolpath, self.options, default_tool, start_at):
                yield self.step(*cl)
        finally:
            stop_worker()

    def save_checkpoint(self, folder: Path, next_cl: int) -> None:
        """Write the engine state atomically into ``folder`` (:mod:`~fusioncut.engines.brep.checkpoint`).

        ``next_cl`` is the index of the first CL not yet processed. The binary BRep keeps doubles
        exactly, so a run resumed from here gives the same results as one never stopped.
        """
        save_checkpoint(folder, EngineState(next_cl, self.cells, self.stock_volume, self.removed_total, self.cleared))

    def load_checkpoint(self, folder: Path) -> int | None:
        """Restore the state saved by :meth:`save_checkpoint`; the next CL index, or None if none."""
        state = load_checkpoint(folder)
        if state is None:
            return None
        self.cells, self.stock_volume, self.removed_total = state.cells, state.stock_volume, state.removed_total
        self.cleared = state.cleared
        return state.next_cl

    # -- one CL -----------------------------------------------------------------------------------
    def step(self, index: int, move: Move, tool: MillingTool, feed_angle: float) -> EngagementMap:
        """Process one CL segment (its map says ``engine="brep"``); never raises for kernel trouble
        (the map says FAILED).

        ``timings_ms`` holds the wall time of each stage and their ``total`` (ms).
        """
        cl = CL(index, move, tool, feed_angle)
        t0 = time.perf_counter()
        try:
            m = self._step(cl)
        except Exception as exc:  # noqa: BLE001 - the last net: a kernel surprise fails this CL, not the run
            log.error("CL %d (%s): %s", index, move.source, exc)
            m = EngagementMap(**cl_base(cl), status=CLStatus.FAILED, reason=f"kernel error: {exc}")
        timings = dict(m.timings_ms)
        timings["total"] = (time.perf_counter() - t0) * 1e3
        return replace(m, timings_ms=tuple(timings.items()), engine=EngineKind.BREP.value)

    def _step(self, cl: CL) -> EngagementMap:
        outcome, contacts = self.cut(*cl)
        t0 = time.perf_counter()
        heights = slice_heights(outcome.z_range, cl.tool, self.options.slice_height)
        flute = [c for c in contacts if c.surface.zone == "flute"]
        try:
            arcs = [slice_intervals(flute, cl.move.end, z) if active else [] for z, active in heights]
        except Exception as exc:  # noqa: BLE001 - a kernel surprise becomes a FAILED CL
            outcome = replace(outcome, status=CLStatus.FAILED, reason=f"contact analysis failed: {exc}")
            arcs = []
        outcome.timings["slicing"] = (time.perf_counter() - t0) * 1e3
        return engagement_map(cl, outcome, heights, arcs, self.options.slice_height, self.options.min_chip_thickness)

    def cut(self, index: int, move: Move, tool: MillingTool, feed_angle: float) -> tuple[CutOutcome, list[ContactFace]]:
        """Phase 1 of a CL on this engine's cells: sweep, Booleans, contact faces.

        Returns the picklable outcome and the contact faces (kernel objects, they stay here).
        """
        cleared, self.cleared = self.cleared, None  # a CL that raises or fails leaves nothing proven
        outcome, contacts = self._cut(CL(index, move, tool, feed_angle), cleared)
        if outcome.status != CLStatus.FAILED and self.options.exact:
            # the exact sweep holds the tool at the motion's end: every cell lost what lay in it
            self.cleared = ClearedTool.at_end(step_motion(move).end, tool)
        return outcome, contacts

    def _cut(self, cl: CL, cleared: ClearedTool | None) -> tuple[CutOutcome, list[ContactFace]]:
        index, move, tool, feed_angle = cl
        timings: dict[str, float] = {}
        t0 = time.perf_counter()
        deadline = Deadline(self.options.kernel_budget_s)
        seam = math.radians(feed_angle) + math.pi  # seams behind the tool, away from the engaged side
        # a piece of a ramp or helix is swept as a step (see fusioncut.engines.segments); the
        # published method's sampled copies follow the move itself
        motion = step_motion(move) if self.options.exact else move
        idle = CLStatus.RAPID if move.is_rapid else CLStatus.AIR
        ceiling = self._material_ceiling()
        fp = footprint(motion, tool) if self.options.exact else None
        open_start = starts_cleared(motion, tool, cleared)
        candidates = self._candidates(motion, tool, fp, open_start, ceiling)
        t1 = time.perf_counter()
        timings["ceiling"] = (t1 - t0) * 1e3
        if fp is not None and not candidates:
            if ceiling is not None:
                ceiling.clear(fp)  # the exact sweep holds no material, so nothing is left in it either
            return CutOutcome(idle, timings=timings), []  # no sweep built: no method to report
        region = self._cutting_region(motion, tool, open_start) if any(c.layers for c in candidates) else None
        as_layers, as_solids = [], []
        for c in candidates:
            if (c.layers is not None and region is not None and len(c.layers) <= self.options.max_layers
                    and c.layers[-1].z_hi <= region.z_top):
                as_layers.append(c)
            else:
                as_solids.append(c)
        method = SweepMethod.STEP if motion is not move else SweepMethod.EXACT
        touched: list[Cell] = []
        sweep = None
        if as_solids:
            try:
                with within(deadline):  # its fuses of tool copies run under the CL's budget
                    sweep = swept_volume(tool, motion, self.options.sweep, seam, open_start)
            except Exception as exc:  # noqa: BLE001 - kernel failures become a FAILED CL, never a crash
                return CutOutcome(CLStatus.FAILED, reason=f"sweep construction failed: {exc}", timings=timings), []
            if motion is not move and sweep.method == SweepMethod.EXACT:
                sweep = replace(sweep, method=SweepMethod.STEP)
            method = sweep.method
            if fp is not None and sweep.method == SweepMethod.SAMPLED:
                fp = replace(fp, r_clear=None)  # a sampled sweep's scallops prove nothing removed
            sweep_box = bounding_box(sweep.shape)
            touched = [c for c in as_solids if boxes_overlap(sweep_box, c.box)]
            for c in touched:
                c.to_solid()
        t2 = time.perf_counter()
        timings["sweep"] = (t2 - t1) * 1e3
        if not touched and not as_layers:
            if fp is not None and ceiling is not None:
                ceiling.clear(fp)
            return CutOutcome(idle, method=method, timings=timings), []
        t1 = t2
        # all cells are cut before any is changed: a failure leaves the IPW as it was
        results: list[SolidCut] = []
        if touched:
            def resweep(turn: float, start_left_out: bool) -> SweptVolume:
                with within(deadline):
                    return swept_volume(tool, motion, self.options.sweep, seam + turn, start_left_out)

            try:
                results, sweep = self._solid_cutter(deadline).cut_with_retries(
                    touched, sweep, end_probes(motion, tool), resweep, open_start, as_layers)
            except KernelBudgetExceeded as exc:
                saved = self._save_failure(index, sweep.shape)
                log.error("CL %d (%s): %s; shapes saved to %s", index, move.source, exc, saved)
                return CutOutcome(CLStatus.FAILED, method=method, timings=timings,
                                  reason=f"CL {index}: {exc}; the workpiece is kept as before the CL; "
                                         f"shapes saved to {saved}"), []
            except BooleanFailure as exc:
                saved = self._save_failure(index, sweep.shape)
                log.error("CL %d (%s): Boolean failed: %s; shapes saved to %s", index, move.source, exc, saved)
                return CutOutcome(CLStatus.FAILED, method=method, timings=timings,
                                  reason=f"Boolean failed after retries: {exc}; shapes saved to {saved}"), []
        try:
            fuzzies = (self.options.fuzzy or 0.0, *self.options.fuzzy_retries)
            layered = [LayeredCut(c, cut_stack(c.layers, region.outline, region.z_tip, region.z_top, fuzzies,
                                               c.swept.get(region.key))) for c in as_layers]
        except RegionCutFailure as exc:
            saved = self._save_failure(index, region=outline_faces(region.outline))
            log.error("CL %d (%s): layered Boolean failed: %s; shapes saved to %s", index, move.source, exc, saved)
            return CutOutcome(CLStatus.FAILED, method=method, timings=timings,
                              reason=f"Boolean of the layers failed after retries: {exc}; shapes saved to {saved}"), []
        t2 = time.perf_counter()
        timings["boolean"] = (t2 - t1) * 1e3
        if fp is not None and ceiling is not None:  # the cells are cut (below) or lose nothing: the sweep is gone
            ceiling.clear(fp)
        for c in as_layers:
            c.swept[region.key] = min(region.z_tip, c.swept.get(region.key, math.inf))
        results = [r for r in results if r.shape is not None]
        layered = [r for r in layered if r.cut.cuts]
        if not results and not layered:  # nothing removed: the tool only touches or misses the material
            return CutOutcome(idle, method=method, timings=timings), []
        outcome = self._apply(cl, results, layered)
        outcome.method, outcome.timings = method, timings
        if method == SweepMethod.SAMPLED:
            ridge = sampled_ridge(tool, motion)
            if ridge > self.options.chord_tolerance:
                outcome.warnings = (f"swept as the published method's tool copies, which leave material up to "
                                    f"{ridge:.3g} mm high between them: the removed volume and the engagement "
                                    "miss it (the analytic engine sweeps this tool exactly)",)
        contacts = []
        try:
            contacts = self._contact_faces(cl, results, layered, sweep, region)
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
            for part in r.parts:
                self._maybe_merge(part.cell, level_flat_cut)
        return outcome, contacts

    # -- the rooms' glue --------------------------------------------------------------------------
    def _apply(self, cl: CL, results: list[SolidCut], layered: list[LayeredCut]) -> CutOutcome:
        """Give the cells the material the CL's cuts left them; the outcome's status, the volume
        removed (mm³) and, where every cell that lost material was layered, its slice bands' volumes."""
        removed = sum(r.removed for r in results) + sum(r.cut.removed for r in layered)
        for r in results:
            for part in r.parts:
                part.cell.set(part.shape, part.volume)
        for r in layered:
            r.cell.set_layers(r.cut.layers)
        self.removed_total += removed
        z_tip = cl.move.end[2]
        lost = [(c.z_lo, c.z_hi, c.lost) for r in layered for c in r.cut.cuts]
        bands = None if results else band_volumes(lost, z_tip, self.options.slice_height,
                                                  min(max(p[1] for p in lost) - z_tip, cl.tool.flute_length))
        return CutOutcome(CLStatus.RAPID if cl.move.is_rapid else CLStatus.ENGAGED, removed=removed, band_volumes=bands)

    def _candidates(self, motion: Move, tool: MillingTool, fp: SweepFootprint | None, open_start: bool,
                    ceiling: MaterialCeiling | None) -> list[Cell]:
        """The cells within the tool's reach of the path that may hold material the sweep could
        remove, found before the sweep is built (without a footprint: every cell with material)."""
        candidates = [c for c in self.cells if not c.empty]
        if fp is None:
            return candidates
        reach = reach_box(fp, motion, tool)
        candidates = [c for c in candidates if boxes_overlap(reach, c.box)
                      and not column_clear_of(c.square, motion, fp.reach, open_start)]
        if candidates and ceiling is not None:
            candidates = [c for c, may in zip(candidates, ceiling.may_cut(fp, [c.box for c in candidates])) if may]
        return candidates

    def _contact_faces(self, cl: CL, results: list[SolidCut], layered: list[LayeredCut],
                       sweep: SweptVolume | None, region: CuttingRegion | None) -> list[ContactFace]:
        """The CL's contact faces: the layers' engaged arcs extruded over their heights, and the
        sweep's faces that the solid cells' splits put on the new material and not on the old."""
        end = cl.move.end
        arcs = [p for r in layered for p in contact_patches(r.cut.cuts, end[:2], region.radius)]
        candidates = [f for r in results for f in r.contact_candidates(sweep.shape)]
        return arc_contacts(arcs, cl.tool, end) + find_contact_faces(candidates, cl.tool, end)

    def _material_ceiling(self) -> MaterialCeiling | None:
        """The height map of this engine's cells (None when switched off or no material is left)."""
        if self.options.ceiling_pixel is None or not self.options.exact:
            return None
        if self._ceiling_cells is not self.cells:
            boxes = [c.box for c in self.cells if c.box is not None]
            self._ceiling_cells = self.cells
            self._ceiling = None if not boxes else MaterialCeiling(
                (min(b[0][0] for b in boxes), min(b[0][1] for b in boxes)),
                (max(b[1][0] for b in boxes), max(b[1][1] for b in boxes)),
                max(b[1][2] for b in boxes), self.options.ceiling_pixel)
        return self._ceiling

    def _solid_cutter(self, deadline: Deadline | None = None) -> SolidCutter:
        """The 3D Booleans of one CL with this engine's cells and options (``deadline``: the CL's
        kernel budget; None: none, the Booleans run in this process, as a test calling it wants)."""
        return SolidCutter(self.cells, (self._first_fuzzy, *self.options.fuzzy_retries), self.options.kernel_threads,
                           self.stock_volume, deadline or Deadline(None))

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
        if self._max_layers is None or not (merged or level_flat_cut):
            return
        cell.to_layers(self._max_layers)  # back to layers once a helical entry's floor steps are gone
        # quarters only after a level flat-end-mill cut: while a helix steps down they would multiply
        # its Booleans, and a ball end mill's scallops are everywhere it went, so its quarters would
        # stay solid (docs/decisions/engine-cells.md)
        if (cell.layers is None and level_flat_cut and cell.square is not None
                and cell.square.size > smallest_square(self.options.cell_size)
                and cell.square not in self._unsplittable):
            self._quarter(cell)

    @property
    def _max_layers(self) -> int | None:
        """The most layers a cell keeps, or None when cells are never layered (no layers, or sampled sweeps)."""
        return self.options.max_layers if self.options.layers and self.options.exact else None

    @property
    def _first_fuzzy(self) -> float:
        """The fuzzy value (mm) a 3D Boolean tries first."""
        return self.options.fuzzy if self.options.fuzzy is not None else (1e-6 if self.options.cell_size else 0.0)

    def _quarter(self, cell: Cell) -> None:
        """Put the cell's quarter squares in its place (:func:`~fusioncut.engines.brep.cells.quarter_cells`);
        a square whose split fails is not tried again."""
        quarters = quarter_cells(cell, self._max_layers)
        if quarters is None:
            self._unsplittable.add(cell.square)
            return
        k = next(k for k, c in enumerate(self.cells) if c is cell)
        self.cells[k:k + 1] = quarters

    def _save_failure(self, index: int, sweep: TopoDS_Shape | None = None, region: TopoDS_Shape | None = None) -> str:
        """Write the workpiece before CL ``index`` and what failed to cut it (the sweep of a solid
        Boolean, or the planar faces, z = 0, of the region a layered one cut) as BRep files into the
        failure folder; their pattern."""
        folder = Path(self.options.failure_dir or "fusioncut-failures")
        folder.mkdir(parents=True, exist_ok=True)
        write_brep(self.ipw, str(folder / f"cl{index:06d}_ipw.brep"))
        for name, shape in (("sweep", sweep), ("region", region)):
            if shape is not None:
                write_brep(shape, str(folder / f"cl{index:06d}_{name}.brep"))
        return str(folder / f"cl{index:06d}_*.brep")
