"""Contact area of a flat end mill's side at a CL's end: one integral around the tool.

Machine frame, mm, radians. A flat end mill's surface of revolution is its flat end (no angular
extent: not counted, :mod:`.area`) and its side, the cylinder of radius ``R`` about the axis at the
CL's end ``e``. A point of the side at angle ``theta`` and height ``z`` is engaged (:mod:`.contact`)
when

* it lies ahead: ``u(theta) . v_xy >= 0`` (:func:`.contact.front_limits`; on the cylinder
  ``rho' = 0``, so the front's closed form does not depend on ``z``),
* the stock held material there: ``q = e + R u(theta)`` strictly inside the stock's box, ``z`` strictly
  between its bottom and top, and below every earlier sweep's lower surface less ``eps``
  (:func:`.contact.material_blocker`): ``z < H(q) = min_j L_j(q) - eps``, footprints widened by ``eps``,
* and, on an arc (XY or vertical), no earlier position of the CL holds it by more than ``eps``: a flat
  end mill's tool at ``t`` holds ``(q, z)`` iff ``|q - c(t)| < R`` and ``z >= z(t)``, so that is
  ``z < m(q)``, the least tip height over the positions within ``R - eps`` of ``q`` (the CL's own lower
  surface with the footprint narrowed by ``eps``; :func:`.contact._past_own_turns`).

Each condition but the first bounds ``z`` on one side, and none depends on ``z`` otherwise, so the
engaged heights at ``theta`` are one interval, and the contact area between heights ``z_lo`` and
``z_hi`` above the tip is

    area = R * integral over the angles ahead of
           max(0, min(e_z + z_hi, z_top, H(q), m(q)) - max(e_z + z_lo, z_bottom)) dtheta      (mm²)

where ``q`` lies inside the stock's box: a one-dimensional integral of lower surfaces, where
:func:`.area.contact_area` integrates the engaged span ``W(z)``, each a scan of the slice. The
integrand jumps where ``q`` crosses a footprint's edge or a face of the stock and bends where its
lower surfaces do (:func:`.breaks.boundary_curves`, whose crossings with the tool's circle are
found in closed form, :func:`.polar.ring_breaks`), and where two of the bounds cross: adaptive
Gauss-Kronrod (7, 15) between those angles, with a global error budget (as :mod:`.volume`) and the
map of :func:`.volume._smooth` on each part (a footprint's edge crossed tangentially ends in a
square root).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.brent import GOLDEN
from fusioncut.engines.analytic.contact import beside_walls, front_limits
from fusioncut.engines.analytic.polar import _wrap, ring_breaks
from fusioncut.engines.analytic.sweeps import LINE, end_velocity, sweep_lower
from fusioncut.engines.analytic.volume import _PANELS, _error, _node, _smooth, next_split


@njit(cache=True)
def _high(theta, S, P, R, low, z1, C, CB, PP, NPC, RR, stock, eps):
    """The top (mm, machine) of the side's engaged heights at machine angle ``theta`` below ``z1``: the least
    of ``z1``, the stock's top, ``m(q)`` and ``H(q)`` (module docstring), -inf where ``q`` is not strictly inside
    the stock's box; once it is at most ``low``, a value at most ``low`` (nothing is engaged there). The front's
    test is left to the caller."""
    qx, qy = S[4] + R * math.cos(theta), S[5] + R * math.sin(theta)
    if not (stock[0] < qx < stock[3] and stock[1] < qy < stock[4]):
        return -math.inf
    high = min(z1, stock[5])
    if S[0] != LINE:  # an arc's own earlier positions (a line's front needs none)
        high = min(high, sweep_lower(S, P, R, qx, qy, -eps))
    for j in range(C.shape[0]):
        if high <= low:
            return high
        if qx < CB[j, 0] - eps or qx > CB[j, 2] + eps or qy < CB[j, 1] - eps or qy > CB[j, 3] + eps:
            continue
        if C[j, 3] - eps >= high and C[j, 6] - eps >= high:
            continue  # its lower surface is nowhere below its path's lowest tip
        k = int(C[j, 12])
        high = min(high, sweep_lower(C[j], PP[k, :NPC[k]], RR[k], qx, qy, eps) - eps)
    return high


@njit(cache=True, inline="always")
def _height(theta, S, P, R, z0, z1, C, CB, PP, NPC, RR, stock, eps):
    """The engaged height (mm) of the side at machine angle ``theta`` between the machine heights z0 and
    z1 (module docstring), the front's test left to the caller."""
    low = max(z0, stock[2])
    return max(_high(theta, S, P, R, low, z1, C, CB, PP, NPC, RR, stock, eps) - low, 0.0)


@njit(cache=True)
def _gk_theta(a, b, S, P, R, z0, z1, C, CB, PP, NPC, RR, stock, eps):
    k = 0.0
    g = 0.0
    m = 0.0
    for i in range(15):
        u, wk, wg = _node(i)
        t, w = _smooth(a, b, u)
        f = w * _height(t, S, P, R, z0, z1, C, CB, PP, NPC, RR, stock, eps)
        k += wk * f
        g += wg * f
        m += wk * abs(f)
    return k, _error(abs(k - g), m)


@njit(cache=True)
def side_area(S, P, R, z_lo, z_hi, C, CB, PP, NPC, RR, stock, eps, circles, segments, rel):
    """(the contact area (mm²) of a flat end mill's side at the end of sweep ``S`` between ``z_lo`` and
    ``z_hi`` mm above the tip, its error estimate), to ``rel`` of the area (module docstring); the
    earlier sweeps ``C`` as :func:`.contact.slice_arcs` takes them, ``circles`` and ``segments`` their
    and the CL's boundary curves (:func:`.breaks.boundary_curves`)."""
    ex, ey, ez = S[4], S[5], S[6]
    z0, z1 = ez + z_lo, ez + z_hi
    if z1 <= z0:
        return 0.0, 0.0
    ts = ring_breaks(R, ex, ey, stock[0], stock[3], stock[1], stock[4], np.zeros((0, 2)), np.zeros((0, 2)),
                     circles, segments)
    vx, vy, _ = end_velocity(S)
    lim = front_limits(vx, vy, 0.0)
    for i in range(lim.shape[0]):
        lim[i] = _wrap(lim[i])  # as ring_breaks' angles, in [-pi, pi)
    ts = np.sort(np.concatenate((ts, lim)))
    lo = np.empty(_PANELS)
    hi = np.empty(_PANELS)
    val = np.empty(_PANELS)
    err = np.empty(_PANELS)
    n = 0
    for p in range(ts.shape[0] - 1):
        a, b = ts[p], ts[p + 1]
        t = 0.5 * (a + b)
        if b > a and n < _PANELS and math.cos(t) * vx + math.sin(t) * vy >= 0.0:
            lo[n], hi[n] = a, b
            val[n], err[n] = _gk_theta(a, b, S, P, R, z0, z1, C, CB, PP, NPC, RR, stock, eps)
            n += 1
    while n < _PANELS:
        k = next_split(lo, hi, val, err, n, 0.0, rel)
        if k < 0:
            break
        a, b = lo[k], hi[k]
        m = 0.5 * (a + b)
        hi[k] = m
        val[k], err[k] = _gk_theta(a, m, S, P, R, z0, z1, C, CB, PP, NPC, RR, stock, eps)
        lo[n], hi[n] = m, b
        val[n], err[n] = _gk_theta(m, b, S, P, R, z0, z1, C, CB, PP, NPC, RR, stock, eps)
        n += 1
    return R * val[:n].sum(), R * err[:n].sum()


@njit(cache=True)
def side_range(S, P, R, z_lo, z_hi, C, CB, PP, NPC, RR, stock, eps, n_scan, circles, segments):
    """(lo, hi): the heights (mm above the tip) between ``z_lo`` and ``z_hi`` where a flat end mill's side at
    the end of sweep ``S`` touches material, or (nan, nan) where it touches none; the sweeps as
    :func:`side_area` takes them.

    At an angle ahead, the engaged heights are one interval from ``low`` (the greater of ``z_lo`` and the
    stock's bottom, the same at every angle) to :func:`_high` (module docstring), so the engaged arcs shrink
    as the height grows: the contact starts at ``low`` wherever any angle is engaged and ends at the greatest
    ``_high`` over the angles ahead. That is sampled at ``n_scan`` angles a turn and beside and between the
    circle's crossings with the earlier footprints' edges ``circles`` and ``segments`` (walls, as
    :func:`.contact.slice_arcs` scans them), and each local maximum among the engaged samples (where none is,
    among all: a last touch between two samples) refined by golden section to ~1e-12 rad, as
    :func:`.contact.slice_margin` refines the material margin."""
    ex, ey, ez = S[4], S[5], S[6]
    low = max(ez + z_lo, stock[2])
    cap = min(ez + z_hi, stock[5])
    if cap <= low:
        return math.nan, math.nan
    vx, vy, _ = end_velocity(S)
    lim = front_limits(vx, vy, 0.0)
    if lim.shape[0] == 2:
        t0 = lim[0]
        t1 = lim[1] if lim[1] > lim[0] else lim[1] + 2.0 * math.pi
    else:
        t0, t1 = 0.0, 2.0 * math.pi  # a plunge: ahead all round
    m = max(8, int(math.ceil((t1 - t0) / (2.0 * math.pi) * n_scan)))
    walls = ring_breaks(R, ex, ey, stock[0], stock[3], stock[1], stock[4], np.zeros((0, 2)), np.zeros((0, 2)),
                        circles, segments)
    beside = beside_walls(walls, (t1 - t0) / m)
    ts = np.empty(m + 1 + beside.shape[0])
    for i in range(m + 1):
        ts[i] = t0 + (t1 - t0) * i / m
    n = m
    for t in beside:
        t = t0 + (t - t0) % (2.0 * math.pi)
        if t < t1:
            n += 1
            ts[n] = t
    ts = np.sort(ts[:n + 1])
    hs = np.empty(n + 1)
    floor = low  # _high's values stop at low: enough where a sample is engaged
    for attempt in range(2):
        best = -math.inf
        for i in range(n + 1):
            hs[i] = _high(ts[i], S, P, R, floor, cap, C, CB, PP, NPC, RR, stock, eps)
            best = max(best, hs[i])
        if best > low:
            break
        floor = -math.inf  # none is: the whole values, whose maxima lead to an engaged sliver between samples
    if best >= cap:
        return low - ez, cap - ez
    for i in range(n + 1):
        if (i > 0 and hs[i] < hs[i - 1]) or (i < n and hs[i] < hs[i + 1]):
            continue
        if (i > 0 and hs[i] == hs[i - 1]) and (i == n or hs[i] == hs[i + 1]):
            continue  # inside a plateau: its ends are refined
        if hs[i] == -math.inf or hs[i] <= floor:
            continue
        a, b = ts[max(i - 1, 0)], ts[min(i + 1, n)]
        c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
        fc = _high(c, S, P, R, floor, cap, C, CB, PP, NPC, RR, stock, eps)
        fd = _high(d, S, P, R, floor, cap, C, CB, PP, NPC, RR, stock, eps)
        for _ in range(48):
            if fc >= fd:
                b, d, fd = d, c, fc
                c = b - GOLDEN * (b - a)
                fc = _high(c, S, P, R, floor, cap, C, CB, PP, NPC, RR, stock, eps)
            else:
                a, c, fc = c, d, fd
                d = a + GOLDEN * (b - a)
                fd = _high(d, S, P, R, floor, cap, C, CB, PP, NPC, RR, stock, eps)
        best = max(best, fc, fd)
    if best <= low:
        return math.nan, math.nan
    return low - ez, best - ez
