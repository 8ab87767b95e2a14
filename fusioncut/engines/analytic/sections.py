"""The removed height's integral along a line ``x = const`` in closed form, where every sweep shaping a
cell is a ball or flat end mill's level line: their lower surfaces' sections are arcs and constants.

Machine frame, mm. Cut by the plane ``x = const``, the lower surface (:mod:`.sweeps`) of

* a **ball** end mill's level line along x (tip height ``z``, radius ``R``), or its plunge, is the lower
  arc of a circle in the (y, z) plane: ``z + R - sqrt(rho^2 - (y - y0)^2)`` for ``|y - y0| <= rho``, with
  ``rho = sqrt(R^2 - dx^2)`` and ``dx`` the distance from ``x`` to the path's x-range (the cylinder
  between the ends, ``dx = 0``, or an end's sphere);
* a ball end mill's level line along y is the constant ``z + R - rho`` over the path's y-range
  (``rho = sqrt(R^2 - (x - x0)^2)``) and its ends' spheres, two such arcs about them: the least of the
  three is the section (each sphere's arc is above the constant where the cylinder is);
* a **flat** end mill's level line in any direction, or its plunge, is the constant ``z`` over the
  interval where the line ``x = const`` crosses its footprint (a stadium: its disks' and its band's
  intervals, whose union is one interval since the stadium is convex).

So along the line, ``h`` (the least of the earlier sweeps' sections, capped by the stock's top) and the
CL's own ``L`` (capped below by the stock's bottom) are each the least of a few *pieces*, arcs and
constants, and the removed height ``max(0, min(h, top) - max(L, bottom))`` follows one piece above and
one below between the points where a piece starts or ends or two pieces cross (:func:`section_breaks`:
arc with arc, arc with a level, in closed form; the levels are the constants, the stock's top and bottom
and the bands' edges). On each such stretch its integral is exact: a constant's times the stretch, an
arc's from :func:`half_disk`. No rule, no error estimate: exact to round-off, as :mod:`.flat` is for
level flat cuts and :mod:`.polar` along a circle about a helix's axis.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.breaks import circle_meetings
from fusioncut.engines.analytic.profile import is_ball, is_flat

CONST, ARC_PIECE = 0.0, 1.0
_NPIECE = 3  # pieces a sweep gives at most (a ball's line along y: its cylinder and its two spheres)


@njit(cache=True, inline="always")
def half_disk(u, r):
    """integral over [0, u] of sqrt(r^2 - v^2) dv (|u| <= r). Near a tangent (|u| close to r) ``r^2 - u^2``
    and ``asin(u / r)`` would lose their digits to cancellation; ``(r - u) (r + u)`` and ``atan2`` keep them."""
    s = math.sqrt(max((r - u) * (r + u), 0.0))
    return 0.5 * (u * s + r * r * math.atan2(u, s))


@njit(cache=True, inline="always")
def _sectionable(S, P, R):
    """A level line or a plunge (kind 0) of a flat end mill, or of a ball end mill along x or y."""
    if S[0] != 0.0:
        return False
    plunge = S[1] == S[4] and S[2] == S[5]
    if not (plunge or S[3] == S[6]):
        return False
    if is_flat(P):
        return True
    return is_ball(P, R) and (S[2] == S[5] or S[1] == S[4])


@njit(cache=True)
def sections_apply(S, P, R, C, PP, NPC, RR) -> bool:
    """Whether the CL's sweep ``S`` and every earlier sweep of ``C`` have sections of arcs and
    constants (module docstring)."""
    if not _sectionable(S, P, R):
        return False
    for j in range(C.shape[0]):
        k = int(C[j, 12])
        if not _sectionable(C[j], PP[k, :NPC[k]], RR[k]):
            return False
    return True


@njit(cache=True, inline="always")
def _put(out, n, kind, a, b, c, m, rho):
    out[n, 0], out[n, 1], out[n, 2], out[n, 3], out[n, 4], out[n, 5] = kind, a, b, c, m, rho
    return n + 1


@njit(cache=True)
def _flat_interval(S, R, x):
    """(lo, hi) of y where the line ``x = const`` crosses the footprint of line ``S`` (radius ``R``): the
    union of its end disks' chords and its band's interval; lo > hi where it does not cross it."""
    lo, hi = math.inf, -math.inf
    for ex, ey in ((S[1], S[2]), (S[4], S[5])):
        d = x - ex
        if abs(d) <= R:
            w = math.sqrt(max((R - d) * (R + d), 0.0))
            lo, hi = min(lo, ey - w), max(hi, ey + w)
    ux, uy = S[4] - S[1], S[5] - S[2]
    length = math.hypot(ux, uy)
    if length == 0.0:
        return lo, hi
    ux, uy = ux / length, uy / length
    dx = x - S[1]
    # the band: t = (p - a) . u in [0, length] and n = (p - a) x u in [-R, R], both linear in y
    y_lo, y_hi = -math.inf, math.inf
    if uy != 0.0:
        t0, t1 = S[2] - dx * ux / uy, S[2] + (length - dx * ux) / uy
        y_lo, y_hi = min(t0, t1), max(t0, t1)
    elif not 0.0 <= dx * ux <= length:
        return lo, hi
    if ux != 0.0:
        n0, n1 = S[2] + (dx * uy - R) / ux, S[2] + (dx * uy + R) / ux
        y_lo, y_hi = max(y_lo, min(n0, n1)), min(y_hi, max(n0, n1))
    elif abs(dx * uy) > R:
        return lo, hi
    if y_lo <= y_hi:
        lo, hi = min(lo, y_lo), max(hi, y_hi)
    return lo, hi


@njit(cache=True)
def _pieces(S, P, R, x, out, n):
    """Appends to ``out`` (rows kind, a, b, c, m, rho) the pieces of sweep ``S``'s section at ``x``
    (module docstring): a constant ``c`` over [a, b], or an arc ``c - sqrt(rho^2 - (y - m)^2)`` over
    [a, b] = [m - rho, m + rho]. The new count."""
    z = min(S[3], S[6])
    if is_flat(P):
        lo, hi = _flat_interval(S, R, x)
        if lo < hi:
            n = _put(out, n, CONST, lo, hi, z, 0.0, 0.0)
        return n
    if S[2] == S[5]:  # along x (or a plunge)
        xa, xb = min(S[1], S[4]), max(S[1], S[4])
        dx = xa - x if x < xa else (x - xb if x > xb else 0.0)
        if dx >= R:
            return n
        rho = math.sqrt((R - dx) * (R + dx))
        return _put(out, n, ARC_PIECE, S[2] - rho, S[2] + rho, z + R, S[2], rho)
    d = abs(x - S[1])  # along y
    if d >= R:
        return n
    rho = math.sqrt((R - d) * (R + d))
    ya, yb = min(S[2], S[5]), max(S[2], S[5])
    n = _put(out, n, CONST, ya, yb, z + R - rho, 0.0, 0.0)
    n = _put(out, n, ARC_PIECE, ya - rho, ya + rho, z + R, ya, rho)
    return _put(out, n, ARC_PIECE, yb - rho, yb + rho, z + R, yb, rho)


@njit(cache=True, inline="always")
def _value(piece, y):
    if piece[0] == CONST:
        return piece[3]
    u = y - piece[4]
    return piece[3] - math.sqrt(max((piece[5] - u) * (piece[5] + u), 0.0))


@njit(cache=True, inline="always")
def _integral(piece, a, b):
    """integral over [a, b] of the piece's height."""
    if piece[0] == CONST:
        return piece[3] * (b - a)
    return piece[3] * (b - a) - (half_disk(b - piece[4], piece[5]) - half_disk(a - piece[4], piece[5]))


@njit(cache=True)
def section_breaks(pieces, n, levels, ylo, yhi):
    """Sorted y in [ylo, yhi], both among them, where a piece starts or ends or two pieces, or a piece
    and a level, cross."""
    out = [ylo, yhi]
    for i in range(n):
        out.append(pieces[i, 1])
        out.append(pieces[i, 2])
        if pieces[i, 0] != ARC_PIECE:
            continue
        m, c, rho = pieces[i, 4], pieces[i, 3], pieces[i, 5]
        for k in range(levels.shape[0] + n):
            if k < levels.shape[0]:
                lv = levels[k]
            elif pieces[k - levels.shape[0], 0] == CONST:
                lv = pieces[k - levels.shape[0], 3]
            else:
                continue
            dz = c - lv
            if 0.0 <= dz <= rho:
                w = math.sqrt(max((rho - dz) * (rho + dz), 0.0))
                out.append(m - w)
                out.append(m + w)
        for j in range(i + 1, n):
            if pieces[j, 0] != ARC_PIECE:
                continue
            # two circles in the (y, z) plane about (m, c) and (m2, c2)
            met, y0, _, y1, _ = circle_meetings(m, c, rho, pieces[j, 4], pieces[j, 3], pieces[j, 5])
            if met:
                out.append(y0)
                out.append(y1)
    ys = np.sort(np.array(out))
    return ys[(ys >= ylo) & (ys <= yhi)]


@njit(cache=True, inline="always")
def _least(pieces, lo, hi, y):
    """(index of the least piece among ``pieces[lo:hi]`` holding ``y`` within its [a, b], -1 where
    none does; its height there)."""
    best, v = -1, math.inf
    for i in range(lo, hi):
        if pieces[i, 1] <= y <= pieces[i, 2]:
            w = _value(pieces[i], y)
            if w < v:
                best, v = i, w
    return best, v


@njit(cache=True)
def section_integral(x, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt, edges, bands):
    """(integral over y in [ylo, yhi] of the removed height at ``x`` (mm²), exact (module docstring));
    its parts within each band [edges[i], edges[i + 1]] are added to ``bands``. Only for sweeps
    :func:`sections_apply` accepts."""
    pieces = np.empty((_NPIECE * (C.shape[0] + 1), 6))
    n_own = _pieces(S, P, R, x, pieces, 0)
    if n_own == 0:
        return 0.0
    n = n_own
    for j in range(C.shape[0]):
        if CB[j, 0] <= x <= CB[j, 2]:
            k = int(C[j, 12])
            n = _pieces(C[j], PP[k, :NPC[k]], RR[k], x, pieces, n)
    nb = max(edges.shape[0] - 1, 0)
    levels = np.empty(2 + edges.shape[0])
    levels[0], levels[1] = zb, zt
    levels[2:] = edges
    ys = section_breaks(pieces, n, levels, ylo, yhi)
    total = 0.0
    for p in range(ys.shape[0] - 1):
        a, b = ys[p], ys[p + 1]
        if b <= a:
            continue
        ym = 0.5 * (a + b)
        own, low = _least(pieces, 0, n_own, ym)
        if own < 0:
            continue  # beyond the CL's footprint
        cause, high = _least(pieces, n_own, n, ym)
        if high <= max(low, zb) or zt <= max(low, zb):
            continue
        top = _integral(pieces[cause], a, b) if high < zt else zt * (b - a)
        bottom = _integral(pieces[own], a, b) if low > zb else zb * (b - a)
        total += top - bottom
        for e in range(nb):
            e0, e1 = edges[e], edges[e + 1]
            hi_v, lo_v = min(high, zt, e1), max(low, zb, e0)
            if hi_v <= lo_v:
                continue
            up = e1 * (b - a) if e1 <= min(high, zt) else top
            down = e0 * (b - a) if e0 >= max(low, zb) else bottom
            bands[e] += up - down
    return total
