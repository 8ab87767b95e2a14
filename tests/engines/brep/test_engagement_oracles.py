"""Engagement angles against closed forms (Altintas immersion convention, see model.angles)."""
from __future__ import annotations

import math

import pytest

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.model import (ArcMove, BallEndMill, BoxStock, CLStatus, FlatEndMill, LinearMove, SpindleDirection,
                             Toolpath)

MID_PASS_TOL = 0.005  # degrees, the bound mid-pass
CORNER_TOL = 0.02  # degrees, at corners


def run(moves, tools, stock, **opts):
    eng = BRepEngine(EngineOptions(**opts))
    out = list(eng.run(Toolpath(tuple(moves), tools), stock))
    return eng, out


def rot(p, ang_deg, about=(0.0, 0.0)):
    a = math.radians(ang_deg)
    x, y = p[0] - about[0], p[1] - about[1]
    return (about[0] + x * math.cos(a) - y * math.sin(a), about[1] + x * math.sin(a) + y * math.cos(a), p[2])


def feed(p0, p1, tool=1, decimals=None):
    """A G1 move; with ``decimals``, its coordinates rounded as a post writes them."""
    return LinearMove(posted(p0, decimals), posted(p1, decimals), feed=600.0, tool=tool)


def posted(p, decimals):
    return p if decimals is None else tuple(round(v, decimals) for v in p)


# coordinates as exact floats, and as posts write them (Fusion's metric posts: 3 or 4 decimals)
POSTED = pytest.mark.parametrize("decimals", [None, 3, 4])


@POSTED
@pytest.mark.parametrize("feed_angle", [0.0, 37.0, 180.0])
def test_full_slot_is_one_interval_0_180_on_every_engaged_slice(feed_angle, decimals):
    tool = FlatEndMill(10, 20)
    stock = BoxStock((-60, -60, -20), (60, 60, 0))
    p0, p1 = rot((-80, 0, -3.0), feed_angle), rot((0, 0, -3.0), feed_angle)
    _, maps = run([feed(p0, p1, decimals=decimals)], {1: tool}, stock, max_segment_length=20.0)
    last = maps[-1]
    assert last.status == CLStatus.ENGAGED
    assert len(last.engaged_slices) == 3  # ap = 3 mm at 1 mm slices
    for s in last.engaged_slices:
        assert len(s.intervals) == 1
        assert s.intervals[0].entry == pytest.approx(0.0, abs=MID_PASS_TOL)
        assert s.intervals[0].exit == pytest.approx(180.0, abs=MID_PASS_TOL)
    assert last.ap == pytest.approx(3.0, abs=1e-9)
    assert last.ae == pytest.approx(10.0, abs=1e-6)
    # front half of the cylinder over the axial depth
    assert last.contact_area == pytest.approx(math.pi * 5 * 3, rel=1e-6)
    # a slot 10 mm wide and 3 mm deep along the segment (20 mm, or 16 when a post's rounding makes the
    # move a hair longer than 80 mm and it is cut into 5)
    assert last.removed_volume == pytest.approx(10 * math.dist(last.start, last.position) * 3, rel=1e-9)


@POSTED
@pytest.mark.parametrize("ae", [1.0, 2.5, 5.0, 8.0])
@pytest.mark.parametrize("side", ["up", "down"])
@pytest.mark.parametrize("spindle", [SpindleDirection.CW, SpindleDirection.CCW])
def test_up_and_down_milling_with_radial_depth(ae, side, spindle, decimals):
    R = 5.0
    tool = FlatEndMill(2 * R, 20, spindle=spindle)
    # material on +y of a +x feed: up-milling for a CW spindle, down-milling for CCW
    material_on_plus_y = (side == "up") == (spindle == SpindleDirection.CW)
    y = 1.0 / 3.0
    if material_on_plus_y:
        stock = BoxStock((-50, y + R - ae, -20), (50, 40, 0))
    else:
        stock = BoxStock((-50, -40, -20), (50, y - R + ae, 0))
    # the feed line off y = 0 by a third of a mm, rounded as a post writes it; the closed form takes the
    # radial depth at the rounded line
    p1 = posted((0, y, -4), decimals)
    _, maps = run([feed((-70, y, -4), p1, decimals=decimals)], {1: tool}, stock, max_segment_length=10.0)
    last = maps[-1]
    ae = ae + (p1[1] - y if material_on_plus_y else y - p1[1])
    phi = math.degrees(math.acos(1 - ae / R))
    expected = (0.0, phi) if side == "up" else (180.0 - phi, 180.0)
    assert len(last.engaged_slices) == 4
    for s in last.engaged_slices:
        assert len(s.intervals) == 1
        assert s.intervals[0].entry == pytest.approx(expected[0], abs=MID_PASS_TOL)
        assert s.intervals[0].exit == pytest.approx(expected[1], abs=MID_PASS_TOL)
    assert last.ae == pytest.approx(ae, abs=1e-6)


@POSTED
def test_ball_end_slot_follows_the_sphere_per_slice(decimals):
    R, depth = 5.0, 3.0
    tool = BallEndMill(2 * R, 20)
    stock = BoxStock((-60, -20, -20), (60, 20, 0))
    y = 2.0 / 3.0  # off the axis, so that a post's rounding moves the line
    moves = [feed((-80, y, -depth), (0, y, -depth), decimals=decimals)]
    _, maps = run(moves, {1: tool}, stock, max_segment_length=20.0, slice_height=0.2)
    last = maps[-1]
    engaged = last.engaged_slices
    assert len(engaged) == round(depth / 0.2)
    for s in engaged:
        r = math.sqrt(R**2 - (R - s.z) ** 2)
        assert s.radius == pytest.approx(r, abs=1e-12)
        assert len(s.intervals) == 1
        assert s.intervals[0].entry == pytest.approx(0.0, abs=MID_PASS_TOL)
        assert s.intervals[0].exit == pytest.approx(180.0, abs=MID_PASS_TOL)
        assert s.radial_width == pytest.approx(2 * r, abs=1e-9)
    # the front half of a spherical zone of height `depth`: pi * R * depth
    assert last.contact_area == pytest.approx(math.pi * R * depth, rel=1e-6)
    assert last.ap == pytest.approx(depth, abs=1e-9)


def test_tool_meeting_two_separate_regions_gives_two_intervals():
    """A 10 mm tool follows a 4 mm slot that ends in a half circle.

    Mid-slot, the slot walls y = 25 +- 2 cut the tool circle: line-circle, [0, acos(2/5)] and
    [180 - acos(2/5), 180]. Near the slot's round end (centre (40, 25), r = 2) with the tool at
    x = 36: circle-circle, the gap is where |p - (40, 25)| <= 2, i.e. sin(phi) >= 37/40.
    """
    big, small = FlatEndMill(10, 20), FlatEndMill(4, 20)
    stock = BoxStock((0, 0, -20), (100, 50, 0))
    moves = [feed((-10, 25, -3), (40, 25, -3), tool=2), LinearMove((40, 25, -3), (40, 25, 10), tool=2, rapid=True),
             LinearMove((-10, 25, 10), (-10, 25, -3), tool=1, rapid=True),
             feed((-10, 25, -3), (20, 25, -3), tool=1), feed((20, 25, -3), (36, 25, -3), tool=1)]
    _, maps = run(moves, {1: big, 2: small}, stock)
    mid, corner = maps[-2], maps[-1]
    a = math.degrees(math.acos(2 / 5))
    assert_intervals(mid, [(0.0, a), (180 - a, 180.0)], MID_PASS_TOL)
    b = math.degrees(math.asin(37 / 40))
    assert_intervals(corner, [(0.0, b), (180 - b, 180.0)], CORNER_TOL)


def assert_intervals(cl_map, expected, tol):
    assert cl_map.engaged_slices
    for s in cl_map.engaged_slices:
        got = [(iv.entry, iv.exit) for iv in s.intervals]
        assert len(got) == len(expected)
        for g, e in zip(got, expected):
            assert g == pytest.approx(e, abs=tol)


def test_volume_is_conserved_over_a_mixed_program():
    tool = FlatEndMill(8, 20)
    ball = BallEndMill(6, 20)
    stock = BoxStock((0, 0, -15), (60, 40, 0))
    moves = [feed((-5, 10, -2), (65, 10, -2)), feed((65, 10, -2), (65, 30, -2)), feed((65, 30, -2), (-5, 30, -4)),
             feed((20, 20, 5), (20, 20, -6)), feed((20, 20, -6), (40, 20, -6), tool=2)]
    eng, maps = run(moves, {1: tool, 2: ball}, stock, max_segment_length=7.0)
    removed = sum(m.removed_volume for m in maps)
    assert all(m.status != CLStatus.FAILED for m in maps)
    assert stock.volume - eng.ipw_volume == pytest.approx(removed, rel=1e-6)


def test_slot_deeper_than_the_flutes_splits_contact_into_flute_and_shank():
    tool = FlatEndMill(10, 8)  # shank of the flute diameter: one cylinder from tip to top
    stock = BoxStock((-60, -60, -20), (60, 60, 0))
    _, maps = run([feed((-80, 0, -12.0), (0, 0, -12.0))], {1: tool}, stock, max_segment_length=20.0)
    last = maps[-1]
    assert last.contact_area == pytest.approx(math.pi * 5 * 8, rel=1e-6)
    assert last.shank_contact_area == pytest.approx(math.pi * 5 * 4, rel=1e-6)
    assert len(last.engaged_slices) == 8
    assert any("shank" in w for w in last.warnings)


@pytest.mark.parametrize("layers", [True, False])
@pytest.mark.parametrize("cell_size", [None, 20.0])
def test_a_wall_only_grazed_is_no_engagement(cell_size, layers):
    """A slot cut 3 mm deep, then again 3 mm deeper along the same line.

    At the second pass's end the tool's front half lies exactly on the end wall the first pass left
    (3-6 mm above its tip): it removes nothing there, so only the 3 mm it cuts are engaged, full slot.
    """
    tool = FlatEndMill(10, 20)
    stock = BoxStock((-60, -30, -20), (60, 30, 0))
    moves = [feed((-80, 0, -3), (0, 0, -3)), LinearMove((0, 0, -3), (-80, 0, -6), rapid=True, tool=1),
             feed((-80, 0, -6), (0, 0, -6))]
    _, maps = run(moves, {1: tool}, stock, max_segment_length=20.0, cell_size=cell_size, layers=layers)
    last = maps[-1]
    assert last.status == CLStatus.ENGAGED
    assert last.ap == pytest.approx(3.0, abs=1e-9)
    assert_intervals(last, [(0.0, 180.0)], MID_PASS_TOL)
    assert last.contact_area == pytest.approx(math.pi * 5 * 3, rel=1e-6)


def posted_arc(p0, end, center, clockwise, decimals, off=0.0):
    """A G2/G3 move as a post writes it: end point and I/J (the centre relative to the start) rounded
    to ``decimals``, the end pushed ``off`` mm off the circle, so start and end radius differ."""
    c = (center[0] - p0[0], center[1] - p0[1])
    r = math.hypot(end[0] - center[0], end[1] - center[1])
    e = (center[0] + (end[0] - center[0]) * (r + off) / r, center[1] + (end[1] - center[1]) * (r + off) / r, end[2])
    e, ij = posted(e, decimals), posted(c, decimals)
    return ArcMove(p0, e, feed=600.0, tool=1, center=(p0[0] + ij[0], p0[1] + ij[1], p0[2]), clockwise=clockwise)


@pytest.mark.parametrize("decimals, off", [(None, 0.0), (4, 0.0), (3, 0.0), (4, 0.002), (4, -0.002)])
@pytest.mark.parametrize("clockwise", [True, False])
def test_slot_along_rounded_arcs_is_one_interval_0_180(decimals, off, clockwise):
    """A D6 slot 2 mm deep along arcs of radius 17.3 mm, as posts write them: I/J and end points
    rounded, and (the issue's case) ends 2 µm off the circle. The controller follows a spiral; every
    CL on it is a full slot, [0, 180] on both slices, within 0.05° (the spiral's feed direction turns
    a little against the circle's tangent; within 0.005° on exact arcs)."""
    R, depth, rho = 3.0, 2.0, 17.3
    stock = BoxStock((-40, -40, -10), (40, 40, 0))
    sgn = -1.0 if clockwise else 1.0
    at = lambda deg: (rho * math.cos(math.radians(deg)), rho * math.sin(math.radians(deg)), -depth)  # noqa: E731
    start = posted(at(0.0), decimals)  # entered from outside the stock along the tangent
    moves = [feed((start[0], -45.0 * sgn, -depth), start, decimals=decimals)]
    for k, deg in enumerate((37.0, 101.0, 163.0)):
        moves.append(posted_arc(moves[-1].end, at(sgn * deg), (0.0, 0.0, -depth), clockwise, decimals,
                                off=off if k % 2 == 0 else -off))
    eng, maps = run(moves, {1: FlatEndMill(2 * R, 12)}, stock, max_segment_length=2.0)
    on_arcs = [m for m in maps if abs(math.hypot(m.position[0], m.position[1]) - rho) < 0.01 and m.position[1] * sgn > 0]
    tol = MID_PASS_TOL if off == 0.0 and decimals is None else 0.05
    assert len(on_arcs) >= 24  # 163° of 17.3 mm in 2 mm CLs
    for m in on_arcs:
        assert m.status == CLStatus.ENGAGED
        assert len(m.engaged_slices) == 2
        assert_intervals(m, [(0.0, 180.0)], tol)
    removed = sum(m.removed_volume for m in maps)
    assert stock.volume - eng.ipw_volume == pytest.approx(removed, rel=1e-9)


@pytest.mark.parametrize("offset", [5e-4, -5e-4])
def test_a_skin_thinner_than_the_minimum_chip_only_rubs(offset):
    """The grazed-wall case above with the second pass 0.5 µm beside the first, as a post's
    rounding puts it: 3-6 mm above its tip the tool takes a crescent skin 0-0.5 µm thick off the
    first pass's wall and end, and its contact arcs there span ~90°. The skin's removed width across
    the path (0.5 µm) is under the default minimum chip thickness (1 µm): those 3 slices rub, they
    are no engagement and ap stays the 3 mm the pass cuts. With the minimum off they count (ap 6).
    The tool goes back over the stock, not through it, so the cells stay layered (a rapid through
    the material would make them solids, whose per-band volumes are unknown: no rubbing is told).
    """
    tool, stock, moves = skin_case(offset)
    _, maps = run(moves, {1: tool}, stock, max_segment_length=20.0)
    last = maps[-1]
    assert last.status == CLStatus.ENGAGED
    assert last.ap == pytest.approx(3.0, abs=1e-9)
    assert last.rubbing_slices == 3
    assert [s.z for s in last.engaged_slices] == pytest.approx([0.5, 1.5, 2.5], abs=1e-9)
    assert_intervals(last, [(0.0, 180.0)], MID_PASS_TOL)
    assert any("rub" in w for w in last.warnings)

    _, maps = run(moves, {1: tool}, stock, max_segment_length=20.0, min_chip_thickness=0.0)
    last = maps[-1]
    assert len(last.engaged_slices) == 6
    assert last.ap == pytest.approx(6.0, abs=1e-6)
    assert last.rubbing_slices == 0


def skin_case(offset):
    tool = FlatEndMill(10, 20)
    stock = BoxStock((-60, -30, -20), (60, 30, 0))
    moves = [feed((-80, 0, -3), (0, 0, -3)), LinearMove((0, 0, -3), (0, 0, 5), rapid=True, tool=1),
             LinearMove((0, 0, 5), (-80, offset, 5), rapid=True, tool=1),
             LinearMove((-80, offset, 5), (-80, offset, -6), rapid=True, tool=1),
             feed((-80, offset, -6), (0, offset, -6))]
    return tool, stock, moves


def test_dask_workers_tell_the_same_rubbing_slices():
    """Workers each cut a part of the cells: the volumes removed per band are summed over them, so
    the skin rubs alike (its cells are split among the workers)."""
    pytest.importorskip("distributed")
    from fusioncut.engines.brep.parallel import ParallelBRepEngine

    tool, stock, moves = skin_case(5e-4)
    _, serial = run(moves, {1: tool}, stock, max_segment_length=20.0)
    with ParallelBRepEngine(EngineOptions(max_segment_length=20.0), workers=2, batch=3) as engine:
        parallel = list(engine.run(Toolpath(tuple(moves), {1: tool}), stock))
    assert sum(m.rubbing_slices for m in serial) >= 3 * 4  # the pass's 4 CLs in the stock
    assert [m.rubbing_slices for m in parallel] == [m.rubbing_slices for m in serial]
    assert [m.ap for m in parallel] == pytest.approx([m.ap for m in serial], abs=1e-9)
    assert [[s.z for s in m.engaged_slices] for m in parallel] == [[s.z for s in m.engaged_slices] for m in serial]


@pytest.mark.parametrize("dr", [5e-4, -5e-4])
def test_a_skin_left_by_an_arc_retraced_a_rounding_beside_only_rubs(dr):
    """A quarter arc slot (R 30) cut at z=-3, then again at z=-6 on a radius 0.5 µm larger or
    smaller (rounded I/J): over the arc's every CL the skin above 3 mm rubs (its width is measured
    over the arc's length), the 3 mm below are a full slot."""
    tool = FlatEndMill(10, 20)
    stock = BoxStock((-10, -30, -20), (50, 50, 0))
    r = 30.0

    def arc(z, radius):
        return ArcMove((radius, 0, z), (0, radius, z), feed=600.0, tool=1, center=(0, 0, z))

    moves = [feed((r, -40, -3), (r, 0, -3)), arc(-3, r), LinearMove((0, r, -3), (0, r, 5), rapid=True, tool=1),
             LinearMove((0, r, 5), (r + dr, -40, 5), rapid=True, tool=1),
             LinearMove((r + dr, -40, 5), (r + dr, -40, -6), rapid=True, tool=1),
             feed((r + dr, -40, -6), (r + dr, 0, -6)), arc(-6, r + dr)]
    _, maps = run(moves, {1: tool}, stock, max_segment_length=10.0)
    second_arc = [m for m in maps if m.position[2] == -6 and m.position[1] > 0]  # the line ends at y = 0
    assert len(second_arc) == 5  # 47.1 mm in pieces of at most 10
    for m in second_arc:
        assert m.ap == pytest.approx(3.0, abs=1e-9), m.cl_index
        assert m.rubbing_slices == 3
        assert [s.z for s in m.engaged_slices] == pytest.approx([0.5, 1.5, 2.5], abs=1e-9)
        assert_intervals(m, [(0.0, 180.0)], MID_PASS_TOL)
