"""Level flat cuts in closed form, their volume (.flat) and contact area (.area.stepwise_area), against the
adaptive integrals (.volume, .area.contact_area) and closed forms."""
from __future__ import annotations

import math
import random
import sys
from pathlib import Path

import pytest

import fusioncut.engines.analytic.engine as analytic
from fusioncut.engines.analytic.flat import _circle_integral
from fusioncut.model import ArcMove, BallEndMill, BoxStock, CylinderStock, FlatEndMill, LinearMove
from tests.engines.analytic.test_engine import AREA_REL, VOLUME_REL, feed, run

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))


def _level_program(seed: int, decimals: int | None) -> list:
    """Random level lines and XY arcs of a flat end mill at three depths over a 40 x 30 mm box, each
    reached by rapids from above; coordinates rounded to ``decimals`` as a post writes them (None: not)."""
    rnd = random.Random(seed)

    def q(v: float) -> float:
        return v if decimals is None else round(v, decimals)

    moves = []
    for _ in range(14):
        z = rnd.choice((-1.0, -2.5, -4.0))
        p = (q(rnd.uniform(-18, 18)), q(rnd.uniform(-13, 13)), z)
        moves += [LinearMove((p[0], p[1], 5.0), p, rapid=True, tool=1)]
        if rnd.random() < 0.5:
            e = (q(rnd.uniform(-18, 18)), q(rnd.uniform(-13, 13)), z)
            moves.append(feed(p, e))
        else:  # an arc about a centre 2-8 mm away, a quarter to a full turn (end = start)
            r, a0 = rnd.uniform(2, 8), rnd.uniform(0, 2 * math.pi)
            c = (q(p[0] - r * math.cos(a0)), q(p[1] - r * math.sin(a0)), z)
            turn = rnd.choice((0.5 * math.pi, math.pi, 2 * math.pi))
            rr = math.hypot(p[0] - c[0], p[1] - c[1])  # the end on the radius the rounded start has
            e = p if turn == 2 * math.pi else (q(c[0] + rr * math.cos(a0 + turn)),
                                               q(c[1] + rr * math.sin(a0 + turn)), z)
            moves.append(ArcMove(p, e, feed=600.0, tool=1, center=c, clockwise=rnd.random() < 0.5))
            e = moves[-1].end
        moves.append(LinearMove(e, (e[0], e[1], 5.0), rapid=True, tool=1))
    return moves


def _both_ways(monkeypatch, moves, tools, stock, **opts):
    """The maps in closed form where .flat applies, and with every cell integrated adaptively."""
    calls = []
    closed = analytic.flat_cells_volume
    monkeypatch.setattr(analytic, "flat_cells_volume", lambda *a: calls.append(int(a[1].sum())) or closed(*a))
    _, flat_maps = run(moves, tools, stock, **opts)
    monkeypatch.setattr(analytic, "FLAT_FORMS", False)
    _, adaptive_maps = run(moves, tools, stock, **opts)
    return flat_maps, adaptive_maps, sum(calls)


@pytest.mark.parametrize("seed,decimals", [(1, None), (2, 3), (3, 3), (4, 4)])
def test_level_flat_cuts_in_closed_form_as_the_adaptive_integral(monkeypatch, seed, decimals):
    """Random level lines and arcs of a flat end mill, exact and rounded as posts write them: each
    CL's volume, contact areas and rubbing slices as the adaptive integrals find them (to their own
    tolerance)."""
    flat, adaptive, calls = _both_ways(monkeypatch, _level_program(seed, decimals), {1: FlatEndMill(6, 20)},
                                       BoxStock((-20, -15, -10), (20, 15, 0)), slice_height=1.0)
    assert calls >= 10  # cells integrated in closed form
    assert sum(m.removed_volume for m in flat) > 100
    for a, b in zip(flat, adaptive, strict=True):
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=VOLUME_REL, abs=1e-9), a.cl_index
        assert a.contact_area == pytest.approx(b.contact_area, rel=AREA_REL, abs=1e-9), a.cl_index
        assert a.shank_contact_area == pytest.approx(b.shank_contact_area, rel=AREA_REL, abs=1e-9), a.cl_index
        assert a.rubbing_slices == b.rubbing_slices
        assert a.engine == b.engine == "analytic"


def test_a_round_bar_and_another_tool_shape(monkeypatch):
    """A round bar's outside is level too; a ball's cut is not, and the cells it shapes are integrated
    adaptively, while the flat cuts before it in other cells stay in closed form."""
    moves = _level_program(5, 3)
    moves += [LinearMove((-18, 0, 5), (-18, 0, -1.5), rapid=True, tool=2), feed((-18, 0, -1.5), (18, 0, -1.5), tool=2)]
    bar = CylinderStock((0.0, 0.0, -10.0), 16.0, 10.0)
    flat, adaptive, calls = _both_ways(monkeypatch, moves, {1: FlatEndMill(6, 20), 2: BallEndMill(4, 20)}, bar,
                                       slice_height=1.0)
    assert calls >= 10  # cells integrated in closed form
    for a, b in zip(flat, adaptive, strict=True):
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=VOLUME_REL, abs=1e-9), a.cl_index


def test_a_slot_in_closed_form():
    """A 6 mm slot 3 mm deep along y across the whole 30 mm block, in 3 CLs whose ends lie inside it: the
    CLs remove the 6 x 30 mm strip 3 mm deep between them, each its own part of it."""
    moves = [LinearMove((0.0, -25.0, 5.0), (0.0, -25.0, -3.0), rapid=True, tool=1),
             feed((0.0, -25.0, -3.0), (0.0, 25.0, -3.0))]
    _, maps = run(moves, {1: FlatEndMill(6, 20)}, BoxStock((-20, -15, -10), (20, 15, 0)), max_segment_length=20.0)
    assert len([m for m in maps if m.removed_volume > 0]) == 3
    assert sum(m.removed_volume for m in maps) == pytest.approx(3.0 * 6.0 * 30.0, rel=1e-12)


def test_circle_integral_at_a_tangent_keeps_its_digits():
    """A cell's edge on a circle's extreme x (215.325 - 1.325 in floating point): the integral of the half
    chord over the first micron against its series in the distance v from the tangent point,
    sqrt(v (2r - v)) = sqrt(2 r v) sum_k binom(1/2, k) (-v / 2r)^k, integrated term by term."""
    cx, r, a, b = 215.325, 1.325, 214.0, 214.00096151669467

    def series(v: float) -> float:
        total, coeff = 0.0, 1.0
        for k in range(10):
            total += coeff * (-1.0 / (2 * r)) ** k * v ** (k + 1.5) / (k + 1.5)
            coeff *= (0.5 - k) / (k + 1)
        return math.sqrt(2 * r) * total

    exact = series(b - cx + r) - series(a - cx + r)
    assert _circle_integral(cx, r, a, b) == pytest.approx(exact, rel=1e-11)


@pytest.mark.parametrize("angle", [20.0, 30.0, 70.0])
def test_a_line_whose_end_circle_tops_its_footprint(monkeypatch, angle):
    """An inclined slot in the open: its footprint's box ends at its end circle's apex, which a cell's
    edge then meets at the middle of the part between the sides' ends (found on fusion-posted/1055_utab,
    CL 31: a closed form that decided the curves at that line alone lost the circle's upper branch)."""
    a = math.radians(angle)
    end = (round(12 * math.cos(a), 3), round(12 * math.sin(a), 3), -2.0)
    moves = [LinearMove((0.0, 0.0, 5.0), (0.0, 0.0, -2.0), rapid=True, tool=1), feed((0.0, 0.0, -2.0), end)]
    flat, adaptive, calls = _both_ways(monkeypatch, moves, {1: FlatEndMill(2.65, 20)},
                                       BoxStock((-20, -20, -10), (30, 30, 0)), slice_height=1.0)
    assert calls >= 1
    exact = 2.0 * (2.65 * math.hypot(end[0], end[1]) + math.pi * 1.325 ** 2)  # the slot: the plunge's disk and the line
    assert sum(m.removed_volume for m in flat) == pytest.approx(exact, rel=1e-12)
    for x, y in zip(flat, adaptive, strict=True):
        assert x.removed_volume == pytest.approx(y.removed_volume, rel=VOLUME_REL, abs=1e-9)


def test_real_level_flat_cuts_in_closed_form_as_the_adaptive_integral(monkeypatch):
    """fusion-posted/1055_utab_265bit.nc CLs 0-119 (a flat end mill's pocket at one depth, CL 31 the one
    above): each CL's volume and contact areas in closed form as the adaptive integrals find them."""
    import real_programs
    from shared_data import DATA

    if not (DATA / "fusion-posted" / "1055_utab_265bit.nc").is_file():
        pytest.skip("shared data missing")
    toolpath, stock, default = real_programs.load(next(p for p in real_programs.PROGRAMS if p.name == "1055_utab"))

    def first(n: int) -> list:
        engine = analytic.AnalyticEngine(analytic.EngineOptions())
        engine.start(stock)
        maps = engine.process(toolpath, default)
        return [next(maps) for _ in range(n)]

    closed = first(120)
    monkeypatch.setattr(analytic, "FLAT_FORMS", False)
    adaptive = first(120)
    assert sum(m.removed_volume for m in closed) > 100
    for a, b in zip(closed, adaptive, strict=True):
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=VOLUME_REL, abs=1e-9), a.cl_index
        assert a.contact_area == pytest.approx(b.contact_area, rel=AREA_REL, abs=1e-9), a.cl_index


def test_the_adaptive_integral_finds_a_sliver_between_curves_crossing_a_cell(monkeypatch):
    """fusion-posted/1117_wall_28bit.nc CL 1557 (an arc starting where a line ends, beside a pass 1 mm
    higher): in one cell the removed region is a band a few µm wide in x between the arc's inner circle
    and the line's side, both nearly along y there and with their extremes just outside the cell. No
    line of the outer rule met it (5.3e-4 mm³ lost, 2.2e-5 of the CL) until the curves' crossings of
    the cell's edges became break points; the closed form's volume is the reference."""
    import real_programs
    from shared_data import DATA

    if not (DATA / "fusion-posted" / "1117_wall_28bit.nc").is_file():
        pytest.skip("shared data missing")
    toolpath, stock, default = real_programs.load(next(p for p in real_programs.PROGRAMS if p.name == "1117_wall"))

    def cl_1557():
        engine = analytic.AnalyticEngine(analytic.EngineOptions())
        engine.start(stock)
        maps = engine.process(toolpath, default, start_at=1557)
        return next(maps)

    closed = cl_1557()
    monkeypatch.setattr(analytic, "FLAT_FORMS", False)
    adaptive = cl_1557()
    assert closed.cl_index == adaptive.cl_index == 1557
    assert closed.removed_volume > 20
    assert adaptive.removed_volume == pytest.approx(closed.removed_volume, rel=1e-8)


@pytest.mark.parametrize("seed,decimals", [(5, None), (6, 3)])
def test_slices_between_the_same_levels_are_scanned_once_and_hold_the_same_arcs(monkeypatch, seed, decimals):
    """A flat end mill's level CLs among level flat cuts: the slices between two heights where material
    may begin or end are scanned once (.engine._band); every slice's arcs are those a scan of each finds."""
    moves, tools = _level_program(seed, decimals), {1: FlatEndMill(6, 20)}
    stock = BoxStock((-20, -15, -10), (20, 15, 0))
    scans = []
    arcs_at = analytic._arcs_at
    monkeypatch.setattr(analytic, "_arcs_at", lambda *a: scans.append(1) or arcs_at(*a))
    _, banded = run(moves, tools, stock, slice_height=0.25)
    n_banded = len(scans)
    monkeypatch.setattr(analytic, "_band", lambda z, bounds: None)
    _, each = run(moves, tools, stock, slice_height=0.25)
    assert n_banded < 0.6 * (len(scans) - n_banded)  # far fewer scans
    assert sum(len(m.engaged_slices) for m in each) > 100
    for a, b in zip(banded, each, strict=True):
        assert a.slices == b.slices
