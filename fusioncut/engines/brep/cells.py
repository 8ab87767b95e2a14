"""The workpiece as cells: square columns of material on a quadtree grid, and the tests by which a CL
leaves a cell alone.

A :class:`Cell` holds the material of one grid column over the full stock height, as a B-Rep solid
or as a stack of 2.5D layers (:mod:`fusioncut.engines.brep.layers`). The grid is laid over the stock
by :func:`split_into_cells` and is a quadtree: a solid cell may be replaced by its four quarter
squares (:func:`quarter_cells`), down to
``cell_size / MAX_SPLIT``, so that only the part near material that is not 2.5D stays solid.

Before a sweep is built a CL drops the cells it cannot cut: those outside the box of the tool's reach
(:func:`reach_box`), and those whose column lies out of the reach of a line's path or behind an open
start (:func:`column_clear_of`). :class:`ClearedTool` records where the last CL's tool left no
material, so that the next sweep may leave the tool at its start out (:func:`starts_cleared`).
"""
from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import NamedTuple

from OCP.TopoDS import TopoDS_Shape

from fusioncut.engines.brep.layers import Layer, solid_layers, stack_box, stack_solid, stack_volume
from fusioncut.engines.brep.occ import Vec3, bounding_box, count_faces, in_box, solids, volume
from fusioncut.engines.brep.sweep import cylinder_tool
from fusioncut.engines.ceiling import Box, SweepFootprint, tool_radii
from fusioncut.model.moves import ArcMove, Move
from fusioncut.model.tools import MillingTool

log = logging.getLogger("fusioncut.engine")

# a solid cell is split into quarters down to cell_size / MAX_SPLIT (20 mm cells: 5 mm)
MAX_SPLIT = 4


class Square(NamedTuple):
    """A grid column ``[x0, x0 + size] × [y0, y0 + size]`` (mm)."""

    x0: float
    y0: float
    size: float


@dataclass
class Cell:
    """One column of the IPW: its material and bounding box (mm).

    The material is either a B-Rep ``solid`` or, while only cylindrical tools have cut it
    horizontally or vertically, a stack of 2.5D ``layers`` (:mod:`fusioncut.engines.brep.layers`);
    then the solid is built only when asked for (``shape``) and kept until the next cut.
    ``square`` is the column of the grid the cell stands for (None: the whole workpiece in one
    cell); a solid cell may be split into its four quarter squares. ``swept`` maps each cutting
    region the layers took (its ``CuttingRegion.key``) to the lowest tip height (mm) it was taken
    from: above that the cell holds none of it, whatever came later, so a cut along the very same
    path deeper down (the next depth level of an adaptive clearing, the next pass of a contour) cuts
    only the layers below that height.
    """

    solid: TopoDS_Shape | None
    box: Box | None
    faces_at_merge: int = 0
    volume: float = 0.0
    layers: tuple[Layer, ...] | None = None
    square: Square | None = None
    swept: dict[tuple, float] = field(default_factory=dict, repr=False)

    @classmethod
    def of_solid(cls, shape: TopoDS_Shape, square: Square | None, faces_at_merge: int | None = None,
                 shape_volume: float | None = None) -> Cell:
        """A solid cell; ``faces_at_merge`` defaults to the shape's face count (a fresh cell)."""
        cell = cls(None, None, count_faces(shape) if faces_at_merge is None else faces_at_merge, square=square)
        cell.set(shape, shape_volume)
        return cell

    @property
    def empty(self) -> bool:
        return self.solid is None and not self.layers

    @property
    def shape(self) -> TopoDS_Shape | None:
        if self.solid is None and self.layers:
            self.solid = stack_solid(self.layers)
        return self.solid

    def set(self, shape: TopoDS_Shape | None, shape_volume: float | None = None) -> None:
        """The material as a solid from now on."""
        if shape is not None and not solids(shape):
            shape = None
        self.layers = None
        self.solid = shape
        self.box = bounding_box(shape) if shape is not None else None
        self.volume = 0.0 if shape is None else volume(shape) if shape_volume is None else shape_volume

    def set_layers(self, layers: tuple[Layer, ...]) -> None:
        self.layers = layers or None
        self.solid = None
        self.box = stack_box(layers) if layers else None
        self.volume = stack_volume(layers) if layers else 0.0

    def to_layers(self, max_layers: int) -> None:
        """Take the layered form when the solid is 2.5D (a box stock's cell, or one only flat end
        mills have cut) in at most ``max_layers`` layers."""
        if self.layers is None and self.solid is not None:
            layers = solid_layers(self.solid, max_layers)
            if layers is not None:
                # the solid goes too: built again from the layers when needed, it is the very shape
                # a run resumed from a checkpoint (which keeps the layers) builds, bit for bit
                self.set_layers(layers)

    def to_solid(self) -> None:
        """Leave the layered form (a cut the layers cannot take is coming)."""
        if self.layers is not None:
            self.set(self.shape, self.volume)


# -- the quadtree -------------------------------------------------------------------------------------


def split_into_cells(solid: TopoDS_Shape, size: float | None) -> list[tuple[TopoDS_Shape, Square | None]]:
    """``solid`` cut into square columns of ``size`` mm in X and Y (full height); ``None``: whole.

    Returns (piece, square) per column, the square ``[x0, x0 + size] × [y0, y0 + size]`` it
    stands for (the outer columns' pieces reach past it: no sliver of material is left out); the
    square is None for the whole solid. Columns without material are left out. The grid starts at
    the corner of the solid's exact bounding box: the usual box is widened by the edges' tolerance
    (1e-7 mm), and walls that far from the round coordinates CAM programs use (a helix centred on a
    wall) sit within the kernel's tolerance of the sweeps' edges; the cells' volumes then drifted by
    1e-6 mm³ per CL, 1.7e-8 of the removal on a helical entry, against 3e-14 with exact walls.
    """
    if size is None:
        return [(solid, None)]
    lo, hi = bounding_box(solid, exact=True)
    nx = max(1, math.ceil((hi[0] - lo[0]) / size - 1e-9))
    ny = max(1, math.ceil((hi[1] - lo[1]) / size - 1e-9))
    out = []
    for i in range(nx):
        for j in range(ny):
            x0, y0 = lo[0] + i * size, lo[1] + j * size
            x1 = x0 + size if i < nx - 1 else hi[0] + 1.0
            y1 = y0 + size if j < ny - 1 else hi[1] + 1.0
            piece = in_box(solid, (x0 - 1.0 if i == 0 else x0, y0 - 1.0 if j == 0 else y0, lo[2] - 1.0),
                            (x1, y1, hi[2] + 1.0))
            if piece is not None:
                out.append((piece, Square(x0, y0, size)))
    return out


def quarters(solid: TopoDS_Shape, x: float, y: float) -> list[TopoDS_Shape | None]:
    """``solid`` split by the planes ``x`` and ``y`` (mm) into its quadrants, in the order
    (-x, -y), (+x, -y), (-x, +y), (+x, +y); None where a quadrant holds no material."""
    lo, hi = bounding_box(solid)
    out = []
    for ya, yb in ((lo[1] - 1.0, y), (y, hi[1] + 1.0)):
        for xa, xb in ((lo[0] - 1.0, x), (x, hi[0] + 1.0)):
            out.append(in_box(solid, (xa, ya, lo[2] - 1.0), (xb, yb, hi[2] + 1.0)) if xa < xb and ya < yb else None)
    return out


def halves(solid: TopoDS_Shape, axis: int, at: float) -> tuple[TopoDS_Shape | None, TopoDS_Shape | None]:
    """``solid`` split by the plane ``x = at`` (``axis`` 0) or ``y = at`` (1), mm: the parts below
    and above it, None where a part holds no material."""
    lo, hi = bounding_box(solid)
    lo, hi = [c - 1.0 for c in lo], [c + 1.0 for c in hi]
    below, above = list(hi), list(lo)
    below[axis] = above[axis] = at
    return in_box(solid, tuple(lo), tuple(below)), in_box(solid, tuple(above), tuple(hi))




def smallest_square(cell_size: float | None) -> float:
    """The size (mm, with 1e-9 to spare) below which a square is not split again."""
    return (cell_size or 0.0) / MAX_SPLIT * (1 + 1e-9)


def quarter_cells(cell: Cell, max_layers: int | None) -> list[Cell] | None:
    """The cell's four quarter squares (those with material), or None when the split fails or loses
    volume (1e-9 relative + 1e-6 mm³): then the cell stays whole and should not be tried again.

    A solid cell stays solid where any of its material is not 2.5D (the ledges a helical entry leaves
    on its bore, a ball end mill's scallops), and every Boolean of every CL near it pays for all its
    faces; its quarters away from such material go back to the cheap layered cuts (``max_layers``:
    those that are 2.5D in at most that many layers take them; None: none do). Quarters stay
    quarters, and a ball end mill's finish over them pays a Boolean per quarter it reaches
    (``docs/decisions/engine-cells.md`` on the depth of the split).
    """
    x0, y0, size = cell.square
    half = 0.5 * size
    try:
        pieces = quarters(cell.shape, x0 + half, y0 + half)
    except Exception as exc:  # noqa: BLE001 - splitting is an optimisation: keep the cell as it is
        log.debug("cell at %s not split: %s", cell.square, exc)
        return None
    volumes = [volume(p) if p is not None else 0.0 for p in pieces]
    if abs(sum(volumes) - cell.volume) > 1e-9 * abs(cell.volume) + 1e-6:
        log.debug("cell at %s not split: the quarters hold %.3g mm³ more than the cell", cell.square,
                  sum(volumes) - cell.volume)
        return None
    out = []
    for (i, j), piece, piece_volume in zip(((0, 0), (1, 0), (0, 1), (1, 1)), pieces, volumes):
        if piece is None:
            continue
        quarter = Cell.of_solid(piece, Square(x0 + i * half, y0 + j * half, half), shape_volume=piece_volume)
        quarter.swept = dict(cell.swept)
        if max_layers is not None:
            quarter.to_layers(max_layers)
        out.append(quarter)
    return out


class Wall(NamedTuple):
    """A neighbour of a cell and the wall they share: the plane ``x = at`` (axis 0) or ``y = at``
    (axis 1), mm."""

    neighbour: Cell
    axis: int
    at: float


def neighbours(cells: list[Cell], cell: Cell) -> Iterator[Wall]:
    """Each cell with material whose column shares a wall (a segment of positive length) with
    ``cell``'s."""
    if cell.square is None:
        return
    x0, y0, size = cell.square
    for n in cells:
        if n is cell or n.empty or n.square is None:
            continue
        a0, b0, other = n.square
        for axis, (lo, hi, nlo, nhi), (olo, ohi, onlo, onhi) in (
                (0, (x0, x0 + size, a0, a0 + other), (y0, y0 + size, b0, b0 + other)),
                (1, (y0, y0 + size, b0, b0 + other), (x0, x0 + size, a0, a0 + other))):
            overlap = min(ohi, onhi) - max(olo, onlo)
            if overlap <= 1e-9:
                continue
            if abs(hi - nlo) <= 1e-9 * size:
                yield Wall(n, axis, hi)
            elif abs(nhi - lo) <= 1e-9 * size:
                yield Wall(n, axis, lo)


# -- what a CL may leave alone --------------------------------------------------------------------------


class ClearedTool(NamedTuple):
    """Where the last CL's tool left no material (mm): the cylinder from ``z_lo`` to ``z_hi`` of
    ``radius`` about (x, y) that a cylindrical tool emptied (radius 0 for another tool), and that
    tool's ``repr`` (``tool_key``), which identifies a tool that is not one cylinder. Saved in
    checkpoints as a JSON list in this order."""

    x: float
    y: float
    z_lo: float
    z_hi: float
    radius: float
    tool_key: str

    @classmethod
    def at_end(cls, end: Vec3, tool: MillingTool) -> ClearedTool:
        """What the tool standing at ``end`` leaves empty once an exact sweep has cut it."""
        cyl = cylinder_tool(tool)
        height = cyl[1] if cyl else tool_radii(tool)[2]
        return cls(end[0], end[1], end[2], end[2] + height, cyl[0] if cyl else 0.0, repr(tool))


def starts_cleared(motion: Move, tool: MillingTool, cleared: ClearedTool | None) -> bool:
    """Whether the tool the previous CL left empty holds this tool at the start of ``motion``: for a
    cylindrical tool, a disk as wide over the whole height its sweep reaches; for another tool, the
    very same tool at the very same point. Then the sweep (and the layers' region) may leave the
    tool at the start out: same material, cheaper Booleans."""
    if cleared is None or (cleared.x, cleared.y) != motion.start[:2]:
        return False
    cyl = cylinder_tool(tool)
    if cyl is None:
        return cleared.tool_key == repr(tool) and cleared.z_lo == motion.start[2]
    z_tip, z_end = sorted((motion.start[2], motion.end[2]))
    return cleared.z_lo <= z_tip and z_end + cyl[1] <= cleared.z_hi and cyl[0] <= cleared.radius


def reach_box(fp: SweepFootprint, motion: Move, tool: MillingTool) -> Box:
    """A box (mm) around everything the tool's sweep along ``motion`` can reach, with 1e-6 mm to spare."""
    x0, y0, x1, y1 = fp.box(fp.reach + 1e-6)
    top = max(motion.start[2], motion.end[2]) + tool_radii(tool)[2]
    return (x0, y0, fp.z_low - 1e-6), (x1, y1, top + 1e-6)


def column_clear_of(square: Square | None, motion: Move, reach: float, open_start: bool) -> bool:
    """Whether the grid column ``square`` meets the exact sweep along a line ``motion`` in zero
    volume: the column lies ``reach`` mm or more from the line's XY path, or, for a level line whose
    sweep leaves the tool at its start out (``open_start``), wholly behind the start.

    A cell's material stands in its column (an outer column's reaches past it by at most 1e-9 of
    the grid), the sweep within ``reach`` of its path and, left open, ahead of its start; where the
    two only touch along a cell's wall their boxes, widened by the edges' tolerance, still overlap,
    and the Boolean would prove nothing removed at full cost (``docs/decisions/engine-cells.md``).
    """
    if square is None or isinstance(motion, ArcMove):
        return False
    x0, y0, size = square
    x1, y1 = x0 + size, y0 + size
    (ax, ay, az), (bx, by, bz) = motion.start, motion.end
    dx, dy = bx - ax, by - ay
    if open_start and az == bz and (dx or dy) and all(
            (cx - ax) * dx + (cy - ay) * dy <= 0.0 for cx in (x0, x1) for cy in (y0, y1)):
        return True
    return segment_box_distance((ax, ay), (bx, by), (x0, y0, x1, y1)) >= reach


def segment_box_distance(a: tuple[float, float], b: tuple[float, float],
                         box: tuple[float, float, float, float]) -> float:
    """The distance (mm) between the segment ``a``-``b`` and the rectangle ``box`` (x0, y0, x1, y1).

    >>> segment_box_distance((0.0, 5.0), (10.0, 5.0), (2.0, 0.0, 3.0, 1.0))
    4.0
    """
    x0, y0, x1, y1 = box
    # Liang-Barsky: the part of the segment inside the rectangle, if any
    lo, hi = 0.0, 1.0
    for p, q in ((a[0] - b[0], a[0] - x0), (b[0] - a[0], x1 - a[0]), (a[1] - b[1], a[1] - y0), (b[1] - a[1], y1 - a[1])):
        if p == 0.0:
            if q < 0.0:
                lo, hi = 1.0, 0.0
                break
        elif p < 0.0:
            lo = max(lo, q / p)
        else:
            hi = min(hi, q / p)
    if lo <= hi:
        return 0.0

    def to_box(p):
        return math.hypot(max(x0 - p[0], 0.0, p[0] - x1), max(y0 - p[1], 0.0, p[1] - y1))

    def to_segment(p):
        # the ceiling's segment distance in scalars: this runs for each candidate cell of each CL,
        # where numpy's per-call overhead outweighs the arithmetic
        ux, uy = b[0] - a[0], b[1] - a[1]
        L2 = ux * ux + uy * uy
        t = 0.0 if L2 == 0.0 else min(1.0, max(0.0, ((p[0] - a[0]) * ux + (p[1] - a[1]) * uy) / L2))
        return math.hypot(p[0] - a[0] - t * ux, p[1] - a[1] - t * uy)

    # apart, the nearest points are an end of the segment and a point of the rectangle, or a corner
    return min(to_box(a), to_box(b), *(to_segment((cx, cy)) for cx in (x0, x1) for cy in (y0, y1)))
