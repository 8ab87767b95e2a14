"""The 3D Boolean of a CL's sweep with the solid cells, its checks and its ladder of retries.

One General Fuse per cell (:func:`~fusioncut.engines.brep.occ.split_pieces`) gives the pieces of the
cell inside the sweep (removed) and outside it (the new material); all cells a CL reaches are cut
before any is changed, so a failure leaves the workpiece as it was. A result is accepted only when it
passes the checks of :meth:`SolidCutter.subtract`: on nearly tangent faces OCCT can build a wrong
shape without reporting an error.

The ladder, each step tried when the one before failed (:meth:`SolidCutter.cut_with_retries`):

1. the fuzzy values: the first one (``EngineOptions.fuzzy``; with cells 1e-6, since with 0 OCCT
   returned an empty Common where a sweep face lay on a cell wall), then ``fuzzy_retries``;
2. the sweep rebuilt with its seams a quarter turn on: the failures seen came where a sweep's
   cylinder met the workpiece near its own seam and the old cylinder's;
3. for a sweep that left the tool at its start out, the sweep with that tool in;
4. a failing cell joined with a neighbour and split back at their wall
   (:meth:`SolidCutter.subtract_joined`): a cell's walls are where the grid put them, not the part's.

When every step fails the engine reports the CL FAILED and saves both shapes.

**Time budget** (``EngineOptions.kernel_budget_s``, :mod:`~fusioncut.engines.brep.budget`): with a
budget, each cell's :meth:`SolidCutter.subtract` (the intersections, the split, and the checks, for
every fuzzy value) runs in a killable child process, which sends back the volume removed, the new
material as binary BRep and the contact candidates (the sweep's faces that the split put on the new
material and not on the old boundary, found there from the split's history, which does not cross a
process boundary). All guarded calls of one CL share one :class:`~fusioncut.engines.brep.budget.Deadline`.
A call past it is killed and :class:`~fusioncut.engines.brep.budget.KernelBudgetExceeded` goes
straight out of the ladder (no step is retried: it would hang again). Since no cell is changed
before all are cut, the workpiece after such a CL is the one before it, as after any failed CL.
Unguarded, in the process: the joined-cell ladder step's fuse, face merge and split back
(:meth:`SolidCutter.subtract_joined`; its Booleans with the sweep are guarded).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import NamedTuple

from OCP.TopAbs import TopAbs_SOLID
from OCP.TopoDS import TopoDS_Shape

from OCP.TopAbs import TopAbs_Orientation
from OCP.TopoDS import TopoDS, TopoDS_Face

from fusioncut.engines.brep.budget import (Deadline, KernelBudgetExceeded, guarded, shape_bytes, shape_from_bytes,
                                           within)
from fusioncut.engines.brep.cells import Cell, halves, neighbours
from fusioncut.engines.brep.occ import (
    Vec3, compound, face_map, faces, fuse_all, intersections, on_old_boundary, pieces, split_pieces,
    strictly_inside, unify, volume, volume_change, without_slivers,
)
from fusioncut.engines.brep.sweep import SweptVolume
from fusioncut.engines.ceiling import tool_radii
from fusioncut.engines.segments import horizontal_direction
from fusioncut.errors import BooleanFailure
from fusioncut.model.moves import Move
from fusioncut.model.tools import MillingTool

__all__ = ["BooleanFailure", "CellPart", "SolidCut", "SolidCutter", "Subtraction", "contact_candidates",
           "end_probes"]


class Subtraction(NamedTuple):
    """One accepted Boolean: the volume removed (mm³), the new material (None when nothing was
    removed) and the split with its history (None when nothing was removed, or when the Boolean ran
    in a child process: then ``candidates`` holds the contact candidates found there)."""

    removed: float
    shape: TopoDS_Shape | None
    split: object | None
    candidates: list[TopoDS_Face] | None = None


def contact_candidates(split, new: TopoDS_Shape, sweep: TopoDS_Shape) -> list[TopoDS_Face]:
    """The faces of the sweep that the split ``split`` put on the new material ``new`` and that do
    not lie on the workpiece's old boundary (:func:`~fusioncut.engines.brep.occ.on_old_boundary`)."""
    kept, own, origins = face_map(new), face_map(sweep), split.Origins()
    out = []
    for f in faces(sweep):
        out.extend(g for g in map(TopoDS.Face, pieces(split, f))
                   if kept.Contains(g) and not on_old_boundary(g, origins, own))
    return out


class CellPart(NamedTuple):
    """A cell and the material a Boolean leaves it (None: all gone), with its volume (mm³)."""

    cell: Cell
    shape: TopoDS_Shape | None
    volume: float


@dataclass
class SolidCut:
    """What one 3D Boolean did: the cells it changes, the volume it removed (mm³), and the new shape
    with the split's history, where the contact faces are found (None when nothing was removed)."""

    parts: list[CellPart]
    removed: float
    shape: TopoDS_Shape | None
    split: object | None
    candidates: list[TopoDS_Face] | None = None

    def contact_candidates(self, sweep: TopoDS_Shape) -> list[TopoDS_Face]:
        """:func:`contact_candidates` of this cut with ``sweep`` (found in the child when it ran there)."""
        if self.candidates is not None:
            return self.candidates
        return [] if self.shape is None else contact_candidates(self.split, self.shape, sweep)


def end_probes(motion: Move, tool: MillingTool) -> tuple[Vec3, ...]:
    """Points (mm) inside the tool at the end of ``motion``, where material must go if the IPW holds
    them: on the axis half the tool's reach (or length) up, and, for a motion with a horizontal
    direction at its end, 0.9 of the tool's radius at that height ahead of the axis. The front
    point is where a slot's new material lies when the end point on the axis is already in a hole."""
    end, (reach, _, length) = motion.end, tool_radii(tool)
    h = 0.5 * min(reach, length)
    axis = (end[0], end[1], end[2] + h)
    d = horizontal_direction(motion)
    if d is None:
        return (axis,)
    r = 0.9 * tool.profile().radius_at(h)
    return axis, (axis[0] + r * d[0], axis[1] + r * d[1], axis[2])


@dataclass
class SolidCutter:
    """The 3D Booleans of one CL with the cells of ``grid`` (mm, mm³).

    ``fuzzy_values``: the first fuzzy value and the retries, in order; ``threads``: the kernel's own
    threads (not in a guarded call's child: see :mod:`~fusioncut.engines.brep.budget`);
    ``stock_volume``: the scale of "nothing removed"; ``deadline``: the CL's kernel budget.
    """

    grid: list[Cell]
    fuzzy_values: tuple[float, ...]
    threads: bool
    stock_volume: float
    deadline: Deadline = field(default_factory=lambda: Deadline(None))
    # the sweep whose volume was integrated last, and that volume: once for all the cells a CL cuts
    _sweep_volume: tuple[TopoDS_Shape, float] | None = field(default=None, init=False, repr=False)
    # the sweep last sent to the kernel's child, as binary BRep: once for all the cells a CL cuts
    _sweep_bytes: tuple[TopoDS_Shape, bytes] | None = field(default=None, init=False, repr=False)

    def cut_with_retries(self, cells: list[Cell], sweep: SweptVolume, probes: tuple[Vec3, ...],
                         resweep: Callable[[float, bool], SweptVolume], open_start: bool,
                         not_joined: list[Cell]) -> tuple[list[SolidCut], SweptVolume]:
        """The Booleans of ``cells`` with ``sweep``, climbing the module's ladder; the cuts and the
        sweep they were made with. ``resweep(turn, open_start)`` builds the sweep again with its
        seams ``turn`` rad on; a cell is never joined with one of ``not_joined`` (cut as layers).
        Raises :class:`BooleanFailure` when every step fails, :class:`KernelBudgetExceeded` as soon
        as one runs past the CL's budget."""
        try:
            return self.cut_cells(cells, sweep.shape, probes), sweep
        except BooleanFailure:
            pass
        for turn, start_left_out in ((0.5 * math.pi, open_start), *(((0.0, False),) if open_start else ())):
            try:
                other = resweep(turn, start_left_out)
                results = self.cut_cells(cells, other.shape, probes)
            except KernelBudgetExceeded:
                raise
            except Exception:  # noqa: BLE001 - a sweep not built, or its Booleans failed too
                continue
            return results, replace(other, method=sweep.method)
        return self.cut_cells(cells, sweep.shape, probes, join_avoiding=not_joined), sweep

    def cut_cells(self, cells: list[Cell], sweep: TopoDS_Shape, probes: tuple[Vec3, ...],
                  join_avoiding: list[Cell] | None = None) -> list[SolidCut]:
        """The Boolean of each solid cell with ``sweep``; raises :class:`BooleanFailure`.

        ``join_avoiding`` (a list, maybe empty): a cell whose Boolean fails is tried once more joined
        with a neighbour that is not in that list (see :meth:`subtract_joined`).
        """
        out: list[SolidCut] = []
        joined: set[int] = set()
        for c in cells:
            if id(c) in joined:
                continue
            try:
                sub = self.subtract(c.shape, sweep, c.volume, probes)
            except BooleanFailure:
                if join_avoiding is None:
                    raise
                busy = {id(x) for x in join_avoiding} | joined
                cut = self.subtract_joined(c, sweep, probes, busy)
                joined.update(id(p.cell) for p in cut.parts)
                out = [r for r in out if not any(id(p.cell) in joined for p in r.parts)]
                out.append(cut)
                continue
            out.append(SolidCut([CellPart(c, sub.shape, c.volume - sub.removed)], *sub))
        return out

    def subtract_joined(self, cell: Cell, sweep: TopoDS_Shape, probes: tuple[Vec3, ...], busy: set[int]) -> SolidCut:
        """The Boolean of ``cell`` joined with a neighbour sharing one of its walls, split back at
        that wall; the first neighbour (not in ``busy``, by id) for which that works.

        A part's faces may meet a cell's wall tangentially (a slot's side on a column's wall,
        tangent to the hole a plunge left), and the General Fuse then finds nothing inside the sweep
        and rebuilds the cell larger, at every fuzzy value and with the seams turned. Joined with
        the cell beside it, the wall is gone and the Boolean right (the layered cells, which cut in
        2D, agree CL by CL); splitting back along the wall is a plain Common with a box. The two
        parts must hold the joined result's volume (1e-9 relative + 1e-6 mm³) and neither more than
        its cell held.
        """
        last = "no neighbour shares a wall with the cell"
        for n, axis, at in neighbours(self.grid, cell):
            if id(n) in busy:
                continue
            try:
                with within(self.deadline):
                    joint = unify(fuse_all([cell.shape, n.shape]), cell.volume + n.volume)
                sub = self.subtract(joint, sweep, cell.volume + n.volume, probes)
                new = sub.shape
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
            return SolidCut([CellPart(cell, mine, v_mine), CellPart(n, theirs, v_theirs)], *sub)
        raise BooleanFailure(f"{last} (the cell alone failed)")

    def sweep_volume(self, sweep: TopoDS_Shape) -> float:
        """The volume of ``sweep`` (mm³), integrated once for all the cells a CL cuts."""
        if self._sweep_volume is None or not self._sweep_volume[0].IsSame(sweep):
            self._sweep_volume = (sweep, volume(sweep))
        return self._sweep_volume[1]

    def subtract(self, ipw: TopoDS_Shape, sweep: TopoDS_Shape, ipw_volume: float,
                 probes: tuple[Vec3, ...] = ()) -> Subtraction:
        """:meth:`subtract_here`, in a killable child when the CL has a budget (see the module)."""
        if not self.deadline.guards:
            return self.subtract_here(ipw, sweep, ipw_volume, probes)

        if self._sweep_bytes is None or not self._sweep_bytes[0].IsSame(sweep):
            self._sweep_bytes = (sweep, shape_bytes(sweep))
        removed, data, found, swept = guarded(
            _subtract_in_child, (shape_bytes(ipw), self._sweep_bytes[1], ipw_volume, probes, self.fuzzy_values,
                                 self.stock_volume), self.deadline, "the Boolean of a cell with the sweep")
        if swept is not None:
            self._sweep_volume = (sweep, swept)
        if data is None:
            return Subtraction(removed, None, None)
        new = shape_from_bytes(data)
        index = face_map(new)
        candidates = [TopoDS.Face(index.FindKey(i).Oriented(TopAbs_Orientation(o))) for i, o in found]
        return Subtraction(removed, new, None, candidates)

    def subtract_here(self, ipw: TopoDS_Shape, sweep: TopoDS_Shape, ipw_volume: float,
                      probes: tuple[Vec3, ...] = ()) -> Subtraction:
        """``ipw`` minus ``sweep``, tried with each fuzzy value until a result passes the checks.

        The pieces inside and outside the sweep must add up to the old IPW (old volume − new volume
        = removed): on nearly tangent faces, such as the floors a helical entry leaves, OCCT can
        build a wrong shape without reporting an error. That holds when nothing is removed too: a
        ball's plunge beside its last one, its cylinder meeting the old one's near both seams, came
        out as no piece inside and the IPW rebuilt larger (the kernel only warned of an acquired
        self-intersection). Nothing removed while one of ``probes`` (mm, points inside the sweep)
        lies inside the IPW is a failure as well (a slot tangent to the last plunge's hole split
        nothing), and so is more removed than the sweep holds. Raises :class:`BooleanFailure` with
        the last reason.
        """
        last = "unknown"
        for fuzzy in self.fuzzy_values:
            pf = intersections(ipw, sweep, fuzzy, self.threads)
            split = None if pf is None else split_pieces(ipw, sweep, pf, TopAbs_SOLID, self.threads)
            if split is None:
                last = f"intersection or split reported errors (fuzzy={fuzzy})"
                continue
            op, inside, outside = split
            removed = volume(compound(inside)) if inside else 0.0
            # GProp's volume of a large, many-faced IPW is good to about 1e-7 of it, and fuzzy noise
            # stays below 0.01 mm³; the wrong shapes are off by far more
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
                return Subtraction(0.0, None, None)
            sweep_volume = self.sweep_volume(sweep)
            if removed > sweep_volume * (1 + 1e-6) + 1e-9:
                # more material than the tool swept: the intersection went wrong, not the physics
                last = f"removed {removed:.6g} mm³ > swept {sweep_volume:.6g} mm³ (fuzzy={fuzzy})"
                continue
            new = compound(outside)
            mismatch = -volume_change(ipw, new) - removed
            if abs(mismatch) > allowed:
                last = f"the pieces in and out of the sweep disagree by {mismatch:.4g} mm³ (fuzzy={fuzzy})"
                continue
            return Subtraction(removed, without_slivers(ipw, new), op)
        raise BooleanFailure(last)


def _subtract_in_child(ipw: bytes, sweep: bytes, ipw_volume: float, probes: tuple[Vec3, ...],
                       fuzzy_values: tuple[float, ...], stock_volume: float) -> tuple:
    """:meth:`SolidCutter.subtract_here` in the kernel's child, on one thread (see
    :mod:`~fusioncut.engines.brep.budget`): the volume removed, the new material as binary BRep and
    its contact candidates as (index in its face map, orientation), and the sweep's volume when it
    was integrated (None: all three None when nothing was removed)."""
    cutter = SolidCutter([], fuzzy_values, False, stock_volume)
    ipw_shape, sweep_shape = shape_from_bytes(ipw), shape_from_bytes(sweep)
    sub = cutter.subtract_here(ipw_shape, sweep_shape, ipw_volume, probes)
    swept = cutter._sweep_volume[1] if cutter._sweep_volume is not None else None
    if sub.shape is None:
        return sub.removed, None, None, swept
    index = face_map(sub.shape)
    found = [(index.FindIndex(f), int(f.Orientation())) for f in contact_candidates(sub.split, sub.shape, sweep_shape)]
    return sub.removed, shape_bytes(sub.shape), found, swept
