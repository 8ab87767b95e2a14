"""A round bar stock (:class:`CylinderStock`): the analytic engine takes the bar's outside as a sweep
cut before the first CL (:func:`.sweeps.outside_row`). Closed forms (a contour around the bar, a
facing pass across it), the B-Rep engine CL by CL, resuming, and the workpiece's mesh."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fusioncut.engines.analytic.cells import cell_ceiling, cell_floor
from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.analytic.sweeps import outside_row, sweep_floor, sweep_lower
from fusioncut.engines.base import EngineOptions
from fusioncut.io.mesh import mesh_volume
from fusioncut.model import ArcMove, BallEndMill, CylinderStock, FlatEndMill, LinearMove, Toolpath
from tests.engines.analytic.test_engine import (AREA_REL, VOLUME_REL, assert_agree, assert_same_intervals, feed,
                                                intervals, run)

RB = 20.0  # the bar's radius (mm), about the origin, z from -10 to 0
BAR = CylinderStock((0.0, 0.0, -10.0), RB, 10.0)
PIECE = np.zeros((1, 6))  # a tool table entry the outside's kernels do not read


def test_the_outsides_lower_surface_and_its_bounds():
    row = outside_row((1.0, 2.0), 5.0, -11.0, 0)
    assert sweep_lower(row, PIECE, 1.0, 1.0, 2.0, 0.0) == math.inf
    assert sweep_lower(row, PIECE, 1.0, 6.0 - 1e-9, 2.0, 0.0) == math.inf
    assert sweep_lower(row, PIECE, 1.0, 6.0, 2.0, 0.0) == -11.0
    assert sweep_lower(row, PIECE, 1.0, 6.0 - 1e-9, 2.0, 1e-8) == -11.0  # eps widens it inward
    assert sweep_floor(row, PIECE, 1.0, 9.0, 9.0, 0.0) == -11.0
    # a cell within the circle: neither bound; reaching beyond it: the floor; wholly beyond: both
    assert cell_floor(row, PIECE, 1.0, 0.0, 1.0, 2.0, 3.0, 0.0) == math.inf
    assert cell_floor(row, PIECE, 1.0, 4.0, 1.0, 7.0, 3.0, 0.0) == -11.0
    assert cell_ceiling(row, PIECE, 1.0, 4.0, 1.0, 7.0, 3.0) == math.inf
    assert cell_ceiling(row, PIECE, 1.0, 6.5, 1.0, 7.0, 3.0) == -11.0


def contour(decimals, ae=1.0, ap=5.0, R=3.0, start_deg=37.0):
    """A plunge at radius ``RB + R - ae`` then half a turn counter-clockwise about the bar's axis at
    ``ap`` below its top, the ends' coordinates rounded to ``decimals`` as a post writes them."""
    rho = RB + R - ae
    a = math.radians(start_deg)
    s = (rho * math.cos(a), rho * math.sin(a), -ap)
    e = (-s[0], -s[1], -ap)
    if decimals is not None:
        s, e = (tuple(round(c, decimals) for c in p) for p in (s, e))
    return [LinearMove((s[0], s[1], 5.0), s, feed=300.0, tool=1),
            ArcMove(s, e, feed=600.0, tool=1, center=(0.0, 0.0, -ap), clockwise=False)]


@pytest.mark.parametrize("decimals", [None, 3])
def test_contour_around_a_bar_closed_form(decimals):
    """Contouring a bar of radius Rb at radial depth ae with a flat end mill of radius R (path radius
    rho = Rb + R - ae): once past the plunge, every slice is engaged from the new surface's tangent
    point over beta, cos beta = (rho² + R² - Rb²) / (2 rho R) (less than on a straight wall: the bar
    is convex), and a CL turning by d_alpha removes d_alpha / 2 (Rb² - (rho - R)²) ap."""
    R, ap = 3.0, 5.0
    moves = contour(decimals, ap=ap, R=R)
    rho = math.hypot(*moves[1].start[:2])
    beta = math.degrees(math.acos((rho ** 2 + R ** 2 - RB ** 2) / (2 * rho * R)))
    eng, maps = run(moves, {1: FlatEndMill(2 * R, 20)}, BAR, max_segment_length=5.0)
    arc = [m for m in maps if m.cl_index >= 2]
    assert len(arc) == 14 and all(m.engine == "analytic" for m in maps)
    d_alpha = math.pi / len(arc)
    for m in arc:
        assert m.ap == pytest.approx(ap, abs=1e-9)
        slices = m.engaged_slices
        assert slices
        for s in slices:
            (entry, exit_), = intervals(s)
            assert (exit_ - entry) % 360 == pytest.approx(beta, abs=0.005)
        if decimals is None:
            assert m.removed_volume == pytest.approx(0.5 * d_alpha * (RB ** 2 - (rho - R) ** 2) * ap, rel=VOLUME_REL)
            assert m.contact_area == pytest.approx(R * math.radians(beta) * ap, rel=AREA_REL)
    removed = sum(m.removed_volume for m in maps)
    assert eng.stock_volume == pytest.approx(math.pi * RB ** 2 * 10.0, rel=1e-15)
    assert eng.ipw_volume == pytest.approx(eng.stock_volume - removed, rel=1e-15)


def _strip(y):
    """The integral of the bar's chord length 2 sqrt(Rb² - y²) from 0 to y (mm²)."""
    return y * math.sqrt(RB * RB - y * y) + RB * RB * math.asin(y / RB)


@pytest.mark.parametrize("y0", [0.0, 15.5, -18.0])
def test_facing_across_a_bar_closed_form(y0):
    """A 6 mm flat end mill 1 mm deep straight across the bar at y0 removes the disc's strip
    |y - y0| <= 3 times 1 mm; where it is wholly on the bar it slots (half the circle). Near the
    bar's side (y0 = -18) the strip's edge runs out of the bar."""
    R, depth = 3.0, 1.0
    moves = [LinearMove((-40.0, y0, 5.0), (-40.0, y0, -depth), feed=300.0, tool=1),
             feed((-40.0, y0, -depth), (40.0, y0, -depth))]
    eng, maps = run(moves, {1: FlatEndMill(2 * R, 20)}, BAR, max_segment_length=4.0)
    lo, hi = max(y0 - R, -RB), min(y0 + R, RB)
    assert sum(m.removed_volume for m in maps) == pytest.approx(depth * (_strip(hi) - _strip(lo)), rel=VOLUME_REL)
    inside = [m for m in maps if abs(m.position[0]) < 8.0 and abs(m.start[0]) < 8.0]  # well within the bar
    assert len(inside) >= 2
    for m in inside:
        for s in m.engaged_slices:
            spans = [(b - a) % 360 for a, b in intervals(s)]
            if abs(y0) + R < RB:
                assert spans == [pytest.approx(180.0, abs=0.005)]
            else:  # the bar's side cuts the half circle short
                assert 0.0 < sum(spans) < 180.0


def ball_across_the_side():
    """A 6 mm ball end mill 2 mm deep along y = 17 (its reach to y = 20 grazes the bar's side), then
    3 mm deep back along y = 14."""
    return [LinearMove((-30.0, 17.0, 5.0), (-30.0, 17.0, -2.0), feed=300.0, tool=1),
            feed((-30.0, 17.0, -2.0), (30.0, 17.0, -2.0)),
            feed((30.0, 17.0, -2.0), (30.0, 14.0, -3.0)),
            feed((30.0, 14.0, -3.0), (-30.0, 14.0, -3.0))]


def test_a_ball_meeting_the_bars_side_touches_from_where_its_slice_reaches_it():
    """CL 2 ends at (-15, 17, -2), the ball beside the bar: it touches from the height where its
    slice's radius reaches |c| - Rb up to the bar's top, 2 mm above its tip."""
    _, maps = run(ball_across_the_side(), {1: BallEndMill(6, 20)}, BAR, max_segment_length=7.5)
    assert maps[2].position == (-15.0, 17.0, -2.0)
    low = 3.0 - math.sqrt(9.0 - (math.hypot(15.0, 17.0) - RB) ** 2)
    assert maps[2].axial_range == pytest.approx((low, 2.0), abs=1e-9)


def test_agrees_with_brep_on_a_rounded_contour_and_a_ball_across_the_bars_side():
    """CL by CL; the ball's CLs end where its contact begins at its tip (the B-Rep engine finds a
    contact that begins on the bar's side ~3e-5 mm off, its faces' tolerance: the closed form above
    checks that case)."""
    assert_agree(contour(3, ae=1.5), {1: FlatEndMill(6, 20)}, BAR, max_segment_length=8.0)
    assert_agree(ball_across_the_side(), {1: BallEndMill(6, 20)}, BAR, max_segment_length=10.0)


def test_starting_later_and_a_checkpoint_give_the_same_maps(tmp_path):
    tools = {1: FlatEndMill(6, 20)}
    moves = contour(3)
    tp = Toolpath(tuple(moves), tools)
    _, whole = run(moves, tools, BAR, max_segment_length=5.0)
    eng = AnalyticEngine(EngineOptions(max_segment_length=5.0))
    eng.start(BAR)
    it = eng.process(tp)
    for _ in range(6):
        next(it)
    eng.save_checkpoint(tmp_path, 6)
    resumed = AnalyticEngine(EngineOptions(max_segment_length=5.0))
    assert resumed.load_checkpoint(tmp_path) == 6
    assert resumed.stock_model() == BAR
    later = list(resumed.process(tp, start_at=6))
    assert [m.cl_index for m in later] == [m.cl_index for m in whole[6:]]
    for a, b in zip(later, whole[6:]):
        assert a.removed_volume == b.removed_volume
        assert [intervals(s) for s in a.slices] == [intervals(s) for s in b.slices]
    assert resumed.ipw_volume == pytest.approx(math.pi * RB ** 2 * 10.0 - sum(m.removed_volume for m in whole),
                                               rel=1e-12)


def test_the_workpiece_mesh_is_the_bar_less_its_cuts():
    """The mesh holds nothing outside the bar; its volume is the bar's less the cuts' to the
    grid's resolution (a 0.25 mm grid: its walls, a chord per grid square, off by ~1 %)."""
    moves = [LinearMove((-40.0, 0.0, 5.0), (-40.0, 0.0, -1.0), feed=300.0, tool=1),
             feed((-40.0, 0.0, -1.0), (40.0, 0.0, -1.0))]
    eng, maps = run(moves, {1: FlatEndMill(6, 20)}, BAR, max_segment_length=20.0)
    tri = eng.ipw_mesh(step=0.25)
    assert tri[:, :, 2].max() == 0.0
    outside = np.hypot(tri[:, :, 0], tri[:, :, 1]) > RB + 0.5
    assert np.all(tri[:, :, 2][outside] == -10.0)
    assert mesh_volume(tri) == pytest.approx(eng.ipw_volume, rel=0.01)


def test_a_cl_the_analytic_engine_cannot_compute_is_computed_by_the_brep_engine_on_the_bar(monkeypatch):
    """The fallback's local workpiece is the bar (not its box) less the earlier CLs: the CL it
    computes agrees with the analytic one to 1e-6 mm³ and 0.001°."""
    tools = {1: FlatEndMill(6, 20)}
    _, want = run(contour(3), tools, BAR, max_segment_length=5.0)
    real = AnalyticEngine._removed
    calls = {"n": 0}

    def removed(self, *args):
        calls["n"] += 1
        if calls["n"] == 8:
            raise RuntimeError("a stand-in for a numerical failure")
        return real(self, *args)

    monkeypatch.setattr(AnalyticEngine, "_removed", removed)
    _, got = run(contour(3), tools, BAR, max_segment_length=5.0)
    fell = [m for m in got if m.engine == "brep"]
    assert len(fell) == 1 and fell[0].removed_volume > 1.0
    k = fell[0].cl_index
    assert got[k].removed_volume == pytest.approx(want[k].removed_volume, abs=1e-6)
    assert len(got[k].slices) == len(want[k].slices)
    for s, t in zip(got[k].slices, want[k].slices):
        assert_same_intervals(intervals(s), intervals(t), 0.001)
    assert [m.removed_volume for m in got if m.cl_index != k] == [m.removed_volume for m in want if m.cl_index != k]
