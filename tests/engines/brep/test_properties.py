"""Invariants: translating the whole job changes nothing; every CL is accounted for; failures are kept."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep import cells as cells_mod
from fusioncut.engines.brep import engine as engine_mod
from fusioncut.engines.brep import layers as layers_mod
from fusioncut.engines.brep import solid_cut
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.brep.solid_cut import SolidCutter
from fusioncut.engines.brep.occ import bounding_box
from fusioncut.engines.brep.sweep import swept_volume
from fusioncut.engines.ceiling import footprint
from fusioncut.engines.segments import cl_segments, horizontal_direction, step_motion
from fusioncut.errors import BooleanFailure, RegionCutFailure
from fusioncut.model import (ArcMove, BallEndMill, BoxStock, BullNoseEndMill, CLStatus, FlatEndMill, LinearMove,
                             TaperedEndMill, Toolpath)

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
    state = {"n": 0, "index": None, "target": None}
    real, real_cut = SolidCutter.subtract, BRepEngine.cut

    def cut(self, index, *args):
        state["index"] = index
        return real_cut(self, index, *args)

    def flaky(self, ipw, sweep, ipw_volume, probes=()):
        # every Boolean of the CL of the second one fails: its retries with the sweep's seams turned
        # and with a cell joined to a neighbour too
        state["n"] += 1
        if state["n"] == 2:
            state["target"] = state["index"]
        if state["index"] == state["target"]:
            raise BooleanFailure("simulated kernel failure")
        return real(self, ipw, sweep, ipw_volume, probes)

    monkeypatch.setattr(BRepEngine, "cut", cut)
    monkeypatch.setattr(SolidCutter, "subtract", flaky)
    eng = BRepEngine(EngineOptions(failure_dir=tmp_path, max_segment_length=6.0, layers=False))
    maps = list(eng.run(program(10, 2), STOCK))
    failed = [m for m in maps if m.status == CLStatus.FAILED]
    assert [m.cl_index for m in failed] == [state["target"]]
    assert "simulated kernel failure" in failed[0].reason
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"cl{failed[0].cl_index:06d}_ipw.brep",
                                                          f"cl{failed[0].cl_index:06d}_sweep.brep"]
    assert failed[0].cl_index < maps[-1].cl_index  # the run went on
    # what the later CLs removed still adds up
    assert STOCK.volume - eng.ipw_volume == pytest.approx(sum(m.removed_volume for m in maps), rel=1e-6)


def test_a_boolean_failed_once_is_retried_with_the_sweeps_seams_turned(monkeypatch):
    seams = []
    real_sweep, real_subtract = engine_mod.swept_volume, SolidCutter.subtract

    def recording(tool, move, method, seam, open_start=False):
        seams.append(seam)
        return real_sweep(tool, move, method, seam, open_start)

    def fails_first(self, ipw, sweep, ipw_volume, probes=()):
        if len(seams) == 1:
            raise BooleanFailure("simulated kernel failure")
        return real_subtract(self, ipw, sweep, ipw_volume, probes)

    monkeypatch.setattr(engine_mod, "swept_volume", recording)
    monkeypatch.setattr(SolidCutter, "subtract", fails_first)
    path = program(10, 2)
    retried = list(BRepEngine(EngineOptions(max_segment_length=6.0, layers=False)).run(path, STOCK))
    monkeypatch.undo()
    plain = list(BRepEngine(EngineOptions(max_segment_length=6.0, layers=False)).run(path, STOCK))
    assert seams[1] == pytest.approx(seams[0] + math.pi / 2)
    assert [m.status for m in retried] == [m.status for m in plain] and CLStatus.FAILED not in [m.status for m in plain]
    assert [m.removed_volume for m in retried] == pytest.approx([m.removed_volume for m in plain], rel=1e-9, abs=1e-9)


def test_a_split_that_removes_nothing_but_rebuilds_the_workpiece_wrong_is_a_failure(monkeypatch):
    """What the kernel did on a ball plunge beside the last one: no piece inside the sweep, and the
    workpiece rebuilt larger. That is a failure after every fuzzy value, not 'nothing removed'."""
    from fusioncut.engines.brep.stock import stock_solid

    eng = BRepEngine(EngineOptions(cell_size=None))
    eng.start(STOCK)
    far = swept_volume(FlatEndMill(6, 15), LinearMove((500.0, 500.0, 0.0), (510.0, 500.0, 0.0))).shape
    ipw = eng.cells[0].shape
    assert eng._solid_cutter().subtract(ipw, far, STOCK.volume).shape is None  # truly nothing removed
    larger = stock_solid(BoxStock(STOCK.minimum, tuple(c + 1.0 for c in STOCK.maximum)))
    real = solid_cut.split_pieces
    monkeypatch.setattr(solid_cut, "split_pieces", lambda *a: (real(*a)[0], [], [larger]))
    with pytest.raises(BooleanFailure, match="nothing removed, yet"):
        eng._solid_cutter().subtract(ipw, far, STOCK.volume)


def test_nothing_removed_while_the_tools_end_lies_in_material_is_a_failure(monkeypatch):
    """A split that finds nothing and changes nothing (a slot tangent to the last plunge's hole did
    that), while a point inside the tool at its end lies inside the workpiece."""
    eng = BRepEngine(EngineOptions(cell_size=None))
    eng.start(STOCK)
    slot = swept_volume(FlatEndMill(6, 15), LinearMove((10.0, 10.0, -2.0), (20.0, 10.0, -2.0))).shape
    ipw = eng.cells[0].shape
    cutter = eng._solid_cutter()
    assert cutter.subtract(ipw, slot, STOCK.volume, ((20.0, 10.0, -1.0),)).removed > 0  # the kernel right
    real = solid_cut.split_pieces
    monkeypatch.setattr(solid_cut, "split_pieces", lambda a, *rest: (real(a, *rest)[0], [], [a]))
    with pytest.raises(BooleanFailure, match=r"holds the point \(20.0, 10.0, -1.0\)"):
        cutter.subtract(ipw, slot, STOCK.volume, ((20.0, 10.0, 3.0), (20.0, 10.0, -1.0)))
    assert cutter.subtract(ipw, slot, STOCK.volume, ((20.0, 10.0, 3.0),)).shape is None  # a probe in the air proves nothing


@pytest.mark.parametrize("tool", [FlatEndMill(6, 15), BallEndMill(6, 15), BullNoseEndMill(10, 20, corner_radius=2)])
@pytest.mark.parametrize("move", [LinearMove((0.0, 0.0, 0.0), (7.0, -3.0, 0.0)),
                                  ArcMove((0.0, 0.0, 0.0), (8.0, 0.0, 0.0), center=(4.0, 0.0, 0.0)),
                                  LinearMove((0.0, 0.0, 5.0), (0.0, 0.0, 0.0))])
def test_the_end_probes_lie_inside_the_tool_at_the_end(tool, move):
    """The points that prove material left in the tool's way lie strictly inside the tool at the
    motion's end (so inside its sweep); a horizontal motion has one ahead of the axis, in the
    direction of motion at the end."""
    from fusioncut.engines.brep.occ import strictly_inside
    from fusioncut.engines.brep.sweep import placed_tool

    probes = solid_cut.end_probes(move, tool)
    solid = placed_tool(tool, move.end)
    assert all(strictly_inside(solid, p, tol=1e-3) for p in probes)
    d = horizontal_direction(move)
    assert len(probes) == (1 if d is None else 2)
    if d is not None:
        ahead = (probes[1][0] - move.end[0]) * d[0] + (probes[1][1] - move.end[1]) * d[1]
        assert ahead == pytest.approx(0.9 * tool.profile().radius_at(probes[0][2] - move.end[2]))


def test_a_failed_boolean_of_the_layers_marks_the_cl_and_goes_on(monkeypatch, tmp_path):
    calls = {"n": 0}
    real = layers_mod._cut_region

    def flaky(*args):
        calls["n"] += 1
        if calls["n"] == 2:
            raise RegionCutFailure("simulated 2D kernel failure")
        return real(*args)

    monkeypatch.setattr(layers_mod, "_cut_region", flaky)
    # the General Fuse is what cuts the layers the closed form cannot decide: here, all of them
    monkeypatch.setattr(layers_mod, "_closed_form_cut", lambda *args: None)
    eng = BRepEngine(EngineOptions(max_segment_length=6.0, failure_dir=str(tmp_path / "failures")))
    maps = list(eng.run(program(10, 2), STOCK))
    failed = [m for m in maps if m.status == CLStatus.FAILED]
    assert len(failed) == 1
    assert "simulated 2D kernel failure" in failed[0].reason
    # the workpiece before the CL and the region it failed to cut are saved, and the reason says where
    k = failed[0].cl_index
    assert {p.name for p in (tmp_path / "failures").iterdir()} == {f"cl{k:06d}_ipw.brep", f"cl{k:06d}_region.brep"}
    assert "shapes saved to" in failed[0].reason
    assert failed[0].cl_index < maps[-1].cl_index  # the run went on
    assert STOCK.volume - eng.ipw_volume == pytest.approx(sum(m.removed_volume for m in maps), rel=1e-6)


REACH_TOOLS = [FlatEndMill(6, 15), BallEndMill(8, 20), BullNoseEndMill(10, 20, corner_radius=2),
               TaperedEndMill(6, 20, taper_angle=5), FlatEndMill(8, 15, shank_diameter=10, overall_length=40)]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tool=st.sampled_from(REACH_TOOLS), kind=st.sampled_from(["line", "ramp", "plunge", "arc"]),
       p=st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-10, 5)),
       d=st.tuples(st.floats(-15, 15), st.floats(-15, 15), st.floats(-5, 5)), sweep=st.floats(-6.2, 6.2))
def test_the_reach_box_holds_the_whole_sweep(tool, kind, p, d, sweep):
    """CLs whose reach box meets no material build no sweep, so the box must hold every sweep."""
    end = {"line": (p[0] + d[0], p[1] + d[1], p[2]), "ramp": (p[0] + d[0], p[1] + d[1], p[2] + d[2]),
           "plunge": (p[0], p[1], p[2] + d[2])}.get(kind)
    if kind == "arc":
        assume(math.hypot(d[0], d[1]) > 0.01)  # the reader refuses arcs without a radius
        c = (p[0] + d[0], p[1] + d[1], p[2])
        rho, a0 = math.hypot(p[0] - c[0], p[1] - c[1]), math.atan2(p[1] - c[1], p[0] - c[0])
        end = (c[0] + rho * math.cos(a0 + sweep), c[1] + rho * math.sin(a0 + sweep), p[2])
        move = ArcMove(p, end, center=c, clockwise=sweep < 0, feed=500, tool=1)
    else:
        move = LinearMove(p, end, feed=500, tool=1)
    motion = step_motion(move)
    lo, hi = cells_mod.reach_box(footprint(motion, tool), motion, tool)
    slo, shi = bounding_box(swept_volume(tool, motion).shape, exact=True)
    assert all(lo[k] <= slo[k] and shi[k] <= hi[k] for k in range(3))


def test_a_move_with_no_material_in_reach_builds_no_sweep():
    """A rapid above the stock and a feed beside it: air without a sweep, so no sweep method to report;
    the cut between them builds its sweep."""
    moves = (LinearMove((-10, 5, 5), (50, 5, 5), tool=1, rapid=True),
             LinearMove((-10, 5, -1), (10, 5, -1), feed=800, tool=1),
             LinearMove((-10, -20, -1), (50, -20, -1), feed=800, tool=1))
    maps = list(BRepEngine(EngineOptions(max_segment_length=100.0)).run(Toolpath(moves, {1: TOOL}), STOCK))
    assert [m.status for m in maps] == [CLStatus.RAPID, CLStatus.ENGAGED, CLStatus.AIR]
    assert [m.sweep_method for m in maps] == ["", "exact", ""]
    assert "sweep" not in dict(maps[0].timings_ms) and "sweep" in dict(maps[1].timings_ms)
