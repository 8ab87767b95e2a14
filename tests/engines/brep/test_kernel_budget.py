"""The B-Rep engine's kernel budget (``EngineOptions.kernel_budget_s``, engines/brep/budget.py): a
Boolean that hangs is killed past the budget, its CL is FAILED with its shapes saved, the run goes on
against the workpiece as it was before that CL, Ctrl-C stops at once, and no child process is left.

The hang is injected in the kernel's child: ``solid_cut.intersections`` (what the child runs first)
sleeps when the sweep is the one of the slot's middle CL, chosen by its bounding box."""
from __future__ import annotations

import math
import operator
import os
import signal
import threading
import time
from pathlib import Path

import psutil
import pytest

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep import budget as budget_mod
from fusioncut.engines.brep import occ, solid_cut
from fusioncut.engines.brep import sweep as sweep_mod
from fusioncut.engines.brep.budget import Deadline, KernelBudgetExceeded, guarded
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.brep.occ import bounding_box
from fusioncut.errors import InputError
from fusioncut.io.job import engine_option_fields
from fusioncut.model import (
    BallEndMill,
    BoxStock,
    CLStatus,
    FlatEndMill,
    LinearMove,
    Toolpath,
)

TOOL = FlatEndMill(6, 15)
STOCK = BoxStock((0, 0, -10), (40, 30, 0))
# the slot's three CLs; the middle one's sweep ends at x = 25 + 3 (the tool's radius)
A = LinearMove((-5, 15, -2), (10, 15, -2), feed=800, tool=1)
B = LinearMove((10, 15, -2), (25, 15, -2), feed=800, tool=1)
C = LinearMove((25, 15, -2), (38, 15, -2), feed=800, tool=1)
# layers off: the Booleans are the 3D ones the budget guards; one cell: one Boolean a CL
OPTIONS = dict(layers=False, cell_size=None)


def run(moves, monkeypatch, tmp_path: Path, sleep: float = 0.0, budget: float | None = None):
    """The maps of ``moves``, with the Booleans of B's sweep sleeping ``sleep`` s first."""
    real = solid_cut.intersections

    def slow_for_b(a, b, fuzzy, parallel=False):
        if sleep and abs(bounding_box(b)[1][0] - 28.0) < 0.5:
            time.sleep(sleep)
        return real(a, b, fuzzy, parallel)

    monkeypatch.setattr(solid_cut, "intersections", slow_for_b)
    engine = BRepEngine(EngineOptions(kernel_budget_s=budget, failure_dir=tmp_path, **OPTIONS))
    try:
        return list(engine.run(Toolpath(tuple(moves), {1: TOOL}), STOCK)), engine
    finally:
        monkeypatch.undo()


def children() -> set[int]:
    """This process's child processes, zombies (exited, not reaped) included."""
    return {p.pid for p in psutil.Process().children(recursive=True)}


def same(m1, m2) -> bool:
    return (m1.status == m2.status and m1.removed_volume == m2.removed_volume
            and [(s.z, s.intervals) for s in m1.slices] == [(s.z, s.intervals) for s in m2.slices])


def test_a_cl_over_budget_is_failed_its_shapes_saved_and_the_next_cl_cut_from_the_workpiece_before_it(
        monkeypatch, tmp_path):
    before = children()
    t0 = time.perf_counter()
    maps, engine = run((A, B, C), monkeypatch, tmp_path / "hang", sleep=60.0, budget=0.5)
    wall = time.perf_counter() - t0
    assert wall < 10.0  # the 60 s sleep was cut off at the budget
    failed = maps[1]
    assert failed.status == CLStatus.FAILED
    assert "CL 1:" in failed.reason and "kernel budget of 0.5 s" in failed.reason
    assert sorted(p.name for p in (tmp_path / "hang").iterdir()) == ["cl000001_ipw.brep", "cl000001_sweep.brep"]
    assert children() <= before  # the killed child was reaped, the kept one ended with the run
    # the run went on, and C was cut from the workpiece A left: as in a program without B
    assert maps[2].status == CLStatus.ENGAGED
    without_b, _ = run((A, C), monkeypatch, tmp_path / "ac", budget=0.5)
    assert same(maps[2], without_b[1]) and same(maps[0], without_b[0])
    # nothing of B was applied: the volumes still add up
    assert STOCK.volume - engine.ipw_volume == pytest.approx(sum(m.removed_volume for m in maps), rel=1e-9)


def test_a_hung_fuse_in_a_sweeps_construction_is_failed_and_the_next_cl_cut_from_the_workpiece_before_it(
        monkeypatch, tmp_path):
    """A sweep's Booleans (here a ball end mill's steep ramps, each a fuse of its end tools and the
    prisms between, about 0.2 s) run in the kernel's child under the CL's budget: one that hangs (a
    sleep patched in for B's, the child forked after the patch) is killed at the budget, B is FAILED
    and C is cut from the workpiece A left."""
    ball = BallEndMill(6, 15)
    a, b, c = (LinearMove((-5, 15, 2), (10, 15, -2), feed=800, tool=1),
               LinearMove((10, 15, -2), (16, 15, -4), feed=800, tool=1),
               LinearMove((16, 15, -4), (38, 15, -4), feed=800, tool=1))
    real = occ.fuse_all

    def slow_for_b(shapes, *args, **kwargs):
        if abs(max(bounding_box(s)[1][0] for s in shapes) - 9.0) < 0.5:  # B's ramp, built at the origin
            time.sleep(60.0)
        return real(shapes, *args, **kwargs)

    def cut(moves, budget):
        sweep_mod._sweep_at_origin.cache_clear()  # B's sweep is built, not taken from an earlier test's cache
        engine = BRepEngine(EngineOptions(kernel_budget_s=budget, failure_dir=tmp_path, **OPTIONS))
        return list(engine.run(Toolpath(tuple(moves), {1: ball}), STOCK)), engine

    monkeypatch.setattr(occ, "fuse_all", slow_for_b)
    t0 = time.perf_counter()
    maps, engine = cut((a, b, c), 5.0)
    assert time.perf_counter() - t0 < 30.0
    assert [m.status for m in maps] == [CLStatus.ENGAGED, CLStatus.FAILED, CLStatus.ENGAGED]
    assert "a fuse of solids ran past the kernel budget of 5 s" in maps[1].reason
    monkeypatch.undo()
    without_b, _ = cut((a, c), 5.0)
    assert same(maps[2], without_b[1]) and same(maps[0], without_b[0])
    assert STOCK.volume - engine.ipw_volume == pytest.approx(sum(m.removed_volume for m in maps), rel=1e-9)


def test_a_slow_boolean_within_budget_gives_the_results_of_the_run_without_a_budget(monkeypatch, tmp_path):
    slow, _ = run((A, B, C), monkeypatch, tmp_path, sleep=0.3, budget=3.0)
    plain, _ = run((A, B, C), monkeypatch, tmp_path)
    assert [m.status for m in plain] == [CLStatus.ENGAGED] * 3
    assert all(same(m1, m2) for m1, m2 in zip(slow, plain))  # the child's Booleans are this process's, bit for bit
    assert not any(tmp_path.iterdir())


def test_ctrl_c_during_a_hung_boolean_kills_its_child_and_stops_at_once(monkeypatch, tmp_path):
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals reach the main thread only")
    from fusioncut.runner import _CtrlC

    before = children()
    timer = threading.Timer(0.8, os.kill, (os.getpid(), signal.SIGINT))
    t0 = time.perf_counter()
    with _CtrlC() as ctrl_c:
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            run((A, B, C), monkeypatch, tmp_path, sleep=60.0, budget=30.0)
    timer.join()
    assert time.perf_counter() - t0 < 5.0
    assert ctrl_c.requested  # the runner's handler was asked too: it would stop the run
    assert children() <= before


def test_guarded_returns_raises_and_kills_past_the_deadline():
    before = children()
    assert guarded(operator.add, (2, 3), Deadline(5.0), "an addition") == 5
    with pytest.raises(ZeroDivisionError):  # the child's exception, as raised there
        guarded(operator.truediv, (1, 0), Deadline(5.0), "a division")
    t0 = time.perf_counter()
    with pytest.raises(KernelBudgetExceeded, match=r"a sleep ran past the kernel budget of 0.3 s"):
        guarded(time.sleep, (60.0,), Deadline(0.3), "a sleep")
    assert time.perf_counter() - t0 < 3.0
    assert guarded(operator.add, (1, 1), Deadline(5.0), "after a kill") == 2  # a fresh child
    spent = Deadline(0.1, start=time.monotonic() - 1.0)
    with pytest.raises(KernelBudgetExceeded):  # a CL's budget already spent: no call at all
        guarded(operator.add, (1, 1), spent, "too late")
    budget_mod.stop_worker()
    assert children() <= before


def test_without_a_budget_the_call_runs_in_this_process():
    assert guarded(os.getpid, (), Deadline(None), "here") == os.getpid()
    assert guarded(os.getpid, (), Deadline(5.0), "there") != os.getpid()
    budget_mod.stop_worker()


def test_the_budget_is_an_option_of_jobs_and_flags_and_must_be_positive():
    field = next(f for f in engine_option_fields() if f.name == "kernel_budget_s")
    assert field.default == 60.0 and field.takes_none and "(s)" in field.help
    for bad in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(InputError, match="kernel_budget_s"):
            BRepEngine(EngineOptions(kernel_budget_s=bad))
