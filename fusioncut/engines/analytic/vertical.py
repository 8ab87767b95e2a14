"""Sweeps of a tool of revolution along an arc in a vertical plane (G18 ZX, G19 YZ), exactly.

Machine frame, mm, radians. A vertical arc is a row of :data:`.sweeps.SWEEP_COLUMNS` of kind
:data:`ZX_ARC` (its plane is ``y = cy``, the coordinate along it ``s = x``) or :data:`YZ_ARC` (its
plane ``x = cx``, ``s = y``). Its tip path is, with ``a(t) = a0 + t sw`` (``t`` in [0, 1]),

    s(t) = s_c + rho cos a(t),   z(t) = z_c + rho sin a(t),

the angle measured in the (s, z) plane from +s towards +z (whatever the G-code's sense; ``sw`` signed),
``s_c`` the centre's ``cx`` (ZX) or ``cy`` (YZ), and the centre's height ``z_c = z0 - rho sin a0``
(so the start lies on the circle). ``x0 .. z1`` are its ends.

**A piece lies within one quarter of its circle** (the CL segments are cut so,
:func:`fusioncut.engines.segments.quarter_pieces`): ``s`` and ``z`` are monotone along it. So its XY path is
the segment between its ends' XY and its lowest tip ``min(z0, z1)``, as a ramp's: every reader that
needs only those (footprints, boxes, floors, boundary curves) treats it as the line between its ends.

With ``e`` the point's distance across the plane and ``w = sqrt(R^2 - e^2)``, the tool positions
within ``R`` of ``p`` are those with ``|s(t) - s_p| <= w``: one interval of ``t`` (``s`` is monotone),
the **window**. Over it the lower surface ``L(p) = min z(t) + f(|p - c(t)|)`` is

* a flat end mill's: ``z`` at the window's lower end (``z`` is monotone), in closed form;
* a ball's, in closed form: the lowest point, on the vertical line through ``p``, of the points within
  ``R`` of the ball centres' arc (the tip's arc raised by ``R``). In the plane at distance ``e`` that
  set is the annular sector of radii ``rho -+ w`` over the piece's angles and the two discs of radius
  ``w`` about its ends (a point's nearest point on an arc is its radial projection if that lies on
  the arc, else an end). The lowest point of that closed set on the line is one of its boundary
  points there: where the line crosses a circle of the annulus at an angle within the piece, where
  it crosses a radial edge at a radius within the annulus, or a disc's lowest point on the line;
* any other profile's: the window sampled at :data:`.brent.ARC_STEP` rad at most, each sampled local minimum
  refined by Brent's method (to :data:`.brent.T_TOL` of its bracket), as an XY arc's windows where no
  convexity holds.

``eps`` (mm) widens the footprint as for the other sweeps (:mod:`.sweeps`): ``|p - c(t)| <= R + eps``
with ``f`` held at ``f(R)`` beyond ``R``. For a ball that adds ``f(R) = R`` over the flat end mill's
minimum on the widened window (within ``R`` that value is above the ball's own), so both closed
forms serve; a negative ``eps`` (a footprint shrunk, for a CL's own earlier positions) takes the
sampled way for round profiles.

A point on the tool at the CL's end is strictly inside the tool at an earlier position of its own
vertical arc (the front condition's part beyond the local one, :mod:`.contact`) iff it lies above
the own sweep's lower surface over the footprint shrunk by ``eps``: the tool extends straight up.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.brent import (ARC_STEP, BRENT_STEPS, T_TOL, brent_best, brent_next, brent_start,
                                              brent_take)
from fusioncut.engines.analytic.profile import is_ball, is_flat, profile_height

ZX_ARC, YZ_ARC = 3.0, 4.0
ANGLE_TOL = 1e-12  # rad: a point of an annulus' circle this far beyond the piece's angles is on it
QUARTER_TOL = 1e-9  # rad: a piece may reach this far past a quarter of its circle (rounding of its ends)


@njit(cache=True, inline="always")
def is_vertical(S):
    """Whether the sweep row ``S`` is a vertical arc's."""
    return S[0] == ZX_ARC or S[0] == YZ_ARC


@njit(cache=True, inline="always")
def _frame(S, px, py):
    """(s, e): ``p``'s coordinate along the arc's plane from the circle's centre, its distance across."""
    if S[0] == ZX_ARC:
        return px - S[7], abs(py - S[8])
    return py - S[8], abs(px - S[7])


@njit(cache=True, inline="always")
def _centre_z(S):
    return S[3] - S[9] * math.sin(S[10])


@njit(cache=True, inline="always")
def _angle_of(s, rho, lo, hi):
    """The angle in [lo, hi] (one quarter of the circle) where ``rho cos a = s``, ``s`` clamped to the
    circle: ``cos`` is monotone there, on the upper half's branch of ``acos`` or the lower half's."""
    mid = 0.5 * (lo + hi)
    k = math.floor(mid / (2.0 * math.pi) + 0.5)
    m = mid - 2.0 * math.pi * k
    base = math.acos(min(max(s / rho, -1.0), 1.0))
    a = (base if m > 0.0 else -base) + 2.0 * math.pi * k
    return min(max(a, lo), hi)


@njit(cache=True, inline="always")
def _window(S, sp, w):
    """The angles [a1, a2] (a1 <= a2) of the tool positions with ``|s(t) - s_p| <= w`` (``s`` relative to
    the centre); a1 > a2 where there are none. A window reaching past an end of the piece stops at that
    end's own angle."""
    rho, a0, sw = S[9], S[10], S[11]
    lo, hi = min(a0, a0 + sw), max(a0, a0 + sw)
    s_lo, s_hi = rho * math.cos(lo), rho * math.cos(hi)
    s_min, s_max = min(s_lo, s_hi), max(s_lo, s_hi)
    if sp + w < s_min or sp - w > s_max:
        return 1.0, 0.0
    ends = [0.0, 0.0]
    for i in range(2):
        target = sp - w if i == 0 else sp + w
        if target <= s_min:
            ends[i] = lo if s_lo <= s_hi else hi
        elif target >= s_max:
            ends[i] = hi if s_lo <= s_hi else lo
        else:
            ends[i] = _angle_of(target, rho, lo, hi)
    return min(ends[0], ends[1]), max(ends[0], ends[1])


@njit(cache=True, inline="always")
def _flat_min(S, sp, w):
    """The least tip height over the window of half-width ``w`` (``z`` monotone: at one of its ends);
    inf where it is empty."""
    a1, a2 = _window(S, sp, w)
    if a1 > a2:
        return math.inf
    zc, rho = _centre_z(S), S[9]
    return zc + rho * min(math.sin(a1), math.sin(a2))


@njit(cache=True, inline="always")
def _within(phi, lo, hi):
    """Whether the angle ``phi`` lies in [lo, hi] (modulo a turn, :data:`ANGLE_TOL` either side)."""
    mid = 0.5 * (lo + hi)
    d = (phi - mid + math.pi) % (2.0 * math.pi) - math.pi
    return abs(d) <= 0.5 * (hi - lo) + ANGLE_TOL


@njit(cache=True)
def _ball_lower(S, R, sp, e):
    """A ball end mill's lower surface at (s_p, e) (module docstring); inf beyond the footprint."""
    if e > R:
        return math.inf
    w = math.sqrt((R - e) * (R + e))
    rho, a0, sw = S[9], S[10], S[11]
    lo, hi = min(a0, a0 + sw), max(a0, a0 + sw)
    zr = _centre_z(S) + R
    best = math.inf
    for a in (lo, hi):  # the discs about the ends
        ds = sp - rho * math.cos(a)
        if abs(ds) <= w:
            best = min(best, zr + rho * math.sin(a) - math.sqrt((w - ds) * (w + ds)))
    for r in (rho + w, rho - w):  # the annulus' circles
        if r <= 0.0 or abs(sp) > r:
            continue
        h = math.sqrt((r - sp) * (r + sp))
        for z in (-h, h):
            if zr + z < best and _within(math.atan2(z, sp), lo, hi):
                best = zr + z
    for a in (lo, hi):  # the sector's radial edges
        c = math.cos(a)
        if c != 0.0:
            r = sp / c
            if max(rho - w, 0.0) <= r <= rho + w:
                best = min(best, zr + r * math.sin(a))
    return best


@njit(cache=True, inline="always")
def _value(S, P, R, sp, e, zc, a):
    """``z + f(min(d, R))`` of the tool at angle ``a`` for the point at (s_p, e)."""
    ds = S[9] * math.cos(a) - sp
    d = math.sqrt(e * e + ds * ds)
    return zc + S[9] * math.sin(a) + profile_height(P, min(d, R))


@njit(cache=True)
def _sampled_min(S, P, R, sp, e, a1, a2):
    """The least :func:`_value` over the angles [a1, a2]: sampled, each local minimum refined."""
    zc = _centre_z(S)
    n = max(4, int(math.ceil((a2 - a1) / ARC_STEP)))
    ts = np.empty(n + 1)
    vs = np.empty(n + 1)
    for i in range(n + 1):
        ts[i] = a1 + (a2 - a1) * i / n if i < n else a2
        vs[i] = _value(S, P, R, sp, e, zc, ts[i])
    best = vs.min()
    if a2 - a1 <= 0.0:
        return best
    for i in range(n + 1):
        if (i > 0 and vs[i] > vs[i - 1]) or (i < n and vs[i] > vs[i + 1]):
            continue
        a, b = ts[max(i - 1, 0)], ts[min(i + 1, n)]
        st = brent_start(a, ts[i], b, vs[i], T_TOL * (b - a))
        for _ in range(BRENT_STEPS):
            u = brent_next(st)
            if math.isnan(u):
                break
            brent_take(st, u, _value(S, P, R, sp, e, zc, u))
        best = min(best, brent_best(st)[1])
    return best


@njit(cache=True)
def vertical_lower(S, P, R, px, py, eps):
    """The lower surface (mm) of the vertical arc sweep ``S`` at ``p`` (module docstring), the footprint
    widened by ``eps``; inf beyond it."""
    sp, e = _frame(S, px, py)
    reach = R + eps
    if e > reach:
        return math.inf
    w = math.sqrt((reach - e) * (reach + e))
    if is_flat(P):
        return _flat_min(S, sp, w)
    if is_ball(P, R) and eps >= 0.0:
        v = _ball_lower(S, R, sp, e)
        return min(v, _flat_min(S, sp, w) + R) if eps > 0.0 else v
    a1, a2 = _window(S, sp, w)
    if a1 > a2:
        return math.inf
    return _sampled_min(S, P, R, sp, e, a1, a2)


@njit(cache=True, inline="always")
def vertical_velocity(S):
    """(vx, vy, vz): dc/dt at t = 1 (mm per unit t)."""
    a = S[10] + S[11]
    ds, dz = -S[9] * S[11] * math.sin(a), S[9] * S[11] * math.cos(a)
    if S[0] == ZX_ARC:
        return ds, 0.0, dz
    return 0.0, ds, dz


def vertical_positions(S: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, y, z) of the tip at the parameters ``t`` (arrays, for tests and pictures)."""
    a = S[10] + t * S[11]
    s, z = S[9] * np.cos(a), S[3] - S[9] * math.sin(S[10]) + S[9] * np.sin(a)
    if S[0] == ZX_ARC:
        return S[7] + s, np.full_like(s, S[8]), z
    return np.full_like(s, S[7]), S[8] + s, z


def within_quarter(a0: float, sw: float) -> bool:
    """Whether the angles from ``a0`` to ``a0 + sw`` stay within one quarter of the circle (to
    :data:`QUARTER_TOL`): no multiple of pi/2 lies inside them."""
    lo, hi = min(a0, a0 + sw), max(a0, a0 + sw)
    k = math.ceil((lo + QUARTER_TOL) / (math.pi / 2))
    return k * math.pi / 2 >= hi - QUARTER_TOL
