"""Thin helpers over OCP (OpenCASCADE) used by the B-Rep engine. Only ``engines/brep`` imports OCP."""
from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Iterator
from itertools import islice

from OCP.BRepClass3d import BRepClass3d_SolidClassifier
from OCP.BOPAlgo import BOPAlgo_Builder, BOPAlgo_PaveFiller
from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepAlgoAPI import BRepAlgoAPI_Common, BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepBuilderAPI import (
    BRepBuilderAPI_Copy, BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakeWire,
    BRepBuilderAPI_Transform,
)
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.BRepTools import BRepTools
from OCP.GC import GC_MakeArcOfCircle
from OCP.GProp import GProp_GProps
from OCP.gp import gp_Ax1, gp_Dir, gp_Pnt, gp_Trsf, gp_Vec
from OCP.ShapeAnalysis import ShapeAnalysis_ShapeTolerance
from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_IN, TopAbs_SOLID, TopAbs_ShapeEnum
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Compound, TopoDS_Edge, TopoDS_Face, TopoDS_Shape
from OCP.collections import IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as AncestorMap
from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeMap
from OCP.collections import List_TopoDS_Shape

from fusioncut.engines.brep.budget import current_deadline, guarded, in_child, shape_bytes, shape_from_bytes
from fusioncut.errors import KernelFailure

Vec3 = tuple[float, float, float]
log = logging.getLogger("fusioncut.engine")


def pnt(p: Vec3) -> gp_Pnt:
    return gp_Pnt(float(p[0]), float(p[1]), float(p[2]))


def volume(shape: TopoDS_Shape) -> float:
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    return props.Mass()


def items(shapes) -> list[TopoDS_Shape]:
    """The shapes of an OCP list (a Boolean's ``Modified``, a history's ``Find``).

    Not ``list(shapes)``: pybind11 ends an iteration by throwing a C++ exception, and unwinding it in
    OCP's large library costs more than the rest of a contact face lookup; taking exactly ``Size()``
    items never asks for the end.
    """
    return list(islice(shapes, shapes.Size()))


def face_map(shape: TopoDS_Shape) -> ShapeMap:
    """The faces of ``shape`` as a map for ``Contains`` (same face and location, any orientation)."""
    m = ShapeMap()
    TopExp.MapShapes_s(shape, TopAbs_FACE, m)
    return m


def volume_change(old: TopoDS_Shape, new: TopoDS_Shape) -> float:
    """volume(new) - volume(old) (mm³) from the faces that differ between the two shapes only.

    The divergence theorem makes a solid's volume a sum over its faces (GProp integrates each face
    against one fixed point), so faces a Boolean left untouched cancel. A Cut reuses the faces it
    did not split, so this integrates a few faces instead of a many-faced workpiece.
    """
    maps = [face_map(old), face_map(new)]

    # the faces only the new shape has, and those only the old one had, reversed: together a closed
    # surface, so its GProp integral does not depend on GProp's own reference point
    picked = [f for f in faces(new) if not maps[0].Contains(f)]
    picked += [f.Reversed() for f in faces(old) if not maps[1].Contains(f)]
    return _enclosed_volume(picked)


def _enclosed_volume(closed: list[TopoDS_Face]) -> float:
    """GProp's volume integral over faces that together bound closed regions (mm³; 0 if none)."""
    if not closed:
        return 0.0
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(compound(closed), props, False)
    return props.Mass()


def area(shape: TopoDS_Shape) -> float:
    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(shape, props)
    return props.Mass()


def _explore(shape: TopoDS_Shape, kind: TopAbs_ShapeEnum) -> Iterator[TopoDS_Shape]:
    exp = TopExp_Explorer(shape, kind)
    while exp.More():
        yield exp.Current()
        exp.Next()


def faces(shape: TopoDS_Shape) -> Iterator[TopoDS_Face]:
    return map(TopoDS.Face, _explore(shape, TopAbs_FACE))


def edges(shape: TopoDS_Shape) -> Iterator[TopoDS_Edge]:
    return map(TopoDS.Edge, _explore(shape, TopAbs_EDGE))


def count_faces(shape: TopoDS_Shape) -> int:
    return sum(1 for _ in faces(shape))


def solids(shape: TopoDS_Shape) -> list[TopoDS_Shape]:
    return list(_explore(shape, TopAbs_SOLID))


def without_slivers(old: TopoDS_Shape, new: TopoDS_Shape, max_faces: int = 64,
                    max_volume: float = 1e-6) -> TopoDS_Shape:
    """``new`` without the empty solids a Boolean may leave beside the real result.

    Near the floors a helical entry leaves (steps 0.01 mm apart), OCCT's Cut returned, besides the
    right workpiece, a 5-face "solid" of zero volume whose shell is not connected. Its volume is
    right, so the removed-against-change check passes, but later Booleans on that workpiece went wrong by
    thousands of mm³. Only solids that appeared in this Boolean and have at most ``max_faces``
    faces are measured (cheap); one enclosing at most ``max_volume`` mm³ is dropped.
    """
    after = solids(new)
    if len(after) <= len(solids(old)):
        return new
    keep = [s for s in after if count_faces(s) > max_faces or abs(volume(s)) > max_volume]
    if len(keep) == len(after):
        return new
    return keep[0] if len(keep) == 1 else compound(keep)  # an empty compound: nothing left


def bounding_box(shape: TopoDS_Shape, exact: bool = False) -> tuple[Vec3, Vec3]:
    """Axis-aligned box (mm); widened by the shapes' tolerances unless ``exact`` (slower)."""
    box = Bnd_Box()
    if exact:
        BRepBndLib.AddOptimal_s(shape, box, False, False)
    else:
        BRepBndLib.Add_s(shape, box, False)
    lo, hi = box.CornerMin(), box.CornerMax()
    return (lo.X(), lo.Y(), lo.Z()), (hi.X(), hi.Y(), hi.Z())


def boxes_overlap(a: tuple[Vec3, Vec3], b: tuple[Vec3, Vec3], gap: float = 1e-7) -> bool:
    # written out: every CL tests it against every cell, and a generator over the axes cost 3x more
    (a0, a1), (b0, b1) = a, b
    return (a0[0] <= b1[0] + gap and b0[0] <= a1[0] + gap and a0[1] <= b1[1] + gap and b0[1] <= a1[1] + gap
            and a0[2] <= b1[2] + gap and b0[2] <= a1[2] + gap)


def wire_from_points(segments: Iterable[tuple[str, tuple[Vec3, ...]]]):
    """Closed wire from ``("line", (p0, p1))`` and ``("arc", (p0, pmid, p1))`` pieces."""
    mk = BRepBuilderAPI_MakeWire()
    for kind, pts in segments:
        if kind == "line":
            edge = BRepBuilderAPI_MakeEdge(pnt(pts[0]), pnt(pts[1])).Edge()
        else:
            arc = GC_MakeArcOfCircle(pnt(pts[0]), pnt(pts[1]), pnt(pts[2])).Value()
            edge = BRepBuilderAPI_MakeEdge(arc).Edge()
        mk.Add(edge)
    if not mk.IsDone():
        raise KernelFailure("could not close the profile wire")
    return mk.Wire()


def planar_face(wire) -> TopoDS_Face:
    mk = BRepBuilderAPI_MakeFace(wire, True)
    if not mk.IsDone():
        raise KernelFailure("could not make a planar face from the profile")
    return mk.Face()


def placement(position: Vec3, angle_rad: float) -> TopLoc_Location:
    """Rotation about +Z by ``angle_rad`` then translation to ``position``."""
    rot = gp_Trsf()
    rot.SetRotation(gp_Ax1(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), angle_rad)
    tr = gp_Trsf()
    tr.SetTranslation(gp_Vec(*map(float, position)))
    return TopLoc_Location(tr.Multiplied(rot))


def moved_copy(shape: TopoDS_Shape, location: TopLoc_Location) -> TopoDS_Shape:
    """A copy of ``shape`` with sub-shapes and geometry of its own, moved to ``location``: a Boolean
    may raise the tolerances of its arguments' sub-shapes in place, so shapes that go into Booleans
    are not shared between CLs (a shared tool solid once made the same sampled sweep come out empty
    twice, then right)."""
    return BRepBuilderAPI_Transform(shape, location.Transformation(), True).Shape()


def shape_list(shapes: Iterable[TopoDS_Shape]) -> List_TopoDS_Shape:
    lst = List_TopoDS_Shape()
    for s in shapes:
        lst.Append(s)
    return lst


def intersections(a: TopoDS_Shape, b: TopoDS_Shape, fuzzy: float, parallel: bool = False):
    """The intersections of ``a`` and ``b`` (a ``BOPAlgo_PaveFiller``) for :func:`split_pieces`, or
    None when the kernel reports errors."""
    pf = BOPAlgo_PaveFiller()
    pf.SetArguments(shape_list([a, b]))
    pf.SetRunParallel(parallel)
    if fuzzy:
        pf.SetFuzzyValue(fuzzy)
    pf.Perform()
    return None if pf.HasErrors() else pf


def split_pieces(a: TopoDS_Shape, b: TopoDS_Shape, pf, kind: TopAbs_ShapeEnum, parallel: bool = False):
    """The General Fuse of ``a`` and ``b`` on the intersections ``pf``: (the split with its history,
    the pieces of ``a``'s sub-shapes of ``kind`` inside ``b``, those outside), or None on errors.

    The split shares a piece that both arguments cover (coincident faces in 2D, the overlap of two
    solids), so a piece of ``a`` inside ``b`` is one that is also a piece of ``b``: the selection a
    Common and a Cut on the same intersections make, for the cost of one split instead of two (the
    same results CL by CL).
    """
    split = BOPAlgo_Builder()
    split.AddArgument(a)
    split.AddArgument(b)
    # no argument here can be an inverted solid (workpieces come from the stock by cuts, sweeps are
    # built outward), so the kernel's check for one is skipped
    split.SetCheckInverted(False)
    split.SetRunParallel(parallel)
    split.PerformWithFiller(pf)
    if split.HasErrors():
        return None
    in_b = ShapeMap()
    for s in _explore(b, kind):
        for piece in pieces(split, s):
            in_b.Add(piece)
    inside, outside = [], []
    for s in _explore(a, kind):
        for piece in pieces(split, s):
            (inside if in_b.Contains(piece) else outside).append(piece)
    return split, inside, outside


def strictly_inside(shape: TopoDS_Shape, point: Vec3, tol: float = 1e-6) -> bool:
    """Whether ``point`` (mm) lies inside the solid ``shape``, farther than ``tol`` from its boundary."""
    return BRepClass3d_SolidClassifier(shape, pnt(point), tol).State() == TopAbs_IN


def pieces(split, shape: TopoDS_Shape) -> list[TopoDS_Shape]:
    """The pieces a General Fuse split ``shape`` into (the shape itself when it was not split: a
    split deletes nothing)."""
    images = split.Modified(shape)
    return items(images) if images.Size() else [shape]


def on_old_boundary(piece: TopoDS_Shape, origins, own: ShapeMap) -> bool:
    """Whether a piece of a split's result (a face in 3D, an edge in 2D) also comes from a shape
    that is not the cutting tool's (not in ``own``): the kernel merged it with a coincident face or
    edge of the workpiece's old boundary.

    There the tool only grazes a wall left by an earlier cut: it removes nothing, the chip is zero
    thick, so it is no engagement. Seen where a second depth level retraces the first level's
    trochoids: the tool lay on the first level's walls and, without this test, reported arcs of a
    few degrees there that force models would read as cutting.
    """
    return origins.IsBound(piece) and any(not own.Contains(s) for s in items(origins.Find(piece)))


def fuse_all(shapes: list[TopoDS_Shape], glue: bool = False, fuzzy: float = 0.0) -> TopoDS_Shape:
    """Union of solids in one Boolean; ``glue`` for arguments that only share whole faces. Inside
    :func:`~fusioncut.engines.brep.budget.within` a deadline that guards, it runs in the kernel's
    killable child (the shapes sent as binary BRep)."""
    if len(shapes) == 1:
        return shapes[0]
    deadline = current_deadline()
    if deadline is not None and deadline.guards:
        data = guarded(_fuse_bytes, ([shape_bytes(s) for s in shapes], glue, fuzzy), deadline, "a fuse of solids")
        return shape_from_bytes(data)
    op = BRepAlgoAPI_Fuse()
    op.SetArguments(shape_list(shapes[:1]))
    op.SetTools(shape_list(shapes[1:]))
    if glue:
        from OCP.BOPAlgo import BOPAlgo_GlueShift

        op.SetGlue(BOPAlgo_GlueShift)
    if fuzzy:
        op.SetFuzzyValue(fuzzy)
    op.Build()
    if not op.IsDone():
        raise KernelFailure("fuse of the sweep pieces failed")
    return unify(op.Shape())


def _fuse_bytes(shapes: list[bytes], glue: bool, fuzzy: float) -> bytes:
    """:func:`fuse_all` of shapes sent as binary BRep (the kernel's child runs this)."""
    return shape_bytes(fuse_all([shape_from_bytes(b) for b in shapes], glue, fuzzy))


# mm: a merged edge or vertex looser than this (and than 10x the shape's loosest) fails the merge
MERGE_TOLERANCE = 1e-4


def unify(shape: TopoDS_Shape, shape_volume: float | None = None, max_rounds: int = 4, gap: float = 0.0) -> TopoDS_Shape:
    """Merge faces that lie on the same surface (what keeps Booleans fast along a path).

    ``ShapeUpgrade_UnifySameDomain`` edits sub-shapes of its argument in place, and those sub-shapes
    are shared with earlier workpieces and cells; so it merges a copy. It also returns, with no
    error, workpieces with a hole where a face went missing (seen on a helical entry's stepped
    floors). So a merge is kept only if the result is valid and of
    the same volume (1e-9 relative + 1e-6 mm³; ``shape_volume``, mm³, when the caller knows it), or
    within ``gap`` (mm) times twice its area of it: the fuzzy value of the Booleans that built
    ``shape``, which may have glued faces that overlap by up to that much. Such faces are what the
    merge puts right: a ball end mill's finish leaves a cylinder patch per CL, each a few µm longer
    than its CL, which merge into one exact face per row and cell.
    When it is not, the faces that reach the hole's free edges are kept as they are and the rest is
    merged again, at most ``max_rounds`` times; if no round gives a sound shape, ``shape`` is returned
    unchanged (refusing the whole merge instead lets the face count, and with it every Boolean's
    cost, grow without bound; ``docs/decisions/engine-measurements.md``).

    A merge is also refused where it leaves an edge or vertex looser than ``MERGE_TOLERANCE`` (and
    ten times the loosest of ``shape``): after a plunge and an arc of the tool's own radius, the
    merged workpiece was valid and of the right volume but had an 8 mm tolerance edge, and every
    later Boolean near it came back empty (a 40.8 mm³ cut reported as air). The faces near such an
    edge are kept like a hole's.
    """
    n_faces = count_faces(shape)
    tolerance_limit = max(MERGE_TOLERANCE, 10.0 * max_tolerance(shape))
    kept = ShapeMap()  # faces of ``shape`` whose edges must stay
    slack = None  # mm³ the volume may move by (the gap), measured once a merge is to be judged
    for _ in range(max_rounds):
        copy = BRepBuilderAPI_Copy(shape)
        u = ShapeUpgrade_UnifySameDomain(copy.Shape(), True, True, False)
        for i in range(1, kept.Extent() + 1):
            for e in edges(kept.FindKey(i)):
                u.KeepShape(copy.Modified(e).First())
        u.Build()
        merged = u.Shape()
        if count_faces(merged) == n_faces:
            return shape
        # both shapes' faces in one pass (the copy shares none with ``shape``): the faces the merge
        # left alone cancel exactly, unlike two whole volumes (each good to ~1e-7 of the workpiece)
        change = _enclosed_volume([*faces(merged), *(f.Reversed() for f in faces(shape))])
        reference = abs(shape_volume if shape_volume is not None else volume(shape))
        if slack is None:
            slack = 2.0 * gap * area(shape) if gap > 0.0 else 0.0
        sound = abs(change) <= 1e-9 * reference + 1e-6 + slack
        # the whole shape's largest tolerance is one C++ pass; the edges are listed only past the limit
        loose = _loose_edges(merged, tolerance_limit) if max_tolerance(merged) > tolerance_limit else []
        if sound and not loose and BRepCheck_Analyzer(merged).IsValid():
            return merged
        # the faces that reach the hole's rim (the one that went missing and its neighbours) or a
        # loose edge (its exact box: its tolerance would take in faces millimetres away), by
        # bounding boxes: the merge history is slow to query from Python edge by edge
        rim = [bounding_box(e) for e in _free_edges(merged)] + [bounding_box(e, exact=True) for e in loose]
        culprits = [f for f in faces(shape) if not kept.Contains(f)
                    and any(boxes_overlap(bounding_box(f), b, 1e-6) for b in rim)]
        log.debug("face merge %d -> %d faces unsound (volume ok: %s, loose edges: %d); keeping %d faces",
                  n_faces, count_faces(merged), sound, len(loose), len(culprits))
        if not culprits:
            return shape
        for f in culprits:
            kept.Add(f)
    return shape


def max_tolerance(shape: TopoDS_Shape) -> float:
    """The largest tolerance (mm) of the vertices, edges and faces of ``shape``."""
    return ShapeAnalysis_ShapeTolerance().Tolerance(shape, 1)


def _loose_edges(shape: TopoDS_Shape, limit: float) -> list[TopoDS_Edge]:
    """The edges of ``shape`` with a tolerance, or a vertex tolerance, above ``limit`` (mm)."""
    out = []
    for e in edges(shape):
        if max(BRep_Tool.Tolerance_s(e), BRep_Tool.Tolerance_s(TopExp.FirstVertex_s(e)),
               BRep_Tool.Tolerance_s(TopExp.LastVertex_s(e))) > limit:
            out.append(e)
    return out


def _free_edges(shape: TopoDS_Shape) -> list[TopoDS_Shape]:
    """The edges of ``shape`` that bound only one face (the rim of a hole in a closed shell)."""
    ancestors = AncestorMap()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, ancestors)
    out = []
    for i in range(1, ancestors.Extent() + 1):
        edge = ancestors.FindKey(i)
        if ancestors.FindFromIndex(i).Size() == 1 and not BRep_Tool.Degenerated_s(TopoDS.Edge(edge)):
            out.append(edge)
    return out


def children(shape: TopoDS_Shape) -> list[TopoDS_Shape]:
    """The direct sub-shapes of a compound, in order."""
    from OCP.TopoDS import TopoDS_Iterator

    out = []
    it = TopoDS_Iterator(shape)
    while it.More():
        out.append(it.Value())
        it.Next()
    return out


def in_box(solid: TopoDS_Shape, lo: Vec3, hi: Vec3) -> TopoDS_Shape | None:
    """The part of ``solid`` inside the box (faces merged), None if it holds no material."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox

    op = BRepAlgoAPI_Common(solid, BRepPrimAPI_MakeBox(pnt(lo), pnt(hi)).Shape())
    if not op.IsDone():
        raise KernelFailure("splitting the workpiece into cells failed")
    piece = op.Shape()
    return unify(piece) if solids(piece) else None


def compound(shapes: Iterable[TopoDS_Shape]) -> TopoDS_Compound:
    c = TopoDS_Compound()
    b = BRep_Builder()
    b.MakeCompound(c)
    for s in shapes:
        b.Add(c, s)
    return c


def write_brep(shape: TopoDS_Shape, path: str) -> None:
    BRepTools.Write_s(shape, path)


def read_brep(path: str) -> TopoDS_Shape:
    shape = TopoDS_Shape()
    BRepTools.Read_s(shape, path, BRep_Builder())
    return shape


def write_binary_brep(shape: TopoDS_Shape, path: str) -> None:
    from OCP.BinTools import BinTools

    if not BinTools.Write_s(shape, path):
        raise OSError(f"could not write {path}")


def read_binary_brep(path: str) -> TopoDS_Shape:
    from OCP.BinTools import BinTools

    shape = TopoDS_Shape()
    BinTools.Read_s(shape, path)
    return shape


def deg(x: float) -> float:
    return math.degrees(x)


__all__ = [
    "BRepAlgoAPI_Common", "BRepAlgoAPI_Cut", "area", "bounding_box", "boxes_overlap", "compound", "count_faces",
    "faces", "fuse_all", "placement", "planar_face", "pnt", "read_brep", "shape_list", "solids", "unify",
    "volume", "wire_from_points", "write_brep",
]


def write_step(shape: TopoDS_Shape, path: str) -> None:
    """Write ``shape`` as an AP214 STEP file in millimetres."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.Interface import Interface_Static
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    writer = STEPControl_Writer()
    Interface_Static.SetCVal_s("write.step.unit", "MM")
    writer.Transfer(shape, STEPControl_AsIs)
    if writer.Write(path) != IFSelect_RetDone:
        raise OSError(f"could not write STEP file {path}")


def write_stl(shape: TopoDS_Shape, path: str, deflection: float = 0.01, angle: float = 0.2) -> None:
    """Write ``shape`` as binary STL, meshed within ``deflection`` mm and ``angle`` rad (on OCCT's
    threads, except in the kernel's child process, whose fork has none of them:
    :mod:`~fusioncut.engines.brep.budget`)."""
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.StlAPI import StlAPI_Writer

    BRepMesh_IncrementalMesh(shape, deflection, False, angle, not in_child())
    writer = StlAPI_Writer()
    writer.ASCIIMode = False
    if not writer.Write(shape, path):
        raise OSError(f"could not write STL file {path}")
