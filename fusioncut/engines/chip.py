"""The minimum chip thickness: slice bands whose cut is thinner than it only rub.

Posts round coordinates to 1 µm or 0.1 µm, so a pass that retraces an earlier one (a deeper step of
a pocket, a finishing pass) often lies a fraction of a µm beside it and takes a skin that thin off the
earlier pass's wall. The skin's contact arcs are wide (up to 90° at the end wall), so the arc says
nothing about the chip; what was removed does. Per slice band k (``[k, k+1) * slice_height`` above
the tip, as :func:`fusioncut.engines.brep.engine.slice_heights` lays them out) the band's removed
width across the path is

    w_k = (volume the CL removed inside the band) / (band height in flute contact) / (horizontal travel)

(mm; mm³ / mm / mm): a 10 mm slot gives 10, side milling at ae 0.5 gives 0.5, a 0.5 µm skin 0.0005.
A band with contact arcs and ``w_k`` below the minimum chip thickness only rubs: its arcs are no
engagement. A CL without horizontal travel (a plunge) or whose per-band volumes are unknown is never
called rubbing. The measure averages over the CL segment: material removed along the segment but
away from the tool's end position counts as much as material at it, so a long segment that enters
the material only at its very end may be called rubbing where its end position cuts a few µm deep.
"""
from __future__ import annotations

import math
from collections.abc import Iterable

from fusioncut.model.moves import ArcMove, ArcPlane, Move


def horizontal_travel(move: Move) -> float | None:
    """The distance (mm) the CL travels across the tool axis: the XY length of a line, the arc
    length of an XY arc (mean of its start and end radius); None for an arc in another plane."""
    if isinstance(move, ArcMove):
        if move.plane != ArcPlane.XY:
            return None
        return abs(move.sweep) * 0.5 * (move.radius + move.end_radius)
    return math.hypot(move.end[0] - move.start[0], move.end[1] - move.start[1])


def band_volumes(pieces: Iterable[tuple[float, float, float]], z_tip: float, dz: float,
                 top: float) -> tuple[float, ...]:
    """Removed volume (mm³) per slice band of height ``dz`` above ``z_tip`` (mm, machine frame), up
    to ``top`` mm above the tip, from ``pieces`` (z_lo, z_hi, area lost in mm²), each a prism of
    removed material between two machine heights."""
    n = max(0, math.ceil(top / dz - 1e-9))
    out = [0.0] * n
    for z_lo, z_hi, lost in pieces:
        lo, hi = z_lo - z_tip, z_hi - z_tip
        for k in range(max(0, math.floor(lo / dz)), min(n, math.ceil(hi / dz))):
            overlap = min(hi, (k + 1) * dz) - max(lo, k * dz)
            if overlap > 0:
                out[k] += lost * overlap
    return tuple(out)


def rubbing_bands(volumes: tuple[float, ...] | None, z_range: tuple[float, float], dz: float,
                  travel: float | None, min_chip: float) -> set[int]:
    """Indices of the bands whose removed width across the path is below ``min_chip`` (mm).

    ``volumes``: removed volume per band (mm³; None: unknown, then no band rubs; a band past its end
    removed nothing). ``z_range``: the flute contact's heights above the tip (mm). ``travel``: the
    CL's horizontal travel (mm; None or 0: no band rubs). ``min_chip`` 0 turns the test off.
    """
    if volumes is None or not travel or travel <= 0 or min_chip <= 0:
        return set()
    z_lo, z_hi = z_range
    out = set()
    for k in range(math.ceil(z_hi / dz - 1e-9)):
        height = min((k + 1) * dz, z_hi) - max(k * dz, z_lo)
        if height <= 0:
            continue
        volume = volumes[k] if k < len(volumes) else 0.0
        if volume / height / travel < min_chip:
            out.add(k)
    return out


def cutting_range(z_range: tuple[float, float], cutting: Iterable[int], dz: float) -> tuple[float, float]:
    """The flute contact's height range (mm above the tip) clamped to the bands ``cutting``;
    (0, 0) when none cuts."""
    ks = list(cutting)
    if not ks:
        return (0.0, 0.0)
    return (max(z_range[0], min(ks) * dz), min(z_range[1], (max(ks) + 1) * dz))


def without_rubbing(arcs: list[list], volumes: tuple[float, ...] | None, z_range: tuple[float, float],
                    dz: float, travel: float | None, min_chip: float) -> tuple[list[list], tuple[float, float], int]:
    """(the bands' arcs with those of rubbing bands left out, the contact range clamped to the bands
    that cut, how many bands with arcs rub). ``arcs`` holds one list per band from the tip up;
    nothing changes when no band with arcs rubs."""
    rubbing = {k for k in rubbing_bands(volumes, z_range, dz, travel, min_chip) if k < len(arcs) and arcs[k]}
    if not rubbing:
        return arcs, z_range, 0
    arcs = [[] if k in rubbing else a for k, a in enumerate(arcs)]
    return arcs, cutting_range(z_range, (k for k, a in enumerate(arcs) if a), dz), len(rubbing)


def summed(a: tuple[float, ...] | None, b: tuple[float, ...] | None) -> tuple[float, ...] | None:
    """Per-band volumes of two parts of the workpiece added band by band; None if either is unknown."""
    if a is None or b is None:
        return None
    return tuple((a[k] if k < len(a) else 0.0) + (b[k] if k < len(b) else 0.0) for k in range(max(len(a), len(b))))
