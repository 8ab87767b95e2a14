"""Layered cells: the 2.5D stack against closed forms, against the solid it stands for, and the
layered engine against the all-solid engine on random flat-end-mill programs."""
from __future__ import annotations

import math
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from OCP.BRepAlgoAPI import BRepAlgoAPI_Common, BRepAlgoAPI_Cut
from hypothesis import strategies as st

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep import engine as engine_mod
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.brep.solid_cut import SolidCutter
from fusioncut.engines.brep.layers import cut_stack, solid_layers, stack_solid, stack_volume
from fusioncut.engines.brep.occ import MERGE_TOLERANCE, area, max_tolerance, volume
from fusioncut.engines.brep.stock import stock_solid
from fusioncut.engines.brep.sweep import cylinder_region, swept_volume
from fusioncut.model import ArcMove, BallEndMill, BoxStock, CLStatus, FlatEndMill, LinearMove, Toolpath

BLOCK = BoxStock((0.0, 0.0, -10.0), (40.0, 30.0, 0.0))
FUZZY = (0.0, 1e-6)


def box_layers():
    layers = solid_layers(stock_solid(BLOCK), 6)
    assert layers is not None and len(layers) == 1
    return layers


def test_a_box_is_one_layer():
    (layer,) = box_layers()
    assert (layer.z_lo, layer.z_hi) == (-10.0, 0.0)
    assert layer.area == pytest.approx(1200.0, rel=1e-12)
    assert layer.volume == pytest.approx(BLOCK.volume, rel=1e-12)


def test_a_plunge_and_a_slot_take_the_closed_form_volumes():
    r = 3.0
    disk = cylinder_region(r, LinearMove((10.0, 15.0, 2.0), (10.0, 15.0, 0.0)))  # regions lie at z = 0
    layers, removed, cuts = cut_stack(box_layers(), disk, -4.0, 20.0, FUZZY)
    assert removed == pytest.approx(math.pi * r * r * 4.0, rel=1e-9)
    assert [(la.z_lo, la.z_hi) for la in layers] == [(-10.0, -4.0), (-4.0, 0.0)]
    assert len(cuts) == 1
    # a slot from the hole, 2 mm deeper: a stadium 2 mm deep under the hole's floor, and the
    # stadium less the hole's disk 4 mm above it
    line = LinearMove((10.0, 15.0, 0.0), (25.0, 15.0, 0.0))
    stadium = cylinder_region(r, line)
    layers, removed, _ = cut_stack(layers, stadium, -6.0, 20.0, FUZZY)
    area = 15.0 * 2 * r + math.pi * r * r
    assert removed == pytest.approx(area * 2.0 + (area - math.pi * r * r) * 4.0, rel=1e-9)
    # the hole's layer and the slot's are now one region: joined
    assert [(la.z_lo, la.z_hi) for la in layers] == [(-10.0, -6.0), (-6.0, 0.0)]
    assert stack_volume(layers) == pytest.approx(BLOCK.volume - math.pi * r * r * 4.0 - removed, rel=1e-12)
    # the same cut again removes nothing
    again, nothing, cuts = cut_stack(layers, stadium, -6.0, 20.0, FUZZY)
    assert nothing == 0.0 and cuts == [] and again == layers


def test_a_cut_must_reach_above_the_stack():
    with pytest.raises(ValueError):
        cut_stack(box_layers(), cylinder_region(3.0, LinearMove((5, 5, 1), (5, 5, 0))), -5.0, -1.0, FUZZY)


def test_the_solid_of_a_stack_is_layered_back_the_same():
    layers = box_layers()
    for z, p0, p1 in ((-3.0, (5, 5, 0), (30, 8, 0)), (-5.0, (12, 20, 0), (12, 20, 0)), (-1.0, (0, 25, 0), (35, 25, 0))):
        layers, _, _ = cut_stack(layers, cylinder_region(4.0, LinearMove(p0, p1)), z, 30.0, FUZZY)
    solid = stack_solid(layers)
    assert volume(solid) == pytest.approx(stack_volume(layers), rel=1e-9)
    back = solid_layers(solid, 6)
    assert back is not None
    assert [(la.z_lo, la.z_hi) for la in back] == [(la.z_lo, la.z_hi) for la in layers]
    for a, b in zip(back, layers):
        assert a.area == pytest.approx(b.area, rel=1e-9)


def test_a_ball_end_cut_is_not_layered():
    solid = stock_solid(BLOCK)
    from fusioncut.engines.brep.occ import BRepAlgoAPI_Cut

    sweep = swept_volume(BallEndMill(6.0, 20.0), LinearMove((5, 15, -2), (30, 15, -2))).shape
    assert solid_layers(BRepAlgoAPI_Cut(solid, sweep).Shape(), 6) is None
    flat = swept_volume(FlatEndMill(6.0, 20.0), LinearMove((5, 15, -2), (30, 15, -2))).shape
    assert solid_layers(BRepAlgoAPI_Cut(solid, flat).Shape(), 6) is not None


def _same(a, b):
    assert a.status == b.status, a.cl_index
    assert a.removed_volume == pytest.approx(b.removed_volume, rel=1e-6, abs=1e-9)
    assert a.contact_area == pytest.approx(b.contact_area, rel=1e-6, abs=1e-9)
    assert [s.z for s in a.slices] == pytest.approx([s.z for s in b.slices], abs=1e-9)
    for sa, sb in zip(a.slices, b.slices):
        assert len(sa.intervals) == len(sb.intervals), (a.cl_index, sa.intervals, sb.intervals)
        for ia, ib in zip(sa.intervals, sb.intervals):
            # on the circle: a sliver of a wall at 0° may come as [359.99994, 360] or [0, 0.00006]
            assert abs(math.remainder(ia.entry - ib.entry, 360.0)) <= 1e-3, (a.cl_index, ia, ib)
            assert abs(math.remainder(ia.exit - ib.exit, 360.0)) <= 1e-3, (a.cl_index, ia, ib)


# on a 0.5 mm grid, as programs are: with arbitrary floats hypothesis found holes offset by 1-15 µm,
# where the solid and the layered kernels' slivers differ by 1e-6..3e-4 mm³ (the solid engine alone
# then broke conservation by 1.6e-5 mm³ once) - the kernel's tolerance, not the layers, is tested there
point = st.tuples(st.integers(-10, 90).map(lambda k: 0.5 * k), st.integers(-10, 70).map(lambda k: 0.5 * k),
                  st.sampled_from([-1.0, -2.5, -4.0]))


# derandomized: a fresh CI run once drew the programs below (KNOWN_SOLID_FAILURES), where the
# all-solid engine's Boolean is wrong and the layered one right; they are kept as an expected
# failure until the solid path handles them, and CI draws the same programs every run
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(points=st.lists(point, min_size=2, max_size=5), arc=st.sampled_from([None, 4.0, 6.0]), cell_size=st.sampled_from([None, 15.0]))
def test_layered_cells_equal_solid_cells(points, arc, cell_size):
    """Random flat-end-mill programs (plunges, lines, an arc; several depths): the layered engine
    gives the all-solid engine's results CL by CL, and both conserve volume. An arc (a half turn)
    has the tool's radius (4 mm) or more."""
    _layered_equals_solid(points, arc, cell_size)


KNOWN_SOLID_FAILURES = [
    # the solid engine's CLs 2-4 found nothing removed (first silently air or wrong volumes,
    # conservation 3.2e-5; then FAILED: a point ahead of the tool's axis lay in material); swept
    # with the tool at their start in, the maps equal the layered engine's, but a later CL's
    # Boolean (fuzzy 1e-6, across the y = 15 wall) leaves 3.1e-5 mm³ of volume noise, 2.6e-9 of
    # the stock (1.1e-5 with the same CL cut from the layered engine's state made solid)
    ([(34.0, 4.5, -2.5), (36.5, 24.5, -1.0)], 4.0, 15.0),
    # found by a random search of 160 programs: a plunge split into CLs, its hole tangent to the
    # stock's wall x = 0; the second step down finds nothing removed while the point on its axis
    # lies in material, also with the seams turned and joined with a neighbour: a FAILED CL (the
    # probe on the axis finds it). Sweeping only the part below the last CL's tip (tried) fails too:
    # the new cylinder is tangent to the same wall
    ([(4.0, 10.5, -4.0), (40.0, 2.0, -1.0), (34.5, 21.5, -2.5), (2.5, 8.0, -1.0), (17.5, 28.5, -1.0)], None, 15.0),
]


@pytest.mark.xfail(strict=True, reason="solid cells' Booleans go wrong on these (the layered cells are right)")
@pytest.mark.parametrize("points, arc, cell_size", KNOWN_SOLID_FAILURES)
def test_layered_cells_equal_solid_cells_where_solid_booleans_fail(points, arc, cell_size):
    _layered_equals_solid(points, arc, cell_size)


def test_a_slot_on_a_cell_wall_tangent_to_a_plunge_hole_is_cut_joined_with_the_neighbour(monkeypatch):
    """A slot from a plunge at (34, 4.5) to the stock's edge: its side lies on the 15 mm column's
    wall x = 30 and is tangent to the plunge's hole. The solid cell's General Fuse found nothing
    inside and rebuilt the cell 25 mm³ larger, at every fuzzy value and with the seams turned;
    joined with the cell beside it the Boolean is right: the same maps as the layered engine."""
    joins = []
    real = SolidCutter.subtract_joined

    def spy(self, cell, *args):
        joins.append(cell.square)
        return real(self, cell, *args)

    monkeypatch.setattr(SolidCutter, "subtract_joined", spy)
    _layered_equals_solid([(34.0, 4.5, -1.0), (34.0, 0.0, -1.0)], None, 15.0)
    assert joins == [(30.0, 0.0, 15.0)]


def test_halves_split_a_solid_at_a_wall():
    from fusioncut.engines.brep.cells import halves
    from fusioncut.engines.brep.stock import stock_solid

    block = stock_solid(BLOCK)  # 40 x 30 x 10 mm
    below, above = halves(block, 1, 12.0)
    assert volume(below) == pytest.approx(40 * 12 * 10, rel=1e-12) and volume(above) == pytest.approx(40 * 18 * 10, rel=1e-12)
    below, above = halves(block, 0, 45.0)
    assert volume(below) == pytest.approx(BLOCK.volume, rel=1e-12) and above is None


def test_a_line_out_of_a_plunge_hole_tangent_to_the_stock_wall_is_cut_with_the_start_swept_in(monkeypatch):
    """Found by a random search of 120 programs: the plunge's hole is tangent to the stock's wall
    x = 0; the lines out of it, swept without the tool at their start (the last CL emptied it),
    found nothing removed while the point ahead of the tool lay in material, at every fuzzy value,
    with the seams turned and joined with either neighbour (before the front probe, CL 2 was
    silently air). Swept with the tool at the start in, they cut what the layered cells cut."""
    calls = []
    real = engine_mod.swept_volume

    def spy(tool, motion, method="exact", seam=0.0, open_start=False):
        calls.append((seam, open_start))
        return real(tool, motion, method, seam, open_start)

    monkeypatch.setattr(engine_mod, "swept_volume", spy)
    _layered_equals_solid([(4.0, 8.0, -2.5), (11.0, 4.0, -2.5)], 4.0, 15.0)
    retried = [k for k in range(len(calls) - 2) if calls[k][1] and calls[k + 1][1] and not calls[k + 2][1]
               and calls[k + 1][0] == pytest.approx(calls[k][0] + math.pi / 2) and calls[k + 2][0] == calls[k][0]]
    assert retried  # open, seams turned, then the start swept in


def test_neighbours_share_a_wall_of_positive_length():
    from fusioncut.engines.brep.cells import Cell, Square, neighbours

    eng = BRepEngine(EngineOptions(cell_size=20.0))
    eng.start(BoxStock((0.0, 0.0, -10.0), (40.0, 40.0, 0.0)))
    cell = next(c for c in eng.cells if c.square == (0.0, 0.0, 20.0))
    eng.cells = [c for c in eng.cells if c.square[0] == 0.0]  # (0, 0) and (0, 20)
    for square in ((20.0, 0.0, 10.0), (20.0, 10.0, 10.0), (20.0, 20.0, 10.0), (-20.0, -20.0, 20.0)):
        n = Cell(None, None, square=Square(*square))
        n.set(cell.shape)  # any material: only the squares count
        eng.cells.append(n)
    found = {(n.square, axis, at) for n, axis, at in neighbours(eng.cells, cell)}
    assert found == {((0.0, 20.0, 20.0), 1, 20.0), ((20.0, 0.0, 10.0), 0, 20.0), ((20.0, 10.0, 10.0), 0, 20.0)}


def _layered_equals_solid(points, arc, cell_size):
    moves = [LinearMove((points[0][0], points[0][1], 5.0), points[0], tool=1, feed=500.0)]
    for a, b in zip(points, points[1:]):
        if a[:2] != b[:2]:
            moves.append(LinearMove(a, (b[0], b[1], a[2]), tool=1, feed=500.0))
        moves.append(LinearMove((b[0], b[1], a[2]), b, tool=1, feed=500.0))
    if arc:
        end = moves[-1].end
        moves.append(ArcMove(end, (end[0] + 2 * arc, end[1], end[2]), center=(end[0] + arc, end[1], end[2]),
                             tool=1, feed=500.0))
    program = Toolpath(tuple(moves), {1: FlatEndMill(8.0, 25.0, number=1)})
    runs = {}
    for layers in (True, False):
        # a failed CL's shapes go to a temporary folder, not into the folder the tests run in
        engine = BRepEngine(EngineOptions(max_segment_length=4.0, cell_size=cell_size, layers=layers,
                                          failure_dir=Path(tempfile.gettempdir()) / "fusioncut-test-failures"))
        runs[layers] = list(engine.run(program, BLOCK))
        assert not [m for m in runs[layers] if m.status == CLStatus.FAILED]
        assert abs(engine.stock_volume - engine.ipw_volume - engine.removed_total) <= 1e-9 * engine.stock_volume
    for a, b in zip(runs[True], runs[False], strict=True):
        _same(a, b)


def test_an_arc_only_grazed_is_no_engagement_in_layers_either():
    """A slot along +x ends at the origin; a second slot along +y ends there too. Its front arc
    lies on the first slot's end wall for a quarter turn (zero chip: grazed) while it cuts new
    material behind: the layers must leave that quarter out, as the solids do."""
    tool = FlatEndMill(10.0, 20.0, number=1)
    moves = (LinearMove((-30, 0, -3), (0, 0, -3), tool=1, feed=500.0), LinearMove((0, 0, -3), (0, 0, 5), tool=1, rapid=True),
             LinearMove((0, -30, 5), (0, -30, -3), tool=1, feed=500.0), LinearMove((0, -30, -3), (0, 0, -3), tool=1, feed=500.0))
    stock = BoxStock((-20.0, -20.0, -10.0), (20.0, 20.0, 0.0))
    runs = {}
    for layers in (True, False):
        engine = BRepEngine(EngineOptions(max_segment_length=40.0, cell_size=None, layers=layers))
        runs[layers] = list(engine.run(Toolpath(moves, {1: tool}), stock))
    last = runs[True][-1]
    assert last.removed_volume > 0
    for a, b in zip(runs[True], runs[False], strict=True):
        _same(a, b)


def test_an_arc_of_the_tool_radius_cuts_the_same_in_solids():
    """Plunge, a step, a 1.5 mm deeper plunge, then a half turn of radius 4 with a 4 mm radius tool:
    the tool reaches 7.5 mm into the block on the last piece of the arc. The solid engine's face
    merge once left an 8 mm tolerance edge there (valid, right volume), and its next Booleans
    reported the 40.8 mm³ cut as air; merges that loosen an edge are now refused."""
    moves = (LinearMove((5.0, 0.0, 5.0), (5.0, 0.0, -1.0), tool=1, feed=500.0),
             LinearMove((5.0, 0.0, -1.0), (1.0, -0.5, -1.0), tool=1, feed=500.0),
             LinearMove((1.0, -0.5, -1.0), (1.0, -0.5, -2.5), tool=1, feed=500.0),
             ArcMove((1.0, -0.5, -2.5), (9.0, -0.5, -2.5), center=(5.0, -0.5, -2.5), tool=1, feed=500.0))
    program = Toolpath(moves, {1: FlatEndMill(8.0, 25.0, number=1)})
    runs = {}
    for layers in (True, False):
        engine = BRepEngine(EngineOptions(max_segment_length=4.0, cell_size=None, layers=layers))
        runs[layers] = []
        for m in engine.run(program, BLOCK):
            runs[layers].append(m)
            assert max_tolerance(engine.ipw) <= MERGE_TOLERANCE, m.cl_index
    assert runs[True][-1].removed_volume > 40.0
    for a, b in zip(runs[True], runs[False], strict=True):
        _same(a, b)


# -- a cut that starts where the last one ended leaves the start disk out of its region ----------------

@pytest.mark.parametrize("move", [
    LinearMove((10.0, 15.0, 0.0), (11.3, 15.4, 0.0)),
    ArcMove((10.0, 15.0, 0.0), (18.0, 15.0, 0.0), center=(14.0, 15.0, 0.0), clockwise=True),  # wide arc
    ArcMove((10.0, 15.0, 0.0), (11.0, 16.0, 0.0), center=(11.0, 15.0, 0.0), clockwise=True),  # tighter than r
])
def test_the_open_start_region_differs_from_the_swept_one_inside_the_start_disk_only(move):
    r = 3.0
    full, open_ = cylinder_region(r, move), cylinder_region(r, move, open_start=True)
    start_disk = cylinder_region(r, LinearMove((*move.start[:2], move.start[2] + 1.0), move.start))  # at z = 0 too
    # full ⊇ open ⊇ full − start disk: the open region adds nothing, and what it leaves out lies in
    # the start disk (and is not nothing)
    left_out = BRepAlgoAPI_Cut(full, open_).Shape()
    assert area(BRepAlgoAPI_Cut(open_, full).Shape()) == pytest.approx(0.0, abs=1e-9)
    assert area(BRepAlgoAPI_Cut(left_out, start_disk).Shape()) == pytest.approx(0.0, abs=1e-9)
    assert area(BRepAlgoAPI_Common(left_out, start_disk).Shape()) > 0.1 * math.pi * r * r


@pytest.mark.parametrize("layers", [True, False])
def test_a_cut_from_the_last_ones_end_disk_equals_the_full_sweep_on_a_trochoid(layers):
    """Consecutive chords of trochoidal loops: every CL after the first starts in the disk the last
    left empty. The engine as it runs (open regions, or open sweeps in solid cells) against one that
    never knows the last disk."""
    tool = FlatEndMill(6.0, 15.0, number=1)
    pts = [(2.0, 15.0, -3.0)]
    for k in range(60):
        t = 2 * math.pi * k / 20
        pts.append((5.0 + 0.12 * k + 2.0 * math.cos(t) - 2.0, 15.0 + 2.0 * math.sin(t), -3.0))
    moves = tuple(LinearMove(a, b, feed=600.0, tool=1) for a, b in zip(pts, pts[1:]))
    open_engine, closed = BRepEngine(EngineOptions(layers=layers)), BRepEngine(EngineOptions(layers=layers))
    open_engine.start(BLOCK)
    closed.start(BLOCK)
    opened = 0
    for index, move in enumerate(moves):
        opened += open_engine.cleared is not None
        a = open_engine.step(index, move, tool, 0.0)
        closed.cleared = None
        _same(a, closed.step(index, move, tool, 0.0))
    assert opened == len(moves) - 1
    assert any(c.layers for c in open_engine.cells) == layers  # the path meant was the one tested


def test_ball_rows_cut_from_the_last_ones_end_equal_the_whole_sweeps():
    """A ball end mill's finishing rows (1 mm lines, the next row 1.5 mm over and 0.05 mm lower): a
    line from where the last one ended leaves the ball's back half out of its sweep. Against an
    engine that never knows where the last tool stood, CL by CL. Every line starts where the last
    CL's tool stood (a row's first, where the plunge ended); no plunge does."""
    tool = BallEndMill(6.0, 15.0, number=2)
    moves = []
    for k in range(3):
        y, z = 12.0 + 1.5 * k, -1.0 - 0.05 * k
        moves.append(LinearMove((5.0, y, 2.0), (5.0, y, z), feed=300.0, tool=1))
        moves += [LinearMove((5.0 + j, y, z), (6.0 + j, y, z), feed=900.0, tool=1) for j in range(6)]
    open_engine, closed = BRepEngine(EngineOptions()), BRepEngine(EngineOptions())
    open_engine.start(BLOCK)
    closed.start(BLOCK)
    opened = 0
    for index, move in enumerate(moves):
        opened += open_engine.cleared is not None and (open_engine.cleared.x, open_engine.cleared.y, open_engine.cleared.z_lo) == move.start
        a = open_engine.step(index, move, tool, 0.0)
        closed.cleared = None
        _same(a, closed.step(index, move, tool, 0.0))
        assert a.status == CLStatus.ENGAGED
    assert opened == 3 * 6  # every line; plunges are not lines
    assert open_engine.ipw_volume == pytest.approx(closed.ipw_volume, rel=1e-9)


@pytest.mark.parametrize("layers", [True, False])
def test_a_cut_below_the_last_ones_end_keeps_its_whole_start_disk(layers):
    """A plunge to 1 mm, then a slot from the same XY but 3 mm deep: the disk the plunge left empty
    ends 1 mm down, so the slot's region must keep its start disk (closed form)."""
    tool, r = FlatEndMill(6.0, 15.0, number=1), 3.0
    moves = (LinearMove((10.0, 15.0, 5.0), (10.0, 15.0, -1.0), feed=300.0, tool=1),
             LinearMove((10.0, 15.0, -3.0), (25.0, 15.0, -3.0), feed=600.0, tool=1))
    engine = BRepEngine(EngineOptions(layers=layers))
    engine.start(BLOCK)
    plunge = engine.step(0, moves[0], tool, 0.0)
    assert engine.cleared[:3] == (10.0, 15.0, -1.0) and engine.cleared[4] == r
    slot = engine.step(1, moves[1], tool, 0.0)
    disk, stadium = math.pi * r * r, 15.0 * 2 * r + math.pi * r * r
    assert plunge.removed_volume == pytest.approx(disk * 1.0, rel=1e-9)
    assert slot.removed_volume == pytest.approx(stadium * 3.0 - disk * 1.0, rel=1e-9)


def _counting_cuts(monkeypatch):
    from fusioncut.engines.brep import layers as layers_module

    calls = []  # one per layer cut (tried in closed form first)
    real = layers_module._closed_form_cut

    def counted(*args):
        calls.append(1)
        return real(*args)

    monkeypatch.setattr(layers_module, "_closed_form_cut", counted)
    return calls


def test_a_region_already_taken_from_the_layers_above_is_cut_from_those_below_only(monkeypatch):
    """A slot 2 mm deep, then the same slot 5 mm deep: told the region went above -2 mm, the stack
    cuts one layer instead of two, with the same result (closed form)."""
    calls = _counting_cuts(monkeypatch)
    r = 3.0
    stadium = cylinder_region(r, LinearMove((10.0, 15.0, 0.0), (25.0, 15.0, 0.0)))
    area = 15.0 * 2 * r + math.pi * r * r
    first, _, _ = cut_stack(box_layers(), stadium, -2.0, 20.0, FUZZY)
    results = {}
    for clear_from in (None, -2.0):
        calls.clear()
        results[clear_from] = cut_stack(first, stadium, -5.0, 20.0, FUZZY, clear_from)
        assert len(calls) == (2 if clear_from is None else 1)
    for layers, removed, cuts in results.values():
        assert removed == pytest.approx(area * 3.0, rel=1e-9)
        assert [(la.z_lo, la.z_hi) for la in layers] == [(-10.0, -5.0), (-5.0, 0.0)]
        assert [(c.z_lo, c.z_hi) for c in cuts] == [(-5.0, -2.0)]


def test_a_contour_retraced_deeper_cuts_fewer_layers_and_the_same_material(monkeypatch):
    """A closed contour at -2 mm, then the same path at -4 and -6 mm (as contour passes come): the
    layered engine skips the layers the same path already cleared, and its results equal the
    all-solid engine's CL by CL."""
    path = [(5.0, 5.0), (30.0, 5.0), (30.0, 22.0), (5.0, 22.0), (5.0, 5.0)]
    moves = []
    for z in (-2.0, -4.0, -6.0):
        moves.append(LinearMove((5.0, 5.0, 5.0), (5.0, 5.0, z), tool=1, feed=300.0))
        moves += [LinearMove((*a, z), (*b, z), tool=1, feed=600.0) for a, b in zip(path, path[1:])]
    program = Toolpath(tuple(moves), {1: FlatEndMill(6.0, 15.0, number=1)})
    calls = _counting_cuts(monkeypatch)
    runs, counts = {}, {}
    from fusioncut.engines.brep import engine as engine_module

    real_cut_stack = engine_module.cut_stack
    for mode in ("remembered", "forgotten", "solid"):
        if mode == "forgotten":  # the same engine, told nothing about earlier regions
            monkeypatch.setattr(engine_module, "cut_stack", lambda *a: real_cut_stack(*a[:5]))
        calls.clear()
        engine = BRepEngine(EngineOptions(max_segment_length=4.0, cell_size=15.0, layers=mode != "solid"))
        runs[mode] = list(engine.run(program, BLOCK))
        counts[mode] = len(calls)
        assert abs(engine.stock_volume - engine.ipw_volume - engine.removed_total) <= 1e-9 * engine.stock_volume
    assert counts["solid"] == 0 and 0 < counts["remembered"] < counts["forgotten"]
    for a, b, c in zip(runs["remembered"], runs["forgotten"], runs["solid"]):
        _same(a, b)
        _same(a, c)


def test_a_split_that_loses_nothing_but_rebuilds_the_region_wrong_is_a_failure(monkeypatch):
    """A General Fuse reporting no lost piece and a kept region of another area (what the 3D kernel
    once did on a ball plunge) is no 'nothing lost': the cut fails, after every fuzzy value."""
    from fusioncut.engines.brep import layers as layers_module
    from fusioncut.engines.brep.layers import RegionCutFailure, _cut_region

    square = cylinder_region(5.0, LinearMove((0.0, 0.0, 0.0), (20.0, 0.0, 0.0)))
    smaller = cylinder_region(5.0, LinearMove((0.0, 0.0, 0.0), (10.0, 0.0, 0.0)))
    tool = cylinder_region(3.0, LinearMove((40.0, 0.0, 0.0), (50.0, 0.0, 0.0)))  # far away: nothing lost
    assert _cut_region(square, tool, area(square), (0.0,)) == (None, None, None)
    real = layers_module.split_pieces
    monkeypatch.setattr(layers_module, "split_pieces", lambda *a: (real(*a)[0], [], [smaller]))
    with pytest.raises(RegionCutFailure, match="disagree"):
        _cut_region(square, tool, area(square), (0.0, 1e-6))
