"""Volume a CL removes: an adaptive integral over its footprint, no Booleans.

Machine frame, mm. With ``L`` the CL's own sweep's lower surface and ``h`` the lowest lower
surface of the earlier sweeps near it (the material before the CL is the box stock below ``h``; a
round bar's outside is one of those sweeps, :func:`.sweeps.outside_row`),

    removed = integral over the footprint within the stock's XY box of
              max(0, min(h, z_top) - max(L, z_bottom))  dx dy          (mm³)

``h`` and ``L`` jump where a footprint ends (a flat end mill's wall) and bend where a tool's
profile changes piece (a bull-nose's flat meets its corner): there the integrand is cut into
smooth parts by **break points** found in closed form, the crossings of the line ``x = const`` with
the footprints' boundary curves (circles about the path's ends and, for an arc, about its centre;
segments parallel to a line's path, an arc's end radii; :mod:`.breaks`, which leaves out those
where nothing is removed around them). The inner integral over ``y`` between break points and the
outer one over ``x`` (break points: the curves' extreme x and where two curves meet,
:func:`.breaks.curve_meetings_x`) are adaptive
Gauss-Kronrod (7, 15) with a **global** error budget, as QUADPACK's QAG: the part with the largest
error estimate (QUADPACK's, from the two rules) is halved until the estimates add up to the budget
(or parts reach :data:`MIN_PART` mm). A budget per part's length would refine a crescent's tip, where
the removed height starts from zero, down to :data:`MIN_PART`; a global one stops there once the
tip's share of the error is small. The budget is the looser of an absolute one (``tol`` mm per mm²
of the rectangle) and a relative one (``rel`` of the integral's current sum, QUADPACK's
``epsrel``); the outer integral gets nine tenths of each, each inner one a tenth (so that their
errors do not look like a rough integrand), the inner's relative one of its own line.

The integrand also bends where no footprint ends: where ``L`` meets ``h`` (the removed region's
edge) and where the earlier sweep giving ``h`` changes. Along a line those **kinks** are found by
probing the integrand's state between break points (at least :data:`N_PROBE` + 1 probes, at most
:data:`PROBE_STEP` tool radii apart), each change located as the root of the two crossing surfaces'
difference, and each dip of the state's margin between probes searched for a region of another
state the probes stepped over (:func:`_with_kinks`; a thin crescent where a finishing pass grazes
the last one); a change the Gauss-Kronrod nodes still meet splits its part there;
across lines, the places where the sequence of states changes (a kink curve turns back, two cross)
become break points of the outer integral (:func:`_with_x_kinks`). A stretch where nothing can be
removed is proven so from bounds and skipped (:func:`_nothing_removed`). Probes are samples: a
kink between two of them is left to the adaptive rule, which then refines it as before.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.breaks import crossings_at_x
from fusioncut.engines.analytic.brent import brent_next, brent_start, brent_take
from fusioncut.engines.analytic.profile import profile_height
from fusioncut.engines.analytic.sections import section_integral
from fusioncut.engines.analytic.sweeps import point_segment_distance, sweep_floor, sweep_lower

MIN_PART = 1e-9  # mm
N_PROBE = 8  # samples a stretch between break points is probed at for kinks
PROBE_STEP = 1 / 16  # tool radii: the probes along a stretch are at most this far apart
MAX_PROBES = 64  # probes a stretch, a bound
MARGIN_TOL = 1e-9  # mm: a dip of the state's margin is searched only above this (equal surfaces, a
# retraced pass, would show dips of round-off)
KINK_TOL = 1e-12  # mm: a kink's place along a line
SAME_TOL = 1e-11  # mm: surfaces this close are one to the integrand's state (_code): a removed height this
# small is none, and a later sweep gives h only where it is this far below the earlier ones. A pass retraced
# at its own height (a circle gone round again, a helix run out on a level circle at its foot) leaves
# surfaces equal up to round-off, where the state would flicker from node to node (the removed height is
# integrated as it is: only where its parts meet is decided with this margin)
X_KINK_TOL = 1e-8  # mm: the place of a line where the kinks along the lines change. The inner integral is
# continuous there (a jump of it, a wall along y, is a curve's end or extreme: an x break point), its slope
# changes or it bends as a power 3/2, so a part ending this far off errs by the order of its square
MAX_CHANGES = 2  # changes of state located between two probes, one after the other; more are left to the adaptive
# rule (each located one costs a part of its own, more than a kink of little weight costs inside one)
CLUSTER = 1e-5  # of the probes' spacing: the next change is looked for this far past the last one (changes
# closer together, where many curves meet at a joint, are one: each would cost the rule a part)
_PANELS = 2000  # parts one adaptive integral may hold (each of the inner ones and the outer one)

# Gauss-Kronrod 15-point nodes (on [-1, 1]) and weights; the Gauss 7-point weights at the odd nodes
_XK = np.array([0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
                0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
                0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
                0.207784955007898467600689403773245, 0.0])
_WK = np.array([0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
                0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
                0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
                0.204432940075298892414161999234649, 0.209482141084727828012999174891714])
_WG = np.array([0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
                0.381830050505118944950369775488975, 0.417959183673469387755102040816327])


@njit(cache=True)
def height_and_cause(px, py, S, P, R, C, CB, PP, NPC, RR, z_bottom, z_top):
    """(max(0, min(h, z_top) - max(L, z_bottom)) at (px, py) in mm; the index in ``C`` of the earlier
    sweep that gave ``h`` there: the least lower surface met before the height was known to be 0, or
    -1 where none is below ``z_top`` or the point is outside the CL's footprint; ``L`` itself, mm,
    inf outside the footprint)."""
    own = sweep_lower(S, P, R, px, py, 0.0)
    if own == math.inf:
        return 0.0, -1, own
    low = max(own, z_bottom)
    high = z_top
    cause = -1
    for j in range(C.shape[0]):
        if px < CB[j, 0] or px > CB[j, 2] or py < CB[j, 1] or py > CB[j, 3]:
            continue
        if C[j, 3] >= high and C[j, 6] >= high:
            continue  # its lower surface is nowhere below its path's lowest tip
        k = int(C[j, 12])
        if sweep_floor(C[j], PP[k, :NPC[k]], RR[k], px, py, 0.0) >= high:
            continue  # its lower surface is nowhere below what is already the least
        h = sweep_lower(C[j], PP[k, :NPC[k]], RR[k], px, py, 0.0)
        if h < high:
            if h < high - SAME_TOL:
                cause = j
            high = h
            if high <= low:
                return 0.0, cause, own
    return (high - low if high > low else 0.0), cause, own


@njit(cache=True, inline="always")
def _state(x, y, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """What shapes the removed height at (x, y): 0 where nothing is removed, else 1 + 2 * (the index
    of the sweep giving ``h``, or -1 for the stock's top) + (1 where ``L`` is below the stock's
    bottom). Within a stretch of one state the removed height is smooth."""
    v, cause, own = height_and_cause(x, y, S, P, R, C, CB, PP, NPC, RR, zb, zt)
    return _code(v, cause, own, zb)


@njit(cache=True, inline="always")
def _code(v, cause, own, zb):
    """:func:`_state`'s code of a removed height ``v`` given by sweep ``cause`` over ``L = own``."""
    return 0 if v <= SAME_TOL else 3 + 2 * cause + (1 if own < zb else 0)


@njit(cache=True)
def _probe(x, y, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """(:func:`_state` at (x, y); its margin there, mm: how far the surfaces that decide the state are
    from deciding another one; the removed height signed, min(h, top) - max(L, bottom), mm). The
    margin: nothing removed, max(L, bottom) - min(h, top), inf outside the CL's footprint; something
    removed, the least of the removed height, the gap from ``h`` to the next lowest earlier sweep (or
    the top) and ``|L - bottom|``. A narrow region of another state between two probes sits in a dip
    of the margin (:func:`_dip`). The signed height is continuous where ``L`` and every earlier lower
    surface are (within a stretch between break points), though it bends where the sweep giving ``h``
    changes; -inf outside the CL's footprint."""
    own = sweep_lower(S, P, R, x, y, 0.0)
    if own == math.inf:
        return 0, math.inf, -math.inf
    low = max(own, zb)
    h1, h2 = zt, math.inf  # the two least lower surfaces, the top counting as one
    cause = -1
    for j in range(C.shape[0]):
        if x < CB[j, 0] or x > CB[j, 2] or y < CB[j, 1] or y > CB[j, 3]:
            continue
        if C[j, 3] >= h2 and C[j, 6] >= h2:
            continue
        k = int(C[j, 12])
        if sweep_floor(C[j], PP[k, :NPC[k]], RR[k], x, y, 0.0) >= h2:
            continue
        h = sweep_lower(C[j], PP[k, :NPC[k]], RR[k], x, y, 0.0)
        if h < h1:
            if h < h1 - SAME_TOL:
                cause = j
            h1, h2 = h, h1
        elif h < h2:
            h2 = h
    if h1 - low <= SAME_TOL:
        return 0, low - h1 + SAME_TOL, h1 - low
    return _code(h1 - low, cause, own, zb), min(h1 - low - SAME_TOL, h2 - h1, abs(own - zb)), h1 - low


@njit(cache=True)
def _dip(x, a, m, b, fm, s0, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """A place in (a, b) of another state than ``s0``, found from the probe ``m`` between ``a`` and
    ``b`` whose margin ``fm`` (:func:`_probe`) is below both of theirs, all three in state ``s0``; nan
    where none is found. Brent's minimisation of the margin (:func:`.brent.brent_next`), stopped
    at the first other state or when the bracket is 1e-9 of its first width: a narrow crescent of
    removed material, or of another sweep's floor, between two probes sits in such a dip (the margin
    is a difference of smooth surfaces, a V where two earlier sweeps cross)."""
    st = brent_start(a, m, b, fm, 1e-9 * (b - a))
    for _ in range(100):
        u = brent_next(st)
        if math.isnan(u):
            break
        state, fu, _ = _probe(x, u, S, P, R, C, CB, PP, NPC, RR, zb, zt)
        if state != s0:
            return u
        brent_take(st, u, fu)
    return math.nan


@njit(cache=True)
def _gap(x, y, s0, s1, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """Where the state changes from ``s0`` to ``s1`` (:func:`_state`), the two surfaces that cross
    there: their difference at (x, y), mm, of one sign on ``s0``'s side and the other on ``s1``'s.
    Into or out of nothing removed: the removed height signed, min(h, top) - max(L, bottom)
    (:func:`_probe`'s; the sweep that leaves nothing on one side need not be the one giving
    ``h`` on the other); another sweep gives ``h``: the two causes' heights (the top for -1); ``L``
    passes the bottom: ``L`` - bottom. NaN where the change is of another kind."""
    if s0 == 0 or s1 == 0:
        return _probe(x, y, S, P, R, C, CB, PP, NPC, RR, zb, zt)[2] - SAME_TOL
    c0, c1 = (s0 - 3) // 2, (s1 - 3) // 2
    if c0 != c1 and (s0 - 3) % 2 == (s1 - 3) % 2:
        h0, h1 = zt, zt
        if c0 >= 0:
            k = int(C[c0, 12])
            h0 = sweep_lower(C[c0], PP[k, :NPC[k]], RR[k], x, y, 0.0)
        if c1 >= 0:
            k = int(C[c1, 12])
            h1 = sweep_lower(C[c1], PP[k, :NPC[k]], RR[k], x, y, 0.0)
        return h0 - h1 - (SAME_TOL if c0 < c1 else -SAME_TOL)  # the later sweep gives h SAME_TOL below
    if c0 == c1:
        return sweep_lower(S, P, R, x, y, 0.0) - zb
    return math.nan


@njit(cache=True)
def _kink(x, lo, hi, s0, s1, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """A place (mm along the line at ``x``, to :data:`KINK_TOL`) in [lo, hi] where the state
    changes from ``s0`` (at ``lo``), on the way to ``s1`` (at ``hi``). The two surfaces that cross there
    (:func:`_gap`) are smooth, so their difference's root is found by Illinois steps (every fourth a
    bisection); the root counts where the state just before it is ``s0`` and the one just after it
    is not (a third state may follow ``s0`` there, on the way to ``s1``: the caller looks on from
    there). Else (a change of two kinds at once, a surface touching another) the states are
    bisected."""
    g0 = _gap(x, lo, s0, s1, S, P, R, C, CB, PP, NPC, RR, zb, zt)
    g1 = _gap(x, hi, s0, s1, S, P, R, C, CB, PP, NPC, RR, zb, zt)
    if math.isfinite(g0) and math.isfinite(g1) and g0 * g1 < 0.0:
        a, b, fa, fb = lo, hi, g0, g1
        side = 0
        for i in range(200):
            if b - a <= KINK_TOL:
                break
            m = 0.5 * (a + b) if i % 4 == 3 else (a * fb - b * fa) / (fb - fa)
            if not a < m < b:
                m = 0.5 * (a + b)
            fm = _gap(x, m, s0, s1, S, P, R, C, CB, PP, NPC, RR, zb, zt)
            if not math.isfinite(fm):
                break
            if fm == 0.0:
                a = b = m
                break
            if (fm < 0.0) == (fa < 0.0):
                a, fa = m, fm
                if side == 1:
                    fb *= 0.5
                side = 1
            else:
                b, fb = m, fm
                if side == -1:
                    fa *= 0.5
                side = -1
        y = 0.5 * (a + b)
        if (b - a <= KINK_TOL and _state(x, max(y - KINK_TOL, lo), S, P, R, C, CB, PP, NPC, RR, zb, zt) == s0
                and _state(x, min(y + KINK_TOL, hi), S, P, R, C, CB, PP, NPC, RR, zb, zt) != s0):
            return y
    while hi - lo > KINK_TOL:
        m = 0.5 * (lo + hi)
        if _state(x, m, S, P, R, C, CB, PP, NPC, RR, zb, zt) == s0:
            lo = m
        else:
            hi = m
    return 0.5 * (lo + hi)


@njit(cache=True)
def _with_kinks(x, pts, owners, rims, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """(``pts`` with the kinks of the removed height along the line at ``x`` added; per stretch between them
    whether anything may be removed there; per point whether the node map bends there (:func:`_ends_map`): a
    kink, or a point of ``pts`` that ``rims`` flags (:func:`.breaks.crossings_at_x`)). A stretch
    :func:`_nothing_removed` proves empty is kept whole; in the others the state and its margin
    (:func:`_probe`) are probed at even samples (:data:`N_PROBE` + 1 at least, :data:`PROBE_STEP` tool radii
    apart at most), each change located (:func:`_kink`; several between two probes one after the other,
    :data:`CLUSTER` of their spacing apart at least), and each probe in the same state as both its
    neighbours with a smaller margin, at most half the larger of theirs, searched for another state
    (:func:`_dip`), whose region's edges are kinks too (a margin convex between the probes stays above twice
    the probe's less the larger neighbour's: a dip shallower than that cannot reach another state). A kink
    left inside a stretch costs the adaptive rule a split at it (:func:`inner_integral`).

    A break point between two stretches probed in one and the same state is dropped where its curve
    (``owners``, as :func:`.breaks.crossings_at_x` gives them) is neither the CL's own sweep's nor that of
    the sweep giving ``h`` there: the removed height is then smooth across it."""
    out = [pts[0]]
    rim = [rims[0] > 0.0]
    live = []
    last = -1  # the state all probes of the last stretch had (-1: none, or a change within it)
    for p in range(pts.shape[0] - 1):
        a, b = pts[p], pts[p + 1]
        if b - a <= 0.0:
            continue
        if _nothing_removed(x, a, b, S, P, R, C, CB, PP, NPC, RR, zb, zt):
            out.append(b)
            rim.append(rims[p + 1] > 0.0)
            live.append(False)
            last = -1
            continue
        uniform = -1
        if b - a > 4 * KINK_TOL:
            n = min(max(N_PROBE, int(math.ceil((b - a) / (PROBE_STEP * R)))), MAX_PROBES)
            ys = np.empty(n + 1)
            sts = np.empty(n + 1, dtype=np.int64)
            gaps = np.empty(n + 1)
            for i in range(n + 1):
                ys[i] = a + KINK_TOL if i == 0 else (a + (b - a) * i / n if i < n else b - KINK_TOL)
                sts[i], gaps[i], _ = _probe(x, ys[i], S, P, R, C, CB, PP, NPC, RR, zb, zt)
            kinks = [0.0]  # typed for numba; the kinks are kinks[1:]
            for i in range(1, n + 1):
                if sts[i] != sts[i - 1]:  # each change between the two probes, one after the other
                    lo, s0 = ys[i - 1], sts[i - 1]
                    for _ in range(MAX_CHANGES):
                        y = _kink(x, lo, ys[i], s0, sts[i], S, P, R, C, CB, PP, NPC, RR, zb, zt)
                        kinks.append(y)
                        lo = min(y + max(KINK_TOL, CLUSTER * (ys[i] - ys[i - 1])), ys[i])
                        s0 = _state(x, lo, S, P, R, C, CB, PP, NPC, RR, zb, zt)
                        if s0 == sts[i]:
                            break
                elif (i < n and sts[i + 1] == sts[i] and MARGIN_TOL < gaps[i] < gaps[i - 1]
                      and gaps[i] <= gaps[i + 1] and 2.0 * gaps[i] <= max(gaps[i - 1], gaps[i + 1])):
                    y = _dip(x, ys[i - 1], ys[i], ys[i + 1], gaps[i], sts[i], S, P, R, C, CB, PP, NPC, RR, zb, zt)
                    if not math.isnan(y):  # a region the probes stepped over: its two edges
                        s1 = _state(x, y, S, P, R, C, CB, PP, NPC, RR, zb, zt)
                        kinks.append(_kink(x, ys[i - 1], y, sts[i], s1, S, P, R, C, CB, PP, NPC, RR, zb, zt))
                        kinks.append(_kink(x, y, ys[i + 1], s1, sts[i], S, P, R, C, CB, PP, NPC, RR, zb, zt))
            for y in np.sort(np.array(kinks[1:])):
                out.append(y)
                rim.append(True)
                live.append(True)
            uniform = sts[0] if len(kinks) == 1 else -1
        owner = int(owners[p])
        if uniform > 0 and uniform == last and owner > 0 and owner != (uniform - 3) // 2 + 1:
            out[-1] = b  # the last stretch goes on through this one
            rim[-1] = rims[p + 1] > 0.0
        else:
            out.append(b)
            rim.append(rims[p + 1] > 0.0)
            live.append(True)
        last = uniform
    return np.array(out), np.array(live, dtype=np.bool_), np.array(rim, dtype=np.bool_)


@njit(cache=True)
def _line_floor(S, P, x, a, b):
    """A lower bound (mm) of the line sweep ``S``'s lower surface over the segment x = ``x``,
    y in [a, b]: the path's lowest tip plus ``f`` at the least XY distance between the two segments
    (0 where they cross, else the least distance of an end of one to the other)."""
    ax, ay, bx, by = S[1], S[2], S[4], S[5]
    d = min(point_segment_distance(x, a, ax, ay, bx, by), point_segment_distance(x, b, ax, ay, bx, by),
            point_segment_distance(ax, ay, x, a, x, b), point_segment_distance(bx, by, x, a, x, b))
    if (ax - x) * (bx - x) <= 0.0 and ax != bx:
        yc = ay + (by - ay) * (x - ax) / (bx - ax)
        if a <= yc <= b:
            d = 0.0
    return min(S[3], S[6]) + profile_height(P, d)


@njit(cache=True)
def _nothing_removed(x, a, b, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """True only where nothing is removed anywhere on the segment x = ``x``, y in [a, b] (a stretch
    between break points, so that the CL's footprint covers all of it or none of it; an earlier
    sweep's may end within it, where nothing is removed around, :mod:`.breaks`).

    Outside the CL's footprint at the point between, it is outside everywhere. Else the removed
    height is max(0, min(h, top) - max(L, bottom)) with max(L, bottom) at least ``floor``, the
    bottom or the CL's own floor (:func:`_line_floor`; an arc's lowest tip). It is 0 all along where
    ``floor`` reaches the top, or where the sweep giving ``h`` at the point between is a line: its
    lower surface is convex in (x, y) (the partial minimum over t of the jointly convex
    z(t) + f(|p - c(t)|)), so at most the larger of its values at the ends, and that is below
    ``floor`` (both ends in its convex footprint: all of the segment is)."""
    y = 0.5 * (a + b)
    v, j, own = height_and_cause(x, y, S, P, R, C, CB, PP, NPC, RR, zb, zt)
    if v > 0.0:
        return False
    if own == math.inf:
        return True
    floor = max(zb, _line_floor(S, P, x, a, b) if S[0] == 0.0 else min(S[3], S[6]))
    if floor >= zt:
        return True
    if j < 0 or C[j, 0] != 0.0:
        return False
    k = int(C[j, 12])
    Pk, Rk = PP[k, :NPC[k]], RR[k]
    return max(sweep_lower(C[j], Pk, Rk, x, a, 0.0), sweep_lower(C[j], Pk, Rk, x, b, 0.0)) <= floor


@njit(cache=True, inline="always")
def _smooth(a, b, u):
    """The point of [a, b] at the Gauss node ``u`` in [-1, 1] under y = a + (b - a) s^2 (3 - 2 s),
    s = (u + 1) / 2, and the weight factor dy/du: the map's zero slope at both ends turns a square
    root at a break point (a ball's rim, a footprint's round end) into a smooth integrand."""
    s = 0.5 * (u + 1.0)
    return a + (b - a) * s * s * (3.0 - 2.0 * s), 3.0 * (b - a) * s * (1.0 - s)


@njit(cache=True, inline="always")
def _ends_map(a, b, u, ra, rb):
    """The point of [a, b] at the Gauss node ``u`` in [-1, 1] and the weight factor dy/du, under a map
    whose slope is zero at each end flagged (``ra``, ``rb``) and not at the others: :func:`_smooth`
    at two, y = a + (b - a) s^2 or b - (b - a) (1 - s)^2 at one, the linear map at none
    (s = (u + 1) / 2). Flagged are the ends where a square root of the distance may start or lie just
    beyond: a rim (:func:`.breaks.boundary_curves`), a kink (the surfaces crossing there may have their
    rims just past it). A cell's edge is none, nor is a part's end where the adaptive rule halved it:
    the integrand is smooth across them, and a zero slope there would spend nodes on it."""
    if ra and rb:
        return _smooth(a, b, u)
    s = 0.5 * (u + 1.0)
    if ra:
        return a + (b - a) * s * s, (b - a) * s
    if rb:
        return b - (b - a) * (1.0 - s) * (1.0 - s), (b - a) * (1.0 - s)
    return a + (b - a) * s, 0.5 * (b - a)


@njit(cache=True, inline="always")
def _node(i):
    """Gauss-Kronrod node i of 15 on [-1, 1] (pairs +-x_j for i < 14, the centre last), its Kronrod
    weight and its Gauss weight (0 at the Kronrod-only nodes)."""
    j = i // 2 if i < 14 else 7
    u = _XK[j] if i % 2 == 0 or i == 14 else -_XK[j]
    wg = _WG[j // 2] if j % 2 == 1 else (_WG[3] if j == 7 else 0.0)
    return u, _WK[j], wg


@njit(cache=True, inline="always")
def _error(diff, scale):
    """QUADPACK's error estimate of a Kronrod sum from its difference to the Gauss sum: the
    Kronrod rule is far more accurate than the Gauss one on smooth parts."""
    if diff == 0.0 or scale == 0.0:
        return diff
    return scale * min(1.0, (200.0 * diff / scale) ** 1.5)


@njit(cache=True)
def _band_overlaps(low, v, edges, out, w):
    """Adds ``w`` times the length (mm) of [low, low + v] within each band [edges[i], edges[i + 1]]
    to ``out[i]``."""
    high = low + v
    for i in range(edges.shape[0] - 1):
        a = max(low, edges[i])
        b = min(high, edges[i + 1])
        if b > a:
            out[i] += w * (b - a)


@njit(cache=True)
def _gk_y(x, a, b, ra, rb, S, P, R, C, CB, PP, NPC, RR, zb, zt, edges, kb, change):
    """Gauss-Kronrod on y in [a, b] at ``x``: (the integral, its error); the Kronrod sums of the
    removed height within each band of ``edges`` are added to ``kb``. ``change`` gets the first
    place along y where the nodes' :func:`_state` changes: (the two nodes' y, their states), or a
    state of -1 where all nodes are in one state."""
    k = 0.0
    g = 0.0
    m = 0.0
    ys = np.empty(15)
    sts = np.empty(15, dtype=np.int64)
    for i in range(15):
        u, wk, wg = _node(i)
        y, w = _ends_map(a, b, u, ra, rb)
        v, cause, own = height_and_cause(x, y, S, P, R, C, CB, PP, NPC, RR, zb, zt)
        f = v * w
        k += wk * f
        g += wg * f
        m += wk * abs(f)
        if v > 0.0:
            _band_overlaps(max(own, zb), v, edges, kb, wk * w)
        ys[i] = y
        sts[i] = _code(v, cause, own, zb)
    order = np.argsort(ys)
    change[2] = -1.0
    for i in range(14):
        p, q = order[i], order[i + 1]
        if sts[p] != sts[q]:
            change[0], change[1], change[2], change[3] = ys[p], ys[q], sts[p], sts[q]
            break
    return k, _error(abs(k - g), m)


@njit(cache=True)
def _worst(err, val, n):
    """Index of the largest of err[:n], the sum of err[:n] and the sum of val[:n]."""
    k = 0
    total = 0.0
    value = 0.0
    for i in range(n):
        total += err[i]
        value += val[i]
        if err[i] > err[k]:
            k = i
    return k, total, value


@njit(cache=True)
def next_split(lo, hi, val, err, n, budget, rel):
    """The part of the first ``n`` (ends ``lo``, ``hi``; values ``val``, error estimates ``err``) that an
    adaptive rule with a global budget (QUADPACK's QAG) splits next: the one with the largest estimate,
    while the estimates add up to more than the looser of ``budget`` and ``rel`` of the values' sum; a
    part :data:`MIN_PART` wide or less is as fine as it goes and taken as it is (its estimate set to 0).
    -1 where the rule is done."""
    while True:
        k, total, value = _worst(err, val, n)
        if total <= max(budget, rel * abs(value)) or err[k] == 0.0:
            return -1
        if hi[k] - lo[k] > MIN_PART:
            return k
        err[k] = 0.0


@njit(cache=True)
def _workspace(nb):
    """The store of an inner integral's parts (:func:`inner_integral`), :data:`_PANELS` of each: ends,
    values, error estimates, whether each end is flagged, band sums (``nb`` bands) and the change of
    state their nodes saw. Allocated once a cell: a line's integral fills what it uses."""
    return (np.empty(_PANELS), np.empty(_PANELS), np.empty(_PANELS), np.empty(_PANELS),
            np.empty(_PANELS, dtype=np.bool_), np.empty(_PANELS, dtype=np.bool_), np.empty((_PANELS, nb)),
            np.empty((_PANELS, 4)))


@njit(cache=True)
def inner_integral(x, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt, budget, rel, edges, work):
    """(integral over y in [ylo, yhi] of the removed height at ``x`` (mm²), to ``budget`` mm² in all
    or ``rel`` of itself, whichever is looser;
    the same integral of the removed height within each band of ``edges`` (its error not controlled
    on its own: it shares the whole integral's nodes)). ``work``: the parts' store
    (:func:`_workspace`), reused from line to line."""
    pts, owners, rims = crossings_at_x(x, circles, segments, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb)
    pts, live, rim = _with_kinks(x, pts, owners, rims, S, P, R, C, CB, PP, NPC, RR, zb, zt)
    lo, hi, val, err, ra, rb, bands, changes = work
    n = 0
    for p in range(pts.shape[0] - 1):
        if live[p] and n < _PANELS:
            lo[n], hi[n], ra[n], rb[n] = pts[p], pts[p + 1], rim[p], rim[p + 1]
            bands[n] = 0.0
            val[n], err[n] = _gk_y(x, lo[n], hi[n], ra[n], rb[n], S, P, R, C, CB, PP, NPC, RR, zb, zt, edges, bands[n],
                                   changes[n])
            n += 1
    while n < _PANELS:
        k = next_split(lo, hi, val, err, n, budget, rel)
        if k < 0:
            break
        a, b = lo[k], hi[k]
        # a kink the probes missed (a narrow crescent of removed material between two of them) is
        # split at, found between the nodes that straddle it; else the part is halved
        m = 0.5 * (a + b)
        at_kink = False
        c = changes[k]
        if c[2] >= 0.0:
            y = _kink(x, c[0], c[1], int(c[2]), int(c[3]), S, P, R, C, CB, PP, NPC, RR, zb, zt)
            if a + MIN_PART < y < b - MIN_PART:
                m = y
                at_kink = True
        hi[k] = m
        lo[n], hi[n], ra[n], rb[n] = m, b, at_kink, rb[k]
        rb[k] = at_kink
        bands[k] = 0.0
        bands[n] = 0.0
        val[k], err[k] = _gk_y(x, a, m, ra[k], rb[k], S, P, R, C, CB, PP, NPC, RR, zb, zt, edges, bands[k],
                               changes[k])
        val[n], err[n] = _gk_y(x, m, b, ra[n], rb[n], S, P, R, C, CB, PP, NPC, RR, zb, zt, edges, bands[n],
                               changes[n])
        n += 1
    return val[:n].sum(), bands[:n].sum(axis=0)


@njit(cache=True)
def _gk_x(a, b, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt, budget, rel, edges, kb, work,
          exact):
    """Gauss-Kronrod on x in [a, b] of the inner integrals: (the integral, its error); each band's Kronrod
    sum is added to ``kb``. ``exact``: the inner integrals in closed form (:mod:`.sections`)."""
    k = 0.0
    g = 0.0
    m = 0.0
    vb = np.zeros(kb.shape[0])
    for i in range(15):
        u, wk, wg = _node(i)
        x, w = _smooth(a, b, u)
        if exact:
            vb[:] = 0.0
            v = section_integral(x, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt, edges, vb)
        else:
            v, vb = inner_integral(x, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt, budget, rel,
                                   edges, work)
        f = v * w
        k += wk * f
        g += wg * f
        m += wk * abs(f)
        kb += (wk * w) * vb
    return k, _error(abs(k - g), m)


@njit(cache=True)
def _signature(x, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """A hash of the line at ``x``: the sequence of :func:`_state` along it (equal neighbours merged),
    probed as :func:`_with_kinks` probes it (a stretch proven empty is one state 0; the others at
    :data:`N_PROBE` + 1 samples), without placing the changes: only the sequence counts here. The
    inner integral is smooth in ``x`` while the sequence stays the same; where it changes (a kink
    curve turns back, two cross, the removed region starts or ends) it is not."""
    pts = crossings_at_x(x, circles, segments, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb)[0]
    h = np.int64(7)
    last = np.int64(-2)
    for p in range(pts.shape[0] - 1):
        a, b = pts[p], pts[p + 1]
        if b - a <= 4 * KINK_TOL:
            continue  # no state of its own: where two crossings all but coincide (nearly tangent curves) it
            # would come and go from line to line
        n = 0 if _nothing_removed(x, a, b, S, P, R, C, CB, PP, NPC, RR, zb, zt) else N_PROBE
        for i in range(n + 1):
            st = np.int64(0)
            if n > 0:
                y = a + KINK_TOL if i == 0 else (a + (b - a) * i / N_PROBE if i < N_PROBE else b - KINK_TOL)
                st = np.int64(_state(x, y, S, P, R, C, CB, PP, NPC, RR, zb, zt))
            if st != last:
                h = h * np.int64(1000003) + st + np.int64(11)
                last = st
    return h


@njit(cache=True)
def _with_x_kinks(xs, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """``xs`` with the places added where the lines' :func:`_signature` changes: probed at
    :data:`N_PROBE` + 1 even lines between break points, bisected to :data:`X_KINK_TOL` mm, so that
    the outer integral's parts end where its integrand is not smooth. Between two probes the
    changes are found one after the other (up to :data:`MAX_CHANGES`): a bisection finds one, and
    the line :data:`CLUSTER` of the probes' spacing past it starts the search for the next."""
    out = [xs[0]]
    for p in range(xs.shape[0] - 1):
        a, b = xs[p], xs[p + 1]
        if b - a > 4 * X_KINK_TOL:
            prev_x = a + X_KINK_TOL
            prev = _signature(prev_x, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt)
            for i in range(1, N_PROBE + 1):
                x = a + (b - a) * i / N_PROBE if i < N_PROBE else b - X_KINK_TOL
                sig = _signature(x, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt)
                for _ in range(MAX_CHANGES):  # each change between the two lines, one after the other
                    if sig == prev:
                        break
                    lo, hi = prev_x, x
                    while hi - lo > X_KINK_TOL:
                        m = 0.5 * (lo + hi)
                        if _signature(m, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt) == prev:
                            lo = m
                        else:
                            hi = m
                    out.append(0.5 * (lo + hi))
                    prev_x = min(hi + CLUSTER * (b - a) / N_PROBE, x)
                    prev = _signature(prev_x, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt)
                prev, prev_x = sig, x
        out.append(b)
    return np.array(out)


@njit(cache=True)
def rough_volume(x0, x1, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """A rough removed volume (mm³) over [x0, x1] x [ylo, yhi]: the mean removed height at the middles of its
    3 x 3 parts times its area. Only an order of the cells, never a result."""
    total = 0.0
    for i in range(3):
        for j in range(3):
            x, y = x0 + (i + 0.5) * (x1 - x0) / 3, ylo + (j + 0.5) * (yhi - ylo) / 3
            total += height_and_cause(x, y, S, P, R, C, CB, PP, NPC, RR, zb, zt)[0]
    return total / 9.0 * (x1 - x0) * (yhi - ylo)


@njit(cache=True)
def removed_volume(xs, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt, tol, rel, edges, exact=False):
    """(the removed volume (mm³) over x between the sorted break points ``xs`` and y in [ylo, yhi],
    to ``tol`` mm per mm² of that rectangle or ``rel`` of the volume, whichever is looser; the volume
    removed within each band [edges[i], edges[i + 1]] of machine heights, on the same nodes). A tenth
    of each goes to the inner integrals (each line's error within a tenth of ``tol (yhi - ylo)`` or of
    ``rel`` of the line's integral), the rest to the outer one; with ``exact``, the inner integrals are in
    closed form (:func:`.sections.section_integral`, for sweeps :func:`.sections.sections_apply` accepts).
    The bands' volumes are as exact as the whole where the removed height's ends do not cross a
    band's edge within a part; where they do, the part is only as fine as the whole needs."""
    area = (xs[-1] - xs[0]) * (yhi - ylo)
    xs = _with_x_kinks(xs, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt)
    budget = 0.9 * tol * area
    inner = 0.1 * tol * (yhi - ylo)
    nb = max(edges.shape[0] - 1, 0)
    lo = np.empty(_PANELS)
    hi = np.empty(_PANELS)
    val = np.empty(_PANELS)
    err = np.empty(_PANELS)
    bands = np.zeros((_PANELS, nb))
    work = _workspace(nb)
    n = 0
    for p in range(xs.shape[0] - 1):
        if xs[p + 1] - xs[p] > 0.0 and n < _PANELS:
            lo[n], hi[n] = xs[p], xs[p + 1]
            val[n], err[n] = _gk_x(lo[n], hi[n], ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt,
                                   inner, 0.1 * rel, edges, bands[n], work, exact)
            n += 1
    while n < _PANELS:
        k = next_split(lo, hi, val, err, n, budget, 0.9 * rel)
        if k < 0:
            break
        a, b = lo[k], hi[k]
        m = 0.5 * (a + b)
        hi[k] = m
        bands[k] = 0.0
        val[k], err[k] = _gk_x(a, m, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt, inner,
                               0.1 * rel, edges, bands[k], work, exact)
        lo[n], hi[n] = m, b
        val[n], err[n] = _gk_x(m, b, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt, inner,
                               0.1 * rel, edges, bands[n], work, exact)
        n += 1
    return val[:n].sum(), bands[:n].sum(axis=0)
