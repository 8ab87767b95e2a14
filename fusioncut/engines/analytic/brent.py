"""Brent's minimisation of a function of one variable as a stepper (R. P. Brent, Algorithms for
Minimization without Derivatives, 1973, ch. 5): parabolic steps through the three best points,
golden-section steps where a parabola's would not shrink the bracket fast enough. The caller evaluates
its own function at each point :func:`brent_next` gives and hands the value to :func:`brent_take`, so
that it may stop early (at the first point of another state, :func:`.volume._dip`). Written out here
because the analytic kernels need it inside numba, where SciPy's ``minimize_scalar`` cannot be called.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

GOLDEN = 0.6180339887498949
# the arcs' windows of tool positions (.sweeps, .vertical) are sampled at ARC_STEP rad at most and each
# sampled local minimum refined until the bracket is T_TOL of its first width; BRENT_STEPS bounds the
# steps (the golden ones alone reach T_TOL in under 50)
ARC_STEP = 0.05  # rad
T_TOL = 1e-10
BRENT_STEPS = 100

# the state: [a, b, x, w, v, fx, fw, fv, d, e, tol], x the best point so far, [a, b] the bracket
_A, _B, _X, _W, _V, _FX, _FW, _FV, _D, _E, _TOL = range(11)


@njit(cache=True, inline="always")
def brent_start(a, x, b, fx, tol):
    """Brent's state on the bracket [a, b] around ``x`` (value ``fx``), to stop once the bracket is
    within ``tol`` of the best point."""
    return np.array([a, b, x, x, x, fx, fx, fx, 0.0, 0.0, tol + 1e-300])


@njit(cache=True, inline="always")
def brent_next(st):
    """The next point to evaluate, or nan once the bracket is within its tolerance."""
    a, b, x, w, v, fx, fw, fv, d, e, tol = st[0], st[1], st[2], st[3], st[4], st[5], st[6], st[7], st[8], st[9], st[10]
    m = 0.5 * (a + b)
    if abs(x - m) <= 2.0 * tol - 0.5 * (b - a):
        return math.nan
    golden = True
    if abs(e) > tol:
        r = (x - w) * (fx - fv)
        q = (x - v) * (fx - fw)
        p = (x - v) * q - (x - w) * r
        q = 2.0 * (q - r)
        if q > 0.0:
            p = -p
        q = abs(q)
        if abs(p) < abs(0.5 * q * e) and p > q * (a - x) and p < q * (b - x):
            e, d = d, p / q
            golden = False
            if x + d - a < 2.0 * tol or b - (x + d) < 2.0 * tol:
                d = tol if x < m else -tol
    if golden:
        e = (a - x) if x >= m else (b - x)
        d = (1.0 - GOLDEN) * e
    st[_D], st[_E] = d, e
    return x + (d if abs(d) >= tol else (tol if d > 0.0 else -tol))


@njit(cache=True, inline="always")
def brent_take(st, u, fu):
    """Take the value ``fu`` at the point ``u`` :func:`brent_next` gave."""
    x = st[_X]
    if fu <= st[_FX]:
        if u >= x:
            st[_A] = x
        else:
            st[_B] = x
        st[_V], st[_FV], st[_W], st[_FW] = st[_W], st[_FW], x, st[_FX]
        st[_X], st[_FX] = u, fu
    else:
        if u < x:
            st[_A] = u
        else:
            st[_B] = u
        if fu <= st[_FW] or st[_W] == x:
            st[_V], st[_FV], st[_W], st[_FW] = st[_W], st[_FW], u, fu
        elif fu <= st[_FV] or st[_V] == x or st[_V] == st[_W]:
            st[_V], st[_FV] = u, fu


@njit(cache=True, inline="always")
def brent_best(st):
    """(the best point so far, its value)."""
    return st[_X], st[_FX]
