"""Exports of the in-process workpiece (IPW) and 3D scenes of one CL, as files or plain numpy arrays.

Everything that leaves this module is numpy arrays, floats, strings and the project's own types: no
OCP object is returned, so :mod:`fusioncut.viz` and the CLI never see the kernel. Units: mm and the
machine frame (Z up) throughout; angles in degrees unless a name ends in ``_rad``.

* :func:`tessellate`: a B-Rep shape as a triangle mesh within a chord deflection.
* :func:`export_ipw`: the IPW as STEP (exact), STL (meshed) or BREP (exact, OCCT's own format).
* :func:`replay`: run the engine from the stock up to CL ``N`` and keep its state there.
* :func:`cl_scene`: what the engine knows at one CL as meshes and line segments: the IPW, the tool
  placed at the CL, the contact faces, the entry / exit lines and the engaged arcs of each slice.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from OCP.BOPAlgo import BOPAlgo_GlueShift
from OCP.BRep import BRep_Tool
from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepLib import BRepLib_ToolTriangulatedShape
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.ShapeFix import ShapeFix_Shape
from OCP.TopAbs import TopAbs_REVERSED
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS_Face, TopoDS_Shape

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.budget import Deadline, guarded, in_child, shape_bytes, shape_from_bytes
from fusioncut.engines.brep.contact import ContactFace, find_contact_faces
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.brep.occ import (
    bounding_box, boxes_overlap, faces, shape_list, solids, unify, volume, write_brep, write_step, write_stl,
)
from fusioncut.engines.brep.sweep import placed_tool
from fusioncut.engines.segments import segments_for
from fusioncut.errors import FusionCutError, GeometryError, InputError
from fusioncut.io.results import slice_band
from fusioncut.model.angles import machine_from_immersion
from fusioncut.model.engagement import EngagementMap, SliceEngagement
from fusioncut.model.moves import Move, Toolpath
from fusioncut.model.stock import Stock
from fusioncut.model.tools import MillingTool

log = logging.getLogger("fusioncut.export")

# the angular deflection (rad) of meshes: with a linear deflection alone, small fillets and the tool's
# corner radius would get a single facet
DEFAULT_ANGLE = 0.3

IPW_SUFFIXES = {".step": "STEP", ".stp": "STEP", ".stl": "STL", ".brep": "BREP"}


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh in mm. Unpacks as ``vertices, triangles = mesh``.

    ``vertices`` (n, 3) float64; ``triangles`` (m, 3) int64 indices, counter-clockwise seen from
    outside the solid (right-hand normal points out); ``normals`` (n, 3) unit surface normals at the
    vertices (pointing out), or ``None`` when not computed.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None = None

    def __iter__(self):
        return iter((self.vertices, self.triangles))

    @property
    def is_empty(self) -> bool:
        return len(self.triangles) == 0

    @property
    def area(self) -> float:
        """Total triangle area, mm²."""
        if self.is_empty:
            return 0.0
        a, b, c = (self.vertices[self.triangles[:, k]] for k in range(3))
        return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())

    @property
    def signed_volume(self) -> float:
        """Enclosed volume (mm³) by the divergence theorem: right for any closed, outward-wound surface,
        even one whose faces do not share vertices."""
        if self.is_empty:
            return 0.0
        a, b, c = (self.vertices[self.triangles[:, k]] for k in range(3))
        return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _empty_mesh() -> Mesh:
    return Mesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), np.zeros((0, 3)))


# -- tessellation -------------------------------------------------------------------------------


def _meshed_copy(shape: TopoDS_Shape, deflection: float, angle: float) -> BRepBuilderAPI_Copy:
    """A copy of ``shape`` (``.Shape()``) carrying a fresh mesh.

    Meshing stores triangulations in the faces; on a copy the caller's shape (the engine's IPW, the
    cached tool solid) is left as it was, and an older, coarser mesh is never reused.
    """
    if not deflection > 0:
        raise ValueError(f"mesh deflection must be > 0 mm, got {deflection}")
    copier = BRepBuilderAPI_Copy(shape, True, False)
    mesher = BRepMesh_IncrementalMesh(copier.Shape(), float(deflection), False, float(angle), not in_child())
    if not mesher.IsDone():
        raise GeometryError(f"meshing failed (deflection {deflection} mm)")
    return copier


def _face_mesh(face: TopoDS_Face) -> Mesh:
    """The triangulation of one meshed face in the machine frame, wound and oriented outward."""
    loc = TopLoc_Location()
    tri = BRep_Tool.Triangulation_s(face, loc)
    if tri is None:
        raise GeometryError("a face of the shape could not be meshed")
    trsf = loc.Transformation()
    n = tri.NbNodes()
    verts = np.empty((n, 3))
    for i in range(n):
        p = tri.Node(i + 1).Transformed(trsf)
        verts[i] = (p.X(), p.Y(), p.Z())
    tris = np.array([tri.Triangle(k + 1).Get() for k in range(tri.NbTriangles())], dtype=np.int64).reshape(-1, 3) - 1
    # normals from the surface itself (at each node's (u, v)): smooth shading of curved faces with no
    # faceting, and sharp edges between faces
    normals = None
    if tri.HasUVNodes():
        BRepLib_ToolTriangulatedShape.ComputeNormals_s(face, tri)  # on the copy's own triangulation
    if tri.HasNormals():
        normals = np.empty((n, 3))
        for i in range(n):
            d = tri.Normal(i + 1).Transformed(trsf)
            normals[i] = (d.X(), d.Y(), d.Z())
    if face.Orientation() == TopAbs_REVERSED:
        # a reversed face's material lies on the other side of its surface: flip winding and normals
        tris = tris[:, ::-1]
        if normals is not None:
            normals = -normals
    return Mesh(verts, tris, normals)


def _concatenate(parts: list[Mesh]) -> Mesh:
    if not parts:
        return _empty_mesh()
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    verts = np.concatenate([p.vertices for p in parts])
    tris = np.concatenate([p.triangles + o for p, o in zip(parts, offsets)])
    normals = None
    if all(p.normals is not None for p in parts):
        normals = np.concatenate([p.normals for p in parts])  # type: ignore[misc]
    return Mesh(verts, tris, normals)


def _merge_vertices(mesh: Mesh, tol: float) -> Mesh:
    """Weld vertices closer than ``tol`` (mm) so that the faces of a solid form one closed surface."""
    if mesh.is_empty:
        return _empty_mesh()
    # neighbouring faces get their boundary nodes from the same edge discretisation, so the copies of
    # a node agree to rounding; a grid of ``tol`` welds them (two different nodes are never that close)
    key = np.round(mesh.vertices / tol).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    tris = inverse.reshape(-1)[mesh.triangles]
    # drop triangles that the weld made degenerate (all of whose corners collapsed within tol)
    keep = (tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])
    return Mesh(mesh.vertices[first], tris[keep], None)


def _snap(parts: list[Mesh], tol: float = 1e-6) -> list[Mesh]:
    """Give copies of a node that several faces' meshes share one position (each keeps its normal).

    A face's boundary nodes agree with its neighbour's only to rounding; drawn as they are, the
    seams show hairline cracks.
    """
    if not parts or all(p.is_empty for p in parts):
        return parts
    verts = np.concatenate([p.vertices for p in parts])
    _, first, inverse = np.unique(np.round(verts / tol).astype(np.int64), axis=0, return_index=True,
                                  return_inverse=True)
    snapped = verts[first][inverse.reshape(-1)]
    out, k = [], 0
    for p in parts:
        out.append(replace(p, vertices=snapped[k:k + len(p.vertices)]))
        k += len(p.vertices)
    return out


def tessellate(shape: TopoDS_Shape, deflection: float, angle: float = DEFAULT_ANGLE, *,
               weld: bool = True) -> Mesh:
    """Triangle mesh of ``shape`` whose facets lie within ``deflection`` mm of the exact surface.

    ``angle`` (rad) bounds the angle between neighbouring facets. With ``weld`` (default) the faces'
    shared boundary nodes are merged, so a solid gives one closed, consistently outward-wound surface;
    without it each face keeps its own vertices and exact surface normals (for shading).
    The enclosed volume differs from the exact one by at most ``deflection`` × surface area.
    """
    meshed = _meshed_copy(shape, deflection, angle).Shape()
    parts = [_face_mesh(f) for f in faces(meshed)]
    return _merge_vertices(_concatenate(parts), tol=1e-6) if weld else _concatenate(_snap(parts))


# -- the workpiece as one solid ----------------------------------------------------------------------


def _fused(parts: list[TopoDS_Shape], glue: bool) -> TopoDS_Shape:
    op = BRepAlgoAPI_Fuse()
    op.SetArguments(shape_list(parts[:1]))
    op.SetTools(shape_list(parts[1:]))
    if glue:
        op.SetGlue(BOPAlgo_GlueShift)  # the cells only share (parts of) faces: no face crosses another
    op.Build()
    if not op.IsDone():
        raise RuntimeError("fuse failed")
    return op.Shape()


def whole_ipw(ipw: TopoDS_Shape | BRepEngine) -> TopoDS_Shape:
    """The IPW as one shape with no internal walls (an engine, or its ``ipw``).

    The engine may keep the workpiece as cells (columns) side by side; their common walls are inside
    the material, and written as they are they would show in a view and make an STL non-manifold.
    Here the cells are fused, repaired where the fuse leaves an invalid shape (it does, where a
    channel crosses a wall: measured on the demo), and faces on the same surface merged; every
    result is checked (valid B-Rep, same volume). Separate pieces of material stay separate solids.
    Should no result pass, the cells are returned as they are with a warning: the volume is right,
    only the walls remain.
    """
    shape = ipw.ipw if isinstance(ipw, BRepEngine) else ipw
    if shape is None or shape.IsNull():
        raise GeometryError("there is no workpiece")
    if len(solids(shape)) <= 1:
        return shape
    # work on a copy: a fuse may widen the tolerances of its arguments' edges and the repair below
    # edits shapes in place, and the cells are the engine's live state (they share those edges)
    parts = solids(BRepBuilderAPI_Copy(shape, True, False).Shape())
    expected = sum(volume(p) for p in parts)

    def good(candidate: TopoDS_Shape) -> bool:
        # the volumes agree to GProp's integration accuracy (about 1e-9 relative), not to rounding
        return (BRepCheck_Analyzer(candidate).IsValid()
                and abs(volume(candidate) - expected) <= 1e-6 * max(1.0, expected))

    for glue in (True, False):
        try:
            fused = _fused(parts, glue)
            if not BRepCheck_Analyzer(fused).IsValid():
                fix = ShapeFix_Shape(fused)
                fix.Perform()
                fused = fix.Shape()
            if not good(fused):
                continue
            merged = unify(fused)
            return merged if good(merged) else fused
        except Exception as exc:  # noqa: BLE001 - OCP raises its own types; the next way is tried
            log.debug("fusing the workpiece cells (glue=%s) failed: %s", glue, exc)
    log.warning("could not fuse the %d workpiece cells into one solid; they are kept side by side", len(parts))
    return shape


# -- files --------------------------------------------------------------------------------------


@contextmanager
def _kernel_errors(what: str, cl_index: int | None = None):
    """Report a failure of the kernel (OCP raises its own exception types) as a :class:`GeometryError`."""
    try:
        yield
    except (FusionCutError, ValueError, OSError):
        raise
    except Exception as exc:  # noqa: BLE001 - OCP's Standard_Failure and kin have no common Python base
        raise GeometryError(f"{what} failed in the geometry kernel: {exc or type(exc).__name__}", cl_index) from exc


@contextmanager
def _quiet_kernel():
    """Keep OCCT's own chatter (the STEP writer's transfer statistics) off the user's terminal."""
    from OCP.Message import Message

    messenger = Message.DefaultMessenger_s()
    printers = list(messenger.Printers())
    for p in printers:
        messenger.RemovePrinter(p)
    try:
        yield
    finally:
        for p in printers:
            messenger.AddPrinter(p)


def export_ipw(ipw: TopoDS_Shape | BRepEngine, path: str | Path, deflection: float = 0.01,
               angle: float = DEFAULT_ANGLE, budget_s: float | None = None) -> str:
    """Write the IPW (an engine, or its ``ipw``) to ``path``; the suffix picks the format. Returns the
    format's name. The cells of the engine's IPW are joined first (:func:`whole_ipw`).

    ``.step`` / ``.stp``: AP214 in mm, exact B-Rep. ``.brep``: OCCT's text format, exact to the bit.
    ``.stl``: binary, facets within ``deflection`` mm (and ``angle`` rad) of the exact surface.

    ``budget_s`` (s): the join and the write run in the kernel's killable child process
    (:func:`~fusioncut.engines.brep.budget.guarded`, the shape sent as binary BRep), killed past it
    (:class:`~fusioncut.engines.brep.budget.KernelBudgetExceeded`, nothing written); None: here,
    unbounded.
    """
    path = Path(path)
    kind = IPW_SUFFIXES.get(path.suffix.lower())
    if kind is None:
        raise InputError(f"unsupported workpiece format {path.suffix!r} (use .step, .stp, .stl or .brep)", path)
    if not path.parent.is_dir():
        raise InputError("the output folder does not exist", path.parent)
    if kind == "STL" and not deflection > 0:
        raise ValueError(f"STL deflection must be > 0 mm, got {deflection}")
    deadline = Deadline(budget_s)
    if deadline.guards:
        shape = ipw.ipw if isinstance(ipw, BRepEngine) else ipw
        if shape is None or shape.IsNull():
            raise GeometryError("there is no workpiece")
        guarded(_write_ipw_bytes, (shape_bytes(shape), str(path), kind, deflection, angle), deadline,
                f"writing {path.name}")
    else:
        _write_ipw(ipw, path, kind, deflection, angle)
    return kind


def _write_ipw_bytes(data: bytes, path: str, kind: str, deflection: float, angle: float) -> None:
    """:func:`_write_ipw` of a shape sent as binary BRep (the kernel's child runs this)."""
    _write_ipw(shape_from_bytes(data), Path(path), kind, deflection, angle)


def _write_ipw(ipw: TopoDS_Shape | BRepEngine, path: Path, kind: str, deflection: float, angle: float) -> None:
    with _kernel_errors(f"writing {path.name}"), _quiet_kernel():
        ipw = whole_ipw(ipw)
        if kind == "STEP":
            write_step(ipw, str(path))
        elif kind == "BREP":
            write_brep(ipw, str(path))
        else:
            # mesh a copy: the engine's IPW keeps no triangulation it did not ask for
            write_stl(BRepBuilderAPI_Copy(ipw, True, False).Shape(), str(path), deflection, angle)


# -- engine state at a CL -------------------------------------------------------------------------


@dataclass
class Replay:
    """The engine after processing CLs ``0..cl_index``: its IPW, the map, move and tool of that CL."""

    engine: BRepEngine
    map: EngagementMap
    move: Move
    tool: MillingTool
    cl_count: int  # CL segments in the whole toolpath


def check_cl_index(toolpath: Toolpath, cl_index: int, options: EngineOptions | None = None) -> list[Move]:
    """The CL segments of ``toolpath`` under ``options``; an :class:`InputError` unless CL ``cl_index`` is one."""
    options = options or EngineOptions()
    segments = segments_for(toolpath.moves, options)
    if not 0 <= cl_index < len(segments):
        raise InputError(f"CL {cl_index} is out of range: the toolpath has {len(segments)} CL segments "
                         f"(0..{len(segments) - 1})", toolpath.source)
    return segments


def replay(toolpath: Toolpath, stock: Stock | TopoDS_Shape, cl_index: int, options: EngineOptions | None = None,
           default_tool: MillingTool | None = None,
           on_cl: Callable[[EngagementMap, int], None] | None = None) -> Replay:
    """Run the engine from ``stock`` through CL ``cl_index`` (inclusive) and stop there.

    CL indices are those of a run with the same ``options`` (the CL segments of
    :func:`fusioncut.engines.segments.segments_for`). ``on_cl(map, cl_index + 1)`` reports progress.
    """
    options = options or EngineOptions()
    segments = check_cl_index(toolpath, cl_index, options)
    engine = BRepEngine(options)
    engine.start(stock)
    last = None
    for m in engine.process(toolpath, default_tool):
        last = m
        if on_cl:
            on_cl(m, cl_index + 1)
        if m.cl_index >= cl_index:
            break
    assert last is not None and last.cl_index == cl_index
    move = segments[cl_index]
    tool = (toolpath.tools.get(move.tool) if move.tool is not None else None) or default_tool
    assert tool is not None  # process() raised already for a move without a tool
    return Replay(engine, last, move, tool, len(segments))


def contact_faces_at(ipw: TopoDS_Shape | BRepEngine, tool: MillingTool, tip: tuple[float, float, float],
                     tol: float = 1e-6) -> list[ContactFace]:
    """The faces of the workpiece (an engine, or its ``ipw``) lying on the surfaces of ``tool`` with
    its tip at ``tip`` (mm), found among the faces near the tool.

    Recomputed from the IPW (its cells joined, :func:`whole_ipw`), not kept from the engine's step:
    the same surface and area as the step's for a CL that removed material, and also any face an
    earlier CL left on the very same tool surface (it touches the tool all the same).
    """
    box = bounding_box(placed_tool(tool, tip))
    near = [f for f in faces(whole_ipw(ipw)) if boxes_overlap(bounding_box(f), box, gap=tol)]
    return find_contact_faces(near, tool, tip, tol)


# -- engagement lines (pure geometry, no kernel) ----------------------------------------------------


@dataclass(frozen=True)
class EngagementLines:
    """Line segments (k, 2, 3) in mm, machine frame, on the tool surface at the CL.

    ``entry`` / ``exit``: for every engaged interval of every slice, the tool-surface generator at the
    machine angle where the teeth enter / leave material, over the slice's band of heights (so the
    segments of successive slices join into the entry and exit curves). ``arcs``: the engaged arc of
    each interval at the slice height, as a polyline of chords at most ``arc_step_deg`` apart.
    """

    entry: np.ndarray
    exit: np.ndarray
    arcs: np.ndarray


def _slice_bands(em: EngagementMap, slice_height: float | None) -> list[tuple[float, float] | None]:
    """Height band (mm above the tip) of each slice, by the engine's slice rule
    (:func:`fusioncut.io.results.slice_band`, as the results record it); ``None`` where it is not
    known: without the run's slice height, or for a slice the rule does not place there."""
    if slice_height is None:
        return [None] * len(em.slices)
    return [slice_band(s.z, slice_height, em.axial_range) for s in em.slices]


def _surface_point(tool: MillingTool, tip, theta_deg: float, z: float, radius: float | None = None) -> np.ndarray:
    r = tool.profile().radius_at(z) if radius is None else radius
    t = math.radians(theta_deg)
    return np.array([tip[0] + r * math.cos(t), tip[1] + r * math.sin(t), tip[2] + z])


def _generator(tool: MillingTool, tip, theta_deg: float, band: tuple[float, float], steps: int = 4) -> list:
    # several pieces: on a ball or a corner radius the generator is curved
    zs = np.linspace(band[0], band[1], steps + 1)
    pts = [_surface_point(tool, tip, theta_deg, float(z)) for z in zs]
    return [(a, b) for a, b in zip(pts, pts[1:])]


def engagement_lines(em: EngagementMap, tool: MillingTool, slice_height: float | None = None,
                     arc_step_deg: float = 3.0) -> EngagementLines:
    """Entry / exit lines and engaged arcs of ``em`` on ``tool`` at the CL (see :class:`EngagementLines`).

    ``slice_height`` (mm) is the run's slice height, which gives each slice its band (the entry and exit
    lines run over it); without it, or for a slice off the engine's slice rule, the band is unknown and
    only the slice's arcs are drawn. An interval engaged all round (a plunge) has no entry or exit;
    only its arc (the whole circle) is drawn.
    """
    tip = em.position
    entry, exit_, arcs = [], [], []
    bands = _slice_bands(em, slice_height) if em.slices else []
    for s, band in zip(em.slices, bands):
        s: SliceEngagement
        for iv, (start, stop) in zip(s.intervals, em.machine_intervals(s)):
            span = stop - start
            n = max(1, math.ceil(span / arc_step_deg - 1e-9))
            pts = [_surface_point(tool, tip, start + span * k / n, s.z, s.radius) for k in range(n + 1)]
            arcs += list(zip(pts, pts[1:]))
            if span >= 360.0 - 1e-9 or band is None:
                continue
            entry += _generator(tool, tip, machine_from_immersion(iv.entry, em.feed_angle, em.spindle), band)
            exit_ += _generator(tool, tip, machine_from_immersion(iv.exit % 360.0, em.feed_angle, em.spindle), band)

    def arr(segs: list) -> np.ndarray:
        return np.array(segs, dtype=float).reshape(-1, 2, 3)

    return EngagementLines(arr(entry), arr(exit_), arr(arcs))


# -- a scene of one CL ------------------------------------------------------------------------------


@dataclass(frozen=True)
class CLScene:
    """Plain-array geometry of one CL (mm, machine frame, Z up).

    ``ipw`` is the workpiece's surface *without* the contact faces, ``contact`` the contact faces:
    together they are the whole IPW (split so a viewer can colour the contact faces without drawing
    two surfaces in the same place). ``tool`` is the tool solid at the CL. Meshes are not welded:
    each B-Rep face has its own vertices and exact normals. ``focus`` is the centre (mm) and radius
    (mm) of the region around the tool worth looking at; ``view_direction`` a unit vector from there
    towards a camera that sees the engaged side through the tool. ``info`` holds what is known about
    the CL (JSON-ready: numbers, strings, lists).
    """

    cl_index: int
    ipw: Mesh
    contact: Mesh
    tool: Mesh
    lines: EngagementLines
    focus: tuple[tuple[float, float, float], float]
    view_direction: tuple[float, float, float]
    info: dict = field(default_factory=dict)
    deflection: float = 0.0


def default_deflection(tool: MillingTool) -> float:
    """A display mesh deflection (mm): fine enough for the tool's corner radii, coarse enough to be quick."""
    return max(0.002, min(0.05, tool.radius / 100.0))


def _view_direction(em: EngagementMap) -> tuple[float, float, float]:
    """Camera direction: from the side opposite to the engaged arcs (weighted by span), turned 30°
    about the tool axis so that the entry and exit lines are not both on the tool's silhouette, and
    50° above (steep enough to see down into a slot)."""
    vx = vy = 0.0
    for s in em.slices:
        for a, b in em.machine_intervals(s):
            if b - a >= 360.0 - 1e-9:
                continue
            m = math.radians(0.5 * (a + b))
            w = math.radians(b - a)
            vx += w * math.cos(m)
            vy += w * math.sin(m)
    if math.hypot(vx, vy) < 1e-9:  # no engagement, or all round: look along the feed
        f = math.radians(em.feed_angle)
        vx, vy = math.cos(f), math.sin(f)
    az = math.atan2(vy, vx) + math.radians(30.0)
    el = math.radians(50.0)
    return (-math.cos(az) * math.cos(el), -math.sin(az) * math.cos(el), math.sin(el))


def _info(em: EngagementMap, tool: MillingTool, ipw_volume: float, contacts: list[ContactFace],
          deflection: float) -> dict:
    return {
        "cl_index": em.cl_index,
        "source": str(em.source),
        "operation": em.operation,
        "status": em.status.value,
        "reason": em.reason,
        "warnings": list(em.warnings),
        "tool": tool.label,
        "tool_kind": tool.kind,
        "tool_diameter_mm": tool.diameter,
        "spindle": em.spindle.value,
        "position_mm": list(em.position),
        "start_mm": list(em.start),
        "feed_mm_per_min": em.feed,
        "feed_angle_deg": em.feed_angle,
        "ae_mm": em.ae,
        "ap_mm": em.ap,
        "engaged_slices": len(em.engaged_slices),
        "removed_volume_mm3": em.removed_volume,
        "contact_area_mm2": em.contact_area,
        "shank_contact_area_mm2": em.shank_contact_area,
        # the same areas measured again on the faces shown (flute and shank zones together)
        "shown_contact_area_mm2": sum(c.area for c in contacts),
        "ipw_volume_mm3": ipw_volume,
        "mesh_deflection_mm": deflection,
        "units": "mm",
    }


def cl_scene(ipw: TopoDS_Shape | BRepEngine, tool: MillingTool, em: EngagementMap, *,
             slice_height: float | None = None, deflection: float | None = None,
             angle: float = DEFAULT_ANGLE) -> CLScene:
    """The scene of CL ``em`` on the workpiece after that CL (an engine, or its ``ipw``). Re-runs nothing.

    ``deflection`` (mm, default :func:`default_deflection`) bounds the meshes' distance to the exact
    surfaces. The contact faces are found again on the workpiece (:func:`contact_faces_at`) and shown
    whole: a face that runs from the flutes onto the shank is one red face. ``slice_height``: the
    run's slice spacing (mm), for the height of the entry / exit lines.
    """
    with _kernel_errors("building the 3D scene", em.cl_index):
        return _cl_scene(ipw, tool, em, slice_height, deflection, angle)


def _cl_scene(ipw, tool: MillingTool, em: EngagementMap, slice_height: float | None, deflection: float | None,
              angle: float) -> CLScene:
    shape = whole_ipw(ipw)
    deflection = deflection or default_deflection(tool)
    tip = em.position
    meshed = _meshed_copy(shape, deflection, angle).Shape()
    box = bounding_box(placed_tool(tool, tip))
    ipw_parts, contact_parts = [], []
    contacts: list[ContactFace] = []
    for f in faces(meshed):
        # one face at a time, so that the face itself (not pieces split by zone) is what is marked
        found = find_contact_faces([f], tool, tip) if boxes_overlap(bounding_box(f), box, gap=1e-6) else []
        contacts += found
        (contact_parts if found else ipw_parts).append(_face_mesh(f))
    seam = math.radians(em.feed_angle) + math.pi  # as the engine places it: the seam behind the tool
    tool_mesh = tessellate(placed_tool(tool, tip, seam), deflection, angle, weld=False)
    lines = engagement_lines(em, tool, slice_height)
    lo, hi = (np.asarray(c) for c in bounding_box(placed_tool(tool, tip, seam)))
    # look at the part of the tool that touches material (or its tip), not the whole shank
    top = min(tool.length, max(em.axial_range[1], 0.0) + tool.diameter)
    hi = np.minimum(hi, np.array([np.inf, np.inf, tip[2] + top]))
    ipw_mesh, contact = _snap([_concatenate(ipw_parts), _concatenate(contact_parts)])
    if not contact.is_empty:
        lo = np.minimum(lo, contact.vertices.min(axis=0))
        hi = np.maximum(hi, contact.vertices.max(axis=0))
    center = 0.5 * (lo + hi)
    radius = float(max(0.5 * np.linalg.norm(hi - lo), tool.diameter)) * 1.5
    info = _info(em, tool, volume(shape), contacts, deflection)
    return CLScene(
        cl_index=em.cl_index, ipw=ipw_mesh, contact=contact, tool=tool_mesh, lines=lines,
        focus=(tuple(float(x) for x in center), radius), view_direction=_view_direction(em),
        info=info, deflection=deflection,
    )


__all__ = [
    "CLScene", "EngagementLines", "Mesh", "Replay", "check_cl_index", "cl_scene", "contact_faces_at",
    "default_deflection",
    "engagement_lines", "export_ipw", "replay", "tessellate", "whole_ipw",
]
