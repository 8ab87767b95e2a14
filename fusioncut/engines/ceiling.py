"""A conservative height map of the workpiece's material, to skip sweeps that only cut air.

Why: in adaptive clearing many CL segments sweep through material earlier segments already removed
(trochoid return arcs, linking moves over the cleared floor). The kernel proves "nothing removed" only
with a full intersection of the cell, and a distance test proves nothing because
such sweeps still touch the walls and floors they run along. This map proves it for most of them at
a small fraction of that cost (``docs/decisions/engine-measurements.md``), exactly in the sense that matters: a skipped (cell, segment) pair would have
removed zero volume.

The map is a grid of square pixels (``pixel`` mm) over the workpiece's XY bounds. ``heights[i, j]`` is an
**upper bound** of the machine Z (mm) of any material over pixel (i, j). It starts at the workpiece's top
and is lowered only on proof, so it stays an upper bound whatever tools and moves come:

* **test**: a sweep lies within ``dist(xy, path) <= reach`` and ``z >= z_low`` (the tip's lowest height:
  every tool here has its body at or above its tip). If no pixel within reach has a height above
  ``z_low`` (plus 1e-9 mm of arithmetic noise, far below the kernel's 1e-7 mm confusion tolerance),
  the sweep meets the material in zero volume.
* **clear**: a tool whose body holds the whole cylinder of radius ``r_clear`` from its tip to its top
  (flat end mills; tapered and chamfer tools with a flat tip: a line-only outline that never goes down)
  moved horizontally or vertically removes every point within ``r_clear`` of the path from the tip's
  height up to its top. A pixel entirely inside that region, whose height bound the top reaches, gets
  the tip's height as its new bound.

A pixel is tested with the distance of its centre less half its diagonal (every point of it is at least
that far from the path) and cleared with the distance plus half its diagonal. Tools with arcs in their
outline (ball, bull nose) are tested but never clear pixels: their bottom is not flat.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit

from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Move, Point
from fusioncut.model.tools import MillingTool, ProfileArc

Box = tuple[Point, Point]  # (lowest corner, highest corner), mm

NOISE = 1e-9  # mm: heights this close count as equal (see the module docstring)
_FLAT = 1e-12  # mm: a move whose ends differ less than this in Z is horizontal


@dataclass(frozen=True)
class SweepFootprint:
    """Where a sweep can be and what it surely removes, in the map's terms (mm, rad).

    The path is a segment ``p0``-``p1`` (a point when equal) or, when ``center`` is set, the arc of
    radius ``rho`` about it from angle ``start_angle`` through the signed ``sweep``, from ``p0`` to ``p1``.
    ``z_low``: the tip's lowest height; ``reach``: the tool's largest radius. ``z_clear``/``r_clear``/
    ``z_top``: the tip height, radius and top of the cylinder the sweep surely removes (``r_clear``
    None: nothing proven).
    """

    p0: tuple[float, float]
    p1: tuple[float, float]
    z_low: float
    reach: float
    center: tuple[float, float] | None = None
    rho: float = 0.0
    start_angle: float = 0.0
    sweep: float = 0.0
    r_clear: float | None = None
    z_clear: float = 0.0
    z_top: float = 0.0

    def box(self, margin: float) -> tuple[float, float, float, float]:
        """XY bounds (x0, y0, x1, y1) of the path grown by ``margin``."""
        if self.center is None:
            xs, ys = (self.p0[0], self.p1[0]), (self.p0[1], self.p1[1])
        else:  # the whole circle: simple and never too small
            cx, cy = self.center
            xs, ys = (cx - self.rho, cx + self.rho), (cy - self.rho, cy + self.rho)
        return min(xs) - margin, min(ys) - margin, max(xs) + margin, max(ys) + margin

    @property
    def path(self) -> tuple:
        """The path as the map's compiled kernels take it (see :func:`_path_distance`)."""
        cx, cy = self.center if self.center is not None else (0.0, 0.0)
        return (self.p0[0], self.p0[1], self.p1[0], self.p1[1], self.center is not None, cx, cy, self.rho,
                self.start_angle, self.sweep)

    def distance(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """Distance (mm) from the points (X, Y) to the path (arrays broadcast together)."""
        X, Y = np.broadcast_arrays(np.asarray(X, dtype=float), np.asarray(Y, dtype=float))
        return _distances(X.ravel(), Y.ravel(), *self.path).reshape(X.shape)


# The map's tests and clears visit every pixel of a window around each CL's path (~15,000 at 0.1 mm
# for a 12 mm tool): compiled loops that stop at the first pixel that decides, instead of a dozen
# numpy passes over the window (each parallel worker pays this for every CL of the program).
@njit(cache=True)
def _path_distance(x: float, y: float, p0x: float, p0y: float, p1x: float, p1y: float, arc: bool,
                   cx: float, cy: float, rho: float, a0: float, sweep: float) -> float:
    """Distance (mm) from (x, y) to the segment p0-p1, or to the arc of radius ``rho`` about
    (cx, cy) from angle ``a0`` through the signed ``sweep`` (rad) when ``arc``."""
    if not arc:
        dx, dy = p1x - p0x, p1y - p0y
        length2 = dx * dx + dy * dy
        if length2 == 0.0:
            return math.hypot(x - p0x, y - p0y)
        t = min(max(((x - p0x) * dx + (y - p0y) * dy) / length2, 0.0), 1.0)
        return math.hypot(x - (p0x + t * dx), y - (p0y + t * dy))
    on_arc = abs(math.hypot(x - cx, y - cy) - rho)
    if abs(sweep) >= 2 * math.pi:
        return on_arc
    rel = ((math.atan2(y - cy, x - cx) - a0) * math.copysign(1.0, sweep)) % (2 * math.pi)
    if rel <= abs(sweep):
        return on_arc
    return min(math.hypot(x - p0x, y - p0y), math.hypot(x - p1x, y - p1y))


@njit(cache=True)
def _distances(xs, ys, p0x, p0y, p1x, p1y, arc, cx, cy, rho, a0, sweep):
    out = np.empty(xs.shape[0])
    for k in range(xs.shape[0]):
        out[k] = _path_distance(xs[k], ys[k], p0x, p0y, p1x, p1y, arc, cx, cy, rho, a0, sweep)
    return out


@njit(cache=True)
def _boxes_reached(heights, i0, i1, j0, j1, above, ox, oy, pixel, reach, boxes,
                   p0x, p0y, p1x, p1y, arc, cx, cy, rho, a0, sweep):
    """For each pixel range ``boxes[b] = (i_lo, j_lo, i_hi, j_hi)`` (half open), whether a pixel of
    the window [i0, i1) x [j0, j1) in it lies above ``above`` and nearer than ``reach`` to the path
    (its centre's distance less half its diagonal)."""
    n = boxes.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    left = n
    half_diagonal = pixel * math.sqrt(0.5)
    for i in range(i0, i1):
        x = ox + (i + 0.5) * pixel
        for j in range(j0, j1):
            if not heights[i, j] > above:
                continue
            reached = -1  # not measured yet: only for a pixel that an undecided box holds
            for b in range(n):
                if out[b] or not (boxes[b, 0] <= i < boxes[b, 2] and boxes[b, 1] <= j < boxes[b, 3]):
                    continue
                if reached < 0:
                    y = oy + (j + 0.5) * pixel
                    d = _path_distance(x, y, p0x, p0y, p1x, p1y, arc, cx, cy, rho, a0, sweep)
                    reached = 1 if d - half_diagonal < reach else 0
                if reached == 0:
                    break
                out[b] = True
                left -= 1
            if left == 0:
                return out
    return out


@njit(cache=True)
def _lower(heights, i0, i1, j0, j1, z_clear, z_top, ox, oy, pixel, r_clear,
           p0x, p0y, p1x, p1y, arc, cx, cy, rho, a0, sweep):
    """Lower to ``z_clear`` every pixel of the window above it, whose bound ``z_top`` reaches and
    which lies wholly within ``r_clear`` of the path (its centre's distance plus half its diagonal)."""
    half_diagonal = pixel * math.sqrt(0.5)
    for i in range(i0, i1):
        x = ox + (i + 0.5) * pixel
        for j in range(j0, j1):
            h = heights[i, j]
            if h > z_clear and h <= z_top:
                y = oy + (j + 0.5) * pixel
                if _path_distance(x, y, p0x, p0y, p1x, p1y, arc, cx, cy, rho, a0, sweep) + half_diagonal <= r_clear:
                    heights[i, j] = z_clear


@lru_cache(maxsize=64)
def tool_radii(tool: MillingTool) -> tuple[float, float | None, float]:
    """(reach, clear radius or None, length) of a tool (mm); see the module docstring."""
    profile = tool.profile()
    segs = profile.segments
    reach = max(s.center[0] + s.radius if isinstance(s, ProfileArc) else max(s.start[0], s.end[0]) for s in segs)
    first = segs[0]
    flat_tip = (not isinstance(first, ProfileArc) and first.start == (0.0, 0.0) and first.end[1] == 0.0
                and first.end[0] > 0.0)
    rising = all(s.end[1] >= s.start[1] for s in segs)
    r_clear = None
    if flat_tip and rising and not any(isinstance(s, ProfileArc) for s in segs):
        r_clear = min([first.end[0], *(min(s.start[0], s.end[0]) for s in segs[1:-1])])
        r_clear = r_clear if r_clear > 0 else None
    return reach, r_clear, profile.height


def footprint(motion: Move, tool: MillingTool) -> SweepFootprint | None:
    """The footprint of the exact sweep of ``tool`` along ``motion`` (what the engine sweeps), or None
    for motions the map does not describe (helices, ZX/YZ arcs). A sampled sweep leaves scallops, so
    it proves nothing removed: its caller drops ``r_clear``."""
    reach, r_clear, length = tool_radii(tool)
    (x0, y0, z0), (x1, y1, z1) = motion.start, motion.end
    if isinstance(motion, ArcMove):
        if motion.plane != ArcPlane.XY or motion.is_helix:
            return None
        cx, cy = motion.center[0], motion.center[1]
        rho = math.hypot(x0 - cx, y0 - cy)
        a0 = math.atan2(y0 - cy, x0 - cx)
        # the sweep builders follow the start's radius; a programmed end off that circle (real programs
        # have µm mismatches) widens what the sweep may reach and narrows what it surely removes
        end = (cx + rho * math.cos(a0 + motion.sweep), cy + rho * math.sin(a0 + motion.sweep))
        off = math.hypot(x1 - end[0], y1 - end[1])
        arc = dict(center=(cx, cy), rho=rho, start_angle=a0, sweep=motion.sweep)
        # an arc within 1e-9 mm of level is swept at its start's height, with the tool itself at its end
        z_low, z_high = min(z0, z1), max(z0, z1)
        if r_clear is not None and r_clear > off:
            return SweepFootprint((x0, y0), end, z_low, reach + off, **arc, r_clear=r_clear - off,
                                  z_clear=z_high, z_top=z_low + length)
        return SweepFootprint((x0, y0), end, z_low, reach + off, **arc)
    if not isinstance(motion, LinearMove):
        return None
    z_low = min(z0, z1)
    vertical = x0 == x1 and y0 == y1
    if r_clear is not None and (vertical or abs(z1 - z0) <= _FLAT):
        # a plunge removes the cylinder from its lowest tip up; a level move is swept at its start's
        # height, within 1e-12 mm of the higher end
        return SweepFootprint((x0, y0), (x1, y1), z_low, reach, r_clear=r_clear,
                              z_clear=z_low if vertical else max(z0, z1), z_top=z_low + length)
    return SweepFootprint((x0, y0), (x1, y1), z_low, reach)


class MaterialCeiling:
    """Upper bounds of the material's height over a pixel grid (see the module docstring).

    ``lo``/``hi``: the XY bounds the material lies in (mm); ``top``: its highest Z; ``pixel``: the pixel
    size (mm), grown when needed so the grid has at most ``max_pixels`` pixels (8 bytes each).
    """

    def __init__(self, lo: tuple[float, float], hi: tuple[float, float], top: float, pixel: float = 0.1,
                 max_pixels: int = 4_000_000) -> None:
        w, h = max(hi[0] - lo[0], pixel), max(hi[1] - lo[1], pixel)
        pixel = max(pixel, math.sqrt(w * h / max_pixels))
        self.pixel = pixel
        self.origin = (lo[0] - pixel, lo[1] - pixel)  # one pixel of margin all round
        self.heights = np.full((math.ceil(w / pixel) + 2, math.ceil(h / pixel) + 2), float(top))

    def _window(self, fp: SweepFootprint, margin: float) -> tuple[int, int, int, int] | None:
        """The pixel ranges [i0, i1) x [j0, j1) around the footprint's path grown by ``margin``."""
        x0, y0, x1, y1 = fp.box(margin)
        i0, j0 = self._index(x0, y0)
        i1, j1 = self._index(x1, y1)
        nx, ny = self.heights.shape
        i0, j0, i1, j1 = max(i0, 0), max(j0, 0), min(i1 + 1, nx), min(j1 + 1, ny)
        return None if i0 >= i1 or j0 >= j1 else (i0, i1, j0, j1)

    def _index(self, x: float, y: float) -> tuple[int, int]:
        return math.floor((x - self.origin[0]) / self.pixel), math.floor((y - self.origin[1]) / self.pixel)

    def may_cut(self, fp: SweepFootprint, boxes: list[Box]) -> list[bool]:
        """For each box (of a workpiece cell's material), whether the sweep may remove material in it."""
        win = self._window(fp, fp.reach + self.pixel)
        if win is None or not boxes:
            return [False] * len(boxes)
        ranges = np.empty((len(boxes), 4), dtype=np.int64)
        for b, (lo, hi) in enumerate(boxes):
            # every pixel that overlaps the box, and one more on each side
            a0, b0 = self._index(lo[0], lo[1])
            a1, b1 = self._index(hi[0], hi[1])
            ranges[b] = (a0 - 1, b0 - 1, a1 + 2, b1 + 2)
        reached = _boxes_reached(self.heights, *win, fp.z_low + NOISE, *self.origin, self.pixel, fp.reach,
                                 ranges, *fp.path)
        return [bool(r) for r in reached]

    def clear(self, fp: SweepFootprint) -> None:
        """Record that the sweep has been removed from the material."""
        if fp.r_clear is None:
            return
        win = self._window(fp, fp.r_clear + self.pixel)
        if win is not None:
            _lower(self.heights, *win, fp.z_clear, fp.z_top, *self.origin, self.pixel, fp.r_clear, *fp.path)


_warm = False


def load_kernels() -> None:
    """Compile (or load from numba's cache) the map's kernels now, once per process: the first call
    loads or compiles them, which would otherwise land in the first CL's time."""
    global _warm
    if not _warm:
        tiny = MaterialCeiling((0.0, 0.0), (1.0, 1.0), 0.0, pixel=0.5)
        for fp in (SweepFootprint((0.0, 0.0), (1.0, 0.0), -1.0, 1.0, r_clear=1.0, z_clear=-1.0, z_top=1.0),
                   SweepFootprint((0.0, 0.0), (1.0, 0.0), -1.0, 1.0, center=(0.5, 0.0), rho=0.5, sweep=1.0)):
            tiny.may_cut(fp, [((0.0, 0.0, -1.0), (1.0, 1.0, 0.0))])
            tiny.clear(fp)
        _warm = True
