"""Exact swept volumes of 3-axis tools of revolution (tool axis fixed along +Z), as B-Rep solids.

A tool of revolution moved by translation sweeps, in every horizontal slice, a disk of the slice's
radius along the path's projection. That gives exact constructions without sampling:

* **horizontal line**: back half of the tool at the start, prism of the full axial section (the
  plane through the axis perpendicular to the move), front half at the end. The three pieces meet
  in whole faces, so their outer faces are sewn into one solid (see :func:`_glued`). Exact for any
  profile.
* **arc in the XY plane** (axis parallel to the tool axis): tool(start), tool(end) and the revolution
  about the arc axis of the axial section through both axes (clipped to the arc axis when the tool
  covers it). Exact for any profile.
* **vertical plunge / retract**: one revolved profile (lower tool's rising part, the widest band
  stretched over the travel, upper tool's falling part). Exact for profiles whose radius rises then
  falls (all families here).
* **cylindrical tools** (a flat end mill whose shank has the flute diameter — what adaptive
  clearing uses): on horizontal lines and on XY arcs up to half a turn the sweep is a prism of the
  planar region the disk covers (stadium, or annular sector with half-disk caps, or for a tight arc
  the outer arc with the two end circles meeting behind the centre). One prism, no Boolean: an order
  of magnitude cheaper than the general constructions.
* **ramp** (oblique line), convex tool B, direction d: B ∪ (B+d) ∪ prism(S, d) for any surface S ⊂ B
  whose projection along d covers B's. For a flat end mill S = axial rectangle + top + bottom disk;
  for a ball end mill S = cylinder's axial rectangle + top disk + the sphere's great disk ⊥ d
  (both are hints that hold for every convex body made of those parts). Other tools on ramps use the
  sampled sweep (reported as ``sweep_method = "sampled"``).

The **sampled** sweep reproduces the published method: a union of tool copies every R/4 along the
move. It is the comparison baseline and the fallback. Helices and arcs in the ZX/YZ planes are split
into chords before they get here (see :mod:`fusioncut.engines.segments`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepBuilderAPI import (
    BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakeSolid, BRepBuilderAPI_MakeWire,
    BRepBuilderAPI_Sewing,
)
from OCP.BRepLib import BRepLib
from OCP.GC import GC_MakeArcOfCircle
from OCP.GeomAbs import GeomAbs_Plane
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakePrism, BRepPrimAPI_MakeRevol
from OCP.gp import gp_Ax1, gp_Ax2, gp_Circ, gp_Dir, gp_Vec
from OCP.TopAbs import TopAbs_SHELL
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS, TopoDS_Face, TopoDS_Shape

from fusioncut.engines.base import SweepMethod
from fusioncut.engines.brep import planar
from fusioncut.engines.brep.occ import (
    Vec3, faces, fuse_all, moved_copy, placement, planar_face, pnt, solids, unify, volume, wire_from_points,
)
from fusioncut.engines.ceiling import tool_radii
from fusioncut.errors import KernelFailure, SourceLocation
from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Move
from fusioncut.model.tools import MillingTool, ProfileArc, ProfileLine, ToolProfile

_EPS = 1e-9
# mm: a horizontal travel shorter than this counts as none (the tool at the end; a vertical move):
# the kernel fails to sweep a prism of 1.2e-9 mm, and what such a travel adds is below its tolerance
_SHORT = 1e-7
Z = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class SweptVolume:
    """The solid a tool sweeps over one CL segment, and how it was built (exact or sampled)."""

    shape: TopoDS_Shape
    method: SweepMethod


def _frame_point(o: Vec3, a: Vec3, r: float, z: float) -> Vec3:
    return (o[0] + r * a[0], o[1] + r * a[1], o[2] + z)


def _segment_pieces(seg, o: Vec3, a: Vec3, mirror: bool = False, reverse: bool = False):
    s = -1.0 if mirror else 1.0
    p0 = _frame_point(o, a, s * seg.start[0], seg.start[1])
    p1 = _frame_point(o, a, s * seg.end[0], seg.end[1])
    if reverse:
        p0, p1 = p1, p0
    if isinstance(seg, ProfileArc):
        m = seg.midpoint
        return ("arc", (p0, _frame_point(o, a, s * m[0], m[1]), p1))
    return ("line", (p0, p1))


def half_section(profile: ToolProfile, o: Vec3, a: Vec3):
    """Planar face: the profile on the ``a`` side of the axis through ``o``, closed along the axis."""
    pieces = [_segment_pieces(s, o, a) for s in profile.segments]
    top = profile.segments[-1].end
    pieces.append(("line", (_frame_point(o, a, 0, top[1]), _frame_point(o, a, 0, profile.segments[0].start[1]))))
    return planar_face(wire_from_points(pieces))


def full_section(profile: ToolProfile, o: Vec3, a: Vec3):
    """Planar face: the whole axial section (profile on both sides of the axis)."""
    pieces = [_segment_pieces(s, o, a) for s in profile.segments]
    pieces += [_segment_pieces(s, o, a, mirror=True, reverse=True) for s in reversed(profile.segments)]
    return planar_face(wire_from_points(pieces))


def _revolve(face, o: Vec3, angle: float) -> TopoDS_Shape:
    mk = BRepPrimAPI_MakeRevol(face, gp_Ax1(pnt(o), gp_Dir(*Z)), angle, True)
    mk.Build()
    return mk.Shape()


def _prism(face, v: Vec3) -> TopoDS_Shape:
    mk = BRepPrimAPI_MakePrism(face, gp_Vec(*v), True)
    mk.Build()
    return mk.Shape()


@lru_cache(maxsize=64)
def tool_solid(tool: MillingTool) -> TopoDS_Shape:
    """The tool at the origin, tip at z=0, the cylinder seams in the +X half-plane."""
    return _revolve(half_section(tool.profile(), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)), (0.0, 0.0, 0.0), 2 * math.pi)


def placed_tool(tool: MillingTool, tip: Vec3, seam_angle: float = 0.0) -> TopoDS_Shape:
    """A copy (:func:`~fusioncut.engines.brep.occ.moved_copy`) of the tool with its tip at ``tip``
    and its seam at machine angle ``seam_angle`` (rad)."""
    return moved_copy(tool_solid(tool), placement(tip, seam_angle))


@lru_cache(maxsize=64)
def tool_volume(tool: MillingTool) -> float:
    """The tool's volume (mm³)."""
    return volume(tool_solid(tool))


def _unit(v: Vec3) -> Vec3:
    n = math.sqrt(sum(c * c for c in v))
    return (v[0] / n, v[1] / n, v[2] / n)


def _horizontal_line(tool: MillingTool, p0: Vec3, p1: Vec3, open_start: bool = False) -> TopoDS_Shape:
    """The tool's back half at ``p0``, its axial section swept to ``p1`` and its front half there;
    ``open_start`` leaves the back half out (the sweep then ends behind in the section's plane)."""
    prof = tool.profile()
    d = _unit((p1[0] - p0[0], p1[1] - p0[1], 0.0))
    n = (-d[1], d[0], 0.0)
    L = math.dist(p0, p1)
    body = _prism(full_section(prof, p0, n), (L * d[0], L * d[1], 0.0))
    front = _revolve(half_section(prof, p1, (-n[0], -n[1], 0.0)), p1, math.pi)
    if open_start:
        return _glued([body, front], [(p1, d)])
    back = _revolve(half_section(prof, p0, n), p0, math.pi)
    return _glued([back, body, front], [(p0, d), (p1, d)])


def _glued(pieces: list[TopoDS_Shape], joints: list[tuple[Vec3, Vec3]]) -> TopoDS_Shape:
    """The union of solids that meet only in whole planar faces, each lying in a vertical plane
    through a joint's point with the joint's horizontal normal.

    The outer faces are sewn into one solid and faces on one surface merged: the same volume and
    faces as the glued fuse, for less. If the faces do not close into one valid solid, the glued
    fuse does it.
    """
    solid = _sewn_solid([f for piece in pieces for f in faces(piece) if not _on_joint(f, joints)])
    if solid is not None:
        merged = unify(solid)
        if _sound(merged):
            return merged
    return fuse_all(pieces, glue=True)


def _sewn_solid(face_list: list[TopoDS_Face]) -> TopoDS_Shape | None:
    """The solid bounded by faces that meet edge to edge (within 1e-7 mm), or None if they do not
    close a shell."""
    sewing = BRepBuilderAPI_Sewing(1e-7)
    for face in face_list:
        sewing.Add(face)
    sewing.Perform()
    exp = TopExp_Explorer(sewing.SewedShape(), TopAbs_SHELL)
    if not exp.More():
        return None
    solid = BRepBuilderAPI_MakeSolid(TopoDS.Shell(exp.Current())).Solid()
    BRepLib.OrientClosedSolid_s(solid)
    return solid


def _on_joint(face: TopoDS_Face, joints: list[tuple[Vec3, Vec3]]) -> bool:
    """Whether ``face`` is planar and lies in a joint's plane (within 1e-9 mm and 1e-9 rad)."""
    surface = BRepAdaptor_Surface(face, False)
    if surface.GetType() != GeomAbs_Plane:
        return False
    plane = surface.Plane()
    o, n = plane.Location(), plane.Axis().Direction()
    for p, d in joints:
        if abs(n.X() * d[1] - n.Y() * d[0]) < 1e-9 and abs(n.Z()) < 1e-9 and \
                abs((o.X() - p[0]) * d[0] + (o.Y() - p[1]) * d[1] + (o.Z() - p[2]) * d[2]) < 1e-9:
            return True
    return False


def _sound(shape: TopoDS_Shape) -> bool:
    return len(solids(shape)) == 1 and BRepCheck_Analyzer(shape).IsValid()


def cylinder_tool(tool: MillingTool) -> tuple[float, float] | None:
    """(radius, height) when the whole profile is one cylinder with flat ends, else None."""
    segs = tool.profile().segments
    lateral = [s for s in segs if abs(s.end[1] - s.start[1]) > _EPS]
    if not lateral or not all(isinstance(s, ProfileLine) for s in segs):
        return None
    r = lateral[0].start[0]
    if any(abs(s.start[0] - r) > _EPS or abs(s.end[0] - r) > _EPS for s in lateral):
        return None
    return r, segs[-1].end[1] - segs[0].start[1]


def _add(p: Vec3, v: Vec3, k: float = 1.0) -> Vec3:
    return (p[0] + k * v[0], p[1] + k * v[1], p[2] + k * v[2])


def cylinder_region(r: float, move: Move, open_start: bool = False) -> TopoDS_Face | None:
    """The planar region (at the lower end's height) a disk of radius ``r`` covers along a
    horizontal line, an XY arc of at most half a turn or a vertical move; None for other moves and
    for arcs whose caps would overlap. A cylinder's sweep is this region's prism; the layered
    workpiece (:mod:`fusioncut.engines.brep.layers`) cuts with the region itself.

    ``open_start``: the disk at the start is known to hold no material (the previous CL's tool
    stood there), so the region behind the start's diameter across the path is left out: the cut
    is the same, and the region's back is one straight edge instead of a half circle that lies on
    the previous cut's front arc, touching its side edges tangentially: such tangent pairs are the
    costliest the kernel's intersection meets.
    """
    pieces = _region_pieces(r, move, open_start)
    if pieces is None or pieces[0] == "disk":
        return None if pieces is None else _disk(pieces[1], Z, r)
    return planar_face(wire_from_points(pieces))


def cylinder_region_outline(r: float, move: Move, open_start: bool = False) -> planar.Region | None:
    """:func:`cylinder_region` as a closed-form outline (:mod:`~fusioncut.engines.brep.planar`),
    built without the kernel (the layered cells need no face unless a cut falls back to it)."""
    pieces = _region_pieces(r, move, open_start)
    if pieces is None or pieces[0] == "disk":
        return None if pieces is None else ((planar.arc(pieces[1][0], pieces[1][1], r, 0.0, 2.0 * math.pi),),)
    return planar.from_pieces(pieces)


def _straightened(move: Move, reach: float) -> Move:
    """An XY arc whose outermost point (``reach`` mm beyond its radius) travels less than 1e-6 mm, as
    the line between its ends: the two sweeps differ by less than its sagitta (below 1e-15 mm),
    and the kernel cannot build arcs through three points that close (a 4e-10 rad arc failed)."""
    if isinstance(move, ArcMove) and move.plane == ArcPlane.XY and abs(move.sweep) * (move.radius + reach) < 1e-6:
        return LinearMove(move.start, move.end)
    return move


def _region_pieces(r: float, move: Move, open_start: bool):
    move = _straightened(move, r)
    p0, p1 = move.start, move.end
    if isinstance(move, ArcMove):
        if move.plane != ArcPlane.XY or move.is_helix:
            return None
        return _cylinder_arc_region(r, move, open_start)
    if math.hypot(p1[0] - p0[0], p1[1] - p0[1]) < _SHORT:
        return "disk", (p1[0], p1[1], min(p0[2], p1[2]))
    if abs(p1[2] - p0[2]) < _EPS:
        return _cylinder_line_region(r, p0, p1, open_start)
    return None


def _region_prism(pieces, height: float) -> TopoDS_Shape:
    return _prism(planar_face(wire_from_points(pieces)), (0.0, 0.0, height))


def _cylinder_line_region(r: float, p0: Vec3, p1: Vec3, open_start: bool = False) -> list:
    d = _unit((p1[0] - p0[0], p1[1] - p0[1], 0.0))
    n = (-d[1], d[0], 0.0)
    a, b, c, e = _add(p0, n, r), _add(p1, n, r), _add(p1, n, -r), _add(p0, n, -r)
    back = ("line", (e, a)) if open_start else ("arc", (e, _add(p0, d, -r), a))
    return [("line", (a, b)), ("arc", (b, _add(p1, d, r), c)), ("line", (c, e)), back]


def _cylinder_line(r: float, h: float, p0: Vec3, p1: Vec3, open_start: bool = False) -> TopoDS_Shape:
    return _region_prism(_cylinder_line_region(r, p0, p1, open_start), h)


def _cylinder_arc(r: float, h: float, move: ArcMove, open_start: bool = False) -> TopoDS_Shape | None:
    pieces = _cylinder_arc_region(r, move, open_start)
    return None if pieces is None else _region_prism(pieces, h)


def _cylinder_arc_region(r: float, move: ArcMove, open_start: bool = False) -> list | None:
    """The boundary of the region a disk of radius ``r`` covers along an XY arc of at most half a
    turn (``open_start``: closed behind by a chord of the start disk, see :func:`cylinder_region`)."""
    c, p0, p1 = move.center, move.start, move.end
    theta = move.sweep
    rho = math.hypot(p0[0] - c[0], p0[1] - c[1])
    if abs(theta) > math.pi + 1e-12 or rho < 1e-6 or r < rho <= r + 1e-4:
        return None  # caps would overlap, or a near-degenerate inner arc: use the general sweep
    a0 = math.atan2(p0[1] - c[1], p0[0] - c[0])
    u = lambda a: (math.cos(a), math.sin(a), 0.0)  # noqa: E731
    u0, u1, um = u(a0), u(a0 + theta), u(a0 + 0.5 * theta)
    s = 1.0 if theta > 0 else -1.0
    t0, t1 = (-s * u0[1], s * u0[0], 0.0), (-s * u1[1], s * u1[0], 0.0)
    o0, o1, om = _add(c, u0, rho + r), _add(c, u1, rho + r), _add(c, um, rho + r)
    o0, o1, om = (o0[0], o0[1], p0[2]), (o1[0], o1[1], p0[2]), (om[0], om[1], p0[2])
    if rho > r:
        i0, i1, im = (_add(c, v, rho - r) for v in (u0, u1, um))
        i0, i1, im = ((q[0], q[1], p0[2]) for q in (i0, i1, im))
        back = ("line", (i0, o0)) if open_start else ("arc", (i0, _add(p0, t0, -r), o0))
        pieces = [("arc", (o0, om, o1)), ("arc", (o1, _add(p1, t1, r), i1)), ("arc", (i1, im, i0)), back]
    else:
        # the end circles meet behind the arc centre; every disk in between covers the rest
        half = 0.5 * abs(theta)
        k = math.sqrt(r * r - (rho * math.sin(half)) ** 2) - rho * math.cos(half)
        q = (c[0] - k * um[0], c[1] - k * um[1], p0[2])
        back = ("line", (q, o0)) if open_start else ("arc", (q, _add(p0, t0, -r), o0))
        pieces = [("arc", (o0, om, o1)), ("arc", (o1, _add(p1, t1, r), q)), back]
    return pieces


def _cylinder_ramp(r: float, h: float, p0: Vec3, p1: Vec3) -> TopoDS_Shape | None:
    """Oblique line of a cylinder: its convex hull with its translate, from eight sewn faces.

    With the start ``a`` the higher end (the hull is the same read backwards) and ``d`` the
    horizontal direction towards the lower end ``b``, ``n`` its left normal: the back half cylinder
    at ``a``, the front half cylinder at ``b``, the two side parallelograms at ``±r n``, the top
    disk at ``a``, the bottom disk at ``b``, the front half of the top circle and the back half of
    the bottom circle ruled along the move. No Boolean: a fuse of the tool copies and prisms (the
    general ramp) is slow and breaks down on short chords where the copies nearly coincide.
    """
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakePolygon
    from OCP.gp import gp_Ax3, gp_Cylinder

    a, b = (p0, p1) if p0[2] >= p1[2] else (p1, p0)
    v = (b[0] - a[0], b[1] - a[1], b[2] - a[2])
    d = _unit((v[0], v[1], 0.0))
    n = (-d[1], d[0], 0.0)
    up = (0.0, 0.0, h)

    def half_cylinder(c: Vec3, start: Vec3):
        ax = gp_Ax3(pnt(c), gp_Dir(*Z), gp_Dir(*start))
        return BRepBuilderAPI_MakeFace(gp_Cylinder(ax, r), 0.0, math.pi, 0.0, h).Face()

    def half_circle(c: Vec3, start: Vec3):
        mid = (-start[1], start[0], 0.0)  # a quarter turn counter-clockwise
        return GC_MakeArcOfCircle(pnt(_add(c, start, r)), pnt(_add(c, mid, r)), pnt(_add(c, start, -r))).Value()

    def disk(c: Vec3):
        wire = BRepBuilderAPI_MakeWire(BRepBuilderAPI_MakeEdge(half_circle(c, n)).Edge(),
                                       BRepBuilderAPI_MakeEdge(half_circle(c, (-n[0], -n[1], 0.0))).Edge()).Wire()
        return BRepBuilderAPI_MakeFace(wire, True).Face()

    def ruled(c: Vec3, start: Vec3):
        return _prism(BRepBuilderAPI_MakeEdge(half_circle(c, start)).Edge(), v)

    def side(sign: float):
        q0, q1 = _add(a, n, sign * r), _add(b, n, sign * r)
        poly = BRepBuilderAPI_MakePolygon(pnt(q0), pnt(q1), pnt(_add(q1, up)), pnt(_add(q0, up)), True)
        return BRepBuilderAPI_MakeFace(poly.Wire(), True).Face()

    minus_n = (-n[0], -n[1], 0.0)
    return _sewn_solid([half_cylinder(a, n), half_cylinder(b, minus_n), side(1.0), side(-1.0), disk(_add(a, up)),
                        disk(b), ruled(_add(a, up), minus_n), ruled(a, n)])


def _arc_xy(tool: MillingTool, move: ArcMove, seam: float) -> TopoDS_Shape:
    prof = tool.profile()
    c, p0, p1 = move.center, move.start, move.end
    rho = math.hypot(p0[0] - c[0], p0[1] - c[1])
    theta = move.sweep
    a0 = ((p0[0] - c[0]) / rho, (p0[1] - c[1]) / rho, 0.0)
    r_max = max(prof.radius_at(s.end[1]) for s in prof.segments)
    axis_pt = (c[0], c[1], p0[2])
    sgn = 1.0 if theta > 0 else -1.0
    if rho >= r_max + 1e-6 and abs(theta) < 2 * math.pi - 1e-9:
        a1 = ((p1[0] - c[0]) / rho, (p1[1] - c[1]) / rho, 0.0)
        back = _revolve(half_section(prof, p0, a0), p0, -sgn * math.pi)
        ring = _revolve(full_section(prof, p0, a0), axis_pt, theta)
        front = _revolve(half_section(prof, p1, a1), p1, sgn * math.pi)
        # the ring's end sections: the radial planes at the arc's ends, normal to their tangents
        return _glued([back, ring, front], [(p0, (-a0[1], a0[0], 0.0)), (p1, (-a1[1], a1[0], 0.0))])
    section = full_section(prof, p0, a0)
    if rho < r_max:
        # keep only the part of the section on the tool's side of the arc axis: the rest sweeps
        # a disk about the axis that the tool itself already covers
        big = 4 * (r_max + rho) + prof.height
        n = (-a0[1], a0[0], 0.0)
        # box from the arc axis outward along a0, wide along n and tall along Z (Y = a0 x n = Z)
        corner = (c[0] - big * n[0], c[1] - big * n[1], p0[2] - big)
        ax = gp_Ax2(pnt(corner), gp_Dir(*a0), gp_Dir(*n))
        half_space = BRepPrimAPI_MakeBox(ax, 2 * big, 2 * big + prof.height, 4 * big).Shape()
        section = BRepAlgoAPI_Common(section, half_space).Shape()
    ring = _revolve(section, axis_pt, max(-2 * math.pi, min(2 * math.pi, theta)))
    return fuse_all([placed_tool(tool, p0, seam), ring, placed_tool(tool, p1, seam)])


def _plunge(tool: MillingTool, p0: Vec3, p1: Vec3, seam: float) -> TopoDS_Shape | None:
    """Vertical move: one revolved outline, or ``None`` when the profile is not rise-then-fall."""
    segs = tool.profile().segments
    r_max = max(max(s.start[0], s.end[0]) for s in segs)
    for s in segs:
        if isinstance(s, ProfileArc) and min(s.start[1], s.end[1]) + _EPS < s.center[1] < max(s.start[1], s.end[1]) - _EPS:
            return None  # the arc bulges past its end points: its widest point is not a vertex
    at_max = lambda pt: abs(pt[0] - r_max) < _EPS  # noqa: E731
    first = next(k if at_max(s.start) else k + 1 for k, s in enumerate(segs) if at_max(s.start) or at_max(s.end))
    last = next(k + 1 if at_max(s.end) else k for k, s in reversed(list(enumerate(segs))) if at_max(s.start) or at_max(s.end))
    rising, falling = segs[:first], segs[last:]
    if any(s.end[0] < s.start[0] - _EPS for s in rising) or any(s.end[0] > s.start[0] + _EPS for s in falling):
        return None
    z_first = rising[-1].end[1] if rising else segs[0].start[1]
    z_last = falling[0].start[1] if falling else segs[-1].end[1]
    lo, hi = (p0, p1) if p0[2] <= p1[2] else (p1, p0)
    a = (math.cos(seam), math.sin(seam), 0.0)
    pieces = [_segment_pieces(s, lo, a) for s in rising]
    pieces.append(("line", (_frame_point(lo, a, r_max, z_first), _frame_point(hi, a, r_max, z_last))))
    pieces += [_segment_pieces(s, hi, a) for s in falling]
    pieces.append(("line", (_frame_point(hi, a, 0, segs[-1].end[1]), _frame_point(lo, a, 0, segs[0].start[1]))))
    return _revolve(planar_face(wire_from_points(pieces)), lo, 2 * math.pi)


def _disk(center: Vec3, normal: Vec3, radius: float):
    circ = gp_Circ(gp_Ax2(pnt(center), gp_Dir(*normal)), radius)
    edge = BRepBuilderAPI_MakeEdge(circ).Edge()
    return BRepBuilderAPI_MakeFace(BRepBuilderAPI_MakeWire(edge).Wire(), True).Face()


def _rectangle(o: Vec3, a: Vec3, half_width: float, z0: float, z1: float):
    pts = [_frame_point(o, a, -half_width, z0), _frame_point(o, a, half_width, z0),
           _frame_point(o, a, half_width, z1), _frame_point(o, a, -half_width, z1)]
    return planar_face(wire_from_points([("line", (pts[k], pts[(k + 1) % 4])) for k in range(4)]))


def _ramp(tool: MillingTool, p0: Vec3, p1: Vec3, seam: float) -> TopoDS_Shape | None:
    """Oblique line for convex flat and ball end mills; ``None`` for other tools."""
    if tool.kind not in ("flat", "ball") or not tool.is_convex:
        return None
    v = (p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2])
    dh = _unit((v[0], v[1], 0.0))
    n = (-dh[1], dh[0], 0.0)
    R, top = tool.radius, tool.length
    spans = [_disk((p0[0], p0[1], p0[2] + top), Z, R)]
    if tool.kind == "flat":
        spans += [_rectangle(p0, n, R, 0.0, top), _disk(p0, Z, R)]
    else:
        spans += [_rectangle(p0, n, R, R, top), _disk((p0[0], p0[1], p0[2] + R), _unit(v), R)]
    prisms = [_prism(f, v) for f in spans]
    return fuse_all([placed_tool(tool, p0, seam), placed_tool(tool, p1, seam), *prisms])


def _exact_sweep(tool: MillingTool, move: Move, seam: float, cyl: tuple[float, float] | None,
                 open_start: bool) -> TopoDS_Shape | None:
    """The exact construction for ``move`` (an XY arc, or a line of nonzero length), or None."""
    p0, p1 = move.start, move.end
    if isinstance(move, ArcMove):
        return (_cylinder_arc(*cyl, move, open_start) if cyl else None) or _arc_xy(tool, move, seam)
    dz = p1[2] - p0[2]
    dh = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
    if abs(dz) < _EPS:
        return _cylinder_line(*cyl, p0, p1, open_start) if cyl else _horizontal_line(tool, p0, p1, open_start)
    if dh < _SHORT:
        return _plunge(tool, p0, p1, seam)
    return (_cylinder_ramp(*cyl, p0, p1) if cyl else None) or _ramp(tool, p0, p1, seam)


def _relative(move: Move) -> Move:
    """``move``'s geometry alone, started at the origin (what its sweep's shape depends on)."""
    p0 = move.start
    moved = move.translated((-p0[0], -p0[1], -p0[2]))
    return replace(moved, start=(0.0, 0.0, 0.0), feed=None, spindle_rpm=None, tool=None, operation="",
                   source=SourceLocation())


@lru_cache(maxsize=256)
def _sweep_at_origin(tool: MillingTool, move: Move, seam: float, open_start: bool) -> TopoDS_Shape | None:
    """The exact sweep of ``move`` (starting at the origin), or None when there is none or the
    kernel built one smaller than the tool (a sweep holds the tool at its end; one left open at
    the start, the tool's front half at least)."""
    shape = _exact_sweep(tool, move, seam, None, open_start)
    least = tool_volume(tool) * (0.5 if open_start else 1.0)
    return shape if shape is not None and _holds(shape, least) else None


def _holds(shape: TopoDS_Shape, least: float) -> bool:
    """Whether ``shape`` is one solid of at least ``least`` mm³ (1e-9 relative to spare)."""
    return len(solids(shape)) == 1 and volume(shape) >= least * (1 - 1e-9)


def sampled_sweep(tool: MillingTool, move: Move, seam: float = 0.0, spacing: float | None = None) -> TopoDS_Shape:
    """Union of tool copies along the move every ``spacing`` mm (default R/4): the published method.

    Copies whose sides nearly coincide are where the kernel's fuse goes wrong without an error (a
    ramp 2.5 mm up and 1e-6 mm sideways fused into 3e-5 mm³ with fuzzy 0, 5 solids with 1e-6, 197
    mm³ with 1e-5): an axis along which the copies spread less than ``_SNAP`` mm keeps them all
    at the start's coordinate (coincident sides fuse right; the union is that much smaller, far
    below the copies' own scallops). The union must then be one solid between one tool's volume
    and, on a line, the closed form of the exact sweep's (else fuzzier fuses are tried; then it fails).
    """
    n = _copies(tool, move, spacing)
    points = [move.point_at(k / n) for k in range(n + 1)]
    for axis in range(3):
        values = [p[axis] for p in points]
        if max(values) - min(values) < _SNAP:
            points = [(*p[:axis], move.start[axis], *p[axis + 1:]) for p in points]
    least = tool_volume(tool) * (1 - 1e-9)
    most = _line_sweep_volume_bound(tool, move) if not isinstance(move, ArcMove) else (n + 1) * least
    for fuzzy in (0.0, 1e-5, 1e-4, 1e-3):
        shape = fuse_all([placed_tool(tool, p, seam) for p in points], fuzzy=fuzzy)
        if len(solids(shape)) == 1 and least <= volume(shape) <= most:
            return shape
    raise KernelFailure(f"the union of {n + 1} tool copies along the move is not one solid of a sweep's volume")


_SNAP = 1e-4  # mm


def _copies(tool: MillingTool, move: Move, spacing: float | None = None) -> int:
    """The intervals between the tool copies of :func:`sampled_sweep` (copies every ``spacing`` mm
    along the move at most, default R/4)."""
    return max(1, math.ceil(move.length / (spacing or tool.radius / 4) - 1e-9))


def sampled_ridge(tool: MillingTool, move: Move, spacing: float | None = None) -> float:
    """How high (mm, above the copies' tips) the material between two neighbouring copies of
    :func:`sampled_sweep` can stand: the height where the tool's radius reaches half their horizontal
    distance (a ball's scallop, a V-bit's ridge). The exact sweep leaves none."""
    if isinstance(move, ArcMove):
        horizontal = abs(move.sweep) * max(move.radius, move.end_radius)
    else:
        horizontal = math.hypot(move.end[0] - move.start[0], move.end[1] - move.start[1])
    half = 0.5 * horizontal / _copies(tool, move, spacing)
    profile = tool.profile()
    lo, hi = 0.0, profile.height
    if half <= 0.0 or profile.radius_at(lo) >= half:
        return 0.0
    for _ in range(60):  # bisection on the profile's radius, which grows with z up to R (convex tools)
        mid = 0.5 * (lo + hi)
        if profile.radius_at(mid) >= half:
            hi = mid
        else:
            lo = mid
    return hi


def _line_sweep_volume_bound(tool: MillingTool, move: Move) -> float:
    """An upper bound (mm³) of the volume a tool sweeps along a line: the tool plus the line's length
    times twice the shadow, across the line, of the cylinder of the tool's largest radius and its
    length (πR²|cos θ| + 2RL|sin θ|, θ from the tool axis), with 1e-6 relative to spare. Once the
    shadow would do for a convex tool; twice, for a shank wider than the flutes, whose body a line
    may cross twice."""
    d = [e - s for s, e in zip(move.start, move.end)]
    length = math.sqrt(sum(c * c for c in d))
    if length == 0.0:
        return tool_volume(tool) * (1 + 1e-6)
    cos = abs(d[2]) / length
    sin = math.sqrt(max(0.0, 1.0 - cos * cos))
    r, _, height = tool_radii(tool)
    shadow = math.pi * r * r * cos + 2.0 * r * height * sin
    return (tool_volume(tool) + 2.0 * length * shadow) * (1 + 1e-6)


def swept_volume(tool: MillingTool, move: Move, method: SweepMethod = SweepMethod.EXACT, seam: float = 0.0,
                 open_start: bool = False) -> SweptVolume:
    """The solid swept by ``tool`` along ``move`` (a line, or an arc in the XY plane).

    ``seam`` (rad, machine angle) is where full tool copies put their cylinder seams: the engine points
    it away from the feed so that seams never split the engaged faces. ``open_start``: the tool at
    the start is known to stand in no material, so a level sweep may leave it out behind the
    start's axial section: a cylindrical tool's (:func:`cylinder_region`) and another tool's on a
    line; other sweeps ignore it. Left out, a ball end mill's back hemisphere no longer meets the
    neighbouring row's groove (a sphere against a cylinder, a costly intersection; a plane across
    the groove meets it in arcs).
    """
    if method == SweepMethod.SAMPLED:
        return SweptVolume(sampled_sweep(tool, move, seam), SweepMethod.SAMPLED)
    if isinstance(move, ArcMove) and (move.plane != ArcPlane.XY or move.is_helix):
        raise ValueError("helices and ZX/YZ arcs must be split into chords first")
    move = _straightened(move, tool_radii(tool)[0])
    p0, p1 = move.start, move.end
    if not isinstance(move, ArcMove) and math.hypot(p1[0] - p0[0], p1[1] - p0[1]) < _SHORT and abs(p1[2] - p0[2]) < _EPS:
        return SweptVolume(placed_tool(tool, p1, seam), SweepMethod.EXACT)
    cyl = cylinder_tool(tool)
    shape: TopoDS_Shape | None
    if cyl:
        shape = _exact_sweep(tool, move, seam, cyl, open_start)
    else:
        # other tools' constructions are costly (a ball end mill's line is sewn from three revolved
        # and swept pieces), and a finishing pass repeats the same motion at every CL: built once at
        # the origin, each CL gets a translated copy
        open_line = open_start and not isinstance(move, ArcMove) and abs(p1[2] - p0[2]) < _EPS
        origin = _sweep_at_origin(tool, _relative(move), seam, open_line)
        shape = None if origin is None else moved_copy(origin, placement(p0, 0.0))
    if shape is None or not solids(shape):
        # no exact construction for this tool and move, or the kernel built nothing (seen on
        # steep chords of a few µm): the published method's sampled sweep, reported as such
        return SweptVolume(sampled_sweep(tool, move, seam), SweepMethod.SAMPLED)
    return SweptVolume(shape, SweepMethod.EXACT)
