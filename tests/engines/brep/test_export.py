"""Exports of the workpiece and the plain-array scene of one CL.

Files read back with the same solid; meshes close, point outward and stay within their deflection of
the exact volume; contact faces, entry / exit lines and arcs lie where the engine says the tool
touches material.
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import pytest
import trimesh

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep import budget as budget_mod
from fusioncut.engines.brep import export as export_module
from fusioncut.engines.brep.budget import KernelBudgetExceeded
from fusioncut.engines.brep.export import (
    CLScene, cl_scene, contact_faces_at, engagement_lines, export_ipw, replay, tessellate, whole_ipw,
)
from fusioncut.engines.brep.occ import area, bounding_box, compound, read_brep, solids, volume
from fusioncut.engines.brep.stock import stock_solid
from fusioncut.engines.brep.sweep import placed_tool
from fusioncut.errors import InputError
from fusioncut.io.mesh import read_stl
from fusioncut.model import (AngleInterval, BallEndMill, BoxStock, CLStatus, CylinderStock, EngagementMap,
                             FlatEndMill, LinearMove, SliceEngagement, SpindleDirection, Toolpath)
from fusioncut.model.angles import machine_from_immersion
from fusioncut.model.stock import SolidStock

TOOL = FlatEndMill(6.0, 15.0, number=1)
STOCK = BoxStock((0.0, 0.0, -10.0), (30.0, 20.0, 0.0))
SLICE = 0.5
# two side passes, then a full slot along +x at y=12 that stops inside the block at x=20
PTS = [(-5.0, 5.0, -2.0), (12.0, 5.0, -2.0), (12.0, 9.0, -2.0), (-5.0, 9.0, -2.0), (-5.0, 12.0, -3.0),
       (20.0, 12.0, -3.0)]
SLOT_CL = 4


def _toolpath() -> Toolpath:
    return Toolpath(tuple(LinearMove(a, b, feed=600.0, tool=1) for a, b in zip(PTS, PTS[1:])), {1: TOOL})


@pytest.fixture(scope="module")
def state():
    return replay(_toolpath(), STOCK, SLOT_CL, EngineOptions(slice_height=SLICE))


def _closed_outward(mesh) -> trimesh.Trimesh:
    tm = trimesh.Trimesh(mesh.vertices, mesh.triangles, process=False)
    assert tm.is_watertight
    assert tm.is_winding_consistent
    assert tm.volume > 0  # consistent *and* outward
    return tm


# -- tessellation ---------------------------------------------------------------------------------


def test_box_mesh_is_exact_and_outward():
    box = stock_solid(STOCK)
    mesh = tessellate(box, 0.01)
    vertices, triangles = mesh
    assert vertices.dtype == np.float64 and vertices.shape[1] == 3
    assert np.issubdtype(triangles.dtype, np.integer) and triangles.shape[1] == 3
    tm = _closed_outward(mesh)
    assert len(mesh.vertices) == 8  # welded: the corners are shared by the faces
    assert tm.volume == pytest.approx(STOCK.volume, rel=1e-12)  # planar faces: no chord error
    # every facet normal points away from the box centre
    centre = np.array([15.0, 10.0, -5.0])
    assert (np.einsum("ij,ij->i", tm.face_normals, tm.triangles_center - centre) > 0).all()


@pytest.mark.parametrize("deflection", [0.05, 0.005])
@pytest.mark.parametrize("shape_name", ["cylinder", "ball tool"])
def test_curved_mesh_volume_within_deflection(shape_name, deflection):
    shape = (stock_solid(CylinderStock((1.0, 2.0, -5.0), 7.0, 12.0)) if shape_name == "cylinder"
             else placed_tool(BallEndMill(6.0, 12.0), (3.0, -4.0, 1.0)))
    mesh = tessellate(shape, deflection, angle=0.5)
    tm = _closed_outward(mesh)
    # every point of the exact surface is within the deflection of the mesh: the volumes differ by at
    # most deflection x area; a convex solid's inscribed mesh is smaller
    exact = volume(shape)
    assert exact - deflection * area(shape) <= tm.volume <= exact * (1 + 1e-12)
    # the bound is not vacuous: the finer mesh is the closer one
    assert abs(tm.volume - exact) < 0.02 * exact


def test_tessellate_leaves_the_shape_unmeshed():
    from OCP.BRep import BRep_Tool
    from OCP.TopLoc import TopLoc_Location

    from fusioncut.engines.brep.occ import faces

    box = stock_solid(STOCK)
    tessellate(box, 0.1)
    assert all(BRep_Tool.Triangulation_s(f, TopLoc_Location()) is None for f in faces(box))


def test_cells_side_by_side_become_one_solid():
    # an engine may keep the workpiece as columns sharing walls: they are joined before export
    left = stock_solid(BoxStock((0.0, 0.0, 0.0), (10.0, 10.0, 5.0)))
    right = stock_solid(BoxStock((10.0, 0.0, 0.0), (25.0, 10.0, 5.0)))
    cells = compound([left, right])
    joined = whole_ipw(cells)
    assert len(solids(joined)) == 1
    assert volume(joined) == pytest.approx(1250.0, rel=1e-9)
    tm = _closed_outward(tessellate(joined, 0.01))
    assert tm.volume == pytest.approx(1250.0, rel=1e-9)
    # the raw cells would leave the shared wall inside the mesh: edges used by four triangles
    raw = tessellate(cells, 0.01)
    assert not trimesh.Trimesh(raw.vertices, raw.triangles, process=False).is_watertight


def test_ipw_mesh_closes(state):
    shape = whole_ipw(state.engine)
    d = 0.01
    tm = _closed_outward(tessellate(shape, d))
    assert abs(tm.volume - state.engine.ipw_volume) <= d * area(shape)


# -- files ----------------------------------------------------------------------------------------


def test_step_reads_back_the_same_solid(state, tmp_path):
    path = tmp_path / "ipw.step"
    assert export_ipw(state.engine, path) == "STEP"
    back = stock_solid(SolidStock(path))
    assert volume(back) == pytest.approx(state.engine.ipw_volume, rel=1e-6)
    lo, hi = bounding_box(back)
    assert np.allclose(lo, STOCK.minimum, atol=1e-5) and np.allclose(hi, STOCK.maximum, atol=1e-5)


def test_brep_reads_back_the_same_solid(state, tmp_path):
    path = tmp_path / "ipw.brep"
    assert export_ipw(state.engine.ipw, path) == "BREP"
    # OCCT's own format keeps every double: the very same solid
    assert volume(read_brep(str(path))) == pytest.approx(volume(whole_ipw(state.engine)), rel=1e-12)


@pytest.mark.parametrize("deflection", [0.05, 0.01])
def test_stl_is_watertight_and_within_deflection(state, tmp_path, deflection):
    path = tmp_path / "ipw.stl"
    assert export_ipw(state.engine, path, deflection=deflection) == "STL"
    mesh = trimesh.load(path)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    # facets lie within `deflection` of the exact surface: |V_mesh - V| <= deflection x area
    shape = whole_ipw(state.engine)
    assert abs(mesh.volume - volume(shape)) <= deflection * area(shape)


def test_export_errors(state, tmp_path):
    with pytest.raises(InputError, match="unsupported workpiece format"):
        export_ipw(state.engine, tmp_path / "ipw.obj")
    with pytest.raises(InputError, match="output folder does not exist"):
        export_ipw(state.engine, tmp_path / "missing" / "ipw.step")


@pytest.mark.parametrize("suffix", [".brep", ".stl"])
def test_an_export_under_a_budget_writes_the_same_file_from_the_kernels_child(state, tmp_path, suffix):
    """The shape crosses to the child as binary BRep, which keeps every double but not a zero's sign
    in a direction (-0 comes back 0): the same numbers, the same mesh."""
    here, there = tmp_path / f"here{suffix}", tmp_path / f"there{suffix}"
    export_ipw(state.engine, here)
    export_ipw(state.engine, there, budget_s=60.0)
    if suffix == ".brep":
        def numbers(path):
            return ["0" if t == "-0" else t for t in path.read_text().split()]
        assert numbers(there) == numbers(here)
    else:
        assert np.array_equal(read_stl(there), read_stl(here))


def test_an_export_past_its_budget_is_killed_and_writes_nothing(state, tmp_path, monkeypatch):
    """A join that hangs (stood in for by a sleep in the child, forked after the patch) is killed at
    the budget: KernelBudgetExceeded names the file, and no file is left."""
    budget_mod.stop_worker()  # the next guarded call forks a child that has the patch
    monkeypatch.setattr(export_module, "whole_ipw", lambda ipw: time.sleep(60))
    t0 = time.monotonic()
    with pytest.raises(KernelBudgetExceeded, match="writing ipw.step ran past the kernel budget of 0.5 s"):
        export_ipw(state.engine, tmp_path / "ipw.step", budget_s=0.5)
    assert time.monotonic() - t0 < 10 and not (tmp_path / "ipw.step").exists()
    monkeypatch.undo()
    budget_mod.stop_worker()


# -- replay and contact faces -------------------------------------------------------------------------


def test_replay_stops_at_the_cl(state):
    m = state.map
    assert m.cl_index == SLOT_CL and state.cl_count == len(PTS) - 1
    assert m.position == PTS[-1] and state.tool is TOOL
    assert m.status == CLStatus.ENGAGED
    assert state.engine.removed_total == pytest.approx(STOCK.volume - state.engine.ipw_volume,
                                                       abs=1e-6 * STOCK.volume)


def test_replay_rejects_a_cl_out_of_range():
    with pytest.raises(InputError, match=r"CL 5 is out of range.*0\.\.4"):
        replay(_toolpath(), STOCK, 5)


def test_recomputed_contact_faces_are_the_engines(state):
    m = state.map
    found = contact_faces_at(state.engine, TOOL, m.position)
    assert found and all(c.surface.zone == "flute" for c in found)
    assert sum(c.area for c in found) == pytest.approx(m.contact_area, rel=1e-9)
    # the slot's end: half the cylinder, 3 mm deep
    assert m.contact_area == pytest.approx(math.pi * TOOL.radius * 3.0, rel=1e-9)


# -- entry / exit lines -----------------------------------------------------------------------------


def _map(intervals, spindle=SpindleDirection.CW, feed_angle=0.0, radius=3.0, zs=(0.25, 0.75)) -> EngagementMap:
    slices = tuple(SliceEngagement(z=z, z_machine=z, radius=radius,
                                   intervals=tuple(AngleInterval(a, b) for a, b in intervals)) for z in zs)
    return EngagementMap(cl_index=0, position=(10.0, 20.0, 0.0), start=(0.0, 20.0, 0.0), tool="T1",
                         spindle=spindle, feed_angle=feed_angle, status=CLStatus.ENGAGED, slices=slices,
                         axial_range=(0.0, 1.0))


def _angles(points: np.ndarray, centre=(10.0, 20.0)) -> np.ndarray:
    return np.degrees(np.arctan2(points[..., 1] - centre[1], points[..., 0] - centre[0])) % 360.0


def _radii(points: np.ndarray, centre=(10.0, 20.0)) -> np.ndarray:
    return np.hypot(points[..., 0] - centre[0], points[..., 1] - centre[1])


@pytest.mark.parametrize("spindle, entry_deg, exit_deg", [
    # up-milling, feed +X: a clockwise tooth enters at +Y (immersion 0) and leaves 60° later, at 30°
    (SpindleDirection.CW, 90.0, 30.0),
    # a counter-clockwise spindle mirrors the frame: enters at -Y, leaves at 330°
    (SpindleDirection.CCW, 270.0, 330.0),
])
def test_entry_and_exit_lines_on_the_tool(spindle, entry_deg, exit_deg):
    m = _map([(0.0, 60.0)], spindle)
    assert machine_from_immersion(0.0, 0.0, spindle) == pytest.approx(entry_deg)
    lines = engagement_lines(m, TOOL, slice_height=0.5)
    assert len(lines.entry) and len(lines.exit) == len(lines.entry)
    assert np.allclose(_angles(lines.entry), entry_deg) and np.allclose(_angles(lines.exit), exit_deg)
    for segs in (lines.entry, lines.exit, lines.arcs):
        assert np.allclose(_radii(segs), TOOL.radius)  # on the tool's cylinder
    # the generators of both slices run over their bands and join: 0 .. 1 mm above the tip
    zs = lines.entry[..., 2]
    assert zs.min() == pytest.approx(0.0) and zs.max() == pytest.approx(1.0)
    # the arcs span the interval at each slice height, counter-clockwise from exit to entry (CW) or
    # entry to exit (CCW), in steps of at most 3°
    a = _angles(lines.arcs)
    lo, hi = sorted((entry_deg, exit_deg))
    assert a.min() == pytest.approx(lo) and a.max() == pytest.approx(hi)
    assert set(np.round(lines.arcs[..., 2].ravel(), 9)) == {0.25, 0.75}
    step = np.linalg.norm(lines.arcs[:, 1] - lines.arcs[:, 0], axis=1)
    assert step.max() <= 2 * TOOL.radius * math.sin(math.radians(1.5)) + 1e-12


def test_full_round_has_arcs_but_no_entry_or_exit():
    lines = engagement_lines(_map([(0.0, 360.0)]), TOOL, slice_height=0.5)
    assert len(lines.entry) == 0 and len(lines.exit) == 0
    a = np.sort(_angles(lines.arcs[:, 0]))
    assert len(a) >= 120 and np.diff(a).max() <= 3.0 + 1e-9  # a whole circle per slice


def test_lines_follow_a_ball_nose():
    ball = BallEndMill(6.0, 12.0)
    m = _map([(30.0, 150.0)], radius=ball.profile().radius_at(0.25), zs=(0.25,))
    lines = engagement_lines(m, ball)
    pts = np.concatenate([lines.entry, lines.exit]).reshape(-1, 3)
    expected = [ball.profile().radius_at(z) for z in pts[:, 2]]
    assert np.allclose(_radii(pts), expected, atol=1e-12)  # on the sphere, not on a cylinder
    assert np.allclose(_radii(lines.arcs), m.slices[0].radius)


def test_no_slices_no_lines():
    m = dataclasses.replace(_map([]), slices=(), status=CLStatus.AIR)
    lines = engagement_lines(m, TOOL)
    assert lines.entry.shape == (0, 2, 3) and lines.arcs.shape == (0, 2, 3)


# -- the scene of one CL ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def scene(state) -> CLScene:
    return cl_scene(state.engine, TOOL, state.map, slice_height=SLICE, deflection=0.01)


def test_scene_is_plain_arrays(scene):
    def check(value):
        assert not type(value).__module__.startswith("OCP"), type(value)
        if dataclasses.is_dataclass(value):
            for f in dataclasses.fields(value):
                check(getattr(value, f.name))
        elif isinstance(value, (tuple, list)):
            for v in value:
                check(v)
        elif isinstance(value, dict):
            for v in value.values():
                check(v)

    check(scene)
    assert scene.info["cl_index"] == SLOT_CL and scene.info["status"] == "engaged"


def test_scene_surfaces_make_up_the_workpiece(state, scene):
    # IPW without the contact faces + the contact faces = the whole workpiece, closed and outward
    both = scene.ipw.signed_volume + scene.contact.signed_volume
    shape = whole_ipw(state.engine)
    assert abs(both - volume(shape)) <= scene.deflection * area(shape)
    assert scene.info["ipw_volume_mm3"] == pytest.approx(state.engine.ipw_volume, rel=1e-6)


def test_scene_contact_faces_lie_on_the_tool(state, scene):
    m = state.map
    v = scene.contact.vertices
    assert len(v) > 0
    assert np.allclose(_radii(v, m.position[:2]), TOOL.radius, atol=1e-6)
    assert v[:, 2].min() >= m.position[2] - 1e-6 and v[:, 2].max() <= 0.0 + 1e-6
    # chords of a concave face: a little less area than the exact face, never more
    assert m.contact_area * (1 - 0.01) <= scene.contact.area <= m.contact_area * (1 + 1e-9)
    assert scene.info["shown_contact_area_mm2"] == pytest.approx(m.contact_area, rel=1e-9)
    # and no facet of the rest lies on the tool's cylinder (corners on it, normal horizontal)
    corners = scene.ipw.vertices[scene.ipw.triangles]
    on_circle = (np.abs(_radii(corners, m.position[:2]) - TOOL.radius) < 1e-6).all(axis=1)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    vertical_facet = np.abs(normals[:, 2]) < 0.1 * np.linalg.norm(normals, axis=1)
    assert on_circle.any()  # the slot's floor and the top face end on the circle ...
    assert not (on_circle & vertical_facet).any()  # ... but no wall facet of the cylinder is left


def test_scene_tool_and_lines_at_the_cl(state, scene):
    x, y, z = state.map.position
    lo, hi = scene.tool.vertices.min(axis=0), scene.tool.vertices.max(axis=0)
    assert np.allclose(lo, (x - 3, y - 3, z), atol=0.02) and np.allclose(hi, (x + 3, y + 3, z + TOOL.length), atol=0.02)
    assert scene.tool.signed_volume == pytest.approx(volume(placed_tool(TOOL, state.map.position)), rel=0.01)
    # a full slot along +X with a clockwise spindle: the tooth enters at +Y and leaves at -Y
    assert np.allclose(scene.lines.entry[..., 1], y + 3) and np.allclose(scene.lines.exit[..., 1], y - 3)
    assert scene.lines.entry[..., 2].min() == pytest.approx(z) and scene.lines.entry[..., 2].max() == pytest.approx(0.0)
    # the camera looks from behind the tool (the material is ahead of it) and from above
    d = np.array(scene.view_direction)
    assert np.linalg.norm(d) == pytest.approx(1.0) and d[0] < -0.5 and d[2] > 0.3
    centre, radius = scene.focus
    assert math.hypot(centre[0] - x, centre[1] - y) < radius


def test_scene_normals_point_out_with_the_winding(scene):
    for mesh in (scene.ipw, scene.contact, scene.tool):
        corners = mesh.vertices[mesh.triangles]
        facet = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        facet /= np.linalg.norm(facet, axis=1)[:, None]
        assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0)
        # the exact surface normals at a facet's corners lean the way its winding says (outward)
        assert (np.einsum("ij,ij->i", facet, mesh.normals[mesh.triangles].mean(axis=1)) > 0.9).all()


def test_kernel_failures_become_geometry_errors(state, tmp_path, monkeypatch):
    from OCP.TopoDS import TopoDS_Shape

    from fusioncut.engines.brep import export
    from fusioncut.errors import GeometryError

    with pytest.raises(GeometryError, match="no workpiece"):
        cl_scene(TopoDS_Shape(), TOOL, state.map)

    def broken(*args):
        raise RuntimeError("Standard_Failure")

    monkeypatch.setattr(export, "write_step", broken)
    with pytest.raises(GeometryError, match="writing ipw.step failed in the geometry kernel: Standard_Failure"):
        export_ipw(state.engine, tmp_path / "ipw.step")
