"""Reduced necks and drills in the tool's axial profile (issue 23, item 7)."""
from __future__ import annotations

import math

import pytest

from fusioncut.errors import ToolDefinitionError
from fusioncut.model.tools import ChamferMill, Drill, FlatEndMill, MillingTool, ProfileLine


def revolved_volume(tool: MillingTool) -> float:
    """Volume (mm^3) of the solid the profile revolves into: by Green's theorem the region's
    ``2*pi * integral r dA`` is ``pi * (closed integral of r^2 dz)`` along the outline (walked
    counter-clockwise in the (r, z) plane; the axis adds nothing since r = 0 there)."""
    total = 0.0
    for s in tool.profile().segments:
        assert isinstance(s, ProfileLine)
        (r0, z0), (r1, z1) = s.start, s.end
        total += (z1 - z0) * (r0 * r0 + r0 * r1 + r1 * r1) / 3
    return math.pi * total


def cylinder(d: float, h: float) -> float:
    return math.pi * d * d / 4 * h


# coordinates as posts and libraries write them: exact, 3 and 4 decimals
@pytest.mark.parametrize("d, lcf, neck, shoulder, shank, oal", [
    (4.0, 12.0, 4.0, 18.0, 6.0, 40.0),  # the cutter: 4 mm neck to 18 mm, 6 mm shank
    (3.175, 9.525, 2.9, 22.0, 3.175, 38.1),  # reduced neck below the cutting diameter
    (6.35, 19.05, 5.842, 31.75, 6.35, 50.8),
    (2.654, 8.113, 2.4, 14.287, 3.175, 38.0),
    (1.5875, 4.7625, 1.4224, 12.7, 3.175, 38.1),
])
def test_neck_profile_is_a_stack_of_cylinders(d, lcf, neck, shoulder, shank, oal):
    tool = FlatEndMill(d, lcf, neck_diameter=neck, shoulder_length=shoulder, shank_diameter=shank,
                       overall_length=oal)
    expected = cylinder(d, lcf) + cylinder(neck, shoulder - lcf) + cylinder(shank, oal - shoulder)
    assert revolved_volume(tool) == pytest.approx(expected, rel=1e-12)
    prof = tool.profile()
    assert prof.radius_at(0.5 * (lcf + shoulder)) == pytest.approx(neck / 2)
    assert prof.radius_at(0.5 * (shoulder + oal)) == pytest.approx(shank / 2)
    # the neck does not cut: everything above the flutes is the shank zone
    assert all(s.zone == "shank" for s in prof.segments if min(s.start[1], s.end[1]) >= lcf - 1e-12)
    assert all(s.zone == "flute" for s in prof.segments if max(s.start[1], s.end[1]) <= lcf + 1e-12
               and s.start[1] != s.end[1])


def test_neck_defaults_and_refusals():
    # without a neck diameter the neck keeps the cutting diameter up to the shoulder
    plain = FlatEndMill(4, 12, shoulder_length=18, shank_diameter=6, overall_length=40)
    assert plain.profile().radius_at(15) == pytest.approx(2.0)
    assert revolved_volume(plain) == pytest.approx(cylinder(4, 18) + cylinder(6, 22), rel=1e-12)
    # the default overall length reaches at least the shoulder
    long_neck = FlatEndMill(2, 4, neck_diameter=1.8, shoulder_length=30)
    assert long_neck.length == 30 and long_neck.profile().height == 30
    with pytest.raises(ToolDefinitionError, match="shoulder length 10 mm must exceed the flute length 12"):
        FlatEndMill(4, 12, neck_diameter=3.8, shoulder_length=10)
    with pytest.raises(ToolDefinitionError, match="needs the shoulder length"):
        FlatEndMill(4, 12, neck_diameter=3.8)
    with pytest.raises(ToolDefinitionError, match="overall length shorter than the shoulder"):
        FlatEndMill(4, 12, neck_diameter=3.8, shoulder_length=30, overall_length=25)
    with pytest.raises(ToolDefinitionError, match="neck diameter must be > 0"):
        FlatEndMill(4, 12, neck_diameter=0.0, shoulder_length=30)


@pytest.mark.parametrize("d, point_angle", [(3.0, 118.0), (6.35, 118.0), (5.1, 135.0), (2.5, 90.0),
                                            (3.175, 118.0), (6.5, 140.0), (4.2, 120.0)])
def test_drill_point_is_a_cone_of_half_the_point_angle(d, point_angle):
    drill = Drill(d, 30.0, point_angle=point_angle)
    r = d / 2
    h = r / math.tan(math.radians(point_angle / 2))
    assert drill.cone_height == pytest.approx(h, rel=1e-12)
    prof = drill.profile()
    assert prof.segments[0].start == (0.0, 0.0)
    assert prof.segments[0].end == pytest.approx((r, h), rel=1e-12)
    assert prof.radius_at(h / 2) == pytest.approx(r / 2, rel=1e-9)
    assert prof.radius_at(h + 1.0) == pytest.approx(r, rel=1e-12)
    # cone + cylinder up to the flutes + shank (default: the cutting diameter, to flute length + 2 d)
    expected = math.pi * r * r * h / 3 + cylinder(d, 30.0 - h) + cylinder(d, 2 * d)
    assert revolved_volume(drill) == pytest.approx(expected, rel=1e-12)
    # the same cutter as a pointed chamfer mill of half-angle point_angle / 2
    chamfer = ChamferMill(d, 30.0, taper_angle=point_angle / 2)
    assert drill.apt() == chamfer.apt()
    assert drill.kind == "drill" and drill.is_convex


@pytest.mark.parametrize("angle", [0.0, 180.0, 200.0, -118.0])
def test_drill_point_angle_out_of_range(angle):
    with pytest.raises(ToolDefinitionError, match=r"drill point angle must be in \(0, 180\)"):
        Drill(3, 30, point_angle=angle)


def test_drill_point_longer_than_the_flutes_is_refused():
    with pytest.raises(ToolDefinitionError, match="point .* longer than the flutes"):
        Drill(10, 2, point_angle=118)
