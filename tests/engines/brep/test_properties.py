"""Invariants: translating the whole job changes nothing; every CL is accounted for; failures are kept."""
from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep import engine as engine_mod
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.segments import cl_segments
from fusioncut.model import ArcMove, BoxStock, CLStatus, FlatEndMill, LinearMove, Toolpath

TOOL = FlatEndMill(6, 15)
STOCK = BoxStock((0, 0, -10), (40, 30, 0))


def program(y: float, depth: float) -> Toolpath:
    moves = (
        LinearMove((-5, y, 5), (-5, y, -depth), tool=1, rapid=True),
        LinearMove((-5, y, -depth), (25, y, -depth), feed=800, tool=1),
        ArcMove((25, y, -depth), (25, y + 8, -depth), center=(25, y + 4, -depth), feed=800, tool=1),
        LinearMove((25, y + 8, -depth), (10, y + 8, -depth - 1), feed=800, tool=1),
        LinearMove((10, y + 8, -depth - 1), (10, y + 8, 5), tool=1, rapid=True),
    )
    return Toolpath(moves, {1: TOOL})


def shifted(stock: BoxStock, v) -> BoxStock:
    return BoxStock(tuple(a + b for a, b in zip(stock.minimum, v)), tuple(a + b for a, b in zip(stock.maximum, v)))


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(y=st.floats(5, 15), depth=st.floats(0.5, 4),
       v=st.tuples(st.floats(-500, 500), st.floats(-500, 500), st.floats(-100, 100)))
def test_results_invariant_under_translation(y, depth, v):
    opts = EngineOptions(max_segment_length=6.0)
    a = list(BRepEngine(opts).run(program(y, depth), STOCK))
    b = list(BRepEngine(opts).run(program(y, depth).translated(v), shifted(STOCK, v)))
    assert [m.status for m in a] == [m.status for m in b]
    for ma, mb in zip(a, b):
        assert mb.removed_volume == pytest.approx(ma.removed_volume, rel=1e-6, abs=1e-6)
        assert len(ma.slices) == len(mb.slices)
        for sa, sb in zip(ma.slices, mb.slices):
            assert len(sa.intervals) == len(sb.intervals)
            for ia, ib in zip(sa.intervals, sb.intervals):
                assert ib.entry == pytest.approx(ia.entry, abs=1e-6)
                assert ib.exit == pytest.approx(ia.exit, abs=1e-6)


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(y=st.floats(5, 15), depth=st.floats(0.5, 4), seg=st.sampled_from([None, 3.0, 7.5]))
def test_every_cl_is_reported_in_order(y, depth, seg):
    tp = program(y, depth)
    maps = list(BRepEngine(EngineOptions(max_segment_length=seg)).run(tp, STOCK))
    assert [m.cl_index for m in maps] == list(range(len(cl_segments(tp.moves, seg))))
    assert all(m.status in CLStatus for m in maps)
    assert maps[0].status == CLStatus.RAPID
    assert any(m.status == CLStatus.ENGAGED for m in maps)


def test_failed_boolean_marks_the_cl_saves_shapes_and_goes_on(tmp_path: Path, monkeypatch):
    calls = {"n": 0}
    real = BRepEngine._subtract

    def flaky(self, ipw, sweep, ipw_volume):
        calls["n"] += 1
        if calls["n"] == 2:
            raise engine_mod.BooleanFailure("simulated kernel failure")
        return real(self, ipw, sweep, ipw_volume)

    monkeypatch.setattr(BRepEngine, "_subtract", flaky)
    eng = BRepEngine(EngineOptions(failure_dir=tmp_path, max_segment_length=6.0))
    maps = list(eng.run(program(10, 2), STOCK))
    failed = [m for m in maps if m.status == CLStatus.FAILED]
    assert len(failed) == 1
    assert "simulated kernel failure" in failed[0].reason
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"cl{failed[0].cl_index:06d}_ipw.brep",
                                                          f"cl{failed[0].cl_index:06d}_sweep.brep"]
    assert failed[0].cl_index < maps[-1].cl_index  # the run went on
    # what the later CLs removed still adds up
    assert STOCK.volume - eng.ipw_volume == pytest.approx(sum(m.removed_volume for m in maps), rel=1e-6)
