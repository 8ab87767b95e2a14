"""A cell of the in-process workpiece as 2.5D columns, cut by planar regions.

While a cell has been cut only by cylindrical tools (flat end mills whose shank has the flute's
diameter) moving horizontally or vertically, its material is a height field: every point of its
footprint has material from the cell's bottom up to one height. It is kept as **columns**: planar
regions (disjoint, tiling the footprint), each extruded from the bottom up to its own height. Such a
cut sweeps the prism of a planar region (:func:`fusioncut.engines.brep.sweep.cylinder_region`) from
the tip up past the cell's top, so every column taller than the tip loses the region down to the
tip: the column keeps its region less the tool's, and what it lost becomes a column at the tip's
height. Doing that as 2D Booleans gives the same material as the 3D Boolean of the cell and the
prism, at a fraction of the cost (on the Titan-like benchmark's adaptive cells, 40-edge regions: a
2D Cut 0.3–2 ms against 3–16 ms for the 3D Cut of the same cell).

A cut costs a 2D Boolean for each column it reaches (by bounding boxes, above its tip), not for
each height in the cell: a helical entry leaves its bore's floor in 0.05 mm steps, some 40 heights
per turn, which the trochoids beside it never reach. (An earlier form of stacked horizontal layers
cut every layer above the tip, so such cells had to stay solid.)

Conventions: regions are compounds of planar faces in the plane z = 0 (mm); a column holds
``z_lo <= z <= z_hi`` (mm, machine frame) over its region; all columns of a cell share ``z_lo``.
Every cut reaches above the highest column (the engine cuts in 3D otherwise), so the material stays
a height field.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from OCP.BOPAlgo import BOPAlgo_Operation
from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Surface
from OCP.BRepClass import BRepClass_FaceClassifier
from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy, BRepBuilderAPI_MakeFace, BRepBuilderAPI_Transform
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepPrimAPI import BRepPrimAPI_MakePrism
from OCP.GeomAbs import GeomAbs_Circle, GeomAbs_Cylinder, GeomAbs_Plane
from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
from OCP.gp import gp_Ax3, gp_Cylinder, gp_Dir, gp_Pnt, gp_Trsf, gp_Vec
from OCP.TopAbs import TopAbs_IN, TopAbs_REVERSED
from OCP.TopoDS import TopoDS_Face, TopoDS_Shape

from fusioncut.engines.brep.occ import (
    area, boolean, bounding_box, boxes_overlap, compound, edges, faces, fuse_all, intersections, unify, volume,
)

Box = tuple[tuple[float, float, float], tuple[float, float, float]]
Z_SNAP = 1e-7  # mm: a tip this close to a column's boundary stops on it (no column thinner than this)


class RegionCutFailure(Exception):
    pass


@dataclass(frozen=True)
class Column:
    """Material between ``z_lo`` and ``z_hi`` (mm): ``region`` (planar faces at z = 0) extruded.

    ``tier``: how many rounds of merging built it (0: a piece one cut left under its tip; see
    :func:`cut_columns`); ``WHOLE_TIER``: all of its height when it was made (taken from a solid,
    or its level merged after the tool left it).
    """

    z_lo: float
    z_hi: float
    region: TopoDS_Shape
    area: float  # mm²
    box: Box  # the region's bounding box (z = 0)
    tier: int = 0

    @property
    def volume(self) -> float:
        return self.area * (self.z_hi - self.z_lo)


WHOLE_TIER = 1000


def make_column(z_lo: float, z_hi: float, region: TopoDS_Shape, tier: int = 0) -> Column:
    return Column(z_lo, z_hi, region, area(region), bounding_box(region), tier)


def _moved(shape: TopoDS_Shape, dz: float) -> TopoDS_Shape:
    t = gp_Trsf()
    t.SetTranslation(gp_Vec(0.0, 0.0, dz))
    return BRepBuilderAPI_Transform(shape, t, True).Shape()


def solid_columns(solid: TopoDS_Shape, max_heights: int) -> tuple[Column, ...] | None:
    """``solid`` as columns, one per height of its up faces (at most ``max_heights``), when it is
    2.5D, else None.

    That is: every face is vertical (a plane or a cylinder about a vertical axis) or horizontal,
    and the only face looking down is the bottom; so every point of the footprint has one top, and
    the up-looking faces tile the footprint. A box stock's cell is one column. The columns' volume
    must be the solid's (1e-9 relative).
    """
    z0 = bounding_box(solid, exact=True)[0][2]
    up: dict[float, list[TopoDS_Face]] = {}
    for f in faces(solid):
        s = BRepAdaptor_Surface(f)
        t = s.GetType()
        if t == GeomAbs_Cylinder:
            if abs(abs(s.Cylinder().Axis().Direction().Z()) - 1.0) > 1e-12:
                return None
            continue
        if t != GeomAbs_Plane:
            return None
        nz = s.Plane().Axis().Direction().Z() * (-1.0 if f.Orientation() == TopAbs_REVERSED else 1.0)
        if abs(nz) < 1e-12:
            continue  # a vertical wall
        z = s.Plane().Location().Z()
        if abs(abs(nz) - 1.0) > 1e-12 or (nz < 0 and abs(z - z0) > 1e-9):
            return None  # slanted, or an overhang: not 2.5D from above
        if nz > 0:
            key = next((k for k in up if abs(k - z) < 1e-9), z)
            up.setdefault(key, []).append(f)
            if len(up) > max_heights:
                return None
    heights = sorted(up)
    if not heights or heights[0] - z0 < Z_SNAP:
        return None
    columns = []
    for z in heights:
        tops = [_moved(f, -z) for f in up[z]]
        columns.append(make_column(z0, z, tops[0] if len(tops) == 1 else _union(tops), WHOLE_TIER))
    columns = tuple(columns)
    if abs(columns_volume(columns) - volume(solid)) > 1e-9 * columns_volume(columns):
        return None
    return columns


def _union(regions: list[TopoDS_Shape]) -> TopoDS_Shape:
    """One region from disjoint planar regions (z = 0): fused, and same-plane faces merged, each
    step kept only when it keeps the area (1e-9 relative) and is valid; else the regions' faces
    as they are, in one compound (the same material, only more faces)."""
    total = sum(area(r) for r in regions)
    as_is = compound([f for r in regions for f in faces(r)])
    try:
        fused = fuse_all(regions)
    except RuntimeError:
        return as_is
    if abs(area(fused) - total) > 1e-9 * total:
        return as_is
    u = ShapeUpgrade_UnifySameDomain(BRepBuilderAPI_Copy(fused).Shape(), True, True, False)
    u.Build()
    merged = u.Shape()
    return merged if abs(area(merged) - total) <= 1e-9 * total and BRepCheck_Analyzer(merged).IsValid() else fused


def columns_box(columns: tuple[Column, ...]) -> Box:
    """The columns' box, widened by the edges' tolerance in z as in x and y (the regions' boxes at
    z = 0 span ± that much), like the box of the same material as a solid: the material's height
    bounds start from the cells' box tops, and a run resumed from a checkpoint, whose cells may be
    in the other form, must start them at the same height."""
    return ((min(col.box[0][0] for col in columns), min(col.box[0][1] for col in columns), min(col.z_lo + col.box[0][2] for col in columns)),
            (max(col.box[1][0] for col in columns), max(col.box[1][1] for col in columns), max(col.z_hi + col.box[1][2] for col in columns)))


def columns_volume(columns: tuple[Column, ...]) -> float:
    return sum(col.volume for col in columns)


def columns_solid(columns: tuple[Column, ...]) -> TopoDS_Shape:
    """The columns as one B-Rep solid (their prisms fused, same-surface faces merged)."""
    prisms = [BRepPrimAPI_MakePrism(_moved(col.region, col.z_lo), gp_Vec(0.0, 0.0, col.z_hi - col.z_lo)).Shape()
              for col in columns]
    if len(prisms) == 1:
        return prisms[0]
    return unify(fuse_all(prisms), columns_volume(columns))


@dataclass(frozen=True)
class CuttingRegion:
    """What a cylindrical tool's move takes from columns: the planar region it covers (faces at
    z = 0), the tool's radius, and the heights of its tip and of its top (mm)."""

    face: TopoDS_Face
    radius: float
    z_tip: float
    z_top: float


@dataclass(frozen=True)
class ColumnCut:
    """What a cut took from one column: ``lost`` (planar faces at z = 0), from ``z_lo`` to
    ``z_hi`` (mm)."""

    z_lo: float
    z_hi: float
    lost: TopoDS_Shape


MERGE_COLUMNS = 8  # columns of one height and tier kept apart before they are fused (see cut_columns)


def cut_columns(columns: tuple[Column, ...], region: TopoDS_Shape, z_tip: float, z_top: float,
                fuzzy_values: tuple[float, ...]) -> tuple[tuple[Column, ...], float, list[ColumnCut]]:
    """The columns after removing the prism of ``region`` (z = 0) from ``z_tip`` to ``z_top`` (mm).

    Returns (new columns, removed volume in mm³, the cuts of the columns that lost material).
    ``z_top`` must reach the highest column (no overhang is left). A column whose box misses the
    region, or whose top is at or below the tip, costs no Boolean: a cut's cost is the number of
    columns it reaches, not the number of heights in the cell. The parts of the cut columns under
    the tip are new columns at the tip's height, of tier 0; when more than ``MERGE_COLUMNS`` columns
    of one height have one tier, they are fused into one of the next tier, and so on up, so that a
    piece takes part in a few merges of regions of its own size (on the full benchmark's adaptive
    CLs 5000-7000: merges 4.5 of 15.8 s, against 5.1 of 16.0 s merged straight into the level's
    floor; MERGE_COLUMNS 4 or 8 were equal on the quick benchmark, 1 and 32 slower). A cut that
    removes something also merges the columns of every other height into one each (see
    ``_merge_levels``). Raises :class:`RegionCutFailure` when a 2D Boolean fails with every fuzzy
    value.
    """
    if z_top < max(col.z_hi for col in columns) - Z_SNAP:
        raise ValueError("a cut of the columns must reach above the highest column")
    region_box = bounding_box(region)
    # snap the tip to a height it nearly touches: a Z_SNAP-thin step is noise, not material
    for col in columns:
        for z in (col.z_lo, col.z_hi):
            if abs(z - z_tip) < Z_SNAP:
                z_tip = z
    out: list[Column] = []
    cuts: list[ColumnCut] = []
    pieces: list[Column] = []  # what the cut columns keep under the tip
    removed = 0.0
    for col in columns:
        if col.z_hi <= z_tip or not boxes_overlap(col.box, region_box):
            out.append(col)
            continue
        new_region, lost = _cut_region(col.region, region, col.area, fuzzy_values)
        if new_region is None:
            out.append(col)
            continue
        z_lo = max(col.z_lo, z_tip)
        new = make_column(col.z_lo, col.z_hi, new_region, col.tier) if any(True for _ in faces(new_region)) else None
        if new is not None and new.area <= 1e-12:
            new = None
        removed += (col.area - (new.area if new else 0.0)) * (col.z_hi - z_lo)
        if new is not None:
            out.append(new)
        if z_tip > col.z_lo:
            pieces.append(make_column(col.z_lo, z_tip, lost))
        cuts.append(ColumnCut(z_lo, col.z_hi, lost))
    out.extend(pieces)
    tier = 0
    while pieces:
        level = [col for col in out if col.tier == tier and abs(col.z_hi - z_tip) < Z_SNAP]
        if len(level) <= MERGE_COLUMNS:
            break
        out = [col for col in out if not (col.tier == tier and abs(col.z_hi - z_tip) < Z_SNAP)]
        out.append(make_column(level[0].z_lo, z_tip, _union([col.region for col in level]), tier + 1))
        tier += 1
    if cuts:
        out = _merge_levels(out, z_tip)
    return tuple(out), removed, cuts


def _merge_levels(columns: list[Column], z_tip: float) -> list[Column]:
    """The columns with those of each height other than ``z_tip`` fused into one.

    A tool that cuts at another height has left those levels (or comes back to them rarely): one
    column per level means one Boolean for a cut that reaches the level, where its pieces would
    each cost one (on a mid-size Titan-like program, trochoids one level down cut ~4 pieces of the
    level above per CL).
    """
    levels: dict[float, list[Column]] = {}
    for col in columns:
        if abs(col.z_hi - z_tip) >= Z_SNAP:
            key = next((z for z in levels if abs(z - col.z_hi) < Z_SNAP), col.z_hi)
            levels.setdefault(key, []).append(col)
    merged = {id(col) for level in levels.values() if len(level) > 1 for col in level}
    if not merged:
        return columns
    out = [col for col in columns if id(col) not in merged]
    for level in levels.values():
        if len(level) > 1:
            out.append(make_column(level[0].z_lo, level[0].z_hi, _union([col.region for col in level]), WHOLE_TIER))
    return out


def _cut_region(old: TopoDS_Shape, tool: TopoDS_Shape, old_area: float, fuzzy_values: tuple[float, ...]):
    """(the new region, the region lost), or (None, None) when nothing is lost.

    As in 3D, the Common is an independent check of the Cut: old area − new area = common area.
    """
    last = "unknown"
    for fuzzy in fuzzy_values:
        pf = intersections(old, tool, fuzzy)
        if pf is None:
            last = f"2D intersection reported errors (fuzzy={fuzzy})"
            continue
        common = boolean(old, tool, pf, BOPAlgo_Operation.BOPAlgo_COMMON, history=False)
        if common.HasErrors():
            last = f"2D common failed (fuzzy={fuzzy})"
            continue
        lost = area(common.Shape())
        if lost <= 1e-12 * max(1.0, old_area):
            return None, None
        cut = boolean(old, tool, pf, BOPAlgo_Operation.BOPAlgo_CUT, history=False)
        if cut.HasErrors():
            last = f"2D cut failed (fuzzy={fuzzy})"
            continue
        new = cut.Shape()
        mismatch = old_area - area(new) - lost
        if abs(mismatch) > 1e-6 + 1e-6 * old_area:
            last = f"2D cut and common disagree by {mismatch:.4g} mm² (fuzzy={fuzzy})"
            continue
        return new, common.Shape()
    raise RegionCutFailure(last)


def contact_patches(cuts: list[ColumnCut], after: tuple[Column, ...], center: tuple[float, float], radius: float,
                    tol: float = 1e-6) -> list[TopoDS_Face]:
    """Faces on the tool's cylinder (axis through ``center``, ``radius`` mm) where the tool cut
    material that is left beside it: the circle's arcs on the lost pieces' boundaries, each from
    the tip up to the lower of the piece's column top and the top of the column just outside the
    circle after the cut (``after``). Inside the end circle every column above the tip was cut,
    so an arc with material cut on the inside and material left outside is engaged; where no
    material was inside (a wall the tool only grazes) there is no lost piece, and the arc is left
    out, as the 3D engine leaves out such faces.
    """
    ax = gp_Ax3(gp_Pnt(center[0], center[1], 0.0), gp_Dir(0.0, 0.0, 1.0), gp_Dir(1.0, 0.0, 0.0))
    patches = []
    for c in cuts:
        for e in edges(c.lost):
            if not _on_circle(e, center, radius, tol):
                continue
            a0, a1 = _arc_angles(e, center)
            z_hi = min(c.z_hi, _height_at(after, center, radius + OUTSIDE, 0.5 * (a0 + a1)))
            if z_hi > c.z_lo + Z_SNAP:
                patches.append(BRepBuilderAPI_MakeFace(gp_Cylinder(ax, radius), a0, a1, c.z_lo, z_hi).Face())
    return patches


OUTSIDE = 1e-5  # mm: how far outside the tool's circle the material left is looked up


def _height_at(columns: tuple[Column, ...], center: tuple[float, float], r: float, angle: float) -> float:
    """The top (mm) of the column holding the point at ``r`` mm and ``angle`` rad about
    ``center``; -inf where none holds it."""
    x, y = center[0] + r * math.cos(angle), center[1] + r * math.sin(angle)
    for col in columns:
        (x0, y0, _), (x1, y1, _) = col.box
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            continue
        for f in faces(col.region):
            if BRepClass_FaceClassifier(f, gp_Pnt(x, y, 0.0), 1e-9).State() == TopAbs_IN:
                return col.z_hi
    return -math.inf


def _on_circle(edge, center: tuple[float, float], radius: float, tol: float) -> bool:
    c = BRepAdaptor_Curve(edge)
    if c.GetType() != GeomAbs_Circle:
        return False
    circ = c.Circle()
    o = circ.Location()
    return abs(circ.Radius() - radius) < tol and math.hypot(o.X() - center[0], o.Y() - center[1]) < tol


def _arc_angles(edge, center: tuple[float, float]) -> tuple[float, float]:
    """The counter-clockwise angle range (rad, from +X) of a circular edge about ``center``."""
    c = BRepAdaptor_Curve(edge)
    t0, t1 = c.FirstParameter(), c.LastParameter()
    if t1 - t0 > 2 * math.pi - 1e-9:
        p = c.Value(t0)
        a = math.atan2(p.Y() - center[1], p.X() - center[0])
        return a, a + 2 * math.pi
    ang = [math.atan2(p.Y() - center[1], p.X() - center[0]) for p in (c.Value(t0), c.Value(0.5 * (t0 + t1)), c.Value(t1))]
    a0, am, a1 = ang
    span = (a1 - a0) % (2 * math.pi)
    if (am - a0) % (2 * math.pi) > span:  # the arc runs clockwise from a0: the same arc from a1
        a0, span = a1, (a0 - a1) % (2 * math.pi)
    return a0, a0 + span
