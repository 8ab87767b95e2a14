"""Engaged arcs of the tool at the end of a CL, slice by slice, without Booleans.

Machine frame, mm, radians. The tool stands at the end ``e`` of the CL's sweep ``S``; its slice at
``zs`` mm above the tip is the circle of radius ``r = rho(zs)`` about the axis. The point ``q(theta) =
e + r (cos theta, sin theta)`` at height ``e_z + zs`` is **engaged** when both hold:

* **material**: it lies strictly inside the stock's box and above no earlier sweep's
  lower surface (:func:`fusioncut.engines.analytic.sweeps.sweep_lower` with the footprint widened
  by ``eps``, lower surface + ``eps`` <= its height: cut; a round bar's outside is such a sweep,
  :func:`fusioncut.engines.analytic.sweeps.outside_row`). So a wall an earlier pass left exactly
  where the tool now stands (a deeper pass retracing it) holds no material: no interval, as in the
  B-Rep engine's zero-thickness rule.
* **front**: it lies on the boundary of the CL's own sweep, not strictly inside the tool at an
  earlier position of the same CL. With ``phi(t) = |q - c(t)| - rho(q_z - z(t))`` (< 0: strictly
  inside the tool at ``t``), ``phi(1) = 0``; on a line ``phi`` is convex, so the point is on the
  front iff ``phi'(1) <= 0``, that is ``u . v_xy >= rho'(zs) v_z`` with ``u`` the unit radial
  direction and ``v = c'(1)``: a closed form (half the circle on a level move, all of it on a plunge,
  more than half going down a ramp). On an arc the same local condition holds and the least ``phi``
  over the arc must not be below ``-eps`` (the tool at an earlier turn of a helix or circle); on a
  vertical arc the point must not lie above the arc's own lower surface (:mod:`.vertical`).

Interval ends: the predicate is evaluated at :data:`N_SCAN` even angles plus the closed-form front
limits, then every change between neighbours is bisected to :data:`ANGLE_TOL` rad. The scan takes
its angles :data:`BLOCK` at a time: where bounds over the block's arc settle the material test for
all its points at once (:func:`block_state`: all inside the stock and above every sweep's floor,
or all below one line sweep's tool at a single position), only the front's test is left per angle;
the result is the same as angle by angle. The angles where the slice's circle crosses an earlier
footprint's edge (a wall) are scanned too, just either side, so engaged arcs narrower than the scan step
(0.5 degrees) can be missed only where both their ends are neither a wall nor a front limit (an arc
between two lower surfaces that the slice's height crosses twice within the step). An edge whose sweep's
lower surface is above the slice all along it ends no arc and is not scanned (:func:`standing_walls`: a
finishing pass's many short moves before, each a ball's edge at its centre's height). Where the circle
only touches a boundary (tangent to a stock face or an earlier wall), rounding leaves a gap of
~1e-8 rad: gaps under :data:`GAP_TOL` are closed, as the B-Rep engine's one contact face has none.

The contact's height range needs the highest (and lowest) height where any point of the slice is
engaged; near it the engaged arc shrinks to a point, which a scan would miss. So
:func:`slice_margin` maximises the **material margin** (the least of the distances to the stock's
faces and of the earlier sweeps' lower surfaces above the point, mm) over the front arc, sampled
and refined by golden section: the slice touches material where that maximum is positive.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.brent import GOLDEN
from fusioncut.engines.analytic.cells import DOMINANCE_MOST, relevant_sweeps
from fusioncut.engines.analytic.polar import ring_breaks
from fusioncut.engines.analytic.profile import profile_height, profile_radius, profile_radius_slope
from fusioncut.engines.analytic.sweeps import (ARC, LINE, OUTSIDE, arc_holds, end_velocity, floor_within,
                                               segment_nearest, sweep_floor, sweep_lower)
from fusioncut.engines.analytic.vertical import is_vertical, vertical_lower

N_SCAN = 720
BLOCK = 8  # scan angles tested at once (block_state)
ANGLE_TOL = 1e-10  # rad
N_TOUCH = 360  # angles per height scanned for the contact's height range (contact_range)
Z_TOL = 1e-10  # mm: the contact's height range
MARGIN_NOISE = 1e-10  # mm: contact_range's regula falsi halves the bracket where an end's margin is within
# this of 0 but not 0: below a tangential onset the margin is round-off (~1e-13 mm), flat, and would pull
# every chord onto that end
NO_FOOT = np.empty(0)  # relevant_sweeps' footprint ceilings: none (a contact point may lie beyond the CL's footprint)
MANY = 12  # a grid cell holding more sweeps leaves out the dominated ones (.cells.relevant_sweeps)
BESIDE = 1e-7  # rad: a wall's crossing of a slice is scanned this far either side (beside_walls)
GAP_TOL = 1e-6  # rad: gaps narrower than this between engaged arcs are tangent points, not gaps
# end_cause's codes beside material_blocker's stock faces (-2..-7) and the earlier sweeps' (>= 0: 2 j, 2 j + 1)
FRONT_LIMIT = -8
OWN_TURN = -9
ENGAGED = -10
TWO_PI = 2.0 * math.pi


@njit(cache=True, inline="always")
def _cell(px, py, G, gstart):
    """(first, end) of the slice of the grid's item list for the cell holding (px, py); ``G`` = (x0,
    y0, cell width, cells a side), ``gstart`` the cells' offsets (row-major in x), see
    :func:`sweep_grid`."""
    n = int(G[3])
    i = min(max(int((px - G[0]) / G[2]), 0), n - 1)
    j = min(max(int((py - G[1]) / G[2]), 0), n - 1)
    c = i * n + j
    return gstart[c], gstart[c + 1]


@njit(cache=True)
def material_blocker(px, py, pz, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems):
    """What keeps (px, py, pz) out of the material before the CL: -1 nothing (the stock held
    material there), -2 - f the stock's face f (x0, y0, z0, x1, y1, z1 = 0..5) it is not strictly
    inside of, else the row in ``C`` of an earlier sweep whose lower surface is at or below it
    (footprint boxes ``CB``; tool tables ``PP``, ``NPC``, ``RR``; ``stock`` = x0, y0, z0, x1, y1, z1).
    Only the sweeps the grid cell of the point lists are looked at (:func:`sweep_grid`)."""
    p = (px, py, pz)
    for f in range(3):
        if p[f] <= stock[f]:
            return -2 - f
        if p[f] >= stock[3 + f]:
            return -5 - f
    first, end = _cell(px, py, G, gstart)
    for q in range(first, end):
        j = gitems[q]
        if px < CB[j, 0] - eps or px > CB[j, 2] + eps or py < CB[j, 1] - eps or py > CB[j, 3] + eps:
            continue
        if C[j, 3] > pz + eps and C[j, 6] > pz + eps:
            continue  # the whole sweep is above the point
        k = int(C[j, 12])
        if sweep_floor(C[j], PP[k, :NPC[k]], RR[k], px, py, eps) > pz + eps:
            continue  # its lower surface is above the point everywhere near it
        if sweep_lower(C[j], PP[k, :NPC[k]], RR[k], px, py, eps) <= pz + eps:
            return j
    return -1


@njit(cache=True)
def block_state(t0, t1, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems):
    """What holds for every point of the arc ``[t0, t1]`` (rad, ``t1 - t0 < pi``) of the circle of
    radius ``r`` about ``(ex, ey)`` at height ``pz`` (:func:`material_at`), for certain: 1 all in the
    material, 0 none, -1 not known. The arc lies within ``delta`` of its midpoint ``m``. It is all in
    the material where it is strictly inside the stock's box and no sweep of the grid cells the disc
    of radius ``delta`` about ``m`` meets has a floor over that disc (:func:`.sweeps.floor_within`) at
    or below it; none is where it is beyond a face of the box, or where one line sweep of those cells
    holds the whole disc below its lower surface: with ``c`` the point of its path nearest ``m``
    (XY) at distance ``d``, ``d + delta <= R`` and ``z(c) + f(d + delta)`` at or below the arc (the
    tool at ``c`` alone reaches that low over the disc), and the arc is lower than the stock's top by
    twice ``eps`` (a grid cell leaves out the sweeps whose floor is above the top, :func:`sweep_grid`)."""
    tm = 0.5 * (t0 + t1)
    mx, my = ex + r * math.cos(tm), ey + r * math.sin(tm)
    delta = 2.0 * r * math.sin(0.25 * (t1 - t0)) * (1.0 + 1e-9) + 1e-12
    if (mx + delta <= stock[0] or mx - delta >= stock[3] or my + delta <= stock[1] or my - delta >= stock[4]
            or pz <= stock[2] or pz >= stock[5]):
        return 0
    clear = stock[0] + delta < mx < stock[3] - delta and stock[1] + delta < my < stock[4] - delta
    n = int(G[3])
    i0 = min(max(int((mx - delta - G[0]) / G[2]), 0), n - 1)
    i1 = min(max(int((mx + delta - G[0]) / G[2]), 0), n - 1)
    j0 = min(max(int((my - delta - G[1]) / G[2]), 0), n - 1)
    j1 = min(max(int((my + delta - G[1]) / G[2]), 0), n - 1)
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            c = i * n + j
            for q in range(gstart[c], gstart[c + 1]):
                k = gitems[q]
                if (mx + delta < CB[k, 0] - eps or mx - delta > CB[k, 2] + eps or my + delta < CB[k, 1] - eps
                        or my - delta > CB[k, 3] + eps):
                    continue
                if C[k, 3] > pz + eps and C[k, 6] > pz + eps:
                    continue
                t = int(C[k, 12])
                P = PP[t, :NPC[t]]
                if C[k, 0] == 0.0:
                    s, d = segment_nearest(mx, my, C[k, 1], C[k, 2], C[k, 4], C[k, 5])
                    d += delta
                    z = C[k, 3] + s * (C[k, 6] - C[k, 3])
                    if d <= RR[t] and pz + 2.0 * eps < stock[5] and z + profile_height(P, d) <= pz + eps:
                        return 0
                if clear and floor_within(C[k], P, RR[t], mx, my, eps, delta) <= pz + eps:
                    clear = False
    return 1 if clear else -1


@njit(cache=True, inline="always")
def material_at(px, py, pz, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems):
    """True where the stock held material at (px, py, pz) before the CL (:func:`material_blocker`)."""
    return material_blocker(px, py, pz, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems) == -1


@njit(cache=True)
def sweep_grid(x0, y0, width, n, S, P, R, C, PP, NPC, RR, zb, zt, eps, ring_in=0.0, ring_out=math.inf):
    """(G, gstart, gitems): the square (x0, y0) + [0, width]² cut into ``n`` x ``n`` cells, and per
    cell the rows of ``C`` that can give the least lower surface in it (:func:`.cells.relevant_sweeps`,
    footprints widened by ``eps``); a point then meets only its cell's sweeps. Points outside the
    square take the nearest cell: callers keep them inside. Only the cells meeting the ring between
    ``ring_in`` and ``ring_out`` mm from the square's centre get their sweeps (a flat end mill's slices
    all lie on the circle of its radius): a point queried elsewhere would meet none.

    A block of cells is quartered (halved along a side one cell wide) down to single cells, each part
    starting from the sweeps its block kept: one left out of a block can shape the material in none of
    its cells (as the volume's quarters are), and the parts' tests are cheaper for it."""
    w = width / n
    items = [np.empty(0, dtype=np.int64) for _ in range(n * n)]
    stack = [(0, n, 0, n, np.arange(C.shape[0]))]
    cx, cy = x0 + 0.5 * width, y0 + 0.5 * width
    while len(stack) > 0:
        i0, i1, j0, j1, rows = stack.pop()
        if not _meets_ring(x0 + i0 * w - cx, y0 + j0 * w - cy, x0 + i1 * w - cx, y0 + j1 * w - cy, ring_in, ring_out):
            continue
        single = i1 - i0 == 1 and j1 - j0 == 1
        keep = relevant_sweeps(x0 + i0 * w, y0 + j0 * w, x0 + i1 * w, y0 + j1 * w, S, P, R, C[rows], PP, NPC, RR, zb,
                               zt, eps, MANY, math.inf if single else DOMINANCE_MOST, NO_FOOT)[1]
        rows = rows[keep]
        if single:
            items[i0 * n + j0] = rows
            continue
        im = (i0 + i1) // 2 if i1 - i0 > 1 else i1
        jm = (j0 + j1) // 2 if j1 - j0 > 1 else j1
        for a0, a1 in ((i0, im), (im, i1)):
            for b0, b1 in ((j0, jm), (jm, j1)):
                if a0 < a1 and b0 < b1:
                    stack.append((a0, a1, b0, b1, rows))
    starts = np.zeros(n * n + 1, dtype=np.int64)
    for c in range(n * n):
        starts[c + 1] = starts[c] + items[c].shape[0]
    flat = np.empty(starts[n * n], dtype=np.int64)
    for c in range(n * n):
        flat[starts[c]:starts[c + 1]] = items[c]
    G = np.empty(4)
    G[0], G[1], G[2], G[3] = x0, y0, w, n
    return G, starts, flat


@njit(cache=True, inline="always")
def _meets_ring(bx0, by0, bx1, by1, r_in, r_out):
    """Whether the box [bx0, bx1] x [by0, by1] (about the origin) meets the ring between the radii ``r_in``
    and ``r_out``: its nearest point is within ``r_out`` and its farthest corner beyond ``r_in``."""
    nx, ny = max(bx0, 0.0, -bx1), max(by0, 0.0, -by1)
    fx, fy = max(abs(bx0), abs(bx1)), max(abs(by0), abs(by1))
    return nx * nx + ny * ny <= r_out * r_out and fx * fx + fy * fy >= r_in * r_in


@njit(cache=True, inline="always")
def _ahead(theta, vx, vy, lift):
    """The front condition's closed-form part at machine angle ``theta``: ``u . v_xy >= lift``."""
    return _ahead_cs(math.cos(theta), math.sin(theta), vx, vy, lift)


@njit(cache=True, inline="always")
def _ahead_cs(c, s, vx, vy, lift):
    """:func:`_ahead` at the angle whose cosine and sine are ``c`` and ``s``."""
    g = c * vx + s * vy - lift
    return g >= -1e-12 * (abs(vx) + abs(vy) + abs(lift))


@njit(cache=True, inline="always")
def _past_own_turns(S, P, R, px, py, pz, eps):
    """The front condition's part beyond the closed form: (px, py, pz) is not inside the tool at an
    earlier position of the CL's arc by more than ``eps`` (a line's front needs nothing more; a vertical
    arc's: not above its own lower surface over the footprint shrunk by ``eps``, :mod:`.vertical`)."""
    if S[0] == 0.0:
        return True
    if is_vertical(S):
        return vertical_lower(S, P, R, px, py, -eps) >= pz - eps
    return not arc_holds(S, P, R, px, py, pz, eps)


@njit(cache=True)
def _front_at(theta, vx, vy, lift, S, P, R, ex, ey, pz, r, eps):
    """The front condition at machine angle ``theta`` (module docstring); ``lift = rho'(zs) v_z``."""
    if not _ahead(theta, vx, vy, lift):
        return False
    return _past_own_turns(S, P, R, ex + r * math.cos(theta), ey + r * math.sin(theta), pz, eps)


@njit(cache=True, inline="always")
def _engaged(theta, vx, vy, lift, S, P, R, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems):
    """Engaged at machine angle ``theta``: the closed-form front test first (it rules out the back
    half of a level move's circle at no cost), then the material, then an arc's earlier turns."""
    return _engaged_cs(math.cos(theta), math.sin(theta), vx, vy, lift, S, P, R, ex, ey, pz, r, C, CB, PP, NPC, RR,
                       stock, eps, G, gstart, gitems)


@njit(cache=True, inline="always")
def _engaged_cs(c, s, vx, vy, lift, S, P, R, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems):
    """:func:`_engaged` at the angle whose cosine and sine are ``c`` and ``s``."""
    if not _ahead_cs(c, s, vx, vy, lift):
        return False
    px, py = ex + r * c, ey + r * s
    if not material_at(px, py, pz, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems):
        return False
    return _past_own_turns(S, P, R, px, py, pz, eps)


@njit(cache=True)
def end_cause(theta, inside, vx, vy, lift, S, P, R, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart,
              gitems):
    """Why machine angle ``theta`` (just outside an engaged arc; ``inside`` just within it) is not
    engaged: ``FRONT_LIMIT`` off the front's closed-form half, a code of :func:`material_blocker` for
    a stock face, ``2 j`` where the end lies on the lower surface of the earlier sweep ``C[j]`` (the
    lowest there) and ``2 j + 1`` on its wall (``inside`` is beyond its footprint), ``OWN_TURN``
    inside the tool at an arc's earlier position, ``ENGAGED`` where it is engaged after all. An arc's
    span bends where the cause of one of its ends changes: from one sweep to another, and where a
    sweep's ball or corner meets its straight flank, whose curvature jumps."""
    if not _ahead(theta, vx, vy, lift):
        return FRONT_LIMIT
    px, py = ex + r * math.cos(theta), ey + r * math.sin(theta)
    b = material_blocker(px, py, pz, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems)
    if b >= 0:
        j = _lowest_sweep(px, py, C, CB, PP, NPC, RR, eps, G, gstart, gitems)
        j = j if j >= 0 else b
        k = int(C[j, 12])
        wall = sweep_lower(C[j], PP[k, :NPC[k]], RR[k], ex + r * math.cos(inside), ey + r * math.sin(inside),
                           eps) == math.inf
        return 2 * j + (1 if wall else 0)
    if b != -1:
        return b
    return ENGAGED if _past_own_turns(S, P, R, px, py, pz, eps) else OWN_TURN


@njit(cache=True)
def _lowest_sweep(px, py, C, CB, PP, NPC, RR, eps, G, gstart, gitems):
    """The row of the earlier sweep whose lower surface is lowest at (px, py) among those the
    point's grid cell lists, the first row among surfaces within 1e-9 mm of it (consecutive moves'
    sweeps share the tool at their joint: the same surface there must give the same cause)."""
    best, low = -1, math.inf
    first, end = _cell(px, py, G, gstart)
    for q in range(first, end):
        j = gitems[q]
        if px < CB[j, 0] - eps or px > CB[j, 2] + eps or py < CB[j, 1] - eps or py > CB[j, 3] + eps:
            continue
        k = int(C[j, 12])
        h = sweep_lower(C[j], PP[k, :NPC[k]], RR[k], px, py, eps)
        if h < low - 1e-9 or (h <= low + 1e-9 and j < best):
            best, low = j, min(h, low)
    return best


@njit(cache=True)
def front_limits(vx, vy, lift):
    """Machine angles (rad) where the front condition changes: cos(theta - psi) |v_xy| = lift."""
    out = np.empty(2)
    h = math.sqrt(vx * vx + vy * vy)
    if h <= 0.0 or abs(lift) >= h:
        return out[:0]
    psi = math.atan2(vy, vx)
    w = math.acos(lift / h)
    out[0] = (psi - w) % TWO_PI
    out[1] = (psi + w) % TWO_PI
    return out


@njit(cache=True)
def beside_walls(walls, step):
    """Angles (rad) to scan about the sorted angles ``walls`` where a circle crosses earlier footprints' edges:
    :data:`BESIDE` either side of each (an arc that a wall ends), and the middle between two closer than the
    scan's ``step`` (an arc that both end, however narrow: a point within the footprint widened by eps of a
    wall the circle crosses at a grazing angle is no nearer the arc's middle; a wider one holds a scan angle)."""
    n = walls.shape[0]
    out = np.empty(max(3 * n - 1, 0))
    k = 0
    for i in range(n):
        out[k] = walls[i] - BESIDE
        out[k + 1] = walls[i] + BESIDE
        k += 2
        if i + 1 < n and walls[i + 1] - walls[i] < step:
            out[k] = 0.5 * (walls[i] + walls[i + 1])
            k += 1
    return out[:k]


@njit(cache=True)
def standing_walls(curves, owner, pz, C, PP, NPC, RR, eps):
    """The footprint boundary curves (rows of ``curves``, their sweep's row in ``C`` in column ``owner``)
    that may end an engaged arc at height ``pz``: all but a line's or an XY arc's whose edge stands
    wholly above ``pz`` + 2 ``eps``. On its footprint's edge (distance R from its path, widened by
    ``eps``) a sweep's lower surface is at least its path's lowest tip plus the profile's height at R, and it
    is continuous up to that edge from within; where that bound is above the slice, the sweep holds the
    slice's points near its edge on neither side of it, so its edge changes no point's material test there
    (what does change there, a crossing of its surface with the slice, the scan finds as anywhere else)."""
    keep = np.ones(curves.shape[0], dtype=np.bool_)
    for i in range(curves.shape[0]):
        j = int(curves[i, owner])
        if C[j, 0] == LINE or C[j, 0] == ARC:
            k = int(C[j, 12])
            keep[i] = min(C[j, 3], C[j, 6]) + profile_height(PP[k, :NPC[k]], RR[k]) <= pz + 2.0 * eps
    return curves[keep]


@njit(cache=True)
def scan_angles(n_scan, extra):
    """(the scan's angles, rad: the ``n_scan`` even ones 2 pi i / n_scan and the sorted ``extra`` ones, merged in
    order; their cosines; their sines). The even angles' cosines and sines come from the first quarter's
    cosines by the quarter turns' symmetries (where ``n_scan`` is a multiple of 4), within a few ulps of
    each one's own: a scan angle only brackets an arc's end, which bisection then finds."""
    n = n_scan + extra.shape[0]
    th, cs, sn = np.empty(n), np.empty(n), np.empty(n)
    q = n_scan // 4 if n_scan % 4 == 0 else 0
    quarter = np.empty(q + 1)
    for j in range(q + 1):
        quarter[j] = math.cos(TWO_PI * j / n_scan)
    i = e = 0
    for k in range(n):
        if e == extra.shape[0] or (i < n_scan and TWO_PI * i / n_scan <= extra[e]):
            t = TWO_PI * i / n_scan
            th[k] = t
            if q > 0:
                turn, j = divmod(i, q)
                c, s = quarter[j], quarter[q - j]  # cos and sin of the angle within its quarter
                if turn == 0:
                    cs[k], sn[k] = c, s
                elif turn == 1:
                    cs[k], sn[k] = -s, c
                elif turn == 2:
                    cs[k], sn[k] = -c, -s
                else:
                    cs[k], sn[k] = s, -c
            else:
                cs[k], sn[k] = math.cos(t), math.sin(t)
            i += 1
        else:
            th[k] = extra[e]
            cs[k], sn[k] = math.cos(extra[e]), math.sin(extra[e])
            e += 1
    return th, cs, sn


@njit(cache=True)
def slice_arcs(S, P, R, zs, r, drho, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems, n_scan, circles, segments):
    """Engaged machine arcs (start, span) in rad, counter-clockwise, of the slice ``zs`` mm above the
    tip (radius ``r``, ``drho = rho'(zs)``) of the tool at the end of sweep ``S``, with the
    :func:`end_cause` of either end: an (n, 4) array (start, span, start's cause, end's cause); one
    row (0, 2 pi, ENGAGED, ENGAGED) when engaged all round. ``circles`` and ``segments``: the earlier
    sweeps' footprint boundaries (:func:`.breaks.boundary_curves`, their owners rows of ``C``), whose
    crossings with the slice's circle (and the stock's faces') are scanned beside and between
    (:func:`beside_walls`; those :func:`standing_walls` keeps): an engaged arc narrower than the scan's step
    that ends at a wall is not missed."""
    ex, ey, ez = S[4], S[5], S[6]
    vx, vy, vz = end_velocity(S)
    lift = 0.0 if vz == 0.0 else drho * vz
    pz = ez + zs
    lim = front_limits(vx, vy, lift)
    walls = ring_breaks(r, ex, ey, stock[0], stock[3], stock[1], stock[4], np.zeros((0, 2)), np.zeros((0, 2)),
                        standing_walls(circles, 3, pz, C, PP, NPC, RR, eps),
                        standing_walls(segments, 4, pz, C, PP, NPC, RR, eps))
    beside = beside_walls(walls, TWO_PI / n_scan)
    extra = np.empty(lim.shape[0] + beside.shape[0])
    extra[:lim.shape[0]] = lim
    for i in range(beside.shape[0]):
        extra[lim.shape[0] + i] = beside[i] % TWO_PI
    th, cs, sn = scan_angles(n_scan, np.sort(extra))
    n = th.shape[0]
    on = np.empty(n, dtype=np.bool_)
    for i in range(n):
        on[i] = _ahead_cs(cs[i], sn[i], vx, vy, lift)
    for i0 in range(0, n, BLOCK):
        i1 = min(i0 + BLOCK, n) - 1
        if not on[i0:i1 + 1].any():
            continue  # off the front's closed-form part
        state = block_state(th[i0], th[i1], ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems) \
            if i1 > i0 else -1
        for i in range(i0, i1 + 1):
            if not on[i]:
                continue
            if state == 0:
                on[i] = False
            elif state == 1:
                on[i] = _past_own_turns(S, P, R, ex + r * cs[i], ey + r * sn[i], pz, eps)
            else:
                on[i] = _engaged_cs(cs[i], sn[i], vx, vy, lift, S, P, R, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps,
                                    G, gstart, gitems)
    out = np.empty((n, 4))
    out[:, 2:] = ENGAGED
    if on.all():
        out[0, 0], out[0, 1] = 0.0, TWO_PI
        return out[:1]
    if not on.any():
        return out[:0]
    # the changes between neighbours (cyclic), each bisected: rises start an arc, falls end one
    starts = np.empty(n)
    ends = np.empty(n)
    start_causes = np.empty(n)
    end_causes = np.empty(n)
    ns = 0
    ne = 0
    for i in range(n):
        j = (i + 1) % n
        if on[i] == on[j]:
            continue
        a = th[i]
        b = th[j] if j > i else th[j] + TWO_PI
        for _ in range(60):
            if b - a <= ANGLE_TOL:
                break
            m = 0.5 * (a + b)
            if _engaged(m % TWO_PI, vx, vy, lift, S, P, R, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart,
                        gitems) == on[i]:
                a = m
            else:
                b = m
        edge = (0.5 * (a + b)) % TWO_PI
        cause = end_cause((b if on[i] else a) % TWO_PI, (a if on[i] else b) % TWO_PI, vx, vy, lift, S, P, R, ex, ey,
                          pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems)
        if on[i]:
            ends[ne] = edge
            end_causes[ne] = cause
            ne += 1
        else:
            starts[ns] = edge
            start_causes[ns] = cause
            ns += 1
    # a start within GAP_TOL after an end closes a gap of a touching point (the tool's circle tangent
    # to a face of the stock or to an earlier sweep's wall): the arcs are one
    keep_s = np.ones(ns, dtype=np.bool_)
    keep_e = np.ones(ne, dtype=np.bool_)
    for i in range(ns):
        for j in range(ne):
            if keep_e[j] and (starts[i] - ends[j]) % TWO_PI < GAP_TOL:
                keep_s[i] = False
                keep_e[j] = False
                break
    if not keep_s.any():
        out[0, 0], out[0, 1] = 0.0, TWO_PI
        return out[:1]
    # pair each start with the first end after it (counter-clockwise)
    k = 0
    for i in range(ns):
        if not keep_s[i]:
            continue
        best = 10.0
        cause = ENGAGED
        for j in range(ne):
            span = (ends[j] - starts[i]) % TWO_PI
            if keep_e[j] and span < best:
                best = span
                cause = end_causes[j]
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = starts[i], best, start_causes[i], cause
        k += 1
    return out[:k]


@njit(cache=True)
def material_margin(px, py, pz, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems):
    """How deep (mm) the point lies in the material before the CL: the least distance to a stock
    face, height below an earlier sweep's lower surface and distance inside a round bar's side (less
    ``eps``); <= 0 where there is none.
    Only the sweeps of the point's grid cell are looked at (:func:`sweep_grid`)."""
    m = min(px - stock[0], stock[3] - px, py - stock[1], stock[4] - py, pz - stock[2], stock[5] - pz)
    first, end = _cell(px, py, G, gstart)
    for q in range(first, end):
        j = gitems[q]
        if m <= 0.0:
            return m
        if px < CB[j, 0] - eps or px > CB[j, 2] + eps or py < CB[j, 1] - eps or py > CB[j, 3] + eps:
            continue
        if C[j, 0] == OUTSIDE:  # a round bar's side: the distance to it
            m = min(m, C[j, 9] - eps - math.hypot(px - C[j, 7], py - C[j, 8]))
            continue
        if C[j, 3] - eps - pz >= m and C[j, 6] - eps - pz >= m:
            continue  # its lower surface is nowhere below its path's lowest tip
        k = int(C[j, 12])
        if sweep_floor(C[j], PP[k, :NPC[k]], RR[k], px, py, eps) - eps - pz >= m:
            continue
        h = sweep_lower(C[j], PP[k, :NPC[k]], RR[k], px, py, eps) - eps - pz
        if h < m:
            m = h
    return m


@njit(cache=True, inline="always")
def _margin_at(t, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems):
    return material_margin(ex + r * math.cos(t), ey + r * math.sin(t), pz, C, CB, PP, NPC, RR, stock, eps, G, gstart,
                           gitems)


@njit(cache=True)
def slice_margin(S, P, R, zs, r, drho, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems, n_scan):
    """The slice ``zs`` mm above the tip holds an engaged point where this is positive (mm): the
    material margin's maximum over the front arc (sampled at ``n_scan`` angles a turn; where no
    sample is positive, the local maxima refined by golden section to ~1e-12 rad), for an arc only
    at points on its sweep's front; -inf where the slice has no front."""
    ex, ey, ez = S[4], S[5], S[6]
    vx, vy, vz = end_velocity(S)
    lift = 0.0 if vz == 0.0 else drho * vz
    pz = ez + zs
    lim = front_limits(vx, vy, lift)
    h = math.sqrt(vx * vx + vy * vy)
    if lim.shape[0] == 2:
        t0 = lim[0]
        t1 = lim[1] if lim[1] > lim[0] else lim[1] + TWO_PI
    elif lift <= -h:
        t0, t1 = 0.0, TWO_PI  # all round: a plunge, or steeply down
    else:
        return -math.inf  # no front: the tool moves up faster than its flank rises
    n = max(8, int(math.ceil((t1 - t0) / TWO_PI * n_scan)))
    ts = np.empty(n + 1)
    ms = np.empty(n + 1)
    for i in range(n + 1):
        ts[i] = t0 + (t1 - t0) * i / n
        ms[i] = _margin_at(ts[i], ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems)
    best = -math.inf
    for i in range(n + 1):
        if ms[i] > best and (S[0] == 0.0 or _front_at(ts[i] % TWO_PI, vx, vy, lift, S, P, R, ex, ey, pz, r, eps)):
            best = ms[i]
    if best > 0.0:
        return best
    for i in range(n + 1):
        if (i > 0 and ms[i] < ms[i - 1]) or (i < n and ms[i] < ms[i + 1]):
            continue
        if i > 0 and ms[i] == ms[i - 1] and (i == n or ms[i] == ms[i + 1]):
            continue  # inside a plateau: its ends are refined
        a = ts[max(i - 1, 0)]
        b = ts[min(i + 1, n)]
        c = b - GOLDEN * (b - a)
        d = a + GOLDEN * (b - a)
        fc = _margin_at(c, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems)
        fd = _margin_at(d, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems)
        for _ in range(48):
            if fc >= fd:
                b, d, fd = d, c, fc
                c = b - GOLDEN * (b - a)
                fc = _margin_at(c, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems)
            else:
                a, c, fc = c, d, fd
                d = a + GOLDEN * (b - a)
                fd = _margin_at(d, ex, ey, pz, r, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems)
        t = c if fc >= fd else d
        v = max(fc, fd)
        if v > best and (S[0] == 0.0 or _front_at(t % TWO_PI, vx, vy, lift, S, P, R, ex, ey, pz, r, eps)):
            best = v
            if best > 0.0:
                return best
    return best


def contact_range(args: tuple, bottom: float, top: float, dz: float, levels: list[float]
                  ) -> tuple[float, float] | None:
    """The height range (mm above the tip) between ``bottom`` and ``top`` where the tool at the end
    of ``args``' sweep touches material (``args`` as :func:`.contact.slice_arcs` takes them, less the
    height, radius, slope and scan count: its first 13), or None: the flutes' contact with ``(0, flute
    length)``, the shank's with ``(flute length, inf)``.

    The candidate heights are every quarter of ``dz`` and just above and below each machine height
    of ``levels`` (the stock's top, the earlier sweeps' ends), within the range and the stock's
    height. The lowest touching candidate is found walking up from the bottom, the highest walking
    down from the top (the heights between them are not tested; on a line's wall, the candidates within
    a slice's negative margin below it are passed over); the change from its untouched
    neighbour is found to :data:`Z_TOL` by the Illinois variant of regula falsi on the slice's
    material margin (:func:`.contact.slice_margin`, positive where it touches), every fourth step
    a halving so that the bracket shrinks however the margin bends, and a halving too where an
    end's margin is round-off (within :data:`MARGIN_NOISE` of 0, not 0: flat below a tangential
    onset). That is the place where the margin's maximum over the slice, as found, changes sign:
    where the contact ends on a tangency whose margin peaks as a square root of the angle (a helical
    bore's last touch of the turn before), the peak found to ~1e-12 rad is ~1e-6 mm low, and so is
    the height."""
    row, pieces, stock = args[0], args[1], args[8]
    ez = row[6]
    seen: dict[float, float] = {}

    def margin(zs: float) -> float:
        if zs not in seen:
            r = profile_radius(pieces, zs)
            seen[zs] = -math.inf if r <= 0 else float(
                slice_margin(row, pieces, args[2], zs, r, profile_radius_slope(pieces, zs), *args[3:13],
                             N_TOUCH))
        return seen[zs]

    def touches(zs: float) -> bool:
        return margin(zs) > 0.0

    end = min(top, stock[5] - ez + 1e-7)  # no material above the stock's top
    if end <= bottom:
        return None
    zs = {min(bottom + 1e-9, end), end}
    step = dz / 4
    zs.update(bottom + step * k for k in range(1, math.ceil((end - bottom) / step)))
    for level in levels:
        for z in (level - ez - 1e-7, level - ez + 1e-7):
            if bottom < z < end:
                zs.add(z)
    grid = sorted(z for z in zs if z > stock[2] - ez - 1e-7)  # nor below its bottom
    first = next((i for i, z in enumerate(grid) if touches(z)), None)
    if first is None:
        return None
    # above the profile (the tool's wall) a line's slices are one circle and one front, and each point's margin
    # grows by no more than the height drops (its lower surfaces and the stock's faces do not move with it):
    # below a slice there of margin -m no slice within m holds material, and its candidates are passed over
    wall = profile_height(pieces, args[2]) if row[0] == LINE else math.inf
    last = len(grid) - 1
    while last > first:
        m = margin(grid[last])
        if m > 0.0:
            break
        below = last - 1
        if grid[last] >= wall and math.isfinite(m):
            while below > first and grid[below] >= wall and grid[below] >= grid[last] + m:
                below -= 1
        last = below

    def edge(a: float, b: float) -> float:
        fa, fb = margin(a), margin(b)
        kept = 0  # +1: the last step moved b, -1: it moved a
        for k in range(200):
            if b - a <= Z_TOL:
                break
            x = 0.5 * (a + b)
            if k % 4 != 3 and math.isfinite(fa) and math.isfinite(fb) and fa != fb:
                near = min(abs(fa), abs(fb))  # the chord crosses 0 nearest the end of least margin
                if near == 0.0 or near > MARGIN_NOISE:  # else that margin is round-off: halve
                    x = min(max(a - fa * (b - a) / (fb - fa), a + 0.25 * Z_TOL), b - 0.25 * Z_TOL)
            fx = margin(x)
            if (fx > 0.0) == (fa > 0.0):
                a, fa = x, fx
                fb = 0.5 * fb if kept < 0 else fb  # Illinois: an end kept twice has its value halved
                kept = -1
            else:
                b, fb = x, fx
                fa = 0.5 * fa if kept > 0 else fa
                kept = 1
        return 0.5 * (a + b)

    if first == 0 and grid[0] <= bottom + 1e-9:
        lo = bottom  # touching from the range's bottom
    else:
        lo = edge(grid[first - 1] if first else bottom, grid[first])
    if last == len(grid) - 1 and end >= top:
        hi = top  # touching up to the range's top
    else:
        hi = edge(grid[last], grid[last + 1] if last + 1 < len(grid) else end + 1e-7)
    return (lo, hi)
