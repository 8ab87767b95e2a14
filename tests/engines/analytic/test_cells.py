"""The cells' bounds hold at every point, and leaving out the sweeps they rule out changes nothing."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import fusioncut.engines.analytic.contact as contact
import fusioncut.engines.analytic.engine as analytic
from fusioncut.engines.analytic.cells import cell_ceiling, cell_floor
from fusioncut.engines.analytic.flat import all_level_flat
from fusioncut.engines.analytic.partition import ADAPTIVE, FLAT, POLAR
from fusioncut.engines.analytic.polar import polar_applies
from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.analytic.sweeps import arc_row, line_row, sweep_lower, vertical_row
from fusioncut.engines.base import EngineOptions
from test_sweeps import TOOLS, coord  # the same tool families and coordinates


def _points(rect, n=9):
    x0, y0, x1, y1 = rect
    return [(x, y) for x in np.linspace(x0, x1, n) for y in np.linspace(y0, y1, n)]


def _check(row, lp, rect, attained=True):
    floor = cell_floor(row, lp.pieces, lp.radius, *rect, 0.0)
    ceiling = cell_ceiling(row, lp.pieces, lp.radius, *rect)
    values = [sweep_lower(row, lp.pieces, lp.radius, x, y, 0.0) for x, y in _points(rect)]
    finite = [v for v in values if math.isfinite(v)]
    if finite:
        assert floor <= min(finite) + 1e-12
    if math.isfinite(ceiling):
        assert all(math.isfinite(v) for v in values)  # the whole rectangle lies in the footprint
        assert max(values) <= ceiling + 1e-12
        if attained:
            assert max(values) >= ceiling - 1e-12  # a line's: attained at a corner
    return floor, ceiling


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(sorted(TOOLS)), a=st.tuples(coord, coord, coord), b=st.tuples(coord, coord, coord),
       c=st.tuples(coord, coord), size=st.tuples(st.floats(0.01, 6), st.floats(0.01, 6)))
@example(kind="ball", a=(0.0, 3.0, 0.0), b=(2.5, 3.0, 0.0), c=(0.0, 0.0), size=(1.0, 1.0))  # an edge on the footprint
def test_line_sweep_floor_and_ceiling_bound_it_over_a_cell(kind, a, b, c, size):
    _check(line_row(a, b, 0), lower_profile(TOOLS[kind]), (c[0], c[1], c[0] + size[0], c[1] + size[1]))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(sorted(TOOLS)), c=st.tuples(coord, coord), rho=st.floats(0.2, 8),
       a0=st.floats(-4, 4), sw=st.floats(-13, 13).filter(lambda v: abs(v) > 1e-3), z=st.tuples(coord, coord),
       q=st.tuples(coord, coord), size=st.tuples(st.floats(0.01, 6), st.floats(0.01, 6)))
def test_arc_sweep_floor_and_ceiling_bound_it_over_a_cell(kind, c, rho, a0, sw, z, q, size):
    start = (c[0] + rho * math.cos(a0), c[1] + rho * math.sin(a0), z[0])
    end = (c[0] + rho * math.cos(a0 + sw), c[1] + rho * math.sin(a0 + sw), z[1])
    row = arc_row(start, end, c, rho, a0, sw, 0)
    rect = (q[0], q[1], q[0] + size[0], q[1] + size[1])
    _check(row, lower_profile(TOOLS[kind]), rect, attained=False)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(sorted(TOOLS)), zx=st.booleans(), c=st.tuples(coord, coord, coord), rho=st.floats(0.2, 8),
       quarter=st.integers(-2, 1), f=st.tuples(st.floats(0, 1), st.floats(0, 1)).filter(lambda f: abs(f[0] - f[1]) > 1e-3),
       q=st.tuples(coord, coord), size=st.tuples(st.floats(0.01, 6), st.floats(0.01, 6)))
def test_vertical_arc_sweep_floor_and_ceiling_bound_it_over_a_cell(kind, zx, c, rho, quarter, f, q, size):
    """A ZX / YZ arc within one quarter of its circle: its floor is a line's between its ends, its ceiling
    the least of its ends' tools that hold the cell."""
    a0, a1 = ((quarter + v) * math.pi / 2 for v in f)
    si = 0 if zx else 1

    def point(a):
        p = [c[0], c[1], c[2] + rho * math.sin(a)]
        p[si] += rho * math.cos(a)
        return tuple(p)

    row = vertical_row(point(a0), point(a1), c[si], zx, rho, a0, a1 - a0, 0)
    rect = (q[0], q[1], q[0] + size[0], q[1] + size[1])
    _check(row, lower_profile(TOOLS[kind]), rect, attained=False)


@pytest.mark.parametrize("kind", ["flat", "ball", "bullnose"])
def test_a_helix_turn_over_a_small_cell_is_bounded_by_its_nearby_part(kind):
    """Over a 0.1 mm cell under a helix of several turns the floor is the lowest turn's nearby tip
    (not the helix's lowest tip), and the ceiling the tool's height there: the turns above it are
    then ruled out for the cell."""
    lp = lower_profile(TOOLS[kind])
    c, rho, turns, pitch = (0.0, 0.0), 8.0, 3, 1.0
    sw = 2 * math.pi * turns
    row = arc_row((rho, 0.0, 0.0), (rho, 0.0, -pitch * turns), c, rho, 0.0, sw, 0)
    rect = (-0.05, rho - 0.05, 0.05, rho + 0.05)  # under the path at a quarter turn
    floor, ceiling = _check(row, lp, rect, attained=False)
    # the path passes over the cell's centre at 1/4, 5/4 and 9/4 turns, lowest at 9/4 (z = -2.25);
    # the floor takes the tips within the tool's reach of the cell about it (the helix's own
    # lowest tip is -3), the ceiling the tool there (its corners 0.0707 mm off the axis)
    reach = math.asin((lp.radius + 0.0708) / rho) if lp.radius + 0.0708 < rho else math.pi
    assert -2.25 - pitch * reach / (2 * math.pi) - 1e-9 <= floor < -2.25
    assert ceiling <= -2.25 + lp.f(0.0708) + 1e-9


def test_a_pass_retraced_lower_lies_under_the_first():
    """Of two level passes along the same path the lower one lies under the higher wherever it
    reaches, so the higher is left out; a pass beside it, or an arc, is kept."""
    from fusioncut.engines.analytic.cells import relevant_sweeps

    lp = lower_profile(TOOLS["flat"])
    rows = np.array([line_row((0, 0, -2), (10, 0, -2), 0), line_row((0, 0, -4), (10, 0, -4), 0),
                     line_row((0, 1, -3), (10, 1, -3), 0),
                     arc_row((5, 0, -1), (0, 5, -1), (0, 0), 5.0, 0.0, math.pi / 2, 0)])
    PP, NPC, RR = lp.pieces[None], np.array([len(lp.pieces)]), np.array([lp.radius])
    own = line_row((-5, 0, -6), (20, 0, -6), 0)
    cell = (-20.0, -20.0, 30.0, 20.0)  # no sweep holds it: no ceiling
    _, keep, _ = relevant_sweeps(*cell, own, lp.pieces, lp.radius, rows, PP, NPC, RR, -20.0, 0.0, 0.0,
                                 0, math.inf, np.empty(0))
    assert keep.tolist() == [False, True, True, True]
    _, keep, _ = relevant_sweeps(*cell, own, lp.pieces, lp.radius, rows, PP, NPC, RR, -20.0, 0.0, 0.0,
                                 10, math.inf, np.empty(0))
    assert keep.all()  # as many as that: not looked for
    _, keep, _ = relevant_sweeps(*cell, own, lp.pieces, lp.radius, rows, PP, NPC, RR, -20.0, 0.0, 0.0,
                                 0, 3, np.empty(0))
    assert keep.all()  # more than `most`: not looked for either (the caller quarters the cell)


def test_a_cl_whose_footprint_a_deeper_pass_holds_removes_nothing():
    """held_below: an earlier line sweep holding the CL's whole footprint with its top at or below the
    CL's lowest tip (a flat pass 3 mm lower; a ball's pass whose top, R above its tips, is at the CL's
    tip, under the same ball), or retraced by it higher up; not a pass beside it, a lower CL, a wider
    tool, an arc."""
    from fusioncut.engines.analytic.cells import held_below

    flat, ball = lower_profile(TOOLS["flat"]), lower_profile(TOOLS["ball"])
    PP = np.zeros((2, max(len(flat.pieces), len(ball.pieces)), 6))
    PP[0, :len(flat.pieces)], PP[1, :len(ball.pieces)] = flat.pieces, ball.pieces
    NPC, RR = np.array([len(flat.pieces), len(ball.pieces)]), np.array([flat.radius, ball.radius])
    R = flat.radius

    def held(own, *rows, radius=R):
        return held_below(own, radius, np.array(rows), PP, NPC, RR)

    deep = line_row((0, 0, -5), (10, 0, -5), 0)
    assert held(line_row((2, 0, -2), (8, 0, -2), 0), deep)
    assert held(line_row((0, 0, -5), (10, 0, -5), 0), deep)  # the same pass again
    assert not held(line_row((2, 0.01, -2), (8, 0.01, -2), 0), deep)
    assert not held(line_row((2, 0, -6), (8, 0, -6), 0), deep)
    assert not held(line_row((2, 0, -2), (8, 0, -2), 0), deep, radius=R + 0.1)
    ball_deep = line_row((0, 0, -5 - ball.radius), (10, 0, -5 - ball.radius), 1)
    assert held(line_row((2, 0, -5), (8, 0, -5), 1), ball_deep, radius=ball.radius)
    # its top is above this CL's tip, but the CL goes over its path higher up (_retraces)
    assert held(line_row((2, 0, -5.5), (8, 0, -5.5), 1), ball_deep, radius=ball.radius)
    assert not held(line_row((2, 0, -8.5), (8, 0, -5.5), 1), ball_deep, radius=ball.radius)
    assert not held(line_row((2, 0, -5), (8, 0, -5), 0), ball_deep)  # the flat end mill is wider
    assert not held(arc_row((5, 0, -2), (0, 5, -2), (0, 0), 5.0, 0.0, math.pi / 2, 0), deep)


def _arc(rho, a0, sw, z, tool=0, center=(0.0, 0.0)):
    start = (center[0] + rho * math.cos(a0), center[1] + rho * math.sin(a0), z)
    end = (center[0] + rho * math.cos(a0 + sw), center[1] + rho * math.sin(a0 + sw), z)
    return arc_row(start, end, center, rho, a0, sw, tool)


def test_an_arc_cl_whose_footprint_a_deeper_arc_holds_removes_nothing():
    """held_below for arcs: an earlier arc about the same centre whose circle is within the tools'
    radii' difference and whose angles hold the CL's (a full turn holds any), its top at or below
    the CL's lowest tip (a contour's spring pass, a circle retraced higher)."""
    from fusioncut.engines.analytic.cells import held_below

    flat = lower_profile(TOOLS["flat"])
    PP, NPC, RR = flat.pieces[None], np.array([len(flat.pieces)]), np.array([flat.radius])

    def held(own, *rows, radius=flat.radius):
        return held_below(own, radius, np.array(rows), PP, NPC, RR)

    circle, half = _arc(10, 0.0, 2 * math.pi, -5), _arc(10, 0.0, math.pi, -5)
    quarter = _arc(10, math.pi / 4, math.pi / 2, -2)
    assert held(quarter, circle) and held(quarter, half) and held(_arc(10, math.pi / 4, math.pi / 2, -5), half)
    assert held(_arc(10, 2 * math.pi + 3 * math.pi / 4, -math.pi / 2, -2), half)  # clockwise, a turn on
    assert not held(_arc(10, 3 * math.pi / 4, math.pi / 2, -2), half)  # beyond its end
    assert not held(_arc(10.01, math.pi / 4, math.pi / 2, -2), circle)  # off its circle
    assert not held(_arc(10, math.pi / 4, math.pi / 2, -2, center=(0.0, 0.01)), circle)  # another centre
    assert not held(_arc(10, math.pi / 4, math.pi / 2, -6), circle)  # below it
    assert not held(quarter, circle, radius=flat.radius + 0.1)  # a wider tool
    assert not held(quarter, line_row((10, -20, -5), (10, 20, -5), 0))  # a line holds no arc here


def test_a_helix_of_a_turn_or_more_caps_h_over_a_cl_on_its_circle_at_its_lowest_turn():
    """footprint_ceiling: an earlier helix of a turn or more about the CL's centre, whose circle is within
    the tools' radii's difference of the CL's, passes over all of the CL's footprint on its lowest turn,
    so its lower surface there is at most that turn's highest tip plus f(R); a shorter arc holding it
    is bounded by its top; one that does not hold it gives no bound. held_below takes the same bound."""
    from fusioncut.engines.analytic.cells import footprint_ceiling, held_below

    for kind in ("flat", "ball"):
        lp = lower_profile(TOOLS[kind])
        PP, NPC, RR = lp.pieces[None], np.array([len(lp.pieces)]), np.array([lp.radius])
        rise = lp.radius if kind == "ball" else 0.0  # f(R)
        down = arc_row((10, 0, 0), (10, 0, -3), (0, 0), 10.0, 0.0, 6 * math.pi, 0)  # three turns, 1 mm each
        up = arc_row((10, 0, -3), (10, 0, 0), (0, 0), 10.0, 0.0, 6 * math.pi, 0)
        quarter = _arc(10, math.pi / 4, math.pi / 2, -3.5)

        def ceiling(row, own=quarter, radius=lp.radius):
            return footprint_ceiling(np.array([row]), 0, PP, NPC, RR, own, radius)

        assert ceiling(down) == pytest.approx(-2.0 + rise, abs=1e-12)  # its last turn's highest tip
        assert ceiling(up) == pytest.approx(-2.0 + rise, abs=1e-12)  # its first turn's
        assert ceiling(_arc(10, 0.0, math.pi, -1)) == pytest.approx(-1.0 + rise)  # half a turn: its top
        assert ceiling(_arc(10.5, 0.0, 6 * math.pi, -1)) == math.inf  # off the CL's circle by more than 0
        assert ceiling(down, radius=lp.radius + 0.1) == math.inf  # a wider tool
        assert ceiling(line_row((10, -20, -5), (10, 20, -5), 0)) == math.inf  # a line holds no arc here
        assert ceiling(line_row((0, 0, -5), (20, 0, -5), 0), own=line_row((5, 0, -4), (15, 0, -4), 0)) \
            == pytest.approx(-5.0 + rise)  # a line in a line: its top
        # a narrower tool's arc 0.05 mm off its circle (no retrace of its path): held where its lowest tip is
        # at or above that bound
        narrower = lp.radius - 0.05
        assert held_below(_arc(10.05, 1.0, 0.5, -2.0 + rise), narrower, np.array([down]), PP, NPC, RR)
        assert not held_below(_arc(10.05, 1.0, 0.5, -2.01 + rise), narrower, np.array([down]), PP, NPC, RR)


def _integrated_rows(monkeypatch, key) -> list:
    """A list that gets ``key`` of the CL's sweep row for every cell whose removed volume is integrated,
    adaptively (.volume) or in closed form (.flat)."""
    integrals = []
    adaptive, closed = analytic.removed_volume, analytic.flat_cells_volume
    monkeypatch.setattr(analytic, "removed_volume", lambda *a: integrals.append(key(a[5])) or adaptive(*a))
    monkeypatch.setattr(analytic, "flat_cells_volume", lambda *a: (a[1].any() and integrals.append(key(a[4])))
                        or closed(*a))
    return integrals


@pytest.mark.parametrize("offset", [0.0, 0.01])
def test_a_circle_retraced_higher_removes_what_sticks_out_of_it(monkeypatch, offset):
    """A 6 mm flat end mill's full circle of radius 10 mm 5 mm deep, then one ``offset`` mm wider 2 mm
    deep (plunged into by a rapid): the second pass removes the annulus the wider circle adds,
    pi ((13 + offset)² - 13²) x 2 mm³; retracing, its arcs are never integrated."""
    from tests.engines.analytic.test_engine import VOLUME_REL, run

    from fusioncut.model import ArcMove, BoxStock, FlatEndMill, LinearMove

    integrals = _integrated_rows(monkeypatch, lambda row: tuple(row[[0, 6]]))
    r = 10.0 + offset
    moves = [LinearMove((10, 0, 5), (10, 0, -5), rapid=True, tool=1),
             ArcMove((10, 0, -5), (10, 0, -5), feed=600.0, tool=1, center=(0, 0, -5), clockwise=False),
             LinearMove((10, 0, -5), (10, 0, 5), rapid=True, tool=1),
             LinearMove((10, 0, 5), (r, 0, 5), rapid=True, tool=1),
             LinearMove((r, 0, 5), (r, 0, -2), rapid=True, tool=1),
             ArcMove((r, 0, -2), (r, 0, -2), feed=600.0, tool=1, center=(0, 0, -2), clockwise=False)]
    _, maps = run(moves, {1: FlatEndMill(6, 20)}, BoxStock((-20, -20, -10), (20, 20, 0)), max_segment_length=8.0)
    first_up = next(i for i, m in enumerate(maps) if m.position == (10.0, 0.0, 5.0))
    second = sum(m.removed_volume for m in maps[first_up:])
    assert second == pytest.approx(math.pi * ((13.0 + offset) ** 2 - 13.0 ** 2) * 2.0, rel=VOLUME_REL, abs=1e-12)
    assert ((1.0, -2.0) in integrals) == (offset > 0)


@pytest.mark.parametrize("offset", [0.0, 0.01])
def test_a_slot_retraced_higher_removes_what_sticks_out_of_it(monkeypatch, offset):
    """A 6 mm slot 5 mm deep, then the same path 2 mm deep, ``offset`` mm aside: the second pass
    removes offset x 2 mm per mm of travel (0 when it retraces the slot, without an integral)."""
    from tests.engines.analytic.test_engine import VOLUME_REL, feed, run

    from fusioncut.model import BoxStock, FlatEndMill, LinearMove

    integrals = _integrated_rows(monkeypatch, lambda row: row[6])
    moves = [feed((-40, 0, -5), (40, 0, -5)), LinearMove((40, 0, -5), (40, 0, 5), rapid=True, tool=1),
             LinearMove((40, 0, 5), (-40, offset, 5), rapid=True, tool=1),
             LinearMove((-40, offset, 5), (-40, offset, -2), rapid=True, tool=1),
             feed((-40, offset, -2), (40, offset, -2))]
    _, maps = run(moves, {1: FlatEndMill(6, 20)}, BoxStock((-30, -20, -10), (30, 20, 0)), max_segment_length=20.0)
    second = [m for m in maps if m.position[2] == -2.0 and m.start[2] == -2.0]
    assert len(second) == 4
    assert sum(m.removed_volume for m in second) == pytest.approx(60.0 * offset * 2.0, rel=VOLUME_REL, abs=1e-12)
    assert (-2.0 in integrals) == (offset > 0)  # the retraced pass's CLs are never integrated


@pytest.mark.parametrize("start", [1512, pytest.param(8515, marks=pytest.mark.slow)])  # slow: without the culling
def test_culling_leaves_the_cls_as_they_were_on_a_real_program(monkeypatch, start):
    """fusion-posted/1117_wall_28bit.nc CLs 1512-1515: CLs that cross hundreds of earlier passes of a
    flat end mill, one with a sliver of 1.5e-6 mm³ between two earlier passes; CLs 8515-8516: a
    helical entry retraced in a hole cut 8 mm deeper before, 2,349 earlier chords around it. Computed
    with the cells' culling and quartering, and with every sweep that meets the footprint in one
    piece: the same volumes (to the integral's tolerance), contact ranges, areas and slices."""
    from itertools import islice

    from shared_data import DATA

    from fusioncut.io.readers import read_toolpath
    from fusioncut.io.stock import infer_stock

    path = DATA / "fusion-posted" / "1117_wall_28bit.nc"
    if not path.is_file():
        pytest.skip("shared data missing")
    toolpath = read_toolpath(path)
    stock = infer_stock(toolpath)

    def maps():
        eng = analytic.AnalyticEngine(EngineOptions(slice_height=1.0))
        eng.start(stock)
        return list(islice(eng.process(toolpath, start_at=start), 4 if start == 1512 else 2))

    culled = maps()
    every = contact.relevant_sweeps

    def keep_all(*args):
        empty, keep, floors = every(*args)
        return False, np.ones_like(keep), floors

    def whole_tiles(x0, y0, x1, y1, tile, S, P, R, C, CB, PP, NPC, RR, *rest):
        """One cell a tile, with every sweep whose box meets it (.partition.volume_cells' tiles)."""
        nx, ny = max(1, math.ceil((x1 - x0) / tile)), max(1, math.ceil((y1 - y0) / tile))
        xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
        cells, kinds, lists = [], [], []
        for i in range(nx):
            for j in range(ny):
                c = (xs[i], ys[j], xs[i + 1], ys[j + 1])
                meet = np.flatnonzero((CB[:, 0] <= c[2]) & (CB[:, 2] >= c[0]) & (CB[:, 1] <= c[3]) & (CB[:, 3] >= c[1]))
                flat = all_level_flat(S, P, C[meet], PP, NPC)
                polar = not flat and polar_applies(S, P, C[meet], PP, NPC)
                cells.append(c)
                kinds.append(FLAT if flat else (POLAR if polar else ADAPTIVE))
                lists.append(meet)
        starts = np.cumsum([0] + [len(m) for m in lists])
        return np.array(cells), np.array(kinds), starts, np.concatenate(lists).astype(np.int64)

    monkeypatch.setattr(analytic, "volume_cells", whole_tiles)
    monkeypatch.setattr(contact, "relevant_sweeps", keep_all)
    monkeypatch.setattr(analytic, "held_below", lambda *args: False)  # the retraced entry integrated too
    whole = maps()
    if start == 1512:
        assert sum(m.removed_volume > 0 for m in culled) >= 3
    for a, b in zip(culled, whole):
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=1e-8, abs=1e-10), a.cl_index
        assert a.ap == pytest.approx(b.ap, abs=1e-9)
        assert a.contact_area == pytest.approx(b.contact_area, rel=1e-7, abs=1e-9)
        assert len(a.slices) == len(b.slices)
        for s, t in zip(a.slices, b.slices):
            assert len(s.intervals) == len(t.intervals)
            for i, j in zip(s.intervals, t.intervals):
                assert (i.entry, i.exit) == pytest.approx((j.entry, j.exit), abs=1e-6)


def test_a_finishing_pass_grazing_the_last_one_removes_the_same_in_any_cells(monkeypatch):
    """The generated ball spiral (benchmarks/finishing_programs.py) CLs 7-8: each pass grazes the one
    before, leaving thin crescents of removed material (micrometres deep, a tenth of a millimetre
    wide) between long stretches where nothing is removed. Integrated over tiles of 4 tool radii and
    of half a radius, the stretches and their probes lie elsewhere, yet the volumes agree to the
    integral's tolerance: no crescent is stepped over (with 9 probes a stretch and no search of the
    margin's dips, 5e-6 mm³ of CL 7 came and went with the tiling). The integral runs at a hundredth
    of the default tolerance, so that its own error (a few 1e-9 of the volume at the default 1e-8)
    is far below what the check must see."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))
    from finishing_programs import load

    toolpath, stock, _ = load("gen_spiral_ball")

    def volumes(tile_radii):
        monkeypatch.setattr(analytic, "TILE_RADII", tile_radii)
        eng = analytic.AnalyticEngine(EngineOptions(), volume_rel=1e-10, volume_tol=1e-12)
        eng.start(stock)
        maps = eng.process(toolpath, start_at=7)
        return [next(maps).removed_volume for _ in range(2)]

    for a, b in zip(volumes(4.0), volumes(0.5)):
        assert a > 10 and a == pytest.approx(b, rel=1e-9)


def test_a_sweep_retracing_an_earlier_path_at_or_above_it():
    """_retraces: a line on an earlier line's path, at or above it at both ends (both heights are
    linear along it); a helix piece on an earlier helix about the same centre and radius, at or above
    one of its turns at the same angles. The same tool only; beyond the path, off it or below it, no."""
    from fusioncut.engines.analytic.cells import _retraces

    ramp = line_row((0.0, 0.0, 0.0), (10.0, 5.0, -2.0), 0)
    assert _retraces(ramp, line_row((2.0, 1.0, -0.4), (6.0, 3.0, -1.2), 0))  # on it
    assert _retraces(ramp, line_row((6.0, 3.0, 1.0), (2.0, 1.0, -0.3), 0))  # above, backwards
    assert _retraces(ramp, line_row((4.0, 2.0, 0.0), (4.0, 2.0, -0.8), 0))  # a plunge onto it
    assert not _retraces(ramp, line_row((2.0, 1.0, -0.41), (6.0, 3.0, -1.2), 0))  # below at one end
    assert not _retraces(ramp, line_row((2.0, 1.0, 0.0), (12.0, 6.0, 0.0), 0))  # beyond its end
    assert not _retraces(ramp, line_row((2.0, 1.0 + 1e-9, 0.0), (6.0, 3.0 + 1e-9, 0.0), 0))  # beside it
    assert not _retraces(ramp, line_row((2.0, 1.0, -0.4), (6.0, 3.0, -1.2), 1))  # another tool
    plunge = line_row((1.0, 1.0, 5.0), (1.0, 1.0, -3.0), 0)
    assert _retraces(plunge, line_row((1.0, 1.0, 2.0), (1.0, 1.0, -3.0), 0))
    assert not _retraces(plunge, line_row((1.0, 1.0, 2.0), (1.0, 1.0, -3.5), 0))

    def helix(a0, sw, z0, z1, rho=2.0, tool=0):
        s = (1.0 + rho * math.cos(a0), rho * math.sin(a0), z0)
        e = (1.0 + rho * math.cos(a0 + sw), rho * math.sin(a0 + sw), z1)
        return arc_row(s, e, (1.0, 0.0), rho, a0, sw, tool)

    bore = helix(0.0, 6 * math.pi, 0.0, -6.0)  # three turns down, 1 mm a radian / pi
    assert _retraces(bore, helix(0.5, 0.2, -0.5 / math.pi, -0.7 / math.pi))  # a piece of it
    assert _retraces(bore, helix(0.5 + 2 * math.pi, 0.2, 0.0, -0.1))  # a turn on, higher than its second turn
    assert _retraces(bore, helix(0.7, -0.2, 1.0, 1.0))  # level above, clockwise
    assert not _retraces(bore, helix(0.5, 0.2, -5.0, -5.1))  # below its last turn there
    assert not _retraces(bore, helix(6 * math.pi - 0.1, 0.2, -6.0, -6.0))  # beyond its end
    assert not _retraces(bore, helix(0.5, 0.2, 0.0, 0.0, rho=2.0 + 1e-9))
    assert not _retraces(bore, helix(0.5, 0.2, 0.0, 0.0, tool=1))


def test_a_steep_helical_entry_run_twice_removes_nothing_the_second_time(monkeypatch):
    """The second run of a steep helical entry and its ramp out retraces the first: its CLs remove 0
    with none of them integrated (held_below), the first run's volume unchanged."""
    from fusioncut.model import ArcMove, BoxStock, FlatEndMill, LinearMove, Toolpath

    def entry():
        s = (4.0, 0.0, 0.0)
        return [LinearMove((4.0, 0.0, 3.0), s, feed=300.0, tool=1),
                ArcMove(s, (4.0, 0.0, -4.0), feed=600.0, tool=1, center=(3.0, 0.0, 0.0), clockwise=False),
                LinearMove((4.0, 0.0, -4.0), (9.0, 0.0, -5.0), feed=600.0, tool=1),
                LinearMove((9.0, 0.0, -5.0), (9.0, 0.0, 3.0), feed=300.0, tool=1, rapid=True)]

    stock = BoxStock((-20, -20, -20), (20, 20, 0))
    options = EngineOptions(chord_tolerance=0.02)
    once = list(analytic.AnalyticEngine(options).run(Toolpath(tuple(entry()), {1: FlatEndMill(6, 20)}), stock))
    assert sum(m.removed_volume for m in once) > 50
    integrals = _integrated_rows(monkeypatch, lambda row: row[6])
    engine = analytic.AnalyticEngine(options)
    engine.start(stock)
    again = list(engine.process(Toolpath(tuple(entry() * 2), {1: FlatEndMill(6, 20)}), start_at=len(once)))
    assert len(again) == len(once) and all(m.removed_volume == 0.0 for m in again)
    assert integrals == []
