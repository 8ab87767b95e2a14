"""Which earlier sweeps can shape a CL's removed height over a cell of its footprint.

Machine frame, mm. A cell is an axis-aligned rectangle (x0, y0, x1, y1). Over a cell the removed
height ``max(0, min(h, top) - max(L, bottom))`` (:mod:`.volume`) depends only on the earlier sweeps
that can be the least lower surface ``h`` somewhere in it. Two closed-form bounds decide that:

* a sweep's **floor** over the cell: the lowest tip of the part of its path that can reach the cell
  (a line's whole path; an arc's angles within reach of the cell's circumscribed circle) plus ``f``
  at the least XY distance between the cell and its path (for an arc, between the cell and the
  arc's whole circle), a lower bound of its lower surface there (``f`` grows outward); inf where the
  cell is beyond its footprint;
* a sweep's **ceiling** over a cell inside its footprint. A line's (every corner within ``R`` of its
  path: the footprint is convex): the most of its lower surface at the corners; its lower surface
  is convex in (x, y) (see :func:`.volume._nothing_removed`), so that is its maximum over the cell.
  An arc's: the least over a few tool positions ``t`` whose reach holds the whole cell of
  ``z(t) + f(the farthest corner's distance)``, an upper bound (the lower surface is at most any
  one position's, and the distance to a point is largest at a corner); inf where none holds it.
  A vertical arc's (:mod:`.vertical`) the same over its two ends; its floor is a line's between its
  ends (its XY path is that segment, its lowest tip the lower end).

A stock's outside (:func:`.sweeps.outside_row`) has both in closed form: its height ``z0`` where the
cell reaches beyond its circle (floor) or lies wholly beyond it (ceiling), else inf.

With ``U`` the least of the stock's top and the ceilings, ``h`` (capped by the top) is at most ``U``
all over the cell: a sweep whose floor is at least ``U`` never lowers it and is left out (the sweep
that gives ``U`` is kept). Where the CL's own floor over the cell reaches ``U``, nothing is removed
in it. Among many sweeps left, one is also left out where a single other one lies under it wherever
it reaches: its footprint holds the first's whole footprint and its **top** (the highest its lower
surface gets: its path's highest tip plus ``f(R)``) is at most the first's floor (a helix retraced
deeper, a pass repeated lower). A cell still met by many sweeps is quartered
(:func:`relevant_sweeps` says which are left). The same holding decides a whole CL at once: where
an earlier sweep holds the CL's whole footprint with its top at or below the CL's lowest tip (a
pass retraced above a deeper one, a lead-in run again higher up, a contour's spring pass; a line in a
line, an arc in an arc about the same centre), or where the CL goes over part of an earlier sweep's
path at or above it with the same tool (a helical entry or a ramp run again), ``h`` is nowhere above
the CL's lower surface and it removes nothing (:func:`held_below`). An earlier sweep holding the CL's
whole footprint bounds ``h`` wherever the CL removes anything, by its top or, for an arc of a turn or
more, by its lowest turn's highest tip plus ``f(R)`` (:func:`footprint_ceiling`): that bound caps a
cell's sweeps as a ceiling over the cell does, where the cell reaches beyond the holder's footprint
(a helix's earlier turns under a bore's disc-shaped footprint).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.profile import is_flat, profile_height
from fusioncut.engines.analytic.sweeps import (ARC, OUTSIDE, angle_windows, lowest_turn_top, point_segment_distance,
                                               sweep_lower, window_span)
from fusioncut.engines.analytic.vertical import is_vertical


DOMINANCE_MOST = 48  # sweeps: a caller that quarters a cell left with more passes this as relevant_sweeps' `most`
# (the O(n²) search for dominated sweeps is then left to the quarters)
BOX_SLACK = 1e-9  # mm: how far a held footprint's box may reach beyond its holder's in _undominated's
# pre-test (the boxes are rounded; the test proper is _holds)
EDGE_REL = 1e-12  # of the radius: a corner this close to a line's footprint's edge is taken as outside it in
# cell_ceiling (sweep_lower decides points on the edge by its own round-off)
HOLD_TOL = 1e-12  # mm: how far a held sweep's path may reach beyond its holder's in held_below (the
# rounding of a CL piece's radius, of a merged circle's turns)


@njit(cache=True)
def _point_distance(x0, y0, x1, y1, px, py):
    """XY distance (mm) from (px, py) to the rectangle (0 inside it)."""
    dx = max(x0 - px, 0.0, px - x1)
    dy = max(y0 - py, 0.0, py - y1)
    return math.sqrt(dx * dx + dy * dy)


@njit(cache=True)
def _farthest_corner(x0, y0, x1, y1, px, py):
    """XY distance (mm) from (px, py) to the rectangle's farthest corner."""
    dx = max(px - x0, x1 - px)
    dy = max(py - y0, y1 - py)
    return math.sqrt(dx * dx + dy * dy)


@njit(cache=True)
def _segment_meets(x0, y0, x1, y1, ax, ay, bx, by):
    """Whether the segment from (ax, ay) to (bx, by) meets the rectangle (Liang-Barsky clipping)."""
    t0, t1 = 0.0, 1.0
    dx, dy = bx - ax, by - ay
    for p, q in ((-dx, ax - x0), (dx, x1 - ax), (-dy, ay - y0), (dy, y1 - ay)):
        if p == 0.0:
            if q < 0.0:
                return False
            continue
        r = q / p
        if p < 0.0:
            t0 = max(t0, r)
        else:
            t1 = min(t1, r)
        if t0 > t1:
            return False
    return True


@njit(cache=True)
def path_distance(S, x0, y0, x1, y1):
    """A lower bound (mm) of the XY distance between the rectangle and the sweep's path: exact for
    a line and a vertical arc (0 where they meet, else the least of its ends' distances to the
    rectangle and the corners' to it), for an XY arc the distance to its whole circle."""
    if S[0] != ARC:
        ax, ay, bx, by = S[1], S[2], S[4], S[5]
        if _segment_meets(x0, y0, x1, y1, ax, ay, bx, by):
            return 0.0
        d = min(_point_distance(x0, y0, x1, y1, ax, ay), _point_distance(x0, y0, x1, y1, bx, by))
        for cx, cy in ((x0, y0), (x1, y0), (x0, y1), (x1, y1)):
            d = min(d, point_segment_distance(cx, cy, ax, ay, bx, by))
        return d
    cx, cy, rho = S[7], S[8], S[9]
    near = _point_distance(x0, y0, x1, y1, cx, cy)
    far = _farthest_corner(x0, y0, x1, y1, cx, cy)
    if rho < near:
        return near - rho
    if rho > far:
        return rho - far
    return 0.0


@njit(cache=True)
def _arc_low_tip(S, x0, y0, x1, y1, reach):
    """The lowest tip height (mm) of an arc sweep's path over the angles whose points lie within
    ``reach`` of the rectangle's circumscribed circle; inf where none does."""
    mx, my = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    rr = reach + 0.5 * math.sqrt((x1 - x0) ** 2 + (y1 - y0) ** 2)
    qx, qy = mx - S[7], my - S[8]
    Q, rho, sw = math.sqrt(qx * qx + qy * qy), S[9], S[11]
    if Q * rho <= 1e-12:
        return min(S[3], S[6]) if abs(Q - rho) <= rr else math.inf
    kappa = (rho * rho + Q * Q - rr * rr) / (2.0 * rho * Q)
    if kappa > 1.0:
        return math.inf
    if kappa <= -1.0:
        return min(S[3], S[6])
    w = math.acos(kappa)
    b0 = S[10] - math.atan2(qy, qx)
    lo, hi = min(b0, b0 + sw), max(b0, b0 + sw)
    best = math.inf
    k0, k1 = angle_windows(lo, hi, w)
    for k in range(k0, k1 + 1):
        ta, tb = window_span(k, lo, hi, w, b0, sw)
        if ta <= tb:
            for t in (ta, tb):  # z is linear in t: lowest at an end of the window
                best = min(best, S[3] + t * (S[6] - S[3]))
    return best


@njit(cache=True)
def cell_floor(S, P, R, x0, y0, x1, y1, eps):
    """A lower bound (mm) of the sweep's lower surface over the rectangle; inf beyond its footprint
    widened by ``eps``."""
    if S[0] == OUTSIDE:
        return S[3] if _farthest_corner(x0, y0, x1, y1, S[7], S[8]) >= S[9] - eps else math.inf
    if S[0] != ARC:  # a line's (a vertical arc's) footprint lies within its ends' box widened by R
        reach = R + eps
        if (min(S[1], S[4]) - reach > x1 or max(S[1], S[4]) + reach < x0 or min(S[2], S[5]) - reach > y1
                or max(S[2], S[5]) + reach < y0):
            return math.inf
    d = path_distance(S, x0, y0, x1, y1)
    if d > R + eps:
        return math.inf
    low = _arc_low_tip(S, x0, y0, x1, y1, R + eps) if S[0] == ARC else min(S[3], S[6])
    return low + profile_height(P, min(d, R))


@njit(cache=True)
def _arc_ceiling_at(S, P, R, x0, y0, x1, y1, t):
    """``z(t) + f(the farthest corner's distance)`` for the arc sweep's tool at ``t`` (mm), where its
    reach holds the whole rectangle; inf where it does not."""
    a = S[10] + t * S[11]
    far = _farthest_corner(x0, y0, x1, y1, S[7] + S[9] * math.cos(a), S[8] + S[9] * math.sin(a))
    if far > R:
        return math.inf
    return S[3] + t * (S[6] - S[3]) + profile_height(P, far)


@njit(cache=True)
def _arc_ceiling(S, P, R, x0, y0, x1, y1):
    """An upper bound (mm) of an arc sweep's lower surface over a rectangle (module docstring): the
    tool positions looked at are the path's ends and where it passes the direction of the
    rectangle's centre (each turn)."""
    best = min(_arc_ceiling_at(S, P, R, x0, y0, x1, y1, 0.0), _arc_ceiling_at(S, P, R, x0, y0, x1, y1, 1.0))
    sw = S[11]
    b0 = S[10] - math.atan2(0.5 * (y0 + y1) - S[8], 0.5 * (x0 + x1) - S[7])
    lo, hi = min(b0, b0 + sw), max(b0, b0 + sw)
    for k in range(int(math.ceil(lo / (2.0 * math.pi))), int(math.floor(hi / (2.0 * math.pi))) + 1):
        best = min(best, _arc_ceiling_at(S, P, R, x0, y0, x1, y1, (2.0 * math.pi * k - b0) / sw))
    return best


@njit(cache=True)
def cell_ceiling(S, P, R, x0, y0, x1, y1):
    """An upper bound (mm) of the sweep's lower surface over a rectangle inside its footprint (a
    line's: its maximum there); inf where none is known (module docstring)."""
    if S[0] == OUTSIDE:
        return S[3] if _point_distance(x0, y0, x1, y1, S[7], S[8]) >= S[9] else math.inf
    if S[0] == ARC:
        return _arc_ceiling(S, P, R, x0, y0, x1, y1)
    if is_vertical(S):  # the tool at either end, where its reach holds the whole rectangle
        best = math.inf
        for ex, ey, ez in ((S[1], S[2], S[3]), (S[4], S[5], S[6])):
            far = _farthest_corner(x0, y0, x1, y1, ex, ey)
            if far <= R:
                best = min(best, ez + profile_height(P, far))
        return best
    if (x0 < min(S[1], S[4]) - R or x1 > max(S[1], S[4]) + R or y0 < min(S[2], S[5]) - R
            or y1 > max(S[2], S[5]) + R):
        return math.inf  # a corner beyond the footprint's box
    level_flat = S[3] == S[6] and is_flat(P)  # its lower surface is S[3] all over its footprint
    top = -math.inf
    for cx, cy in ((x0, y0), (x1, y0), (x0, y1), (x1, y1)):
        if point_segment_distance(cx, cy, S[1], S[2], S[4], S[5]) > R * (1.0 - EDGE_REL):
            return math.inf  # beyond the footprint, or on its edge, where the lower surface may round to inf
        if not level_flat:
            top = max(top, sweep_lower(S, P, R, cx, cy, 0.0))
    return S[3] if level_flat else top


@njit(cache=True)
def _holds(A, RA, B, RB, tol=0.0):
    """Whether line sweep ``A``'s footprint (radius ``RA``) holds line sweep ``B``'s (``RB``): both
    ends of B's path within ``RA - RB`` (+ ``tol``, mm) of A's (the distance to A's path is convex
    along B's)."""
    if A[0] != 0.0 or B[0] != 0.0 or RB > RA:
        return False
    room = RA - RB + tol
    return (point_segment_distance(B[1], B[2], A[1], A[2], A[4], A[5]) <= room
            and point_segment_distance(B[4], B[5], A[1], A[2], A[4], A[5]) <= room)


@njit(cache=True)
def _top(C, j, PP, NPC, RR):
    """The highest the lower surface of sweep ``C[j]`` gets (mm): its path's highest tip plus ``f(R)``."""
    k = int(C[j, 12])
    return max(C[j, 3], C[j, 6]) + profile_height(PP[k, :NPC[k]], RR[k])


@njit(cache=True)
def _holds_arc(A, RA, B, RB):
    """Whether arc sweep ``A``'s footprint (radius ``RA``) holds arc sweep ``B``'s (``RB``), to
    :data:`HOLD_TOL` mm: about the same centre, every point of B's path within ``RA - RB`` of A's
    path. B's angles are taken from where they start within A's (a turn or more of A holds every
    angle); those beyond A's end lie within ``|rho_A - rho_B| + 2 rho_B sin(gap / 2)`` of it (the
    turns of a merged circle add up to 2 pi only to rounding)."""
    room = RA - RB + HOLD_TOL
    if A[0] != 1.0 or B[0] != 1.0 or A[7] != B[7] or A[8] != B[8] or abs(A[9] - B[9]) > room:
        return False
    if abs(A[11]) >= 2.0 * math.pi:
        return True
    a_lo, a_hi = min(A[10], A[10] + A[11]), max(A[10], A[10] + A[11])
    b_lo, b_hi = min(B[10], B[10] + B[11]), max(B[10], B[10] + B[11])
    turns = math.floor((b_lo - a_lo) / (2.0 * math.pi))
    gap = max(b_hi - 2.0 * math.pi * turns - a_hi, 0.0)
    return gap < math.pi and abs(A[9] - B[9]) + 2.0 * B[9] * math.sin(0.5 * gap) <= room


@njit(cache=True)
def _line_z_under(A, px, py):
    """The least tip height (mm) of line sweep ``A``'s positions at (px, py), or inf where its path
    passes farther than :data:`HOLD_TOL` from there (a vertical path stands on one point)."""
    ux, uy = A[4] - A[1], A[5] - A[2]
    n2 = ux * ux + uy * uy
    if n2 == 0.0:
        return min(A[3], A[6]) if math.hypot(px - A[1], py - A[2]) <= HOLD_TOL else math.inf
    u = min(max(((px - A[1]) * ux + (py - A[2]) * uy) / n2, 0.0), 1.0)
    if math.hypot(A[1] + u * ux - px, A[2] + u * uy - py) > HOLD_TOL:
        return math.inf
    return A[3] + u * (A[6] - A[3])


@njit(cache=True)
def _retraces(A, B):
    """Whether sweep ``B`` goes over part of sweep ``A``'s path at or above it: the same tool, and
    each of B's tool positions over one of A's at the same XY (to :data:`HOLD_TOL` mm) and no lower.
    Then B's lower surface is nowhere below A's (a minimum over positions each at or above one of
    A's), so B removes nothing A left. Both heights are linear along the shared path, so B's ends
    decide: on a line, both on A's path; on an arc, about the same centre and radius, B's angles
    within A's a whole number of turns on (each turn of a helix tried)."""
    if A[0] != B[0] or A[12] != B[12]:
        return False
    if A[0] == 0.0:
        return (_line_z_under(A, B[1], B[2]) <= B[3] + HOLD_TOL
                and _line_z_under(A, B[4], B[5]) <= B[6] + HOLD_TOL)
    if (A[0] != 1.0 or A[11] == 0.0 or abs(A[7] - B[7]) > HOLD_TOL or abs(A[8] - B[8]) > HOLD_TOL
            or abs(A[9] - B[9]) > HOLD_TOL):
        return False
    slack = HOLD_TOL / max(A[9], HOLD_TOL)  # rad
    a_lo, a_hi = min(A[10], A[10] + A[11]), max(A[10], A[10] + A[11])
    (b_lo, z_lo), (b_hi, z_hi) = sorted(((B[10], B[3]), (B[10] + B[11], B[6])))
    for k in range(math.ceil((a_lo - b_lo - slack) / (2.0 * math.pi)),
                   math.floor((a_hi - b_hi + slack) / (2.0 * math.pi)) + 1):
        shift = 2.0 * math.pi * k
        za_lo = A[3] + (b_lo + shift - A[10]) / A[11] * (A[6] - A[3])
        za_hi = A[3] + (b_hi + shift - A[10]) / A[11] * (A[6] - A[3])
        if za_lo <= z_lo + HOLD_TOL and za_hi <= z_hi + HOLD_TOL:
            return True
    return False


@njit(cache=True)
def footprint_ceiling(C, j, PP, NPC, RR, S, R):
    """An upper bound (mm) of sweep ``C[j]``'s lower surface over the whole footprint of sweep ``S``
    (radius ``R``), where ``C[j]``'s footprint holds it (a line's a line's, an arc's an arc's about the
    same centre: :func:`_holds`, :func:`_holds_arc`); inf where it does not. Its top
    (:func:`_top`), or for an arc of a turn or more its lowest turn's highest tip plus ``f(R_j)``: that
    turn passes over every point within ``R_j`` of its circle, which holds ``S``'s footprint
    (:func:`.sweeps.lowest_turn_top`)."""
    if C[j, 0] != S[0] or (S[0] != 0.0 and S[0] != 1.0):
        return math.inf
    k = int(C[j, 12])
    rj = RR[k]
    if S[0] == 0.0:
        return _top(C, j, PP, NPC, RR) if _holds(C[j], rj, S, R, HOLD_TOL) else math.inf
    if not _holds_arc(C[j], rj, S, R):
        return math.inf
    if abs(C[j, 11]) < 2.0 * math.pi:
        return _top(C, j, PP, NPC, RR)
    return lowest_turn_top(C[j]) + profile_height(PP[k, :NPC[k]], rj)


@njit(cache=True)
def footprint_ceilings(S, R, C, PP, NPC, RR):
    """:func:`footprint_ceiling` of each row of ``C`` over ``S``'s footprint (mm; inf where unknown)."""
    out = np.empty(C.shape[0])
    for j in range(C.shape[0]):
        out[j] = footprint_ceiling(C, j, PP, NPC, RR, S, R)
    return out


@njit(cache=True)
def held_below(S, R, C, PP, NPC, RR):
    """Whether an earlier sweep of ``C`` holds the whole footprint of sweep ``S`` (radius ``R``; a
    line by a line, an arc by an arc about the same centre) with its lower surface there at or below
    ``S``'s lowest tip (:func:`footprint_ceiling`), or ``S`` retraces part of its path at or above it
    (:func:`_retraces`): then the CL removes nothing (module docstring)."""
    if S[0] != 0.0 and S[0] != 1.0:
        return False
    low = min(S[3], S[6])
    for j in range(C.shape[0]):
        if C[j, 0] != S[0]:
            continue
        rj = RR[int(C[j, 12])]
        if R <= rj and _retraces(C[j], S):
            return True
        if footprint_ceiling(C, j, PP, NPC, RR, S, R) <= low:
            return True
    return False


@njit(cache=True)
def _undominated(C, PP, NPC, RR, keep, floors):
    """``keep`` less the sweeps another kept line sweep lies under wherever they reach (module
    docstring); of two equal ones the later is left out."""
    n = C.shape[0]
    top = np.empty(n)
    box = np.empty((n, 4))
    for j in range(n):
        top[j] = _top(C, j, PP, NPC, RR)
        r = RR[int(C[j, 12])]
        box[j, 0], box[j, 1] = min(C[j, 1], C[j, 4]) - r, min(C[j, 2], C[j, 5]) - r
        box[j, 2], box[j, 3] = max(C[j, 1], C[j, 4]) + r, max(C[j, 2], C[j, 5]) + r
    out = keep.copy()
    by_top = np.argsort(top)
    for j in range(n):
        if not keep[j] or C[j, 0] != 0.0:
            continue
        kj = int(C[j, 12])
        for i in by_top:
            if top[i] > floors[j]:
                break  # the rest are higher still
            if i == j or not out[i]:
                continue
            if top[i] == floors[j] and top[j] == top[i] and i > j:
                continue  # equal ones: the earlier is the one kept
            if (box[i, 0] > box[j, 0] + BOX_SLACK or box[i, 1] > box[j, 1] + BOX_SLACK
                    or box[i, 2] < box[j, 2] - BOX_SLACK or box[i, 3] < box[j, 3] - BOX_SLACK):
                continue  # a footprint holding another holds its box
            ki = int(C[i, 12])
            if _holds(C[i], RR[ki], C[j], RR[kj]):
                out[j] = False
                break
    return out


@njit(cache=True)
def relevant_sweeps(x0, y0, x1, y1, S, P, R, C, PP, NPC, RR, zb, zt, eps, many, most, foot):
    """(whether the CL ``S`` can remove nothing in the rectangle, the mask of the rows of ``C`` that
    can give ``h`` in it, their floors (mm)), as the module docstring says; footprints widened by
    ``eps`` (mm) for the floors, as :func:`.contact.material_at` widens them. Where more than
    ``many`` and at most ``most`` are left, the dominated ones are left out too (O(n²): a caller that
    quarters a cell left with more than ``many`` passes a ``most`` that spares it this for the
    hundreds of sweeps a wide cell of an adaptive clearing meets). ``foot``: per row, a bound of its
    lower surface over ``S``'s footprint (:func:`footprint_ceilings`), which caps ``h`` wherever the
    CL can remove anything, as a ceiling over the whole cell does (a helix's earlier turns under a cell
    that reaches beyond them); empty where none is given (the contact's points may lie outside it)."""
    n = C.shape[0]
    keep = np.zeros(n, dtype=np.bool_)
    floors = np.full(n, math.inf)
    cap = zt
    capper = -1
    for j in range(n):
        k = int(C[j, 12])
        floors[j] = cell_floor(C[j], PP[k, :NPC[k]], RR[k], x0, y0, x1, y1, eps)
        if floors[j] < cap:
            c = cell_ceiling(C[j], PP[k, :NPC[k]], RR[k], x0, y0, x1, y1)
            if foot.shape[0] > 0:
                c = min(c, foot[j])
            if c < cap:
                cap = c
                capper = j
    count = 0
    for j in range(n):
        keep[j] = floors[j] < cap or j == capper
        count += keep[j]
    if many < count <= most:
        keep = _undominated(C, PP, NPC, RR, keep, floors)
    own = max(zb, cell_floor(S, P, R, x0, y0, x1, y1, 0.0))
    return own >= cap, keep, floors
