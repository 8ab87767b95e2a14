"""Sizing a job from its moves before anything is expanded, and refusing one over its budget.

:func:`size_job` counts what a run would make, in closed form per move, without building a single CL
segment: the CL segments exactly as :func:`fusioncut.engines.segments.cl_segments` cuts them (a line's
length over ``max_segment_length``, a ramp's steps of ``ramp_step``, a helix's steps and their
quarter turns, the chords of a ZX / YZ arc or a steep helix within ``chord_tolerance``, all turns
included), an upper bound of the slices evaluated (per CL ``ceil(flute_length / slice_height)`` of
the tool at that CL, as :func:`fusioncut.engines.brep.engine.slice_heights` cuts the flutes), the
workpiece snapshots, the checkpoints and the workpiece cells over a box or cylinder stock. Counting
stops as soon as a count passes its :class:`Budget`, so refusing a job costs at most a budget's worth of arithmetic, and a single move
that alone makes more pieces than the budget (a 90-byte ``G18 G2 ... P100000``: 15.7 million chords)
is refused in O(1).

Mechanism: most moves are one closed form. Where the pieces of a move differ from one another (the
chords of a ZX / YZ arc, each stepped by its own slope; the steps of a helix whose end radius differs
from its start radius) they are counted with numpy, :data:`_CHUNK` pieces at a time, so memory stays
bounded whatever the count (spiral arcs: see :func:`move_segments`). The count equals ``len(cl_segments(...))`` (tested on every real program
of the test data and on generated moves) up to float rounding where a piece's length lies within
1e-9 of a multiple of ``max_segment_length``.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from fusioncut.errors import JobTooLarge
from fusioncut.engines.segments import STAIRCASE_SLOPE, _oblique, quarter_crossings, quarter_pieces
from fusioncut.model.moves import ArcMove, ArcPlane, Move, Toolpath
from fusioncut.model.stock import BoxStock, CylinderStock, Stock
from fusioncut.model.tools import MillingTool

_CHUNK = 1 << 16  # pieces counted per numpy pass: 65,536 x a few float64 arrays, about 3 MB
_SPIRAL_PIECES = 1 << 12  # circular pieces of a spiral up to which they are made to be counted
_EPS = 1e-9  # as segments._EPS: shorter rises or horizontal travels are no ramp


@dataclass(frozen=True)
class Budget:
    """The most a run may make; :func:`size_job` refuses a job beyond any of these.

    ``max_cls``: CL segments. Each costs a sweep and Booleans (milliseconds to a second) and a row of
    results; 5,000,000 is a few days of computing and ~1 GB of segments held in memory by the run.
    ``max_slices``: slice evaluations, counted as ``ceil(flute_length / slice_height)`` for every CL;
    each is a section of the contact faces and a row of the slices table (100,000,000 rows is several
    GB of tables). ``max_snapshots``: entries of ``snapshot_cls``, each a STEP file of the whole
    workpiece. ``max_checkpoints``: checkpoints written in one run, each a copy of the whole engine
    state. ``max_cells``: workpiece cells (``cell_size`` squares over the stock's XY extent), each a
    solid the engine cuts out of the stock when it starts (a Boolean each) and keeps in memory;
    100,000 is a 6.3 m square stock in the default 20 mm cells. ``raise_hint``: how the user raises the limits where the budget is applied (the CLI's
    options, the service's settings), quoted in the refusal.
    """

    max_cls: int = 5_000_000
    max_slices: int = 100_000_000
    max_snapshots: int = 1_000
    max_checkpoints: int = 100_000
    max_cells: int = 100_000
    raise_hint: str = "raise the limit with fusioncut run --max-cls / --max-slices"


@dataclass(frozen=True)
class JobSize:
    """What a run would make: ``cls`` CL segments, at most ``slices`` slice evaluations (at most
    ``max_slices_per_cl`` for one CL), ``snapshots`` workpiece snapshots, ``checkpoints``
    checkpoints (the final one included) and ``cells`` workpiece cells (0: the stock's extent is not
    known before it is read, a STEP stock)."""

    cls: int
    slices: int
    max_slices_per_cl: int
    snapshots: int
    checkpoints: int
    cells: int = 0


def _splits(length: np.ndarray | float, msl: float | None) -> np.ndarray | int:
    """Pieces :meth:`Move.split` cuts a move of ``length`` mm into."""
    if msl is None:
        return np.ones_like(length, dtype=np.int64) if isinstance(length, np.ndarray) else 1
    if isinstance(length, np.ndarray):
        return np.where(length <= msl, 1, np.ceil(length / msl - 1e-9)).astype(np.int64)
    return 1 if length <= msl else math.ceil(length / msl - 1e-9)


def _line_steps(dh: np.ndarray, dz: np.ndarray, ramp_step: float, rapid: bool = False) -> np.ndarray:
    """Steps :func:`segments.staircase` cuts straight feed moves of horizontal travel ``dh`` and rise
    ``dz`` into (1 for those that are no ramp)."""
    adz = np.abs(dz)
    ramp = (adz >= _EPS) & (dh >= _EPS) & (adz <= STAIRCASE_SLOPE * dh)
    if rapid or not ramp.any():
        return np.ones_like(dh, dtype=np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        n = np.ceil(dh * adz / np.hypot(dh, dz) / ramp_step - 1e-12)
    return np.where(ramp, np.maximum(n, 1), 1).astype(np.int64)


def _line_count(m: Move, msl: float | None, ramp_step: float) -> int:
    oblique = _oblique(m)
    if oblique is None:
        return _splits(m.length, msl)
    dh, dz = oblique
    n = max(1, math.ceil(dh * abs(dz) / math.hypot(dh, dz) / ramp_step - 1e-12))
    return n * _splits(m.length / n, msl)


def _arc_points(arc: ArcMove, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(in-plane a, in-plane b, normal) coordinates of :meth:`ArcMove.point_at` at parameters ``t``."""
    a, b, n = arc.plane.axes
    r0 = arc.radius
    a0 = math.atan2(arc.start[b] - arc.center[b], arc.start[a] - arc.center[a])
    ang = a0 + t * arc.sweep
    r = r0 + t * (arc.end_radius - r0)
    return (arc.center[a] + r * np.cos(ang), arc.center[b] + r * np.sin(ang), arc.start[n] + t * arc.rise)


def chord_count(arc: ArcMove, chord_tolerance: float) -> int:
    """Chords :func:`segments.chords` cuts ``arc`` into, in O(1)."""
    rho = max(arc.radius, arc.end_radius)
    if chord_tolerance >= rho:
        return max(1, math.ceil(abs(arc.sweep) / math.pi))
    dmax = 2 * math.acos(1 - chord_tolerance / rho)
    return max(1, math.ceil(abs(arc.sweep) / dmax - 1e-12))


def _helix_steps(arc: ArcMove, ramp_step: float) -> int:
    dh, dz = _oblique(arc)  # type: ignore[misc]
    n = math.ceil(dh * abs(dz) / math.hypot(dh, dz) / ramp_step - 1e-12)
    return max(n, math.ceil(abs(arc.sweep) / (math.pi / 2) - 1e-12))


def _pieces_count(arc: ArcMove, n: int, msl: float | None, ramp_step: float, chords: bool,
                  room: int) -> int:
    """Segments of ``arc`` cut into ``n`` pieces (chords, each then stepped and split; or helix steps,
    each split), counted ``_CHUNK`` pieces at a time; stops once the count passes ``room``."""
    total = 0
    a_ax, b_ax, n_ax = arc.plane.axes
    for k0 in range(0, n, _CHUNK):
        k = np.arange(k0, min(n, k0 + _CHUNK), dtype=np.float64)
        if chords:
            pa, pb, pn = _arc_points(arc, np.append(k, k[-1] + 1) / n)
            if k0 + len(k) == n:  # the last chord ends exactly at the arc's end
                pa[-1], pb[-1], pn[-1] = arc.end[a_ax], arc.end[b_ax], arc.end[n_ax]
            xyz = {a_ax: pa, b_ax: pb, n_ax: pn}
            d = [np.diff(xyz[i]) for i in range(3)]
            dh, dz = np.hypot(d[0], d[1]), d[2]
            steps = _line_steps(dh, dz, ramp_step)
            length = np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
            counts = steps * _splits(length / steps, msl)
        else:  # a helix's steps: equal turns and rises, radius from the start's to the end's
            r = arc.radius + (k / n) * (arc.end_radius - arc.radius)
            counts = _splits(np.hypot(abs(arc.sweep) / n * r, arc.rise / n), msl)
        total += int(counts.sum())
        if total > room:
            return total
    return total


def move_segments(m: Move, max_segment_length: float | None, chord_tolerance: float, ramp_step: float,
                  room: int | None = None) -> int:
    """CL segments :func:`segments.cl_segments` makes of ``m``, counted without making them; once
    the count passes ``room`` (if given) a number above ``room`` is returned, not the exact count.

    A spiral arc (end radius off the start's) is first followed by circular pieces
    (:meth:`ArcMove.circular_pieces`): up to :data:`_SPIRAL_PIECES` of them they are made and each is
    counted; beyond, the count is a lower bound (the pieces, or the arc's own count without them,
    whichever is larger), which is what a refusal needs."""
    room = math.inf if room is None else room  # type: ignore[assignment]
    if not isinstance(m, ArcMove):
        return _line_count(m, max_segment_length, ramp_step)
    if m.is_spiral:
        n = m.circular_piece_count(chord_tolerance)
        if n > _SPIRAL_PIECES or n > room:
            return max(n, _arc_count(m, max_segment_length, chord_tolerance, ramp_step, room))
        total = 0
        for piece in m.circular_pieces(chord_tolerance):
            total += _arc_count(piece, max_segment_length, chord_tolerance, ramp_step, room - total)
            if total > room:
                break
        return total
    return _arc_count(m, max_segment_length, chord_tolerance, ramp_step, room)


def _arc_count(m: ArcMove, max_segment_length: float | None, chord_tolerance: float, ramp_step: float,
               room: float) -> int:
    if m.plane != ArcPlane.XY and not m.is_helix:  # cut at its in-plane extremes first
        nq = 1 + len(quarter_crossings(m)[2])  # segments.quarter_pieces' count
        if nq > 1:
            if nq > room or nq > _SPIRAL_PIECES:  # a lower bound, as for spirals
                return max(nq, chord_count(m, chord_tolerance))
            total = 0
            for piece in quarter_pieces(m):
                total += _chord_pieces_count(piece, max_segment_length, chord_tolerance, ramp_step, room - total)
                if total > room:
                    break
            return total
    return _chord_pieces_count(m, max_segment_length, chord_tolerance, ramp_step, room)


def _chord_pieces_count(m: ArcMove, max_segment_length: float | None, chord_tolerance: float, ramp_step: float,
                        room: float) -> int:
    helix_steps = m.plane == ArcPlane.XY and m.is_helix and _oblique(m) is not None
    if m.plane == ArcPlane.XY and not m.is_helix:
        return _splits(m.length, max_segment_length)
    n = _helix_steps(m, ramp_step) if helix_steps else chord_count(m, chord_tolerance)
    if n > room:  # every piece is at least one segment
        return n
    if helix_steps and abs(m.end_radius - m.radius) <= 1e-12:
        return n * _splits(math.hypot(abs(m.sweep) / n * m.radius, m.rise / n), max_segment_length)
    return _pieces_count(m, n, max_segment_length, ramp_step, not helix_steps, room)  # type: ignore[arg-type]


def size_job(moves: Sequence[Move], options, flute_length: Callable[[Move], float],
             checkpoint_every: int = 0, snapshot_cls: Iterable[int] = (), budget: Budget | None = None,
             xy_extent: tuple[float, float] | None = None) -> JobSize:
    """Size a run of ``moves`` with ``options`` (an :class:`~fusioncut.engines.base.EngineOptions`),
    ``flute_length(move)`` giving the flute length (mm) of the tool at each move, on a stock of
    ``xy_extent`` (mm, None: unknown); raises :class:`~fusioncut.errors.JobTooLarge` naming the
    limit, the count and the move where the count passed it, as soon as any count passes ``budget``
    (default :class:`Budget`)."""
    budget = budget or Budget()
    cells = 0
    if xy_extent is not None:
        size = options.cell_size
        cells = 1 if size is None else math.prod(max(1, math.ceil(e / size - 1e-9)) for e in xy_extent)
        if cells > budget.max_cells:
            raise JobTooLarge(f"options.cell_size: {size:g} mm cells over the stock's {xy_extent[0]:g} x "
                              f"{xy_extent[1]:g} mm are {cells:,} cells, more than the limit of "
                              f"{budget.max_cells:,} (each is a solid cut from the stock); use larger cells")
    snapshots = len(set(snapshot_cls))
    if snapshots > budget.max_snapshots:
        raise JobTooLarge(f"options.snapshot_cls: {snapshots:,} snapshots, more than the limit of "
                          f"{budget.max_snapshots:,} (each is a STEP file of the whole workpiece)")
    cls = slices = per_cl_max = 0
    msl, tol, ramp, dz = options.max_segment_length, options.chord_tolerance, options.ramp_step, options.slice_height
    per_tool: dict[float, int] = {}
    for m in moves:
        n = move_segments(m, msl, tol, ramp, budget.max_cls - cls)
        cls += n
        if cls > budget.max_cls:
            raise JobTooLarge(f"the job makes more than {budget.max_cls:,} CL segments (this move "
                              f"alone {n:,}{_why(m, msl, tol, ramp)}); {budget.raise_hint}, or use a longer "
                              "max_segment_length, chord_tolerance or ramp_step", m.source)
        flute = flute_length(m)
        per_cl = per_tool.get(flute)
        if per_cl is None:
            per_cl = per_tool[flute] = max(1, math.ceil(flute / dz - 1e-9))
        per_cl_max = max(per_cl_max, per_cl)
        slices += n * per_cl
        if slices > budget.max_slices:
            raise JobTooLarge(f"the job evaluates more than {budget.max_slices:,} slices (CL segments "
                              f"x flute length {flute:g} mm / slice_height {dz:g} mm = {per_cl:,} a CL); "
                              f"{budget.raise_hint}, or use a larger slice_height", m.source)
    checkpoints = 1 + ((cls - 1) // checkpoint_every if checkpoint_every and cls else 0)
    if checkpoints > budget.max_checkpoints:
        raise JobTooLarge(f"options.checkpoint_every: {checkpoint_every} makes {checkpoints:,} checkpoints of "
                          f"{cls:,} CLs, more than the limit of {budget.max_checkpoints:,} (each saves the whole "
                          "workpiece); checkpoint less often")
    return JobSize(cls, slices, per_cl_max, snapshots, checkpoints, cells)


def size_toolpath(toolpath: Toolpath, options, default_tool: MillingTool | None = None, checkpoint_every: int = 0,
                  snapshot_cls: Iterable[int] = (), budget: Budget | None = None, stock: Stock | None = None) -> JobSize:
    """:func:`size_job` for a toolpath: the tool at a move is its T number's, else ``default_tool``
    (moves without a T word), else the longest flutes of the toolpath's tools (an upper bound); the
    cells over a box or cylinder ``stock``."""
    flutes = {n: t.flute_length for n, t in toolpath.tools.items()}
    longest = max([*flutes.values(), *([default_tool.flute_length] if default_tool else [])], default=1.0)

    def flute_length(m: Move) -> float:
        if m.tool is None and default_tool is not None:
            return default_tool.flute_length
        return flutes.get(m.tool, longest)  # type: ignore[arg-type]

    extent = None
    if isinstance(stock, BoxStock):
        extent = (stock.maximum[0] - stock.minimum[0], stock.maximum[1] - stock.minimum[1])
    elif isinstance(stock, CylinderStock):
        extent = (2 * stock.radius, 2 * stock.radius)
    return size_job(toolpath.moves, options, flute_length, checkpoint_every, snapshot_cls, budget, extent)


def _why(m: Move, msl: float | None, tol: float, ramp: float) -> str:
    if isinstance(m, ArcMove):
        turns = abs(m.sweep) / (2 * math.pi)
        return f": an arc of {turns:,.4g} turns on radius {max(m.radius, m.end_radius):g} mm"
    return f": {m.length:g} mm long" + (f" over max_segment_length {msl:g} mm" if msl else "")


__all__ = ["Budget", "JobSize", "chord_count", "move_segments", "size_job", "size_toolpath"]
