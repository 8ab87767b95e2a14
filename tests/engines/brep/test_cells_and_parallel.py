"""The fast paths give the whole-IPW engine's results: IPW cells, and cells split among Dask workers."""
from __future__ import annotations


import pytest

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
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
