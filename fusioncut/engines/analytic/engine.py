"""The analytic engagement engine: exact 3-axis engagement from the toolpath, no Booleans (issue 26).

For tools of revolution without undercut moved in 3 axes over a box stock or a round bar along z,
the in-process workpiece before CL k is ``stock ∩ {z <= h_k(x, y)}`` with ``h_k`` the lowest lower
surface of the sweeps of CLs 0..k-1 (:mod:`.sweeps`; the tool extends straight up, as a 3-axis
tool's shank and holder do). A round bar is its box less its outside, which is indexed as the
first sweep (:func:`.sweeps.outside_row`), so that every stage meets the bar's side as an earlier
wall. Nothing is built or kept but the sweeps themselves (one row each, :mod:`.index`):

* the **removed volume** of CL k integrates ``min(h_k, top) - max(L_k, bottom)`` over its
  footprint (:mod:`.volume`), to ``volume_tol`` mm per mm² of footprint or ``volume_rel`` of the
  volume (QUADPACK's ``epsabs`` and ``epsrel``; :class:`AnalyticEngine` says how the cells share
  them, the cells likely to hold the most volume first), cell by cell: tiles
  (:func:`.partition.volume_cells`), quartered while many earlier sweeps can shape the removed height in them or a
  quarter is proven to remove nothing (and is skipped), each cell integrated with only the sweeps
  that can shape it there (:mod:`.cells`); a CL whose whole footprint an earlier, deeper sweep
  holds removes nothing and is not integrated (:func:`.cells.held_below`); a cell where the CL and
  every sweep shaping it are level flat cuts is not integrated but computed in closed form
  (:mod:`.flat`), and quartered only beyond :data:`FLAT_SWEEPS` of them; where the CL is a flat end
  mill's arc or helix and every sweep shaping the cell is on its axis or level, or the CL is level and
  the sweeps shaping the cell are level or on the axis of an earlier helix (a helical entry's ledge),
  the inner integral runs over the angle about the axis, in closed form (:mod:`.polar`);
* its **engagement** is found slice by slice on the tool at the CL's end (:mod:`.contact`): arcs
  where material was before the CL and the tool's surface is on the sweep's front, their ends
  bisected to 1e-10 rad; the slices are laid out and converted to immersion angles as the B-Rep
  engine does (:func:`fusioncut.engines.brep.engine.slice_heights`, ``engagement_map``), so the
  output is the same :class:`~fusioncut.model.engagement.EngagementMap` per CL;
* the flute contact's height range (``ap``): the lowest and highest touching heights among the
  quarter slices and the heights of the stock's top and the earlier sweeps' ends (walking up from
  the bottom and down from the stock's top), each found to 1e-10 mm against its neighbour
  (:func:`.contact.contact_range`); on a flat end mill's side, from its lowest engaged height to the
  highest top of the engaged heights around it (:func:`.cylinder.side_range`);
* a slice band **rubs** (:mod:`fusioncut.engines.chip`) by the volume removed within its heights:
  the removed volume's integral split by the bands' edges on the same nodes;
* the **contact areas** integrate the engaged arcs' span over the tool's surface (:mod:`.area`; a flat
  end mill's side, the engaged heights around it, :mod:`.cylinder`):
  the flutes' over the flute contact's height range, the shank's (the tool taken straight up at
  ``R`` above the flutes, as it is swept) over its own range above the flutes, found as the
  flutes' is;
* the earlier sweeps near the CL come from a grid index of their footprints, where the CLs of one
  move are one sweep (:class:`.index.SweepIndex`).

Since the workpiece before a CL follows from the path alone, :meth:`AnalyticEngine.process` can
start at any CL: the sweeps before it are indexed, not evaluated. A checkpoint
(:meth:`AnalyticEngine.save_checkpoint`) therefore holds the stock, the removed total, the next CL
and the sweep rows; on resume the rows are indexed again from the path and must equal the saved
ones (a checkpoint of another toolpath is refused). There is no B-Rep in-process workpiece
(``ipw`` is None; ``ipw_volume`` is the stock's less the removed total), so a run exports none; its
volume is integrated from the sweeps alone by :meth:`AnalyticEngine.material_volume`, which checks
the CLs' volumes (the volume's conservation).

The CL segments are the B-Rep engine's (:func:`fusioncut.engines.segments.segments_for`), so CL
indices match; a piece of a ramp or helix is swept along the programmed path itself, not as the
B-Rep engine's level step. A neck or shank wider than the flutes is one more sweep per CL, of a
flat-bottomed part of the tool (:func:`.profile.upper_parts`, :meth:`AnalyticEngine.part_sweeps`):
its removed volume is what it takes beyond the CL's lower parts, its contact is shank contact. Not
here: a stock read from a solid (STEP, BREP).
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

import numpy as np

from fusioncut.engines.analytic.area import Shape, contact_area
from fusioncut.engines.analytic.breaks import curves_at, sweep_curves, x_breaks
from fusioncut.engines.analytic.cells import DOMINANCE_MOST, held_below
from fusioncut.engines.analytic.contact import N_SCAN, N_TOUCH, contact_range, slice_arcs, sweep_grid
from fusioncut.engines.analytic.cylinder import side_area, side_range
from fusioncut.engines.analytic.flat import all_level_flat, flat_cells_volume
from fusioncut.engines.analytic.heightmap import NODE_RADII, grid, height_map, ipw_mesh
from fusioncut.engines.analytic.index import ProfileTable, SweepIndex
from fusioncut.engines.analytic.partition import FLAT, POLAR, volume_cells
from fusioncut.engines.analytic.polar import polar_volume
from fusioncut.engines.analytic.profile import (LowerProfile, lower_profile, profile_height, profile_radius,
                                                profile_radius_slope, upper_parts)
from fusioncut.engines.analytic.sections import sections_apply
from fusioncut.engines.analytic.sweeps import LINE, NCOL, OUTSIDE, arc_row, is_flat, line_row, outside_row, vertical_row
from fusioncut.engines.analytic.volume import removed_volume, rough_volume
from fusioncut.engines.base import EngineKind, EngineOptions, SweepMethod
from fusioncut.engines.cl_maps import CL, CutOutcome, cl_base, cl_sequence, engagement_map, slice_heights
from fusioncut.errors import InputError
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.moves import ArcMove, ArcPlane, Move, Toolpath
from fusioncut.model.stock import BoxStock, CylinderStock, Stock
from fusioncut.model.tools import MillingTool

WALL_EPS = 1e-10  # mm: a point this close to an earlier sweep's surface counts as cut (zero-thickness walls)
VOLUME_EPS = 1e-12  # mm³: a CL removing less is idle (air, or a rapid through air)
TILE_RADII = 4.0  # the volume's tiles are at most this many tool radii wide
CELL_SWEEPS = 12  # a cell of the volume's integral met by more earlier sweeps is quartered (.cells),
# as is one with a quarter where nothing can be removed
MIN_CELL_RADII = 0.125  # down to this many tool radii wide
POLAR_SWEEPS = CELL_SWEEPS  # a cell whose sweeps are all on the CL's axis or level (.polar) and which an earlier
# helix holds in part (polar.held_annuli) is not quartered up to this many: its held radii cost nothing there
FLAT_FORMS = POLAR_FORMS = SECTION_FORMS = True  # the closed forms (.flat, .polar, .sections' inner integrals) are
# taken where they apply (False: those cells are integrated adaptively, as the tests' differential checks do)
FLAT_SWEEPS = 8  # a cell whose sweeps are all level and flat is integrated in closed form (.flat) whole up to
# this many, not quartered where a quarter is empty; with more, its quarters cost less (the closed form's parts
# between curve meetings grow as the square of the curves, and each part's regions with them)
SIDE_REL = 1e-9  # a flat end mill's side contact area's tolerance, relative (.cylinder)
AREA_WARN = 1e-6  # relative: a contact area whose error estimate is over this share of it comes with a warning
# (its rule ran out of evaluations, .area.MAX_EVALS)
END_GRID = 8  # cells a side of the grid over the tool's square at the CL's end (contact.sweep_grid)
log = logging.getLogger("fusioncut.analytic")
BAND_TOL = 1e-6  # mm: a slice this close to a height where material may begin or end is scanned on its own
STATE = "state.json"  # in a checkpoint folder: the next CL (what the runner's tests and people read)
SWEEPS = "ipw-sweeps.npz"  # the engine state; named like the B-Rep engine's IPW files so that a
# fresh run clears it with them


@dataclass(frozen=True)
class PartSweep:
    """The sweep of one convex part of the tool over a CL (:func:`.profile.upper_parts`): its lower
    profile, row (:data:`.sweeps.SWEEP_COLUMNS`, the path raised by ``height``), footprint box (x0,
    y0, x1, y1) and lowest height (mm); ``height`` is the part's bottom above the tool's tip (0 for
    the cutting part)."""

    profile: LowerProfile
    row: np.ndarray
    box: tuple[float, float, float, float]
    z_low: float
    height: float = 0.0


class UnsupportedStock(InputError):
    """A stock the analytic engine cannot take (it needs a box or a round bar along z)."""


class CheckpointMismatch(InputError):
    """A checkpoint whose sweeps are not the toolpath's before its next CL."""


@dataclass
class AnalyticEngine:
    """Exact Boolean-free engine for 3-axis tools of revolution over a box stock or a round bar.

    ``bin_size`` (mm): the sweep index's grid (None: twice the first tool's diameter).
    ``volume_tol`` (mm) and ``volume_rel``: the removed volume's integration tolerance, per mm² of
    footprint and relative to the volume; each cell's integral stops at the loosest of ``volume_tol``
    per mm² of it, ``volume_rel`` of its own volume and ``volume_rel`` of the CL's volume found so far
    times its share of the integrated area (:meth:`_removed`), so the CL's error estimate is within
    ``volume_tol`` x area + 2 ``volume_rel`` x volume. ``volume_rel`` is a tenth of the 1e-7 asked of
    a CL's volume (issue 26).
    """

    options: EngineOptions = field(default_factory=EngineOptions)
    bin_size: float | None = None
    volume_tol: float = 1e-10
    volume_rel: float = 1e-8
    stock: tuple[float, ...] = ()  # the stock's box: x0, y0, z0, x1, y1, z1 (mm)
    round_bar: tuple[float, ...] = ()  # a round bar's axis and radius in that box: cx, cy, r (mm); () for a box
    removed_total: float = 0.0
    _index: SweepIndex | None = field(default=None, init=False, repr=False)
    _tools: ProfileTable = field(default_factory=ProfileTable, init=False, repr=False)
    _saved_sweeps: np.ndarray | None = field(default=None, init=False, repr=False)
    # the CLs indexed, in order, with their footprint boxes (.fallback builds a local workpiece of them)
    _done: list[tuple[CL, tuple[float, float, float, float]]] = field(default_factory=list, init=False, repr=False)

    @property
    def kind(self) -> EngineKind:
        return EngineKind.ANALYTIC

    @property
    def shares_cells(self) -> bool:
        return False

    def close(self) -> None:
        """Nothing is held outside this process."""

    def start(self, stock: Stock) -> None:
        if isinstance(stock, BoxStock):
            self._reset(stock.bounds, 0.0)
        elif isinstance(stock, CylinderStock):
            self._reset(stock.bounds, 0.0, (*stock.base_center[:2], stock.radius))
        else:
            raise UnsupportedStock(f"the analytic engine needs a box stock or a round bar, got {type(stock).__name__} "
                                   "(choose the brep engine for it)")

    def stock_model(self) -> Stock:
        """The stock this engine was started with (or its checkpoint holds)."""
        s = self.stock
        if self.round_bar:
            cx, cy, r = self.round_bar
            return CylinderStock((cx, cy, s[2]), r, s[5] - s[2])
        return BoxStock(s[:3], s[3:])

    def _reset(self, stock: tuple[float, ...], removed_total: float, round_bar: tuple[float, ...] = ()) -> None:
        self.stock = tuple(float(v) for v in stock)
        self.round_bar = tuple(float(v) for v in round_bar)
        self.removed_total = removed_total
        self._index = SweepIndex(self.bin_size) if self.bin_size else None
        self._tools = ProfileTable()
        self._saved_sweeps = None
        self._done = []

    @property
    def ipw(self) -> None:
        """None: this engine keeps no B-Rep workpiece, only the sweeps (see the module docstring)."""
        return None

    @property
    def ipw_volume(self) -> float:
        """The workpiece's volume (mm³): the stock's less what the CLs handed out removed."""
        return self.stock_volume - self.removed_total

    def ipw_mesh(self, step: float | None = None) -> np.ndarray:
        """The workpiece after the CLs indexed so far as a closed triangle mesh ((n, 3, 3), mm,
        :func:`.heightmap.ipw_mesh`): its exact height at the nodes of a grid ``step`` mm apart
        (None: :data:`.heightmap.NODE_RADII` of the smallest tool radius met, or the stock's
        smaller side / 64 before any), as coarse as :data:`.heightmap.MAX_NODES` needs."""
        s = self._started("asking for its workpiece")
        if step is None:
            radii = self._tools.radii
            step = NODE_RADII * float(radii.min()) if radii.size else min(s[3] - s[0], s[4] - s[1]) / 64
        xs, ys = grid((s[0], s[1], s[3], s[4]), step)
        n = self._index.size if self._index else 0
        rows = self._index.rows[:n] if self._index else np.zeros((0, NCOL))
        boxes = self._index.boxes[:n] if self._index else np.zeros((0, 4))
        t = self._tools
        Z = height_map(rows, boxes, t.profiles, t.counts, t.radii, xs, ys, s[2], s[5])
        if self.round_bar:  # the bar's outside (also before its row is indexed at the first CL)
            cx, cy, r = self.round_bar
            Z[np.hypot(*np.meshgrid(xs - cx, ys - cy)) >= r] = s[2]
        return ipw_mesh(xs, ys, Z, s[2])

    def _sweeps(self) -> np.ndarray:
        n = self._index.size if self._index else 0
        return self._index.rows[:n].copy() if self._index else np.zeros((0, 0))

    def save_checkpoint(self, folder: Path, next_cl: int) -> None:
        """Write the stock, the removed total (mm³), ``next_cl`` and the sweep rows into ``folder``:
        :data:`SWEEPS` (the state, replaced whole) then :data:`STATE` (``next_cl`` for readers)."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        tmp = folder / (SWEEPS + ".tmp")
        with open(tmp, "wb") as f:
            np.savez(f, stock=np.array(self.stock), round_bar=np.array(self.round_bar, dtype=np.float64),
                     removed_total=np.array(self.removed_total), next_cl=np.array(next_cl), sweeps=self._sweeps())
        os.replace(tmp, folder / SWEEPS)
        tmp = folder / (STATE + ".tmp")
        tmp.write_text(json.dumps({"engine": self.kind.value, "next_cl": next_cl, "state": SWEEPS}))
        os.replace(tmp, folder / STATE)

    def load_checkpoint(self, folder: Path) -> int | None:
        """Restore a checkpoint of :meth:`save_checkpoint`; its next CL, or None when there is none
        readable. The sweeps are indexed again by :meth:`process` and checked against the saved rows."""
        try:
            with np.load(Path(folder) / SWEEPS, allow_pickle=False) as saved:
                stock, removed = tuple(saved["stock"]), float(saved["removed_total"])
                next_cl, sweeps = int(saved["next_cl"]), saved["sweeps"]
                round_bar = tuple(saved["round_bar"]) if "round_bar" in saved.files else ()
        except (OSError, ValueError, KeyError):
            return None
        if len(stock) != 6 or len(round_bar) not in (0, 3):
            return None
        self._reset(stock, removed, round_bar)
        self._saved_sweeps = sweeps
        return next_cl

    @property
    def stock_volume(self) -> float:
        s = self.stock
        if self.round_bar:
            return math.pi * self.round_bar[2] ** 2 * (s[5] - s[2])
        return (s[3] - s[0]) * (s[4] - s[1]) * (s[5] - s[2])

    def run(self, toolpath: Toolpath, stock: Stock, default_tool: MillingTool | None = None) -> Iterator[EngagementMap]:
        self.start(stock)
        yield from self.process(toolpath, default_tool)

    def check_tools(self, toolpath: Toolpath, default_tool: MillingTool | None = None) -> None:
        """Refuse a toolpath with a tool this engine cannot sweep (:class:`.profile.UnsupportedTool`
        names the tool and why), before any CL is run."""
        for tool in [*toolpath.tools.values(), *([default_tool] if default_tool else [])]:
            lower_profile(tool)

    def process(self, toolpath: Toolpath, default_tool: MillingTool | None = None,
                start_at: int = 0) -> Iterator[EngagementMap]:
        """One map per CL segment from CL ``start_at`` on; the sweeps of the CLs before it are only
        indexed (their removed volume is not counted in ``removed_total``). After
        :meth:`load_checkpoint` they must be the checkpoint's sweeps (else :class:`CheckpointMismatch`)."""
        self._started("processing")
        for cl in self.cl_sequence(toolpath, default_tool):
            if cl.index < start_at:
                self.index_only(cl)
                continue
            if cl.index == start_at:
                self.check_saved_sweeps(toolpath)
            yield self.step(cl)

    def cl_sequence(self, toolpath: Toolpath, default_tool: MillingTool | None = None,
                    start_at: int = 0) -> Iterator[CL]:
        """The CL segments this engine computes: :func:`.cl_maps.cl_sequence`'s (the same CLs as the
        B-Rep engine's), a helix too steep to be stepped cut into pieces on the helix rather than
        chords (:func:`fusioncut.engines.segments.helix_pieces`): it sweeps helices exactly, and the
        pieces of one helix are one sweep in its index. :meth:`index_only` takes these."""
        return cl_sequence(toolpath, self.options, default_tool, start_at, exact_arcs=True)

    def index_only(self, cl: CL) -> None:
        """Take CL ``cl`` as done without computing it: its sweep is indexed, nothing is counted."""
        self._take(cl, self.part_sweeps(cl))

    def record(self, cl: CL, m: EngagementMap) -> None:
        """Take CL ``cl`` as done by another engine on the same path (a parallel worker): its sweep
        is indexed and its removed volume (``m``, mm³) counted, as :meth:`step` would have."""
        self.index_only(cl)
        self.removed_total += m.removed_volume

    def check_saved_sweeps(self, toolpath: Toolpath) -> None:
        """After :meth:`load_checkpoint` and indexing the CLs before its next one: the sweeps must be
        the checkpoint's (else :class:`CheckpointMismatch`)."""
        saved, self._saved_sweeps = self._saved_sweeps, None
        if saved is not None and not np.array_equal(saved.reshape(-1, NCOL), self._sweeps().reshape(-1, NCOL)):
            raise CheckpointMismatch("the checkpoint's sweeps are not this toolpath's; run it afresh",
                                     toolpath.source or None)

    def _index_of(self, profile: LowerProfile) -> SweepIndex:
        if self._index is None:
            self._index = SweepIndex(4 * profile.radius)
        if self._index.size == 0 and self.round_bar:
            row, box = self._outside(self._tools.index_of(profile))
            self._index.add(row, box, row[3], everywhere=True)
        return self._index

    def _started(self, what: str) -> tuple[float, ...]:
        """The stock's box; an :class:`InputError` naming ``what`` was asked before :meth:`start`."""
        if not self.stock:
            raise InputError(f"the analytic engine has no stock yet: start() it (or load a checkpoint) before {what}")
        return self.stock

    def _outside(self, tool: int) -> tuple[np.ndarray, tuple[float, float, float, float]]:
        """(the row, its box) of a round bar's outside, cut before the first CL: 1 mm below the bar's
        bottom, over its whole box (``tool``: any table index)."""
        s, (cx, cy, r) = self.stock, self.round_bar
        return outside_row((cx, cy), r, s[2] - 1.0, tool), (s[0], s[1], s[3], s[4])

    def step(self, cl: CL) -> EngagementMap:
        """Process one CL segment (its map says ``engine="analytic"``); ``timings_ms`` holds each
        stage's wall time and the ``total`` (ms). Never raises for a CL it cannot compute: that CL
        goes to the B-Rep engine on a local workpiece (:mod:`.fallback`, ``engine="brep"``; FAILED
        when that fails too), and its sweep is indexed all the same, so later CLs are unaffected."""
        t0 = time.perf_counter()
        try:
            m = replace(self._step(cl), engine=EngineKind.ANALYTIC.value)
        except Exception as exc:  # noqa: BLE001 - any error of this CL's computation: the fallback's
            m = self._fallback(cl, f"{type(exc).__name__}: {exc}")
            timings = {**dict(m.timings_ms), "total": (time.perf_counter() - t0) * 1e3}
            m = replace(m, timings_ms=tuple(timings.items()))
        return m

    def part_sweeps(self, cl: CL) -> list[PartSweep]:
        """The sweeps of CL ``cl``'s tool parts: the cutting part's, then each wider neck or shank's
        (:func:`.profile.upper_parts`) whose lowest point is below the stock's top (one above it
        can never meet material, and is left out)."""
        profile = lower_profile(cl.tool)
        out = [PartSweep(profile, *sweep_row(cl.move, profile, self._tools.index_of(profile)))]
        for part in upper_parts(cl.tool):
            row, box, z_low = sweep_row(cl.move, part.profile, self._tools.index_of(part.profile))
            if z_low + part.height >= self.stock[5]:
                break  # the parts come by increasing height
            row[3] += part.height
            row[6] += part.height
            out.append(PartSweep(part.profile, row, box, z_low + part.height, part.height))
        return out

    def _take(self, cl: CL, parts: list[PartSweep]) -> None:
        """Take CL ``cl``'s part sweeps (:meth:`part_sweeps`) as cut."""
        index = self._index_of(parts[0].profile)
        for p in parts:
            index.add(p.row, p.box, p.z_low)
        self._done.append((cl, _union(p.box for p in parts)))

    def _fallback(self, cl: CL, why: str) -> EngagementMap:
        """CL ``cl`` by :func:`.fallback.brep_fallback` (the analytic step raised ``why``), its sweep
        indexed and its removed volume counted as :meth:`_step` would have."""
        from fusioncut.engines.analytic.fallback import brep_fallback

        log.warning("CL %d (%s): the analytic engine failed (%s); the B-Rep engine computes it on a local workpiece",
                    cl.index, cl.move.source, why)
        try:
            parts = self.part_sweeps(cl)
        except Exception as exc:  # noqa: BLE001 - no sweep to index: this CL fails, the run goes on
            return EngagementMap(**cl_base(cl), status=CLStatus.FAILED, engine=EngineKind.ANALYTIC.value,
                                 reason=f"analytic engine: {why}; its sweep cannot be built: {exc}")
        m = brep_fallback(cl, _union(p.box for p in parts), self._done, self.stock_model(), self.options, why)
        self._take(cl, parts)
        self.removed_total += m.removed_volume
        return m

    def _step(self, cl: CL) -> EngagementMap:
        move, tool = cl.move, cl.tool
        t0 = time.perf_counter()
        parts = self.part_sweeps(cl)
        cut = parts[0]
        row, profile = cut.row, cut.profile
        index = self._index_of(profile)
        whole = _union(p.box for p in parts)
        near = index.near((whole[0] - WALL_EPS, whole[1] - WALL_EPS, whole[2] + WALL_EPS, whole[3] + WALL_EPS),
                          z_max=self.stock[5])
        C, CB = index.rows[near], index.boxes[near]
        t1 = time.perf_counter()
        edges = self._band_edges(row[6], tool)
        removed, band_volumes = self._removed(row, profile, C, CB, cut.box, edges)
        for i, p in enumerate(parts[1:], 1):
            # what a wider part takes beyond the CL's lower parts: theirs count as earlier sweeps
            removed += self._removed(p.row, p.profile, *_with_own(C, CB, parts[:i]), p.box, np.zeros(0))[0]
        t2 = time.perf_counter()
        timings = {"index": (t1 - t0) * 1e3, "volume": (t2 - t1) * 1e3}
        idle = CLStatus.RAPID if move.is_rapid else CLStatus.AIR
        heights: list[tuple[float, bool]] = []
        arcs: list[list[tuple[float, float]]] = []
        if removed <= VOLUME_EPS:
            outcome = CutOutcome(idle, method=SweepMethod.EXACT, timings=timings)
        else:
            top, dz = self.stock[5], self.options.slice_height
            args, near = self._end_args(cut, parts, C, CB)
            levels = sorted({top, *args[3][near, 3], *args[3][near, 6]})
            z_range = self._range(args, near, cut, 0.0, tool.flute_length, levels)
            heights = slice_heights(z_range, tool, dz)
            # a flat end mill's level CL among flat cuts of one height each: the slices between the same two
            # heights where material can begin or end hold the same arcs (.contact: a point's material and
            # front tests compare its height only with those), so each band is scanned once
            banded = all_level_flat(row, profile.pieces, args[3][near], self._tools.profiles, self._tools.counts,
                                    plunges=True)
            bounds = np.array(sorted({self.stock[2], *levels})) if banded else None
            scanned: dict[int, list[tuple[float, float]]] = {}
            for z, active in heights:
                band = _band(row[6] + z, bounds) if banded and active else None
                if band is None:
                    arcs.append(_arcs_at(args, z) if active else [])
                    continue
                if band not in scanned:
                    scanned[band] = _arcs_at(args, z)
                arcs.append(scanned[band])
            t3 = time.perf_counter()
            timings["contact"] = (t3 - t2) * 1e3
            flute_area = shank_area = 0.0
            warnings: list[str] = []
            wider = upper_parts(tool)
            if z_range is not None:
                flute_area = self._area(args, near, cut, z_range, warnings)
                # the cutting part taken straight up, as it is swept, up to the first wider part
                shank = self._range(args, near, cut, tool.flute_length, wider[0].height if wider else math.inf, levels) \
                    if z_range[1] >= tool.flute_length else None
                if shank is not None:
                    shank_area = self._area(args, near, cut, shank, warnings)
                    warnings += _narrow_neck(tool, profile, shank)
            for i, p in enumerate(parts[1:], 1):
                # a wider neck or shank touches wherever it meets material, up to the next wider part
                p_args, p_near = self._end_args(p, parts, C, CB)
                p_levels = sorted({top, *p_args[3][p_near, 3], *p_args[3][p_near, 6]})
                p_top = wider[i].height - p.height if i < len(wider) else math.inf
                rng = self._range(p_args, p_near, p, 0.0, p_top, p_levels)
                if rng is not None:
                    shank_area += self._area(p_args, p_near, p, rng, warnings)
            timings["area"] = (time.perf_counter() - t3) * 1e3
            outcome = CutOutcome(CLStatus.RAPID if move.is_rapid else CLStatus.ENGAGED, removed=removed,
                                 method=SweepMethod.EXACT, timings=timings, z_range=z_range,
                                 band_volumes=band_volumes if len(edges) else None, flute_area=flute_area,
                                 shank_area=shank_area, warnings=tuple(warnings))
        m = engagement_map(cl, outcome, heights, arcs, self.options.slice_height,
                           self.options.min_chip_thickness)
        self._take(cl, parts)  # the state changes last: a step that raised left it as it was
        self.removed_total += removed
        timings["total"] = (time.perf_counter() - t0) * 1e3
        return replace(m, timings_ms=tuple(timings.items()))

    def _range(self, args: tuple, near: np.ndarray, part: PartSweep, bottom: float, top: float, levels: list[float]
               ) -> tuple[float, float] | None:
        """The heights (mm above ``part``'s tip) between ``bottom`` and ``top`` where it touches material at the
        CL's end, or None (``args`` and ``near`` as :meth:`_end_args` gives them, ``levels`` the machine heights
        where the contact may start or end): a flat end mill's side (or a wider part's) from the engaged heights
        around it (:func:`.cylinder.side_range`), another tool's by its slices (:func:`.contact.contact_range`)."""
        if is_flat(part.profile.pieces):
            lo, hi = side_range(part.row, part.profile.pieces, part.profile.radius, bottom, top, args[3][near],
                                args[4][near], *args[5:10], N_TOUCH, *args[13:])
            return None if math.isnan(lo) else (float(lo), float(hi))
        return contact_range(args, bottom, top, self.options.slice_height, levels)

    def _area(self, args: tuple, near: np.ndarray, part: PartSweep, z_range: tuple[float, float],
              warnings: list[str]) -> float:
        """The contact area (mm²) of ``part``'s surface between the heights ``z_range`` (mm above its tip)
        at the CL's end (``args`` and ``near`` as :meth:`_end_args` gives them): a flat end mill's side (or a
        wider part's) by one integral around it of the engaged heights (:func:`.cylinder.side_area`),
        another tool's by the integral of the engaged span over its height (:func:`.area.contact_area`,
        its parts starting at :func:`_area_breaks`). Where the integral's error estimate is over
        :data:`AREA_WARN` of it, a warning saying so is appended to ``warnings``."""
        C, CB = args[3][near], args[4][near]
        if is_flat(part.profile.pieces):
            circles, segments = self._curves(np.vstack([part.row[None, :], C]), args[5], args[6])
            area, err = side_area(part.row, part.profile.pieces, part.profile.radius, *z_range, C, CB, *args[5:10],
                                  circles, segments, SIDE_REL)
        else:
            breaks = _area_breaks(C, args[5], args[6], self.stock[5] - part.row[6], part.row[6])
            area, err = contact_area(lambda z: _width(args, z), part.profile.pieces, *z_range, breaks)
        if err > AREA_WARN * abs(area):
            warnings.append(f"contact area not converged: error estimate {err:.2g} mm² on {area:.6g} mm² "
                            f"({z_range[0]:.4g} to {z_range[1]:.4g} mm above the tip)")
        return float(area)

    def _curves(self, rows: np.ndarray, P: np.ndarray, NP: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`.breaks.sweep_curves` of the sweeps ``rows`` (tool tables ``P``, ``NP``) about the stock's
        bottom and top."""
        return sweep_curves(rows, P, NP, self.stock[2], self.stock[5])

    def _end_args(self, part: PartSweep, parts: list[PartSweep], C: np.ndarray, CB: np.ndarray
                  ) -> tuple[tuple, np.ndarray]:
        """(the arguments of :func:`.contact.slice_arcs` for the slices of ``part`` at the CL's end (less the
        height, radius, slope and scan count), the indices among their sweeps of those that can shape the
        material there). A point there meets only the sweeps that can shape
        the material in its cell of a grid over the part's square (:func:`.contact.sweep_grid`): the
        earlier sweeps and the CL's other parts' sweeps, which hold what those parts took during the
        CL (they hold no point of this part's slices at the end itself: a wider part is higher, a
        narrower one stands inside it)."""
        s, row, R = self.stock, part.row, part.profile.radius
        C, CB = _with_own(C, CB, [p for p in parts if p is not part])
        ex, ey, reach = row[4], row[5], R + 2 * WALL_EPS
        at_end = ((CB[:, 0] <= ex + reach) & (CB[:, 2] >= ex - reach) & (CB[:, 1] <= ey + reach)
                  & (CB[:, 3] >= ey - reach))
        Ce, CBe = C[at_end], CB[at_end]
        t = self._tools
        # a flat profile's slices all lie on the circle of its radius: only the grid's cells on it are filled
        ring = (R - 2 * WALL_EPS, reach) if is_flat(part.profile.pieces) else (0.0, math.inf)
        grid = sweep_grid(ex - reach, ey - reach, 2 * reach, END_GRID, row, part.profile.pieces, R, Ce, t.profiles,
                          t.counts, t.radii, s[2], s[5], 2 * WALL_EPS, *ring)
        near = np.unique(grid[2])
        # the footprints' edges (walls): the boundary curves at each sweep's tool radius, each owned by its
        # sweep's row in Ce (slice_arcs leaves out the walls that stand wholly above its slice)
        shaping = Ce[near]
        walls = curves_at(shaping, t.radii[shaping[:, 12].astype(np.int64)][:, None],
                          np.ones(len(shaping), dtype=np.int64), np.full(len(shaping), math.nan))
        walls[0][:, 3] = near[walls[0][:, 3].astype(np.int64)]
        walls[1][:, 4] = near[walls[1][:, 4].astype(np.int64)]
        args = (row, part.profile.pieces, R, Ce, CBe, t.profiles, t.counts, t.radii, np.array(s), WALL_EPS, *grid, *walls)
        return args, near

    def _band_edges(self, ez: float, tool: MillingTool) -> np.ndarray:
        """Machine heights (mm) of the slice bands' edges from the tip at ``ez`` up to the flutes' or
        the stock's top, whichever is lower: the removed volume is split by them for the minimum chip
        thickness (:mod:`fusioncut.engines.chip`). Empty where that test is off."""
        dz = self.options.slice_height
        top = min(tool.flute_length, self.stock[5] - ez)
        if self.options.min_chip_thickness <= 0 or top <= 0:
            return np.zeros(0)
        return ez + dz * np.arange(math.ceil(top / dz - 1e-9) + 1)

    def material_volume(self, box: tuple[float, float, float, float] | None = None) -> float:
        """The workpiece's volume (mm³) over the XY ``box`` (x0, y0, x1, y1; None: the stock's) after the
        CLs indexed so far, integrated in one piece from their sweeps: ``min(h, top) - bottom`` where
        ``h`` is above the bottom, a round bar's outside taken as cut. It is the volume a flat tool
        wider than the box would remove from below the stock's bottom (:meth:`_removed`, that tool's
        sweep the CL's), so its cells and error budget are a CL's, tiled at the run's smallest tool
        radius. It does not read the CLs' removed volumes, whose sum it checks: over a run,
        ``stock_volume == material_volume() + removed_total`` to the integrals' tolerances (the
        volume's conservation); over a box holding CLs j..k's footprints, the box's material before
        CL j less that after CL k is those CLs' removed volume."""
        s = self._started("asking for its workpiece")
        box = box or (s[0], s[1], s[3], s[4])
        t = self._tools
        n = self._index.size if self._index else 0
        near = self._index.near(box) if n else np.zeros(0, dtype=np.int64)
        C, CB = (self._index.rows[near], self._index.boxes[near]) if n else (np.zeros((0, NCOL)), np.zeros((0, 4)))
        # the wide flat tool's lower profile, one piece (f = 0 out to its radius), after the run's tools
        reach = 0.5 * math.hypot(box[2] - box[0], box[3] - box[1]) + 1.0
        wide = LowerProfile(np.array([[LINE, 0.0, reach, 0.0, 0.0, 0.0]]), reach)
        tables, k = t.tables_with(wide), len(t.counts)
        if self.round_bar and n == 0:  # its outside is indexed at the first CL
            row, bar = self._outside(k)
            C, CB = np.vstack([row[None, :], C]), np.vstack([bar, CB])
        cx, cy = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
        row = line_row((cx, cy, s[2] - 2.0), (cx, cy, s[2] - 2.0), k)
        scale = float(t.radii.min()) if t.radii.size else reach
        return self._removed(row, wide, C, CB, box, np.zeros(0), tables, scale)[0]

    def _removed(self, row: np.ndarray, profile: LowerProfile, C: np.ndarray, CB: np.ndarray,
                 box: tuple[float, float, float, float], edges: np.ndarray, tables: tuple | None = None,
                 scale: float | None = None) -> tuple[float, tuple[float, ...]]:
        """The CL's removed volume (mm³) and its parts within the bands between ``edges`` (machine z,
        mm; :func:`.volume.removed_volume`), integrated cell by cell (module docstring), each cell
        with the sweeps that can shape the removed height in it and its share of the error budget.
        ``tables``: the tools' (profiles, counts, radii) (None: the run's); ``scale`` (mm): the radius
        the cells are sized by (None: the CL's tool's)."""
        s = self.stock
        bands = np.zeros(max(len(edges) - 1, 0))
        x0, x1 = max(box[0], s[0]), min(box[2], s[3])
        y0, y1 = max(box[1], s[1]), min(box[3], s[4])
        if x0 >= x1 or y0 >= y1 or min(row[3], row[6]) >= s[5]:
            return 0.0, tuple(bands)  # beside the stock, or above it: the lower surface is nowhere below the lowest tip
        P, NP, RR = tables or (self._tools.profiles, self._tools.counts, self._tools.radii)
        scale = scale or profile.radius
        if held_below(row, profile.radius, C, P, NP, RR):
            return 0.0, tuple(bands)  # retraced above a deeper pass that holds its whole footprint
        cells, kinds, starts, items = volume_cells(x0, y0, x1, y1, TILE_RADII * scale, row, profile.pieces,
                                                   profile.radius, C, CB, P, NP, RR, s[2], s[5],
                                                   MIN_CELL_RADII * scale, CELL_SWEEPS, FLAT_SWEEPS, POLAR_SWEEPS,
                                                   DOMINANCE_MOST, FLAT_FORMS, POLAR_FORMS)
        flat = kinds == FLAT
        total, flat_bands = flat_cells_volume(cells, flat, starts, items, row, profile.pieces, profile.radius, C, CB,
                                              P, NP, RR, s[2], s[5], edges)
        bands += flat_bands
        adaptive = []  # the cells to integrate adaptively, with their sweeps and boundary curves
        for i in np.flatnonzero(~flat):
            (cx0, cy0, cx1, cy1), rows = cells[i].tolist(), items[starts[i]:starts[i + 1]]
            Ct, CBt = C[rows], CB[rows]
            circles, segments = self._curves(np.vstack([row[None, :], Ct]), P, NP)
            adaptive.append((cx0, cy0, cx1, cy1, Ct, CBt, circles, segments, kinds[i] == POLAR))
        if adaptive:
            # the CL's relative budget shared by area, the cells likely to hold the most volume first: each
            # stops at the loosest of volume_tol per mm² of it, volume_rel of its own volume and volume_rel of
            # the CL's volume found so far times its share of the cells' area (so the CL's error estimate is
            # within volume_tol x area + 2 volume_rel x volume, and a cell holding a sliver of it is not held
            # to volume_rel of the sliver)
            area = sum((c[2] - c[0]) * (c[3] - c[1]) for c in adaptive)
            rough = [rough_volume(c[0], c[2], c[1], c[3], row, profile.pieces, profile.radius, c[4], c[5], P, NP, RR,
                                  s[2], s[5]) for c in adaptive]
            for k in np.argsort(rough, kind="stable")[::-1]:
                cx0, cy0, cx1, cy1, Ct, CBt, circles, segments, polar = adaptive[k]
                tol = max(self.volume_tol, self.volume_rel * total / area)
                if polar:
                    v, vb = polar_volume(cx0, cx1, cy0, cy1, circles, segments, row, profile.pieces, profile.radius,
                                         Ct, CBt, P, NP, RR, s[2], s[5], tol, self.volume_rel, edges)
                else:
                    xs = x_breaks(circles, segments, cx0, cx1, cy0, cy1, row, profile.pieces, profile.radius, Ct,
                                  CBt, P, NP, RR, s[2])
                    exact = SECTION_FORMS and sections_apply(row, profile.pieces, profile.radius, Ct, P, NP, RR)
                    v, vb = removed_volume(xs, cy0, cy1, circles, segments, row, profile.pieces, profile.radius, Ct,
                                           CBt, P, NP, RR, s[2], s[5], tol, self.volume_rel, edges, exact)
                total += v
                bands += vb
        return float(total), tuple(float(v) for v in bands)


def _narrow_neck(tool: MillingTool, profile: LowerProfile, touching: tuple[float, float]) -> list[str]:
    """The warning for a neck narrower than the flutes touching material within ``touching`` (mm above
    the tip, where the cutting part taken straight up touches): the real neck would leave an
    overhang there (:mod:`.profile`), which the height field takes as cut."""
    neck = tool.neck_radius
    if neck is None or tool.shoulder_length is None or neck >= profile.radius - 1e-9 \
            or touching[0] >= tool.shoulder_length:
        return []
    return [f"the neck ({2 * neck:g} mm) is narrower than the flutes ({2 * profile.radius:g} mm) and meets material "
            "here: the analytic engine takes it as wide as the flutes, so what it would leave hanging is cut "
            "(the brep engine models the neck)"]


def _union(boxes) -> tuple[float, float, float, float]:
    """The box (x0, y0, x1, y1) holding every box of ``boxes``."""
    x0s, y0s, x1s, y1s = zip(*boxes)
    return float(min(x0s)), float(min(y0s)), float(max(x1s)), float(max(y1s))


def _with_own(C: np.ndarray, CB: np.ndarray, parts: list[PartSweep]) -> tuple[np.ndarray, np.ndarray]:
    """The earlier sweeps ``C`` (boxes ``CB``) followed by the CL's part sweeps ``parts``."""
    if not parts:
        return C, CB
    return np.vstack([C, *(p.row[None, :] for p in parts)]), np.vstack([CB, np.array([p.box for p in parts])])


def _band(z: float, bounds: np.ndarray) -> int | None:
    """The index of the interval between the sorted heights ``bounds`` (mm) that holds ``z`` strictly inside,
    :data:`BAND_TOL` from either end; None where ``z`` is that close to one of them."""
    i = int(np.searchsorted(bounds, z))
    if (i > 0 and z - bounds[i - 1] <= BAND_TOL) or (i < len(bounds) and bounds[i] - z <= BAND_TOL):
        return None
    return i


def _found(args: tuple, z: float) -> np.ndarray:
    """:func:`.contact.slice_arcs` of the slice ``z`` mm above the tip (``args`` as
    :func:`.contact.contact_range` takes them): rows (start, span, start's cause, end's cause)."""
    pieces = args[1]
    return slice_arcs(args[0], pieces, args[2], z, profile_radius(pieces, z), profile_radius_slope(pieces, z),
                      *args[3:13], N_SCAN, *args[13:])


def _arcs_at(args: tuple, z: float) -> list[tuple[float, float]]:
    """The engaged machine arcs (start, span), rad, of the slice ``z`` mm above the tip."""
    return [(float(a), float(w)) for a, w, _, _ in _found(args, z)]


def _width(args: tuple, z: float) -> tuple[float, Shape]:
    """The engaged arcs' total span (rad) at ``z`` mm above the tip, and their shape: the contact
    area's integrand (:func:`.area.contact_area`), whose parts end where the shape changes. The
    shape is the number of arcs (-1: the whole circle) and the sorted causes of their ends
    (:func:`.contact.end_cause`: the front's limit, a stock face, an earlier sweep): where an end
    passes from one to another the span bends (from a front limit to an earlier pass's surface, with
    a square-root onset), which a part's end makes smooth."""
    found = _found(args, z)
    if len(found) == 1 and found[0, 1] >= 2 * math.pi:
        return 2 * math.pi, (-1, ())
    return float(found[:, 1].sum()), (len(found), tuple(sorted(found[:, 2:].ravel().tolist())))


def _area_breaks(shaping: np.ndarray, PP: np.ndarray, NPC: np.ndarray, top: float, ez: float) -> list[float]:
    """Heights (mm above the tip at machine height ``ez``) where the engaged span ``W`` may jump or
    bend at a known height: the stock's top (``top``), and for each earlier level sweep of
    ``shaping`` (tool tables ``PP``, ``NPC``) its tip plus each height where its profile's pieces
    meet: the region below such a sweep goes from none to its whole footprint at a flat bottom (a
    jump), and its edge's curvature jumps where a ball or corner meets the straight flank. Elsewhere
    a sweep's lowest point gives an arc born from a point (a change of the arcs' number, which
    :func:`.area.contact_area` finds as such)."""
    out = {top}
    for r in shaping:
        if r[3] != r[6] or r[0] == OUTSIDE:
            continue  # a ramp or helix: its profile's heights vary along it; a bar's side is vertical
        k = int(r[12])
        pieces = PP[k, :NPC[k]]
        out.update(float(r[3] + profile_height(pieces, d) - ez) for d in (0.0, *pieces[:, 2]))
    return sorted(out)


def _vertical_sweep_row(move: ArcMove, R: float, tool_index: int
                        ) -> tuple[np.ndarray, tuple[float, float, float, float], float]:
    """:func:`sweep_row` of a ZX / YZ arc within one quarter of its circle (:func:`.segments.quarter_pieces`):
    on its start's circle in its plane, ending at the programmed end's angle (:mod:`.vertical`); a piece
    too short to have a direction is swept as the line between its ends."""
    if move.is_helix:
        raise InputError("the analytic engine sweeps ZX/YZ arcs in their plane only (helical ones come as chords)",
                         move.source)
    zx = move.plane == ArcPlane.ZX
    si = 0 if zx else 1  # the machine axis along the arc's plane
    sc, zc = move.center[si], move.center[2]
    s0, z0 = move.start[si] - sc, move.start[2] - zc
    rho = math.hypot(s0, z0)
    a0 = math.atan2(z0, s0)
    # G18's in-plane angle runs from z towards x, the row's from s (= x) towards z: the opposite sense
    sw = -move.sweep if zx else move.sweep
    end = list(move.start)
    end[si], end[2] = sc + rho * math.cos(a0 + sw), zc + rho * math.sin(a0 + sw)
    x0, y0, x1, y1 = min(move.start[0], end[0]), min(move.start[1], end[1]), max(move.start[0], end[0]), \
        max(move.start[1], end[1])
    box = (x0 - R - 1e-9, y0 - R - 1e-9, x1 + R + 1e-9, y1 + R + 1e-9)
    z_low = min(move.start[2], end[2])
    if rho * abs(sw) <= 1e-12 or move.start[2] == end[2]:
        return line_row(move.start, tuple(end), tool_index), box, z_low
    return vertical_row(move.start, tuple(end), sc, zx, rho, a0, sw, tool_index), box, z_low


def sweep_row(move: Move, profile: LowerProfile, tool_index: int
              ) -> tuple[np.ndarray, tuple[float, float, float, float], float]:
    """(the sweep's row, its footprint box (x0, y0, x1, y1), its lowest tip height) for a CL segment
    (mm). An XY arc runs on its start's circle (spirals are cut into circular pieces before, see
    :meth:`fusioncut.model.moves.ArcMove.circular_pieces`), ending at the programmed end's angle."""
    R = profile.radius
    z_low = min(move.start[2], move.end[2])
    if isinstance(move, ArcMove) and move.plane != ArcPlane.XY:
        return _vertical_sweep_row(move, R, tool_index)
    if isinstance(move, ArcMove):
        cx, cy = move.center[0], move.center[1]
        rho = math.hypot(move.start[0] - cx, move.start[1] - cy)
        a0 = math.atan2(move.start[1] - cy, move.start[0] - cx)
        sw = move.sweep
        end = (cx + rho * math.cos(a0 + sw), cy + rho * math.sin(a0 + sw), move.end[2])
        row = arc_row(move.start, end, (cx, cy), rho, a0, sw, tool_index)
        lo, hi = move.bounds
        pad = R + abs(math.hypot(move.end[0] - cx, move.end[1] - cy) - rho) + 1e-9
        return row, (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad), z_low
    row = line_row(move.start, move.end, tool_index)
    (x0, y0, _), (x1, y1, _) = move.start, move.end
    return row, (min(x0, x1) - R, min(y0, y1) - R, max(x0, x1) + R, max(y0, y1) + R), z_low
