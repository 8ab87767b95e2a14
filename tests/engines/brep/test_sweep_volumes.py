"""Swept volumes against closed forms: vol(B ⊕ d) = vol(B) + |d| * area(projection of B on the plane ⊥ d)."""
from __future__ import annotations

import math

import pytest

from fusioncut.engines.brep import planar
from fusioncut.engines.brep.occ import area, volume
from fusioncut.engines.brep.sweep import (cylinder_region_outline, full_section, sampled_ridge, swept_volume,
                                         tool_solid)
from fusioncut.model import (AptCutter, AptParameters, ArcMove, BallEndMill, BullNoseEndMill, ChamferMill,
                             FlatEndMill, LinearMove, TaperedEndMill)

TOOLS = {
    "flat": FlatEndMill(12, 30),
    "ball": BallEndMill(10, 20),
    "bullnose": BullNoseEndMill(12, 30, corner_radius=2),
    "tapered": TaperedEndMill(6, 20, taper_angle=5),
    "chamfer": ChamferMill(10, 10, taper_angle=45),
    "chamfer-flat-tip": ChamferMill(10, 10, tip_diameter=2, taper_angle=30),
    "apt": AptCutter(10, 20, apt_parameters=AptParameters(10, 2, 3, 2, 0, 0, 20)),
}
REL = 1e-6


def profile_section_area(tool) -> float:
    """Area of the full axial section by Simpson's rule on the profile radius (independent of OCCT)."""
    prof = tool.profile()
    n = 20000
    h = prof.height / n
    vals = [prof.radius_at(k * h) for k in range(n + 1)]
    # the profile radius has kinks only at segment ends; integrate piecewise exactly for lines
    return 2 * h / 3 * (vals[0] + vals[-1] + 4 * sum(vals[1:-1:2]) + 2 * sum(vals[2:-1:2]))


def max_radius(tool) -> float:
    return max(max(s.start[0], s.end[0]) for s in tool.profile().segments)


@pytest.mark.parametrize("name", TOOLS)
@pytest.mark.parametrize("d", [(20.0, 5.0, 0.0), (-3.0, 0.5, 0.0)])
def test_horizontal_line(name, d):
    tool = TOOLS[name]
    sv = swept_volume(tool, LinearMove((1, 2, 3), (1 + d[0], 2 + d[1], 3)))
    assert sv.method == "exact"
    section = area(full_section(tool.profile(), (0, 0, 0), (1, 0, 0)))
    assert section == pytest.approx(profile_section_area(tool), rel=1e-5)
    expected = volume(tool_solid(tool)) + math.hypot(*d) * section
    assert volume(sv.shape) == pytest.approx(expected, rel=REL)


@pytest.mark.parametrize("name", TOOLS)
@pytest.mark.parametrize("dz", [-7.0, 4.0])
def test_plunge_and_retract(name, dz):
    tool = TOOLS[name]
    sv = swept_volume(tool, LinearMove((0, 0, 0), (0, 0, dz)))
    assert sv.method == "exact"
    expected = volume(tool_solid(tool)) + abs(dz) * math.pi * max_radius(tool) ** 2
    assert volume(sv.shape) == pytest.approx(expected, rel=REL)


def _projected_area(tool, v) -> float:
    """Closed-form projection along v of a cylinder (flat) or a hemisphere-capped cylinder (ball)."""
    R, H = tool.radius, tool.length
    g = math.acos(abs(v[2]) / math.sqrt(sum(c * c for c in v)))
    if tool.kind == "flat":
        return math.pi * R * R * abs(math.cos(g)) + 2 * R * H * math.sin(g)
    return math.pi * R * R / 2 + 2 * R * (H - R) * math.sin(g) + math.pi * R * R * abs(math.cos(g)) / 2


@pytest.mark.parametrize("name", ["flat", "ball"])
# the short chords are a helical entry's: copies of the tool nearly coincide
@pytest.mark.parametrize("v", [(10.0, 3.0, -4.0), (-2.0, 1.0, 6.0), (1.0, 0.0, -20.0), (0.55, 0.2, -0.05),
                               (-0.3, 0.4, 0.02)])
def test_ramp_exact(name, v):
    from OCP.BRepCheck import BRepCheck_Analyzer

    tool = TOOLS[name]
    sv = swept_volume(tool, LinearMove((0, 0, 0), v))
    assert sv.method == "exact"
    assert BRepCheck_Analyzer(sv.shape).IsValid()
    L = math.sqrt(sum(c * c for c in v))
    expected = volume(tool_solid(tool)) + L * _projected_area(tool, v)
    assert volume(sv.shape) == pytest.approx(expected, rel=REL)


@pytest.mark.parametrize("name", ["bullnose", "tapered", "chamfer"])
def test_ramp_of_other_tools_falls_back_to_sampled_and_says_so(name):
    tool = TOOLS[name]
    sv = swept_volume(tool, LinearMove((0, 0, 0), (6.0, 2.0, -2.0)))
    assert sv.method == "sampled"
    # copies inside the true sweep: never more than the convex bound, and more than the end tools alone
    assert volume(sv.shape) > volume(tool_solid(tool))


@pytest.mark.parametrize("name", TOOLS)
@pytest.mark.parametrize("clockwise", [False, True])
def test_xy_arc_is_revolved_section_plus_end_caps(name, clockwise):
    tool = TOOLS[name]
    rho = 20.0
    end = (0.0, -rho if clockwise else rho, -1.0)
    arc = ArcMove((rho, 0.0, -1.0), end, center=(0.0, 0.0, -1.0), clockwise=clockwise)
    sv = swept_volume(tool, arc)
    section = area(full_section(tool.profile(), (0, 0, 0), (1, 0, 0)))
    # Pappus: the symmetric section's centroid lies on the arc; the two half tools make one tool
    expected = volume(tool_solid(tool)) + abs(arc.sweep) * rho * section
    assert volume(sv.shape) == pytest.approx(expected, rel=REL)


def test_arc_tighter_than_the_tool_matches_the_slice_wise_area():
    """Arc radius 2 < tool radius 6: the section is clipped at the arc axis; each slice of the sweep is
    a disk of radius rho + R over the swept angle plus the two tool disks (closed form for a flat mill)."""
    tool = TOOLS["flat"]
    R, rho, H = 6.0, 2.0, tool.length
    arc = ArcMove((rho, 0, 0), (0, rho, 0), center=(0, 0, 0))  # quarter circle, CCW
    sv = swept_volume(tool, arc)
    # slice area: union of disk(P0,R), disk(P1,R) and the annular sector 0..90° of radii [0, rho+R]
    # computed independently on a fine grid
    n = 1200
    ext = rho + R
    step = 2 * ext / n
    inside = 0
    for i in range(n):
        x = -ext + (i + 0.5) * step
        for j in range(n):
            y = -ext + (j + 0.5) * step
            r = math.hypot(x, y)
            a = math.atan2(y, x)
            if (math.hypot(x - rho, y) <= R or math.hypot(x, y - rho) <= R
                    or (0 <= a <= math.pi / 2 and r <= rho + R)):
                inside += 1
    grid_area = inside * step * step
    assert volume(sv.shape) / H == pytest.approx(grid_area, rel=2e-3)


@pytest.mark.parametrize("name", ["ball", "bullnose", "tapered", "apt"])
def test_lines_and_arcs_are_sewn_without_a_boolean(name, monkeypatch):
    """The pieces of a line's or a wide arc's sweep meet in whole faces: their outer faces close into
    one valid solid of the closed-form volume, with faces on one surface merged (a ball's line: 8
    faces), and the glued fuse is never needed."""
    from OCP.BRepCheck import BRepCheck_Analyzer

    from fusioncut.engines.brep import sweep as sweep_module
    from fusioncut.engines.brep.occ import count_faces

    def no_fuse(*args, **kwargs):
        raise AssertionError("the sweep fell back to a fuse")

    monkeypatch.setattr(sweep_module, "fuse_all", no_fuse)
    tool = TOOLS[name]
    section = area(full_section(tool.profile(), (0, 0, 0), (1, 0, 0)))
    line = swept_volume(tool, LinearMove((1, 2, 3), (1.3, 2.9, 3)))
    arc = ArcMove((20.0, 0.0, -1.0), (0.0, -20.0, -1.0), center=(0.0, 0.0, -1.0), clockwise=True)
    ring = swept_volume(tool, arc)
    for sv, travel in ((line, math.hypot(0.3, 0.9)), (ring, 20.0 * math.pi / 2)):
        assert BRepCheck_Analyzer(sv.shape).IsValid()
        assert volume(sv.shape) == pytest.approx(volume(tool_solid(tool)) + travel * section, rel=REL)
    if name == "ball":
        assert count_faces(line.shape) == 8


@pytest.mark.parametrize("name", ["ball", "bullnose", "tapered", "chamfer", "apt"])
@pytest.mark.parametrize("d", [(0.6, 0.8, 0.0), (-20.0, 5.0, 0.0)])
def test_a_line_open_at_its_start_leaves_out_the_tools_back_half_only(name, d):
    """Closed form: the section swept over the line plus the tool's front half; the open sweep lies
    inside the whole one, and what it leaves out lies in the tool at the start."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut

    from fusioncut.engines.brep.sweep import placed_tool

    tool = TOOLS[name]
    move = LinearMove((1, 2, 3), (1 + d[0], 2 + d[1], 3))
    whole, open_ = swept_volume(tool, move), swept_volume(tool, move, open_start=True)
    assert open_.method == "exact"
    section = area(full_section(tool.profile(), (0, 0, 0), (1, 0, 0)))
    assert volume(open_.shape) == pytest.approx(volume(tool_solid(tool)) / 2 + math.hypot(*d) * section, rel=REL)
    assert volume(BRepAlgoAPI_Cut(open_.shape, whole.shape).Shape()) == pytest.approx(0.0, abs=1e-6)
    left_out = BRepAlgoAPI_Cut(whole.shape, open_.shape).Shape()
    assert volume(BRepAlgoAPI_Cut(left_out, placed_tool(tool, move.start)).Shape()) == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("move", [LinearMove((3.0, 4.0, -2.0), (4.0, 4.0, -2.0)),
                                  LinearMove((3.0, 4.0, -2.0), (3.0, 4.0, -6.0)),
                                  ArcMove((3.0, 4.0, -2.0), (7.0, 8.0, -2.0), center=(7.0, 4.0, -2.0))])
def test_a_motion_repeated_elsewhere_gets_its_sweep_moved_and_unshared(move):
    """Non-cylindrical tools' sweeps are built once per relative motion and copied into place: the
    copy is the sweep built where the motion is (volume, box), and shares no face with the sweep
    of the same motion elsewhere."""
    from fusioncut.engines.brep.occ import bounding_box, faces
    from fusioncut.engines.brep.sweep import _exact_sweep

    tool = BallEndMill(6.0, 20.0)
    here = swept_volume(tool, move, seam=1.0)
    there = swept_volume(tool, move.translated((10.0, -5.0, 1.0)), seam=1.0)
    built = _exact_sweep(tool, move, 1.0, None, False)
    assert here.method == there.method == "exact"
    assert volume(here.shape) == pytest.approx(volume(built), rel=1e-9)
    for a, b in zip(bounding_box(here.shape), bounding_box(built)):
        assert a == pytest.approx(b, abs=1e-7)
    for a, b in zip(bounding_box(there.shape), bounding_box(here.shape)):
        assert [u - v for u, v in zip(a, b)] == pytest.approx([10.0, -5.0, 1.0], abs=1e-7)
    assert volume(there.shape) == pytest.approx(volume(here.shape), rel=1e-9)
    theirs = list(faces(there.shape))
    assert not any(f.IsPartner(g) for f in faces(here.shape) for g in theirs)


def test_tool_copies_whose_sides_nearly_coincide_still_make_the_whole_sweep():
    """A ramp 2.5 mm up and 1e-6 mm sideways (a case hypothesis found): the published method's tool
    copies have nearly coincident side faces, which the kernel fused into 3e-5 mm³ without an
    error, and a tool solid shared by the copies made the next call differ. A near-vertical union
    of copies is the tool stretched up (closed form), on every call."""
    tool = BullNoseEndMill(10, 20, corner_radius=2)
    dz = 2.5133576507673734
    move = LinearMove((0.0, -12.351750246432578, 0.0), (0.0, -12.351749246432579, dz))
    stretched = volume(tool_solid(tool)) + math.pi * 5.0 ** 2 * dz
    for _ in range(2):
        sweep = swept_volume(tool, move)
        assert sweep.method == "sampled"
        assert volume(sweep.shape) == pytest.approx(stretched, rel=1e-6)


@pytest.mark.parametrize("radius", [1.0, 3.0])
@pytest.mark.parametrize("tool", [FlatEndMill(6, 15), BallEndMill(6, 15)])
def test_an_arc_too_short_for_the_kernel_sweeps_as_its_chord(tool, radius):
    """4e-10 rad on a 1 or 3 mm radius (found by hypothesis): the kernel makes no circle through
    three points that close, nor a prism along the 1.2e-9 mm chord; the sweep, and the layers'
    cutting region, are the tool's at the end."""
    a = 4.1427845113545693e-10
    move = ArcMove((0.0, -radius, 0.0), (radius * math.sin(a), -radius * math.cos(a), 0.0), center=(0.0, 0.0, 0.0))
    assert volume(swept_volume(tool, move).shape) == pytest.approx(volume(tool_solid(tool)), rel=1e-6)
    assert planar.region_area(cylinder_region_outline(3.0, move)) == pytest.approx(math.pi * 9.0, rel=1e-6)


@pytest.mark.parametrize("tool, half_angle", [(ChamferMill(diameter=12.5, flute_length=16, taper_angle=22.5), 22.5),
                                              (BallEndMill(6, 20), None)])
def test_the_sampled_sweeps_ridge_between_copies(tool, half_angle):
    """Copies R/4 apart along a 4 mm, 0.84 mm deep ramp (3 intervals, 4/3 mm apart across the
    floor): a V-bit's ridge between two is where its cone reaches 2/3 mm, a ball's its scallop."""
    move = LinearMove((36, 0, -0.38), (40, 0, -1.22), feed=600)
    half = 0.5 * 4 / math.ceil(move.length / (tool.radius / 4))
    if half_angle is not None:
        expected = half / math.tan(math.radians(half_angle))
    else:
        expected = tool.radius - math.sqrt(tool.radius**2 - half**2)
    assert sampled_ridge(tool, move) == pytest.approx(expected, abs=1e-9)
    assert sampled_ridge(tool, LinearMove((0, 0, 0), (0, 0, -2), feed=600)) == 0.0  # a plunge's copies stack
