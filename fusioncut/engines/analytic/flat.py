"""Volume a flat end mill's level cut removes where every sweep shaping it is level and flat: in closed form.

Machine frame, mm. Where the CL's own sweep and every earlier sweep that can shape the removed height in
a cell are a flat end mill moved at one height (a line or an XY arc; :func:`is_level_flat`) or a round
bar's outside (:func:`.sweeps.outside_lower`), each lower surface is one constant over its footprint, so
the removed height ``max(0, min(h, top) - max(L, bottom))`` (:mod:`.volume`) is **constant** between the
footprints' boundary curves (:func:`.breaks.boundary_curves`: circles and segments). Between two
consecutive *events* along x the curves' crossings with a line ``x = const`` keep their order: a curve's
extreme x, a segment's end, two curves meeting (:func:`.breaks.curve_meetings_x`) and a curve meeting the
cell's edges ``y = ylo`` or ``y = yhi`` (:func:`.breaks.edge_crossings`). On such a part ``[a, b]`` the
removed volume is therefore

    sum over the stretches k between consecutive curves spanning the part (the cell's edges among them) of
        c_k * integral over [a, b] of (y_upper_k(x) - y_lower_k(x)) dx

with ``c_k`` the removed height inside the stretch and each curve's ``y(x)`` a circle's branch
``cy +- sqrt(r^2 - (x - cx)^2)`` (its integral in closed form, :func:`_circle_integral`) or a segment's
line: exact up to round-off, no error estimate needed. This is the 2.5D planar cut of the B-Rep engine's
layers, as an integral: no polygon is built.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.breaks import curve_meetings_x, edge_crossings, sweep_curves
from fusioncut.engines.analytic.sections import half_disk
from fusioncut.engines.analytic.sweeps import ARC, LINE, OUTSIDE, is_flat
from fusioncut.engines.analytic.volume import _band_overlaps, height_and_cause


@njit(cache=True)
def is_level_flat(S, P) -> bool:
    """Whether the sweep row ``S`` (its tool's lower profile ``P``) has one constant lower surface over its
    footprint: a flat end mill's line or XY arc at one height, or a round bar's outside."""
    if S[0] == OUTSIDE:
        return True
    return (S[0] == LINE or S[0] == ARC) and S[3] == S[6] and is_flat(P)


@njit(cache=True)
def all_level_flat(S, P, C, PP, NPC, plunges=False) -> bool:
    """Whether the CL's sweep ``S`` (profile ``P``) and every earlier sweep of ``C`` are level and flat
    (:func:`is_level_flat`); with ``plunges``, a flat end mill's plunge counts too (one lower surface
    height over its footprint, its lower end's)."""
    if not _level_flat(S, P, plunges):
        return False
    for j in range(C.shape[0]):
        k = int(C[j, 12])
        if not _level_flat(C[j], PP[k, :NPC[k]], plunges):
            return False
    return True


@njit(cache=True, inline="always")
def _level_flat(S, P, plunges) -> bool:
    return is_level_flat(S, P) or (plunges and S[0] == LINE and S[1] == S[4] and S[2] == S[5] and is_flat(P))


@njit(cache=True, inline="always")
def _circle_integral(cx, r, a, b):
    """integral over x in [a, b] of sqrt(r^2 - (x - cx)^2) dx (a, b within [cx - r, cx + r])."""
    return half_disk(b - cx, r) - half_disk(a - cx, r)


@njit(cache=True, inline="always")
def _segment_y(seg, x):
    return seg[1] + (seg[3] - seg[1]) * (x - seg[0]) / (seg[2] - seg[0])


@njit(cache=True)
def _events(x0, x1, ylo, yhi, circles, segments):
    """Sorted x in [x0, x1], both among them, where the order of the curves' crossings along a line
    x = const may change (module docstring): every one, unlike :func:`.breaks.x_breaks`, which leaves
    out those where nothing is removed around and merges near ones (an adaptive rule's parts may
    straddle a reordering; the closed form's may not)."""
    out = [x0, x1]
    for i in range(circles.shape[0]):
        out.append(circles[i, 0] - circles[i, 2])
        out.append(circles[i, 0] + circles[i, 2])
    for i in range(segments.shape[0]):
        out.append(segments[i, 0])
        out.append(segments[i, 2])
    edge = edge_crossings(circles, segments, ylo, yhi)
    for i in range(edge.shape[0]):
        out.append(edge[i, 0])
    meet = curve_meetings_x(circles, segments, x0, ylo, x1, yhi)
    for i in range(meet.shape[0]):
        out.append(meet[i, 0])
    xs = np.unique(np.array(out))
    return xs[(xs >= x0) & (xs <= x1)]


@njit(cache=True)
def plane_stretches(x0, x1, ylo, yhi, circles, segments):
    """(areas, xs, ys): the regions of the rectangle [x0, x1] x [ylo, yhi] between consecutive curves
    (``circles`` (cx, cy, r, ...) and ``segments`` (x0, y0, x1, y1, ...)) on each part between two
    :func:`_events`, as their areas (mm², in closed form) and one point inside each. Whatever is
    constant between the curves is constant on each region, so its integral over the rectangle is the
    sum of its value at the points times the areas.

    On a part the curves that span it (a circle's two branches, a segment) and the cell's edges are
    ordered by their mean y over it, which orders them at every x inside (they do not cross there), and
    a curve whose mean lies outside [ylo, yhi] lies outside all along (it crosses neither edge): no
    decision rests on one line x = const, where a curve may just touch an edge (a circle's apex on it).
    The point is the middle of the region at the widest of three lines across the part (two curves that
    meet at an end of the part, or touch inside it, leave no width at that line)."""
    xs = _events(x0, x1, ylo, yhi, circles, segments)
    nc, ns = circles.shape[0], segments.shape[0]
    means = np.empty(2 * nc + ns + 2)
    ints = np.empty(2 * nc + ns + 2)
    ids = np.empty(2 * nc + ns + 2, dtype=np.int64)
    areas, px, py = [0.0], [0.0], [0.0]  # typed for numba; the regions are [1:]
    for p in range(xs.shape[0] - 1):
        a, b = xs[p], xs[p + 1]
        if b <= a:
            continue
        xm = 0.5 * (a + b)
        # the curves spanning the part: circle i's lower branch is 2 i, its upper 2 i + 1, segment j
        # 2 nc + j; the cell's edges -1 and -2
        n = 0
        for i in range(-2, 2 * nc + ns):
            if 0 <= i < 2 * nc and abs(xm - circles[i // 2, 0]) >= circles[i // 2, 2]:
                continue
            if i >= 2 * nc:
                sx0, sx1 = segments[i - 2 * nc, 0], segments[i - 2 * nc, 2]
                if not min(sx0, sx1) < xm < max(sx0, sx1):
                    continue
            v = _branch_integral(i, a, b, ylo, yhi, circles, segments, nc)
            mean = v / (b - a)
            if i < 0 or ylo < mean < yhi:
                ints[n], means[n], ids[n] = v, mean, i
                n += 1
        order = np.argsort(means[:n], kind="mergesort")
        for q in range(n - 1):
            lo, hi = order[q], order[q + 1]
            area = ints[hi] - ints[lo]
            if area <= 0.0:
                continue
            best, xb = -1.0, xm
            for x in (a + 0.25 * (b - a), xm, a + 0.75 * (b - a)):
                gap = _branch_y(ids[hi], x, ylo, yhi, circles, segments, nc) - \
                    _branch_y(ids[lo], x, ylo, yhi, circles, segments, nc)
                if gap > best:
                    best, xb = gap, x
            areas.append(area)
            px.append(xb)
            py.append(0.5 * (_branch_y(ids[hi], xb, ylo, yhi, circles, segments, nc)
                             + _branch_y(ids[lo], xb, ylo, yhi, circles, segments, nc)))
    return np.array(areas[1:]), np.array(px[1:]), np.array(py[1:])


@njit(cache=True)
def flat_volume(x0, x1, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt, edges):
    """(the volume removed over [x0, x1] x [ylo, yhi] (mm³), in closed form (module docstring); its parts
    within each band [edges[i], edges[i + 1]] of machine heights). Only for sweeps that
    :func:`all_level_flat` accepts; ``circles`` and ``segments`` are their boundary curves, between which
    the removed height is constant (:func:`plane_stretches`)."""
    nb = max(edges.shape[0] - 1, 0)
    bands = np.zeros(nb)
    areas, xs, ys = plane_stretches(x0, x1, ylo, yhi, circles, segments)
    total = 0.0
    for i in range(areas.shape[0]):
        v, _, own = height_and_cause(xs[i], ys[i], S, P, R, C, CB, PP, NPC, RR, zb, zt)
        if v > 0.0:
            total += v * areas[i]
            if nb > 0:
                _band_overlaps(max(own, zb), v, edges, bands, areas[i])
    return total, bands


@njit(cache=True)
def flat_cells_volume(cells, which, starts, items, S, P, R, C, CB, PP, NPC, RR, zb, zt, edges):
    """(the volume removed over the cells ``which`` marks, mm³; its parts within the bands of ``edges``):
    :func:`flat_volume` of each, in order, with its sweeps ``C[items[starts[i]:starts[i + 1]]]`` and their
    boundary curves with the CL's (:func:`.breaks.sweep_curves` about ``zb`` and ``zt``), as
    :func:`.partition.volume_cells` gives them. One kernel for all of a CL's closed-form cells."""
    bands = np.zeros(max(edges.shape[0] - 1, 0))
    total = 0.0
    for i in range(cells.shape[0]):
        if not which[i]:
            continue
        keep = items[starts[i]:starts[i + 1]]
        rows = np.empty((keep.shape[0] + 1, C.shape[1]))
        rows[0] = S
        rows[1:] = C[keep]
        circles, segments = sweep_curves(rows, PP, NPC, zb, zt)
        v, vb = flat_volume(cells[i, 0], cells[i, 2], cells[i, 1], cells[i, 3], circles, segments, S, P, R, rows[1:],
                            CB[keep], PP, NPC, RR, zb, zt, edges)
        total += v
        bands += vb
    return total, bands


@njit(cache=True)
def _branch_y(i, x, ylo, yhi, circles, segments, nc):
    """The y of curve ``i`` (:func:`plane_stretches`' numbering) at ``x``."""
    if i == -1:
        return ylo
    if i == -2:
        return yhi
    if i < 2 * nc:
        c = i // 2
        u = x - circles[c, 0]
        w = math.sqrt(max((circles[c, 2] - u) * (circles[c, 2] + u), 0.0))
        return circles[c, 1] + (w if i % 2 == 1 else -w)
    return _segment_y(segments[i - 2 * nc], x)


@njit(cache=True)
def _branch_integral(i, a, b, ylo, yhi, circles, segments, nc):
    """integral over x in [a, b] of curve ``i``'s y (:func:`plane_stretches`' numbering)."""
    if i == -1:
        return ylo * (b - a)
    if i == -2:
        return yhi * (b - a)
    if i < 2 * nc:
        c = i // 2
        s = _circle_integral(circles[c, 0], circles[c, 2], a, b)
        return circles[c, 1] * (b - a) + (s if i % 2 == 1 else -s)
    seg = segments[i - 2 * nc]
    return 0.5 * (_segment_y(seg, a) + _segment_y(seg, b)) * (b - a)
