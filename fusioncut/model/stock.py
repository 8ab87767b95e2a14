"""Stock (raw workpiece) descriptions, machine frame, mm."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from fusioncut.errors import InputError

Point = tuple[float, float, float]


@dataclass(frozen=True)
class BoxStock:
    """Axis-aligned block from ``minimum`` to ``maximum`` corner (mm)."""

    minimum: Point
    maximum: Point
    inferred: bool = False  # True when guessed from the toolpath extents

    def __post_init__(self) -> None:
        if any(hi <= lo for lo, hi in zip(self.minimum, self.maximum)):
            raise InputError(f"box stock needs maximum > minimum on every axis, got {self.minimum}..{self.maximum}")

    @property
    def volume(self) -> float:
        dx, dy, dz = (hi - lo for lo, hi in zip(self.minimum, self.maximum))
        return dx * dy * dz

    @property
    def bounds(self) -> tuple[float, float, float, float, float, float]:
        """The box (x0, y0, z0, x1, y1, z1), mm."""
        return (*self.minimum, *self.maximum)


@dataclass(frozen=True)
class CylinderStock:
    """Round bar along +z: base centre ``base_center`` (mm), ``radius``, ``height``."""

    base_center: Point
    radius: float
    height: float

    def __post_init__(self) -> None:
        if self.radius <= 0 or self.height <= 0:
            raise InputError(f"cylinder stock needs radius and height > 0, got r={self.radius} h={self.height}")

    @property
    def bounds(self) -> tuple[float, float, float, float, float, float]:
        """The box holding the bar (x0, y0, z0, x1, y1, z1), mm."""
        (cx, cy, z0), r = self.base_center, self.radius
        return (cx - r, cy - r, z0, cx + r, cy + r, z0 + self.height)


@dataclass(frozen=True)
class SolidStock:
    """Any solid read from a STEP or BREP file."""

    path: Path


Stock = BoxStock | CylinderStock | SolidStock
