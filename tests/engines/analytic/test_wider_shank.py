"""Tools whose neck or shank is wider than their flutes: the analytic engine sweeps each wider
cylinder as one more part of the tool (closed forms, the B-Rep engine CL by CL, and the union of the
parts' sweeps against the same parts run one after the other)."""
from __future__ import annotations

import math

import pytest

from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.analytic.profile import upper_parts
from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.model import ArcMove, BallEndMill, BoxStock, FlatEndMill, LinearMove, Toolpath
from tests.engines.analytic.test_engine import (AREA_REL, VOLUME_REL, assert_agree, assert_same_intervals, feed,
                                                intervals, rot, run)


@pytest.mark.parametrize("tool, expected", [
    (FlatEndMill(6, 2), []),
    (FlatEndMill(6, 2, shank_diameter=4), []),  # narrower: taken at the flutes' width
    (FlatEndMill(6, 2, shank_diameter=10), [(2.0, 5.0)]),
    (FlatEndMill(6, 2, shank_diameter=10, neck_diameter=4, shoulder_length=8), [(8.0, 5.0)]),
    (FlatEndMill(6, 2, shank_diameter=10, neck_diameter=8, shoulder_length=8), [(2.0, 4.0), (8.0, 5.0)]),
    (FlatEndMill(6, 2, shank_diameter=7, neck_diameter=8, shoulder_length=8), [(2.0, 4.0)]),
    (BallEndMill(6, 4, shank_diameter=12), [(4.0, 6.0)]),
])
def test_upper_parts_are_the_cylinders_wider_than_all_below_them(tool, expected):
    parts = upper_parts(tool)
    assert [(p.height, p.profile.radius) for p in parts] == expected
    for p in parts:  # each a flat end mill of its radius
        assert p.profile.f(0.0) == 0.0 and p.profile.f(p.profile.radius) == 0.0


@pytest.mark.parametrize("decimals", [None, 3])
def test_slot_with_a_wider_shank_closed_form(decimals):
    """A 6 mm flat end mill with 2 mm of flutes on a 10 mm shank slots 3 mm deep at 37 degrees: per mm
    of travel the flutes take 6 x 2 mm² and the shank 10 x 1; the flutes touch on the half cylinder
    below 2 mm, the shank on its own half cylinder above; the B-Rep engine says the same CL by CL."""
    R, Rs = 3.0, 5.0
    tool = FlatEndMill(2 * R, 2.0, shank_diameter=2 * Rs)
    pts = [rot(p, 37.0) for p in ((-80, 0, -3.0), (-40, 0, -3.0), (0, 0, -3.0))]
    if decimals is not None:
        pts = [tuple(round(c, decimals) for c in p) for p in pts]
    moves = [feed(pts[0], pts[1]), feed(pts[1], pts[2])]
    stock = BoxStock((-60, -60, -20), (60, 60, 0))
    _, maps = run(moves, {1: tool}, stock, max_segment_length=20.0)
    last = maps[-1]
    length = math.dist(pts[1], pts[2]) / 2
    assert last.removed_volume == pytest.approx(length * (2 * R * 2.0 + 2 * Rs * 1.0), rel=VOLUME_REL)
    assert last.ap == pytest.approx(2.0, abs=1e-9)
    assert last.contact_area == pytest.approx(math.pi * R * 2.0, rel=AREA_REL)
    assert last.shank_contact_area == pytest.approx(math.pi * Rs * 1.0, rel=AREA_REL)
    assert any("shank" in w for w in last.warnings)
    for s in last.engaged_slices:  # the flutes' front half, as without the shank
        assert len(intervals(s)) == 1
        assert (intervals(s)[0][1] - intervals(s)[0][0]) % 360 == pytest.approx(180.0, abs=0.005)
    if decimals is None:
        assert_agree(moves, {1: tool}, stock, max_segment_length=20.0)


def wall_case():
    """A 20 mm flat end mill (T2) opens a channel |y| <= 10 mm, 10 mm deep, along x; then a 6 mm ball
    end mill (T1, 4 mm of flutes) on a 12 mm shank runs along it 6 mm deep at y = 6.5: its flutes
    reach y = 9.5 and meet nothing, its shank (from 2 mm below the top) reaches y = 12.5 and shaves
    2.5 mm off the wall's top 2 mm."""
    tools = {1: BallEndMill(6, 4, shank_diameter=12), 2: FlatEndMill(20, 30)}
    stock = BoxStock((-40, -30, -20), (40, 30, 0))
    moves = [LinearMove((-60, 0, -10), (60, 0, -10), feed=600.0, tool=2),
             LinearMove((60, 0, -10), (60, 0, 10), rapid=True, tool=2),
             LinearMove((-60, 6.5, 10), (-60, 6.5, -6), rapid=True, tool=1),
             feed((-60, 6.5, -6), (-20, 6.5, -6)), feed((-20, 6.5, -6), (20, 6.5, -6))]
    return tools, stock, moves


def test_a_shank_shaves_a_wall_its_flutes_do_not_reach():
    tools, stock, moves = wall_case()
    _, maps = run(moves, tools, stock, max_segment_length=20.0)
    last = maps[-1]
    assert last.removed_volume == pytest.approx(20.0 * 2.5 * 2.0, rel=VOLUME_REL)
    assert last.contact_area == 0.0 and not last.engaged_slices
    span = math.pi / 2 - math.asin(3.5 / 6.0)  # the shank's front quarter beyond y = 10
    assert last.shank_contact_area == pytest.approx(6.0 * span * 2.0, rel=AREA_REL)
    assert any("shank" in w for w in last.warnings)
    assert_agree(moves, tools, stock, max_segment_length=20.0)


def test_agrees_with_brep_with_a_wider_neck_and_shank_on_level_lines_and_an_arc():
    """A 6 mm ball on an 8 mm neck up to 5 mm and a 10 mm shank above: a slot 6 mm deep along x, a
    quarter arc, then a pass 2 mm beside the slot: each CL's volume, ap, areas and slices as the B-Rep
    engine's."""
    tool = BallEndMill(6, 3.5, shank_diameter=10, neck_diameter=8, shoulder_length=5)
    moves = [feed((-40, 0, -6), (0, 0, -6)),
             ArcMove((0, 0, -6), (10, -10, -6), feed=600.0, tool=1, center=(0, -10, -6), clockwise=True),
             LinearMove((10, -10, -6), (10, -10, 5), rapid=True, tool=1),
             LinearMove((10, -10, 5), (-40, 2, 5), rapid=True, tool=1),
             feed((-40, 2, 5), (-40, 2, -6)), feed((-40, 2, -6), (0, 2, -6))]
    assert_agree(moves, {1: tool}, BoxStock((-30, -30, -20), (30, 30, 0)), max_segment_length=10.0)


def test_a_narrower_neck_through_material_is_taken_as_wide_as_the_flutes_and_says_so():
    """A 6 mm ball on a 4 mm neck from 3.5 to 5 mm slotting 6 mm deep: the real neck leaves 1 mm
    ledges of the walls hanging over the slot between its heights, which no height field holds; the
    analytic engine cuts them as the flutes' width and warns (the B-Rep engine keeps them)."""
    tool = BallEndMill(6, 3.5, shank_diameter=10, neck_diameter=4, shoulder_length=5)
    moves = [feed((-40, 0, -6), (-10, 0, -6)), feed((-10, 0, -6), (0, 0, -6))]
    stock = BoxStock((-30, -30, -20), (30, 30, 0))
    _, ours = run(moves, {1: tool}, stock, max_segment_length=10.0)
    _, theirs = run(moves, {1: tool}, stock, engine=BRepEngine, max_segment_length=10.0)
    ledges = 2 * (3.0 - 2.0) * (5.0 - 3.5) * 10.0  # two ledges 1 x 1.5 mm over the last CL's 10 mm
    assert ours[-1].removed_volume - theirs[-1].removed_volume == pytest.approx(ledges, rel=1e-6)
    assert any("neck" in w for w in ours[-1].warnings)


def raised(moves, dz, tool):
    """``moves`` with every point raised by ``dz`` mm and run by ``tool``."""
    up = lambda p: (p[0], p[1], p[2] + dz)  # noqa: E731
    out = []
    for m in moves:
        if isinstance(m, ArcMove):
            out.append(ArcMove(up(m.start), up(m.end), feed=m.feed, tool=tool, center=up(m.center),
                               clockwise=m.clockwise))
        else:
            out.append(LinearMove(up(m.start), up(m.end), feed=m.feed, tool=tool, rapid=m.rapid))
    return out


HELIX_DOWN = [feed((-40, 0, 2), (-10, 0, -7)),
              ArcMove((-10, 0, -7), (-10, 0, -8), feed=600.0, tool=1, center=(-4, 0, -7), clockwise=False),
              feed((-10, 0, -8), (20, 5, -3))]
RAMPS = [feed((-40, 0, 2), (-10, 0, -7)), feed((-10, 0, -7), (-10, 8, -8)), feed((-10, 8, -8), (20, 5, -3))]


@pytest.mark.slow  # a minute each: ~120 CLs (the ramps' CLs are the B-Rep engine's steps)
@pytest.mark.parametrize("cutter, moves", [(FlatEndMill, HELIX_DOWN), (BallEndMill, RAMPS)],
                         ids=["flat, ramp, helix, ramp", "ball, three ramps"])
def test_ramps_and_a_helix_remove_the_union_of_the_cutter_and_the_shank(cutter, moves):
    """A 6 mm cutter on a 10 mm shank ramps down 7 mm into the stock, goes on down and ramps out: it
    removes what the same path removes with the cutter as wide as its flutes followed by the shank
    alone (a flat end mill of the shank's radius on the path raised by the flute length), to 1e-7."""
    R, Rs, flutes = 3.0, 5.0, 4.0
    stock = BoxStock((-30, -20, -20), (30, 20, 0))
    opts = dict(max_segment_length=8.0)
    _, whole = run(moves, {1: cutter(2 * R, flutes, shank_diameter=2 * Rs)}, stock, **opts)
    apart = moves + raised(moves, flutes, 2)
    _, split = run(apart, {1: cutter(2 * R, flutes), 2: FlatEndMill(2 * Rs, 30)}, stock, **opts)
    total = sum(m.removed_volume for m in whole)
    assert sum(m.removed_volume for m in split) == pytest.approx(total, rel=VOLUME_REL)
    shank_alone = sum(m.removed_volume for m in split[len(whole):])
    assert shank_alone > 10.0  # the shank does cut here
    assert sum(m.shank_contact_area > 0 for m in whole) >= 3


def test_a_shank_above_the_stock_changes_nothing():
    """Where the wider shank stays above the stock's top its sweeps are not even kept: the maps are
    those of the tool without it, bit for bit."""
    moves = [feed((-40, 0, -2), (0, 0, -2)),
             ArcMove((0, 0, -2), (10, -10, -2), feed=600.0, tool=1, center=(0, -10, -2), clockwise=True),
             feed((10, -10, -2), (10, -10, -3.5)), feed((10, -10, -3.5), (-30, 4, -3.5))]
    stock = BoxStock((-30, -30, -20), (30, 30, 0))
    a_eng, a = run(moves, {1: BallEndMill(6, 4, shank_diameter=12)}, stock, max_segment_length=10.0)
    b_eng, b = run(moves, {1: BallEndMill(6, 4)}, stock, max_segment_length=10.0)
    assert a_eng._index.size == b_eng._index.size
    for x, y in zip(a, b):
        assert x.removed_volume == y.removed_volume and x.contact_area == y.contact_area
        assert [intervals(s) for s in x.slices] == [intervals(s) for s in y.slices]


def test_a_moves_parts_stay_one_sweep_each_and_a_later_start_gives_the_same_maps():
    """The CLs of one move merge into one sweep per part of the tool though their rows interleave, and
    starting at a later CL (the earlier ones only indexed, both parts) gives the whole run's maps."""
    tools, stock, moves = wall_case()
    eng, whole = run(moves, tools, stock, max_segment_length=5.0)
    # T2's slot, its rapid up, T1's descent (its shank stays above the top down to -4: one part),
    # then T1's two feed moves along one line: one sweep for the cutter, one for the shank
    assert eng._index.size <= 6
    tp = Toolpath(tuple(moves), tools)
    later_eng = AnalyticEngine(EngineOptions(max_segment_length=5.0))
    later_eng.start(stock)
    start = len(whole) - 3
    later = list(later_eng.process(tp, start_at=start))
    for x, y in zip(later, whole[start:]):
        assert x.removed_volume == y.removed_volume
        assert x.shank_contact_area == y.shank_contact_area
        for s, t in zip(x.slices, y.slices):
            assert_same_intervals(intervals(s), intervals(t), 0.0)
