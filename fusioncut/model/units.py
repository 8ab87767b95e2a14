"""Units of length the readers convert from: FusionCut works in millimetres (mm, mm/min, degrees).

The inch is defined as exactly 25.4 mm (international yard and pound agreement); every reader that
meets inch input (G20 G-code, APT ``UNITS/INCHES``, inch tool libraries) scales by this one number.
"""
from __future__ import annotations

__all__ = ["MM_PER_INCH", "length_scale"]

MM_PER_INCH = 25.4


def length_scale(inch: bool) -> float:
    """Millimetres per program unit: :data:`MM_PER_INCH` for inch input, 1 for millimetres."""
    return MM_PER_INCH if inch else 1.0
