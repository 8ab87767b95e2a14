"""Sweeps of a tool of revolution along a line, an XY arc / helix or a vertical arc: their lower surface, exactly.

Machine frame, mm, radians. A sweep is one float64 row of :data:`SWEEP_COLUMNS`:

* ``kind`` 0, a line from ``(x0, y0, z0)`` to ``(x1, y1, z1)``: ``c(t) = start + t (end - start)``;
* ``kind`` 1, an XY arc or helix of radius ``rho`` about ``(cx, cy)``: ``c(t) = (cx + rho cos a(t),
  cy + rho sin a(t), z0 + t (z1 - z0))`` with ``a(t) = a0 + t sw`` (``sw`` signed, > 0
  counter-clockwise); the row's ``x1, y1`` is the arc's end;
* ``kind`` 2, **the stock's outside**: a round bar stock is its box less what lies outside its
  circle of radius ``rho`` about ``(cx, cy)``, taken as cut before the first CL: a sweep whose
  lower surface is ``z0`` (below the stock's bottom) wherever ``|p - (cx, cy)| >= rho - eps`` and
  inf inside (its wall is the bar's side, as a flat end mill's is its own), so that every reader of
  the sweeps sees the bar's side as it sees an earlier pass's wall;
* ``kind`` 3 or 4, an arc in the ZX or YZ plane (G18, G19) within one quarter of its circle
  (:mod:`.vertical`, which has its lower surface): its XY path is the segment between its ends;

``t`` in [0, 1], ``tool`` the index of the tool's lower profile (:mod:`.profile`) in the engine's
table. With the lower profile ``f`` (radius ``R``), the sweep removes every point above its

    lower surface  L(p) = min over t with |p - c(t)| <= R of  z(t) + f(|p - c(t)|)      (xy distances)

and ``L = inf`` outside its footprint. On a line ``z(t) + f(d(t))`` is convex in ``t`` (``d`` is
convex, ``f`` convex and non-decreasing), so its minimum is bracketed by the sign of its
derivative ``g`` and the bracket ``[lo, hi]`` is shrunk (Illinois steps on ``g``, every third step a
bisection) until convexity bounds the value's error, ``min(-g(lo), g(hi)) (hi - lo)``, by
:data:`VALUE_TOL` (closed forms where the derivative keeps a sign, a flat end mill's ramps, and on
level moves: there the lowest tool is the one nearest ``p``; a ball's minimum inside the bracket is
its envelope cylinder's lowest point). On an arc the points within ``R``
form windows of angle around the direction of ``p``; each window is sampled at :data:`ARC_STEP`
rad at most and every sampled local minimum is refined by Brent's method to 1e-10 of its bracket: minima
closer together than the step could merge. A level arc needs none of it: its lowest tool is the one nearest ``p``;
nor does a flat end mill's helix, whose ``z(t) + f`` is linear in ``t`` over a window: lowest at one of its ends.
Nor does a window where the value is convex: there it is minimised as on a line, from its slope.
With ``u`` the angle from the direction of ``p`` (at XY distance ``Q`` from the centre),
``d^2 = A - B cos u`` (``A = rho^2 + Q^2``, ``B = 2 rho Q``), and ``d`` is convex in ``u`` while
``cos u >= min(rho, Q) / max(rho, Q)`` (``d'' >= 0`` iff ``2 A cos u - B cos^2 u - B >= 0``), so then
is ``f(d)`` (``f`` convex, non-decreasing); a round profile's (ball, bull-nose: :func:`_round`)
``f(d) = F(d^2)`` with ``F`` convex and non-decreasing is convex further, while ``cos u >= 0``. Where a
round profile's window within ``R`` reaches beyond that (the path's circle passes round ``p``, ``rho <
R``), its near half is minimised so and its far parts (``cos u <= 0``, where ``d`` grows towards
``u = pi``) by branch and bound on ``min z + f(min d)`` over sub-intervals (:func:`_far_min`); another
profile's window that reaches beyond its convex part is sampled. A helix of more than a turn is lowest
on its last turn going down (first going up): each tool position lies a pitch below the one a turn
before above the same place.

Whether a point lies inside the tool at some position of an arc (:func:`arc_holds`, the front
condition of an arc's own earlier turns) is decided from ``d^2 - rho^2``, convex over each window
within ``cos u >= 0`` where ``rho^2`` is concave (flat, ball, bull-nose): one minimum a window,
bracketed by its slope's sign, no sampling; other tools' windows are sampled as above.

``eps`` (mm) widens the footprint: ``|p - c(t)| <= R + eps`` with ``f`` held at ``f(R)`` beyond
``R``, so that a wall an earlier sweep left exactly where the tool stands now (a retraced pass) is
taken as cut, not as a zero-thickness skin.

The small functions the analytic kernels' inner loops call (here, in :mod:`.profile`, :mod:`.contact`
and :mod:`.volume`) are ``njit(inline="always")``: numba compiles a call to another njit function as
a call, and these run millions of times a CL. Larger ones (``line_lower``, ``arc_lower``) stay calls:
inlined at every call site they multiply the compile time.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.brent import (ARC_STEP, BRENT_STEPS, T_TOL, brent_best, brent_next, brent_start,
                                              brent_take)
from fusioncut.engines.analytic.profile import (is_ball, is_flat, profile_height, profile_radius, profile_radius_slope,
                                                profile_slope)
from fusioncut.engines.analytic.vertical import (YZ_ARC, ZX_ARC, is_vertical, vertical_lower, vertical_positions,
                                                 vertical_velocity, within_quarter)

SWEEP_COLUMNS = ("kind", "x0", "y0", "z0", "x1", "y1", "z1", "cx", "cy", "rho", "a0", "sw", "tool")
NCOL = len(SWEEP_COLUMNS)
LINE, ARC, OUTSIDE = 0.0, 1.0, 2.0
_BISECTIONS = 64
VALUE_TOL = 1e-13  # mm: the error bound of a line sweep's lower surface (module docstring)


def line_row(start, end, tool: int) -> np.ndarray:
    row = np.zeros(NCOL)
    row[0] = LINE
    row[1:4] = start
    row[4:7] = end
    row[12] = tool
    return row


def arc_row(start, end, center, rho: float, a0: float, sw: float, tool: int) -> np.ndarray:
    row = line_row(start, end, tool)
    row[0] = ARC
    row[7], row[8], row[9], row[10], row[11] = center[0], center[1], rho, a0, sw
    return row


def outside_row(center, radius: float, z: float, tool: int) -> np.ndarray:
    """The row of the outside of a round bar of ``radius`` about ``center`` (x, y), its lower surface
    at ``z`` (below the bar's bottom); ``tool`` is any table index (the row's own kernels read none)."""
    row = line_row((center[0], center[1], z), (center[0], center[1], z), tool)
    row[0] = OUTSIDE
    row[7], row[8], row[9] = center[0], center[1], radius
    return row


@njit(cache=True, inline="always")
def lowest_turn_top(S):
    """The highest tip height (mm) on the lowest whole turn of arc sweep ``S`` of a turn or more (the last
    turn going down, the first going up): that turn passes over every point within the tool's radius of
    its circle, so the sweep's lower surface there is at most this plus ``f(R)``."""
    turn = 2.0 * math.pi / abs(S[11])
    return S[3] + (S[6] - S[3]) * (1.0 - turn) if S[6] < S[3] else S[3] + (S[6] - S[3]) * turn


def vertical_row(start, end, s_centre: float, plane_zx: bool, rho: float, a0: float, sw: float,
                 tool: int) -> np.ndarray:
    """The row of a vertical arc from ``start`` (on its circle) to ``end`` (x, y, z, mm): in the ZX plane
    ``y = start's y`` about ``x = s_centre`` (``plane_zx``), else in the YZ plane ``x = start's x`` about
    ``y = s_centre``; angles as in the module docstring."""
    if not within_quarter(a0, sw):
        raise ValueError(f"a vertical arc sweep spans one quarter of its circle at most (angles {a0!r}, {sw!r})")
    row = np.zeros(NCOL)
    row[0] = ZX_ARC if plane_zx else YZ_ARC
    row[1:4] = start
    row[4:7] = end
    row[7], row[8] = (s_centre, start[1]) if plane_zx else (start[0], s_centre)
    row[9], row[10], row[11], row[12] = rho, a0, sw, tool
    return row


@njit(cache=True, inline="always")
def outside_lower(S, px, py, eps):
    """The lower surface of a stock's outside (kind 2, module docstring) at ``p``: ``z0`` at or
    beyond ``rho - eps`` from the centre, inf within."""
    if math.hypot(px - S[7], py - S[8]) >= S[9] - eps:
        return S[3]
    return math.inf


# -- lines ---------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _line_slope(S, P, R, px, py, t):
    """d/dt of z(t) + f(d(t)) on a line (the right derivative where d = 0)."""
    ux, uy = S[4] - S[1], S[5] - S[2]
    dx, dy = S[1] + t * ux - px, S[2] + t * uy - py
    d = math.sqrt(dx * dx + dy * dy)
    dz = S[6] - S[3]
    fp = profile_slope(P, d if d < R else R)  # held at the edge's slope on the eps margin
    if d <= 0.0:
        dd = math.sqrt(ux * ux + uy * uy)
    else:
        dd = (dx * ux + dy * uy) / d
    if dd == 0.0:
        return dz
    return dz + fp * dd


@njit(cache=True, inline="always")
def _line_value(S, P, R, px, py, t):
    dx, dy = S[1] + t * (S[4] - S[1]) - px, S[2] + t * (S[5] - S[2]) - py
    d = math.sqrt(dx * dx + dy * dy)
    return S[3] + t * (S[6] - S[3]) + profile_height(P, d if d < R else R)


@njit(cache=True)
def line_lower(S, P, R, px, py, eps):
    """L(p) of a line sweep (mm); inf outside the footprint widened by ``eps``."""
    ax, ay = S[1], S[2]
    ux, uy = S[4] - ax, S[5] - ay
    qx, qy = px - ax, py - ay
    uu = ux * ux + uy * uy
    Re = R + eps
    if uu < 1e-30:  # a plunge: the lowest tool of the two ends
        if qx * qx + qy * qy > Re * Re:
            return math.inf
        return _line_value(S, P, R, px, py, 0.0 if S[6] >= S[3] else 1.0)
    b = (qx * ux + qy * uy) / uu
    c = (qx * qx + qy * qy - Re * Re) / uu
    disc = b * b - c
    if disc < 0.0:
        return math.inf
    s = math.sqrt(disc)
    lo, hi = max(0.0, b - s), min(1.0, b + s)
    if lo > hi:
        return math.inf
    if S[6] == S[3]:  # level: the tool nearest p is lowest there (f grows outward)
        return _line_value(S, P, R, px, py, min(max(b, lo), hi))
    if _line_slope(S, P, R, px, py, lo) >= 0.0:
        return _line_value(S, P, R, px, py, lo)
    if _line_slope(S, P, R, px, py, hi) <= 0.0:
        return _line_value(S, P, R, px, py, hi)
    if is_ball(P, R):
        # a ball: the minimum inside (lo, hi) lies on the swept sphere's envelope, the cylinder of
        # radius R about the centres' line, whose lowest point above p is below the centre over p's
        # foot on the path by W sqrt(1 + uz^2 / uu), W^2 = R^2 - (p's XY distance from the path)^2,
        # at t = b - uz W / sqrt(uu (uu + uz^2))
        uz = S[6] - S[3]
        cross = qx * uy - qy * ux
        w2 = R * R - cross * cross / uu
        if w2 >= 0.0:
            w = math.sqrt(w2)
            t = b - uz * w / math.sqrt(uu * (uu + uz * uz))
            if lo <= t <= hi:
                return S[3] + R + b * uz - w * math.sqrt(1.0 + uz * uz / uu)
    return _convex_min(S, P, R, px, py, lo, hi)


@njit(cache=True, inline="always")
def _slope(S, P, R, px, py, t):
    """d/dt of z(t) + f(d(t)) on a line or an arc."""
    if S[0] == LINE:
        return _line_slope(S, P, R, px, py, t)
    return _arc_slope(S, P, R, px, py, t)


@njit(cache=True, inline="always")
def _value(S, P, R, px, py, t):
    """z(t) + f(min(d(t), R)) on a line or an arc."""
    if S[0] == LINE:
        return _line_value(S, P, R, px, py, t)
    return _arc_value(0, S, P, R, px, py, 0.0, t)


@njit(cache=True)
def _convex_min(S, P, R, px, py, lo, hi):
    """min of z(t) + f(d(t)) on [lo, hi] where it is convex and its slope goes from < 0 to > 0:
    Illinois steps on the slope (a bisection every third step, or where a slope is infinite), until
    the convexity bound on the value's error is within :data:`VALUE_TOL` or the bracket is a float
    apart."""
    glo = _slope(S, P, R, px, py, lo)
    ghi = _slope(S, P, R, px, py, hi)
    wlo, whi = glo, ghi  # the slopes the secant uses: Illinois halves the one kept twice
    side = 0
    for it in range(2 * _BISECTIONS):
        if min(-glo, ghi) * (hi - lo) <= VALUE_TOL:
            break
        mid = 0.5 * (lo + hi)
        if it % 3 != 2 and math.isfinite(wlo) and math.isfinite(whi):
            m = lo - wlo * (hi - lo) / (whi - wlo)
            if lo < m < hi:
                mid = m
        if mid <= lo or mid >= hi:
            break
        g = _slope(S, P, R, px, py, mid)
        if g < 0.0:
            lo, glo, wlo = mid, g, g
            if side == -1:
                whi *= 0.5
            side = -1
        elif g > 0.0:
            hi, ghi, whi = mid, g, g
            if side == 1:
                wlo *= 0.5
            side = 1
        else:
            return _value(S, P, R, px, py, mid)
    return min(_value(S, P, R, px, py, lo), _value(S, P, R, px, py, hi))


# -- arcs ----------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _arc_value(mode, S, P, R, px, py, pz, t):
    """mode 0: z(t) + f(min(d, R)); mode 1: phi(t) = d(t) - rho(pz - z(t)) (< 0: p strictly inside
    the tool at t)."""
    a = S[10] + t * S[11]
    dx, dy = S[7] + S[9] * math.cos(a) - px, S[8] + S[9] * math.sin(a) - py
    d = math.sqrt(dx * dx + dy * dy)
    z = S[3] + t * (S[6] - S[3])
    if mode == 0:
        return z + profile_height(P, d if d < R else R)
    r = profile_radius(P, pz - z)
    return d - r


@njit(cache=True, inline="always")
def _arc_slope(S, P, R, px, py, t):
    """d/dt of z(t) + f(d(t)) on an arc (the right derivative where d = 0)."""
    a = S[10] + t * S[11]
    ca, sa = math.cos(a), math.sin(a)
    dx, dy = S[7] + S[9] * ca - px, S[8] + S[9] * sa - py
    d = math.sqrt(dx * dx + dy * dy)
    dz = S[6] - S[3]
    speed = S[9] * S[11]  # the tool's XY velocity is speed * (-sin a, cos a)
    dd = abs(speed) if d <= 0.0 else speed * (dy * ca - dx * sa) / d
    if dd == 0.0:
        return dz
    return dz + profile_slope(P, d if d < R else R) * dd


@njit(cache=True)
def _convex_window_min(S, P, R, px, py, ta, tb, tc, td):
    """Least of z(t) + f(d(t)) over a helix window [ta, tb] whose part within reach ``R``, [tc, td]
    inside it (empty: tc > td), the value is convex on (module docstring): its minimum there is
    bracketed by its slope's sign; beyond it, on the footprint's ``eps`` margin, ``f`` is held at
    ``f(R)`` and the value is linear in ``t``: lowest at one of the window's ends."""
    best = min(_arc_value(0, S, P, R, px, py, 0.0, ta), _arc_value(0, S, P, R, px, py, 0.0, tb))
    if tc > td:
        return best
    if _arc_slope(S, P, R, px, py, tc) >= 0.0:
        return min(best, _arc_value(0, S, P, R, px, py, 0.0, tc))
    if _arc_slope(S, P, R, px, py, td) <= 0.0:
        return min(best, _arc_value(0, S, P, R, px, py, 0.0, td))
    return min(best, _convex_min(S, P, R, px, py, tc, td))


@njit(cache=True)
def _bracket_min(mode, S, P, R, px, py, pz, a, x, b, fx):
    """The least value of :func:`_arc_value` found by Brent's minimisation (:func:`brent_next`) in
    [a, b] from its sampled lowest point ``x`` (value ``fx``), until the bracket is :data:`T_TOL`
    (relative to its width at the start) around the best point. Near a smooth minimum the value's
    error is quadratic in that, far below 1e-20 mm; where the value has a corner (a flat bottom's
    edge, the footprint's rim) the golden steps converge linearly on it."""
    st = brent_start(a, x, b, fx, T_TOL * (b - a))
    for _ in range(BRENT_STEPS):
        u = brent_next(st)
        if math.isnan(u):
            break
        brent_take(st, u, _arc_value(mode, S, P, R, px, py, pz, u))
    return brent_best(st)[1]


@njit(cache=True)
def _window_min(mode, S, P, R, px, py, pz, t0, t1):
    """Least value of :func:`_arc_value` over [t0, t1]: sampled, every local minimum refined
    (:func:`_bracket_min`)."""
    span = abs(t1 - t0) * abs(S[11])
    n = max(4, int(math.ceil(span / ARC_STEP)))
    ts = np.empty(n + 1)
    vs = np.empty(n + 1)
    for i in range(n + 1):
        ts[i] = t0 + (t1 - t0) * i / n
        vs[i] = _arc_value(mode, S, P, R, px, py, pz, ts[i])
    best = vs.min()
    for i in range(n + 1):
        if (i > 0 and vs[i] > vs[i - 1]) or (i < n and vs[i] > vs[i + 1]):
            continue
        best = min(best, _bracket_min(mode, S, P, R, px, py, pz, ts[max(i - 1, 0)], ts[i], ts[min(i + 1, n)], vs[i]))
    return best


@njit(cache=True, inline="always")
def angle_windows(lo, hi, w):
    """(k0, k1): the windows of angle ``[2 pi k - w, 2 pi k + w]`` about a point's direction, k0 <= k <=
    k1, that can meet an arc's angles ``[lo, hi]`` measured from it (rad)."""
    return int(math.ceil((lo - w) / (2.0 * math.pi))), int(math.floor((hi + w) / (2.0 * math.pi)))


@njit(cache=True, inline="always")
def window_span(k, lo, hi, w, b0, sw):
    """(ta, tb): the path parameters, within [0, 1], of window ``k``'s part within the arc's angles
    ``[lo, hi]`` (the angle is ``b0 + t sw`` from the point's direction); ta > tb only where it is
    empty (both ends are held within [0, 1], so a window of one angle at the arc's end stays one)."""
    return angle_span(2.0 * math.pi * k - w, 2.0 * math.pi * k + w, lo, hi, b0, sw)


@njit(cache=True, inline="always")
def angle_span(alo, ahi, lo, hi, b0, sw):
    """(ta, tb): the path parameters, within [0, 1], of the angles ``[alo, ahi]`` within ``[lo, hi]``
    (as :func:`window_span`)."""
    blo, bhi = max(lo, alo), min(hi, ahi)
    if blo > bhi:
        return 1.0, 0.0
    ta, tb = (blo - b0) / sw, (bhi - b0) / sw
    if ta > tb:
        ta, tb = tb, ta
    return min(max(ta, 0.0), 1.0), min(max(tb, 0.0), 1.0)


@njit(cache=True)
def _far_min(S, P, R, px, py, ta, tb, best):
    """min(``best``, the least of z(t) + f(min(d(t), R)) over [ta, tb]), a part of an arc's window on
    the far side of the path's circle from the point (cos u <= 0, u the angle from the point's
    direction), by branch and bound. There ``d`` grows towards u = pi, so over any sub-interval it is
    least at an end, and z is linear: the value is at least min(z) + f(min(d)) at its ends, and an
    interval whose bound is not below the best value found is dropped. One wider than
    :data:`ARC_STEP` rad is halved (the value taken at the halving point, the lower-bounded half
    searched first); a narrower one is refined by Brent from the lowest of its ends and midpoint
    (:func:`_bracket_min`, as :func:`_window_min` refines its samples)."""
    if ta > tb:
        return best
    span = abs(S[11])
    dz = S[6] - S[3]
    va = _arc_value(0, S, P, R, px, py, 0.0, ta)
    vb = _arc_value(0, S, P, R, px, py, 0.0, tb)
    best = min(best, va, vb)
    stack = np.empty((64, 4))  # intervals [a, b] with their values at a and b
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = ta, tb, va, vb
    n = 1
    while n > 0:
        n -= 1
        a, b, va, vb = stack[n, 0], stack[n, 1], stack[n, 2], stack[n, 3]
        za, zb = S[3] + a * dz, S[3] + b * dz
        fa, fb = va - za, vb - zb  # f(min(d, R)) at the ends: the least f over [a, b] is the lesser
        if min(za, zb) + min(fa, fb) >= best:
            continue
        m = 0.5 * (a + b)
        vm = _arc_value(0, S, P, R, px, py, 0.0, m)
        best = min(best, vm)
        if (b - a) * span <= ARC_STEP or n + 2 > stack.shape[0]:  # a leaf, or no room left for two halves
            x, fx = (m, vm) if vm <= min(va, vb) else ((a, va) if va <= vb else (b, vb))
            best = min(best, _bracket_min(0, S, P, R, px, py, 0.0, a, x, b, fx))
            continue
        zm = S[3] + m * dz
        lower_first = min(za, zm) + min(fa, vm - zm) <= min(zm, zb) + min(vm - zm, fb)
        for h in range(2):  # the half with the larger bound first onto the stack: the other is searched first
            if (h == 0) == lower_first:
                stack[n, 0], stack[n, 1], stack[n, 2], stack[n, 3] = m, b, vm, vb
            else:
                stack[n, 0], stack[n, 1], stack[n, 2], stack[n, 3] = a, m, va, vm
            n += 1
    return best


@njit(cache=True, inline="always")
def _round(P):
    """Whether the lower profile ``P`` is round: each piece flat (a flat bottom at the tip) or an
    arc about a centre at ``a >= 0`` from the axis (ball, bull-nose, an APT cutter's corner; not a
    cone). Then ``f'(d) / d`` does not decrease, so ``F(s) = f(sqrt(s))`` is convex and
    non-decreasing in ``s = d^2``; and ``rho(h)^2`` is concave in ``h`` (rho is concave and
    non-decreasing, :mod:`.profile`; on an arc piece it is a + s', s' = sqrt(c^2 - (b - h)^2), so
    rho^2 = a^2 + 2 a s' + s'^2 with s' and s'^2 concave; at the joints (rho^2)' = 2 rho rho' does
    not grow). A cone has neither: f'(d) / d falls and rho^2 is convex."""
    for i in range(P.shape[0]):
        if (P[i, 0] == 0.0 and P[i, 4] != 0.0) or (P[i, 0] != 0.0 and P[i, 3] < 0.0):
            return False
    return True


@njit(cache=True)
def arc_lower(S, P, R, px, py, eps):
    """L(p) of an XY arc / helix sweep (mm); inf outside the footprint widened by ``eps``."""
    qx, qy = px - S[7], py - S[8]
    Q = math.sqrt(qx * qx + qy * qy)
    rho, sw = S[9], S[11]
    Re = R + eps
    if Q * rho <= 1e-15:  # p on the axis (or a zero radius): every tool position equally far
        if Q + rho > Re:
            return math.inf
        return _arc_value(0, S, P, R, px, py, 0.0, 0.0 if S[6] >= S[3] else 1.0)
    kappa = (rho * rho + Q * Q - Re * Re) / (2.0 * rho * Q)
    if kappa > 1.0:
        return math.inf
    w = math.pi if kappa <= -1.0 else math.acos(kappa)
    psi = math.atan2(qy, qx)
    b0 = S[10] - psi
    b1 = b0 + sw
    lo, hi = min(b0, b1), max(b0, b1)
    if abs(sw) > 2.0 * math.pi and S[6] != S[3]:
        # a helix of more than a turn: each tool position of a turn is a pitch lower than the one a turn
        # before above the same place, so the least lower surface is on its last turn (going down) or
        # its first (going up)
        first = S[6] > S[3]
        if (sw > 0.0) == first:
            hi = lo + 2.0 * math.pi
        else:
            lo = hi - 2.0 * math.pi
    if S[6] == S[3]:  # level: lowest where the arc passes nearest p, the direction of p or an end
        d = _circle_nearest(Q, rho, lo, hi)
        if d > Re:
            return math.inf
        return S[3] + profile_height(P, d if d < R else R)
    best = math.inf
    flat = is_flat(P)  # a flat end mill's f: constant
    # convex: the value is convex over each window's part within R, of half-width wr (-1: none, only
    # the eps margin), which spans no more than cos(u) >= limit (module docstring)
    limit = 0.0 if _round(P) else min(rho, Q) / max(rho, Q)
    kr = (rho * rho + Q * Q - R * R) / (2.0 * rho * Q)
    convex = kr >= limit
    wr = math.acos(kr) if limit <= kr <= 1.0 else -1.0
    k0, k1 = angle_windows(lo, hi, w)
    for k in range(k0, k1 + 1):
        ta, tb = window_span(k, lo, hi, w, b0, sw)
        if ta > tb:
            continue
        if flat:  # z(t) + f is linear in t: lowest at the window's end that is lower
            best = min(best, P[0, 3] + S[3] + (tb if S[6] < S[3] else ta) * (S[6] - S[3]))
        elif convex:
            tc, td = window_span(k, lo, hi, wr, b0, sw) if wr >= 0.0 else (1.0, 0.0)
            best = min(best, _convex_window_min(S, P, R, px, py, ta, tb, tc, td))
        elif limit == 0.0:
            # a round profile whose window within R reaches past cos u = 0 (the path's circle passes
            # round the point, rho < R): convex on the near half, all within R; the far parts bounded
            tn, tm = window_span(k, lo, hi, 0.5 * math.pi, b0, sw)
            if tn <= tm:
                best = min(best, _convex_window_min(S, P, R, px, py, tn, tm, tn, tm))
            c = 2.0 * math.pi * k
            fa, fb = angle_span(c + 0.5 * math.pi, c + w, lo, hi, b0, sw)
            best = _far_min(S, P, R, px, py, fa, fb, best)
            fa, fb = angle_span(c - w, c - 0.5 * math.pi, lo, hi, b0, sw)
            best = _far_min(S, P, R, px, py, fa, fb, best)
        else:
            best = min(best, _window_min(0, S, P, R, px, py, 0.0, ta, tb))
    return best


@njit(cache=True)
def arc_depth(S, P, R, px, py, pz):
    """min over t of phi(t) = |p - c(t)| - rho(pz - z(t)) on an arc sweep (mm): < 0 where the point
    lies strictly inside some tool position of the sweep. A flat end mill's in closed form
    (:func:`_flat_arc_depth`), another tool's sampled and refined (:func:`_window_min`; the engine
    asks :func:`arc_holds`, which samples only where the gap is not convex)."""
    if is_flat(P):
        return _flat_arc_depth(S, R, px, py, pz)
    return _window_min(1, S, P, R, px, py, pz, 0.0, 1.0)


@njit(cache=True, inline="always")
def _arc_gap(S, P, px, py, pz, t):
    """d(t)^2 - rho(pz - z(t))^2 on an arc sweep (mm^2), the tip at or below ``pz``: < 0 where the point
    lies strictly inside the tool at ``t``."""
    a = S[10] + t * S[11]
    dx, dy = S[7] + S[9] * math.cos(a) - px, S[8] + S[9] * math.sin(a) - py
    r = profile_radius(P, max(pz - (S[3] + t * (S[6] - S[3])), 0.0))
    return dx * dx + dy * dy - r * r


@njit(cache=True, inline="always")
def _arc_gap_slope(S, P, px, py, pz, t):
    """d/dt of :func:`_arc_gap` (mm^2): 2 (c - p).c' + 2 rho rho'(h) (z1 - z0), h = pz - z(t); nan
    where rho' is infinite (a flat bottom's height) on a helix."""
    a = S[10] + t * S[11]
    ca, sa = math.cos(a), math.sin(a)
    dx, dy = S[7] + S[9] * ca - px, S[8] + S[9] * sa - py
    g = 2.0 * S[9] * S[11] * (dy * ca - dx * sa)
    dz = S[6] - S[3]
    if dz == 0.0:
        return g
    h = max(pz - (S[3] + t * dz), 0.0)
    return g + 2.0 * profile_radius(P, h) * profile_radius_slope(P, h) * dz


@njit(cache=True)
def arc_holds(S, P, R, px, py, pz, eps):
    """Whether (px, py, pz) lies inside the tool at some position of the arc sweep ``S`` by more than
    ``eps`` (mm): the least ``phi`` of :func:`arc_depth` is below ``-eps``.

    Exact without sampling where ``rho^2`` is concave (:func:`_round`: flat, ball, bull-nose)
    and the windows of angle within ``R`` of the point span no more than ``cos u >= 0`` (``u`` the
    angle from the point's direction, :func:`arc_lower`): there ``d^2 = A - B cos u`` is convex in
    ``t`` and so is ``-rho(pz - z(t))^2`` (``z`` linear in ``t``), so the gap ``d^2 - rho^2``
    (:func:`_arc_gap`), of the sign of ``phi``, has one minimum in each window's part where the tip
    is at or below the point: at an end where the slope's sign says so, else found by Brent's method
    to :data:`T_TOL`. Inside by more than ``eps`` at ``t`` needs ``gap(t) < eps^2 - 2 eps rho(t)``, so
    a least gap at or above that with the window's least ``rho`` rules the window out (a point on the
    end tool's own surface has a gap of round-off at the end); ``phi`` below ``-eps`` at the least gap
    rules it in. Otherwise the window is sampled and refined as :func:`arc_depth` does, as is every
    other case."""
    if is_flat(P):
        return _flat_arc_depth(S, R, px, py, pz) < -eps
    qx, qy = px - S[7], py - S[8]
    Q = math.sqrt(qx * qx + qy * qy)
    rho, sw = S[9], S[11]
    if Q * rho <= 1e-15 or sw == 0.0 or not _round(P):
        return _window_min(1, S, P, R, px, py, pz, 0.0, 1.0) < -eps
    kr = (rho * rho + Q * Q - R * R) / (2.0 * rho * Q)
    if kr >= 1.0:
        return False  # every position's axis is R or more away: d >= R >= rho
    if kr < 0.0:
        return _window_min(1, S, P, R, px, py, pz, 0.0, 1.0) < -eps
    z0, z1 = S[3], S[6]
    tlo, thi = 0.0, 1.0  # where the tip is at or below pz (elsewhere phi = d + 1 > 0)
    if z1 == z0:
        if pz < z0:
            return False
    elif z1 > z0:
        thi = min((pz - z0) / (z1 - z0), 1.0)
    else:
        tlo = max((pz - z0) / (z1 - z0), 0.0)
    if tlo > thi:
        return False
    w = math.acos(kr)
    b0 = S[10] - math.atan2(qy, qx)
    lo, hi = min(b0, b0 + sw), max(b0, b0 + sw)
    k0, k1 = angle_windows(lo, hi, w)
    for k in range(k0, k1 + 1):
        ta, tb = window_span(k, lo, hi, w, b0, sw)
        ta, tb = max(ta, tlo), min(tb, thi)
        if ta > tb:
            continue
        ga, gb = _arc_gap_slope(S, P, px, py, pz, ta), _arc_gap_slope(S, P, px, py, pz, tb)
        if math.isnan(ga) or math.isnan(gb):
            t_min = -1.0  # sampled below
        elif gb <= 0.0:  # falling to the window's end
            t_min = tb
        elif ga >= 0.0:
            t_min = ta
        else:
            m = 0.5 * (ta + tb)
            st = brent_start(ta, m, tb, _arc_gap(S, P, px, py, pz, m), T_TOL * (tb - ta))
            for _ in range(BRENT_STEPS):
                u = brent_next(st)
                if math.isnan(u):
                    break
                brent_take(st, u, _arc_gap(S, P, px, py, pz, u))
            t_min = brent_best(st)[0]
        if t_min >= 0.0:
            gap = _arc_gap(S, P, px, py, pz, t_min)
            # inside by more than eps at t needs gap(t) < eps^2 - 2 eps rho(t), and rho(t) >= rho at
            # the window's least height
            h_min = pz - max(S[3] + ta * (S[6] - S[3]), S[3] + tb * (S[6] - S[3]))
            if gap >= eps * eps - 2.0 * eps * max(profile_radius(P, h_min), 0.0):
                continue
            if _arc_value(1, S, P, R, px, py, pz, t_min) < -eps:
                return True
        if _window_min(1, S, P, R, px, py, pz, ta, tb) < -eps:
            return True
    return False


@njit(cache=True)
def _circle_nearest(Q, rho, lo, hi):
    """The least distance (mm) from a point at ``Q`` from a circle's centre to the circle's points
    (radius ``rho``) at angles ``u`` in [lo, hi] from the point's direction: d² = rho² + Q² - 2 rho Q
    cos u, least where u passes a multiple of 2 pi (``|Q - rho|``), else at the nearer end."""
    if 2.0 * math.pi * math.ceil(lo / (2.0 * math.pi)) <= hi:
        return abs(Q - rho)
    c = max(math.cos(lo), math.cos(hi))
    return math.sqrt(max(rho * rho + Q * Q - 2.0 * rho * Q * c, 0.0))


@njit(cache=True)
def _arc_nearest(S, px, py, ta, tb):
    """The least XY distance (mm) from p to the arc's path over t in [ta, tb] (:func:`_circle_nearest`)."""
    qx, qy = px - S[7], py - S[8]
    psi = math.atan2(qy, qx)
    u0, u1 = S[10] + ta * S[11] - psi, S[10] + tb * S[11] - psi
    return _circle_nearest(math.sqrt(qx * qx + qy * qy), S[9], min(u0, u1), max(u0, u1))


@njit(cache=True)
def _flat_arc_depth(S, R, px, py, pz):
    """:func:`arc_depth` of a flat end mill: rho(h) = R at and above the tip, -1 below it, so phi is
    the XY distance less R where z(t) <= pz and the distance plus 1 where z(t) > pz; z is linear in
    t, so each is the least distance over one interval of t (:func:`_arc_nearest`)."""
    z0, z1 = S[3], S[6]
    if z1 == z0:
        tc = 1.0 if pz >= z0 else -1.0  # every position at or below pz, or none
    else:
        tc = (pz - z0) / (z1 - z0)  # z(t) <= pz for t <= tc rising, for t >= tc falling
    below_lo, below_hi = (0.0, min(tc, 1.0)) if z1 >= z0 else (max(tc, 0.0), 1.0)
    above_lo, above_hi = (max(tc, 0.0), 1.0) if z1 >= z0 else (0.0, min(tc, 1.0))
    best = math.inf
    if below_lo <= below_hi:
        best = _arc_nearest(S, px, py, below_lo, below_hi) - R
    if above_lo <= above_hi and (z1 != z0 or tc < 0.0):
        best = min(best, _arc_nearest(S, px, py, above_lo, above_hi) + 1.0)
    return best


# -- either --------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def sweep_lower(S, P, R, px, py, eps):
    if S[0] == 0.0:
        return line_lower(S, P, R, px, py, eps)
    if S[0] == OUTSIDE:
        return outside_lower(S, px, py, eps)
    if is_vertical(S):
        return vertical_lower(S, P, R, px, py, eps)
    return arc_lower(S, P, R, px, py, eps)


@njit(cache=True, inline="always")
def segment_nearest(px, py, ax, ay, bx, by):
    """(t, d): the point ``a + t (b - a)`` (t in [0, 1]) of the segment from (ax, ay) to (bx, by)
    nearest the point (px, py), and its XY distance (mm) to it."""
    ux, uy = bx - ax, by - ay
    uu = ux * ux + uy * uy
    t = 0.0 if uu <= 0.0 else min(max(((px - ax) * ux + (py - ay) * uy) / uu, 0.0), 1.0)
    return t, math.hypot(px - ax - t * ux, py - ay - t * uy)


@njit(cache=True, inline="always")
def point_segment_distance(px, py, ax, ay, bx, by):
    """XY distance (mm) from the point (px, py) to the segment from (ax, ay) to (bx, by)."""
    return segment_nearest(px, py, ax, ay, bx, by)[1]


@njit(cache=True, inline="always")
def point_path_distance(S, px, py):
    """The least XY distance (mm) from ``p`` to the path of a line or arc sweep ``S`` (a vertical arc's XY
    path is the segment between its ends, :mod:`.vertical`)."""
    if S[0] == 0.0 or is_vertical(S):
        return point_segment_distance(px, py, S[1], S[2], S[4], S[5])
    qx, qy = px - S[7], py - S[8]
    Q = math.sqrt(qx * qx + qy * qy)
    sw = S[11]
    inside = abs(sw) >= 2.0 * math.pi or Q <= 0.0
    if not inside:  # is the direction of p within the arc's angular span?
        off = (math.atan2(qy, qx) - S[10]) % (2.0 * math.pi)
        inside = off <= sw if sw > 0.0 else off - 2.0 * math.pi >= sw
    if inside:
        return abs(Q - S[9])
    return min(math.sqrt((px - S[1]) ** 2 + (py - S[2]) ** 2), math.sqrt((px - S[4]) ** 2 + (py - S[5]) ** 2))


@njit(cache=True, inline="always")
def sweep_floor(S, P, R, px, py, eps):
    """A lower bound (mm) of :func:`sweep_lower` at ``p``, in closed form: the path's lowest tip
    height plus ``f`` at the least XY distance from ``p`` to the path (``z(t) >= min z`` and ``f``
    grows outward); inf outside the footprint widened by ``eps``. It lets a caller skip a sweep
    whose lower surface cannot be below a height it already has. A stock's outside's is exact."""
    if S[0] == OUTSIDE:
        return outside_lower(S, px, py, eps)
    return floor_within(S, P, R, px, py, eps, 0.0)


@njit(cache=True, inline="always")
def floor_within(S, P, R, px, py, eps, reach):
    """A lower bound (mm) of :func:`sweep_lower` over the disc of radius ``reach`` about ``p``: as
    :func:`sweep_floor`, at the XY distance to the path less ``reach`` (a distance to a set changes
    by no more than the point moves); inf where the whole disc is outside the footprint widened by
    ``eps``. A stock's outside gets none (-inf)."""
    if S[0] == OUTSIDE:
        return -math.inf
    d = max(point_path_distance(S, px, py) - reach, 0.0)
    if d > R + eps:
        return math.inf
    return min(S[3], S[6]) + profile_height(P, d if d < R else R)


@njit(cache=True, inline="always")
def end_velocity(S):
    """(vx, vy, vz): dc/dt at t = 1 (mm per unit t)."""
    if S[0] == 0.0:
        return S[4] - S[1], S[5] - S[2], S[6] - S[3]
    if is_vertical(S):
        return vertical_velocity(S)
    a = S[10] + S[11]
    return -S[9] * S[11] * math.sin(a), S[9] * S[11] * math.cos(a), S[6] - S[3]


def brute_lower(S: np.ndarray, P: np.ndarray, R: float, px: float, py: float, n: int = 200_001,
                refine: int = 0, eps: float = 0.0) -> float:
    """L(p) by dense sampling of t (for tests): an upper bound that tends to L as n grows. ``refine``
    times over, the ``n`` samples are taken again between the best one's neighbours: where the
    minimum is smooth, within ~(2 / n) ** (refine + 1) of t's range of it. ``eps`` widens the footprint
    as :func:`sweep_lower`'s does."""
    t = np.linspace(0.0, 1.0, n)
    best = math.inf
    for _ in range(refine + 1):
        z = S[3] + t * (S[6] - S[3])
        if S[0] == LINE:
            cx, cy = S[1] + t * (S[4] - S[1]), S[2] + t * (S[5] - S[2])
        elif is_vertical(S):
            cx, cy, z = vertical_positions(S, t)
        else:
            a = S[10] + t * S[11]
            cx, cy = S[7] + S[9] * np.cos(a), S[8] + S[9] * np.sin(a)
        d = np.hypot(px - cx, py - cy)
        ok = d <= R + eps
        if not ok.any():
            return best
        v = np.where(ok, z + _heights(P, np.minimum(d, R)), np.inf)
        i = int(np.argmin(v))
        best = min(best, float(v[i]))
        t = np.linspace(t[max(i - 1, 0)], t[min(i + 1, n - 1)], n)
    return best


@njit(cache=True)
def _heights(P, d):
    out = np.empty(d.shape[0])
    for i in range(d.shape[0]):
        out[i] = profile_height(P, d[i])
    return out
