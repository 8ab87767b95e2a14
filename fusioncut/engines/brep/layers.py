"""A cell of the in-process workpiece as a stack of 2.5D layers, cut by planar regions.

While a cell has been cut only by cylindrical tools (flat end mills whose shank has the flute's
diameter) moving horizontally or vertically, its material is a stack of prisms: between two
consecutive heights where a cut's tip stopped, the material is one planar region extruded. Such a
cut sweeps the prism of a planar region (:func:`fusioncut.engines.brep.sweep.cylinder_region`) from
the tip up past the cell's top, so it takes that region away from every layer above the tip, and
removes nothing below it. Doing that as 2D Booleans on the layers' regions gives the same material
as the 3D Boolean of the cell and the prism, at a fraction of the cost (an order of magnitude on
adaptive cells: ``docs/decisions/engine-measurements.md``). Regions of lines and arcs, which are all a
flat end mill leaves, are cut in closed form (:mod:`fusioncut.engines.brep.planar`, again about ten
times cheaper than OCCT's General Fuse); a cut it cannot decide, and a region with other curves, goes
to the General Fuse.

Conventions: regions are compounds of planar faces in the plane z = 0 (mm); a layer covers
``z_lo <= z <= z_hi`` (mm, machine frame). Layers are ordered bottom up and never overlap.

Every cut reaches above the stack's top (the engine falls back to 3D otherwise), so the regions are
**nested**: a layer's region holds every region above it (a cut taking material from a layer takes
it from every layer above too). Two neighbouring layers of equal area are then the same region, and
are joined; a layer that loses nothing to a cut means the layers above lose nothing either.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import NamedTuple

from OCP.BOPAlgo import BOPAlgo_Builder
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Surface
from OCP.BRepBuilderAPI import (
    BRepBuilderAPI_Copy, BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakeVertex,
    BRepBuilderAPI_MakeWire, BRepBuilderAPI_Transform,
)
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepPrimAPI import BRepPrimAPI_MakePrism
from OCP.BRepTools import BRepTools_WireExplorer
from OCP.GeomAbs import GeomAbs_Circle, GeomAbs_Cylinder, GeomAbs_Line, GeomAbs_Plane
from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
from OCP.gp import gp_Ax2, gp_Circ, gp_Dir, gp_Lin, gp_Pln, gp_Pnt, gp_Trsf, gp_Vec
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_REVERSED, TopAbs_WIRE
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopoDS import TopoDS, TopoDS_Face, TopoDS_Shape
from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeMap

from fusioncut.engines.brep import planar
from fusioncut.engines.brep.occ import (
    area, bounding_box, boxes_overlap, compound, edges, faces, fuse_all, intersections, on_old_boundary,
    pieces, split_pieces, unify, volume,
)
from fusioncut.engines.ceiling import Box
from fusioncut.errors import KernelFailure, RegionCutFailure

log = logging.getLogger(__name__)
Z_SNAP = 1e-7  # mm: a tip this close to a layer's boundary stops on it (no layer thinner than this)
EDGE_TOLERANCE = 1e-7  # mm: OCCT's tolerance of a new edge (Precision::Confusion)


class Layer:
    """Material between ``z_lo`` and ``z_hi`` (mm): a planar region at z = 0 extruded, its ``area``
    (mm²) and bounding ``box`` (z = 0, widened by the edges' tolerance). The region is held as
    B-Rep faces (``region``), as a closed-form outline of lines and arcs (``outline``, see
    :mod:`fusioncut.engines.brep.planar`), or both: each is made from the other when first asked
    for (``outline`` is None for a region with other curves)."""

    __slots__ = ("z_lo", "z_hi", "area", "box", "_shared")

    def __init__(self, z_lo: float, z_hi: float, area: float, box: Box, shared: list) -> None:
        self.z_lo, self.z_hi, self.area, self.box = z_lo, z_hi, area, box
        self._shared = shared  # [faces or None, outline or None or False (none)]: shared by the layers of one region

    @property
    def region(self) -> TopoDS_Shape:
        if self._shared[0] is None:
            self._shared[0] = outline_faces(self._shared[1])
        return self._shared[0]

    @property
    def outline(self) -> planar.Region | None:
        if self._shared[1] is None:
            self._shared[1] = outline(self._shared[0]) or False
        return self._shared[1] or None

    def between(self, z_lo: float, z_hi: float) -> Layer:
        """The same region between other heights (mm)."""
        return Layer(z_lo, z_hi, self.area, self.box, self._shared)

    @property
    def volume(self) -> float:
        return self.area * (self.z_hi - self.z_lo)

    def state(self) -> list:
        """What :func:`layer_from_state` needs besides the region's faces, as JSON values (floats
        round-trip exactly): a resumed run must cut the very same numbers."""
        known = self._shared[1]
        loops = [[[type(e).__name__, *e] for e in loop] for loop in known] if known else known
        return [self.z_lo, self.z_hi, self.area, [*self.box[0], *self.box[1]], loops]


def layer_from_state(region: TopoDS_Shape, state: list) -> Layer:
    """The layer :meth:`Layer.state` saved, its region's faces read back (heights alone, as older
    checkpoints saved them: measured again from the faces)."""
    if len(state) == 2:
        return make_layer(state[0], state[1], region)
    z_lo, z_hi, region_area, box, loops = state
    kinds = {"Line": planar.Line, "Arc": planar.Arc}
    known = tuple(tuple(kinds[k](*v) for k, *v in loop) for loop in loops) if loops else loops
    return Layer(z_lo, z_hi, region_area, (tuple(box[:3]), tuple(box[3:])), [region, known])


def make_layer(z_lo: float, z_hi: float, region: TopoDS_Shape, region_area: float | None = None) -> Layer:
    return Layer(z_lo, z_hi, area(region) if region_area is None else region_area, bounding_box(region), [region, None])


def outline_layer(z_lo: float, z_hi: float, region: planar.Region, region_area: float) -> Layer:
    """A layer whose region is an outline."""
    return Layer(z_lo, z_hi, region_area, _outline_box(region), [None, region])


def _outline_box(region: planar.Region) -> Box:
    """The outline's box (z = 0), widened by the tolerance (1e-7 mm) the kernel gives the edges of
    its faces, as those faces' box would be."""
    x0, y0, x1, y1 = planar.region_box(region)
    t = EDGE_TOLERANCE
    return (x0 - t, y0 - t, -t), (x1 + t, y1 + t, t)


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
    """What a cylindrical tool's move takes from a stack: the planar region it covers (an outline
    at z = 0, :mod:`~fusioncut.engines.brep.planar`), the tool's radius, and the heights of its tip
    and of its top (mm). ``key`` names the region exactly (equal keys: the very same region), so a
    stack can remember what it lost."""

    outline: planar.Region
    radius: float
    z_tip: float
    z_top: float
    key: tuple = ()


@dataclass(frozen=True)
class LayerCut:
    """One layer cut by a region: the layer after the cut (None when all of it went), and how the
    cutting region's boundary came into the new one: the kernel's split with its history, or, cut
    in closed form, the pieces of the cutting region's edges on the new boundary (``kept``).
    ``lost``: the area (mm²) the layer lost between ``z_lo`` and ``z_hi`` (mm, machine frame), so
    the removed volume is ``lost * (z_hi - z_lo)`` and can be told per height."""

    z_lo: float
    z_hi: float
    new: Layer | None
    op: BOPAlgo_Builder | None = None
    tool: TopoDS_Shape | None = None  # the cutting region's faces the split was made with
    kept: tuple[planar.Edge, ...] = ()
    lost: float = 0.0


class StackCut(NamedTuple):
    """A stack after a cut: its ``layers``, the volume ``removed`` (mm³) and the ``cuts`` of the
    layers that lost material (empty: the stack lost nothing)."""

    layers: tuple[Layer, ...]
    removed: float
    cuts: list[LayerCut]


def cut_stack(layers: tuple[Layer, ...], region: TopoDS_Shape | planar.Region, z_tip: float, z_top: float,
              fuzzy_values: tuple[float, ...], clear_from: float | None = None,
              ) -> StackCut:
    """The stack after removing the prism of ``region`` (faces or an outline at z = 0) from
    ``z_tip`` to ``z_top`` (mm).

    Returns the new layers, the removed volume (mm³) and the cuts of the layers that lost material.
    ``z_top`` must reach the stack's top (the regions stay nested). ``clear_from``: a height (mm)
    above which this very region was already taken from the stack (material only ever goes, so
    layers from there up lose nothing and are not cut). Each layer whose region is lines and arcs,
    as the cutting region's, is cut in closed form (:func:`planar.difference`); otherwise, or where
    that cannot decide, by the kernel's General Fuse. Raises :class:`RegionCutFailure` when a 2D
    Boolean fails with every fuzzy value.
    """
    if z_top < layers[-1].z_hi - Z_SNAP:
        raise ValueError("a layered cut must reach above the stack")
    if isinstance(region, tuple):
        region_outline, face, region_box = region, None, _outline_box(region)
    else:
        region_outline, face = outline(region), region
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
        z_lo = max(la.z_lo, z_tip)
        closed = _closed_form_cut(la, region_outline) if region_outline else None
        if closed is not None:
            new_outline, new_area, kept = closed
            op = None
            new = outline_layer(z_lo, la.z_hi, new_outline, new_area) if new_outline else None
        else:
            if face is None:
                face = outline_faces(region_outline)
            new_region, new_area, op = _cut_region(la.region, face, la.area, fuzzy_values)
            kept = ()
            new = None
            if new_region is not None and any(True for _ in faces(new_region)):
                new = make_layer(z_lo, la.z_hi, new_region, new_area)
        if new_area is None:
            untouched_above = True  # nested regions: nothing lost here, nothing lost above
            out.append(la)
            continue
        if la.z_lo < z_tip:
            out.append(la.between(la.z_lo, z_tip))
        if new is not None and new.area <= 1e-12:
            new = None
        lost = la.area - (new.area if new else 0.0)
        removed += lost * (la.z_hi - z_lo)
        if new is not None:
            out.append(new)
        cuts.append(LayerCut(z_lo, la.z_hi, new, op, face if op is not None else None, kept, lost))
    return StackCut(_joined(out), removed, cuts)


def _joined(layers: list[Layer]) -> tuple[Layer, ...]:
    """Neighbours of equal area joined (nested regions of equal area are the same region)."""
    out: list[Layer] = []
    for la in layers:
        if out and abs(out[-1].z_hi - la.z_lo) < Z_SNAP and abs(out[-1].area - la.area) <= 1e-9 * max(1.0, la.area):
            below = out.pop()
            la = la.between(below.z_lo, la.z_hi)
        out.append(la)
    return tuple(out)


def _closed_form_cut(layer: Layer, tool: planar.Region):
    """(new outline, its area in mm², the tool's edge pieces on it) of ``layer`` minus ``tool`` in
    closed form; (None, None, ()) when nothing is lost; None when the layer's region is not lines
    and arcs, or the configuration is too nearly degenerate to decide here (the General Fuse then).

    The outline's area and the area lost must tile the layer's (1e-6 mm² + 1e-6 relative: its area
    may come from the kernel's integration), and the loss cannot exceed the tool's region.
    """
    old = layer.outline
    if old is None:
        return None
    try:
        d = planar.difference(old, tool)
    except planar.Degenerate as exc:
        log.debug("layer cut by the General Fuse: %s", exc)
        return None
    if (d.area < -1e-9 or d.lost < -1e-9 or d.lost > planar.region_area(tool) + 1e-9
            or abs(layer.area - d.area - d.lost) > 1e-6 + 1e-6 * layer.area):
        log.debug("layer cut by the General Fuse: closed-form areas %.12g + %.12g for %.12g", d.area, d.lost, layer.area)
        return None
    if d.lost <= 1e-12 * max(1.0, layer.area):
        return None, None, ()
    return d.region, d.area, d.b_pieces


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


def contact_patches(cuts: list[LayerCut], center: tuple[float, float], radius: float,
                    tol: float = 1e-6) -> list[tuple[float, float, float, float]]:
    """The engaged arcs on the tool's cylinder (axis through ``center``, ``radius`` mm): where the
    cut layers' new boundaries come from the cutting region's edges on that circle, each over its
    layer's height, as (start, span, z_lo, z_hi): the machine arc in rad (counter-clockwise from
    +X, the start in (-π, π]) and the heights in mm. An edge that also comes from the layer's old
    boundary is a wall the tool only grazes (no chip), and is left out, as the 3D engine leaves out
    such faces.
    """
    patches = []
    for c in cuts:
        if c.new is None:
            continue
        if c.op is None:
            for e in c.kept:
                if type(e) is planar.Arc and abs(e.r - radius) < tol and math.hypot(e.cx - center[0], e.cy - center[1]) < tol:
                    x, y = (e.x0, e.y0) if e.a1 > e.a0 else (e.x1, e.y1)
                    patches.append((math.atan2(y - e.cy, x - e.cx), abs(e.a1 - e.a0), c.z_lo, c.z_hi))
            continue
        own = ShapeMap()
        TopExp.MapShapes_s(c.tool, TopAbs_EDGE, own)
        on_circle = [e for e in edges(c.tool) if _on_circle(e, center, radius, tol)]
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


# -- regions as closed-form outlines (fusioncut.engines.brep.planar) and back ----------------

def outline(region: TopoDS_Shape) -> planar.Region | None:
    """The region's loops as lines and arcs (region on their left), or None when an edge is
    another curve or a face does not lie in a horizontal plane."""
    loops = []
    for f in faces(region):
        s = BRepAdaptor_Surface(f, False)
        if s.GetType() != GeomAbs_Plane or abs(abs(s.Plane().Axis().Direction().Z()) - 1.0) > 1e-12:
            return None
        face_loops = []
        wires = TopExp_Explorer(f, TopAbs_WIRE)
        while wires.More():
            loop = []
            it = BRepTools_WireExplorer(TopoDS.Wire(wires.Current()), f)
            while it.More():
                e = it.Current()
                c = BRepAdaptor_Curve(e)
                p0, p1 = BRep_Tool.Pnt_s(TopExp.FirstVertex_s(e, True)), BRep_Tool.Pnt_s(TopExp.LastVertex_s(e, True))
                t = c.GetType()
                if t == GeomAbs_Line:
                    loop.append(planar.Line(p0.X(), p0.Y(), p1.X(), p1.Y()))
                elif t == GeomAbs_Circle:
                    circ = c.Circle()
                    o = circ.Location()
                    ccw = (circ.Axis().Direction().Z() > 0) == (e.Orientation() != TopAbs_REVERSED)
                    span = c.LastParameter() - c.FirstParameter()
                    a0 = math.atan2(p0.Y() - o.Y(), p0.X() - o.X())
                    loop.append(planar.Arc(p0.X(), p0.Y(), p1.X(), p1.Y(), o.X(), o.Y(), circ.Radius(),
                                           a0, a0 + span if ccw else a0 - span))
                else:
                    return None
                it.Next()
            face_loops.append(tuple(loop))
            wires.Next()
        if planar.region_area(face_loops) < 0:
            face_loops = [planar.reversed_loop(loop) for loop in face_loops]
        loops.extend(face_loops)
    return tuple(loops)


def outline_faces(region: planar.Region) -> TopoDS_Shape:
    """The planar faces (z = 0) of an outline: each counter-clockwise loop a face, with the
    clockwise loops inside it (the smallest that holds them) as its holes."""
    outers = [loop for loop in region if planar.region_area((loop,)) > 0]
    holes: dict[int, list] = {k: [] for k in range(len(outers))}
    for loop in region:
        if planar.region_area((loop,)) > 0:
            continue
        x, y = planar.edge_point(loop[0])
        owners = [k for k, o in enumerate(outers) if planar.winding(list(o), x, y) > 0]
        if not owners:
            raise KernelFailure("a hole of the region lies in none of its outer loops")
        holes[min(owners, key=lambda k: planar.region_area((outers[k],)))].append(loop)
    vertices: dict[tuple[float, float], object] = {}

    def vertex(x: float, y: float):
        v = vertices.get((x, y))
        if v is None:
            v = vertices[(x, y)] = BRepBuilderAPI_MakeVertex(gp_Pnt(x, y, 0.0)).Vertex()
        return v

    def wire(loop):
        mk = BRepBuilderAPI_MakeWire()
        for e in loop:
            v0, v1 = vertex(e.x0, e.y0), vertex(e.x1, e.y1)
            if type(e) is planar.Line:
                edge = BRepBuilderAPI_MakeEdge(gp_Lin(gp_Pnt(e.x0, e.y0, 0.0), gp_Dir(e.x1 - e.x0, e.y1 - e.y0, 0.0)), v0, v1).Edge()
            else:  # the circle's axis up for a counter-clockwise arc, down for a clockwise one
                axis = gp_Dir(0.0, 0.0, 1.0 if e.a1 > e.a0 else -1.0)
                edge = BRepBuilderAPI_MakeEdge(gp_Circ(gp_Ax2(gp_Pnt(e.cx, e.cy, 0.0), axis), e.r), v0, v1).Edge()
            mk.Add(edge)
        if not mk.IsDone():
            raise KernelFailure("the region's loop does not close")
        return mk.Wire()

    out = []
    for k, o in enumerate(outers):
        mk = BRepBuilderAPI_MakeFace(gp_Pln(gp_Pnt(0.0, 0.0, 0.0), gp_Dir(0.0, 0.0, 1.0)), wire(o), True)
        for h in holes[k]:
            mk.Add(wire(h))
        out.append(mk.Face())
    return out[0] if len(out) == 1 else compound(out)
