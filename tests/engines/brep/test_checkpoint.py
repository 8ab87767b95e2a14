"""A run stopped after a checkpoint and resumed gives exactly the results of an uninterrupted run."""
from dataclasses import replace

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.model import BoxStock, FlatEndMill, LinearMove, Toolpath

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
