"""The material's height bounds: exact distances, and never a sweep called empty that cuts material."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusioncut.engines.ceiling import MaterialCeiling, footprint, tool_radii
from fusioncut.model import ArcMove, BallEndMill, FlatEndMill, LinearMove

coord = st.floats(-20.0, 20.0, allow_nan=False)


def path_points(fp, n=20001):
    """Dense points of a footprint's path (the brute-force distance's reference)."""
    t = np.linspace(0.0, 1.0, n)
    if fp.center is None:
        return fp.p0[0] + t * (fp.p1[0] - fp.p0[0]), fp.p0[1] + t * (fp.p1[1] - fp.p0[1])
    a = fp.start_angle + t * fp.sweep
    return fp.center[0] + fp.rho * np.cos(a), fp.center[1] + fp.rho * np.sin(a)


def brute_distance(fp, x, y):
    px, py = path_points(fp)
    return np.hypot(px[None, :] - x[:, None], py[None, :] - y[:, None]).min(axis=1)


@settings(max_examples=60, deadline=None)
@given(coord, coord, coord, coord, st.lists(st.tuples(coord, coord), min_size=1, max_size=20))
def test_segment_distance_is_exact(x0, y0, x1, y1, points):
    fp = footprint(LinearMove((x0, y0, -1.0), (x1, y1, -1.0), feed=100.0), FlatEndMill(6.0, 10.0))
    x, y = np.array([p[0] for p in points]), np.array([p[1] for p in points])
    got = fp.distance(x, y)
    step = math.hypot(x1 - x0, y1 - y0) / 20000
    assert np.all(got <= brute_distance(fp, x, y) + 1e-12)
    assert np.all(got >= brute_distance(fp, x, y) - step)


@settings(max_examples=60, deadline=None)
@given(st.floats(0.5, 10.0), st.floats(-math.pi, math.pi), st.floats(0.05, 2 * math.pi - 0.05), st.booleans(),
       st.lists(st.tuples(coord, coord), min_size=1, max_size=20))
def test_arc_distance_is_exact(rho, a0, span, clockwise, points):
    c = (1.0, -2.0, -1.0)
    a1 = a0 - span if clockwise else a0 + span
    start = (c[0] + rho * math.cos(a0), c[1] + rho * math.sin(a0), c[2])
    end = (c[0] + rho * math.cos(a1), c[1] + rho * math.sin(a1), c[2])
    fp = footprint(ArcMove(start, end, feed=100.0, center=c, clockwise=clockwise), FlatEndMill(6.0, 10.0))
    assert fp.sweep == pytest.approx(-span if clockwise else span, abs=1e-9)
    x, y = np.array([p[0] for p in points]), np.array([p[1] for p in points])
    got = fp.distance(x, y)
    step = rho * span / 20000
    assert np.all(got <= brute_distance(fp, x, y) + 1e-9)
    assert np.all(got >= brute_distance(fp, x, y) - step - 1e-9)


def test_tool_radii():
    assert tool_radii(FlatEndMill(12.0, 30.0)) == (6.0, 6.0, 54.0)
    # a neck thinner than the flutes: only the neck's cylinder is surely removed up to the top
    assert tool_radii(FlatEndMill(12.0, 30.0, shank_diameter=10.0))[:2] == (6.0, 5.0)
    # a rounded bottom removes no flat-bottomed cylinder: such tools never clear pixels
    reach, r_clear, _ = tool_radii(BallEndMill(10.0, 20.0))
    assert (reach, r_clear) == (5.0, None)


def moves_strategy():
    z = st.sampled_from([-1.0, -2.0, -3.0])
    pt = st.tuples(st.floats(0.0, 30.0), st.floats(0.0, 20.0))

    def line(a, b, zz):
        return LinearMove((a[0], a[1], zz), (b[0], b[1], zz), feed=100.0)

    def arc(a, rho, a0, span, zz):
        c = (a[0], a[1], zz)
        s = (c[0] + rho * math.cos(a0), c[1] + rho * math.sin(a0), zz)
        e = (c[0] + rho * math.cos(a0 + span), c[1] + rho * math.sin(a0 + span), zz)
        return ArcMove(s, e, feed=100.0, center=c)

    lines = st.builds(line, pt, pt, z)
    arcs = st.builds(arc, pt, st.floats(0.5, 6.0), st.floats(-3.0, 3.0), st.floats(0.1, 3.0), z)
    plunges = st.builds(lambda a, zz: LinearMove((a[0], a[1], 5.0), (a[0], a[1], zz), feed=100.0), pt, z)
    return st.lists(st.one_of(lines, arcs, plunges), min_size=1, max_size=12)


@settings(max_examples=40, deadline=None)
@given(moves_strategy())
def test_a_sweep_called_empty_never_holds_material(moves):
    """Brute force: material as sample points of a 30×20×4 block, removed exactly by each flat end
    mill sweep (within R of the path, above the tip). The bounds must stay above every point left, and
    a box the map calls empty for a sweep must hold no point strictly inside it."""
    tool = FlatEndMill(4.0, 10.0)
    R = tool.radius
    rng = np.random.default_rng(len(moves))
    pts = rng.uniform((0.0, 0.0, -4.0), (30.0, 20.0, 0.0), size=(20000, 3))
    ceiling = MaterialCeiling((0.0, 0.0), (30.0, 20.0), 0.0, pixel=0.25)
    boxes = [((x, y, -4.0), (x + 10.0, y + 10.0, 0.0)) for x in (0.0, 10.0, 20.0) for y in (0.0, 10.0)]
    for move in moves:
        fp = footprint(move, tool)
        z_tip = min(move.start[2], move.end[2])
        inside = (fp.distance(pts[:, 0], pts[:, 1]) < R - 1e-9) & (pts[:, 2] > z_tip + 1e-9)
        for (lo, hi), may in zip(boxes, ceiling.may_cut(fp, boxes)):
            in_box = np.all((pts >= lo) & (pts <= hi), axis=1)
            assert may or not np.any(inside & in_box), (move, lo)
        pts = pts[~inside]
        ceiling.clear(fp)
        i = np.floor((pts[:, 0] - ceiling.origin[0]) / ceiling.pixel).astype(int)
        j = np.floor((pts[:, 1] - ceiling.origin[1]) / ceiling.pixel).astype(int)
        assert np.all(pts[:, 2] <= ceiling.heights[i, j] + 1e-12)


def test_a_cleared_slot_is_empty_for_the_next_pass_but_not_for_a_deeper_one():
    tool = FlatEndMill(6.0, 20.0)
    ceiling = MaterialCeiling((0.0, 0.0), (40.0, 20.0), 0.0, pixel=0.1)
    box = [((0.0, 0.0, -10.0), (40.0, 20.0, 0.0))]
    for y in (9.0, 11.0):  # a slot 8 mm wide, walls at y = 6 and 14
        ceiling.clear(footprint(LinearMove((5.0, y, -2.0), (35.0, y, -2.0), feed=100.0), tool))
    inner = LinearMove((8.0, 10.5, -2.0), (30.0, 9.5, -2.0), feed=100.0)  # 0.5 mm or more inside the walls
    assert ceiling.may_cut(footprint(inner, tool), box) == [False]
    # along a wall: the pixels it cuts through were never wholly inside a sweep
    slot = LinearMove((5.0, 9.0, -2.0), (35.0, 9.0, -2.0), feed=100.0)
    assert ceiling.may_cut(footprint(slot, tool), box) == [True]
    deeper = LinearMove((8.0, 10.0, -2.5), (30.0, 10.0, -2.5), feed=100.0)
    assert ceiling.may_cut(footprint(deeper, tool), box) == [True]
    # a ball end mill is tested like any tool but proves nothing removed
    ball = footprint(slot, BallEndMill(6.0, 20.0))
    assert ball.r_clear is None
