"""Volume a flat end mill removes where the sweeps shaping it share one axis or are level: the inner
integral over the angle about the axis in closed form.

Machine frame, mm, radians. The axis is the centre of the CL's arc or helix; for a level CL (a level
line, a plunge), that of an earlier helix or ramped arc (a helical entry whose last turn left a ramped
ledge that the level cuts after it meet: :func:`polar_axis`). In polar coordinates ``(r, theta)`` about
it, a flat end mill's arc or helix about the same centre (radius ``rho``, angles ``[lo, hi]``, tip
height linear in the angle) holds the point at ``(r, theta)`` from the path angles within ``alpha(r)``
of ``theta`` (``cos alpha = (rho^2 + r^2 - R^2) / (2 rho r)``), and its lower surface there is the tip
height at one end of those angles within ``[lo, hi]``: **linear in theta** (or constant) between the
angles where an end of the window meets an end of the arc, ``theta = e +- alpha(r)`` (``e`` an end, or
an end a turn in: a helix of more than a turn is lowest on its last turn, :mod:`.sweeps`); the removed
height bends where that surface crosses the stock's top or bottom or a level sweep's height, which is
where the window's end meets the path angle ``e`` at that height: those are ends too (:func:`_axial`). A
level sweep, a plunge and a round bar's outside (and a level CL) have one constant lower surface over
their footprint, which the circle of radius ``r`` enters and leaves where it crosses their boundary
curves (:func:`.breaks.boundary_curves`). So along that circle, between the angles where any of that
happens or the circle crosses a cell's edge (:func:`ring_breaks`), every lower surface is linear in
``theta``, and the removed height ``max(0, min(h, z_top) - max(L, z_bottom))`` (:mod:`.volume`) is
piecewise linear with corners where two of those lines cross, found in closed form: its integral over
the angle is exact (trapezoids between the corners, :func:`ring_integral`), and so are its parts within
each band of heights (corners where a surface crosses a band's edge).

A surface is taken linear on an interval from its values at the interval's thirds, extrapolated to its
ends: exact for a linear function, to a few units of round-off.

The outer integral over ``r`` is adaptive Gauss-Kronrod (7, 15) with a global budget, as
:func:`.volume.removed_volume`'s, with the map of :func:`.volume._smooth` on each part (the circle's
crossings move like a square root near a tangency), between the radii where the structure along the
circle changes (:func:`polar_volume`): where it touches a curve or passes a corner of the cell or a
meeting of two curves at a point near which the CL can remove something (:func:`_removes_near`: in its
footprint, held by no level sweep at or below its lowest tip; elsewhere the integrand is zero around the
point, and so is what the change there does to it), where ``alpha`` starts or ends (``r = |rho - R|``,
``rho + R``), and where two ends' angles ``e_i + alpha`` and ``e_j - alpha`` of arcs with one ``rho``
and ``R`` meet (``alpha = (e_j - e_i) / 2``, in closed form). Where arcs with other radii meet so, the
bend is left to the rule's error estimate, as :mod:`.volume` leaves a kink between its probes to its
own. The radii an earlier helix of a turn or more holds below the CL's lowest tip are skipped
(:func:`held_annuli`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.breaks import curve_meetings_x, edge_crossings
from fusioncut.engines.analytic.sweeps import (ARC, LINE, OUTSIDE, is_flat, lowest_turn_top, point_path_distance,
                                               sweep_lower)
from fusioncut.engines.analytic.volume import _PANELS, _error, _node, _smooth, next_split

AXIS_TOL = 1e-10  # mm: arcs whose centres are this close share the CL's axis
NEAR = 1e-6  # mm: a break radius is kept for a point this close to the CL's footprint
MERGE_TOL = 1e-12  # mm per mm of radius: break radii this close are one
_TWO_PI = 2.0 * math.pi


@njit(cache=True, inline="always")
def _on_axis(S, cx, cy):
    return S[0] == ARC and abs(S[7] - cx) <= AXIS_TOL and abs(S[8] - cy) <= AXIS_TOL and S[9] > 0.0


@njit(cache=True, inline="always")
def _level_flat(S):
    """A sweep whose lower surface is one constant over its footprint (its profile flat): level, a
    plunge (a line whose ends share their XY) or a stock's outside."""
    if S[0] == OUTSIDE or S[3] == S[6]:
        return True
    return S[0] == LINE and S[1] == S[4] and S[2] == S[5]


@njit(cache=True)
def polar_axis(S, P, C, PP, NPC):
    """(cx, cy), the axis the removed height is integrated about (module docstring), or (nan, nan) where
    none applies: the tool is a flat end mill, the CL's sweep ``S`` (profile ``P``) is an arc or helix
    (its centre) or level (a level line, a plunge: the centre of the first earlier arc of ``C`` that is
    not level), and every sweep of ``C`` is flat and either on that axis (:data:`AXIS_TOL`) or level."""
    none = (math.nan, math.nan)
    if not is_flat(P):
        return none
    if S[0] == ARC and S[9] > 0.0:
        cx, cy = S[7], S[8]
    elif S[0] == LINE and _level_flat(S):
        cx, cy = math.nan, math.nan
        for j in range(C.shape[0]):
            if C[j, 0] == ARC and C[j, 9] > 0.0 and not _level_flat(C[j]):
                cx, cy = C[j, 7], C[j, 8]
                break
        if math.isnan(cx):
            return none
    else:
        return none
    for j in range(C.shape[0]):
        k = int(C[j, 12])
        if C[j, 0] != OUTSIDE and not is_flat(PP[k, :NPC[k]]):
            return none
        if not (_level_flat(C[j]) or _on_axis(C[j], cx, cy)):
            return none
    return cx, cy


@njit(cache=True)
def polar_applies(S, P, C, PP, NPC) -> bool:
    """Whether the removed height over cells whose sweeps are ``C`` is integrated about an axis
    (:func:`polar_axis`)."""
    return not math.isnan(polar_axis(S, P, C, PP, NPC)[0])


@njit(cache=True, inline="always")
def _wrap(t):
    """The angle ``t`` in [-pi, pi)."""
    return (t + math.pi) % _TWO_PI - math.pi


@njit(cache=True, inline="always")
def _half_window(r, rho, R):
    """alpha (module docstring): the half-angle of the path angles within ``R`` of a point at ``r`` from
    the centre of an arc of radius ``rho``; 0 where none is, pi where all are."""
    kappa = (rho * rho + r * r - R * R) / (2.0 * rho * r)
    if kappa >= 1.0:
        return 0.0
    if kappa <= -1.0:
        return math.pi
    return math.acos(kappa)


@njit(cache=True)
def _axial(S, P, R, C, PP, NPC, RR, zb, zt, cx, cy):
    """(rows (rho, R) of the CL's arc (where it is one), then of each earlier arc on the axis (cx, cy);
    rows (the arc's row there, an angle ``e``) of their *ends*: the angles ``e`` whose ``e +- alpha``
    bound the pieces where their lower surfaces are linear (each arc's ends, and each end a turn in: a
    helix of more than a turn is lowest on its last) and where the removed height bends: where an arc's
    tip crosses the stock's top or bottom or a level sweep's height, the CL's own where it is level)."""
    levels = [zt, zb]
    if S[0] != ARC:
        levels.append(min(S[3], S[6]) + P[0, 3])
    for j in range(C.shape[0]):
        if _level_flat(C[j]):
            k = int(C[j, 12])
            levels.append(min(C[j, 3], C[j, 6]) + (0.0 if C[j, 0] == OUTSIDE else PP[k, 0, 3]))
    rows = [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)]  # typed for numba; the rows are [1:]
    if S[0] == ARC:
        rows.append((S[9], R, S[10], S[11], S[3] + P[0, 3], S[6] + P[0, 3]))
    for j in range(C.shape[0]):
        if _on_axis(C[j], cx, cy):
            k = int(C[j, 12])
            rows.append((C[j, 9], RR[k], C[j, 10], C[j, 11], C[j, 3] + PP[k, 0, 3], C[j, 6] + PP[k, 0, 3]))
    axial = np.empty((len(rows) - 1, 2))
    ends = [(0.0, 0.0)]  # typed for numba; the ends are [1:]
    for i in range(len(rows) - 1):
        rho, Ri, a0, sw, z0, z1 = rows[i + 1]
        axial[i, 0], axial[i, 1] = rho, Ri
        lo, hi = min(a0, a0 + sw), max(a0, a0 + sw)
        for e in (lo, hi, hi - _TWO_PI, lo + _TWO_PI):
            ends.append((float(i), e))
        if z1 != z0:
            for lv in levels:
                t = (lv - z0) / (z1 - z0)
                if 0.0 < t < 1.0:
                    ends.append((float(i), a0 + t * sw))
    out = np.empty((len(ends) - 1, 2))
    for i in range(1, len(ends)):
        out[i - 1, 0], out[i - 1, 1] = ends[i]
    return axial, out


@njit(cache=True)
def ring_breaks(r, cx, cy, x0, x1, y0, y1, axial, ends, circles, segments):
    """Sorted angles in [-pi, pi], both ends among them, along the circle of radius ``r`` about
    (cx, cy) between which every lower surface and the removed height are linear (module docstring):
    its crossings of the cell's edges, of the ``circles`` and ``segments`` (:func:`.breaks.boundary_curves`'
    columns), and the angles ``e +- alpha`` of the axial arcs' ``ends`` (:func:`_axial`)."""
    out = [-math.pi, math.pi]
    for xe in (x0, x1):
        u = (xe - cx) / r
        if -1.0 <= u <= 1.0:
            a = math.acos(u)
            out.append(a)
            out.append(-a)
    for ye in (y0, y1):
        u = (ye - cy) / r
        if -1.0 <= u <= 1.0:
            a = math.asin(u)
            out.append(a)
            out.append(_wrap(math.pi - a))
    for i in range(ends.shape[0]):
        al = _half_window(r, axial[int(ends[i, 0]), 0], axial[int(ends[i, 0]), 1])
        if 0.0 < al < math.pi:
            out.append(_wrap(ends[i, 1] - al))
            out.append(_wrap(ends[i, 1] + al))
    for i in range(circles.shape[0]):
        dx, dy, q = circles[i, 0] - cx, circles[i, 1] - cy, circles[i, 2]
        d = math.sqrt(dx * dx + dy * dy)
        if d <= 0.0 or d > r + q or d < abs(r - q):
            continue
        c = min(max((r * r + d * d - q * q) / (2.0 * r * d), -1.0), 1.0)
        phi, delta = math.atan2(dy, dx), math.acos(c)
        out.append(_wrap(phi - delta))
        out.append(_wrap(phi + delta))
    for i in range(segments.shape[0]):
        px, py = segments[i, 0] - cx, segments[i, 1] - cy
        ux, uy = segments[i, 2] - segments[i, 0], segments[i, 3] - segments[i, 1]
        uu = ux * ux + uy * uy
        if uu <= 0.0:
            continue
        b = px * ux + py * uy
        disc = b * b - uu * (px * px + py * py - r * r)
        if disc < 0.0:
            continue
        w = math.sqrt(disc)
        for t in ((-b - w) / uu, (-b + w) / uu):
            if 0.0 <= t <= 1.0:
                out.append(math.atan2(py + t * uy, px + t * ux))
    return np.sort(np.array(out))


@njit(cache=True, inline="always")
def _crossing(fa, fb, ga, gb):
    """Where in (0, 1) the lines through (0, fa), (1, fb) and (0, ga), (1, gb) cross; -1 where they do
    not cross strictly inside."""
    da, db = fa - ga, fb - gb
    if (da > 0.0 and db < 0.0) or (da < 0.0 and db > 0.0):
        return da / (da - db)
    return -1.0


@njit(cache=True)
def ring_integral(r, S, P, R, C, CB, PP, NPC, RR, zb, zt, x0, x1, y0, y1, axial, ends, circles, segments, edges,
                  bands, cx, cy):
    """integral over theta of the removed height at radius ``r`` about the axis (cx, cy) within the
    cell [x0, x1] x [y0, y1] (mm², no factor ``r``), exact (module docstring); its parts within each
    band [edges[i], edges[i + 1]] are added to ``bands``."""
    ts = ring_breaks(r, cx, cy, x0, x1, y0, y1, axial, ends, circles, segments)
    nb = max(edges.shape[0] - 1, 0)
    nc = C.shape[0]
    fa = np.empty(nc + 1)  # the surfaces at the interval's ends: the CL's first, then the earlier ones
    fb = np.empty(nc + 1)
    sub = np.empty(4 * (nc + 2) * (nc + 2) + 4 * (nc + 2) * (nb + 1) + 2)
    total = 0.0
    for p in range(ts.shape[0] - 1):
        a, b = ts[p], ts[p + 1]
        if b - a <= 0.0:
            continue
        xm, ym = cx + r * math.cos(0.5 * (a + b)), cy + r * math.sin(0.5 * (a + b))
        if not (x0 <= xm <= x1 and y0 <= ym <= y1):
            continue
        t1, t2 = a + (b - a) / 3.0, a + 2.0 * (b - a) / 3.0
        c1, s1, c2, s2 = math.cos(t1), math.sin(t1), math.cos(t2), math.sin(t2)
        v1 = sweep_lower(S, P, R, cx + r * c1, cy + r * s1, 0.0)
        if v1 == math.inf:
            continue
        v2 = sweep_lower(S, P, R, cx + r * c2, cy + r * s2, 0.0)
        if v2 == math.inf:
            continue
        fa[0], fb[0] = 2.0 * v1 - v2, 2.0 * v2 - v1
        m = 1
        px1, py1 = cx + r * c1, cy + r * s1
        for j in range(nc):
            if px1 < CB[j, 0] or px1 > CB[j, 2] or py1 < CB[j, 1] or py1 > CB[j, 3]:
                continue  # beyond its footprint's box at a third, so beyond its footprint all along
            k = int(C[j, 12])
            w1 = sweep_lower(C[j], PP[k, :NPC[k]], RR[k], px1, py1, 0.0)
            if w1 == math.inf:
                continue  # absent all along the interval
            w2 = sweep_lower(C[j], PP[k, :NPC[k]], RR[k], cx + r * c2, cy + r * s2, 0.0)
            if w2 == math.inf:
                continue  # at a footprint's edge, to round-off
            fa[m], fb[m] = 2.0 * w1 - w2, 2.0 * w2 - w1
            if fa[m] < zt or fb[m] < zt:  # else above the top all along
                m += 1
        # the corners of the piecewise linear height: two surfaces, or a surface and a level (the top,
        # the bottom, a band's edge), crossing inside the interval; u in (0, 1) along it
        ns = 0
        sub[ns] = 0.0
        sub[ns + 1] = 1.0
        ns += 2
        for i in range(m):
            for j in range(i + 1, m):
                u = _crossing(fa[i], fb[i], fa[j], fb[j])
                if u > 0.0:
                    sub[ns] = u
                    ns += 1
            for lv in range(-2, nb + 1):
                z = zt if lv == -2 else (zb if lv == -1 else edges[lv])
                u = _crossing(fa[i], fb[i], z, z)
                if u > 0.0:
                    sub[ns] = u
                    ns += 1
        us = np.sort(sub[:ns])
        prev_u, prev_g = 0.0, 0.0
        for q in range(ns):
            u = us[q]
            low = max(zb, fa[0] + u * (fb[0] - fa[0]))
            high = zt
            for j in range(1, m):
                high = min(high, fa[j] + u * (fb[j] - fa[j]))
            g = max(high - low, 0.0)
            if q > 0 and u > prev_u:
                w = 0.5 * (u - prev_u) * (b - a)
                total += w * (g + prev_g)
            if nb > 0 and q > 0 and u > prev_u:
                # each band's overlap: linear between the corners as well (its own corners, where a
                # surface meets a band's edge, are among them)
                for e in range(nb):
                    ov = _overlap(fa, fb, m, prev_u, zb, zt, edges[e], edges[e + 1]) + \
                        _overlap(fa, fb, m, u, zb, zt, edges[e], edges[e + 1])
                    bands[e] += 0.5 * (u - prev_u) * (b - a) * ov
            prev_u, prev_g = u, g
    return total


@njit(cache=True, inline="always")
def _overlap(fa, fb, m, u, zb, zt, e0, e1):
    """The length (mm) of [max(L, zb), min(h, zt)] within [e0, e1] at ``u`` along an interval."""
    low = max(zb, fa[0] + u * (fb[0] - fa[0]))
    high = zt
    for j in range(1, m):
        high = min(high, fa[j] + u * (fb[j] - fa[j]))
    return max(min(high, e1) - max(low, e0), 0.0)


@njit(cache=True, inline="always")
def _removes_near(px, py, S, P, R, C, PP, NPC, RR):
    """Whether the CL can remove anything near the point: it lies in the CL's footprint (widened by
    :data:`NEAR` mm) and no level sweep at or below the CL's lowest tip holds it with :data:`NEAR` to
    spare. Elsewhere the removed height is zero around it, so what happens to the structure along a
    circle through it changes the integrand only where it is zero."""
    if sweep_lower(S, P, R, px, py, NEAR) == math.inf:
        return False
    floor = min(S[3], S[6]) + P[0, 3]
    for j in range(C.shape[0]):
        if not _level_flat(C[j]):
            continue
        if C[j, 0] == OUTSIDE:
            if C[j, 3] <= floor and math.hypot(px - C[j, 7], py - C[j, 8]) >= C[j, 9] + NEAR:
                return False
            continue
        k = int(C[j, 12])
        if min(C[j, 3], C[j, 6]) + PP[k, 0, 3] <= floor and point_path_distance(C[j], px, py) <= RR[k] - NEAR:
            return False
    return True


@njit(cache=True, inline="always")
def _footprint_radii(S, R, cx, cy):
    """(least, greatest) distance (mm) from the axis (cx, cy) to the CL's footprint, or bounds of them: an
    arc's about the axis, [rho - R, rho + R]; a line's, within R of the segment between its ends."""
    if S[0] == ARC:
        return max(S[9] - R, 0.0), S[9] + R
    ux, uy = S[4] - S[1], S[5] - S[2]
    px, py = cx - S[1], cy - S[2]
    uu = ux * ux + uy * uy
    t = min(max((px * ux + py * uy) / uu, 0.0), 1.0) if uu > 0.0 else 0.0
    near = math.hypot(px - t * ux, py - t * uy)
    far = max(math.hypot(px, py), math.hypot(cx - S[4], cy - S[5]))
    return max(near - R, 0.0), far + R


@njit(cache=True)
def _radius_breaks(S, P, R, x0, x1, y0, y1, axial, ends, circles, segments, cx, cy, C, PP, NPC, RR):
    """Sorted radii about the axis (cx, cy) where the structure along the circle may change
    (module docstring), within the CL's footprint's radii and the cell's: the radii where ``alpha``
    of an axial arc starts or ends, and those of the points in the CL's footprint where a circle
    through them touches a curve or the cell's edge or passes a corner: the cell's corners, the
    curves' meetings, their crossings of the cell's edges."""
    nx, ny = min(max(cx, x0), x1), min(max(cy, y0), y1)  # the cell's point nearest the centre
    near, reach = _footprint_radii(S, R, cx, cy)
    rmin = max(math.hypot(nx - cx, ny - cy), near)
    far = 0.0
    for x in (x0, x1):
        for y in (y0, y1):
            far = max(far, math.hypot(x - cx, y - cy))
    rmax = min(reach, far)
    out = [rmin, rmax]
    pts = [(cx, cy)]  # typed for numba; [1:] are the points whose radii are breaks where the CL removes near them
    for x in (x0, x1):
        pts.append((x, min(max(cy, y0), y1)))  # an edge's point nearest the centre
        for y in (y0, y1):
            pts.append((x, y))
    for y in (y0, y1):
        pts.append((min(max(cx, x0), x1), y))
    for i in range(axial.shape[0]):
        out.append(abs(axial[i, 0] - axial[i, 1]))
        out.append(axial[i, 0] + axial[i, 1])
    # where the angles e_i +- alpha of two ends of arcs with one rho and R meet: alpha = (e_j - e_i) / 2
    # (mod pi), at the radii where alpha is that
    for i in range(ends.shape[0]):
        ai = int(ends[i, 0])
        rho, Ri = axial[ai, 0], axial[ai, 1]
        for j in range(i + 1, ends.shape[0]):
            aj = int(ends[j, 0])
            if axial[aj, 0] != rho or axial[aj, 1] != Ri:
                continue
            for sign in (1.0, -1.0):
                al = 0.5 * ((sign * (ends[j, 1] - ends[i, 1])) % _TWO_PI)
                ca = math.cos(al)
                disc = rho * rho * ca * ca - rho * rho + Ri * Ri
                if disc < 0.0:
                    continue
                for root in (rho * ca - math.sqrt(disc), rho * ca + math.sqrt(disc)):
                    if root > 0.0:
                        t = ends[i, 1] + sign * al
                        pts.append((cx + root * math.cos(t), cy + root * math.sin(t)))
    for i in range(circles.shape[0]):
        dx, dy, q = circles[i, 0] - cx, circles[i, 1] - cy, circles[i, 2]
        d = math.hypot(dx, dy)
        if d > 0.0:  # the circle's points nearest and farthest from the centre
            pts.append((circles[i, 0] - q * dx / d, circles[i, 1] - q * dy / d))
            pts.append((circles[i, 0] + q * dx / d, circles[i, 1] + q * dy / d))
        else:
            out.append(q)
    for i in range(segments.shape[0]):
        ax, ay = segments[i, 0], segments[i, 1]
        ux, uy = segments[i, 2] - ax, segments[i, 3] - ay
        pts.append((ax, ay))
        pts.append((ax + ux, ay + uy))
        uu = ux * ux + uy * uy
        if uu > 0.0:
            t = ((cx - ax) * ux + (cy - ay) * uy) / uu
            if 0.0 < t < 1.0:
                pts.append((ax + t * ux, ay + t * uy))
    meet = curve_meetings_x(circles, segments, x0, y0, x1, y1)
    for i in range(1, meet.shape[0]):
        pts.append((meet[i, 0], meet[i, 1]))
    edge = edge_crossings(circles, segments, y0, y1)
    for i in range(edge.shape[0]):
        if x0 <= edge[i, 0] <= x1:
            pts.append((edge[i, 0], edge[i, 1]))
    # the curves' crossings of the cell's edges x = x0 and x = x1: those of y = x0 and y = x1 with x and
    # y swapped
    turned_c = circles.copy()
    turned_c[:, 0], turned_c[:, 1] = circles[:, 1], circles[:, 0]
    turned_s = segments.copy()
    turned_s[:, 0], turned_s[:, 1], turned_s[:, 2], turned_s[:, 3] = \
        segments[:, 1], segments[:, 0], segments[:, 3], segments[:, 2]
    edge = edge_crossings(turned_c, turned_s, x0, x1)
    for i in range(edge.shape[0]):
        if y0 <= edge[i, 0] <= y1:
            pts.append((edge[i, 1], edge[i, 0]))
    for i in range(1, len(pts)):
        px, py = pts[i]
        if _removes_near(px, py, S, P, R, C, PP, NPC, RR):
            out.append(math.hypot(px - cx, py - cy))
    rs = np.unique(np.array(out))
    rs = rs[(rs >= rmin) & (rs <= rmax)]
    # one break for radii apart by round-off (a point reached by two ways): a part between them would
    # cost the rule a whole part
    keep = np.ones(rs.shape[0], dtype=np.bool_)
    last = -math.inf
    for i in range(rs.shape[0]):
        if rs[i] - last <= MERGE_TOL * max(1.0, rs[i]) and i < rs.shape[0] - 1:
            keep[i] = False
        else:
            last = rs[i]
    return rs[keep]


@njit(cache=True)
def _gk_r(a, b, S, P, R, C, CB, PP, NPC, RR, zb, zt, x0, x1, y0, y1, axial, ends, circles, segments, edges, kb, cx,
          cy):
    """Gauss-Kronrod (7, 15) of r times :func:`ring_integral` over r in [a, b] (the map of
    :func:`.volume._smooth`): (the integral, its error); each band's Kronrod sum is added to ``kb``."""
    k = 0.0
    g = 0.0
    m = 0.0
    vb = np.zeros(kb.shape[0])
    for i in range(15):
        u, wk, wg = _node(i)
        r, w = _smooth(a, b, u)
        vb[:] = 0.0
        f = r * w * ring_integral(r, S, P, R, C, CB, PP, NPC, RR, zb, zt, x0, x1, y0, y1, axial, ends, circles, segments,
                                  edges, vb, cx, cy)
        k += wk * f
        g += wg * f
        m += wk * abs(f)
        kb += (wk * r * w) * vb
    return k, _error(abs(k - g), m)


@njit(cache=True)
def held_annuli(S, P, C, PP, NPC, RR):
    """Rows (r0, r1): annuli about the CL's axis where nothing can be removed, each held by an earlier arc
    on the axis of a turn or more: its tool covers every point of [|rho - R|, rho + R] (rho > R) or
    [0, rho + R] on each turn, so its lower surface there is at most the highest tip of its lowest turn
    (the last going down, the first going up), and where that is no higher than the CL's lowest tip,
    the CL's lower surface is nowhere below it."""
    own = min(S[3], S[6]) + P[0, 3]
    cx, cy = polar_axis(S, P, C, PP, NPC)
    out = [(0.0, -1.0)]  # typed for numba; the rows are [1:]
    for j in range(C.shape[0]):
        sw = abs(C[j, 11])
        if not (_on_axis(C[j], cx, cy) and sw >= _TWO_PI):
            continue
        k = int(C[j, 12])
        if lowest_turn_top(C[j]) + PP[k, 0, 3] <= own:
            rho, Rj = C[j, 9], RR[k]
            out.append((max(rho - Rj, 0.0), rho + Rj))
    res = np.empty((len(out) - 1, 2))
    for i in range(1, len(out)):
        res[i - 1, 0], res[i - 1, 1] = out[i]
    return res


@njit(cache=True, inline="always")
def _within(a, b, held):
    """Whether [a, b] lies in one of the annuli ``held``."""
    for i in range(held.shape[0]):
        if held[i, 0] <= a and b <= held[i, 1]:
            return True
    return False


@njit(cache=True)
def polar_volume(x0, x1, y0, y1, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt, tol, rel, edges):
    """(the volume removed over [x0, x1] x [y0, y1] (mm³), to ``tol`` mm per mm² of the cell or ``rel`` of
    the volume, whichever is looser; its parts within each band [edges[i], edges[i + 1]] of machine
    heights), as the integral over ``r`` of :func:`ring_integral` times ``r`` (module docstring). Only
    for sweeps :func:`polar_applies` accepts; ``circles`` and ``segments`` are their boundary curves
    (:func:`.breaks.boundary_curves`)."""
    cx, cy = polar_axis(S, P, C, PP, NPC)
    axial, ends = _axial(S, P, R, C, PP, NPC, RR, zb, zt, cx, cy)
    nb = max(edges.shape[0] - 1, 0)
    rs = _radius_breaks(S, P, R, x0, x1, y0, y1, axial, ends, circles, segments, cx, cy, C, PP, NPC, RR)
    budget = tol * (x1 - x0) * (y1 - y0)
    lo = np.empty(_PANELS)
    hi = np.empty(_PANELS)
    val = np.empty(_PANELS)
    err = np.empty(_PANELS)
    bands = np.zeros((_PANELS, nb))
    n = 0
    held = held_annuli(S, P, C, PP, NPC, RR)
    for p in range(rs.shape[0] - 1):
        if rs[p + 1] > rs[p] and n < _PANELS and not _within(rs[p], rs[p + 1], held):
            lo[n], hi[n] = rs[p], rs[p + 1]
            val[n], err[n] = _gk_r(lo[n], hi[n], S, P, R, C, CB, PP, NPC, RR, zb, zt, x0, x1, y0, y1, axial, ends,
                                   circles, segments, edges, bands[n], cx, cy)
            n += 1
    while n < _PANELS:
        k = next_split(lo, hi, val, err, n, budget, rel)
        if k < 0:
            break
        a, b = lo[k], hi[k]
        m = 0.5 * (a + b)
        hi[k] = m
        bands[k] = 0.0
        val[k], err[k] = _gk_r(a, m, S, P, R, C, CB, PP, NPC, RR, zb, zt, x0, x1, y0, y1, axial, ends, circles,
                               segments, edges, bands[k], cx, cy)
        lo[n], hi[n] = m, b
        val[n], err[n] = _gk_r(m, b, S, P, R, C, CB, PP, NPC, RR, zb, zt, x0, x1, y0, y1, axial, ends, circles,
                               segments, edges, bands[n], cx, cy)
        n += 1
    if n == 0:
        return 0.0, np.zeros(nb)
    return val[:n].sum(), bands[:n].sum(axis=0)
