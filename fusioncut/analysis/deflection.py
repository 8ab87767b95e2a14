"""Static tool deflection and the surface location error of a milled wall.

The tool is a stepped Euler-Bernoulli cantilever clamped in the holder at the stick-out ``L`` (mm above
the tip): sections from the tip up, each with a length and a diameter (the fluted part with an
*effective* diameter, a fraction of the nominal one that gives the same bending stiffness as the
fluted cross-section; 0.8 D is a common value for two to four flutes), then the neck and the shank.
Young's modulus ``E`` in N/mm² (cemented carbide about 6e5, HSS about 2.1e5). Second moment of area of
a solid round section ``I = pi d^4 / 64`` (mm^4).

Deflection (unit-load method). With ``x`` the height above the tip, a lateral force ``P`` at ``x = a``
bends every section above it by ``M(x) = P (x - a)``; the deflection at ``x = b`` is

    delta(b) = P * int_{max(a, b)}^{L} (x - a) (x - b) / (E I(x)) dx

integrated in closed form section by section; for one section loaded and observed at the tip this is
``P L^3 / (3 E I)``. The compliance matrix ``C[i, j]`` (mm/N) is the deflection at height ``b_i`` per
newton at height ``a_j``; the two lateral directions bend alike and independently.

Per CL the forces of every engagement band (the force model, :mod:`fusioncut.analysis.forces`) are
applied at the band's height for every sampled spindle angle; the deflection of the edge point at
height ``z`` is the sum over the bands. A wall is finished where the edge passes immersion ``0`` (an
up-milling cut: the wall on the +y side of the feed frame) or ``180 deg`` (down-milling: the wall on
the -y side); the **surface location error** at height ``z`` is the deflection along the wall's normal
at the instant the edge at that height passes the wall, counted positive when the tool bends away from
the wall (material left, undercut) and negative when it bends into it (overcut). Only the quasi-static
deflection is modelled (no vibration, no holder or spindle compliance).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from fusioncut.analysis.forces import (CuttingCoefficients, _bands, _tooth_signal, _weights,
                                       feed_per_tooth_from_map)
from fusioncut.errors import GeometryError, InputError
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.tools import MillingTool

CARBIDE_E_N_MM2 = 6.0e5
_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class SteppedCantilever:
    """Sections ``(length_mm, diameter_mm)`` from the tip up to the clamp, and Young's modulus (N/mm²)."""

    sections: tuple[tuple[float, float], ...]
    youngs_modulus_n_mm2: float = CARBIDE_E_N_MM2

    def __post_init__(self) -> None:
        if not self.sections:
            raise InputError("a cantilever needs at least one section")
        for length, d in self.sections:
            if not (length > 0 and d > 0 and math.isfinite(length) and math.isfinite(d)):
                raise InputError(f"a section needs a length and a diameter > 0 mm, got {length!r}, {d!r}")
        if not (self.youngs_modulus_n_mm2 > 0 and math.isfinite(self.youngs_modulus_n_mm2)):
            raise InputError(f"Young's modulus must be > 0 N/mm², got {self.youngs_modulus_n_mm2!r}")

    @classmethod
    def for_tool(cls, tool: MillingTool, stick_out_mm: float, flute_diameter_factor: float = 0.8,
                 youngs_modulus_n_mm2: float = CARBIDE_E_N_MM2) -> "SteppedCantilever":
        """The tool from its tip to the holder face ``stick_out_mm`` above it: the flutes at
        ``flute_diameter_factor`` times the diameter, the neck (when the tool has one), the shank."""
        if not (stick_out_mm > 0 and math.isfinite(stick_out_mm)):
            raise InputError(f"stick-out must be > 0 mm, got {stick_out_mm!r}")
        if not (0 < flute_diameter_factor <= 1):
            raise InputError(f"the flutes' effective diameter factor must be in (0, 1], got {flute_diameter_factor!r}")
        steps: list[tuple[float, float]] = [(tool.flute_length, flute_diameter_factor * tool.diameter)]
        if tool.shoulder_length is not None:
            steps.append((tool.shoulder_length, tool.neck_diameter or tool.diameter))
        steps.append((math.inf, tool.shank_diameter or tool.diameter))
        sections, start = [], 0.0
        for top, d in steps:
            end = min(top, stick_out_mm)
            if end > start:
                sections.append((end - start, d))
                start = end
            if start >= stick_out_mm:
                break
        return cls(tuple(sections), youngs_modulus_n_mm2)

    @property
    def length(self) -> float:
        return float(sum(s[0] for s in self.sections))

    def compliance(self, observe_mm: Sequence[float], load_mm: Sequence[float]) -> np.ndarray:
        """``C[i, j]``: deflection (mm) at height ``observe_mm[i]`` per newton at height ``load_mm[j]``
        (heights above the tip, in ``[0, length]``)."""
        b = np.asarray(observe_mm, dtype=float)[:, None]
        a = np.asarray(load_mm, dtype=float)[None, :]
        if np.any(b < 0) or np.any(a < 0) or np.any(b > self.length + 1e-9) or np.any(a > self.length + 1e-9):
            raise InputError(f"heights must lie on the tool between the tip and the holder ({self.length:g} mm)")
        lo = np.maximum(a, b)
        out = np.zeros(np.broadcast_shapes(a.shape, b.shape))
        x0 = 0.0
        for length, d in self.sections:
            x1 = x0 + length
            ei = self.youngs_modulus_n_mm2 * math.pi * d ** 4 / 64.0
            s0, s1 = np.clip(lo, x0, x1), x1

            def prim(x: np.ndarray | float) -> np.ndarray:
                return x ** 3 / 3.0 - (a + b) * x ** 2 / 2.0 + a * b * x

            out += np.where(lo < x1, (prim(s1) - prim(s0)) / ei, 0.0)
            x0 = x1
        return out


@dataclass(frozen=True)
class CLDeflection:
    """Deflection of one CL over a revolution: ``angles`` (deg, tooth 0's tip), ``heights`` (mm above the
    tip, the engaged bands), ``deflection`` (mm, feed frame x and y, shape (S, M, 2)) of the edge point at
    each height, ``tip_peak_mm`` the largest deflection magnitude at the tip, ``sle_mm`` per height the
    surface location error of the wall finished there (NaN where no wall is finished: the band's arcs
    reach neither immersion 0 nor 180 deg) and ``wall`` ``"up"`` (the wall at immersion 0),
    ``"down"`` (at 180 deg; a slot reports this one) or ``""`` per height."""

    cl_index: int
    angles: np.ndarray
    heights: np.ndarray
    deflection: np.ndarray
    tip_peak_mm: float
    sle_mm: np.ndarray
    wall: tuple[str, ...]


def cl_deflection(emap: EngagementMap, tool: MillingTool, coefficients: CuttingCoefficients,
                  beam: SteppedCantilever, *, rpm: float, dz: float | None = None,
                  samples: int = 360) -> CLDeflection:
    """Static deflection and wall surface location error of one CL (module docstring)."""
    if emap.status == CLStatus.FAILED:
        raise GeometryError(f"no engagement known ({emap.reason or 'engine failed'})", emap.cl_index)
    angles = np.arange(samples) * (360.0 / samples)
    if not emap.engaged_slices:
        return CLDeflection(emap.cl_index, angles, np.zeros(0), np.zeros((samples, 0, 2)), 0.0, np.zeros(0), ())
    b = _bands(emap, tool, dz)
    c = feed_per_tooth_from_map(emap, rpm, tool.flutes)
    w = _weights(b, coefficients, c)  # [basis, band, (Fx, Fy, Fz, torque)] in the immersion frame
    lag = 2.0 * math.tan(math.radians(tool.helix_angle)) * b.z / tool.diameter
    theta = np.radians(angles)
    n = tool.flutes
    every = np.mod(theta[:, None] + np.arange(n) * (_TWO_PI / n), _TWO_PI).ravel()
    per_band = np.stack([_tooth_signal(every, lag[m:m + 1], _sub(b, m), w[:, m:m + 1, :])
                         .reshape(samples, n, 4).sum(axis=1)[:, :2] for m in range(len(b.z))], axis=1)  # (S, M, 2)
    if np.any(b.z > beam.length):
        raise InputError(f"CL {emap.cl_index}: engaged at {b.z.max():.3g} mm above the tip, beyond the "
                         f"stick-out {beam.length:g} mm", emap.source)
    comp = beam.compliance(np.concatenate(([0.0], b.z)), b.z)  # (1 + M, M)
    defl = np.einsum("ij,sjk->sik", comp, per_band)  # (S, 1 + M, 2), immersion frame
    tip = float(np.hypot(defl[:, 0, 0], defl[:, 0, 1]).max())
    # SLE: at height z_m the edge of tooth 0 is at phi = theta - lag_m; it passes the wall angle at
    # theta = phi_wall + lag_m (the teeth are alike); the periodic deflection is interpolated there
    sle = np.full(len(b.z), np.nan)
    walls = []
    for m in range(len(b.z)):
        ends = [(b.entry[m, q], b.entry[m, q] + b.span[m, q]) for q in range(b.entry.shape[1]) if b.span[m, q] >= 0]
        side = ""
        if any(_covers(lo, hi, math.pi) for lo, hi in ends):
            side, phi_wall, sign = "down", math.pi, 1.0  # wall on -y: bending to +y leaves material
        elif any(_covers(lo, hi, 0.0) for lo, hi in ends):
            side, phi_wall, sign = "up", 0.0, -1.0  # wall on +y: bending to +y cuts into it
        walls.append(side)
        if side:
            t = math.degrees((phi_wall + lag[m]) % _TWO_PI)
            sle[m] = sign * np.interp(t, np.r_[angles, 360.0], np.r_[defl[:, 1 + m, 1], defl[0, 1 + m, 1]])
    if emap.spindle.value == "ccw":
        defl[..., 1] *= -1.0  # immersion frame -> feed frame (M4 mirrors y)
    return CLDeflection(emap.cl_index, angles, b.z.copy(), defl[:, 1:], tip, sle, tuple(walls))


def _covers(lo: float, hi: float, phi: float) -> bool:
    """Whether the arc [lo, hi] (rad) reaches immersion ``phi`` (mod 2 pi), ends included within 1e-6."""
    k = math.ceil((lo - phi - 1e-6) / _TWO_PI)
    return phi + k * _TWO_PI <= hi + 1e-6


def _sub(b: object, m: int) -> object:
    """Band ``m`` of the force model's bands alone."""
    import dataclasses

    return dataclasses.replace(b, **{f.name: getattr(b, f.name)[m:m + 1] for f in dataclasses.fields(b)})


DEFLECTION_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("tip_deflection_peak_um", "um", "largest static deflection of the tool tip over a revolution"),
    ("sle_min_um", "um", "smallest wall surface location error over the heights finishing a wall (- overcut)"),
    ("sle_max_um", "um", "largest wall surface location error over the heights finishing a wall (+ undercut)"),
)
"""Columns of :func:`deflection_table`: (name, unit, meaning)."""


def deflection_table(maps: Sequence[EngagementMap], tool: MillingTool, coefficients: CuttingCoefficients,
                     beam: SteppedCantilever, rpm: Sequence[float | None], *, dz: float | None = None,
                     samples: int = 360):  # -> pandas.DataFrame
    """Per-CL deflection summary (columns :data:`DEFLECTION_COLUMNS`, micrometres), one row per map;
    NaN for rapids, failed CLs and CLs without a feed or spindle speed, and SLE NaN where no wall is
    finished."""
    import pandas as pd

    rows = []
    for emap, n in zip(maps, rpm):
        row = dict.fromkeys([c[0] for c in DEFLECTION_COLUMNS], math.nan)
        rows.append(row)
        if emap.status in (CLStatus.FAILED, CLStatus.RAPID) or not n or emap.feed is None:
            continue
        d = cl_deflection(emap, tool, coefficients, beam, rpm=float(n), dz=dz, samples=samples)
        row["tip_deflection_peak_um"] = 1e3 * d.tip_peak_mm
        known = d.sle_mm[np.isfinite(d.sle_mm)]
        if len(known):
            row["sle_min_um"], row["sle_max_um"] = 1e3 * float(known.min()), 1e3 * float(known.max())
    return pd.DataFrame(rows, columns=[c[0] for c in DEFLECTION_COLUMNS])
