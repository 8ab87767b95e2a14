"""The fast paths give the whole-IPW engine's results: IPW cells, and cells split among Dask workers."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.cl_maps import cl_sequence
from fusioncut.model import ArcMove, BoxStock, CLStatus, FlatEndMill, LinearMove, Toolpath

STOCK = BoxStock((0.0, 0.0, -12.0), (50.0, 40.0, 0.0))
ANGLE_TOL = 1e-3  # degrees: the bound between the fast path and the whole IPW
VOLUME_REL = 1e-6


def program() -> Toolpath:
    """Slots across cell walls, a trochoid (tight XY arcs) and a contour: every CL kind but ramps."""
    moves = []
    pts = [(-8.0, 9.0, -3.0), (58.0, 9.0, -3.0), (58.0, 21.0, -3.0), (-8.0, 21.0, -3.0)]
    moves += [LinearMove(a, b, feed=900.0, tool=1) for a, b in zip(pts, pts[1:])]
    x, y, z, r = 4.0, 31.0, -5.0, 2.0
    for k in range(12):  # trochoidal loops advancing 1.5 mm along +x
        c = (x + 1.5 * k + r, y, z)
        start = (x + 1.5 * k, y, z)
        mid = (c[0] + r, y, z)
        moves.append(ArcMove(start, mid, feed=900.0, tool=1, center=c))
        moves.append(ArcMove(mid, (start[0] + 1.5, y, z), feed=900.0, tool=1, center=(c[0] + 0.75, y, z)))
    moves.append(LinearMove(moves[-1].end, (30.0, 31.0, -5.0), feed=900.0, tool=1))
    return Toolpath(tuple(moves), {1: FlatEndMill(8.0, 20.0, number=1)})


def assert_same(fast, whole):
    assert [m.cl_index for m in fast] == [m.cl_index for m in whole]
    for a, b in zip(fast, whole):
        assert a.status == b.status, a.cl_index
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=VOLUME_REL, abs=1e-9)
        assert a.contact_area == pytest.approx(b.contact_area, rel=VOLUME_REL, abs=1e-9)
        assert len(a.slices) == len(b.slices)
        for sa, sb in zip(a.slices, b.slices):
            assert sa.z == pytest.approx(sb.z, abs=1e-9)
            assert len(sa.intervals) == len(sb.intervals), (a.cl_index, sa.intervals, sb.intervals)
            for ia, ib in zip(sa.intervals, sb.intervals):
                assert ia.entry == pytest.approx(ib.entry, abs=ANGLE_TOL)
                assert ia.exit == pytest.approx(ib.exit, abs=ANGLE_TOL)


def conserved(engine):
    """The issue's conservation bound: |stock - IPW - Σ removed| <= 1e-6 of the stock volume."""
    assert abs(engine.stock_volume - engine.ipw_volume - engine.removed_total) <= 1e-6 * engine.stock_volume


@pytest.fixture(scope="module")
def whole():
    """The reference: one solid, and every Boolean run in 3D (no height bounds, no layers)."""
    engine = BRepEngine(EngineOptions(max_segment_length=3.0, cell_size=None, fuzzy=1e-6, ceiling_pixel=None,
                                      layers=False))
    maps = list(engine.run(program(), STOCK))
    assert sum(m.status == CLStatus.ENGAGED for m in maps) > 20
    return maps


@pytest.mark.parametrize("cell_size", [10.0, 20.0])
def test_cells_equal_the_whole_workpiece(whole, cell_size):
    engine = BRepEngine(EngineOptions(max_segment_length=3.0, cell_size=cell_size, fuzzy=1e-6))
    fast = list(engine.run(program(), STOCK))
    assert len(engine.cells) > 1
    assert_same(fast, whole)
    conserved(engine)
    # at least one CL really was cut in two cells and joined again
    assert any(len(s.intervals) == 1 and s.intervals[0].exit - s.intervals[0].entry > 90 for m in fast
               for s in m.slices)


@pytest.mark.parametrize("cell_size", [None, 20.0])
def test_height_bounds_skip_air_and_change_nothing(whole, cell_size):
    engine = BRepEngine(EngineOptions(max_segment_length=3.0, cell_size=cell_size, fuzzy=1e-6))
    fast = list(engine.run(program(), STOCK))
    assert_same(fast, whole)
    conserved(engine)
    # the trochoid's return arcs run through its own cleared slot: no Boolean at all there
    skipped = [m for m in fast if "ceiling" in dict(m.timings_ms) and "boolean" not in dict(m.timings_ms)]
    assert len(skipped) >= 5


def test_cells_equal_the_whole_workpiece_on_a_helical_entry():
    """The entry's steps leave a floor of many levels across the cells' walls (the oblique sweeps
    this replaced made cell and whole-IPW Booleans disagree there)."""
    from test_helical_entry import STOCK as BLOCK, helical_entry

    runs = {}
    for cell_size, layers in ((None, False), (10.0, True)):
        engine = BRepEngine(EngineOptions(ramp_step=0.05, cell_size=cell_size, fuzzy=1e-6, layers=layers))
        runs[cell_size] = list(engine.run(helical_entry(), BLOCK))
        conserved(engine)
    assert_same(runs[10.0], runs[None])


def test_cell_checkpoint_round_trip(tmp_path):
    engine = BRepEngine(EngineOptions(max_segment_length=3.0, cell_size=10.0, fuzzy=1e-6))
    engine.start(STOCK)
    for _, _m in zip(range(6), engine.process(program())):
        pass
    engine.save_checkpoint(tmp_path, next_cl=6)
    again = BRepEngine(EngineOptions(max_segment_length=3.0, cell_size=10.0, fuzzy=1e-6))
    assert again.load_checkpoint(tmp_path) == 6
    assert len(again.cells) == len(engine.cells)
    assert again.ipw_volume == engine.ipw_volume


def test_dask_workers_equal_one_process(whole):
    pytest.importorskip("distributed")
    from fusioncut.engines.brep.parallel import ParallelBRepEngine

    with ParallelBRepEngine(EngineOptions(max_segment_length=3.0, cell_size=10.0, fuzzy=1e-6), workers=2, batch=7) as engine:
        maps = list(engine.run(program(), STOCK))
        conserved(engine)
    assert_same(maps, whole)


def test_dask_workers_cut_ahead_and_hand_over_the_workpiece_of_the_last_cl_handed_out(whole):
    """Batches of 2 CLs, 3 cut ahead: stopped after CL 9, the workers have cut further, yet the
    workpiece they hand over (its volume, its cells) is the one after CL 9; going on from there
    ends with the whole workpiece's maps."""
    pytest.importorskip("distributed")
    from fusioncut.engines.brep.parallel import ParallelBRepEngine

    options = EngineOptions(max_segment_length=3.0, cell_size=10.0, fuzzy=1e-6)
    with ParallelBRepEngine(options, workers=2, batch=2, ahead=3) as engine:
        maps = []
        for m in engine.run(program(), STOCK):
            maps.append(m)
            if m.cl_index == 9:
                break
        removed = sum(m.removed_volume for m in maps)
        assert removed > 0
        assert engine.ipw_volume == pytest.approx(engine.stock_volume - removed, rel=1e-9)
        cells = engine.cells  # fetched from the workers, as a checkpoint fetches them
        maps += list(engine.process(program(), start_at=10))
        conserved(engine)
    one = BRepEngine(options)
    one.start(STOCK)
    for _, _m in zip(range(10), one.process(program())):
        pass
    assert sum(c.volume for c in cells) == pytest.approx(one.ipw_volume, rel=1e-9)
    assert_same(maps, whole)


@pytest.mark.parametrize("n_cells, parts", [(40, 2), (40, 3), (7, 2), (3, 4), (1, 1)])
def test_cell_partition_deals_out_every_cell_once_and_splits_neighbours(n_cells, parts):
    from fusioncut.engines.brep.parallel import cell_partition

    shares = cell_partition(n_cells, parts)
    assert sorted(i for share in shares for i in share) == list(range(n_cells))
    assert len(shares) == min(n_cells, parts) and all(shares)
    owner = {i: k for k, share in enumerate(shares) for i in share}
    # the cells are listed column by column: the next one in the list is a neighbour in its column
    assert all(owner[i] != owner[i + 1] for i in range(n_cells - 1)) or parts == 1
    assert max(map(len, shares)) - min(map(len, shares)) <= 1


def staircase_and_slots() -> Toolpath:
    """1.75 turns of a helical entry (no flat turn: a staircase floor) centred on the corner of four
    20 mm cells, then level slots that reach over three of them."""
    from test_helical_entry import helical_entry

    entry = helical_entry()
    z = entry.moves[1].end[2]
    pts = [(0.0, 4.0), (17.0, 4.0), (17.0, -6.0), (-16.0, -6.0), (-16.0, 15.0)]
    slots = tuple(LinearMove((*a, z), (*b, z), feed=900.0, tool=1) for a, b in zip(pts, pts[1:]))
    return Toolpath(entry.moves[:2] + slots, entry.tools)


def test_solid_cells_split_into_quarters_equal_unsplit_cells(monkeypatch):
    """A helical entry without a flat turn leaves a staircase floor: with at most 6 layers a cell,
    its four 20 mm cells go solid. Level slots after it split them into quarters, and those away
    from the staircase take the layers; CL by CL the results equal an engine that never splits,
    and volume adds up."""
    import fusioncut.engines.brep.cells as cells_module
    from test_helical_entry import STOCK as BLOCK

    tp = staircase_and_slots()
    options = EngineOptions(ramp_step=0.2, max_segment_length=2.0, max_layers=6)
    runs = {}
    for split in (1, cells_module.MAX_SPLIT):
        monkeypatch.setattr(cells_module, "MAX_SPLIT", split)
        engine = BRepEngine(options)
        runs[split] = list(engine.run(tp, BLOCK))
        conserved(engine)
        sizes = sorted({c.square[2] for c in engine.cells})
        if split == 1:
            assert sizes == [20.0] and any(c.layers is None for c in engine.cells)
        else:
            assert sizes[0] < 20.0  # quartered...
            assert any(c.layers is not None and c.square[2] < 20.0 for c in engine.cells)  # ...and layered again
    assert_same(runs[cells_module.MAX_SPLIT], runs[1])


def test_a_staircase_stays_layered_and_equals_its_solid_cells():
    """The same staircase with the default layer limit: its ledges stay layers (more than the 6
    that turned the cells solid), and CL by CL the results equal those of the solid cells."""
    from test_helical_entry import STOCK as BLOCK

    runs, most = {}, {}
    for limit in (6, EngineOptions().max_layers):
        engine = BRepEngine(EngineOptions(ramp_step=0.2, max_segment_length=2.0, max_layers=limit))
        engine.start(BLOCK)
        runs[limit], most[limit] = [], 0
        for index, move, tool, feed_angle in cl_sequence(staircase_and_slots(), engine.options):
            runs[limit].append(engine.step(index, move, tool, feed_angle))
            most[limit] = max([most[limit], *(len(c.layers) for c in engine.cells if c.layers)])
        conserved(engine)
    assert most[EngineOptions().max_layers] > most[6] + 1  # a cut may leave one more than the limit
    assert_same(runs[EngineOptions().max_layers], runs[6])


def test_dask_workers_split_cells_as_one_process():
    """Workers split their own solid cells; the workpiece gathered from them holds every quarter."""
    pytest.importorskip("distributed")
    from test_helical_entry import STOCK as BLOCK

    from fusioncut.engines.brep.occ import volume
    from fusioncut.engines.brep.parallel import ParallelBRepEngine

    options = EngineOptions(ramp_step=0.2, max_segment_length=2.0, max_layers=6)  # the staircase's cells solid
    one = BRepEngine(options)
    alone = list(one.run(staircase_and_slots(), BLOCK))
    with ParallelBRepEngine(options, workers=2, batch=9) as engine:
        maps = list(engine.run(staircase_and_slots(), BLOCK))
        gathered = engine.cells
        assert volume(engine.ipw) == pytest.approx(one.ipw_volume, rel=1e-9)
    assert len(gathered) == len(one.cells) > 4
    assert_same(maps, alone)


coord = st.floats(-30.0, 30.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(coord, coord, coord, coord, coord, coord, st.floats(0.0, 20.0))
def test_segment_box_distance_is_the_brute_force_one(ax, ay, bx, by, x0, y0, size):
    from fusioncut.engines.brep.cells import segment_box_distance

    t = np.linspace(0.0, 1.0, 4001)
    px, py = ax + t * (bx - ax), ay + t * (by - ay)
    u = np.linspace(0.0, size, 401)
    # the rectangle's outline, densely; a segment point inside the rectangle is at distance 0
    rx = np.concatenate([x0 + u, x0 + u, np.full_like(u, x0), np.full_like(u, x0 + size)])
    ry = np.concatenate([np.full_like(u, y0), np.full_like(u, y0 + size), y0 + u, y0 + u])
    inside = np.any((px >= x0) & (px <= x0 + size) & (py >= y0) & (py <= y0 + size))
    brute = 0.0 if inside else np.sqrt(np.min((px[:, None] - rx[None, :]) ** 2 + (py[:, None] - ry[None, :]) ** 2))
    got = segment_box_distance((ax, ay), (bx, by), (x0, y0, x0 + size, y0 + size))
    step = math.hypot(bx - ax, by - ay) / 4000 + size / 400
    assert brute - step - 1e-9 <= got <= brute + 1e-9


def test_a_ball_raster_along_cell_walls_skips_the_columns_it_only_touches(monkeypatch):
    """Ball rows 4 mm deep whose sweeps end on cell walls (1 mm lines from x = 5 to 15, cells of
    5 mm), one 3 mm (the ball's radius) beside a wall, one 2.6 mm: the columns behind a line's open
    start and those at exactly its reach get no Boolean, the one just within reach does; the maps
    equal the whole workpiece's, CL by CL. (The second row's plunge, 0.4 mm beside the first's, is
    where the whole workpiece's Boolean once came out as nothing removed: now a split that changes
    the IPW without removing anything is a failure, and the sweep with its seams turned cuts it.)"""
    from fusioncut.engines.brep import engine as engine_module
    from fusioncut.model import BallEndMill

    tool = BallEndMill(6.0, 15.0, number=2)
    moves = []
    for y, z in ((7.6, -4.0), (8.0, -4.1), (9.5, -4.05)):
        moves.append(LinearMove((5.0, y, 3.0), (5.0, y, z), feed=300.0, tool=1))
        moves += [LinearMove((5.0 + j, y, z), (6.0 + j, y, z), feed=900.0, tool=1) for j in range(10)]
    path = Toolpath(tuple(moves), {1: tool})
    whole = list(BRepEngine(EngineOptions(cell_size=None, fuzzy=1e-6, ceiling_pixel=None)).run(path, STOCK))
    behind, beside = [], set()
    clear_of = engine_module.column_clear_of

    def counted(square, motion, reach, open_start):
        skip = clear_of(square, motion, reach, open_start)
        if skip and open_start and not clear_of(square, motion, reach, False):
            behind.append(square)
        elif skip:
            beside.add((square, motion.start))
        return skip

    monkeypatch.setattr(engine_module, "column_clear_of", counted)
    engine = BRepEngine(EngineOptions(cell_size=5.0, fuzzy=1e-6))
    fast = list(engine.run(path, STOCK))
    assert_same(fast, whole)
    conserved(engine)
    assert ((5.0, 0.0, 5.0), (6.0, 8.0, -4.1)) in beside  # the column at exactly 3 mm from its line
    assert ((5.0, 0.0, 5.0), (6.0, 7.6, -4.0)) not in beside  # 2.6 mm: the ball cuts there
    assert len(behind) >= 30  # a column behind every line (one starting on a wall, two within)
