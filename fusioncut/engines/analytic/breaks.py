"""Where a CL's removed height may jump or bend: the boundary curves of the sweeps over a cell and
the break points they make (:mod:`.volume` integrates between them).

Machine frame, mm. Each sweep's lower surface jumps where its footprint ends and bends where its
tool's profile changes piece: on circles about the path's ends (and, for an arc, about its centre),
segments beside a line's path and an arc's end radii (:func:`boundary_curves`; a round bar's outside
on its circle). Along a line x = const the curves' crossings part the inner integral
(:func:`crossings_at_x`); across lines the curves' ends, extremes, centres and meetings part the
outer one (:func:`x_breaks`, :func:`curve_meetings_x`).

A curve needs to part nothing where the removed height is smooth on both sides of it whatever its
sweep does (:func:`nothing_removed_near`): where it is 0, strictly outside the CL's footprint or
strictly inside a deeper sweep's footprint (the finish allowance of a wall beside an earlier
ramp's many tiny pieces meets dozens of such curves a cell); and where the curve's sweep lies
above another one there, so that it gives the material's top nowhere near (a raster's pass before
last, whose footprint's edge runs under the last pass's scallop). Nor does a point outside the
cell: it moves no crossing within it.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.profile import corner_radii, profile_radius, rim_radius
from fusioncut.engines.analytic.sweeps import ARC, NCOL, OUTSIDE, sweep_floor, sweep_lower

ZERO_MARGIN = 1e-9  # mm: how far inside another footprint, and below the CL's surface, a crossing must lie
# for it to be no break point (nothing_removed_near)
RIM_BEYOND = 1e-9  # mm: a rim this far past a line's end (or on it) flags that end (_rim_end)
MERGE_TOL = 1e-12  # mm: x break points this close are one; a kink moved this far costs the outer integral
# no more than this times the inner integral's jump there


@njit(cache=True, inline="always")
def _near_lower(C, PP, NPC, RR, j, x, y):
    """The earlier sweep ``C[j]``'s lower surface at (x, y) (mm), its footprint widened by
    :data:`ZERO_MARGIN` so that a point on its rim is inside whatever the round-off (the surface is
    continuous up to its rim, where it takes its limit; beyond, it is +inf, so anything below it
    near the point is below it all around)."""
    t = int(C[j, 12])
    return sweep_lower(C[j], PP[t, :NPC[t]], RR[t], x, y, ZERO_MARGIN)


@njit(cache=True)
def nothing_removed_near(j, i, x, y, S, P, R, C, CB, PP, NPC, RR, zb):
    """Whether a meeting of earlier sweeps ``j``'s and ``i``'s curves at (x, y) (``j`` = ``i``: a
    curve's own end or extreme) parts nothing: True where the point lies strictly outside the CL's
    footprint, or strictly inside another sweep's footprint whose lower surface is below, by more
    than :data:`ZERO_MARGIN`, the CL's (or the bottom: nothing is removed around) or ``j``'s or
    ``i``'s own (:func:`_near_lower`: that sweep gives the least lower surface nowhere around, so
    where it jumps or bends the least one does not, and its curve is no break point there either:
    the other curve's crossings keep their order through the meeting). All those surfaces are
    continuous there (or jump up), so each inequality holds around the point. The CL's closed-form
    floor decides first, its surface only where that does not."""
    own = sweep_floor(S, P, R, x, y, 0.0)  # the CL's lower surface is at least this; inf outside it
    if own == math.inf:
        return True
    hidden = max(_near_lower(C, PP, NPC, RR, j, x, y), _near_lower(C, PP, NPC, RR, i, x, y)) - ZERO_MARGIN
    bound = max(max(own, zb) - ZERO_MARGIN, hidden)
    exact = math.nan  # the CL's lower surface itself, found once a sweep needs it
    for k in range(C.shape[0]):
        if k == j or k == i or C[k, 0] == OUTSIDE:
            continue
        if x < CB[k, 0] or x > CB[k, 2] or y < CB[k, 1] or y > CB[k, 3]:
            continue
        t = int(C[k, 12])
        if sweep_floor(C[k], PP[t, :NPC[t]], RR[t], x, y, -ZERO_MARGIN) == math.inf:
            continue  # not strictly inside its footprint
        h = sweep_lower(C[k], PP[t, :NPC[t]], RR[t], x, y, 0.0)
        if h < bound:
            return True
        if math.isnan(exact):
            exact = max(sweep_lower(S, P, R, x, y, 0.0), zb) - ZERO_MARGIN
        if h < exact:
            return True
    return False


@njit(cache=True, inline="always")
def _rim_end(y, lo, hi, is_rim):
    """Which end of [lo, hi] the crossing ``y`` of a curve outside (lo, hi) flags (0 lo, 1 hi, -1 none): a rim
    on an end or at most :data:`RIM_BEYOND` past it (a footprint's side along a cell's edge, the CL's own where
    the cell's edge is its footprint box's), where the removed height rises as a square root."""
    if is_rim > 0.0:
        if lo - RIM_BEYOND <= y <= lo:
            return 0
        if hi <= y <= hi + RIM_BEYOND:
            return 1
    return -1


@njit(cache=True)
def crossings_at_x(x, circles, segments, lo, hi, S, P, R, C, CB, PP, NPC, RR, zb):
    """Sorted break points in [lo, hi] on the line at ``x``, with lo and hi; the index (in the
    cell's rows: 0 the CL's own sweep, j + 1 the earlier sweep ``C[j]``) of the sweep whose curve
    makes each one (-1 for lo and hi); and whether that curve is a rim (:func:`boundary_curves`; lo and
    hi, a cell's edges, are one where a rim runs on them, :func:`_rim_end`). A crossing of an earlier
    sweep's curve where nothing is removed around it (:func:`nothing_removed_near`) is left out."""
    out = [lo, hi]
    own = [-1.0, -1.0]
    rim = [0.0, 0.0]
    for i in range(circles.shape[0]):
        u = x - circles[i, 0]
        s = circles[i, 2] * circles[i, 2] - u * u
        if s >= 0.0:
            w = math.sqrt(s)
            for y in (circles[i, 1] - w, circles[i, 1] + w):
                j = int(circles[i, 3]) - 1
                end = -1 if lo < y < hi else _rim_end(y, lo, hi, circles[i, 4])
                if (lo < y < hi or end >= 0) and not (
                        j >= 0 and nothing_removed_near(j, j, x, y, S, P, R, C, CB, PP, NPC, RR, zb)):
                    if end >= 0:
                        rim[end] = circles[i, 4]
                    else:
                        out.append(y)
                        own.append(circles[i, 3])
                        rim.append(circles[i, 4])
    for i in range(segments.shape[0]):
        x0, y0, x1, y1 = segments[i, 0], segments[i, 1], segments[i, 2], segments[i, 3]
        if x1 != x0 and min(x0, x1) <= x <= max(x0, x1):
            y = y0 + (y1 - y0) * (x - x0) / (x1 - x0)
            j = int(segments[i, 4]) - 1
            end = -1 if lo < y < hi else _rim_end(y, lo, hi, segments[i, 5])
            if (lo < y < hi or end >= 0) and not (
                    j >= 0 and nothing_removed_near(j, j, x, y, S, P, R, C, CB, PP, NPC, RR, zb)):
                if end >= 0:
                    rim[end] = segments[i, 5]
                else:
                    out.append(y)
                    own.append(segments[i, 4])
                    rim.append(segments[i, 5])
    pts = np.array(out)
    order = np.argsort(pts, kind="mergesort")
    return pts[order], np.array(own)[order], np.array(rim)[order]


def boundary_curves(rows: np.ndarray, radii_of: list[tuple[float, ...]],
                    rims: list[float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Circles (cx, cy, r, owner, rim) and segments (x0, y0, x1, y1, owner, rim) where the lower
    surfaces of the sweeps ``rows`` may jump or bend: for each sweep, at each radius of
    ``radii_of[i]`` (its tool's R and the radii where its profile has a corner), for a stock's
    outside its circle; ``owner`` is the sweep's index in ``rows``; ``rim`` is 1 on the curves at
    ``rims[i]`` (:func:`.profile.rim_radius`, nan: none) that bound the footprint, where the lower
    surface rises like the square root of the distance (a line's end circles and sides, an arc's
    circles about its centre and its ends' circles), else 0. :func:`curves_at` with the radii as lists."""
    rows = np.asarray(rows, dtype=np.float64).reshape(-1, NCOL)
    width = max((len(r) for r in radii_of), default=0)
    radii = np.zeros((len(radii_of), max(width, 1)))
    for i, r in enumerate(radii_of):
        radii[i, :len(r)] = r
    counts = np.array([len(r) for r in radii_of], dtype=np.int64)
    rim = np.full(len(rows), math.nan) if rims is None else np.array(rims, dtype=np.float64)
    return curves_at(rows, radii, counts, rim)


@njit(cache=True)
def curves_at(rows, radii, counts, rims):
    """:func:`boundary_curves` of ``rows`` at the radii ``radii[i, :counts[i]]`` (mm) each, ``rims[i]``
    the radius of row ``i``'s rim curves (nan: none), in the same order: per row, per radius, its ends'
    circles, then a line's (a vertical arc's) two sides or an arc's circles about its centre (outer,
    then inner where it has one) and its two end radii."""
    nc = ns = 0
    for i in range(rows.shape[0]):
        row = rows[i]
        if row[0] == OUTSIDE:
            nc += 1
            continue
        for m in range(counts[i]):
            nc += 2
            if row[0] != ARC:
                if math.hypot(row[4] - row[1], row[5] - row[2]) > 0.0:
                    ns += 2
            else:
                nc += 2 if row[9] > radii[i, m] else 1
                ns += 2
    circles = np.empty((nc, 5))
    segments = np.empty((ns, 6))
    c = g = 0
    for i in range(rows.shape[0]):
        row = rows[i]
        if row[0] == OUTSIDE:
            circles[c, 0], circles[c, 1], circles[c, 2], circles[c, 3], circles[c, 4] = row[7], row[8], row[9], i, 0.0
            c += 1
            continue
        x0, y0, x1, y1 = row[1], row[2], row[4], row[5]
        for m in range(counts[i]):
            r = radii[i, m]
            edge = 1.0 if r == rims[i] else 0.0
            for cx, cy in ((x0, y0), (x1, y1)):
                circles[c, 0], circles[c, 1], circles[c, 2], circles[c, 3], circles[c, 4] = cx, cy, r, i, edge
                c += 1
            if row[0] != ARC:  # a line, or a vertical arc: its XY path is the segment between its ends
                ux, uy = x1 - x0, y1 - y0
                n = math.hypot(ux, uy)
                if n > 0:
                    nx, ny = -uy / n * r, ux / n * r
                    for side in (1.0, -1.0):
                        segments[g, 0], segments[g, 1] = x0 + side * nx, y0 + side * ny
                        segments[g, 2], segments[g, 3] = x1 + side * nx, y1 + side * ny
                        segments[g, 4], segments[g, 5] = i, edge
                        g += 1
            else:
                cx, cy, rho, a0, sw = row[7], row[8], row[9], row[10], row[11]
                circles[c, 0], circles[c, 1], circles[c, 2], circles[c, 3], circles[c, 4] = cx, cy, rho + r, i, edge
                c += 1
                if rho > r:
                    circles[c, 0], circles[c, 1], circles[c, 2], circles[c, 3] = cx, cy, rho - r, i
                    circles[c, 4] = edge
                    c += 1
                lo = max(rho - r, 0.0)
                for a in (a0, a0 + sw):
                    ca, sa = math.cos(a), math.sin(a)
                    segments[g, 0], segments[g, 1] = cx + lo * ca, cy + lo * sa
                    segments[g, 2], segments[g, 3] = cx + (rho + r) * ca, cy + (rho + r) * sa
                    segments[g, 4], segments[g, 5] = i, 0.0
                    g += 1
    return circles, segments


@njit(cache=True)
def sweep_curves(rows, PP, NPC, zb, zt):
    """:func:`boundary_curves` of the sweeps ``rows`` (tool tables ``PP``, ``NPC``) at their break radii:
    ``R`` and the profile's corners (:func:`.profile.corner_radii`); for a level sweep also where it
    crosses the heights ``zb`` and ``zt`` (mm: the stock's bottom and top), where the removed height
    bends. Rims at :func:`.profile.rim_radius`; a stock's outside gives its circle."""
    n = rows.shape[0]
    radii = np.zeros((n, PP.shape[1] + 2))
    counts = np.zeros(n, dtype=np.int64)
    rims = np.full(n, math.nan)
    for i in range(n):
        if rows[i, 0] == OUTSIDE:
            continue
        k = int(rows[i, 12])
        P = PP[k, :NPC[k]]
        corners = corner_radii(P)
        c = corners.shape[0]
        radii[i, :c] = corners
        if rows[i, 3] == rows[i, 6]:
            for level in (zb, zt):
                r = profile_radius(P, level - rows[i, 3])
                if 0 < r < P[P.shape[0] - 1, 2]:
                    radii[i, c] = r
                    c += 1
        counts[i] = c
        rims[i] = rim_radius(P)
    return curves_at(rows, radii, counts, rims)


@njit(cache=True)
def _meets(x, y, x0, y0, x1, y1, a, b, out):
    """Appends (x, y, a, b) to ``out`` where (x, y) lies in the rectangle (``a``, ``b``: the curves'
    owners)."""
    if x0 <= x <= x1 and y0 <= y <= y1:
        out.append((x, y, a, b))


@njit(cache=True, inline="always")
def circle_meetings(ax, ay, ar, bx, by, br):
    """(whether the circles about (ax, ay) of radius ``ar`` and about (bx, by) of radius ``br`` meet; the two
    points where they do, the one left of the line from the first centre to the second first; concentric
    circles meet nowhere)."""
    dx, dy = bx - ax, by - ay
    d2 = dx * dx + dy * dy
    if d2 <= 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    d = math.sqrt(d2)
    if d > ar + br or d < abs(ar - br):
        return False, 0.0, 0.0, 0.0, 0.0
    a = (ar * ar - br * br + d2) / (2.0 * d)
    h = math.sqrt(max(ar * ar - a * a, 0.0))
    mx, my = ax + a * dx / d, ay + a * dy / d
    return True, mx - h * dy / d, my + h * dx / d, mx + h * dy / d, my - h * dx / d


@njit(cache=True)
def curve_meetings_x(circles, segments, x0, y0, x1, y1):
    """Every point in the rectangle where two of the boundary curves meet (circle and circle, circle
    and segment, segment and segment): rows (x, y, the two curves' owners). Between them and the
    curves' extreme x, the order of the curves' crossings along a line x = const stays the same, so
    a region between two curves (a sliver a flat end mill leaves beside earlier passes) is a stretch
    of every line through it and a part of the outer integral ends where it begins and ends: no
    sample has to hit it."""
    out = [(x0, y0, -1.0, -1.0)]
    nc, ns = circles.shape[0], segments.shape[0]
    for i in range(nc):
        ax, ay, ar, ao = circles[i, 0], circles[i, 1], circles[i, 2], circles[i, 3]
        for j in range(i + 1, nc):
            bx, by, br = circles[j, 0], circles[j, 1], circles[j, 2]
            met, px, py, qx, qy = circle_meetings(ax, ay, ar, bx, by, br)
            if met:
                _meets(px, py, x0, y0, x1, y1, ao, circles[j, 3], out)
                _meets(qx, qy, x0, y0, x1, y1, ao, circles[j, 3], out)
        for j in range(ns):
            px, py = segments[j, 0], segments[j, 1]
            ux, uy = segments[j, 2] - px, segments[j, 3] - py
            uu = ux * ux + uy * uy
            if uu <= 0.0:
                continue
            fx, fy = px - ax, py - ay
            b = fx * ux + fy * uy
            c = fx * fx + fy * fy - ar * ar
            disc = b * b - uu * c
            if disc < 0.0:
                continue
            w = math.sqrt(disc)
            for t in ((-b - w) / uu, (-b + w) / uu):
                if 0.0 <= t <= 1.0:
                    _meets(px + t * ux, py + t * uy, x0, y0, x1, y1, ao, segments[j, 4], out)
    for i in range(ns):
        px, py = segments[i, 0], segments[i, 1]
        ux, uy = segments[i, 2] - px, segments[i, 3] - py
        for j in range(i + 1, ns):
            qx, qy = segments[j, 0], segments[j, 1]
            vx, vy = segments[j, 2] - qx, segments[j, 3] - qy
            den = ux * vy - uy * vx
            if den == 0.0:
                continue
            t = ((qx - px) * vy - (qy - py) * vx) / den
            u = ((qx - px) * uy - (qy - py) * ux) / den
            if 0.0 <= t <= 1.0 and 0.0 <= u <= 1.0:
                _meets(px + t * ux, py + t * uy, x0, y0, x1, y1, segments[i, 4], segments[j, 4], out)
    res = np.empty((len(out), 4))
    for i in range(len(out)):
        res[i, 0], res[i, 1], res[i, 2], res[i, 3] = out[i]
    return res


@njit(cache=True)
def edge_crossings(circles, segments, ylo, yhi):
    """Rows (x, y, owner): where the curves cross the lines y = ``ylo`` and y = ``yhi`` (a cell's
    edges), each a place where a curve's crossing of the lines x = const enters or leaves the cell.
    ``(r - d)(r + d)``, not ``r^2 - d^2``: a circle tangent to an edge keeps its digits."""
    out = [(0.0, 0.0, 0.0)]  # typed for numba; the rows are out[1:]
    for i in range(circles.shape[0]):
        cx, cy, r = circles[i, 0], circles[i, 1], circles[i, 2]
        for y in (ylo, yhi):
            s = (r - (y - cy)) * (r + (y - cy))
            if s >= 0.0:
                w = math.sqrt(s)
                out.append((cx - w, y, circles[i, 3]))
                out.append((cx + w, y, circles[i, 3]))
    for i in range(segments.shape[0]):
        x0, y0, x1, y1 = segments[i, 0], segments[i, 1], segments[i, 2], segments[i, 3]
        if y1 != y0:
            for y in (ylo, yhi):
                t = (y - y0) / (y1 - y0)
                if 0.0 <= t <= 1.0:
                    out.append((x0 + t * (x1 - x0), y, segments[i, 4]))
    res = np.empty((len(out) - 1, 3))
    for i in range(1, len(out)):
        res[i - 1, 0], res[i - 1, 1], res[i - 1, 2] = out[i]
    return res


@njit(cache=True)
def x_breaks(circles, segments, lo, hi, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb):
    """Sorted x break points in [lo, hi], lo and hi among them: of the points within the rectangle
    [lo, hi] x [ylo, yhi] where a line x = const meets a curve's end or extreme, two curves meet
    (:func:`curve_meetings_x`) or a curve crosses the rectangle's edge y = ylo or yhi
    (:func:`edge_crossings`: a band between two curves that run along y through the cell, their
    extremes outside it, is then a part of its own, not left to the outer rule's lines to hit), the
    circles' centres (a cone's apex) with them, those where the removed height may bend. One outside
    the rectangle moves no crossing within it; one where nothing is removed around it whatever the
    curves' sweeps do (:func:`nothing_removed_near`) bends nothing. Where the CL's own curve meets an
    earlier sweep's, that sweep's curve alone decides: where it is no break point around the meeting,
    the CL's curve's crossings run on smoothly through it.
    A segment along x = const (a line's sweep along y) crosses no line: its x is a break wherever it
    meets the rectangle. Points within :data:`MERGE_TOL` of the last one kept are one (two curves
    through one point, in round-off apart: a part between them would cost the outer rule all its
    nodes for nothing); lo and hi stay."""
    cand = [(lo, ylo, -1.0, -1.0), (hi, ylo, -1.0, -1.0)]
    for i in range(circles.shape[0]):
        cx, cy, r, o = circles[i, 0], circles[i, 1], circles[i, 2], circles[i, 3]
        cand.append((cx - r, cy, o, o))
        cand.append((cx + r, cy, o, o))
        cand.append((cx, cy, o, o))
    for i in range(segments.shape[0]):
        x0, y0, x1, y1 = segments[i, 0], segments[i, 1], segments[i, 2], segments[i, 3]
        if x0 == x1:  # along a line x = const: no line crosses it, its x must part the lines
            if min(y0, y1) <= yhi and max(y0, y1) >= ylo:
                cand.append((x0, ylo, -1.0, -1.0))
            continue
        cand.append((x0, y0, segments[i, 4], segments[i, 4]))
        cand.append((x1, y1, segments[i, 4], segments[i, 4]))
    edge = edge_crossings(circles, segments, ylo, yhi)
    for i in range(edge.shape[0]):
        cand.append((edge[i, 0], edge[i, 1], edge[i, 2], edge[i, 2]))
    meet = curve_meetings_x(circles, segments, lo, ylo, hi, yhi)
    for i in range(meet.shape[0]):
        cand.append((meet[i, 0], meet[i, 1], meet[i, 2], meet[i, 3]))
    xs = []
    for x, y, a, b in cand:
        if not (lo <= x <= hi and ylo <= y <= yhi):
            continue
        if a == 0.0 and b >= 1.0 or b == 0.0 and a >= 1.0:  # the CL's own curve meets an earlier sweep's
            a = b = max(a, b)
        if a >= 1.0 and b >= 1.0 and nothing_removed_near(int(a) - 1, int(b) - 1, x, y, S, P, R, C, CB, PP, NPC, RR,
                                                         zb):
            continue
        xs.append(x)
    u = np.unique(np.array(xs))
    keep = [u[0]]  # lo
    for x in u[1:-1]:
        if x - keep[-1] > MERGE_TOL:
            keep.append(x)
    if len(keep) > 1 and u[-1] - keep[-1] <= MERGE_TOL:
        keep[-1] = u[-1]
    else:
        keep.append(u[-1])  # hi
    return np.array(keep)
