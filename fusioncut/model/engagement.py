"""Engagement results: what the engine says about each cutter location (CL).

Units: lengths mm, areas mm², volumes mm³, angles degrees. Angular intervals are immersion angles
(see :mod:`fusioncut.model.angles`); machine-frame angles are derived on request. Heights ``z`` of a
slice are measured along the tool axis from the tool tip at the CL (``z_machine`` is the same height
in the machine frame).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

from fusioncut.errors import SourceLocation
from fusioncut.model.angles import machine_from_immersion
from fusioncut.model.tools import SpindleDirection


class CLStatus(str, Enum):
    ENGAGED = "engaged"  # the tool touches material at the end of the segment
    AIR = "air"  # nothing touched, nothing removed
    RAPID = "rapid"  # rapid move: not a cut (material it hits is still removed and warned about)
    FAILED = "failed"  # the kernel failed; ``reason`` says why and the shapes were saved


@dataclass(frozen=True)
class AngleInterval:
    """Engaged arc of one slice: the tooth enters at ``entry`` and leaves at ``exit`` (immersion, deg)."""

    entry: float
    exit: float

    @property
    def span(self) -> float:
        return self.exit - self.entry


@dataclass(frozen=True)
class SliceEngagement:
    """Engagement of the tool's cross-section at height ``z`` (mm above the tip), radius ``radius``."""

    z: float
    z_machine: float
    radius: float
    intervals: tuple[AngleInterval, ...]

    @property
    def radial_width(self) -> float:
        """Width of the engaged arcs across the feed direction (mm): ae of this slice."""
        ys = []
        for iv in self.intervals:
            lo, hi = math.radians(iv.entry), math.radians(iv.exit)
            ys += [math.cos(lo), math.cos(hi)]
            # cos is extreme at multiples of pi inside the interval
            k = math.ceil(lo / math.pi)
            while k * math.pi <= hi:
                ys.append(math.cos(k * math.pi))
                k += 1
        return self.radius * (max(ys) - min(ys)) if ys else 0.0


@dataclass(frozen=True)
class EngagementMap:
    """Everything known about one CL segment, the tool being at the segment's end point.

    ``feed_angle`` is the machine angle (deg) of the horizontal feed direction used for the immersion
    frame (for a plunge, the last horizontal direction, +X at the start of a program).
    ``rubbing_slices``: slices whose contact arcs only rub (the material removed in their band is
    thinner across the path than the minimum chip thickness, :mod:`fusioncut.engines.chip`); their
    arcs are left out of ``slices`` and ``axial_range`` covers only the slices that cut.
    ``engine``: which engine computed the CL, ``"analytic"`` or ``"brep"`` (the analytic engine
    hands a CL it cannot compute to the B-Rep engine, see
    :mod:`fusioncut.engines.analytic.fallback`); ``""`` until an engine or the runner says.
    """

    cl_index: int
    position: tuple[float, float, float]
    start: tuple[float, float, float]
    tool: str
    spindle: SpindleDirection
    feed_angle: float
    status: CLStatus
    source: SourceLocation = field(default_factory=SourceLocation)
    feed: float | None = None
    operation: str = ""
    slices: tuple[SliceEngagement, ...] = ()
    contact_area: float = 0.0
    shank_contact_area: float = 0.0
    removed_volume: float = 0.0
    reason: str = ""
    warnings: tuple[str, ...] = ()
    sweep_method: str = ""
    axial_range: tuple[float, float] = (0.0, 0.0)  # z-range (mm above the tip) of flute contact
    timings_ms: tuple[tuple[str, float], ...] = ()
    rubbing_slices: int = 0
    engine: str = ""

    @property
    def engaged_slices(self) -> tuple[SliceEngagement, ...]:
        return tuple(s for s in self.slices if s.intervals)

    @property
    def shank_contact(self) -> bool:
        return self.shank_contact_area > 0

    @property
    def ap(self) -> float:
        """Axial depth of cut (mm): the exact height range of the flute contact faces."""
        return self.axial_range[1] - self.axial_range[0]

    @property
    def ae(self) -> float:
        """Radial depth of cut (mm): the largest slice radial width."""
        return max((s.radial_width for s in self.slices), default=0.0)

    def machine_intervals(self, s: SliceEngagement) -> list[tuple[float, float]]:
        """Intervals of a slice as machine angles (deg, counter-clockwise from +X)."""
        out = []
        for iv in s.intervals:
            # a CW spindle runs the immersion angle clockwise, so counter-clockwise the arc starts at exit
            start = iv.exit if self.spindle == SpindleDirection.CW else iv.entry
            a = machine_from_immersion(start, self.feed_angle, self.spindle)
            out.append((a, a + iv.span))
        return out
