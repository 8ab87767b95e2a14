"""The analytic engine against closed forms, and CL by CL against the B-Rep engine where that is exact."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from fusioncut.engines.analytic.engine import AnalyticEngine, UnsupportedStock
from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.cl_maps import cl_sequence
from fusioncut.model import (AptCutter, AptParameters, ArcMove, BallEndMill, BoxStock, BullNoseEndMill, ChamferMill,
                             CLStatus, FlatEndMill, LinearMove, SolidStock, SpindleDirection, Toolpath)

ANGLE_TOL = 0.001  # degrees (issue 26: 0.001 against the B-Rep engine, 0.005 against closed forms)
VOLUME_REL = 1e-7
AREA_REL = 1e-7  # the contact area's integration tolerance (issue 26), against closed forms
# against the B-Rep engine: its contact faces are bounded by intersection curves the kernel approximates
# (to ~1e-7 mm), and their areas carry that: on the ball slot beside a deeper pass below, 1.06e-7
# relative off the analytic area, which stays put to 1e-12 as its own tolerance goes to 1e-11
BREP_AREA_REL = 1e-6


def run(moves, tools, stock, engine=AnalyticEngine, **opts):
    eng = engine(EngineOptions(**opts))
    return eng, list(eng.run(Toolpath(tuple(moves), tools), stock))


def assert_maps_agree(maps, others):
    """Each CL's volume and contact area to the analytic integrals' tolerances, its rubbing slices the same,
    both from the analytic engine: a closed form against the adaptive integral it replaces."""
    for a, b in zip(maps, others, strict=True):
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=VOLUME_REL, abs=1e-9), a.cl_index
        assert a.contact_area == pytest.approx(b.contact_area, rel=AREA_REL, abs=1e-9), a.cl_index
        assert a.rubbing_slices == b.rubbing_slices, a.cl_index
        assert a.engine == b.engine == "analytic"


def feed(p0, p1, tool=1):
    return LinearMove(p0, p1, feed=600.0, tool=tool)


def rot(p, ang_deg):
    a = math.radians(ang_deg)
    return (p[0] * math.cos(a) - p[1] * math.sin(a), p[0] * math.sin(a) + p[1] * math.cos(a), p[2])


def angle_gap(a: float, b: float) -> float:
    """|a - b| in degrees on the circle (an entry of 0 and of 360 are the same angle)."""
    d = (a - b) % 360.0
    return min(d, 360.0 - d)


def assert_same_intervals(got, expected, tol):
    """Each expected interval has one got interval of the same entry and span within ``tol`` degrees
    (paired by the nearest entry on the circle: an entry of 359.999999 is one of 0)."""
    assert len(got) == len(expected), (got, expected)
    left = list(got)
    for ee, ex in expected:
        ge, gx = min(left, key=lambda iv: angle_gap(iv[0], ee))
        left.remove((ge, gx))
        assert angle_gap(ge, ee) <= tol, (got, expected)
        assert abs((gx - ge) - (ex - ee)) <= tol, (got, expected)


def intervals(s):
    return [(iv.entry, iv.exit) for iv in s.intervals]


@pytest.mark.parametrize("feed_angle", [0.0, 37.0, 180.0])
def test_full_slot_closed_form(feed_angle):
    tool = FlatEndMill(10, 20)
    stock = BoxStock((-60, -60, -20), (60, 60, 0))
    _, maps = run([feed(rot((-80, 0, -3.0), feed_angle), rot((0, 0, -3.0), feed_angle))], {1: tool}, stock,
                  max_segment_length=20.0)
    last = maps[-1]
    assert last.status == CLStatus.ENGAGED
    assert len(last.engaged_slices) == 3
    for s in last.engaged_slices:
        assert_same_intervals(intervals(s), [(0.0, 180.0)], ANGLE_TOL)
    assert last.ap == pytest.approx(3.0, abs=1e-9)
    assert last.ae == pytest.approx(10.0, abs=1e-6)
    assert last.removed_volume == pytest.approx(10 * 20 * 3, rel=VOLUME_REL)


@pytest.mark.parametrize("ae", [1.0, 2.5, 8.0])
@pytest.mark.parametrize("side", ["up", "down"])
@pytest.mark.parametrize("spindle", [SpindleDirection.CW, SpindleDirection.CCW])
def test_up_and_down_milling_closed_form(ae, side, spindle):
    R = 5.0
    tool = FlatEndMill(2 * R, 20, spindle=spindle)
    plus_y = (side == "up") == (spindle == SpindleDirection.CW)
    y = 1.0 / 3.0
    stock = BoxStock((-50, y + R - ae, -20), (50, 40, 0)) if plus_y else BoxStock((-50, -40, -20), (50, y - R + ae, 0))
    _, maps = run([feed((-70, y, -4), (0, y, -4))], {1: tool}, stock, max_segment_length=10.0)
    last = maps[-1]
    phi = math.degrees(math.acos(1 - ae / R))
    expected = (0.0, phi) if side == "up" else (180.0 - phi, 180.0)
    assert len(last.engaged_slices) == 4
    for s in last.engaged_slices:
        assert_same_intervals(intervals(s), [expected], ANGLE_TOL)
    assert last.ae == pytest.approx(ae, abs=1e-6)
    # a level cut of width ae and depth 4 along the 10 mm segment
    assert last.removed_volume == pytest.approx(ae * 10 * 4, rel=VOLUME_REL)


@pytest.mark.parametrize("tool", [FlatEndMill(10, 20), BallEndMill(10, 20), BullNoseEndMill(10, 20, corner_radius=2.0)],
                         ids=["flat", "ball", "bull-nose"])
@pytest.mark.parametrize("decimals", [None, 3])
def test_slot_contact_area_closed_form(tool, decimals):
    """A slot 3 mm deep: the contact is the front half of the tool's surface below 3 mm (its end
    face left out). Cylinder: pi R ap; sphere zone (Archimedes): pi R ap; bull-nose: the corner's
    half torus, pi (pi/2 (R - rc) rc + rc²), and the cylinder above it, pi R (ap - rc). Also along a
    path written with 3 decimals, as a post writes an oblique line."""
    R, ap = 5.0, 3.0
    end = rot((0, 0, -ap), 37.0)
    if decimals is not None:
        end = tuple(round(v, decimals) for v in end)
    start = rot((-80, 0, -ap), 37.0)
    _, maps = run([feed(start, end)], {1: tool}, BoxStock((-60, -60, -20), (60, 60, 0)), max_segment_length=20.0)
    rc = getattr(tool, "corner_radius", 0.0) if not isinstance(tool, BallEndMill) else None
    if rc is None or rc == 0.0:
        expected = math.pi * R * ap
    else:
        expected = math.pi * (0.5 * math.pi * (R - rc) * rc + rc * rc) + math.pi * R * (ap - rc)
    assert maps[-1].contact_area == pytest.approx(expected, rel=AREA_REL)
    assert maps[-1].shank_contact_area == 0.0


def test_shank_contact_closed_form_and_as_brep():
    """A flat end mill with 2 mm of flutes slotting 3 mm deep: the flutes' half cylinder below 2 mm,
    the shank's above it, each pi R times its height; the B-Rep engine says the same CL by CL."""
    R = 5.0
    tool = FlatEndMill(2 * R, 2.0)
    moves = [feed((-80, 0, -3.0), (-40, 0, -3.0)), feed((-40, 0, -3.0), (0, 0, -3.0))]
    stock = BoxStock((-60, -60, -20), (60, 60, 0))
    _, maps = run(moves, {1: tool}, stock, max_segment_length=20.0)
    assert maps[-1].contact_area == pytest.approx(math.pi * R * 2.0, rel=AREA_REL)
    assert maps[-1].shank_contact_area == pytest.approx(math.pi * R * 1.0, rel=AREA_REL)
    assert any("shank" in w for w in maps[-1].warnings)
    assert_agree(moves, {1: tool}, stock, max_segment_length=20.0)


def test_ball_slot_closed_form():
    R, depth = 5.0, 3.0
    tool = BallEndMill(2 * R, 20)
    stock = BoxStock((-60, -20, -20), (60, 20, 0))
    _, maps = run([feed((-80, 2 / 3, -depth), (0, 2 / 3, -depth))], {1: tool}, stock, max_segment_length=20.0,
                  slice_height=0.2)
    last = maps[-1]
    assert len(last.engaged_slices) == round(depth / 0.2)
    for s in last.engaged_slices:
        assert s.radius == pytest.approx(math.sqrt(R**2 - (R - s.z) ** 2), abs=1e-12)
        assert_same_intervals(intervals(s), [(0.0, 180.0)], ANGLE_TOL)
    assert last.ap == pytest.approx(depth, abs=1e-9)
    # the slot's cross-section is the circular segment of height `depth`
    segment = R * R * math.acos((R - depth) / R) - (R - depth) * math.sqrt(2 * R * depth - depth**2)
    assert last.removed_volume == pytest.approx(20 * segment, rel=VOLUME_REL)


@pytest.mark.parametrize("depth", [3.0, 0.01])
@pytest.mark.parametrize(("tol", "rel"), [(0.0, 1e-8), (1e-10, 0.0)], ids=["relative", "absolute"])
def test_volume_tolerance_relative_or_absolute_alone(depth, tol, rel):
    """Either tolerance alone holds the ball slot's closed form (a deep slot and a skim whose volume
    is 1/300 of it): the integral stops at the looser of the two, so each must be enough by itself."""
    R = 5.0
    stock = BoxStock((-60, -20, -20), (60, 20, 0))
    _, maps = run([feed((-80, 2 / 3, -depth), (0, 2 / 3, -depth))], {1: BallEndMill(2 * R, 20)}, stock,
                  engine=lambda o: AnalyticEngine(o, volume_tol=tol, volume_rel=rel), max_segment_length=20.0)
    segment = R * R * math.acos((R - depth) / R) - (R - depth) * math.sqrt(2 * R * depth - depth**2)
    assert maps[-1].removed_volume == pytest.approx(20 * segment, rel=VOLUME_REL)
    cap = math.pi * depth**2 * (3 * R - depth) / 3  # the ball under the top; half of it lies past the slot's end
    assert sum(m.removed_volume for m in maps) == pytest.approx(60 * segment + cap / 2, rel=VOLUME_REL)


def test_ball_ramp_engages_beyond_the_front_half_by_the_slope():
    """A ball going down a ramp of slope m along +x, deep in the stock: a point of the sphere at
    height z above the tip is on the sweep's front iff cos(theta) >= -m (R - z) / r(z) (the sphere's
    normal against the motion), so each slice is engaged over 2 acos(-m (R - z) / r(z)) centred on the
    feed direction (immersion 90); above the ball the cylinder's front half."""
    R, m = 3.0, 0.15
    tool = BallEndMill(2 * R, 20)
    stock = BoxStock((-60, -20, -30), (60, 20, 0))
    start, end = (-40.0, 0.0, -4.0), (0.0, 0.0, -4.0 - 40 * m)
    _, maps = run([feed(start, end)], {1: tool}, stock, max_segment_length=5.0, slice_height=0.5, ramp_step=100.0)
    last = maps[-1]
    assert last.ap == pytest.approx(-end[2], abs=1e-9)
    for s in last.engaged_slices:
        if s.z < R:
            r = math.sqrt(R * R - (R - s.z) ** 2)
            half = math.degrees(math.acos(-m * (R - s.z) / r))
        else:
            half = 90.0
        assert_same_intervals(intervals(s), [(90.0 - half, 90.0 + half)], ANGLE_TOL)


@pytest.mark.slow  # tens of seconds: the volume integral on ramps and helices is not fast yet
def test_ball_going_up_a_ramp_touches_from_where_its_front_begins():
    """A ball rising at angle a: the end sphere's front is the half facing the motion, whose lowest
    point is R (1 - cos a) above the tip; the contact reaches up to the stock's top. (The B-Rep engine
    gives 0.0370 instead of 0.0375 on such a move: a rapid rising at 9 degrees.)"""
    R = 3.0
    tool = BallEndMill(2 * R, 20)
    stock = BoxStock((-60, -20, -30), (60, 20, 0))
    start, end = (-40.0, 0.0, -6.0), (0.0, 0.0, -2.0)
    _, maps = run([feed(start, end)], {1: tool}, stock, max_segment_length=5.0, ramp_step=100.0)
    a = math.atan2(end[2] - start[2], end[0] - start[0])
    assert maps[-1].axial_range == pytest.approx((R * (1 - math.cos(a)), -end[2]), abs=1e-9)


@pytest.mark.slow  # tens of seconds: the volume integral on ramps and helices is not fast yet
def test_split_ramp_removes_what_the_whole_ramp_removes():
    """Volumes add up: a ball ramp cut into 8 CLs removes what it removes as one CL (1e-7)."""
    tool = BallEndMill(6, 20)
    stock = BoxStock((-30, -20, -30), (30, 20, 0))
    moves = [feed((-35.0, 1.0, 1.0), (20.0, 3.0, -3.0))]
    _, whole = run(moves, {1: tool}, stock, ramp_step=100.0)
    _, split = run(moves, {1: tool}, stock, ramp_step=100.0, max_segment_length=moves[0].length / 8 + 1e-9)
    assert len(whole) == 1 and len(split) == 8
    assert sum(m.removed_volume for m in split) == pytest.approx(whole[0].removed_volume, rel=VOLUME_REL)


@pytest.mark.slow  # tens of seconds: the volume integral on ramps and helices is not fast yet
def test_helical_bore_removes_the_closed_form_pocket():
    """A flat end mill (R 6) down a helix of radius 4 (1.75 turns to 3 mm deep), then one level turn:
    the pocket is the cylinder of radius 10, 3 mm deep. The helix is swept exactly, not in steps."""
    R, rho, depth, top = 6.0, 4.0, 3.0, 0.5
    start = (rho, 0.0, top)
    moves = [feed((rho, 0.0, 5.0), start),
             ArcMove(start, (0.0, rho, -depth), center=(0.0, 0.0, top), clockwise=True, turns=1, feed=800.0, tool=1)]
    pts = [(0.0, rho), (rho, 0.0), (0.0, -rho), (-rho, 0.0), (0.0, rho)]
    moves += [ArcMove((*a, -depth), (*b, -depth), center=(0.0, 0.0, -depth), clockwise=True, feed=800.0, tool=1)
              for a, b in zip(pts, pts[1:])]
    stock = BoxStock((-20, -20, -10), (20, 20, 0))
    _, maps = run(moves, {1: FlatEndMill(2 * R, 20.0)}, stock, ramp_step=1.0)
    assert all(m.status != CLStatus.FAILED for m in maps)
    assert sum(m.removed_volume for m in maps) == pytest.approx(math.pi * (rho + R) ** 2 * depth, rel=VOLUME_REL)
    # on the helix below the top every CL cuts, and the slices below the helix's previous turn see
    # material all along the front
    helix = [m for m in maps[1:] if m.start[2] != m.position[2] and m.position[2] < 0]
    assert helix and all(m.status == CLStatus.ENGAGED and m.removed_volume > 0 for m in helix)


@pytest.mark.parametrize("decimals", [None, 3])
def test_helical_bore_in_solid_closed_form_slices(decimals):
    """A flat end mill (R 6) down a helix of radius 4 (2.25 turns, pitch p = 2 mm) into solid, the
    last CL's slices. A point q of the slice h above the tip, on the front half, at distance D from
    the helix's axis, was last under the tool a turn earlier, at the end of the angle 2 alpha over
    which the path's centre stays within R of it (cos alpha = (D² + rho² - R²) / (2 D rho)); the tool's
    bottom was then p (1 - alpha / pi) above the tip's height now. So q holds material iff h is below
    that: iff D² - 2 rho c D + rho² - R² > 0 with c = -cos(pi h / p), that is iff its machine angle
    lies within acos(kappa) of the centre's outward direction, kappa = (D*² - rho² - R²) / (2 rho R)
    with D* the positive root. On the front half (the feed direction is the outward direction less
    90 degrees, clockwise) that is the immersion interval (0, acos(kappa)). With points rounded to
    3 decimals as posts write them, the radius of the helix's end differs by up to a micron."""
    R, rho, p, turns = 6.0, 4.0, 2.0, 2.25
    top, z_end = 0.5, 0.5 - p * turns

    def pt(v):
        return v if decimals is None else tuple(round(c, decimals) for c in v)

    start, end = pt((rho, 0.0, top)), pt((0.0, -rho, z_end))
    moves = [feed(pt((rho, 0.0, 5.0)), start),
             ArcMove(start, end, center=pt((0.0, 0.0, top)), clockwise=True, turns=2, feed=800.0, tool=1)]
    tp = Toolpath(tuple(moves), {1: FlatEndMill(2 * R, 20.0)})
    opts = EngineOptions(slice_height=0.25, max_segment_length=2.0)
    last = len(list(cl_sequence(tp, opts))) - 1
    eng = AnalyticEngine(opts)
    eng.start(BoxStock((-20, -20, -10), (20, 20, 0)))
    m = next(eng.process(tp, start_at=last))
    # the contact's top is a tangency (q at D = R + rho, alpha = 0) where the material margin peaks
    # as a square root of the angle: its peak, found to ~1e-12 rad, is ~1e-6 mm low (contact_range)
    assert m.ap == pytest.approx(p, abs=1e-5)
    for s in m.slices:
        c = -math.cos(math.pi * s.z / p)
        d_star = rho * c + math.sqrt(rho * rho * c * c - rho * rho + R * R)
        kappa = (d_star ** 2 - rho * rho - R * R) / (2 * rho * R)
        expected = [] if s.z >= p else [(0.0, math.degrees(math.acos(kappa)))]
        assert_same_intervals(intervals(s), expected, 0.005 if decimals else ANGLE_TOL)


def test_a_wall_only_grazed_is_no_engagement():
    """A slot cut 3 mm deep, then again 3 mm deeper along the same line: at the second pass's end the
    tool's front lies on the end wall the first pass left, so only the 3 mm it cuts are engaged. The
    rapid back goes down from -3 to -6 over 80 mm and takes 3 |x| / 80 mm off the floor of the last
    20 mm (x in [-20, 0]): 10 mm wide, 75 mm³."""
    tool = FlatEndMill(10, 20)
    stock = BoxStock((-60, -30, -20), (60, 30, 0))
    moves = [feed((-80, 0, -3), (0, 0, -3)), LinearMove((0, 0, -3), (-80, 0, -6), rapid=True, tool=1),
             feed((-80, 0, -6), (0, 0, -6))]
    _, maps = run(moves, {1: tool}, stock, max_segment_length=20.0)
    last = maps[-1]
    assert last.status == CLStatus.ENGAGED
    assert last.ap == pytest.approx(3.0, abs=1e-9)
    for s in last.engaged_slices:
        assert_same_intervals(intervals(s), [(0.0, 180.0)], ANGLE_TOL)
    assert last.removed_volume == pytest.approx(10 * 20 * 3 - 75, rel=VOLUME_REL)


@pytest.mark.slow  # tens of seconds: the volume integral on ramps and helices is not fast yet
def test_starting_at_a_later_cl_gives_the_same_maps():
    """The workpiece before a CL follows from the path: CLs 5.. alone equal CLs 5.. of a whole run."""
    tool = BallEndMill(6, 20)
    stock = BoxStock((-30, -20, -30), (30, 20, 0))
    moves = [feed((-35.0, 0.0, -2.0), (25.0, 0.0, -2.0)), feed((25.0, 0.0, -2.0), (25.0, 4.0, -2.5)),
             feed((25.0, 4.0, -2.5), (-35.0, 4.0, -2.5))]
    tp = Toolpath(tuple(moves), {1: tool})
    whole = list(AnalyticEngine(EngineOptions(max_segment_length=10.0)).run(tp, stock))
    eng = AnalyticEngine(EngineOptions(max_segment_length=10.0))
    eng.start(stock)
    later = list(eng.process(tp, start_at=5))
    assert [m.cl_index for m in later] == [m.cl_index for m in whole[5:]]
    for a, b in zip(later, whole[5:]):
        assert a.removed_volume == b.removed_volume
        assert [intervals(s) for s in a.slices] == [intervals(s) for s in b.slices]


def test_a_solid_stock_is_refused_by_name():
    with pytest.raises(UnsupportedStock, match="box stock or a round bar, got SolidStock"):
        run([feed((0, 0, 0), (1, 0, 0))], {1: FlatEndMill(6, 10)}, SolidStock(Path("blank.step")))


# -- against the B-Rep engine, CL by CL ---------------------------------------------------------------
def assert_agree(moves, tools, stock, **opts):
    _, ours = run(moves, tools, stock, **opts)
    _, theirs = run(moves, tools, stock, engine=BRepEngine, **opts)
    assert len(ours) == len(theirs)
    for a, b in zip(ours, theirs):
        assert a.status == b.status, a.cl_index
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=1e-6, abs=1e-9), a.cl_index
        assert a.ap == pytest.approx(b.ap, abs=1e-9), a.cl_index
        assert a.contact_area == pytest.approx(b.contact_area, rel=BREP_AREA_REL, abs=1e-9), a.cl_index
        assert a.shank_contact_area == pytest.approx(b.shank_contact_area, rel=BREP_AREA_REL, abs=1e-9), a.cl_index
        assert a.rubbing_slices == b.rubbing_slices, a.cl_index
        assert len(a.slices) == len(b.slices), a.cl_index
        for s, t in zip(a.slices, b.slices):
            assert s.z == pytest.approx(t.z, abs=1e-9)
            assert_same_intervals(intervals(s), intervals(t), ANGLE_TOL)


def test_agrees_with_brep_on_a_flat_slot_then_side_milling_and_an_arc():
    moves = [feed((-40, 3, -3), (0, 3, -3)),
             ArcMove((0, 3, -3), (10, -7, -3), feed=600.0, tool=1, center=(0, -7, -3), clockwise=True),
             feed((10, -7, -3), (10, -25, -3))]
    assert_agree(moves, {1: FlatEndMill(10, 20)}, BoxStock((-30, -30, -20), (30, 5, 0)), max_segment_length=10.0)


def test_agrees_with_brep_on_a_ball_slot_and_a_deeper_pass_beside_it():
    moves = [feed((-40, 0, -2), (0, 0, -2)), feed((0, 0, -2), (0, 20, -2)),
             LinearMove((0, 20, -2), (0, 20, 5), rapid=True, tool=1), LinearMove((0, 20, 5), (-40, 2, 5), rapid=True, tool=1),
             feed((-40, 2, 5), (-40, 2, -3)), feed((-40, 2, -3), (0, 2, -3))]
    assert_agree(moves, {1: BallEndMill(6, 20)}, BoxStock((-30, -30, -20), (30, 30, 0)), max_segment_length=10.0)


@pytest.mark.parametrize("end_radius", ["exact", "3 decimals", "4 decimals", "+2 um", "-2 um"])
def test_slot_along_an_arc_as_posts_round_it_is_the_front_half(end_radius):
    """A 6 mm flat end mill slots 2 mm deep along a G2 arc of radius 20 in solid material. Posts round
    the end point (3 or 4 decimals) or leave it microns off the circle: the arc is a spiral, and every
    slice at its last CL is still one interval spanning 180 degrees within 0.05 (issue 23: a spiral
    turns the feed direction a little against the circle's tangent)."""
    tool = FlatEndMill(6, 15)
    stock = BoxStock((-40, -40, -10), (40, 40, 0))
    a = math.radians(-60.0)
    end = {"exact": (20 * math.cos(a), 20 * math.sin(a)),
           "3 decimals": (round(20 * math.cos(a), 3), round(20 * math.sin(a), 3)),
           "4 decimals": (round(20 * math.cos(a), 4), round(20 * math.sin(a), 4)),
           "+2 um": (20.002 * math.cos(a), 20.002 * math.sin(a)),
           "-2 um": (19.998 * math.cos(a), 19.998 * math.sin(a))}[end_radius]
    moves = [feed((20, 0, 5), (20, 0, -2)),
             ArcMove((20, 0, -2), (*end, -2), center=(0, 0, -2), clockwise=True, feed=600.0, tool=1)]
    _, maps = run(moves, {1: tool}, stock, max_segment_length=5.0, slice_height=1.0)
    arc_cls = [m for m in maps[1:] if m.status == CLStatus.ENGAGED]
    assert len(arc_cls) >= 4
    for m in arc_cls[1:]:  # the first arc CL still leaves the plunge's hole
        assert len(m.engaged_slices) == 2
        for s in m.engaged_slices:
            (entry, exit_), = intervals(s)
            assert abs((exit_ - entry) % 360 - 180.0) <= 0.05, (entry, exit_)
            assert angle_gap(entry, 0.0) <= 0.05


@pytest.mark.parametrize("stepover", [2.5, 4.0, 5.5])
def test_bull_nose_stepping_over_a_level_floor_meets_its_own_cusp(stepover):
    """A bull-nose end mill (R 5, corner 2) cuts a level pass along x at y = 0, then a second one at
    y = s. The first leaves the floor z = -d + f(|y|), f the tool's own lower profile; so a point of
    the second pass's slice at z above the tip (radius r(z)) holds material iff |s + r sin(phi)| > r(z):
    with the spindle clockwise the slice is engaged over immersion (0, acos(1 - s / r(z))), on the
    torus and on the cylinder above it alike."""
    R, rc, d = 5.0, 2.0, 3.0
    tool = BullNoseEndMill(2 * R, 20, corner_radius=rc)
    stock = BoxStock((-50, -20, -20), (50, 20, 0))
    moves = [feed((-60, 0, -d), (60, 0, -d)), feed((60, 0, -d), (60, 0, 5)), feed((60, 0, 5), (-60, stepover, 5)),
             feed((-60, stepover, 5), (-60, stepover, -d)), feed((-60, stepover, -d), (0, stepover, -d))]
    _, maps = run(moves, {1: tool}, stock, max_segment_length=10.0, slice_height=0.25)
    last = maps[-1]
    assert last.status == CLStatus.ENGAGED
    assert len(last.engaged_slices) == round(d / 0.25)
    for s in last.engaged_slices:
        r = R - rc + math.sqrt(rc * rc - (rc - s.z) ** 2) if s.z < rc else R
        assert s.radius == pytest.approx(r, abs=1e-12)
        assert_same_intervals(intervals(s), [(0.0, math.degrees(math.acos(1 - stepover / r)))], 0.005)


@pytest.mark.parametrize("offset", [5e-4, -5e-4])
def test_a_skin_thinner_than_the_minimum_chip_only_rubs(offset):
    """A deeper pass 0.5 µm beside an earlier slot (as a post's rounding puts it): 3-6 mm above its
    tip it takes a 0.5 µm skin off the earlier wall, under the default minimum chip thickness
    (1 µm), so those 3 slices rub and ap is the 3 mm it cuts; with the minimum off they count. The
    B-Rep engine says the same CL by CL (its layered cells know their per-band volumes)."""
    from tests.engines.brep.test_engagement_oracles import skin_case

    tool, stock, moves = skin_case(offset)
    _, maps = run(moves, {1: tool}, stock, max_segment_length=20.0)
    last = maps[-1]
    assert last.ap == pytest.approx(3.0, abs=1e-9)
    assert last.rubbing_slices == 3
    assert [s.z for s in last.engaged_slices] == pytest.approx([0.5, 1.5, 2.5], abs=1e-9)
    assert any("rub" in w for w in last.warnings)
    _, maps = run(moves, {1: tool}, stock, max_segment_length=20.0, min_chip_thickness=0.0)
    assert len(maps[-1].engaged_slices) == 6 and maps[-1].rubbing_slices == 0
    assert_agree(moves, {1: tool}, stock, max_segment_length=20.0)


def test_agrees_with_brep_cl_by_cl_on_a_real_program():
    """The first CLs of a Fusion post (fusion-posted/1117_wall_28bit.nc, the stock the runner infers):
    the engines agree CL by CL. A volume integral whose break points left out a sweep bounding a
    sliver of the removed region was 3.5e-5 off on its CL 9."""
    from itertools import islice

    from shared_data import DATA

    from fusioncut.io.readers import read_toolpath
    from fusioncut.io.stock import infer_stock

    path = DATA / "fusion-posted" / "1117_wall_28bit.nc"
    if not path.is_file():
        pytest.skip("shared data missing")
    toolpath = read_toolpath(path)
    stock = infer_stock(toolpath)
    options = EngineOptions(slice_height=1.0)
    ours = list(islice(AnalyticEngine(options).run(toolpath, stock), 12))
    theirs = list(islice(BRepEngine(options).run(toolpath, stock), 12))
    assert sum(m.removed_volume > 0 for m in ours) >= 6
    for a, b in zip(ours, theirs):
        assert a.status == b.status, a.cl_index
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=VOLUME_REL, abs=1e-9), a.cl_index
        assert a.ap == pytest.approx(b.ap, abs=1e-9), a.cl_index
        assert a.contact_area == pytest.approx(b.contact_area, rel=BREP_AREA_REL, abs=1e-9), a.cl_index
        assert len(a.slices) == len(b.slices), a.cl_index
        for s, t in zip(a.slices, b.slices):
            assert_same_intervals(intervals(s), intervals(t), ANGLE_TOL)


@pytest.mark.parametrize("engine", [AnalyticEngine, BRepEngine])
@pytest.mark.parametrize("path", ["along x", "at 37 degrees, 3 decimals"])
def test_tapered_ball_in_a_v_groove_closed_form(path, engine):
    """A V-bit (half-angle g) cuts a groove of depth Dv; a tapered ball (ball radius r, cone at b
    from the axis tangent to the ball) then runs deeper (tip at -d) along the same line. The groove
    leaves material at |y| > w(z) = (Dv - d + z) tan g across the path at z above the tip, so the slice
    of radius rho(z) holds material on its front half where |cos(immersion)| > w / rho: immersion (0,
    a) and (180 - a, 180), a = acos(w / rho); the whole front half where w <= 0. The contact ends
    where w = rho on the cone, and a CL of length L inside removes L times the cross-section between
    the groove's V and the tool's outline (ball arc, then cone), in closed form. A post rounds the
    path's two points (3 decimals) for both passes alike; the CL checked is one in the middle of the
    second pass, cut into 10 mm CLs along the same line."""
    r, b, g, Dv, d = 1.5, math.radians(15.0), math.radians(45.0), 4.0, 6.0
    tool = AptCutter(2 * r * math.cos(b), 20, apt_parameters=AptParameters(2 * r * math.cos(b), r, 0.0, r, 0.0,
                                                                            math.degrees(b), 20))
    vbit = ChamferMill(20, 20, taper_angle=math.degrees(g))
    stock = BoxStock((-50, -50, -20), (50, 50, 0))
    turn = 0.0 if path == "along x" else 37.0
    ends = [rot((x, 0.0, 0.0), turn) for x in (-60.0, 60.0)]
    if path != "along x":
        ends = [(round(p[0], 3), round(p[1], 3), 0.0) for p in ends]
    (x0, y0, _), (x1, y1, _) = ends
    moves = [feed((x0, y0, -Dv), (x1, y1, -Dv), tool=2), feed((x1, y1, -Dv), (x1, y1, 5), tool=2),
             feed((x1, y1, 5), (x0, y0, 5)), feed((x0, y0, 5), (x0, y0, -d)), feed((x0, y0, -d), (x1, y1, -d))]
    _, maps = run(moves, {1: tool, 2: vbit}, stock, engine, slice_height=0.25, min_chip_thickness=0.0,
                  max_segment_length=10.0)
    last = min(maps[-12:], key=lambda m: math.hypot(*m.position[:2]))  # the second pass's CL ending at the middle
    assert last.engine == engine(EngineOptions()).kind.value  # each engine's maps say which made them
    cot_b, cot_g = 1 / math.tan(b), 1 / math.tan(g)
    yj, zj = r * math.cos(b), r * (1 - math.sin(b))  # where the cone meets the ball (mm from the axis, above the tip)
    yc = (Dv - d + zj - yj * cot_b) / (cot_g - cot_b)  # where the groove's side meets the cone
    top = zj + (yc - yj) * cot_b  # the contact's top above the tip
    assert last.ap == pytest.approx(top, abs=1e-9)
    assert len(last.engaged_slices) == math.ceil(top / 0.25)
    for s in last.engaged_slices:
        rho = math.sqrt(r * r - (r - s.z) ** 2) if s.z < zj else yj + (s.z - zj) * math.tan(b)
        assert s.radius == pytest.approx(rho, abs=1e-12)
        w = (Dv - d + s.z) * math.tan(g)
        a = math.degrees(math.acos(w / rho)) if w > 0 else 90.0
        expected = [(0.0, 180.0)] if w <= 0 else [(0.0, a), (180.0 - a, 180.0)]
        assert_same_intervals(intervals(s), expected, ANGLE_TOL)
    # the cross-section: 2 x the integral over 0..yc of the groove's floor less the tool's outline
    groove = -Dv * yc + 0.5 * cot_g * yc * yc
    ball = (r - d) * yj - (0.5 * yj * math.sqrt(r * r - yj * yj) + 0.5 * r * r * math.asin(yj / r))
    cone = (zj - d) * (yc - yj) + 0.5 * cot_b * (yc - yj) ** 2
    length = math.dist(last.start, last.position)
    assert last.removed_volume == pytest.approx(2 * (groove - ball - cone) * length, rel=VOLUME_REL)


def test_on_a_v_bits_steep_ramp_the_brep_engines_tool_copies_warn_and_miss_what_the_exact_sweep_removes():
    """The B-Rep engine sweeps a chamfer mill's ramp steeper than it steps (wave's move at line 27,
    isolated) as tool copies R/4 apart: their cones leave 1.61 mm ridges between them, it says so,
    and removes less than the exact sweep (the copies lie inside it)."""
    tool = ChamferMill(diameter=12.5, flute_length=16, taper_angle=22.5)
    moves = [feed((36, 0, -0.38395), (40, 0, -1.220484))]
    stock = BoxStock((20, -10, -6), (60, 10, 0))
    _, (exact,) = run(moves, {1: tool}, stock)
    _, (sampled,) = run(moves, {1: tool}, stock, engine=BRepEngine)
    assert exact.sweep_method == "exact" and not exact.warnings
    assert sampled.sweep_method == "sampled"
    assert any("material up to 1.61 mm high between them" in w for w in sampled.warnings), sampled.warnings
    assert 0 < sampled.removed_volume < 0.5 * exact.removed_volume


def test_a_contact_area_out_of_evaluations_comes_with_a_warning(monkeypatch):
    """A ball going down a ramp from 1 to 4 mm deep beside a slot 2 mm deep: its contact area converges with no
    warning; with its rule allowed only 20 evaluations (:data:`.area.MAX_EVALS`), the area comes with a
    warning giving its error estimate."""
    import fusioncut.engines.analytic.area as area

    up, across = LinearMove((0, 3, -2), (0, 3, 5), rapid=True, tool=1), LinearMove((0, 3, 5), (-40, 0, 5), rapid=True,
                                                                                 tool=1)
    moves = [feed((-40, 3, -2), (0, 3, -2)), up, across, feed((-40, 0, 5), (-40, 0, -1)), feed((-40, 0, -1), (0, 0, -4))]
    tools = {1: BallEndMill(10, 20)}
    stock = BoxStock((-60, -60, -20), (60, 60, 0))
    _, maps = run(moves, tools, stock, max_segment_length=20.0)
    assert maps[-1].contact_area > 0 and not any("contact area" in w for w in maps[-1].warnings)
    monkeypatch.setattr(area, "MAX_EVALS", 20)
    _, maps = run(moves, tools, stock, max_segment_length=20.0)
    assert any(w.startswith("contact area not converged: error estimate") for w in maps[-1].warnings)
