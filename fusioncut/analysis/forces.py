"""Mechanistic (linear edge-force) milling force model on top of the engagement maps.

Model (Altintas, *Manufacturing Automation*, 2nd ed., 2012, ch. 2; general tool profile after Engin &
Altintas, *Int. J. Mach. Tools Manuf.* 41 (2001) 2195-2212). Every axial band of the tool (one per
engagement slice, height ``dz``) and every tooth ``j`` of ``N`` carries, when its edge point is inside one
of the slice's engaged immersion intervals, the elemental forces

    dFt = Ktc * h * db + Kte * dS      (tangential, opposing the cutting velocity)
    dFr = Krc * h * db + Kre * dS      (radial, along the edge's outward surface normal)
    dFa = Kac * h * db + Kae * dS      (axial, along the profile's tangent, up the tool)

with ``h = c * sin(phi_j) * sin(kappa)`` the uncut chip thickness (``c`` feed per tooth, mm),
``dS = dz / sin(kappa)`` the length of the cutting edge's projection on the profile (mm) and
``db = dS`` the chip width. ``kappa`` is the local axial immersion (lead) angle: the angle between the
tool axis and the outward normal of the tool surface, 90 deg on a cylinder, smaller on a ball or corner
radius towards the tip, ``90 - half-angle`` on a cone. It is taken from the chord of the tool profile
across the band, so that ``h * db = c * sin(phi) * dz`` (the chip area) holds exactly and ``dS`` is the
chord length (the arc length to within ``dkappa**2 / 24`` on a ball).

Angles (see :mod:`fusioncut.model.angles`): ``phi`` is the immersion angle, measured from +y of the
feed frame in the sense the teeth turn; a tooth at ``phi`` sits at ``r * (sin phi, cos phi)``. Tooth
``j`` at height ``z`` above the tip is at

    phi_j(z) = phi + j * 2*pi/N - 2 * tan(beta) * z / D

``phi`` being the spindle angle of tooth 0 at the tip (the reported ``angles``). The helix lag is the
constant-lead one, ``2*pi*z / L`` with lead ``L = pi * D / tan(beta)`` and ``D = tool.diameter`` (the
nominal diameter; the tip diameter of a tapered mill), on every tool: ball-end flutes ground at constant
lead have exactly this lag (Lee & Altintas, *Int. J. Mach. Tools Manuf.* 36 (1996) 1059-1072), their
local helix angle being smaller than ``beta`` towards the tip.

Resolution of the elemental forces into the (immersion) feed frame, x along the feed, z the tool axis
(derived from the tooth position above: the cutting velocity is ``t = (cos phi, -sin phi, 0)``, the
outward surface normal ``n = (sin k sin phi, sin k cos phi, -cos k)``, the profile tangent
``a = (cos k sin phi, cos k cos phi, sin k)``, and the force on the tool is ``-dFt t - dFr n + dFa a``)::

    dFx = -dFt cos(phi) - dFr sin(k) sin(phi) + dFa cos(k) sin(phi)
    dFy = +dFt sin(phi) - dFr sin(k) cos(phi) + dFa cos(k) cos(phi)
    dFz =                 dFr cos(k)          + dFa sin(k)

For a flat end mill (``k = 90``) this is Altintas's ``Fx = -Ft cos phi - Fr sin phi``,
``Fy = Ft sin phi - Fr cos phi``, ``Fz = Fa``. The sign of the axial term is that of his flat-end-mill
chapter (``Fz = +Fa``, for which the tabulated ``Kac``, ``Kae`` and the slot-calibration formulas of
:mod:`fusioncut.analysis.calibrate` hold). The general-profile transformation of the ball-end and
general-cutter papers is usually printed with ``-dFa`` in the axial column, i.e. with the opposite sign
convention for ``Kac``, ``Kae``; we keep ``+dFa`` so one set of coefficients means the same thing on
every tool (negate ``Kac``, ``Kae`` taken from a source that uses the other convention).

Forces are those **exerted by the workpiece on the tool**, in newtons. Reported frames:

* feed frame: x along the horizontal feed, y 90 deg counter-clockwise from it (seen from +Z), z the tool
  axis (up). For an M3 (CW) spindle this is the immersion frame. An M4 (CCW) cut is the mirror image of
  an M3 cut (left-hand tools run M4), so the same immersion intervals give the same Fx and Fz and the
  opposite Fy.
* machine frame: the feed frame turned by ``feed_angle`` about Z.

Torque (N*m) is the cutting torque resisting the spindle, ``sum(dFt * r)``; power (W) is
``torque * 2*pi*rpm/60``.

Not modelled: run-out, tool deflection and vibration (regenerative chip), size effect (coefficients
constant in ``h``), forces of the flat bottom edges of a flat end mill (z = 0, no axial extent), the
vertical component of a ramp's or plunge's feed (only the horizontal feed makes the chip, see
:func:`feed_per_tooth_from_map`), and rubbing of the shank (bands above the flute length are ignored).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Sequence

import numpy as np

from fusioncut.analysis.result_maps import (
    engagement_maps_from_results, results_slice_height,
)
from fusioncut.errors import GeometryError, InputError
from fusioncut.model.engagement import CLStatus, EngagementMap, SliceEngagement
from fusioncut.model.tools import MillingTool, ProfileArc, ProfileLine, SpindleDirection

if TYPE_CHECKING:  # the force model itself needs no pandas; only results tables bring it
    from fusioncut.io.results import Results

_TWO_PI = 2.0 * math.pi
_EPS = 1e-9


@dataclass(frozen=True)
class CuttingCoefficients:
    """Linear edge-force cutting coefficients of one tool / work-material pair.

    Cutting (shearing) coefficients ``ktc``, ``krc``, ``kac`` in N/mm², edge (ploughing) coefficients
    ``kte``, ``kre``, ``kae`` in N/mm; tangential, radial, axial. Sign convention of the axial ones: see
    the module docstring (Altintas's flat-end-mill convention, ``Fz = +Fa``).
    """

    ktc: float
    krc: float
    kac: float
    kte: float
    kre: float
    kae: float
    name: str = ""
    source: str = ""

    def __post_init__(self) -> None:
        for key in ("ktc", "krc", "kac", "kte", "kre", "kae"):
            value = getattr(self, key)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise InputError(f"cutting coefficient {key} must be a finite number, got {value!r}")

    def as_dict(self) -> dict[str, float]:
        return {k: float(getattr(self, k)) for k in ("ktc", "krc", "kac", "kte", "kre", "kae")}


def feed_per_tooth(feed: float, rpm: float, flutes: int) -> float:
    """Feed per tooth ``c`` (mm) from the feed rate (mm/min), spindle speed (rev/min) and flute count."""
    if not (rpm > 0 and math.isfinite(rpm)):
        raise InputError(f"spindle speed must be > 0 rev/min, got {rpm}")
    if flutes < 1:
        raise InputError(f"need at least one flute, got {flutes}")
    if not (feed >= 0 and math.isfinite(feed)):
        raise InputError(f"feed rate must be >= 0 mm/min, got {feed}")
    return feed / (rpm * flutes)


def feed_per_tooth_from_map(emap: EngagementMap, rpm: float, flutes: int) -> float:
    """Horizontal feed per tooth (mm) of the CL segment of ``emap``.

    ``emap.feed`` (mm/min) is the feed along the path; only its horizontal part, the fraction
    ``|dXY| / |dXYZ|`` of the segment from ``emap.start`` to ``emap.position``, thickens the chip in the
    immersion frame the engagement intervals are given in (a zero-length segment counts as horizontal).
    """
    if emap.feed is None:
        raise InputError(f"CL {emap.cl_index}: no feed rate known; pass feed_per_tooth explicitly", emap.source)
    d = np.subtract(emap.position, emap.start, dtype=float)
    length = float(np.linalg.norm(d))
    horizontal = 1.0 if length < _EPS else float(math.hypot(d[0], d[1])) / length
    return feed_per_tooth(emap.feed, rpm, flutes) * horizontal


@dataclass(frozen=True, eq=False)
class CLForces:
    """Cutting forces at one CL over one spindle revolution (see the module docstring for the model).

    ``angles`` (deg, ``[0, 360)``, shape ``(S,)``) is the immersion angle of tooth 0's tip. ``feed_frame``
    and ``machine_frame`` (N, shape ``(S, 3)``, columns x, y, z) are the instantaneous forces on the tool
    at those angles; ``torque`` (N*m, ``(S,)``) the cutting torque. ``mean_feed_frame``,
    ``mean_machine_frame`` (N) and ``mean_torque`` (N*m) are the exact time averages over a revolution
    (integrated in closed form per slice, so they carry no sampling error; the average of the samples
    differs from them by O(360/S deg) where an edge enters or leaves the cut). Peaks are the largest
    absolute sampled values. Arrays are read-only.
    """

    cl_index: int
    spindle: SpindleDirection
    feed_angle: float
    rpm: float
    feed_per_tooth: float
    angles: np.ndarray
    feed_frame: np.ndarray
    machine_frame: np.ndarray
    torque: np.ndarray
    mean_feed_frame: np.ndarray
    mean_machine_frame: np.ndarray
    mean_torque: float
    timings_ms: tuple[tuple[str, float], ...] = field(default=())

    # -- components -------------------------------------------------------------------------------
    @property
    def fx(self) -> np.ndarray:
        return self.feed_frame[:, 0]

    @property
    def fy(self) -> np.ndarray:
        return self.feed_frame[:, 1]

    @property
    def fz(self) -> np.ndarray:
        return self.feed_frame[:, 2]

    @property
    def fx_machine(self) -> np.ndarray:
        return self.machine_frame[:, 0]

    @property
    def fy_machine(self) -> np.ndarray:
        return self.machine_frame[:, 1]

    @property
    def fz_machine(self) -> np.ndarray:
        return self.machine_frame[:, 2]

    # -- summaries --------------------------------------------------------------------------------
    @property
    def peak_feed_frame(self) -> np.ndarray:
        """Largest sampled ``|Fx|, |Fy|, |Fz|`` in the feed frame (N)."""
        return np.abs(self.feed_frame).max(axis=0) if len(self.angles) else np.zeros(3)

    @property
    def peak_machine_frame(self) -> np.ndarray:
        """Largest sampled ``|FX|, |FY|, |FZ|`` in the machine frame (N)."""
        return np.abs(self.machine_frame).max(axis=0) if len(self.angles) else np.zeros(3)

    @property
    def resultant(self) -> np.ndarray:
        """``|F|`` at each sample (N); the same in both frames."""
        return np.linalg.norm(self.feed_frame, axis=1)

    @property
    def resultant_peak(self) -> float:
        return float(self.resultant.max()) if len(self.angles) else 0.0

    @property
    def resultant_mean(self) -> float:
        """Time average of ``|F|`` (N), from the samples (``|F|`` has no closed form)."""
        return float(self.resultant.mean()) if len(self.angles) else 0.0

    @property
    def torque_peak(self) -> float:
        return float(np.abs(self.torque).max()) if len(self.angles) else 0.0

    @property
    def omega(self) -> float:
        """Spindle angular speed (rad/s)."""
        return self.rpm * _TWO_PI / 60.0

    @property
    def power(self) -> np.ndarray:
        """Instantaneous cutting power at the spindle (W)."""
        return self.torque * self.omega

    @property
    def power_mean(self) -> float:
        """Mean cutting power (W), from the exact mean torque."""
        return self.mean_torque * self.omega

    @property
    def power_peak(self) -> float:
        return self.torque_peak * self.omega

    def summary(self) -> dict[str, float]:
        """Scalar results (N, N*m, W) keyed by name, for tables and per-CL outputs."""
        out: dict[str, float] = {"cl_index": float(self.cl_index), "feed_per_tooth_mm": self.feed_per_tooth}
        for frame, peak, mean in (
            ("", self.peak_feed_frame, self.mean_feed_frame),
            ("_machine", self.peak_machine_frame, self.mean_machine_frame),
        ):
            for k, axis in enumerate("xyz"):
                out[f"f{axis}{frame}_peak_N"] = float(peak[k])
                out[f"f{axis}{frame}_mean_N"] = float(mean[k])
        out["resultant_peak_N"] = self.resultant_peak
        out["resultant_mean_N"] = self.resultant_mean
        out["torque_peak_Nm"] = self.torque_peak
        out["torque_mean_Nm"] = self.mean_torque
        out["power_peak_W"] = self.power_peak
        out["power_mean_W"] = self.power_mean
        return out


# ------------------------------------------------------------------------------------------------
# geometry of the bands
# ------------------------------------------------------------------------------------------------

def _radius_at_many(tool: MillingTool, z: np.ndarray) -> np.ndarray:
    """Vectorised :meth:`ToolProfile.radius_at` over the *cutting* profile only (not the shank).

    Same rule as the model's: the largest radius of any profile piece spanning ``z`` (so the flat bottom
    of a flat end mill gives the full radius at z = 0).
    """
    best = np.zeros_like(z)
    for s in tool.cutting_profile():
        if isinstance(s, ProfileLine):
            (r0, z0), (r1, z1) = s.start, s.end
            lo, hi = min(z0, z1), max(z0, z1)
            inside = (z >= lo - _EPS) & (z <= hi + _EPS)
            if abs(z1 - z0) < _EPS:
                r = np.full_like(z, max(r0, r1))
            else:
                r = r0 + (r1 - r0) * (z - z0) / (z1 - z0)
        elif isinstance(s, ProfileArc):
            (rc, zc), rr = s.center, s.radius
            lo, hi = min(s.start[1], s.end[1]), max(s.start[1], s.end[1])
            inside = (z >= lo - _EPS) & (z <= hi + _EPS)
            dz = np.minimum(np.abs(z - zc), rr)
            r = rc + np.sqrt(np.maximum(rr * rr - dz * dz, 0.0))
        else:  # pragma: no cover - the model has only these two
            raise TypeError(f"unknown profile piece {s!r}")
        best = np.where(inside, np.maximum(best, r), best)
    return best


def _band_edges(
    emap: EngagementMap, tool: MillingTool, dz: float | None
) -> tuple[np.ndarray, np.ndarray, list[SliceEngagement]]:
    """Lower and upper band edges (mm above the tip) of the engaged slices, in height order.

    With ``dz`` the bands are the cells ``[k dz, (k+1) dz]`` of a grid from the tool tip, each slice
    standing for the cell it lies in: the convention of the B-Rep engine, which cuts the flutes into
    such bands and evaluates each at the middle of its part in contact, so passing the engine's slice
    height reproduces its bands exactly (also the clipped end bands, whose slices are off-centre).
    Without ``dz`` the bands are the cells between the midpoints of consecutive slice heights (all
    slices of the map, engaged or not, define the grid), the end bands reaching as far beyond the end
    slices as half the neighbouring spacing. Either way bands are clipped to the flutes
    ``[0, flute_length]`` and, when the map has one, to its axial contact range ``axial_range``.
    """
    slices = sorted(emap.slices, key=lambda s: s.z)
    zs = np.array([s.z for s in slices], dtype=float)
    if dz is not None:
        if not (dz > 0 and math.isfinite(dz)):
            raise InputError(f"slice thickness dz must be > 0 mm, got {dz}")
        cell = np.floor(zs / dz + 1e-9)  # a slice on a grid line belongs to the cell above it
        if np.any(np.diff(cell[[bool(s.intervals) for s in slices]]) == 0):
            raise InputError(
                f"CL {emap.cl_index}: two engaged slices lie in one band of dz = {dz:g} mm; pass their real "
                "spacing", emap.source,
            )
        lo, hi = cell * dz, (cell + 1) * dz
    else:
        if len(zs) < 2:
            raise InputError(
                f"CL {emap.cl_index}: cannot infer the slice thickness from {len(zs)} slice(s); pass dz", emap.source
            )
        gaps = np.diff(zs)
        if np.any(gaps <= _EPS):
            raise InputError(f"CL {emap.cl_index}: two slices at the same height; pass dz", emap.source)
        mid = 0.5 * (zs[1:] + zs[:-1])
        lo = np.concatenate(([zs[0] - 0.5 * gaps[0]], mid))
        hi = np.concatenate((mid, [zs[-1] + 0.5 * gaps[-1]]))
    bottom, top = 0.0, tool.flute_length
    a0, a1 = emap.axial_range
    if a1 - a0 > _EPS:
        bottom, top = max(bottom, a0), min(top, a1)
    lo, hi = np.clip(lo, bottom, top), np.clip(hi, bottom, top)
    engaged = np.array([bool(s.intervals) for s in slices], dtype=bool)
    return lo[engaged], hi[engaged], [s for s, e in zip(slices, engaged) if e]


@dataclass(frozen=True)
class _Bands:
    """Per engaged band: chip-area factor ``area = dz`` (= sin(k)*dS), edge length ``ds`` (mm),
    ``sin k``, ``cos k``, radius ``r`` (mm), height ``z`` (mm), and the padded immersion intervals
    ``entry`` / ``span`` (rad, shape (M, K); padding has span -1)."""

    area: np.ndarray
    ds: np.ndarray
    sk: np.ndarray
    ck: np.ndarray
    r: np.ndarray
    z: np.ndarray
    entry: np.ndarray
    span: np.ndarray


def _bands(emap: EngagementMap, tool: MillingTool, dz: float | None) -> _Bands:
    lo, hi, slices = _band_edges(emap, tool, dz)
    keep = hi - lo > _EPS
    lo, hi = lo[keep], hi[keep]
    slices = [s for s, k in zip(slices, keep) if k]
    # kappa from the chord of the profile across the band: (dr, dz) is the direction up the profile
    radii = _radius_at_many(tool, np.concatenate((lo, hi)))
    d_r = radii[len(lo):] - radii[: len(lo)]
    d_z = hi - lo
    chord = np.hypot(d_r, d_z)
    m = len(slices)
    k = max((len(s.intervals) for s in slices), default=0)
    entry = np.zeros((m, max(k, 1)))
    span = np.full((m, max(k, 1)), -1.0)
    for i, s in enumerate(slices):
        for q, iv in enumerate(s.intervals):
            entry[i, q] = math.radians(iv.entry % 360.0)
            span[i, q] = math.radians(min(max(iv.span, 0.0), 360.0))
    return _Bands(
        area=d_z,
        ds=chord,
        sk=d_z / chord,
        ck=d_r / chord,
        r=np.array([s.radius for s in slices], dtype=float),
        z=0.5 * (lo + hi),
        entry=entry,
        span=span,
    )


def _weights(b: _Bands, k: CuttingCoefficients, c: float) -> np.ndarray:
    """Weights ``W[basis, band, output]`` so that output = sum over basis and bands of basis * W.

    Basis functions of the edge's immersion ``phi``: 0: sin*cos, 1: cos, 2: sin^2, 3: sin, 4: 1.
    Outputs: Fx, Fy, Fz (N, immersion frame) and torque (N*m). Derived by expanding the resolution
    formulas of the module docstring with Ft = Ktc*c*area*sin(phi) + Kte*ds, etc.
    """
    ca = c * b.area
    radial_xy_cut = ca * (-b.sk * k.krc + b.ck * k.kac)  # in-plane part of (Fr, Fa), cutting
    radial_xy_edge = b.ds * (-b.sk * k.kre + b.ck * k.kae)  # ... edge
    w = np.zeros((5, len(b.area), 4))
    w[0, :, 0] = -k.ktc * ca
    w[1, :, 0] = -k.kte * b.ds
    w[2, :, 0] = radial_xy_cut
    w[3, :, 0] = radial_xy_edge
    w[0, :, 1] = radial_xy_cut
    w[1, :, 1] = radial_xy_edge
    w[2, :, 1] = k.ktc * ca
    w[3, :, 1] = k.kte * b.ds
    w[3, :, 2] = ca * (b.ck * k.krc + b.sk * k.kac)
    w[4, :, 2] = b.ds * (b.ck * k.kre + b.sk * k.kae)
    w[3, :, 3] = k.ktc * ca * b.r * 1e-3  # N*mm -> N*m
    w[4, :, 3] = k.kte * b.ds * b.r * 1e-3
    return w


def _mean_basis(b: _Bands) -> np.ndarray:
    """Integrals of the 5 basis functions over each band's engaged arcs, shape (5, M)."""
    a = b.entry
    e = b.entry + np.maximum(b.span, 0.0)
    valid = b.span >= 0
    sa, se, ca, ce = np.sin(a), np.sin(e), np.cos(a), np.cos(e)
    ints = np.stack(
        (
            0.5 * (se * se - sa * sa),
            se - sa,
            0.5 * (e - a) - 0.25 * (np.sin(2 * e) - np.sin(2 * a)),
            ca - ce,
            e - a,
        )
    )
    return np.where(valid[None], ints, 0.0).sum(axis=2)


def _tooth_signal(theta: np.ndarray, lag: np.ndarray, b: _Bands, w: np.ndarray) -> np.ndarray:
    """Fx, Fy, Fz (immersion frame, N) and torque (N*m) of one tooth whose tip is at ``theta`` (rad,
    in ``[0, 2 pi)``, shape (T,)), summed over the bands; shape (T, 4)."""
    # The edge at band m is at phi = theta - lag_m. It is inside the arc [entry, entry + span) when
    # d = theta - off, off = (lag + entry) mod 2 pi, satisfies 0 <= d < span, or, wrapped once
    # (d in (-2 pi, 0)), d + 2 pi < span. This avoids a floating mod over the whole (T, M) grid.
    off = np.mod(lag[:, None] + b.entry, _TWO_PI)  # (M, K)
    inside = np.zeros((len(theta), len(lag)), dtype=bool)
    for q in range(b.entry.shape[1]):
        d = theta[:, None] - off[None, :, q]
        span = b.span[None, :, q]
        inside |= ((d >= 0.0) & (d < span)) | (d < span - _TWO_PI)
    # sin, cos of theta - lag by the addition formulas: outer products instead of transcendentals
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    sl, cl = np.sin(lag)[None, :], np.cos(lag)[None, :]
    sp = st * cl - ct * sl
    cp = ct * cl + st * sl
    msp = np.where(inside, sp, 0.0)
    mcp = np.where(inside, cp, 0.0)
    return (msp * cp) @ w[0] + mcp @ w[1] + (msp * sp) @ w[2] + msp @ w[3] + inside.astype(float) @ w[4]


def _frames(immersion: np.ndarray, spindle: SpindleDirection, feed_angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Immersion-frame forces (..., 3) to the feed frame and the machine frame."""
    feed = immersion.copy()
    if spindle == SpindleDirection.CCW:
        feed[..., 1] *= -1.0  # the M4 immersion frame is the mirror image of the feed frame in y
    t = math.radians(feed_angle)
    ct, st = math.cos(t), math.sin(t)
    machine = feed.copy()
    machine[..., 0] = ct * feed[..., 0] - st * feed[..., 1]
    machine[..., 1] = st * feed[..., 0] + ct * feed[..., 1]
    return feed, machine


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def compute_cl_forces(
    emap: EngagementMap,
    tool: MillingTool,
    coefficients: CuttingCoefficients,
    *,
    rpm: float,
    feed_per_tooth: float | None = None,
    dz: float | None = None,
    samples: int = 360,
) -> CLForces:
    """Cutting forces of one CL over one spindle revolution.

    ``rpm`` (rev/min) gives the power and, when ``feed_per_tooth`` (mm) is not given, the feed per
    tooth from ``emap.feed`` (see :func:`feed_per_tooth_from_map`). ``dz`` (mm) is the slice height:
    each slice then stands for the cell ``[k dz, (k+1) dz]`` it lies in (pass the engine's slice height
    to get its bands exactly); by default the bands are the cells between the midpoints of consecutive
    slice heights. Either way bands are clipped to the flutes and to ``emap.axial_range`` when set. ``samples``
    spindle angles are evenly spaced over 360 deg (a multiple of the flute count is N times cheaper:
    one tooth's signal is then shifted onto the others). The spindle sense and feed direction are the
    map's; the tool's flute count, helix angle, diameter (``D`` of the helix lag) and cutting profile
    are used. A failed map raises :class:`GeometryError` (its engagement is unknown and zero forces
    would be a lie); maps without engaged slices give zero forces.
    """
    t0 = time.perf_counter()
    if emap.status == CLStatus.FAILED:
        raise GeometryError(f"no engagement known ({emap.reason or 'engine failed'})", emap.cl_index)
    if samples < 1:
        raise InputError(f"need at least one angle sample, got {samples}")
    if not (rpm > 0 and math.isfinite(rpm)):
        raise InputError(f"spindle speed must be > 0 rev/min, got {rpm}")
    n = tool.flutes
    c = feed_per_tooth_from_map(emap, rpm, n) if feed_per_tooth is None else float(feed_per_tooth)
    if not (c >= 0 and math.isfinite(c)):
        raise InputError(f"feed per tooth must be >= 0 mm, got {c}")

    angles = np.arange(samples) * (360.0 / samples)
    if not emap.engaged_slices:
        zeros3 = np.zeros((samples, 3))
        return CLForces(
            emap.cl_index, emap.spindle, emap.feed_angle, float(rpm), c, _readonly(angles),
            _readonly(zeros3), _readonly(zeros3.copy()), _readonly(np.zeros(samples)),
            _readonly(np.zeros(3)), _readonly(np.zeros(3)), 0.0,
        )
    b = _bands(emap, tool, dz)
    w = _weights(b, coefficients, c)
    t1 = time.perf_counter()

    # exact means: every tooth sweeps every band once per revolution, whatever its helix lag
    mean_imm = np.einsum("bm,bmo->o", _mean_basis(b), w) * (n / _TWO_PI)

    # instantaneous: all teeth are alike, so tooth j at angle theta is tooth 0 at theta + j*2pi/N; with
    # S a multiple of N that angle is another sample, and one tooth's signal rolled N times is the sum
    lag = 2.0 * math.tan(math.radians(tool.helix_angle)) * b.z / tool.diameter
    theta = np.radians(angles)
    if samples % n == 0:
        one = _tooth_signal(theta, lag, b, w)
        step = samples // n
        out = one.copy()
        for j in range(1, n):
            out += np.roll(one, -j * step, axis=0)
    else:
        every = np.mod(theta[:, None] + np.arange(n) * (_TWO_PI / n), _TWO_PI).ravel()
        out = _tooth_signal(every, lag, b, w).reshape(samples, n, 4).sum(axis=1)
    t2 = time.perf_counter()

    feed_f, machine_f = _frames(out[:, :3], emap.spindle, emap.feed_angle)
    mean_feed, mean_machine = _frames(mean_imm[:3], emap.spindle, emap.feed_angle)
    return CLForces(
        cl_index=emap.cl_index,
        spindle=emap.spindle,
        feed_angle=emap.feed_angle,
        rpm=float(rpm),
        feed_per_tooth=c,
        angles=_readonly(angles),
        feed_frame=_readonly(feed_f),
        machine_frame=_readonly(machine_f),
        torque=_readonly(np.ascontiguousarray(out[:, 3])),
        mean_feed_frame=_readonly(mean_feed),
        mean_machine_frame=_readonly(mean_machine),
        mean_torque=float(mean_imm[3]),
        timings_ms=(("setup", 1e3 * (t1 - t0)), ("forces", 1e3 * (t2 - t1))),
    )


def compute_forces(
    maps: Sequence[EngagementMap],
    tool: MillingTool,
    coefficients: CuttingCoefficients,
    *,
    rpm: float,
    dz: float | None = None,
    samples: int = 360,
) -> list[CLForces | None]:
    """:func:`compute_cl_forces` for every map of one tool; ``None`` for failed maps and for maps
    without a feed rate (rapids), whose forces are unknown."""
    out: list[CLForces | None] = []
    for emap in maps:
        if emap.status == CLStatus.FAILED or (emap.feed is None and emap.engaged_slices):
            out.append(None)
            continue
        out.append(
            compute_cl_forces(emap, tool, coefficients, rpm=rpm, dz=dz, samples=samples,
                              feed_per_tooth=None if emap.feed is not None else 0.0)
        )
    return out


# ------------------------------------------------------------------------------------------------
# chip thickness, and force tables (also of saved results: maps rebuilt by fusioncut.analysis.result_maps)
# ------------------------------------------------------------------------------------------------

def peak_chip_thickness(emap: EngagementMap, tool: MillingTool, feed_per_tooth: float, *,
                        dz: float | None = None) -> float:
    """Largest uncut chip thickness (mm) over the engaged edge of CL ``emap`` at feed per tooth
    ``feed_per_tooth`` (mm): ``c * max(sin(phi) * sin(kappa))`` over the engaged arcs of every band
    (the model's ``h``, module docstring; bands as in :func:`compute_cl_forces`). Below full radial
    immersion (``ae < R``) the arc never reaches ``phi = 90 deg`` and the chip is thinner than ``c``:
    the chip thinning that chip-thickness feed control exploits. 0 without engagement; a failed map
    raises :class:`GeometryError`."""
    if emap.status == CLStatus.FAILED:
        raise GeometryError(f"no engagement known ({emap.reason or 'engine failed'})", emap.cl_index)
    if not (feed_per_tooth >= 0 and math.isfinite(feed_per_tooth)):
        raise InputError(f"feed per tooth must be >= 0 mm, got {feed_per_tooth}")
    if not emap.engaged_slices:
        return 0.0
    b = _bands(emap, tool, dz)
    best = 0.0
    for m in range(len(b.area)):
        for q in range(b.entry.shape[1]):
            if b.span[m, q] < 0:
                continue
            a, e = b.entry[m, q], b.entry[m, q] + b.span[m, q]
            # sin is largest at pi/2 (+ 2 pi k) inside the arc, else at an end
            k = math.ceil((a - math.pi / 2) / _TWO_PI - 1e-12)
            top = 1.0 if math.pi / 2 + k * _TWO_PI <= e + 1e-12 else max(math.sin(a), math.sin(e))
            best = max(best, top * float(b.sk[m]))
    return feed_per_tooth * best


FORCE_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("cl", "", "CL index"),
    ("file", "", "source file of the move"),
    ("line", "", "1-based source line"),
    ("operation", "", "operation"),
    ("status", "", "engagement status of the CL (engaged, air, rapid, failed)"),
    ("feed_mm_min", "mm/min", "programmed feed along the path"),
    ("rpm", "1/min", "spindle speed"),
    ("feed_per_tooth_mm", "mm", "horizontal feed per tooth c"),
    *((f"f{a}{fr}_{k}_N", "N", f"{'largest |F' + a + '|' if k == 'peak' else 'mean F' + a} over a revolution, "
       f"{'feed frame (x feed, y 90 deg CCW, z up)' if not fr else 'machine frame'}")
      for fr in ("", "_machine") for a in "xyz" for k in ("peak", "mean")),
    ("resultant_peak_N", "N", "largest |F| over a revolution"),
    ("resultant_mean_N", "N", "mean |F| over a revolution"),
    ("torque_peak_Nm", "N*m", "largest cutting torque over a revolution"),
    ("torque_mean_Nm", "N*m", "mean cutting torque"),
    ("power_peak_W", "W", "largest spindle cutting power"),
    ("power_mean_W", "W", "mean spindle cutting power"),
    ("chip_peak_mm", "mm", "largest uncut chip thickness"),
)
"""Columns of :func:`forces_table`: (name, unit, meaning). Forces act on the tool."""


def forces_table(
    maps: Sequence[EngagementMap],
    tool: MillingTool,
    coefficients: CuttingCoefficients,
    rpm: float | Sequence[float | None],
    *,
    dz: float | None = None,
    samples: int = 360,
):  # -> pandas.DataFrame (imported lazily: the force model itself does not need pandas)
    """Per-CL force summary (columns :data:`FORCE_COLUMNS`, units in the names), one row per map.

    ``rpm`` is one spindle speed (rev/min) or one per map. Rapids, failed CLs, feed moves without a
    feed and CLs without a spindle speed get NaN forces (unknown, not zero); air CLs get zeros.
    """
    rpms = [rpm] * len(maps) if isinstance(rpm, (int, float)) else list(rpm)
    if len(rpms) != len(maps):
        raise InputError(f"{len(rpms)} spindle speeds for {len(maps)} CLs")
    names = [c[0] for c in FORCE_COLUMNS]
    rows = []
    for emap, n in zip(maps, rpms):
        row: dict[str, object] = dict.fromkeys(names, math.nan)
        row.update(cl=emap.cl_index, file=str(emap.source.file), line=int(emap.source.line),
                   operation=emap.operation, status=emap.status.value,
                   feed_mm_min=math.nan if emap.feed is None else float(emap.feed),
                   rpm=math.nan if not n else float(n))
        known = (emap.status not in (CLStatus.FAILED, CLStatus.RAPID) and emap.feed is not None and bool(n))
        if known:
            f = compute_cl_forces(emap, tool, coefficients, rpm=float(n), dz=dz, samples=samples)  # type: ignore[arg-type]
            s = f.summary()
            s.pop("cl_index")
            row.update(s)
            row["chip_peak_mm"] = peak_chip_thickness(emap, tool, f.feed_per_tooth, dz=dz)
        rows.append(row)
    return _force_frame(rows)


def _force_frame(rows: list[dict[str, object]]):  # -> pandas.DataFrame
    import pandas as pd

    df = pd.DataFrame(rows, columns=[c[0] for c in FORCE_COLUMNS])
    return df.astype({"cl": "int64", "line": "int64", "file": "string", "operation": "string", "status": "string"})


def forces_from_results(
    results: Results,
    coefficients: CuttingCoefficients,
    *,
    rpm: float | None = None,
    tools: dict[str, MillingTool] | None = None,
    dz: float | None = None,
    samples: int = 360,
):  # -> pandas.DataFrame
    """Per-CL force table (:func:`forces_table`, rows in ``cl`` table order) of a results folder with
    what it records, no program needed: each CL's tool (:attr:`Results.tools` by the ``tool`` label),
    the program's spindle speed at its move (``spindle_rpm``), the slice height and the slices' bands.

    ``rpm`` (rev/min) replaces every recorded speed; ``tools`` (label -> tool) replaces recorded tools
    (e.g. another flute count); ``dz`` (mm) is only for folders that do not record the slice height
    (:func:`results_slice_height`). A folder that does not record the speeds needs ``rpm``; a tool
    without a full record needs ``tools``: both are :class:`InputError` naming the folder. CLs whose
    move had no spindle speed programmed get NaN forces (unknown).
    """
    import pandas as pd

    if rpm is None and "spindle_rpm" in results.missing:
        raise InputError("the spindle speeds are not recorded (results written before they were): give the "
                         "spindle speed (--rpm)", results.path)
    dz = results_slice_height(results, dz)
    maps = engagement_maps_from_results(results, dz)
    recorded = results.cl["spindle_rpm"].to_numpy(dtype=float)
    rpms = [float(rpm) if rpm is not None else None if math.isnan(n) else float(n) for n in recorded]
    groups: dict[str, list[int]] = {}
    for i, m in enumerate(maps):
        groups.setdefault(m.tool, []).append(i)
    parts = []
    for label, idx in groups.items():
        tool = (tools or {}).get(label) or results.tool(label)
        part = forces_table([maps[i] for i in idx], tool, coefficients, [rpms[i] for i in idx], dz=dz,
                            samples=samples)
        part.index = idx
        parts.append(part)
    return pd.concat(parts).sort_index() if parts else _force_frame([])
