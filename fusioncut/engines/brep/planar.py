"""Closed-form Booleans of planar regions bounded by line segments and circular arcs.

The layered cells (:mod:`fusioncut.engines.brep.layers`) take a tool's planar region from each
layer's region at every CL. OCCT's General Fuse does that for any curves, and pays for it: its
edge-edge intersection is numeric, and the nearer two arcs of the tool's radius a CL apart come to
coinciding (the front arcs of consecutive CLs), the more it costs. Our regions only ever hold lines
and arcs, whose intersections have closed forms, so the difference is computed here in closed form
(``docs/decisions/engine-measurements.md`` has the costs); no library we can use does
exact line/arc polygon Booleans (shapely and Clipper take polylines).

Conventions: points in mm in the plane (x, y); angles in rad, counter-clockwise from +X. A region
is a tuple of closed loops; a loop is a tuple of edges, each ending where the next starts; the
region lies on the left of its edges (outer loops counter-clockwise, holes clockwise). An edge is
``Line(x0, y0, x1, y1)`` or ``Arc(x0, y0, x1, y1, cx, cy, r, a0, a1)``: the arc runs from angle
``a0`` to ``a1`` about (cx, cy) (counter-clockwise when ``a1 > a0``), its end points stored as well
so that loops close exactly.

:func:`difference` raises :class:`Degenerate` where it cannot decide a piece's side within
``SNAP`` (a near-tangency the exact arithmetic here does not settle); the caller then uses the
kernel's General Fuse.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from fusioncut.errors import Degenerate

SNAP = 1e-7  # mm: points closer than this are one vertex; pieces shorter than this are dropped
EPS = 1e-9  # mm: curves closer than this coincide (tangent, or overlapping)
TWO_PI = 2.0 * math.pi


class Line(NamedTuple):
    x0: float
    y0: float
    x1: float
    y1: float


class Arc(NamedTuple):
    x0: float
    y0: float
    x1: float
    y1: float
    cx: float
    cy: float
    r: float
    a0: float
    a1: float


Edge = Line | Arc
Region = tuple[tuple[Edge, ...], ...]


def arc(cx: float, cy: float, r: float, a0: float, a1: float) -> Arc:
    """The arc about (cx, cy) from angle ``a0`` to ``a1`` (rad), its end points computed (a whole
    turn ends exactly where it starts)."""
    x0, y0 = cx + r * math.cos(a0), cy + r * math.sin(a0)
    if abs(abs(a1 - a0) - TWO_PI) < 1e-15:
        return Arc(x0, y0, x0, y0, cx, cy, r, a0, a1)
    return Arc(x0, y0, cx + r * math.cos(a1), cy + r * math.sin(a1), cx, cy, r, a0, a1)


def from_pieces(pieces) -> Region:
    """One loop from ``("line", (p0, p1))`` and ``("arc", (p0, through, p1))`` pieces in order
    (points (x, y, ...) in mm; an arc is the circle through its three points), counter-clockwise."""
    loop = []
    for kind, pts in pieces:
        (x0, y0), (x1, y1) = pts[0][:2], pts[-1][:2]
        if kind == "line":
            loop.append(Line(x0, y0, x1, y1))
            continue
        xm, ym = pts[1][:2]
        # the circumcentre, from the perpendicular bisectors
        bx, by, cx_, cy_ = xm - x0, ym - y0, x1 - x0, y1 - y0
        den = 2.0 * (bx * cy_ - by * cx_)
        ux = (cy_ * (bx * bx + by * by) - by * (cx_ * cx_ + cy_ * cy_)) / den
        uy = (bx * (cx_ * cx_ + cy_ * cy_) - cx_ * (bx * bx + by * by)) / den
        cx, cy = x0 + ux, y0 + uy
        a0 = math.atan2(y0 - cy, x0 - cx)
        turn = (math.atan2(y1 - cy, x1 - cx) - a0) % TWO_PI
        a1 = a0 + turn if den > 0 else a0 - (TWO_PI - turn)  # den > 0: the three points turn left
        loop.append(Arc(x0, y0, x1, y1, cx, cy, math.hypot(ux, uy), a0, a1))
    return (tuple(loop),) if region_area((loop,)) >= 0 else (reversed_loop(loop),)


def _angles(e: Arc) -> tuple[float, float]:
    """The arc's angle range (rad) in increasing order, whichever way it runs."""
    return (e.a0, e.a1) if e.a1 >= e.a0 else (e.a1, e.a0)


def reversed_loop(loop) -> tuple[Edge, ...]:
    """The loop run the other way."""
    return tuple(reversed_edge(e) for e in reversed(loop))


def edge_area(e: Edge) -> float:
    """Half of ∮ x dy − y dx along ``e`` (mm²): a closed loop's edges sum to its signed area. An
    arc's is taken from its stored end points (cx Δy − cy Δx + r² Δa), so that a loop's sum does not
    depend on where the origin is even for an arc whose ends were snapped (by up to ``SNAP``) to a
    neighbour's: its error stays that gap times the arc's size, not times the distance to the origin."""
    if type(e) is Line:
        return 0.5 * (e.x0 * e.y1 - e.x1 * e.y0)
    return 0.5 * (e.cx * (e.y1 - e.y0) - e.cy * (e.x1 - e.x0) + e.r * e.r * (e.a1 - e.a0))


def region_area(region: Region) -> float:
    """The region's area (mm²)."""
    return sum(edge_area(e) for loop in region for e in loop)


_boxes: dict[Edge, tuple[float, float, float, float]] = {}


def edge_box(e: Edge) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) of the edge, exact (an arc's extreme points where it passes them).
    Remembered: a region's edges are mostly those of the region it was cut from."""
    box = _boxes.get(e)
    if box is None:
        if len(_boxes) > 200_000:
            _boxes.clear()
        box = _boxes[e] = _edge_box(e)
    return box


def _edge_box(e: Edge) -> tuple[float, float, float, float]:
    xs, ys = [e.x0, e.x1], [e.y0, e.y1]
    if type(e) is Arc:
        lo, hi = _angles(e)
        k = math.ceil(lo / (0.5 * math.pi))
        while k * 0.5 * math.pi <= hi:
            q = k % 4
            xs.append(e.cx + (e.r, 0.0, -e.r, 0.0)[q])
            ys.append(e.cy + (0.0, e.r, 0.0, -e.r)[q])
            k += 1
    return min(xs), min(ys), max(xs), max(ys)


def region_box(region: Region) -> tuple[float, float, float, float]:
    return _union_box([edge_box(e) for loop in region for e in loop])


def _overlap(a, b, gap: float) -> bool:
    return a[0] <= b[2] + gap and b[0] <= a[2] + gap and a[1] <= b[3] + gap and b[1] <= a[3] + gap


# -- parameters: a line's t in [0, 1], an arc's angle between a0 and a1 ------------------------

def _point(e: Edge, t: float) -> tuple[float, float]:
    if type(e) is Line:
        return e.x0 + t * (e.x1 - e.x0), e.y0 + t * (e.y1 - e.y0)
    return e.cx + e.r * math.cos(t), e.cy + e.r * math.sin(t)


def _span(e: Edge) -> tuple[float, float]:
    return (0.0, 1.0) if type(e) is Line else (e.a0, e.a1)


def _length_per_param(e: Edge) -> float:
    return math.hypot(e.x1 - e.x0, e.y1 - e.y0) if type(e) is Line else e.r


def _arc_param(e: Arc, angle: float, slack: float) -> float | None:
    """The parameter of ``e`` at polar ``angle`` (any turn), or None when the arc does not reach it
    (``slack``: rad past its ends still taken)."""
    lo, hi = _angles(e)
    t = lo + (angle - lo) % TWO_PI
    if t > hi + slack:
        if t - TWO_PI >= lo - slack:
            t -= TWO_PI
        else:
            return None
    return t


def _line_param(e: Line, x: float, y: float) -> float:
    dx, dy = e.x1 - e.x0, e.y1 - e.y0
    return ((x - e.x0) * dx + (y - e.y0) * dy) / (dx * dx + dy * dy)


def _params_at(e: Edge, x: float, y: float) -> float | None:
    """The parameter of the point (x, y) of ``e``'s curve, if it lies within the edge (± SNAP)."""
    if type(e) is Line:
        t = _line_param(e, x, y)
        slack = SNAP / max(_length_per_param(e), 1e-300)
        return min(1.0, max(0.0, t)) if -slack <= t <= 1.0 + slack else None
    t = _arc_param(e, math.atan2(y - e.cy, x - e.cx), SNAP / e.r)
    if t is None:
        return None
    lo, hi = _angles(e)
    return min(hi, max(lo, t))


# -- intersections -----------------------------------------------------------------------------

def _crossings(a: Edge, b: Edge) -> tuple[list[tuple[float, float]], tuple | None]:
    """Points where the curves of ``a`` and ``b`` meet within both edges, and, when the two lie on
    one curve, the parameter interval of ``a`` they share (with b's direction: +1 same, -1 opposite)."""
    if type(a) is Line and type(b) is Line:
        return _line_line(a, b)
    if type(a) is Line:
        return _line_circle(a, b), None
    if type(b) is Line:
        return _line_circle(b, a), None
    return _circle_circle(a, b)


def _line_line(a: Line, b: Line):
    dax, day = a.x1 - a.x0, a.y1 - a.y0
    dbx, dby = b.x1 - b.x0, b.y1 - b.y0
    la, lb = math.hypot(dax, day), math.hypot(dbx, dby)
    cross = dax * dby - day * dbx
    # distances of b's ends from a's line, and a's ends from b's
    db0 = (dax * (b.y0 - a.y0) - day * (b.x0 - a.x0)) / la
    db1 = (dax * (b.y1 - a.y0) - day * (b.x1 - a.x0)) / la
    if abs(db0) < EPS and abs(db1) < EPS:
        t0, t1 = _line_param(a, b.x0, b.y0), _line_param(a, b.x1, b.y1)
        lo, hi = max(0.0, min(t0, t1)), min(1.0, max(t0, t1))
        if (hi - lo) * la > SNAP:
            return [], (lo, hi, 1 if dax * dbx + day * dby > 0 else -1)
        pts = [p for p in ((b.x0, b.y0), (b.x1, b.y1), (a.x0, a.y0), (a.x1, a.y1))
               if _params_at(a, *p) is not None and _params_at(b, *p) is not None]
        return pts, None
    if abs(cross) < 1e-300:
        return [], None
    s = ((b.x0 - a.x0) * dby - (b.y0 - a.y0) * dbx) / cross
    u = ((b.x0 - a.x0) * day - (b.y0 - a.y0) * dax) / cross
    if -SNAP / la <= s <= 1 + SNAP / la and -SNAP / lb <= u <= 1 + SNAP / lb:
        return [(a.x0 + s * dax, a.y0 + s * day)], None
    return [], None


def _line_circle(a: Line, c: Arc) -> list[tuple[float, float]]:
    dx, dy = a.x1 - a.x0, a.y1 - a.y0
    length = math.hypot(dx, dy)
    ux, uy = dx / length, dy / length
    # foot of the perpendicular from the centre, and the centre's distance from the line
    s = (c.cx - a.x0) * ux + (c.cy - a.y0) * uy
    fx, fy = a.x0 + s * ux, a.y0 + s * uy
    d = math.hypot(c.cx - fx, c.cy - fy)
    gap = d - c.r
    if gap > EPS:
        return []
    if gap >= -EPS:
        cands = [(fx, fy)]
    else:
        h = math.sqrt(c.r * c.r - d * d)
        cands = [(fx - h * ux, fy - h * uy), (fx + h * ux, fy + h * uy)]
    return [p for p in cands if _params_at(a, *p) is not None and _params_at(c, *p) is not None]


def _circle_circle(a: Arc, b: Arc):
    dx, dy = b.cx - a.cx, b.cy - a.cy
    d = math.hypot(dx, dy)
    if d <= EPS and abs(a.r - b.r) <= EPS:
        return _same_circle(a, b)
    if d > a.r + b.r + EPS or d < abs(a.r - b.r) - EPS or d <= EPS:
        return [], None
    ux, uy = dx / d, dy / d
    x = (d * d + a.r * a.r - b.r * b.r) / (2.0 * d)  # along the centre line, from a's centre
    h2 = a.r * a.r - x * x
    if abs(d - (a.r + b.r)) <= EPS or abs(d - abs(a.r - b.r)) <= EPS or h2 <= 0.0:
        cands = [(a.cx + x * ux, a.cy + x * uy)]
    else:
        h = math.sqrt(h2)
        cands = [(a.cx + x * ux - h * uy, a.cy + x * uy + h * ux), (a.cx + x * ux + h * uy, a.cy + x * uy - h * ux)]
    return [p for p in cands if _params_at(a, *p) is not None and _params_at(b, *p) is not None], None


def _same_circle(a: Arc, b: Arc):
    """Arcs of one circle: the part of ``a`` that ``b`` covers (one interval, or none; two when the
    arcs overlap at both ends, which a region's arcs of at most a turn rarely do: then Degenerate)."""
    (alo, ahi), (blo, bhi) = _angles(a), _angles(b)
    same = (a.a1 >= a.a0) == (b.a1 >= b.a0)
    found, points = [], []
    for k in (-2, -1, 0, 1, 2):
        lo, hi = max(alo, blo + k * TWO_PI), min(ahi, bhi + k * TWO_PI)
        if (hi - lo) * a.r > SNAP:
            found.append((lo, hi))
        elif hi - lo > -SNAP / a.r:
            points.append(_point(a, 0.5 * (lo + hi)))
    if len(found) > 1:
        raise Degenerate("two arcs of one circle overlap twice")
    if found:
        return [], (*found[0], 1 if same else -1)
    return points, None


# -- the difference -----------------------------------------------------------------------------

class _Vertices:
    """Points merged within SNAP, each given an id (what the loops are chained by)."""

    def __init__(self) -> None:
        self.points: list[tuple[float, float]] = []
        self.grid: dict[tuple[int, int], list[int]] = {}
        self.exact: dict[tuple[float, float], int] = {}

    def id(self, x: float, y: float) -> int:
        k = self.exact.get((x, y))
        if k is not None:
            return k
        k = self._merged(x, y)
        self.exact[(x, y)] = k
        return k

    def _merged(self, x: float, y: float) -> int:
        gx, gy = int(math.floor(x / SNAP)), int(math.floor(y / SNAP))
        for i in range(gx - 1, gx + 2):
            for j in range(gy - 1, gy + 2):
                for k in self.grid.get((i, j), ()):
                    p = self.points[k]
                    if abs(p[0] - x) <= SNAP and abs(p[1] - y) <= SNAP:
                        return k
        self.points.append((x, y))
        self.grid.setdefault((gx, gy), []).append(len(self.points) - 1)
        return len(self.points) - 1


def _split(e: Edge, cuts: list[tuple[float, float]], verts: _Vertices):
    """``e`` cut at the points ``cuts``: [(piece, start id, end id, t0, t1)]; cut points closer than
    SNAP to an end or to each other are one. A piece ends at the very point it was cut at (the piece
    of the other edge cut there ends there too)."""
    lo, hi = _span(e)
    at = sorted(((t, p) for p in cuts if (t := _params_at(e, *p)) is not None), reverse=hi < lo)
    scale = _length_per_param(e)
    marks = [(lo, (e.x0, e.y0))]
    for t, p in at:
        if abs(t - marks[-1][0]) * scale > SNAP and abs(hi - t) * scale > SNAP:
            marks.append((t, p))
    marks.append((hi, (e.x1, e.y1)))
    if len(marks) == 2:
        return [(e, verts.id(e.x0, e.y0), verts.id(e.x1, e.y1), lo, hi)]
    out = []
    for (t0, p0), (t1, p1) in zip(marks, marks[1:]):
        piece = Line(*p0, *p1) if type(e) is Line else Arc(*p0, *p1, e.cx, e.cy, e.r, t0, t1)
        out.append((piece, verts.id(*p0), verts.id(*p1), t0, t1))
    return out


def edge_point(e: Edge) -> tuple[float, float]:
    return _point(e, 0.5 * sum(_span(e)))


def _tangent(e: Edge, at_end: bool) -> float:
    """Direction (rad) of travel along ``e`` at its start or end."""
    if type(e) is Line:
        return math.atan2(e.y1 - e.y0, e.x1 - e.x0)
    a = e.a1 if at_end else e.a0
    return a + (0.5 * math.pi if e.a1 >= e.a0 else -0.5 * math.pi)


def winding(region_edges: list[Edge], x: float, y: float) -> int:
    """Winding number about (x, y) of the closed loops ``region_edges`` make: the signed crossings of
    the ray to +X, each y-monotone stretch of an edge taken on the half-open range [low, high) of its
    heights, so that a ray through a vertex counts it once."""
    w = 0
    for e in region_edges:
        if type(e) is Line:
            if e.y0 <= y < e.y1 or e.y1 <= y < e.y0:
                if e.x0 + (y - e.y0) * (e.x1 - e.x0) / (e.y1 - e.y0) > x:
                    w += 1 if e.y1 > e.y0 else -1
            continue
        if e.cx + e.r <= x or not e.cy - e.r <= y < e.cy + e.r:
            continue
        for (t0, p0), (t1, p1) in _monotone(e):
            up = p1 > p0
            if (p0 <= y < p1) if up else (p1 <= y < p0):
                # on a stretch that does not pass an extreme, cos keeps the sign it has at its middle
                c = math.sqrt(max(0.0, 1.0 - ((y - e.cy) / e.r) ** 2))
                if e.cx + (c if math.cos(0.5 * (t0 + t1)) > 0 else -c) * e.r > x:
                    w += 1 if up else -1
    return w


def _monotone(e: Arc) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """The arc's stretches between its ends and the top and bottom of its circle, as
    ((angle, height), (angle, height)) in the arc's direction; the arc's own end heights exact."""
    ccw = e.a1 >= e.a0
    lo, hi = _angles(e)
    k = math.floor(lo / math.pi - 0.5) + 1
    cuts = []
    while (k + 0.5) * math.pi < hi:
        t = (k + 0.5) * math.pi
        cuts.append((t, e.cy + (e.r if k % 2 == 0 else -e.r)))
        k += 1
    if not ccw:
        cuts.reverse()
    marks = [(e.a0, e.y0), *cuts, (e.a1, e.y1)]
    return list(zip(marks, marks[1:]))


def _distance(e: Edge, x: float, y: float) -> float:
    if type(e) is Line:
        t = min(1.0, max(0.0, _line_param(e, x, y)))
        return math.hypot(x - e.x0 - t * (e.x1 - e.x0), y - e.y0 - t * (e.y1 - e.y0))
    t = _arc_param(e, math.atan2(y - e.cy, x - e.cx), 0.0)
    if t is not None:
        return abs(math.hypot(x - e.cx, y - e.cy) - e.r)
    return min(math.hypot(x - e.x0, y - e.y0), math.hypot(x - e.x1, y - e.y1))


def _side(edges_near: list[Edge], all_edges: list[Edge], boxes, x: float, y: float) -> bool:
    """Whether (x, y) lies inside the loops of ``all_edges`` (their ``boxes``); Degenerate when it
    is within EPS·10 of their boundary (``edges_near``: the ones that may be that close)."""
    for e in edges_near:
        if _distance(e, x, y) < 10 * EPS:
            raise Degenerate(f"a piece's midpoint ({x:.9g}, {y:.9g}) lies on the other region's boundary")
    # only edges level with the point and reaching right of it can cross the ray to +X
    return winding([e for e, b in zip(all_edges, boxes) if b[1] <= y <= b[3] and b[2] > x], x, y) > 0


class Difference(NamedTuple):
    """``a`` minus ``b``: the new region, its area (mm²), the area lost (mm²), and the pieces of
    ``b``'s edges on the new region's boundary (in ``b``'s direction)."""

    region: Region
    area: float
    lost: float
    b_pieces: tuple[Edge, ...]


def difference(a: Region, b: Region) -> Difference:
    """The region ``a`` minus the region ``b``. Raises :class:`Degenerate` (see the module)."""
    a_edges = [e for loop in a for e in loop]
    b_edges = [e for loop in b for e in loop]
    if any(math.hypot(e.x1 - e.x0, e.y1 - e.y0) < SNAP and (type(e) is Line or abs(e.a1 - e.a0) < math.pi)
           for e in (*a_edges, *b_edges)):
        raise Degenerate("an edge shorter than the vertex tolerance")
    a_boxes = [edge_box(e) for e in a_edges]
    b_boxes = [edge_box(e) for e in b_edges]
    bb, a_box = _union_box(b_boxes), _union_box(a_boxes)
    near_a = [i for i, box in enumerate(a_boxes) if _overlap(box, bb, SNAP)]
    cuts_a: dict[int, list] = {i: [] for i in near_a}
    cuts_b: list[list] = [[] for _ in b_edges]
    shared_a: dict[int, list] = {}  # a's edge -> [(lo, hi, direction)] it shares with b
    shared_b: dict[int, list] = {}
    for i in near_a:
        ea = a_edges[i]
        for j, eb in enumerate(b_edges):
            if not _overlap(a_boxes[i], b_boxes[j], SNAP):
                continue
            pts, common = _crossings(ea, eb)
            if common is not None:
                lo, hi, sign = common
                ends = [_point(ea, lo), _point(ea, hi)]
                pts = pts + ends
                shared_a.setdefault(i, []).append((lo, hi, sign))
                blo, bhi = (_params_at(eb, *ends[0]), _params_at(eb, *ends[1]))
                if blo is None or bhi is None:
                    raise Degenerate("a shared stretch whose ends are not on both edges")
                shared_b.setdefault(j, []).append((min(blo, bhi), max(blo, bhi), sign))
            cuts_a[i].extend(pts)
            cuts_b[j].extend(pts)
    verts = _Vertices()
    new: list[tuple[Edge | list[Edge], int, int]] = []  # a piece, or a run of untouched edges
    lost: list[tuple[Edge, int, int]] = []
    b_kept: list[Edge] = []
    kept_loops: list[tuple[Edge, ...]] = []
    first = 0
    for loop in a:
        count = len(loop)
        touched = [k for k in range(count) if first + k in cuts_a]
        if not touched:
            kept_loops.append(loop)  # wholly outside b's box: kept as it is
            first += count
            continue
        # from a touched edge round the loop: the untouched edges between go as one run
        start = touched[0]
        run: list[Edge] = []
        for step in range(count):
            k = (start + step) % count
            i = first + k
            if i not in cuts_a:
                run.append(loop[k])
                if (k + 1) % count == start or first + (k + 1) % count in cuts_a:
                    new.append((run, verts.id(run[0].x0, run[0].y0), verts.id(run[-1].x1, run[-1].y1)))
                    run = []
                continue
            e = loop[k]
            for piece, v0, v1, t0, t1 in _split(e, cuts_a[i], verts):
                tm = 0.5 * (t0 + t1)
                on = next((s for lo, hi, s in shared_a.get(i, ()) if lo - 1e-12 <= tm <= hi + 1e-12), None)
                if on is not None:
                    (lost if on > 0 else new).append((piece, v0, v1))
                    continue
                box = edge_box(piece)
                near = [eb for eb, bb_j in zip(b_edges, b_boxes) if _overlap(box, bb_j, 10 * EPS)]
                inside = _side(near, b_edges, b_boxes, *edge_point(piece))
                (lost if inside else new).append((piece, v0, v1))
        first += count
    for j, e in enumerate(b_edges):
        for piece, v0, v1, t0, t1 in _split(e, cuts_b[j], verts):
            tm = 0.5 * (t0 + t1)
            if any(lo - 1e-12 <= tm <= hi + 1e-12 for lo, hi, _ in shared_b.get(j, ())):
                continue  # on a's boundary: a's own piece there says which side keeps it
            box = edge_box(piece)
            if not _overlap(box, a_box, SNAP):
                continue
            near = [a_edges[i] for i in near_a if _overlap(box, a_boxes[i], 10 * EPS)]
            if not _side(near, a_edges, a_boxes, *edge_point(piece)):
                continue
            lost.append((piece, v0, v1))
            new.append((reversed_edge(piece), v1, v0))
            b_kept.append(piece)
    new_loops = kept_loops + _chain(new, verts.points)
    islands = [loop for loop in new_loops if _island(loop)]
    lost_area = region_area(_chain(lost, verts.points))
    if islands:  # removed with the rest: their area is lost, the tool's edges round them touch nothing
        new_loops = [loop for loop in new_loops if not any(loop is i for i in islands)]
        lost_area += region_area(islands)
        gone = {e for loop in islands for e in loop}
        b_kept = [e for e in b_kept if reversed_edge(e) not in gone]
    return Difference(tuple(new_loops), region_area(new_loops), lost_area, tuple(b_kept))


# mm: a loop of material smaller than this across in x and in y is no material. Such islands are left
# where several tool circles nearly meet at one point (a helix whose radius is the tool's: every
# step's circle passes within a µm of the helix axis); their µm edges are below what the kernel can
# make faces of (a checkpoint of such a layer failed with StdFail_NotDone), and below the resolution
# at which posts write coordinates.
ISLAND = 1e-3


def _island(loop: tuple[Edge, ...]) -> bool:
    x, y = loop[0].x0, loop[0].y0
    for e in loop:  # most loops are decided by their first vertices: far apart, no island
        if abs(e.x1 - x) >= ISLAND or abs(e.y1 - y) >= ISLAND:
            return False
    x0, y0, x1, y1 = region_box((loop,))
    return x1 - x0 < ISLAND and y1 - y0 < ISLAND and region_area((loop,)) > 0


def _union_box(boxes) -> tuple[float, float, float, float]:
    return (min(x[0] for x in boxes), min(x[1] for x in boxes), max(x[2] for x in boxes), max(x[3] for x in boxes))


def reversed_edge(e: Edge) -> Edge:
    if type(e) is Line:
        return Line(e.x1, e.y1, e.x0, e.y0)
    return Arc(e.x1, e.y1, e.x0, e.y0, e.cx, e.cy, e.r, e.a1, e.a0)


def _first(piece):
    return piece[0] if type(piece) is list else piece


def _last(piece):
    return piece[-1] if type(piece) is list else piece


def _chain(pieces: list[tuple[Edge, int, int]], points: list[tuple[float, float]]) -> list[tuple[Edge, ...]]:
    """The pieces joined end to start into closed loops; at a vertex several loops pass through,
    the sharpest right turn (which keeps each loop simple). Degenerate if they do not close. A
    piece's ends are moved onto its vertices' ``points`` (where a vertex merged points up to SNAP
    apart), so that every loop closes exactly."""
    out_of: dict[int, list[int]] = {}
    for k, (_, v0, _) in enumerate(pieces):
        out_of.setdefault(v0, []).append(k)
    used = [False] * len(pieces)
    loops = []
    for k0 in range(len(pieces)):
        if used[k0]:
            continue
        loop, k = [], k0
        while True:
            used[k] = True
            e, v0, v1 = pieces[k]
            p0, p1 = points[v0], points[v1]
            if type(e) is list:  # a run of edges: only its ends may move
                if (e[0].x0, e[0].y0) != p0:
                    e = [e[0]._replace(x0=p0[0], y0=p0[1]), *e[1:]]
                if (e[-1].x1, e[-1].y1) != p1:
                    e = [*e[:-1], e[-1]._replace(x1=p1[0], y1=p1[1])]
                loop.extend(e)
            else:
                if (e.x0, e.y0) != p0 or (e.x1, e.y1) != p1:
                    e = e._replace(x0=p0[0], y0=p0[1], x1=p1[0], y1=p1[1])
                loop.append(e)
            end = pieces[k][2]
            if end == pieces[k0][1]:
                break
            options = [m for m in out_of.get(end, ()) if not used[m]]
            if not options:
                raise Degenerate("the pieces of the boundary do not close into loops")
            if len(options) > 1:
                heading = _tangent(_last(pieces[k][0]), True)
                options.sort(key=lambda m: (_tangent(_first(pieces[m][0]), False) - heading + math.pi) % TWO_PI)
            k = options[0]
        loops.append(tuple(loop))
    return loops
