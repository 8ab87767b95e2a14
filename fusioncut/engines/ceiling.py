"""A conservative height map of the workpiece's material, to skip sweeps that only cut air.

Why: in adaptive clearing many CL segments sweep through material earlier segments already removed
(trochoid return arcs, linking moves over the cleared floor). The kernel proves "nothing removed" only
with a full intersection, ~50 ms a cell on the benchmark, and a distance test proves nothing because
such sweeps still touch the walls and floors they run along. This map proves it for most of them in
well under a millisecond, exactly in the sense that matters: a skipped (cell, segment) pair would have
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

from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Move
from fusioncut.model.tools import MillingTool, ProfileArc

Box = tuple[tuple[float, float, float], tuple[float, float, float]]

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

    def distance(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """Distance (mm) from the points (X, Y) to the path (arrays broadcast together)."""
        if self.center is None:
            return _segment_distance(X, Y, self.p0, self.p1)
        cx, cy = self.center
        on_arc = np.abs(np.hypot(X - cx, Y - cy) - self.rho)
        if abs(self.sweep) >= 2 * math.pi:
            return on_arc
        rel = (np.arctan2(Y - cy, X - cx) - self.start_angle) * math.copysign(1.0, self.sweep) % (2 * math.pi)
        d_ends = np.minimum(np.hypot(X - self.p0[0], Y - self.p0[1]), np.hypot(X - self.p1[0], Y - self.p1[1]))
        return np.where(rel <= abs(self.sweep), on_arc, d_ends)


def _segment_distance(X: np.ndarray, Y: np.ndarray, p0: tuple[float, float], p1: tuple[float, float]) -> np.ndarray:
    dx, dy = p1[0] - p0[0], p1[1] - p0[1]
    L2 = dx * dx + dy * dy
    if L2 == 0.0:
        return np.hypot(X - p0[0], Y - p0[1])
    t = np.clip(((X - p0[0]) * dx + (Y - p0[1]) * dy) / L2, 0.0, 1.0)
    return np.hypot(X - (p0[0] + t * dx), Y - (p0[1] + t * dy))


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
        self.half_diagonal = pixel * math.sqrt(0.5)

    def _window(self, fp: SweepFootprint, margin: float, above: float):
        """The pixel ranges around the footprint, and of the pixels there whose height bound is above
        ``above`` (mm) their indices in the window and the distances of their centres to the path.

        Only those pixels can matter to a test or a clear, and along a trochoid most of the window
        lies in the slot already cut: measuring the distance of just these took the map's share of a
        benchmark CL from ~0.8 ms to ~0.3 ms (the same pixels, the same formula)."""
        x0, y0, x1, y1 = fp.box(margin)
        i0, j0 = self._index(x0, y0)
        i1, j1 = self._index(x1, y1)
        nx, ny = self.heights.shape
        i0, j0, i1, j1 = max(i0, 0), max(j0, 0), min(i1 + 1, nx), min(j1 + 1, ny)
        if i0 >= i1 or j0 >= j1:
            return None
        si, sj = slice(i0, i1), slice(j0, j1)
        ii, jj = np.nonzero(self.heights[si, sj] > above)
        p = self.pixel
        xs = self.origin[0] + (ii + i0 + 0.5) * p
        ys = self.origin[1] + (jj + j0 + 0.5) * p
        return si, sj, ii, jj, fp.distance(xs, ys)

    def _index(self, x: float, y: float) -> tuple[int, int]:
        return math.floor((x - self.origin[0]) / self.pixel), math.floor((y - self.origin[1]) / self.pixel)

    def may_cut(self, fp: SweepFootprint, boxes: list[Box]) -> list[bool]:
        """For each box (of a workpiece cell's material), whether the sweep may remove material in it."""
        win = self._window(fp, fp.reach + self.pixel, fp.z_low + NOISE)
        if win is None:
            return [False] * len(boxes)
        si, sj, ii, jj, d = win
        hot = d - self.half_diagonal < fp.reach
        ii, jj = ii[hot] + si.start, jj[hot] + sj.start
        if not len(ii):
            return [False] * len(boxes)
        out = []
        for (lo, hi) in boxes:
            # every pixel that overlaps the box, and one more on each side
            a0, b0 = self._index(lo[0], lo[1])
            a1, b1 = self._index(hi[0], hi[1])
            out.append(bool(((ii >= a0 - 1) & (ii < a1 + 2) & (jj >= b0 - 1) & (jj < b1 + 2)).any()))
        return out

    def clear(self, fp: SweepFootprint) -> None:
        """Record that the sweep has been removed from the material."""
        if fp.r_clear is None:
            return
        # only pixels above the tip can be lowered
        win = self._window(fp, fp.r_clear + self.pixel, fp.z_clear)
        if win is None:
            return
        si, sj, ii, jj, d = win
        view = self.heights[si, sj]
        inside = (d + self.half_diagonal <= fp.r_clear) & (view[ii, jj] <= fp.z_top)
        view[ii[inside], jj[inside]] = fp.z_clear
