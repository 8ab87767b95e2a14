"""Cutting a toolpath into CL segments (pure geometry, no kernel).

A CL segment is one motion the engine evaluates; the engagement is reported with the tool at its end,
which lies on the programmed path (on a chord, within ``chord_tolerance``, for the arcs below).

* Horizontal lines, XY arcs and vertical plunges are swept exactly.
* Arcs in the ZX / YZ planes, and helices steeper than ``STAIRCASE_SLOPE``, become chords whose
  sagitta ``rho * (1 - cos(dtheta / 2))`` is at most ``chord_tolerance`` mm; a ZX / YZ arc is first
  cut at its in-plane extremes (:func:`quarter_pieces`). For an engine that sweeps such arcs
  exactly (the analytic one) they become the same CL segments on the arc itself
  (:func:`helix_pieces`, :func:`vertical_pieces`), so that both engines' CLs are the same ones.
* Feed moves that go down or up while moving sideways at a slope up to ``STAIRCASE_SLOPE`` (ramps,
  helices, those chords) are cut into pieces on the path that the engine sweeps as a **staircase**:
  each piece as the horizontal move (a line, or an XY arc for a helix) at the height of its end
  (:func:`step_motion`). The step's sweep contains the short vertical move at its start, and every
  swept tool position lies within ``ramp_step`` mm of the programmed path (the corner of a step is
  ``dh * dz / L`` from the oblique line it replaces).

Why not the exact oblique sweep: the convex hull of a flat end mill moved obliquely has a ruled
bottom face (its circle extruded along the move), which is not one of OCCT's analytic surfaces. Left
in the workpiece, such faces meet the next tool cylinders nearly tangentially and OCCT's Booleans
then go silently wrong (a chord removing nothing, a later one "removing" its whole sweep) with no
error from the kernel at any fuzzy value. Steps leave only planes and cylinders, on which the
Booleans are as robust as on lines.

Why steps of 0.05 mm, not finer: the wall between two steps is the tool's cylinder at each step's end,
so neighbouring walls are equal cylinders ``d = ramp_step * L / |dz|`` apart, meeting at about
``d / R`` rad. The smaller that angle, the closer the Booleans come to tangent cylinders, where they
go wrong; finer steps also multiply the faces a helical entry leaves. The evidence for 0.05 mm, and
why 0.01 mm is not known to be unsound today: ``docs/decisions/engine-measurements.md``.

Rapids and steeper moves keep the exact oblique sweep (a staircase of a long diagonal rapid would be
thousands of steps through air).
"""
from __future__ import annotations

import math
from dataclasses import replace

from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Move


def _chord_count(arc: ArcMove, chord_tolerance: float) -> int:
    """How many chords of ``arc`` keep the sagitta within ``chord_tolerance`` mm."""
    rho = max(arc.radius, arc.end_radius)
    if chord_tolerance >= rho:
        return max(1, math.ceil(abs(arc.sweep) / math.pi))
    dmax = 2 * math.acos(1 - chord_tolerance / rho)
    return max(1, math.ceil(abs(arc.sweep) / dmax - 1e-12))


def chords(arc: ArcMove, chord_tolerance: float) -> list[LinearMove]:
    """Chords of a helix or ZX/YZ arc with sagitta <= ``chord_tolerance`` (mm)."""
    n = _chord_count(arc, chord_tolerance)
    pts = [arc.point_at(k / n) for k in range(n + 1)]
    pts[-1] = arc.end
    return [chord(arc, pts[k], pts[k + 1]) for k in range(n)]


def chord(move: Move, start, end) -> LinearMove:
    """The line from ``start`` to ``end`` with ``move``'s feed, tool, operation and source."""
    return LinearMove(start, end, feed=move.feed, spindle_rpm=move.spindle_rpm, tool=move.tool,
                      operation=move.operation, source=move.source)


def helix_pieces(arc: ArcMove, chord_tolerance: float, max_segment_length: float | None) -> list[ArcMove]:
    """The pieces of a steep XY helix that :func:`chords` would make, then :meth:`~Move.split` each of
    those chords, each piece on the helix itself: the same CL segments, ending at the same points of
    the helix where a chord's end lies on it, for an engine that sweeps helices exactly."""
    n = _chord_count(arc, chord_tolerance)
    out: list[ArcMove] = []
    for k in range(n):
        piece = arc.piece(k / n, (k + 1) / n)
        m = len(chord(piece, piece.start, piece.end).split(max_segment_length))  # as its chord is split
        out += [piece.piece(j / m, (j + 1) / m) for j in range(m)] if m > 1 else [piece]
    return out


def quarter_crossings(arc: ArcMove) -> tuple[float, float, range]:
    """(the start's in-plane angle, the sweep, the multiples k of pi/2 that the in-plane angle passes more
    than 1e-9 rad inside the arc): its in-plane extremes, in O(1) however many turns it makes."""
    a, b, _ = arc.plane.axes
    a0 = math.atan2(arc.start[b] - arc.center[b], arc.start[a] - arc.center[a])
    sw = arc.sweep
    lo, hi, q = min(a0, a0 + sw), max(a0, a0 + sw), math.pi / 2
    return a0, sw, range(math.ceil((lo + 1e-9) / q), math.floor((hi - 1e-9) / q) + 1)


def quarter_pieces(arc: ArcMove) -> list[ArcMove]:
    """``arc`` cut at its in-plane extremes (:func:`quarter_crossings`), so that both its in-plane
    coordinates are monotone along each piece."""
    a0, sw, ks = quarter_crossings(arc)
    ts = [0.0, *sorted((k * math.pi / 2 - a0) / sw for k in ks), 1.0]
    return [arc] if len(ts) == 2 else [arc.piece(ts[i], ts[i + 1]) for i in range(len(ts) - 1)]


def vertical_pieces(arc: ArcMove, chord_tolerance: float, ramp_step: float,
                    max_segment_length: float | None) -> list[ArcMove]:
    """The pieces of a ZX / YZ arc within one quarter (:func:`quarter_pieces`) that its :func:`chords`
    would make, each then cut as :func:`staircase` and :meth:`~Move.split` cut that chord, each piece on
    the arc itself: the same CL segments as the chords', for an engine that sweeps such arcs exactly."""
    n = _chord_count(arc, chord_tolerance)
    out: list[ArcMove] = []
    for k in range(n):
        piece = arc.piece(k / n, (k + 1) / n)
        m = sum(len(step.split(max_segment_length)) for step in staircase(chord(piece, piece.start, piece.end),
                                                                          ramp_step))
        out += [piece.piece(j / m, (j + 1) / m) for j in range(m)] if m > 1 else [piece]
    return out


def as_chord(move: Move) -> Move:
    """A piece of :func:`helix_pieces` or :func:`vertical_pieces` as the chord an engine that cannot
    sweep it takes (within ``chord_tolerance`` of it); any other move itself."""
    if isinstance(move, ArcMove) and (move.plane != ArcPlane.XY or (move.is_helix and _oblique(move) is None)):
        return chord(move, move.start, move.end)
    return move


_EPS = 1e-9
# Steeper moves keep the oblique sweep: their steps would be a few µm long, and the µm slivers such
# steps leave between tool cylinders broke later Booleans (1055_utab: 41 of 174 CLs failed when its
# 45-80° entry ramps were stepped, none with the oblique sweep). Helical and linear entries, which
# CAM systems post at 1-5°, are stepped.
STAIRCASE_SLOPE = 0.2  # dz / dh


def _oblique(move: Move) -> tuple[float, float] | None:
    """(horizontal length, rise) of a feed move to be stepped, or None (lines, plunges, rapids, steep)."""
    if move.is_rapid:
        return None
    dz = move.end[2] - move.start[2]
    if isinstance(move, ArcMove):
        if move.plane != ArcPlane.XY or not move.is_helix:
            return None
        dh = abs(move.sweep) * max(move.radius, move.end_radius)
    else:
        dh = math.hypot(move.end[0] - move.start[0], move.end[1] - move.start[1])
    if abs(dz) < _EPS or dh < _EPS or abs(dz) > STAIRCASE_SLOPE * dh:
        return None
    return dh, dz


def staircase(move: Move, ramp_step: float) -> list[Move]:
    """Pieces of an oblique feed move (a line or an XY helix) short enough to be swept as steps.

    The pieces lie on the path; :func:`step_motion` gives the horizontal motion the engine sweeps
    for each, which stays within ``ramp_step`` mm of the path. Other moves are returned as they are.
    """
    oblique = _oblique(move)
    if oblique is None:
        return [move]
    dh, dz = oblique
    n = math.ceil(dh * abs(dz) / math.hypot(dh, dz) / ramp_step - 1e-12)
    if isinstance(move, ArcMove):
        # a quarter turn at most per step keeps every XY arc sweep a simple one
        n = max(n, math.ceil(abs(move.sweep) / (math.pi / 2) - 1e-12))
        return [move.piece(k / n, (k + 1) / n) for k in range(n)]
    return [replace(move, start=move.point_at(k / n), end=move.end if k + 1 == n else move.point_at((k + 1) / n))
            for k in range(max(1, n))]


def step_motion(move: Move) -> Move:
    """The motion swept for a CL segment: for a piece of a ramp or helix, the horizontal move at its
    end's height (the vertical move at its start lies inside that sweep); any other move itself."""
    if _oblique(move) is None:
        return move
    z = move.end[2]
    start = (move.start[0], move.start[1], z)
    if isinstance(move, ArcMove):
        c = move.center
        return replace(move, start=start, center=(c[0], c[1], z))
    return replace(move, start=start)


def cl_segments(moves: list[Move] | tuple[Move, ...], max_segment_length: float | None = None,
                chord_tolerance: float = 1e-3, ramp_step: float = 5e-2, exact_arcs: bool = False) -> list[Move]:
    """The CL segments of ``moves``, in order; no move is dropped (a zero-length one stays a segment).
    ``exact_arcs``: a helix too steep to be stepped is cut into :func:`helix_pieces`, a ZX / YZ arc
    (not a helix about its plane's normal) into :func:`vertical_pieces`, not chords (the same CL
    segments, swept on the arc)."""
    out: list[Move] = []
    for move in moves:
        # a spiral (an arc whose end radius is off its start's: posts round I/J and end points) is
        # followed by as few true circular arcs as the tolerance allows, before it is cut into CL
        # segments, so that the segments of one arc share one circle as they do on exact arcs
        for m in move.circular_pieces(chord_tolerance) if isinstance(move, ArcMove) else [move]:
            # ZX / YZ arcs, and helices too steep to be stepped, become chords first
            steep = isinstance(m, ArcMove) and m.plane == ArcPlane.XY and m.is_helix and _oblique(m) is None
            if steep and exact_arcs:
                out += helix_pieces(m, chord_tolerance, max_segment_length)
                continue
            vertical = isinstance(m, ArcMove) and m.plane != ArcPlane.XY
            if vertical and not m.is_helix:
                quarters = quarter_pieces(m)
                if exact_arcs:
                    out += [p for q in quarters for p in vertical_pieces(q, chord_tolerance, ramp_step,
                                                                        max_segment_length)]
                    continue
                pieces = [c for q in quarters for c in chords(q, chord_tolerance)]
            else:
                pieces = chords(m, chord_tolerance) if steep or vertical else [m]
            for piece in pieces:
                for step in staircase(piece, ramp_step):
                    out += step.split(max_segment_length)
    return out


def segments_for(moves: list[Move] | tuple[Move, ...], options, exact_arcs: bool = False) -> list[Move]:
    """:func:`cl_segments` with the lengths of an :class:`~fusioncut.engines.base.EngineOptions`."""
    return cl_segments(moves, options.max_segment_length, options.chord_tolerance, options.ramp_step, exact_arcs)


def horizontal_direction(move: Move) -> tuple[float, float] | None:
    """Unit horizontal direction of motion at the end of ``move``; ``None`` for vertical moves."""
    t = move.tangent_at(1.0)
    h = math.hypot(t[0], t[1])
    if h < 1e-9:
        return None
    return (t[0] / h, t[1] / h)


__all__ = ["as_chord", "chord", "chords", "cl_segments", "helix_pieces", "horizontal_direction", "quarter_crossings",
           "quarter_pieces", "segments_for", "staircase", "step_motion", "vertical_pieces"]
