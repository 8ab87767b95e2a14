"""An oracle for the analytic engine's volumes where every sweep shaping a cell is a flat end mill's, on
any line, arc or helix: the integral over heights of cross-sections in closed form. Independent of both
the engine's adaptive integral (.volume) and its polar one (.polar), and slower than either on real
cells (its area has corners at heights no break finds), so it checks them in tests only.

Machine frame, mm. A flat end mill at tool position ``c(t)`` holds the disk ``|p - c(t)| <= R`` from its
tip ``z(t)`` up, so a flat sweep's cross-section at height ``z``, ``{p : L(p) <= z}`` (:mod:`.sweeps`), is
the union of the disks along the part of its path whose tip is at or below ``z``
(:func:`section_curves`): a line's part (a sub-segment) is bounded by the circles of radius ``R`` about
its ends and by its two sides; an arc's or a helix's part (a sub-arc) by the circles of radius ``R``
about its ends and of radii ``rho + R`` and ``rho - R`` about the centre (and the radii through its ends,
where those circles touch); a round bar's outside by its circle. The CL removes the point ``(p, z)``
iff ``max(L(p), z_bottom) <= z < min(h(p), z_top)`` (``L`` its own sweep's lower surface, ``h`` the
earlier sweeps' least, :mod:`.volume`). At one ``z``
each of those conditions holds on a set bounded by those curves, so the removed cross-section's area
is the sum of the areas of the regions between the curves (:func:`.flat.plane_stretches`) whose point
is removed (:func:`section_area`): exact to round-off, as the B-Rep engine's planar layers are.

The volume is the integral of that area over ``z`` (a band's volume, its integral over the band):
adaptive Gauss-Kronrod (7, 15) with a global error budget, as :func:`.volume.removed_volume`'s outer
integral, between the heights where the area may jump or bend (:func:`sliced_volume`): each sweep's
lowest and highest tip (a flat sweep's cross-section appears as a whole disk), the stock's top and
bottom, the bands' edges. Between them the area is continuous, and smooth but where a moving curve
passes a meeting of two others or becomes tangent to one, which the rule refines. Above the CL's own
highest tip its cross-section is its whole footprint and the earlier sweeps' only grow, so there the
area does not increase: once it is 0 at a break height it is 0 above it, and the integral stops there.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.flat import plane_stretches
from fusioncut.engines.analytic.sweeps import ARC, LINE, OUTSIDE, is_flat
from fusioncut.engines.analytic.volume import _PANELS, _error, _node, height_and_cause, next_split


@njit(cache=True, inline="always")
def is_flat_sweep(S, P) -> bool:
    """Whether the sweep row ``S`` (its tool's lower profile ``P``) is a flat end mill's line or arc
    (level or not), or a round bar's outside."""
    return S[0] == OUTSIDE or ((S[0] == LINE or S[0] == ARC) and is_flat(P))


@njit(cache=True)
def all_flat(S, P, C, PP, NPC) -> bool:
    """Whether the CL's sweep ``S`` (profile ``P``) and every earlier sweep of ``C`` are flat
    (:func:`is_flat_sweep`)."""
    if not is_flat_sweep(S, P):
        return False
    for j in range(C.shape[0]):
        k = int(C[j, 12])
        if not is_flat_sweep(C[j], PP[k, :NPC[k]]):
            return False
    return True


@njit(cache=True, inline="always")
def _tip_heights(S, P):
    """(the lowest, the highest) tip height of a flat sweep (mm): its path's ends' heights plus its
    bottom's height above the tip (``P[0, 3]``); a stock's outside's ``z0`` twice."""
    if S[0] == OUTSIDE:
        return S[3], S[3]
    a, b = S[3] + P[0, 3], S[6] + P[0, 3]
    return min(a, b), max(a, b)


@njit(cache=True, inline="always")
def _path_point(S, t):
    """The XY of a line's or an arc's path at parameter ``t`` (:mod:`.sweeps`)."""
    if S[0] == LINE:
        return S[1] + t * (S[4] - S[1]), S[2] + t * (S[5] - S[2])
    a = S[10] + t * S[11]
    return S[7] + S[9] * math.cos(a), S[8] + S[9] * math.sin(a)


@njit(cache=True)
def section_curves(z, S, P, R, owner, circles, segments):
    """Appends to ``circles`` (cx, cy, r, owner, 0) and ``segments`` (x0, y0, x1, y1, owner, 0) the curves
    that bound the flat sweep ``S``'s cross-section at height ``z`` (module docstring), none where it is
    empty: the part of the path whose tip is at or below ``z`` is ``t`` in [ta, tb]."""
    if S[0] == OUTSIDE:
        if z >= S[3]:
            circles.append((S[7], S[8], S[9], owner, 0.0))
        return
    za, zb = S[3] + P[0, 3], S[6] + P[0, 3]
    if za == zb:
        if z < za:
            return
        ta, tb = 0.0, 1.0
    else:
        tz = (z - za) / (zb - za)
        if zb < za:  # going down: at or below z from tz on
            if tz > 1.0:
                return
            ta, tb = max(tz, 0.0), 1.0
        else:
            if tz < 0.0:
                return
            ta, tb = 0.0, min(tz, 1.0)
    ax, ay = _path_point(S, ta)
    bx, by = _path_point(S, tb)
    circles.append((ax, ay, R, owner, 0.0))
    if bx != ax or by != ay:
        circles.append((bx, by, R, owner, 0.0))
    if S[0] == LINE:
        n = math.hypot(bx - ax, by - ay)
        if n > 0.0:
            nx, ny = -(by - ay) / n * R, (bx - ax) / n * R
            segments.append((ax + nx, ay + ny, bx + nx, by + ny, owner, 0.0))
            segments.append((ax - nx, ay - ny, bx - nx, by - ny, owner, 0.0))
    elif tb > ta:
        cx, cy, rho = S[7], S[8], S[9]
        circles.append((cx, cy, rho + R, owner, 0.0))
        if rho > R:
            circles.append((cx, cy, rho - R, owner, 0.0))
        # the radii through the sub-arc's ends: an end's circle touches the circles about the centre
        # there, where the region's edge passes from one to the other; a segment's end is an exact
        # break where the touching point, two circles meeting, is found only to round-off (or not)
        lo = max(rho - R, 0.0)
        for e in range(2):
            px, py = (ax, ay) if e == 0 else (bx, by)
            ux, uy = (px - cx) / rho, (py - cy) / rho
            segments.append((cx + lo * ux, cy + lo * uy, cx + (rho + R) * ux, cy + (rho + R) * uy, owner, 0.0))


@njit(cache=True)
def section_area(z, x0, x1, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """The area (mm²) of the part of [x0, x1] x [ylo, yhi] where the CL removes material at height ``z``
    (module docstring; the sweeps as :func:`.volume.height_and_cause` takes them, all flat)."""
    circles = [(0.0, 0.0, 0.0, 0.0, 0.0)]  # typed for numba; the curves are [1:]
    segments = [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)]
    section_curves(z, S, P, R, -1.0, circles, segments)
    if len(circles) == 1:
        return 0.0  # the CL's own sweep is all above z
    for j in range(C.shape[0]):
        k = int(C[j, 12])
        section_curves(z, C[j], PP[k, :NPC[k]], RR[k], float(j), circles, segments)
    ca = np.empty((len(circles) - 1, 5))
    for i in range(1, len(circles)):
        for c in range(5):
            ca[i - 1, c] = circles[i][c]
    sa = np.empty((len(segments) - 1, 6))
    for i in range(1, len(segments)):
        for c in range(6):
            sa[i - 1, c] = segments[i][c]
    areas, px, py = plane_stretches(x0, x1, ylo, yhi, ca, sa)
    total = 0.0
    for i in range(areas.shape[0]):
        v, _, own = height_and_cause(px[i], py[i], S, P, R, C, CB, PP, NPC, RR, zb, zt)
        low = max(own, zb)
        if v > 0.0 and low <= z < low + v:
            total += areas[i]
    return total


@njit(cache=True)
def _gk_z(a, b, x0, x1, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    """Gauss-Kronrod (7, 15) of :func:`section_area` over z in [a, b]: (the integral, its error)."""
    mid, half = 0.5 * (a + b), 0.5 * (b - a)
    k = 0.0
    g = 0.0
    m = 0.0
    for i in range(15):
        u, wk, wg = _node(i)
        f = section_area(mid + half * u, x0, x1, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt)
        k += wk * f
        g += wg * f
        m += wk * f
    return k * half, _error(abs(k - g) * half, m * half)


@njit(cache=True)
def sliced_volume(x0, x1, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt, tol, rel, edges):
    """(the volume removed over [x0, x1] x [ylo, yhi] (mm³), to ``tol`` mm per mm² of the rectangle or
    ``rel`` of the volume, whichever is looser; its parts within each band [edges[i], edges[i + 1]] of
    machine heights), as the integral over z of :func:`section_area` (module docstring). Only for
    sweeps :func:`all_flat` accepts. The bands' edges are break heights, so each part of the rule lies
    in one band."""
    nb = max(edges.shape[0] - 1, 0)
    bands = np.zeros(nb)
    low, high = _tip_heights(S, P)
    z0 = max(zb, low)
    if z0 >= zt:
        return 0.0, bands
    out = [z0, zt, high]
    for i in range(edges.shape[0]):
        out.append(edges[i])
    for j in range(C.shape[0]):
        k = int(C[j, 12])
        a, b = _tip_heights(C[j], PP[k, :NPC[k]])
        out.append(a)
        out.append(b)
    zs = np.unique(np.array(out))
    zs = zs[(zs >= z0) & (zs <= zt)]
    budget = tol * (x1 - x0) * (yhi - ylo)
    above = 1e-3 * tol
    for i in range(zs.shape[0] - 1):
        # above the own sweep's highest tip the area does not increase (module docstring): where it is 0
        # just above a break height (at the height itself a curve may be missing: a sub-arc of one point
        # has no circles about its centre), it is 0 all the way up; the stretch left out, ``above`` mm
        # high, holds at most a thousandth of the budget
        z = zs[i] + above
        if zs[i] >= high and z > zs[i] and \
                section_area(z, x0, x1, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt) == 0.0:
            zs = zs[:i + 1]
            break
    lo = np.empty(_PANELS)
    hi = np.empty(_PANELS)
    val = np.empty(_PANELS)
    err = np.empty(_PANELS)
    n = 0
    for p in range(zs.shape[0] - 1):
        if zs[p + 1] > zs[p] and n < _PANELS:
            lo[n], hi[n] = zs[p], zs[p + 1]
            val[n], err[n] = _gk_z(lo[n], hi[n], x0, x1, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt)
            n += 1
    while n < _PANELS:
        k = next_split(lo, hi, val, err, n, budget, rel)
        if k < 0:
            break
        a, b = lo[k], hi[k]
        m = 0.5 * (a + b)
        hi[k] = m
        val[k], err[k] = _gk_z(a, m, x0, x1, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt)
        lo[n], hi[n] = m, b
        val[n], err[n] = _gk_z(m, b, x0, x1, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt)
        n += 1
    for i in range(n):
        if nb > 0:
            zm = 0.5 * (lo[i] + hi[i])
            for e in range(nb):
                if edges[e] <= zm < edges[e + 1]:
                    bands[e] += val[i]
    return val[:n].sum(), bands
