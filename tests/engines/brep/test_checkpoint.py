"""A run stopped after a checkpoint and resumed gives exactly the results of an uninterrupted run."""
from dataclasses import replace

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.model import BallEndMill, BoxStock, FlatEndMill, LinearMove, Toolpath

TOOL = FlatEndMill(6.0, 15.0, number=1)
STOCK = BoxStock((0.0, 0.0, -10.0), (30.0, 20.0, 0.0))


def _toolpath() -> Toolpath:
    pts = [(-5.0, 5.0, -2.0), (12.0, 5.0, -2.0), (12.0, 9.0, -2.0), (-5.0, 9.0, -2.0), (-5.0, 12.0, -3.0),
           (20.0, 12.0, -3.0)]
    moves = [LinearMove(a, b, feed=600.0, tool=1) for a, b in zip(pts, pts[1:])]
    return Toolpath(tuple(moves), {1: TOOL})


def _strip(maps):
    return [replace(m, timings_ms=()) for m in maps]


def test_resumed_run_equals_uninterrupted(tmp_path):
    tp = _toolpath()
    whole = list(BRepEngine(EngineOptions()).run(tp, STOCK))

    first = BRepEngine(EngineOptions())
    first.start(STOCK)
    done = [m for _, m in zip(range(3), first.process(tp))]
    first.save_checkpoint(tmp_path, next_cl=3)

    second = BRepEngine(EngineOptions())
    assert second.load_checkpoint(tmp_path) == 3
    rest = list(second.process(tp, start_at=3))
    assert _strip(done + rest) == _strip(whole)
    assert abs(second.removed_total - sum(m.removed_volume for m in whole)) < 1e-9
    assert len(list(tmp_path.glob("ipw-*.bbrep"))) == 1


def test_no_checkpoint_gives_none(tmp_path):
    assert BRepEngine().load_checkpoint(tmp_path) is None


def test_resumed_mixed_layered_and_solid_cells_equal_uninterrupted(tmp_path):
    """A flat slot keeps its cell layered; a ball pass turns it into a solid; the ball then runs on
    the stock's top over the other, still layered cell, touching without cutting. Resumed after every
    CL, the cells come back in either form and every result (sweep method included) must match: the
    material's height bounds start from the cells' boxes, so a layered cell's box must be the one
    its solid would have."""
    ball = BallEndMill(6.0, 15.0, number=2)
    moves = (LinearMove((-5.0, 8.0, -2.0), (15.0, 8.0, -2.0), feed=600.0, tool=1),
             LinearMove((15.0, 8.0, 5.0), (15.0, 14.0, -1.0), feed=600.0, tool=2, rapid=True),
             LinearMove((15.0, 14.0, -1.0), (5.0, 14.0, -1.0), feed=600.0, tool=2),
             LinearMove((5.0, 14.0, 0.0), (28.0, 14.0, 0.0), feed=600.0, tool=2))
    tp = Toolpath(moves, {1: TOOL, 2: ball})
    options = EngineOptions(max_segment_length=4.0)
    whole = list(BRepEngine(options).run(tp, STOCK))
    forms = set()
    for k in range(1, len(whole)):
        first = BRepEngine(options)
        first.start(STOCK)
        done = [m for _, m in zip(range(k), first.process(tp))]
        first.save_checkpoint(tmp_path / str(k), next_cl=k)
        second = BRepEngine(options)
        assert second.load_checkpoint(tmp_path / str(k)) == k
        forms.add(tuple(c.layers is not None for c in second.cells))
        assert _strip(done + list(second.process(tp, start_at=k))) == _strip(whole), k
    assert any(False in form and True in form for form in forms)  # resumed with solid and layered cells


def test_the_cells_doctests_hold():
    import doctest

    from fusioncut.engines.brep import cells

    failed, attempted = doctest.testmod(cells)
    assert attempted > 0 and failed == 0
