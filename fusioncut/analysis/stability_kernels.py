"""Compiled ZOA passes of :mod:`fusioncut.analysis.stability`: the limit of many CLs at their speeds and
the nearest stable speed of many CLs, each CL in one pass over the chatter-frequency grid.

Both repeat the arithmetic of the vectorised reference functions of ``stability`` operation for operation
(the eigenvalues ``h +- sqrt(h^2 - det)`` of :func:`~fusioncut.analysis.stability.zoa_curves_many`, the
segment interpolation of :meth:`~fusioncut.analysis.stability.LobeSegments.a_lim`, the unstable ranges of
:func:`~fusioncut.analysis.stability.unstable_speed_ranges` and the search of
:func:`~fusioncut.analysis.stability.nearest_speed_for_all`), so their results equal the reference's to
rounding (``tests/analysis/test_stability_fast.py``). What they leave out cannot change a result:

* the phase ``eps = pi + 2 atan(Im lambda / Re lambda)`` (the costly part of a grid point) is computed
  only at points that end a segment able to lower the result: a lobe's depth interpolated on a segment
  lies between the segment's end depths, so a segment whose ends are both at or above the smallest depth
  found so far (the limit) or above the CL's depth (the nearest speed) cannot matter;
* the within-bracket subsets of segments the reference bisects on give the same minima as all segments.

Units as in ``stability``: ``wc`` rad/s, depths mm, tooth periods s, speeds rev/min.
"""
from __future__ import annotations

import numpy as np
from numba import njit

_TWO_PI = 2.0 * np.pi


@njit(cache=True)
def _eigen_parts(c0, c1, c2, c3, c4, pr, pi_, f):  # pragma: no cover - compiled
    """Re and Im of both eigenvalues of ``Phi alpha0`` at grid point ``f`` (``zoa_curves_many``)."""
    hr = c0 * pr[0, f] + c1 * pr[1, f]
    hi = c0 * pi_[0, f] + c1 * pi_[1, f]
    dr = c2 * pr[2, f] + c3 * pr[3, f] + c4 * pr[4, f]
    di = c2 * pi_[2, f] + c3 * pi_[3, f] + c4 * pi_[4, f]
    big = np.sqrt(0.5 * (np.sqrt(dr * dr + di * di) + abs(dr)))
    small = 0.5 * di / big if big > 0 else 0.0
    if dr >= 0:
        sr, si = big, small
    else:
        sr, si = abs(small), (big if di >= 0 else -big)
    return hr + sr, hi + si, hr - sr, hi - si


@njit(cache=True)
def _depths(coef, scale, pr, pi_, a, lr, li):  # pragma: no cover - compiled
    """Fill ``a`` (F, 2) with the ZOA depth (mm; NaN where ``Re lambda <= 0``) of both eigenvalues at every
    grid point, and ``lr, li`` with the eigenvalues' parts (for the phases computed later)."""
    for f in range(a.shape[0]):
        r0, i0, r1, i1 = _eigen_parts(coef[0], coef[1], coef[2], coef[3], coef[4], pr, pi_, f)
        lr[f, 0], li[f, 0], lr[f, 1], li[f, 1] = r0, i0, r1, i1
        a[f, 0] = scale / r0 if r0 > 0 else np.nan
        a[f, 1] = scale / r1 if r1 > 0 else np.nan


@njit(cache=True)
def _phase(eps, lr, li, f, b):  # pragma: no cover - compiled
    """``eps`` at (f, b), computed once (NaN marks not yet computed; only points with ``Re lambda > 0``)."""
    e = eps[f, b]
    if np.isnan(e):
        e = np.pi + 2.0 * np.arctan(li[f, b] / lr[f, b])
        eps[f, b] = e
    return e


@njit(cache=True)
def _limit(wc, a, lr, li, eps, t):  # pragma: no cover - compiled
    """The ZOA limit (mm) at the tooth period ``t`` (s) from the depths ``a`` of :func:`_depths`: the
    smallest depth on a lobe over every segment between neighbouring grid points of either eigenvalue
    (both ends with a depth, the phase stepping by less than pi), ``inf`` where none crosses a lobe."""
    best = np.inf
    for f in range(1, wc.shape[0]):
        for b in range(2):
            a0, a1 = a[f - 1, b], a[f, b]
            if np.isnan(a0) or np.isnan(a1) or min(a0, a1) >= best:
                continue
            e0 = _phase(eps, lr, li, f - 1, b)
            e1 = _phase(eps, lr, li, f, b)
            if abs(e1 - e0) >= np.pi:
                continue
            u0 = (wc[f - 1] * t - e0) / _TWO_PI
            u1 = (wc[f] * t - e1) / _TWO_PI
            k0, k1 = np.floor(u0), np.floor(u1)
            k = max(k0, k1)
            if k0 != k1 and k >= 0:
                v = a0 + (k - u0) / (u1 - u0) * (a1 - a0)
                best = min(best, v)
    return best


@njit(cache=True)
def zoa_limit_kernel(wc, pr, pi_, coef, scale, period):  # pragma: no cover - compiled
    """The ZOA limit (mm) of each CL ``c`` at its tooth period ``period[c]`` (s) (:func:`_limit`).
    ``coef`` (C, 5): the curve coefficients of each CL; ``scale`` (C,): ``2 pi / (N Ktc)`` in mm per unit
    ``Re lambda``."""
    nf = wc.shape[0]
    out = np.full(coef.shape[0], np.inf)
    a = np.empty((nf, 2))
    lr = np.empty((nf, 2))
    li = np.empty((nf, 2))
    eps = np.empty((nf, 2))
    for c in range(coef.shape[0]):
        _depths(coef[c], scale[c], pr, pi_, a, lr, li)
        eps[:] = np.nan
        out[c] = _limit(wc, a, lr, li, eps, period[c])
    return out


@njit(cache=True)
def _seg_limit(seg, ns, t):  # pragma: no cover - compiled
    """``LobeSegments.a_lim`` of the first ``ns`` segments ``seg`` (rows ``wc0, wc1, a0, a1, e0, e1``) at the
    tooth period ``t``."""
    best = np.inf
    for s in range(ns):
        u0 = (seg[0, s] * t - seg[4, s]) / _TWO_PI
        u1 = (seg[1, s] * t - seg[5, s]) / _TWO_PI
        k0, k1 = np.floor(u0), np.floor(u1)
        k = max(k0, k1)
        if k0 != k1 and k >= 0:
            frac = (k - u0) / (u1 - u0)
            best = min(best, seg[2, s] + frac * (seg[3, s] - seg[2, s]))
    return best


@njit(cache=True)
def _segments_below(wc, a, lr, li, eps, ap, seg):  # pragma: no cover - compiled
    """Fill ``seg`` with the lobe segments that can go below ``ap`` (``LobeSegments.of(below=ap)``); their
    count."""
    ns = 0
    for f in range(wc.shape[0] - 1):
        for b in range(2):
            a0, a1 = a[f, b], a[f + 1, b]
            if np.isnan(a0) or np.isnan(a1) or not min(a0, a1) <= ap:
                continue
            e0 = _phase(eps, lr, li, f, b)
            e1 = _phase(eps, lr, li, f + 1, b)
            if not abs(e1 - e0) < np.pi:
                continue
            seg[0, ns], seg[1, ns], seg[2, ns], seg[3, ns], seg[4, ns], seg[5, ns] = wc[f], wc[f + 1], a0, a1, e0, e1
            ns += 1
    return ns


@njit(cache=True)
def _unstable_ranges(wc, a, lr, li, eps, ap, flutes, lo_c, hi_c, idx, run, turns):  # pragma: no cover
    """``unstable_speed_ranges`` before merging: runs of grid points with ``a < ap`` of either eigenvalue
    through every lobe that reaches ``[lo_c, hi_c]``. Returns ``(lo, hi, count, lobes)``: ``lobes`` is 0,
    or the lobes an eigenvalue's runs span when that exceeds 5000 (then nothing else is computed)."""
    nf = wc.shape[0]
    rlo = np.empty(16)
    rhi = np.empty(16)
    nr = 0
    for b in range(2):
        npts = 0
        for f in range(nf):
            if not np.isnan(a[f, b]) and a[f, b] < ap:
                idx[npts] = f
                npts += 1
        if npts == 0:
            continue
        nruns = 0
        for p in range(npts):
            f = idx[p]
            e = _phase(eps, lr, li, f, b)
            start = p == 0 or idx[p] - idx[p - 1] > 1
            if not start:
                start = abs(e - _phase(eps, lr, li, f - 1, b)) >= np.pi
            if start:
                nruns += 1
            run[p] = nruns - 1
            turns[p] = 60.0 * wc[f] / flutes / _TWO_PI
        kmin = np.inf
        kmax = -np.inf
        for p in range(npts):
            e = eps[idx[p], b]
            kmin = min(kmin, turns[p] / hi_c - e / _TWO_PI)
            kmax = max(kmax, turns[p] / lo_c - e / _TWO_PI)
        k_lo = max(int(np.floor(kmin)), 0)
        k_hi = int(np.ceil(kmax))
        if k_hi - k_lo > 5000:
            return rlo, rhi, nr, k_hi - k_lo
        for k in range(k_lo, k_hi + 1):
            q = 0
            while q < npts:
                r = run[q]
                nmin, nmax = np.inf, -np.inf
                while q < npts and run[q] == r:
                    f = idx[q]
                    n = 60.0 * wc[f] / (flutes * (eps[f, b] + _TWO_PI * k))
                    nmin, nmax = min(nmin, n), max(nmax, n)
                    q += 1
                if nmax >= lo_c and nmin <= hi_c:
                    if nr == rlo.shape[0]:
                        grown_lo, grown_hi = np.empty(2 * nr), np.empty(2 * nr)
                        grown_lo[:nr], grown_hi[:nr] = rlo, rhi
                        rlo, rhi = grown_lo, grown_hi
                    rlo[nr], rhi[nr] = nmin, nmax
                    nr += 1
    return rlo, rhi, nr, 0


@njit(cache=True)
def _nearest(seg, ns, flutes, rpm_c, ap, lo_c, hi_c, mlo, mhi):  # pragma: no cover - compiled
    """``nearest_speed_for_all`` of one CL from its merged unstable ranges ``mlo, mhi``: the ends inside
    ``[lo_c, hi_c]`` nearest first, 20 steps of 0.05 % outwards, 12 bisections; NaN when none works."""
    nk = 0
    cs = np.empty(2 * mlo.shape[0])
    sense = np.empty(2 * mlo.shape[0])
    for j in range(mlo.shape[0]):
        if mlo[j] > lo_c:
            cs[nk], sense[nk] = mlo[j], -1.0
            nk += 1
        if mhi[j] < hi_c:
            cs[nk], sense[nk] = mhi[j], 1.0
            nk += 1
    for j in range(1, nk):  # insertion sort on |speed - rpm|: stable, as Python's sorted
        x, s = cs[j], sense[j]
        i = j - 1
        while i >= 0 and abs(cs[i] - rpm_c) > abs(x - rpm_c):
            cs[i + 1], sense[i + 1] = cs[i], sense[i]
            i -= 1
        cs[i + 1], sense[i + 1] = x, s
    for j in range(nk):
        speed = cs[j]
        found = -1
        prev = speed
        for i in range(1, 21):
            n = speed * (1 + sense[j] * 5e-4 * i)
            if n >= lo_c and n <= hi_c and _seg_limit(seg, ns, 60.0 / (flutes * n)) > ap:
                found = i
                break
            prev = n
        if found < 0:
            continue
        inner = prev
        n = speed * (1 + sense[j] * 5e-4 * found)
        for _ in range(12):
            mid = 0.5 * (inner + n)
            if _seg_limit(seg, ns, 60.0 / (flutes * mid)) > ap:
                n = mid
            else:
                inner = mid
        return n
    return np.nan


@njit(cache=True)
def _merge_clip(lo, hi, n, rpm_lo, rpm_hi):  # pragma: no cover - compiled
    """``np.clip(_merged(ranges), rpm_lo, rpm_hi)`` of the first ``n`` ranges: sorted by their low end
    (insertion sort: a few ranges), overlapping ones joined, then clipped. Returns (lo, hi) arrays."""
    slo = lo[:n].copy()
    shi = hi[:n].copy()
    for j in range(1, n):
        x, y = slo[j], shi[j]
        i = j - 1
        while i >= 0 and slo[i] > x:
            slo[i + 1], shi[i + 1] = slo[i], shi[i]
            i -= 1
        slo[i + 1], shi[i + 1] = x, y
    mlo = np.empty(n)
    mhi = np.empty(n)
    m = 0
    for j in range(n):
        if m > 0 and slo[j] <= mhi[m - 1]:
            mhi[m - 1] = max(mhi[m - 1], shi[j])
        else:
            mlo[m], mhi[m] = slo[j], shi[j]
            m += 1
    for j in range(m):
        mlo[j] = min(max(mlo[j], rpm_lo), rpm_hi)
        mhi[j] = min(max(mhi[j], rpm_lo), rpm_hi)
    return mlo[:m], mhi[:m]


@njit(cache=True)
def zoa_table_kernel(wc, pr, pi_, coef, scale, flutes, rpm, depth, rpm_lo, rpm_hi):  # pragma: no cover
    """Per CL ``c`` its ZOA limit (mm) at ``rpm[c]`` (:func:`zoa_limit_kernel`) and its nearest stable speed
    (rev/min): ``rpm[c]`` when the limit there exceeds ``depth[c]``, else the nearest speed in
    ``[rpm_lo[c], rpm_hi[c]]`` where it does, NaN when none does
    (:func:`~fusioncut.analysis.stability.nearest_stable_rpm`). ``status[c]`` is 0, or the number of lobes
    the speed range spans when that exceeds 5000 (the reference refuses the range; no speed is computed)."""
    nf = wc.shape[0]
    nc = coef.shape[0]
    out = np.full(nc, np.nan)
    limit = np.full(nc, np.inf)
    status = np.zeros(nc, dtype=np.int64)
    a = np.empty((nf, 2))
    lr = np.empty((nf, 2))
    li = np.empty((nf, 2))
    eps = np.empty((nf, 2))
    seg = np.empty((6, 2 * nf))
    idx = np.empty(nf, dtype=np.int64)
    run = np.empty(nf, dtype=np.int64)
    turns = np.empty(nf)
    for c in range(nc):
        _depths(coef[c], scale[c], pr, pi_, a, lr, li)
        eps[:] = np.nan
        ap = depth[c]
        per = 60.0 / (flutes * rpm[c])
        limit[c] = _limit(wc, a, lr, li, eps, per)
        if limit[c] > ap:
            out[c] = rpm[c]
            continue
        ns = _segments_below(wc, a, lr, li, eps, ap, seg)
        if _seg_limit(seg, ns, per) > ap:
            out[c] = rpm[c]
            continue
        rlo, rhi, nr, lobes = _unstable_ranges(wc, a, lr, li, eps, ap, flutes, rpm_lo[c], rpm_hi[c], idx, run, turns)
        if lobes:
            status[c] = lobes
            continue
        mlo, mhi = _merge_clip(rlo, rhi, nr, rpm_lo[c], rpm_hi[c])
        mlo, mhi = _merge_clip(mlo, mhi, mlo.shape[0], rpm_lo[c], rpm_hi[c])
        out[c] = _nearest(seg, ns, flutes, rpm[c], ap, rpm_lo[c], rpm_hi[c], mlo, mhi)
    return limit, out, status
