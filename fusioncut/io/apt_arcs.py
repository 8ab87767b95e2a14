"""Arcs in APT CL data: how a centre/axis arc record becomes an :class:`ArcMove`.

Two conventions for the axis meet in APT files, one per record:

* ISO 4343 ``MOVARC/cx, cy, cz, i, j, k, r, ANGLE, a`` (Autodesk Fusion's APT post): the tool turns
  counter-clockwise about (i, j, k) (right-hand rule) by ``a`` degrees.
* Siemens NX CLSF ``CIRCLE/x, y, z, i, j, k, r, t, f, d, e[, TIMES, n]``: NX's CLSF documentation
  (CLSF Manager, CIRCLE) gives (i, j, k) as the circle or helix axis "assuming a clockwise
  direction": the tool turns clockwise about (i, j, k), i.e. counter-clockwise about -(i, j, k)
  (:func:`nx_circle_axis`). ``t`` is the tolerance, ``f`` the in-tolerance ratio, ``d`` and ``e`` the
  tool's diameter and corner radius; none of them changes the path. ``TIMES, n`` is read as n full
  revolutions added to the arc from the start to the ``GOTO`` that follows.

:func:`solve_arc` turns either into the RS274-style description of :class:`ArcMove` (plane, sense,
extra turns), checking the points against the circle.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

from fusioncut.errors import InputError, SourceLocation
from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Move, Point

__all__ = ["ArcSolution", "TangentCheck", "nx_circle_axis", "nx_marker_line", "solve_arc", "MAX_EXTRA_TURNS"]

_AXIS_TOL = 1e-6  # tolerance on unit arc-axis components
# More revolutions than this in one arc record is a broken file, not a helix; refusing it keeps the
# moves the engines make from one record bounded.
MAX_EXTRA_TURNS = 10_000

# Records that Siemens NX writes into a CLSF and Autodesk's ISO 4343 APT post never does, at the start
# of a line (a ``$$`` comment line starts with ``$``, so commented text never matches).
_NX_MARKERS = re.compile(r"^[ \t]*(TOOL[ \t]+PATH|TLDATA|MSYS|END-OF-PATH|PAINT)[ \t]*(/|$)", re.IGNORECASE | re.MULTILINE)


def nx_marker_line(text: str) -> int | None:
    """The 1-based line of the first record that marks ``text`` as a Siemens NX CLSF (``TOOL PATH``,
    ``TLDATA``, ``MSYS``, ``END-OF-PATH`` or ``PAINT``), or ``None`` when it has none."""
    m = _NX_MARKERS.search(text)
    return None if m is None else text.count("\n", 0, m.start()) + 1


def nx_circle_axis(axis: tuple[float, float, float]) -> tuple[float, float, float]:
    """The right-hand rotation axis of an NX ``CIRCLE`` whose stated axis assumes clockwise motion."""
    return (-axis[0], -axis[1], -axis[2])


# A feed line and an arc meet tangentially when their directions at the joint differ by less than this.
_TANGENT_COS = math.cos(math.radians(1.0))


@dataclass
class TangentCheck:
    """Counts the ``CIRCLE`` arcs that start in, or exactly against, the direction of the feed line
    before them. CAM systems join arcs to lines tangentially; an arc that starts straight back along
    the line reverses the tool on the spot, which real toolpaths do not do. When most tangent joints
    reverse, the file states its arc axes the other way round from the convention applied."""

    along: int = 0
    against: int = 0
    first_against: SourceLocation | None = None

    def add(self, before: Move | None, arc: ArcMove) -> None:
        if not isinstance(before, LinearMove) or before.is_rapid or before.end != arc.start:
            return
        t0, t1 = before.tangent_at(1.0), arc.tangent_at(0.0)
        dot = t0[0] * t1[0] + t0[1] * t1[1] + t0[2] * t1[2]
        if dot >= _TANGENT_COS:
            self.along += 1
        elif dot <= -_TANGENT_COS:
            self.against += 1
            if self.first_against is None:
                self.first_against = arc.source

    def warning(self) -> str | None:
        """A warning when the reversed joints are the majority, else ``None``."""
        if self.against <= self.along:
            return None
        return (
            f"{self.first_against}: {self.against} of {self.along + self.against} CIRCLE arcs that join a feed "
            "line tangentially start back against it: the file seems to state its arc axes the other way "
            "round from NX's convention (clockwise about the axis); check the program's arcs"
        )


@dataclass(frozen=True)
class ArcSolution:
    """How a centre/axis arc maps onto :class:`ArcMove` (centre already at the start's height)."""

    center: Point
    plane: ArcPlane
    clockwise: bool
    turns: int
    sense_from_end_point: bool  # True when the stated axis sense contradicted the end point


def solve_arc(
    start: Point,
    end: Point,
    center: Point,
    axis: tuple[float, float, float],
    where: SourceLocation,
    *,
    radius: float | None = None,
    sweep_deg: float | None = None,
) -> ArcSolution:
    """Turn an arc given by centre, rotation axis (counter-clockwise about it), optional radius and
    optional swept angle (degrees, > 0) into the RS274-style description of :class:`ArcMove`.

    Checks that the axis is a coordinate axis, that start and end lie on one circle about the centre
    (within max(0.01 mm, 0.2 % of r), which absorbs the rounding of 4-decimal posts) and that the
    stated angle fits the points. Raises :class:`InputError` at ``where`` otherwise.
    """
    n_len = math.sqrt(sum(c * c for c in axis))
    if n_len < 1e-9:
        raise InputError(f"arc axis {axis} has zero length", where)
    u = [c / n_len for c in axis]
    k = max(range(3), key=lambda i: abs(u[i]))
    if any(abs(u[i]) > _AXIS_TOL for i in range(3) if i != k):
        raise InputError(
            f"arc about axis ({u[0]:.6g}, {u[1]:.6g}, {u[2]:.6g}) is not in the XY, ZX or YZ plane; "
            "not supported",
            where,
        )
    plane = {2: ArcPlane.XY, 1: ArcPlane.ZX, 0: ArcPlane.YZ}[k]
    clockwise = u[k] < 0
    a, b, n = plane.axes
    c = list(center)
    c[n] = start[n]
    centre: Point = (c[0], c[1], c[2])
    r0 = math.hypot(start[a] - c[a], start[b] - c[b])
    r1 = math.hypot(end[a] - c[a], end[b] - c[b])
    if r0 < 1e-6:
        raise InputError("arc start lies on the arc centre (zero radius)", where)
    tol_r = max(0.01, 0.002 * max(r0, r1))
    if abs(r1 - r0) > tol_r:
        raise InputError(
            f"arc end point is not on the circle: start radius {r0:.6g} mm, end radius {r1:.6g} mm", where
        )
    if radius is not None and abs(radius - r0) > tol_r:
        raise InputError(f"stated arc radius {radius:.6g} mm disagrees with the start point ({r0:.6g} mm)", where)

    def base_sweep(cw: bool) -> float:
        arc = ArcMove(start=start, end=end, center=centre, plane=plane, clockwise=cw)
        return abs(math.degrees(arc.sweep))

    if sweep_deg is None:
        return ArcSolution(centre, plane, clockwise, 0, False)
    if not (sweep_deg > 0):
        raise InputError(f"arc sweep must be > 0 degrees, got {sweep_deg:.6g}", where)
    tol_a = max(0.1, math.degrees(tol_r / r0))
    for cw, flipped in ((clockwise, False), (not clockwise, True)):
        base = base_sweep(cw)
        turns = round((sweep_deg - base) / 360.0)
        if turns >= 0 and abs(base + 360.0 * turns - sweep_deg) <= tol_a:
            return ArcSolution(centre, plane, cw, turns, flipped)
    raise InputError(
        f"arc end point does not lie {sweep_deg:.6g} degrees round from the start "
        f"(the points give {base_sweep(clockwise):.6g} degrees about the stated axis)",
        where,
    )
