"""Chatter stability of milling per CL: zero-order approximation (ZOA) and semi-discretization (SD).

Dynamic chip and forces (Altintas & Budak, *CIRP Annals* 44 (1995) 357-362; Altintas, *Manufacturing
Automation*, 2nd ed., 2012, ch. 3). A tool-tip displacement ``q(t)`` (feed frame: x along the feed, y
90 deg counter-clockwise) leaves the regenerative chip ``h = (dx sin phi + dy cos phi) g(phi)`` on a
tooth at immersion ``phi``, ``d = q(t) - q(t - T)``, ``T = 60 / (N n)`` the tooth period (s) at ``n``
rev/min with ``N`` flutes, ``g = 1`` inside an engaged arc of the band the edge is in and 0 outside.
With ``Ft = Ktc h db`` and ``Fr = Kr Ft`` (only the cutting coefficients: edge forces do not depend on
the vibration) the force on the tool from a band of height ``dz`` is ``(Ktc dz / 2) A(t) d`` with

    a_xx = -sum_j g [sin 2phi_j + Kr (1 - cos 2phi_j)]     a_xy = -sum_j g [1 + cos 2phi_j + Kr sin 2phi_j]
    a_yx = +sum_j g [1 - cos 2phi_j - Kr sin 2phi_j]       a_yy = +sum_j g [sin 2phi_j - Kr (1 + cos 2phi_j)]

On a non-cylindrical part of the tool (lead angle ``kappa``, :mod:`fusioncut.analysis.forces`) the
dynamic chip is ``sin(kappa)`` times the lateral one and the chip width ``dz / sin(kappa)``, so the
tangential force is unchanged and the in-plane radial ratio becomes ``Kr = (Krc sin kappa - Kac cos
kappa) / Ktc`` per band (the axial vibration is not modelled). Bands (height, lead angle, arcs, helix
lag ``2 tan(beta) z / D``) are those of the force model for the same map and slice height.

A CL's depth is scaled as a whole: the **directional matrix per unit depth** is the depth-weighted
sum ``B(t) = sum_bands dz A_band(t) / ap`` (``ap`` the CL's axial depth), and the limit ``a_lim`` is
the ``ap`` at which the CL would lose stability if all its bands grew in proportion; ``margin = ap /
a_lim`` (< 1: stable, >= 1: chatter predicted). Matrices are turned into the machine frame (``feed
angle`` about z; an M4 spindle mirrors y first), where the tool-tip modes are given
(:mod:`fusioncut.analysis.dynamics`).

ZOA: ``B0`` the mean of ``B(t)`` over a tooth period (exact: every tooth sweeps every arc once per
revolution, ``B0 = N / (2 pi) * sum dz alpha / ap`` with the closed-form integrals ``alpha`` of the
a's over the arcs). At chatter frequency ``wc`` the eigenvalues ``lambda`` of ``Phi(i wc) alpha0``
(``alpha0 = sum dz alpha / ap``, ``Phi`` the 2x2 receptance in m/N) give ``Lambda = -1 / lambda =
Lambda_R + i Lambda_I``, ``kappa_ = Lambda_I / Lambda_R`` and

    a_lim = -2 pi Lambda_R (1 + kappa_**2) / (N Ktc),    wc T = eps + 2 k pi,  eps = pi - 2 atan(kappa_)

(lobe ``k = 0, 1, ...``); with ``Lambda = -conj(lambda) / |lambda|^2`` this is ``a_lim = 2 pi / (N Ktc
Re lambda)`` (a depth only where ``Re lambda > 0``) and ``eps = pi + 2 atan(Im lambda / Re lambda)``.
For one mode in x only, ``a_lim = 2 pi / (N Ktc alpha_xx Re Phi_xx)``.
The limit at a given speed is the smallest ``a_lim`` over every (wc, eigenvalue) whose phase matches
that speed's ``T`` on some lobe, found by interpolation on a chatter-frequency grid.

SD (Insperger & Stepan, *Int. J. Numer. Meth. Eng.* 55 (2002) 503-518 and 61 (2004) 117-141; first
order: Insperger, Stepan & Turi, *J. Sound Vib.* 313 (2008) 334-341): the modes are independent
oscillators ``m q'' + c q' + k q = P^T F`` (``P`` sums the modal displacements of each direction),
``F = (a Ktc / 2) B(t) P (q(t) - q(t - T))``. The tooth period is cut into ``steps`` intervals; on each
the time-periodic matrix is replaced by its mean (midpoint rule on ``substeps`` points), the delayed
state is interpolated linearly between the grid points ``T`` back, and the interval is solved exactly
(matrix exponentials). The product over one period is the monodromy matrix: stable when its spectral
radius is below 1 (:mod:`fusioncut.analysis.stability_sd`). ``a_lim`` is the smallest depth at which that
radius reaches 1, bracketed on a geometric grid around the ZOA limit and refined by regula falsi
(:func:`sd_a_lim`).

Units: ``Ktc`` N/mm² (the project's coefficients), receptances m/N, depths mm, speeds rev/min.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Sequence

import numpy as np

from fusioncut.analysis.dynamics import ToolDynamics
# the force model's bands and tooth sampling: one definition of the engaged edge for forces and stability
from fusioncut.analysis.forces import CuttingCoefficients, _bands, _tooth_signal
from fusioncut.analysis.stability_kernels import zoa_limit_kernel, zoa_table_kernel
from fusioncut.analysis.stability_sd import interval_integrals, monodromy, spectral_radius
from fusioncut.errors import GeometryError, InputError
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.tools import MillingTool, SpindleDirection

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class CLDirectional:
    """What stability needs of one CL: bands and the directional factors per unit depth.

    ``alpha0`` (2x2, machine frame, dimensionless): ``sum dz alpha / ap`` (module docstring); ``ap`` (mm)
    the depth the factors are normalised to; ``flutes``; ``frame`` (2x2) turns immersion-frame vectors into
    the machine frame; ``lag`` (rad, per band), ``weights`` (per band ``[basis, band, a_xx a_xy a_yx a_yy]``
    for :func:`fusioncut.analysis.forces._tooth_signal`), ``bands`` the force model's bands.
    """

    cl_index: int
    ap: float
    flutes: int
    alpha0: np.ndarray
    frame: np.ndarray
    lag: np.ndarray
    weights: np.ndarray
    bands: object

    @property
    def engaged(self) -> bool:
        return self.ap > 0 and bool(np.any(self.alpha0))


def _frame(spindle: SpindleDirection, feed_angle: float) -> np.ndarray:
    t = math.radians(feed_angle)
    rot = np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])
    mirror = np.diag([1.0, -1.0 if spindle == SpindleDirection.CCW else 1.0])
    return rot @ mirror


def _alpha_integrals(entry: np.ndarray, span: np.ndarray, kr: np.ndarray) -> np.ndarray:
    """``int a(phi) dphi`` over each band's arcs (padding ``span < 0`` skipped), shape (M, 2, 2)."""
    valid = span >= 0
    a = entry
    e = entry + np.where(valid, span, 0.0)  # a padded arc is empty: its integrals are 0
    k = kr[:, None]
    ds2, dc2, dphi = np.sin(2 * e) - np.sin(2 * a), np.cos(2 * e) - np.cos(2 * a), e - a
    out = np.empty((len(entry), 2, 2))
    out[:, 0, 0] = (0.5 * (dc2 - 2 * k * dphi + k * ds2)).sum(axis=1)
    out[:, 0, 1] = (0.5 * (-ds2 - 2 * dphi + k * dc2)).sum(axis=1)
    out[:, 1, 0] = (0.5 * (-ds2 + 2 * dphi + k * dc2)).sum(axis=1)
    out[:, 1, 1] = (0.5 * (-dc2 - 2 * k * dphi - k * ds2)).sum(axis=1)
    return out


def cl_directional(emap: EngagementMap, tool: MillingTool, coefficients: CuttingCoefficients,
                   dz: float | None = None) -> CLDirectional:
    """Directional factors of one CL (module docstring); a failed map raises :class:`GeometryError`."""
    if emap.status == CLStatus.FAILED:
        raise GeometryError(f"no engagement known ({emap.reason or 'engine failed'})", emap.cl_index)
    if not coefficients.ktc > 0:
        raise InputError(f"stability needs a cutting coefficient Ktc > 0 N/mm², got {coefficients.ktc:g}")
    frame = _frame(emap.spindle, emap.feed_angle)
    n = tool.flutes
    if not emap.engaged_slices:
        return CLDirectional(emap.cl_index, 0.0, n, np.zeros((2, 2)), frame, np.zeros(0), np.zeros((5, 0, 4)), None)
    b = _bands(emap, tool, dz)
    if not len(b.area):
        return CLDirectional(emap.cl_index, 0.0, n, np.zeros((2, 2)), frame, np.zeros(0), np.zeros((5, 0, 4)), None)
    ap = emap.ap if emap.ap > 1e-9 else float(b.area.sum())
    kr = (b.sk * coefficients.krc - b.ck * coefficients.kac) / coefficients.ktc
    alpha = np.einsum("m,mij->ij", b.area, _alpha_integrals(b.entry, b.span, kr)) / ap
    # a's in the basis of _tooth_signal (0: sin cos, 1: cos, 2: sin^2, 3: sin, 4: 1), per unit depth
    w = np.zeros((5, len(b.area), 4))
    d = b.area / ap
    w[0, :, 0], w[2, :, 0] = -2 * d, -2 * kr * d                      # -(2 s c + 2 Kr s^2)
    w[4, :, 1], w[2, :, 1], w[0, :, 1] = -2 * d, 2 * d, -2 * kr * d   # -(2 c^2 + 2 Kr s c)
    w[2, :, 2], w[0, :, 2] = 2 * d, -2 * kr * d                       # 2 s^2 - 2 Kr s c
    w[0, :, 3], w[4, :, 3], w[2, :, 3] = 2 * d, -2 * kr * d, 2 * kr * d  # 2 s c - 2 Kr c^2
    lag = 2.0 * math.tan(math.radians(tool.helix_angle)) * b.z / tool.diameter
    return CLDirectional(emap.cl_index, float(ap), n, frame @ alpha @ frame.T, frame, lag, w, b)


def directional_signal(cd: CLDirectional, theta: np.ndarray) -> np.ndarray:
    """``B(theta)`` (machine frame, per unit depth, summed over the teeth), shape (len(theta), 2, 2), at
    the spindle angles ``theta`` (rad) of tooth 0's tip."""
    theta = np.asarray(theta, dtype=float)
    if not cd.engaged:
        return np.zeros((len(theta), 2, 2))
    every = np.mod(theta[:, None] + np.arange(cd.flutes) * (_TWO_PI / cd.flutes), _TWO_PI).ravel()
    a = _tooth_signal(every, cd.lag, cd.bands, cd.weights).reshape(len(theta), cd.flutes, 4).sum(axis=1)
    return cd.frame @ a.reshape(-1, 2, 2) @ cd.frame.T


# --------------------------------------------------------------------------------------------------
# zero-order approximation


@dataclass(frozen=True)
class ChatterGrid:
    """Receptances of the tool tip on a chatter-frequency grid, computed once per dynamics.

    ``wc`` (rad/s, (F,)), ``phi`` (m/N, (F, 2, 2), diagonal: no cross FRF). The grid is geometric from
    0.5 x the lowest to 2 x the highest natural frequency, ``points`` in all, plus ``points_per_mode``
    within +-10 damping ratios of every mode (where the lobes' minima lie; a limit interpolated on that
    grid is within 2e-4 of the exact one on the 1-DOF benchmark, ``tests/analysis/test_stability.py``).
    ``products`` (5, F): ``phi_x, phi_y, phi_x^2, phi_x phi_y, phi_y^2``, the terms of the eigenvalues'
    trace and discriminant (:func:`zoa_curves_many`).
    """

    wc: np.ndarray
    phi: np.ndarray
    products: np.ndarray

    @cached_property
    def products_re(self) -> np.ndarray:
        """``products.real``, contiguous (the compiled passes' input)."""
        return np.ascontiguousarray(self.products.real)

    @cached_property
    def products_im(self) -> np.ndarray:
        return np.ascontiguousarray(self.products.imag)


def chatter_grid(dyn: ToolDynamics, points: int = 1000, points_per_mode: int = 2000) -> ChatterGrid:
    lo, hi = dyn.frequency_band_hz()
    parts = [np.geomspace(0.5 * lo, 2.0 * hi, points)]
    for _, m in dyn.all_modes:
        parts.append(m.fn_hz * np.linspace(1 - min(10 * m.zeta, 0.5), 1 + min(10 * m.zeta, 1.0), points_per_mode))
    wc = _TWO_PI * np.unique(np.concatenate(parts))
    phi = np.zeros((len(wc), 2, 2), dtype=complex)
    px, py = dyn.receptance("x", wc), dyn.receptance("y", wc)
    phi[:, 0, 0], phi[:, 1, 1] = px, py
    return ChatterGrid(wc, phi, np.stack((px, py, px * px, px * py, py * py)))


def zoa_curves_many(alpha0: np.ndarray, grid: ChatterGrid, ktc: float, flutes: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`zoa_curves` of a stack of directional matrices ``alpha0`` (C, 2, 2): shape (C, F, 2) each.

    With ``Phi = diag(phi_x, phi_y)`` the eigenvalues of ``Phi alpha0`` are ``h +- sqrt(h^2 - det)``,
    ``h = (phi_x a_xx + phi_y a_yy) / 2`` and ``h^2 - det`` a combination of the grid's ``products``
    with coefficients from ``alpha0``: one matrix product for all CLs."""
    coef = _curve_coefficients(alpha0)
    p = grid.products
    hr, hi = coef[:, :2] @ p[:2].real, coef[:, :2] @ p[:2].imag
    dr, di = coef[:, 2:] @ p[2:].real, coef[:, 2:] @ p[2:].imag
    # principal square root of dr + i di in real arithmetic, without cancellation on either side
    r = np.sqrt(dr * dr + di * di)  # |d| (as the compiled passes: no overflow at receptances' scales)
    big = np.sqrt(0.5 * (r + np.abs(dr)))
    small = np.where(big > 0, 0.5 * di / np.where(big > 0, big, 1.0), 0.0)
    sr = np.where(dr >= 0, big, np.abs(small))
    si = np.where(dr >= 0, small, np.copysign(big, di))
    lr = np.stack((hr + sr, hr - sr), axis=-1)
    li = np.stack((hi + si, hi - si), axis=-1)
    # Lambda = -1/lambda: a_lim = -2 pi Lambda_R (1 + kappa^2) / (N Kt) = 2 pi / (N Kt Re lambda) and
    # kappa = -Im lambda / Re lambda; a positive depth needs Re lambda > 0
    ok = lr > 0
    safe = np.where(ok, lr, 1.0)
    a_lim = np.where(ok, (2e3 * math.pi / (flutes * ktc * 1e6)) / safe, np.nan)  # m -> mm
    eps = math.pi + 2.0 * np.arctan(li / safe)
    return a_lim, eps


def zoa_curves(alpha0: np.ndarray, grid: ChatterGrid, ktc: float, flutes: int) -> tuple[np.ndarray, np.ndarray]:
    """Per chatter frequency and eigenvalue: ``a_lim`` (mm; NaN where the eigenvalue gives no positive
    depth) and the phase ``eps`` (rad, in (0, 2 pi)); both shape (F, 2)."""
    a, eps = zoa_curves_many(alpha0, grid, ktc, flutes)
    return a[0], eps[0]


@dataclass(frozen=True)
class LobeSegments:
    """The pieces of the ZOA curves between neighbouring grid frequencies that can carry a lobe: both
    ends with a depth, and the phase ``eps`` stepping by less than pi (a jump of ``eps`` is
    ``Lambda_R`` through 0, ``a -> inf``: no lobe). Flat arrays over both eigenvalues: ``wc0, wc1``
    (rad/s), ``a0, a1`` (mm), ``e0, e1`` (rad)."""

    wc0: np.ndarray
    wc1: np.ndarray
    a0: np.ndarray
    a1: np.ndarray
    e0: np.ndarray
    e1: np.ndarray

    @classmethod
    def of(cls, grid: ChatterGrid, curves: tuple[np.ndarray, np.ndarray], below: float = math.inf) -> "LobeSegments":
        """The segments of ``curves`` ((F, 2) each); with ``below``, only those where a depth under it is
        possible (``min(a0, a1) <= below``: a limit interpolated on any other exceeds ``below``)."""
        a, eps = curves
        a0, a1, e0, e1 = a[:-1], a[1:], eps[:-1], eps[1:]
        with np.errstate(invalid="ignore"):
            keep = np.isfinite(a0) & np.isfinite(a1) & (np.abs(e1 - e0) < math.pi) & (np.minimum(a0, a1) <= below)
        w = np.broadcast_to(grid.wc[:, None], a.shape)
        return cls(w[:-1][keep], w[1:][keep], a0[keep], a1[keep], e0[keep], e1[keep])

    def within(self, period_lo: float, period_hi: float) -> "LobeSegments":
        """The segments that can cross a lobe at some tooth period in ``[period_lo, period_hi]`` (s): ``u``
        is linear in the period at either end of a segment, so the values at the four corners bound it;
        a crossing needs an integer between their least and greatest."""
        u = np.stack([(w * t - e) / _TWO_PI for w, e in ((self.wc0, self.e0), (self.wc1, self.e1))
                      for t in (period_lo, period_hi)])
        keep = (np.floor(u.min(axis=0)) != np.floor(u.max(axis=0))) & (u.max(axis=0) >= 0)
        return LobeSegments(self.wc0[keep], self.wc1[keep], self.a0[keep], self.a1[keep], self.e0[keep],
                            self.e1[keep])

    def a_lim(self, period: np.ndarray) -> np.ndarray:
        """The smallest depth (mm) on a lobe at each tooth period (s; any shape), ``inf`` where none: the
        speed is on lobe ``k >= 0`` where ``u = (wc T - eps) / 2 pi`` crosses ``k`` along a segment,
        the depth interpolated linearly in ``u`` there."""
        period = np.asarray(period, dtype=float)
        t = period[..., None]
        u0 = (self.wc0 * t - self.e0) / _TWO_PI
        u1 = (self.wc1 * t - self.e1) / _TWO_PI
        k0, k1 = np.floor(u0), np.floor(u1)
        k = np.maximum(k0, k1)
        cross = (k0 != k1) & (k >= 0)
        frac = np.where(cross, (k - u0) / np.where(cross, u1 - u0, 1.0), 0.0)
        val = np.where(cross, self.a0 + frac * (self.a1 - self.a0), np.inf)
        return val.min(axis=-1, initial=np.inf)


def _curve_coefficients(alpha0: np.ndarray) -> np.ndarray:
    """Per directional matrix (C, 2, 2) the coefficients (C, 5) of the grid's ``products`` in ``h`` (first
    two) and ``h^2 - det`` (last three), :func:`zoa_curves_many`."""
    al = np.asarray(alpha0, dtype=float).reshape(-1, 2, 2)
    axx, ayy = al[:, 0, 0], al[:, 1, 1]
    d = axx * ayy - al[:, 0, 1] * al[:, 1, 0]
    return np.stack((0.5 * axx, 0.5 * ayy, 0.25 * axx * axx, 0.5 * axx * ayy - d, 0.25 * ayy * ayy), axis=1)


def zoa_a_lim_many(alpha0: np.ndarray, grid: ChatterGrid, ktc: float, flutes: int, rpm: np.ndarray) -> np.ndarray:
    """ZOA limit (mm) of many CLs, each at its own speed: ``alpha0`` (C, 2, 2), ``rpm`` (C,); equal to
    :func:`zoa_a_lim` per CL (a compiled pass over the grid per CL, no curves kept)."""
    coef = _curve_coefficients(alpha0)
    scale = np.full(len(coef), 2e3 * math.pi / (flutes * ktc * 1e6))
    period = 60.0 / (flutes * np.asarray(rpm, dtype=float).reshape(-1))
    return zoa_limit_kernel(grid.wc, grid.products_re, grid.products_im, coef, scale, period)


def zoa_a_lim(alpha0: np.ndarray, grid: ChatterGrid, ktc: float, flutes: int, rpm: np.ndarray | float,
              curves: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """ZOA limiting depth (mm) at each spindle speed ``rpm`` (rev/min); ``inf`` when no lobe reaches it."""
    rpm = np.atleast_1d(np.asarray(rpm, dtype=float))
    seg = LobeSegments.of(grid, curves if curves is not None else zoa_curves(alpha0, grid, ktc, flutes))
    return seg.a_lim(60.0 / (flutes * rpm))


def zoa_lobes(alpha0: np.ndarray, grid: ChatterGrid, ktc: float, flutes: int, rpm_lo: float, rpm_hi: float,
              speeds: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """Speeds (rev/min, ``speeds`` evenly spaced) and the ZOA limiting depth (mm) at each."""
    rpm = np.linspace(rpm_lo, rpm_hi, speeds)
    seg = LobeSegments.of(grid, zoa_curves(alpha0, grid, ktc, flutes))
    out = np.concatenate([seg.a_lim(60.0 / (flutes * rpm[i:i + 50])) for i in range(0, speeds, 50)])
    return rpm, out


def unstable_speed_ranges(grid: ChatterGrid, curves: tuple[np.ndarray, np.ndarray], flutes: int, ap: float,
                          rpm_lo: float, rpm_hi: float) -> np.ndarray:
    """Speed ranges (rev/min, rows ``(lo, hi)``, merged and sorted) within ``[rpm_lo, rpm_hi]`` where the
    ZOA limit is below ``ap`` (mm): every run of chatter frequencies whose ``a_lim < ap`` mapped through
    every lobe ``n_k = 60 wc / (N (eps + 2 k pi))`` (to within the chatter-frequency grid)."""
    a, eps = curves
    out = []
    for b in range(a.shape[1]):
        low = np.isfinite(a[:, b]) & (a[:, b] < ap)
        jump = np.r_[False, np.abs(np.diff(eps[:, b])) >= math.pi]
        idx = np.flatnonzero(low)
        if not len(idx):
            continue
        starts = np.flatnonzero(np.r_[True, (np.diff(idx) > 1) | jump[idx[1:]]])
        wc, e = grid.wc[idx], eps[idx, b]
        turns = 60.0 * wc / flutes / _TWO_PI  # wc T / 2 pi at 1 rev/min
        k_lo = max(int(np.floor((turns / rpm_hi - e / _TWO_PI).min())), 0)
        k_hi = int(np.ceil((turns / rpm_lo - e / _TWO_PI).max()))
        if k_hi - k_lo > 5000:
            raise InputError(f"the speed range {rpm_lo:g}..{rpm_hi:g} rev/min spans {k_hi - k_lo} lobes; narrow it")
        k = np.arange(k_lo, k_hi + 1)
        n = 60.0 * wc[:, None] / (flutes * (e[:, None] + _TWO_PI * k[None, :]))  # (P, K)
        lo, hi = np.minimum.reduceat(n, starts, axis=0), np.maximum.reduceat(n, starts, axis=0)
        keep = (hi >= rpm_lo) & (lo <= rpm_hi)
        out.append(np.stack((lo[keep], hi[keep]), axis=1))
    return np.clip(_merged(out), rpm_lo, rpm_hi)


def _merged(parts: Sequence[np.ndarray]) -> np.ndarray:
    """The union of speed ranges (rows ``(lo, hi)``), sorted, overlapping ones joined."""
    if not parts or not sum(len(o) for o in parts):
        return np.zeros((0, 2))
    r = np.concatenate(parts)
    r = r[np.argsort(r[:, 0])]
    merged = [r[0].copy()]
    for lo, hi in r[1:]:
        if lo <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append(np.array([lo, hi]))
    return np.array(merged)


@dataclass(frozen=True)
class DepthNeed:
    """What one CL needs of a spindle speed: a ZOA limit above ``depth`` (mm). ``segments``: its lobe
    segments that can go below ``depth``; ``ranges``: its unstable speed ranges (rev/min) in the searched
    range (:func:`unstable_speed_ranges`)."""

    depth: float
    segments: LobeSegments
    ranges: np.ndarray

    @classmethod
    def of(cls, grid: ChatterGrid, curves: tuple[np.ndarray, np.ndarray], flutes: int, depth: float,
           rpm_lo: float, rpm_hi: float) -> "DepthNeed":
        return cls(depth, LobeSegments.of(grid, curves, below=depth),
                   unstable_speed_ranges(grid, curves, flutes, depth, rpm_lo, rpm_hi))


def nearest_speed_for_all(needs: Sequence[DepthNeed], flutes: int, rpm: float, rpm_lo: float,
                          rpm_hi: float) -> float:
    """The speed in ``[rpm_lo, rpm_hi]`` nearest to ``rpm`` where every CL's ZOA limit exceeds its
    ``depth``: ``rpm`` itself when it does there, else the nearer end of a range in the union of the
    CLs' unstable ranges moved outwards in steps of 0.05 % until every limit there exceeds its depth,
    then bisected to within 0.05 % / 4096 of the boundary; NaN when no speed in the range does. Whether
    a limit exceeds a depth is decided on the lobe segments that can go below it alone, which gives the
    same answer as all of them."""

    def stable(n: np.ndarray | float, segs: Sequence[LobeSegments]) -> np.ndarray:
        period = 60.0 / (flutes * np.asarray(n, dtype=float))
        ok = np.ones(np.shape(period), dtype=bool)
        for need, seg in zip(needs, segs):
            ok &= seg.a_lim(period) > need.depth
        return ok

    every = [need.segments for need in needs]
    if stable(rpm, every):
        return float(rpm)
    cands = []
    for lo, hi in np.clip(_merged([need.ranges for need in needs]), rpm_lo, rpm_hi):
        if lo > rpm_lo:
            cands.append((lo, -1.0))
        if hi < rpm_hi:
            cands.append((hi, 1.0))
    for speed, sense in sorted(cands, key=lambda c: abs(c[0] - rpm)):
        steps = speed * (1 + sense * 5e-4 * np.arange(1, 21))
        ok = (steps >= rpm_lo) & (steps <= rpm_hi) & stable(steps, every)
        if not ok.any():
            continue
        i = int(np.argmax(ok))
        inner, n = (steps[i - 1] if i else speed), steps[i]
        bracket = sorted((60.0 / (flutes * inner), 60.0 / (flutes * n)))
        near = [seg.within(*bracket) for seg in every]
        for _ in range(12):  # the boundary between the last unstable and the stable speed
            mid = 0.5 * (inner + n)
            if stable(mid, near):
                n = mid
            else:
                inner = mid
        return float(n)
    return math.nan


def zoa_limit_and_nearest_many(alpha0: np.ndarray, grid: ChatterGrid, ktc: float, flutes: int, rpm: np.ndarray,
                               ap: np.ndarray, rpm_lo: np.ndarray, rpm_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per CL (``alpha0`` (C, 2, 2), the rest (C,) or scalars) the ZOA limit (mm) at ``rpm`` and the
    nearest stable speed (rev/min) in ``[rpm_lo, rpm_hi]``: :func:`zoa_a_lim_many` and
    :func:`nearest_stable_rpm` in one compiled pass (:func:`fusioncut.analysis.stability_kernels.
    zoa_table_kernel`), equal to them per CL."""
    coef = _curve_coefficients(alpha0)
    shape = (len(coef),)
    rpm, ap, rpm_lo, rpm_hi = (np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=float), shape))
                               for v in (rpm, ap, rpm_lo, rpm_hi))
    scale = np.full(len(coef), 2e3 * math.pi / (flutes * ktc * 1e6))
    limit, near, status = zoa_table_kernel(grid.wc, grid.products_re, grid.products_im, coef, scale, flutes, rpm,
                                           ap, rpm_lo, rpm_hi)
    bad = np.flatnonzero(status)
    if len(bad):
        i = bad[0]
        raise InputError(f"the speed range {rpm_lo[i]:g}..{rpm_hi[i]:g} rev/min spans {status[i]} lobes; narrow it")
    return limit, near


def nearest_stable_rpm(alpha0: np.ndarray, grid: ChatterGrid, ktc: float, flutes: int, rpm: float, ap: float,
                       rpm_lo: float, rpm_hi: float, curves: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """The speed in ``[rpm_lo, rpm_hi]`` nearest to ``rpm`` where the ZOA limit exceeds ``ap`` (mm)
    (:func:`nearest_speed_for_all` of this one CL); NaN when the whole range is unstable."""
    curves = curves if curves is not None else zoa_curves(alpha0, grid, ktc, flutes)
    seg = LobeSegments.of(grid, curves, below=ap)
    if seg.a_lim(60.0 / (flutes * rpm)) > ap:
        return float(rpm)
    need = DepthNeed(ap, seg, unstable_speed_ranges(grid, curves, flutes, ap, rpm_lo, rpm_hi))
    return nearest_speed_for_all([need], flutes, rpm, rpm_lo, rpm_hi)


# --------------------------------------------------------------------------------------------------
# semi-discretization


@dataclass(frozen=True)
class ModalSystem:
    """The modes as oscillators: masses ``m`` (kg), damping ``c`` (N s/m), stiffness ``k`` (N/m) (n,),
    and ``p`` (2, n) summing each direction's modal displacements."""

    m: np.ndarray
    c: np.ndarray
    k: np.ndarray
    p: np.ndarray

    @classmethod
    def from_dynamics(cls, dyn: ToolDynamics) -> "ModalSystem":
        modes = dyn.all_modes
        p = np.zeros((2, len(modes)))
        for i, (d, _) in enumerate(modes):
            p[0 if d == "x" else 1, i] = 1.0
        return cls(np.array([m.mass_kg for _, m in modes]), np.array([m.damping_n_s_per_m for _, m in modes]),
                   np.array([m.k_n_per_m for _, m in modes]), p)


def _step_matrices(cd: CLDirectional, steps: int, substeps: int) -> np.ndarray:
    """Mean of ``B(t)`` over each of ``steps`` intervals of a tooth period, shape (steps, 2, 2)."""
    pitch = _TWO_PI / cd.flutes
    theta = (np.arange(steps * substeps) + 0.5) * (pitch / (steps * substeps))
    return directional_signal(cd, theta).reshape(steps, substeps, 2, 2).mean(axis=1)


def sd_spectral_radius(cd: CLDirectional, system: ModalSystem, ktc: float, rpm: np.ndarray, a_mm: np.ndarray,
                       steps: int = 40, substeps: int = 8, b_steps: np.ndarray | None = None) -> np.ndarray:
    """Spectral radius of the first-order SD monodromy matrix at each pair ``(rpm[i], a_mm[i])``
    (:func:`fusioncut.analysis.stability_sd.spectral_radius`: the states no interval reads left out, the
    largest multipliers by Arnoldi's method where verified, else LAPACK's eigenvalues)."""
    return spectral_radius(*_sd_steps_of(cd, system, ktc, rpm, a_mm, steps, substeps, b_steps))


def sd_critical_multiplier(cd: CLDirectional, system: ModalSystem, ktc: float, rpm: float, a_mm: float,
                           steps: int = 40, substeps: int = 8) -> complex:
    """The Floquet multiplier of largest modulus at ``(rpm, a_mm)``: leaving the unit circle at -1 it
    is a period-doubling (flip) instability, as a complex pair a secondary Hopf one (the kind ZOA
    predicts)."""
    mu = sd_multipliers(cd, system, ktc, rpm, a_mm, steps, substeps)[0]
    return complex(mu[np.argmax(np.abs(mu))])


def sd_multipliers(cd: CLDirectional, system: ModalSystem, ktc: float, rpm: np.ndarray | float,
                   a_mm: np.ndarray | float, steps: int = 40, substeps: int = 8,
                   b_steps: np.ndarray | None = None) -> np.ndarray:
    """Eigenvalues of the first-order SD monodromy matrix at each pair ``(rpm[i], a_mm[i])``, shape
    (pairs, 2 n + steps r) for ``n`` modes in ``r`` directions (1 or 2) (LAPACK on
    :func:`sd_monodromy`)."""
    return np.linalg.eigvals(sd_monodromy(cd, system, ktc, rpm, a_mm, steps, substeps, b_steps))


def sd_monodromy(cd: CLDirectional, system: ModalSystem, ktc: float, rpm: np.ndarray | float,
                 a_mm: np.ndarray | float, steps: int = 40, substeps: int = 8,
                 b_steps: np.ndarray | None = None) -> np.ndarray:
    """The first-order SD monodromy matrix at each pair ``(rpm[i], a_mm[i])``, shape (pairs, D, D), ``D =
    2 n + steps r`` for ``n`` modes in ``r`` directions (1 or 2): the state ``y = (q, q')`` and the
    delayed displacements.

    The delay enters only through the tool's displacement along the directions that have modes, ``R q``
    (``R`` the nonzero rows of ``P``): the delayed states kept are those ``r`` displacements, not the
    ``n`` modal coordinates, which leaves out only multipliers that are zero."""
    return monodromy(*_sd_steps_of(cd, system, ktc, rpm, a_mm, steps, substeps, b_steps))


def _sd_steps_of(cd: CLDirectional, system: ModalSystem, ktc: float, rpm: np.ndarray | float,
                 a_mm: np.ndarray | float, steps: int, substeps: int,
                 b_steps: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per pair and interval of SD the maps of one step (:func:`fusioncut.analysis.stability_sd.monodromy`):
    ``phi0`` (pairs, steps, 2n, 2n) on the state, ``c_old`` and ``c_new`` (pairs, steps, 2n, r) on the
    delayed displacements ``R q_{i-m}`` and ``R q_{i-m+1}``, and ``R`` (r, n)."""
    rpm = np.atleast_1d(np.asarray(rpm, dtype=float))
    a_mm = np.atleast_1d(np.asarray(a_mm, dtype=float))
    rpm, a_mm = np.broadcast_arrays(rpm, a_mm)
    nb, n, m = len(rpm), len(system.m), steps
    b = _step_matrices(cd, steps, substeps) if b_steps is None else b_steps
    dirs = np.flatnonzero(np.abs(system.p).sum(axis=1) > 0)
    red = system.p[dirs]  # R: (r, n)
    # W = P^T B P = R^T B_r R (N/m per m): the cut's stiffness on the modes, and its delayed input on R q
    w_in = 0.5 * ktc * 1e6 * np.einsum("ai,sab->sib", red, b[:, dirs][:, :, dirs])  # (steps, n, r)
    w = w_in @ red  # (steps, n, n)
    minv = 1.0 / system.m
    dt = 60.0 / (cd.flutes * rpm) / m  # (nb,)
    a_si = a_mm * 1e-3
    # per interval the system matrix A = [[0, I], [-M^-1 (K - a W_i), -M^-1 C]] of y = (q, q')
    d2 = 2 * n
    amat = np.zeros((nb, m, d2, d2))
    amat[:, :, :n, n:] = np.eye(n)
    cut = a_si[:, None, None, None] * minv[None, None, :, None] * w[None]  # a M^-1 W: (nb, steps, n, n)
    amat[:, :, n:, :n] = -np.diag(minv * system.k)[None, None] + cut
    amat[:, :, n:, n:] = -np.diag(minv * system.c)
    # velocities scaled by the highest natural frequency in the series: the exact integrals, fewer doublings
    scale = np.r_[np.ones(n), np.full(n, 1.0 / float(np.sqrt(system.k / system.m).max()))]
    phi0, phi1, f2 = interval_integrals(amat, dt[:, None], scale)
    phi2 = f2 / dt[:, None, None, None]  # int_0^dt e^{A(dt-s)} s ds / dt
    # delayed term: y'' gets -a M^-1 R^T B_r (R q)(t - T); its input matrix acts on the velocity rows
    bq = -a_si[:, None, None, None] * minv[None, None, :, None] * w_in[None]  # (nb, steps, n, r)
    c_old = (phi1 - phi2)[..., n:] @ bq   # coefficient of R q_{i-m}
    c_new = phi2[..., n:] @ bq            # coefficient of R q_{i-m+1}
    return phi0, c_old, c_new, red


def sd_steps(system: ModalSystem, flutes: int, rpm: float, steps: int, per_vibration: float) -> int:
    """Steps per tooth period: at least ``steps`` and ``per_vibration`` per period of the highest mode
    (at low speeds a tooth period holds many vibrations), rounded up to a multiple of 10."""
    f_max = float(np.sqrt(system.k / system.m).max()) / _TWO_PI
    need = max(steps, math.ceil(per_vibration * f_max * 60.0 / (flutes * rpm)))
    return int(10 * math.ceil(need / 10))


def sd_a_lim(cd: CLDirectional, system: ModalSystem, ktc: float, rpm: Sequence[float] | float, a_ref: np.ndarray,
             steps: int = 30, per_vibration: float = 12.0, substeps: int = 8, grid_points: int = 14,
             rel_tol: float = 1e-3, max_steps: int | None = None) -> np.ndarray:
    """SD limiting depth (mm) at each speed: the smallest depth on the geometric grid ``a_ref x [0.05,
    10]`` (``grid_points``) that is unstable, refined against the stable grid point below it to a bracket
    ``hi / lo < 1 + rel_tol`` (the result its geometric mean) by regula falsi on ``log rho`` against ``log
    a`` (``rho`` the spectral radius; a point within a quarter of the tolerance of either end is moved
    inside, so the bracket shrinks every step): the estimate is the secant through the last two points,
    regula falsi on the bracket where that leaves it (an end kept twice in a row halved, the Illinois
    variant), moved half a tolerance past an end it is within half a tolerance of (closing the bracket).
    ``a_ref`` is a scale per speed (the ZOA limit; where that is not finite the CL's ``ap``). ``inf`` when
    the whole grid is stable; the smallest grid depth when that is already unstable. The grid up to its
    first point above ``a_ref`` is probed as :func:`_sd_a_lim_fixed` says, then evaluated one point at a
    time for the speeds still stable. Steps per tooth
    period: :func:`sd_steps`; NaN (not computed) where they would exceed ``max_steps`` (low speeds
    against the modes: the monodromy matrix grows with the steps and its eigenvalues cost their cube;
    the lobes are dense there and close to ZOA's)."""
    rpm = np.atleast_1d(np.asarray(rpm, dtype=float))
    ref = np.broadcast_to(np.asarray(a_ref, dtype=float), rpm.shape)
    out = np.full(rpm.shape, np.inf)
    if not cd.engaged:
        return out
    m_of = np.array([sd_steps(system, cd.flutes, r, steps, per_vibration) for r in rpm])
    if max_steps is not None:
        out[m_of > max_steps] = np.nan
    for m in np.unique(m_of):
        if max_steps is not None and m > max_steps:
            continue
        idx = np.flatnonzero(m_of == m)
        out[idx] = _sd_a_lim_fixed(cd, system, ktc, rpm[idx], ref[idx], int(m), substeps, grid_points, rel_tol)
    return out


def _sd_a_lim_fixed(cd: CLDirectional, system: ModalSystem, ktc: float, rpm: np.ndarray, ref: np.ndarray,
                    steps: int, substeps: int, grid_points: int, rel_tol: float) -> np.ndarray:
    """:func:`sd_a_lim` at speeds sharing their steps. The head of the depth grid (its points up to the first
    above ``a_ref``) is probed at the two points around ``a_ref`` and at the third and fifth below it (2.26
    times apart; the lowest 0.17 ``a_ref`` on the default grid); below the lowest unstable probe only the
    points between it and the stable probe under it (all points, under the lowest probe) are evaluated,
    and the whole head at the speeds next (in ``rpm``) to one found unstable below the probe under
    ``a_ref``, repeated while that finds more. The other head points are taken as stable as the stable
    probes around them: an instability confined between two stable probes below ``a_ref`` (less than 2.26
    times in depth) at a speed whose neighbours have none below ``a_ref`` is not looked for."""
    b = _step_matrices(cd, steps, substeps)

    def log_rho(rows: np.ndarray, depth: np.ndarray) -> np.ndarray:
        return np.log(sd_spectral_radius(cd, system, ktc, rpm[rows], depth, steps, substeps, b))

    ratios = np.geomspace(0.05, 10.0, grid_points)
    nr = len(rpm)
    g = np.full((nr, grid_points), np.nan)  # log rho on the grid, NaN: not evaluated
    first_above = int(np.searchsorted(ratios, 1.0, side="right"))
    head = min(first_above + 1, grid_points)

    def evaluate(rows: np.ndarray, cols: Sequence[int]) -> None:
        cols = np.asarray(cols, dtype=int)
        if len(rows) and len(cols):
            g[np.repeat(rows, len(cols)), np.tile(cols, len(rows))] = log_rho(
                np.repeat(rows, len(cols)), (ref[rows, None] * ratios[None, cols]).ravel())

    # the head of the grid probed at the two points around a_ref and two below, 2.26x apart; where a probe
    # is unstable, the head points between it and the stable probe below it (all below the lowest) too
    probes = [j for j in (first_above - 5, first_above - 3, first_above - 1, first_above) if 0 <= j < head]
    evaluate(np.arange(nr), probes)
    hit = g[:, probes] >= 0
    first_hit = np.where(hit.any(axis=1), hit.argmax(axis=1), -1)
    for k, j in enumerate(probes):
        gap = range(probes[k - 1] + 1 if k else 0, j)
        evaluate(np.flatnonzero(first_hit == k), list(gap))
    # the whole head at the speeds next to one unstable below the probe under a_ref (islands run across speeds)
    order = np.argsort(rpm, kind="stable")
    whole = np.zeros(nr, dtype=bool)
    while True:
        low = order[(g[order, :max(first_above - 1, 0)] >= 0).any(axis=1)]
        pos = np.flatnonzero(np.isin(order, low))
        near = order[np.unique(np.clip(np.concatenate((pos - 1, pos + 1)), 0, nr - 1))] if len(pos) else pos
        near = near[~whole[near]]
        near = near[np.isnan(g[near, :head]).any(axis=1)]
        if not len(near):
            break
        whole[near] = True
        rows, cols = np.nonzero(np.isnan(g[near, :head]))
        g[near[rows], cols] = log_rho(near[rows], ref[near[rows]] * ratios[cols])
    for j in range(head, grid_points):
        todo = np.flatnonzero(~(g[:, :j] >= 0).any(axis=1))
        if not len(todo):
            break
        g[todo, j] = log_rho(todo, ref[todo] * ratios[j])
    unstable = g >= 0
    first = np.where(unstable.any(axis=1), unstable.argmax(axis=1), -1)
    out = np.where(first == 0, ref * ratios[0], np.inf)
    todo = np.flatnonzero(first > 0)
    if not len(todo):
        return out
    j = first[todo]
    xl, xh = np.log(ref[todo] * ratios[j - 1]), np.log(ref[todo] * ratios[j])
    gl, gh = g[todo, j - 1], g[todo, j]
    xa, ga, xb, gb = xl.copy(), gl.copy(), xh.copy(), gh.copy()  # the last two points, b the latest
    side = np.zeros(len(todo))  # +1: the last point replaced the unstable end, -1: the stable one
    tol = math.log1p(rel_tol)
    for _ in range(60):
        live = np.flatnonzero(xh - xl >= tol)
        if not len(live):
            break
        lo, hi, fl, fh, sd = xl[live], xh[live], gl[live], gh[live], side[live]
        # the secant through the last two points (smooth log rho: superlinear), regula falsi on the bracket
        # where the secant leaves it (with the Illinois halving of an end kept twice in a row)
        with np.errstate(divide="ignore", invalid="ignore"):
            sec = xb[live] - gb[live] * (xb[live] - xa[live]) / (gb[live] - ga[live])
        rf = hi - fh * (hi - lo) / (fh - fl)
        x = np.where(np.isfinite(sec) & (sec > lo) & (sec < hi), sec, rf)
        # an estimate within half a tolerance of an end: half a tolerance past it closes the bracket
        x = np.where(x - lo < 0.5 * tol, x + 0.5 * tol, np.where(hi - x < 0.5 * tol, x - 0.5 * tol, x))
        x = np.clip(x, lo + 0.25 * tol, hi - 0.25 * tol)
        gx = log_rho(todo[live], np.exp(x))
        up = gx >= 0
        keep_lo, keep_hi = up & (sd > 0), ~up & (sd < 0)
        gl[live] = np.where(up, np.where(keep_lo, 0.5 * fl, fl), gx)
        gh[live] = np.where(up, gx, np.where(keep_hi, 0.5 * fh, fh))
        xh[live] = np.where(up, x, hi)
        xl[live] = np.where(up, lo, x)
        side[live] = np.where(up, 1.0, -1.0)
        xa[live], ga[live] = xb[live], gb[live]
        xb[live], gb[live] = x, gx
    out[todo] = np.exp(0.5 * (xl + xh))
    return out
