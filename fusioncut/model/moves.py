"""Tool motions in the machine frame (mm, mm/min), each remembering where it came from.

Arcs follow RS274/NGC: the plane is given by its in-plane axes ``(a, b)`` and normal ``n = a x b``
(XY: x, y, z; ZX: z, x, y; YZ: y, z, x). Counter-clockwise (G3) is a positive rotation about ``n``,
clockwise (G2) negative, seen from the positive side of ``n``. A move whose end differs from its
start along ``n`` is a helix. ``turns`` counts extra full revolutions (the G-code ``P`` word - 1).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import Enum

from fusioncut.errors import InputError, SourceLocation
from fusioncut.model.tools import MillingTool

Point = tuple[float, float, float]


class ArcPlane(str, Enum):
    XY = "XY"  # G17
    ZX = "ZX"  # G18
    YZ = "YZ"  # G19

    @property
    def axes(self) -> tuple[int, int, int]:
        """Indices (a, b, n) of the in-plane axes and the normal."""
        return {"XY": (0, 1, 2), "ZX": (2, 0, 1), "YZ": (1, 2, 0)}[self.value]


@dataclass(frozen=True)
class Move:
    """A motion from ``start`` to ``end`` (mm). ``feed`` in mm/min (``None`` for rapids),
    ``spindle_rpm`` the programmed speed, ``tool`` the tool number in effect."""

    start: Point
    end: Point
    feed: float | None = None
    spindle_rpm: float | None = None
    tool: int | None = None
    operation: str = ""
    source: SourceLocation = field(default_factory=SourceLocation)

    @property
    def is_rapid(self) -> bool:
        return False

    @property
    def kind(self) -> str:
        """What sort of motion this is: ``rapid``, ``linear``, ``arc`` or ``helix``."""
        raise NotImplementedError

    @property
    def bounds(self) -> tuple[Point, Point]:
        """Exact axis-aligned bounds (min corner, max corner) of the tool-tip path, mm."""
        lo = (min(self.start[0], self.end[0]), min(self.start[1], self.end[1]), min(self.start[2], self.end[2]))
        hi = (max(self.start[0], self.end[0]), max(self.start[1], self.end[1]), max(self.start[2], self.end[2]))
        return lo, hi

    @property
    def length(self) -> float:
        raise NotImplementedError

    def point_at(self, t: float) -> Point:
        """Point at parameter ``t`` in [0, 1] (proportional to arc length)."""
        raise NotImplementedError

    def tangent_at(self, t: float) -> Point:
        """Unit direction of motion at ``t``."""
        raise NotImplementedError

    def split(self, max_length: float | None) -> list[Move]:
        """Pieces no longer than ``max_length`` mm (the move itself when ``None`` or short enough)."""
        if max_length is None or self.length <= max_length:
            return [self]
        n = math.ceil(self.length / max_length - 1e-9)
        return [self.piece(k / n, (k + 1) / n) for k in range(n)]

    def piece(self, t0: float, t1: float) -> Move:
        raise NotImplementedError

    def translated(self, v: Point) -> Move:
        raise NotImplementedError


def _add(p: Point, v: Point) -> Point:
    return (p[0] + v[0], p[1] + v[1], p[2] + v[2])


@dataclass(frozen=True)
class LinearMove(Move):
    """Straight move: feed (G1) or rapid (G0) when ``rapid`` is set."""

    rapid: bool = False

    @property
    def is_rapid(self) -> bool:
        return self.rapid

    @property
    def kind(self) -> str:
        return "rapid" if self.rapid else "linear"

    @property
    def length(self) -> float:
        return math.dist(self.start, self.end)

    def point_at(self, t: float) -> Point:
        return tuple(s + t * (e - s) for s, e in zip(self.start, self.end))  # type: ignore[return-value]

    def tangent_at(self, t: float) -> Point:
        L = self.length
        if L == 0:
            return (0.0, 0.0, 0.0)
        return tuple((e - s) / L for s, e in zip(self.start, self.end))  # type: ignore[return-value]

    def piece(self, t0: float, t1: float) -> LinearMove:
        return replace(self, start=self.point_at(t0), end=self.end if t1 == 1 else self.point_at(t1))

    def translated(self, v: Point) -> LinearMove:
        return replace(self, start=_add(self.start, v), end=_add(self.end, v))


@dataclass(frozen=True)
class ArcMove(Move):
    """Circular or helical feed move (G2/G3) about ``center`` in ``plane``.

    ``center`` is given at the start's height along the plane normal. ``clockwise`` is G2.
    A start equal to the end (in the plane) is a full circle; ``turns`` adds whole revolutions.
    """

    center: Point = (0.0, 0.0, 0.0)
    plane: ArcPlane = ArcPlane.XY
    clockwise: bool = False
    turns: int = 0

    def _polar(self, p: Point) -> tuple[float, float]:
        a, b, _ = self.plane.axes
        da, db = p[a] - self.center[a], p[b] - self.center[b]
        return math.hypot(da, db), math.atan2(db, da)

    @property
    def radius(self) -> float:
        return self._polar(self.start)[0]

    @property
    def end_radius(self) -> float:
        return self._polar(self.end)[0]

    @property
    def sweep(self) -> float:
        """Signed swept angle in radians (> 0 counter-clockwise about the plane normal)."""
        _, a0 = self._polar(self.start)
        _, a1 = self._polar(self.end)
        d = a1 - a0
        if self.clockwise:
            d = -((-d) % (2 * math.pi))
            if abs(d) < 1e-12:
                d = -2 * math.pi
            return d - 2 * math.pi * self.turns
        d = d % (2 * math.pi)
        if abs(d) < 1e-12:
            d = 2 * math.pi
        return d + 2 * math.pi * self.turns

    @property
    def rise(self) -> float:
        """Travel along the plane normal (helix height), mm."""
        n = self.plane.axes[2]
        return self.end[n] - self.start[n]

    @property
    def is_helix(self) -> bool:
        return abs(self.rise) > 1e-9

    @property
    def kind(self) -> str:
        return "helix" if self.is_helix else "arc"

    @property
    def bounds(self) -> tuple[Point, Point]:
        """Exact axis-aligned bounds of the arc or helix, mm: its end points plus the points where it
        crosses a multiple of 90 degrees in its plane (the in-plane extremes)."""
        a, b, _ = self.plane.axes
        a0 = math.atan2(self.start[b] - self.center[b], self.start[a] - self.center[a])
        sweep = self.sweep
        pts = [self.start, self.end]
        lo_k = math.ceil(min(a0, a0 + sweep) / (math.pi / 2))
        hi_k = math.floor(max(a0, a0 + sweep) / (math.pi / 2))
        # extra turns revisit the same four directions: eight crossings cover every extreme
        for k in range(lo_k, min(hi_k, lo_k + 8) + 1):
            t = (k * math.pi / 2 - a0) / sweep
            if 0.0 <= t <= 1.0:
                pts.append(self.point_at(t))
        lo = (min(p[0] for p in pts), min(p[1] for p in pts), min(p[2] for p in pts))
        hi = (max(p[0] for p in pts), max(p[1] for p in pts), max(p[2] for p in pts))
        return lo, hi

    @property
    def length(self) -> float:
        return math.hypot(abs(self.sweep) * self.radius, self.rise)

    def point_at(self, t: float) -> Point:
        a, b, n = self.plane.axes
        r0, a0 = self._polar(self.start)
        r1, _ = self._polar(self.end)
        ang = a0 + t * self.sweep
        r = r0 + t * (r1 - r0)  # tolerates the small radius mismatch real programs have
        p = [0.0, 0.0, 0.0]
        p[a] = self.center[a] + r * math.cos(ang)
        p[b] = self.center[b] + r * math.sin(ang)
        p[n] = self.start[n] + t * self.rise
        return (p[0], p[1], p[2])

    def tangent_at(self, t: float) -> Point:
        a, b, n = self.plane.axes
        _, a0 = self._polar(self.start)
        ang = a0 + t * self.sweep
        s = self.sweep * self.radius
        v = [0.0, 0.0, 0.0]
        v[a] = -math.sin(ang) * s
        v[b] = math.cos(ang) * s
        v[n] = self.rise
        L = math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
        return (v[0] / L, v[1] / L, v[2] / L)

    def piece(self, t0: float, t1: float) -> ArcMove:
        start = self.start if t0 == 0 else self.point_at(t0)
        end = self.end if t1 == 1 else self.point_at(t1)
        n = self.plane.axes[2]
        c = list(self.center)
        c[n] = start[n]
        cw = self.clockwise
        # a piece never spans a full turn, so its sweep follows from the points alone unless it
        # ends where it started
        return replace(self, start=start, end=end, center=(c[0], c[1], c[2]), clockwise=cw, turns=0)

    def translated(self, v: Point) -> ArcMove:
        return replace(self, start=_add(self.start, v), end=_add(self.end, v), center=_add(self.center, v))

    @property
    def is_spiral(self) -> bool:
        """Whether the end lies off the start's circle by more than :data:`SPIRAL_EPS` (posts round
        I/J and end points, so real arcs are spirals by a few µm; R-format arcs by far less)."""
        return abs(self.end_radius - self.radius) > SPIRAL_EPS

    def circular_piece_count(self, tolerance: float) -> int:
        """How many pieces :meth:`circular_pieces` makes (1 for an arc that is no spiral), without
        making them."""
        if not self.is_spiral:
            return 1
        return max(math.ceil(abs(self.end_radius - self.radius) / tolerance - 1e-12),
                   math.ceil(abs(self.sweep) / math.pi - 1e-12), 1)

    def circular_pieces(self, tolerance: float) -> list[ArcMove]:
        """This arc as arcs of true circles about its programmed centre, for the engine to sweep.

        A spiral (end radius off the start's by more than :data:`SPIRAL_EPS`; posts round I/J and end
        points, so real arcs are spirals by a few µm) is cut into ``n`` pieces with
        ``|end radius - start radius| / n <= tolerance`` (mm), each at most half a turn. Piece ``k``
        starts on the spiral and runs on the circle of its start's radius to the angle (and height) of
        the spiral's next point, where it ends within ``tolerance`` of the programmed path; the next
        piece starts on the spiral again (a radial step of at most ``tolerance``). So every piece's
        sweep ends where the tool ends (the contact faces match the tool there), and each piece keeps
        the programmed centre: a move that joins the arc tangentially in the program still does (sweeps
        meeting at a few 1e-7 rad, as recentred circles gave, made the kernel's Booleans fail on a real
        contour). An arc that is no spiral is returned as it is.
        """
        if not self.is_spiral:
            return [self]
        a, b, _ = self.plane.axes
        n = self.circular_piece_count(tolerance)
        if n > _MAX_SPIRAL_PIECES:
            raise InputError(f"a spiral arc (radius {self.radius:.6g} -> {self.end_radius:.6g} mm) needs {n:,} "
                             f"circular pieces to stay within {tolerance:g} mm of its path", self.source)
        pieces = []
        for k in range(n):
            piece = self.piece(k / n, (k + 1) / n)
            rho, _ = piece._polar(piece.start)
            r1, _ = piece._polar(piece.end)
            end = list(piece.end)
            end[a] = self.center[a] + (end[a] - self.center[a]) * rho / r1
            end[b] = self.center[b] + (end[b] - self.center[b]) * rho / r1
            pieces.append(replace(piece, end=(end[0], end[1], end[2])))
        return pieces


# mm: an arc whose end radius differs from its start radius by more than this is a spiral and is swept
# as circular pieces (:meth:`ArcMove.circular_pieces`); below it the difference is under the kernel's
# tolerance and the arc is swept as it is
SPIRAL_EPS = 1e-9
_MAX_SPIRAL_PIECES = 1_000_000



@dataclass(frozen=True)
class Toolpath:
    """What a reader produced: moves in program order (machine frame, mm), the tools they use
    (keyed by tool number), and the reader's warnings (each naming ``file:line``).

    ``program_tools``: the tools the program describes itself (G-code tool comments) when the reader
    was given tools that replace them in ``tools``; ``None`` when ``tools`` are the program's own."""

    moves: tuple[Move, ...]
    tools: dict[int, MillingTool] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    source: str = "<memory>"
    program_tools: dict[int, MillingTool] | None = None

    def translated(self, v: Point) -> Toolpath:
        return replace(self, moves=tuple(m.translated(v) for m in self.moves))
