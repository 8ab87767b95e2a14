"""A cell of the in-process workpiece as a stack of 2.5D layers, cut by planar regions.

While a cell has been cut only by cylindrical tools (flat end mills whose shank has the flute's
diameter) moving horizontally or vertically, its material is a stack of prisms: between two
consecutive heights where a cut's tip stopped, the material is one planar region extruded. Such a
cut sweeps the prism of a planar region (:func:`fusioncut.engines.brep.sweep.cylinder_region`) from
the tip up past the cell's top, so it takes that region away from every layer above the tip, and
removes nothing below it. Doing that as 2D Booleans on the layers' regions gives the same material
as the 3D Boolean of the cell and the prism, at a fraction of the cost (measured on the Titan-like
benchmark's adaptive cells, 40-edge regions: a 2D Cut 0.3–2 ms against 3–16 ms for the 3D Cut of the
same cell).

Conventions: regions are compounds of planar faces in the plane z = 0 (mm); a layer covers
``z_lo <= z <= z_hi`` (mm, machine frame). Layers are ordered bottom up and never overlap.

Every cut reaches above the stack's top (the engine falls back to 3D otherwise), so the regions are
**nested**: a layer's region holds every region above it (a cut taking material from a layer takes
it from every layer above too). Two neighbouring layers of equal area are then the same region, and
are joined; a layer that loses nothing to a cut means the layers above lose nothing either.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from OCP.BOPAlgo import BOPAlgo_Builder
from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Surface
from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy, BRepBuilderAPI_Transform
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepPrimAPI import BRepPrimAPI_MakePrism
from OCP.GeomAbs import GeomAbs_Circle, GeomAbs_Cylinder, GeomAbs_Plane
from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
from OCP.gp import gp_Trsf, gp_Vec
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_REVERSED
from OCP.TopExp import TopExp
from OCP.TopoDS import TopoDS, TopoDS_Face, TopoDS_Shape
from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeMap

from fusioncut.engines.brep.occ import (
    area, bounding_box, boxes_overlap, compound, edges, faces, fuse_all, intersections, on_old_boundary,
    pieces, split_pieces, unify, volume,
)

Box = tuple[tuple[float, float, float], tuple[float, float, float]]
Z_SNAP = 1e-7  # mm: a tip this close to a layer's boundary stops on it (no layer thinner than this)


class RegionCutFailure(Exception):
    pass


@dataclass(frozen=True)
class Layer:
    """Material between ``z_lo`` and ``z_hi`` (mm): ``region`` (planar faces at z = 0) extruded."""

    z_lo: float
    z_hi: float
    region: TopoDS_Shape
    area: float  # mm²
    box: Box  # the region's bounding box (z = 0)

    @property
    def volume(self) -> float:
        return self.area * (self.z_hi - self.z_lo)


def make_layer(z_lo: float, z_hi: float, region: TopoDS_Shape, region_area: float | None = None) -> Layer:
    return Layer(z_lo, z_hi, region, area(region) if region_area is None else region_area, bounding_box(region))


def _moved(shape: TopoDS_Shape, dz: float) -> TopoDS_Shape:
    t = gp_Trsf()
    t.SetTranslation(gp_Vec(0.0, 0.0, dz))
    return BRepBuilderAPI_Transform(shape, t, True).Shape()


def solid_layers(solid: TopoDS_Shape, max_layers: int) -> tuple[Layer, ...] | None:
    """``solid`` as a stack of at most ``max_layers`` layers when it is 2.5D and nested, else None.

    That is: every face is vertical (a plane or a cylinder about a vertical axis) or horizontal,
    and the only face looking down is the bottom; so every point of the footprint has one top, the
    up-looking faces tile the footprint, and the layer below height z holds the up faces at z and
    above. A box stock's cell is one layer; a cell cut by flat end mills only, taken back from the
    solid form (after a helical entry's floor steps were cut away), a few. The layers' volume must
    be the solid's (1e-9 relative).
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
            if len(up) > max_layers:
                return None
    heights = sorted(up)
    if not heights or heights[0] - z0 < Z_SNAP:
        return None
    layers = []
    for j, z_hi in enumerate(heights):
        tops = [_moved(f, -z) for z in heights[j:] for f in up[z]]
        region = tops[0] if len(tops) == 1 else _union(tops)
        layers.append(make_layer(heights[j - 1] if j else z0, z_hi, region))
    layers = _joined(layers)
    if abs(stack_volume(layers) - volume(solid)) > 1e-9 * stack_volume(layers):
        return None
    return layers


def _union(regions: list[TopoDS_Shape]) -> TopoDS_Shape:
    """One region from planar faces that tile it (z = 0): fused, and same-plane faces merged when
    the merge keeps the area (1e-9 relative)."""
    fused = fuse_all(regions)
    u = ShapeUpgrade_UnifySameDomain(BRepBuilderAPI_Copy(fused).Shape(), True, True, False)
    u.Build()
    merged = u.Shape()
    a = area(fused)
    return merged if abs(area(merged) - a) <= 1e-9 * a and BRepCheck_Analyzer(merged).IsValid() else fused


def stack_box(layers: tuple[Layer, ...]) -> Box:
    """The stack's box, widened by the edges' tolerance in z as in x and y (the regions' boxes at
    z = 0 span ± that much), like the box of the same material as a solid: the material's height
    bounds start from the cells' box tops, and a run resumed from a checkpoint, whose cells may be
    in the other form, must start them at the same height."""
    return ((min(la.box[0][0] for la in layers), min(la.box[0][1] for la in layers), layers[0].z_lo + layers[0].box[0][2]),
            (max(la.box[1][0] for la in layers), max(la.box[1][1] for la in layers), layers[-1].z_hi + layers[-1].box[1][2]))


def stack_volume(layers: tuple[Layer, ...]) -> float:
    return sum(la.volume for la in layers)


def stack_solid(layers: tuple[Layer, ...]) -> TopoDS_Shape:
    """The stack as one B-Rep solid (prisms of the layers glued, same-surface faces merged)."""
    prisms = [BRepPrimAPI_MakePrism(_moved(la.region, la.z_lo), gp_Vec(0.0, 0.0, la.z_hi - la.z_lo)).Shape()
              for la in layers]
    if len(prisms) == 1:
        return prisms[0]
    return unify(fuse_all(prisms), stack_volume(layers))


@dataclass(frozen=True)
class CuttingRegion:
    """What a cylindrical tool's move takes from a stack: the planar region it covers (faces at
    z = 0), the tool's radius, and the heights of its tip and of its top (mm). ``key`` names the
    region exactly (equal keys: the very same region), so a stack can remember what it lost."""

    face: TopoDS_Face
    radius: float
    z_tip: float
    z_top: float
    key: tuple = ()


@dataclass(frozen=True)
class LayerCut:
    """One layer cut by a region: the layer after the cut (None when all of it went) and the split
    of its region by the cutting region, with its history (for the contact edges)."""

    z_lo: float
    z_hi: float
    new: Layer | None
    op: BOPAlgo_Builder


def cut_stack(layers: tuple[Layer, ...], region: TopoDS_Shape, z_tip: float, z_top: float,
              fuzzy_values: tuple[float, ...], clear_from: float | None = None,
              ) -> tuple[tuple[Layer, ...], float, list[LayerCut]]:
    """The stack after removing the prism of ``region`` (z = 0) from ``z_tip`` to ``z_top`` (mm).

    Returns (new layers, removed volume in mm³, the cuts of the layers that lost material).
    ``z_top`` must reach the stack's top (the regions stay nested). ``clear_from``: a height (mm)
    above which this very region was already taken from the stack (material only ever goes, so
    layers from there up lose nothing and are not cut). Raises :class:`RegionCutFailure` when a
    2D Boolean fails with every fuzzy value.
    """
    if z_top < layers[-1].z_hi - Z_SNAP:
        raise ValueError("a layered cut must reach above the stack")
    region_box = bounding_box(region)
    # snap the tip to a boundary it nearly touches: a Z_SNAP-thin layer is noise, not material
    for la in layers:
        for z in (la.z_lo, la.z_hi):
            if abs(z - z_tip) < Z_SNAP:
                z_tip = z
    out: list[Layer] = []
    cuts: list[LayerCut] = []
    removed = 0.0
    untouched_above = False
    for la in layers:
        if (la.z_hi <= z_tip or untouched_above or not boxes_overlap(la.box, region_box)
                or (clear_from is not None and la.z_lo >= clear_from)):
            out.append(la)
            continue
        new_region, new_area, op = _cut_region(la.region, region, la.area, fuzzy_values)
        if new_region is None:
            untouched_above = True  # nested regions: nothing lost here, nothing lost above
            out.append(la)
            continue
        if la.z_lo < z_tip:
            out.append(Layer(la.z_lo, z_tip, la.region, la.area, la.box))
        z_lo = max(la.z_lo, z_tip)
        new = make_layer(z_lo, la.z_hi, new_region, new_area) if any(True for _ in faces(new_region)) else None
        if new is not None and new.area <= 1e-12:
            new = None
        removed += (la.area - (new.area if new else 0.0)) * (la.z_hi - z_lo)
        if new is not None:
            out.append(new)
        cuts.append(LayerCut(z_lo, la.z_hi, new, op))
    return _joined(out), removed, cuts


def _joined(layers: list[Layer]) -> tuple[Layer, ...]:
    """Neighbours of equal area joined (nested regions of equal area are the same region)."""
    out: list[Layer] = []
    for la in layers:
        if out and abs(out[-1].z_hi - la.z_lo) < Z_SNAP and abs(out[-1].area - la.area) <= 1e-9 * max(1.0, la.area):
            below = out.pop()
            la = Layer(below.z_lo, la.z_hi, la.region, la.area, la.box)
        out.append(la)
    return tuple(out)


def _cut_region(old: TopoDS_Shape, tool: TopoDS_Shape, old_area: float, fuzzy_values: tuple[float, ...]):
    """(the new region, its area in mm², the split with its history), or Nones when nothing is lost.

    One General Fuse (:func:`~fusioncut.engines.brep.occ.split_pieces`) gives the pieces of ``old``
    the tool takes and those it leaves; they must tile ``old`` (lost + new area = old area, 1e-6 mm²
    + 1e-6 relative), or the split is retried with the next fuzzy value.
    """
    last = "unknown"
    for fuzzy in fuzzy_values:
        pf = intersections(old, tool, fuzzy)
        split = None if pf is None else split_pieces(old, tool, pf, TopAbs_FACE)
        if split is None:
            last = f"2D intersection or split reported errors (fuzzy={fuzzy})"
            continue
        op, lost_pieces, kept_pieces = split
        lost = area(compound(lost_pieces)) if lost_pieces else 0.0
        new = compound(kept_pieces)
        new_area = area(new) if kept_pieces else 0.0
        # checked when nothing is lost too: a split that loses nothing may still rebuild the region
        # wrong (seen in 3D, see BRepEngine._subtract)
        mismatch = old_area - new_area - lost
        if abs(mismatch) > 1e-6 + 1e-6 * old_area:
            last = f"2D pieces and region disagree by {mismatch:.4g} mm² (fuzzy={fuzzy})"
            continue
        if lost <= 1e-12 * max(1.0, old_area):
            return None, None, None
        return new, new_area, op
    raise RegionCutFailure(last)


def contact_patches(cuts: list[LayerCut], region: TopoDS_Shape, center: tuple[float, float], radius: float,
                    tol: float = 1e-6) -> list[tuple[float, float, float, float]]:
    """The engaged arcs on the tool's cylinder (axis through ``center``, ``radius`` mm): where the
    cut layers' new boundaries come from the cutting region's edges on that circle, each over its
    layer's height, as (start, span, z_lo, z_hi): the machine arc in rad (counter-clockwise from
    +X) and the heights in mm. An edge that also comes from the layer's old boundary is a wall the
    tool only grazes (no chip), and is left out, as the 3D engine leaves out such faces.
    """
    own = ShapeMap()
    TopExp.MapShapes_s(region, TopAbs_EDGE, own)
    on_circle = [e for e in edges(region) if _on_circle(e, center, radius, tol)]
    patches = []
    for c in cuts:
        if c.new is None:
            continue
        kept = ShapeMap()
        TopExp.MapShapes_s(c.new.region, TopAbs_EDGE, kept)
        origins = c.op.Origins()
        for e in on_circle:
            for g in map(TopoDS.Edge, pieces(c.op, e)):
                if not kept.Contains(g):
                    continue
                if on_old_boundary(g, origins, own):
                    continue
                a0, a1 = _arc_angles(g, center)
                patches.append((a0, a1 - a0, c.z_lo, c.z_hi))
    return patches


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
