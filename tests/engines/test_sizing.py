"""Sizing a job before anything is expanded: exact counts, and refusals that cost neither time nor memory."""
from __future__ import annotations

import math
import time
import tracemalloc

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusioncut.engines.base import LOWER_BOUNDS, EngineOptions
from fusioncut.engines.segments import cl_segments
from fusioncut.engines.sizing import Budget, move_segments, size_job
from fusioncut.errors import JobTooLarge
from fusioncut.model import ArcMove, ArcPlane, LinearMove

from shared_data import DATA
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"shared test data not found at {DATA}")

# (max_segment_length, chord_tolerance, ramp_step)
OPTION_SETS = [(None, 1e-3, 5e-2), (1.0, 1e-3, 5e-2), (0.3, 1e-4, 1e-2), (2.0, 1e-2, 0.2)]


def _count(moves, msl, tol, ramp) -> int:
    return sum(move_segments(m, msl, tol, ramp) for m in moves)


@needs_data
@pytest.mark.parametrize("name", [
    "linuxcnc-nc_files/tort.ngc",  # G18/G19 arcs, helices
    "posted-gcode-easy_gcode_plot/BOTTLE.NC",  # 1,093 arcs, spirals of rounded I/J
    "posted-gcode-easy_gcode_plot/G17_18_19.NC",
    "linuxcnc-interp-oracle/inside-corners/test.ngc",
    "fusion-posted/1055_utab_265bit.nc",  # ramps and helical entries
])
def test_counts_equal_the_segments_of_real_programs(name):
    from fusioncut.io.job import read_toolpath

    moves = read_toolpath(DATA / name).moves
    for msl, tol, ramp in OPTION_SETS:
        assert _count(moves, msl, tol, ramp) == len(cl_segments(moves, msl, tol, ramp)), (msl, tol, ramp)


coord = st.floats(-50, 50).map(lambda v: round(v, 3))  # as posts write them


@settings(max_examples=150, deadline=None)
@given(st.sampled_from(["line", "ramp", "xy", "helix", "zx", "yz"]), coord, coord, coord, coord, coord,
       st.floats(0.5, 20).map(lambda v: round(v, 4)), st.integers(0, 3), st.booleans(),
       st.sampled_from(OPTION_SETS))
def test_counts_equal_the_segments_of_rounded_moves(kind, x, y, z, x1, y1, r, turns, cw, opts):
    a = (x, y, z)
    if kind in ("line", "ramp"):
        dz = round(0.1 * math.hypot(x1 - x, y1 - y), 4) if kind == "ramp" else 0.0
        m = LinearMove(a, (x1, y1, round(z - dz, 4)), feed=500.0)
    else:
        plane = {"xy": ArcPlane.XY, "helix": ArcPlane.XY, "zx": ArcPlane.ZX, "yz": ArcPlane.YZ}[kind]
        ax, bx, nx = plane.axes
        c = list(a)
        c[ax] = round(a[ax] + r, 4)
        end = list(a)
        ang = math.atan2(y1, x1)  # an end on the circle, rounded: a spiral by a few µm
        end[ax], end[bx] = round(c[ax] + r * math.cos(ang), 4), round(c[bx] + r * math.sin(ang), 4)
        if kind == "helix":
            end[nx] = round(a[nx] - 0.05 * r * (1 + turns), 4)
        m = ArcMove(a, tuple(end), feed=500.0, center=tuple(c), plane=plane, clockwise=cw, turns=turns)
    assert move_segments(m, *opts) == len(cl_segments([m], *opts))


def _flute(_m) -> float:
    return 12.0


def _refused(moves, options, **kw) -> tuple[JobTooLarge, float, float]:
    """The refusal, the CPU seconds and the peak MB it took."""
    tracemalloc.start()
    t0 = time.process_time()
    try:
        with pytest.raises(JobTooLarge) as info:
            size_job(moves, options, _flute, **kw)
        return info.value, time.process_time() - t0, tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def test_a_90_byte_arc_of_100000_turns_is_refused_at_once():
    # G18 G2 X0 Z0 I5 K0 P100000: 15.7 million chords at the default chord tolerance
    arc = ArcMove((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), feed=300.0, center=(5.0, 0.0, 0.0), plane=ArcPlane.ZX,
                  clockwise=True, turns=99_999)
    err, cpu, mb = _refused([arc], EngineOptions())
    assert "more than 5,000,000 CL segments" in str(err) and "1e+05 turns" in str(err)
    assert cpu < 1.0 and mb < 50


def test_a_long_line_over_a_tiny_segment_length_is_refused_at_once():
    line = LinearMove((0.0, 0.0, -1.0), (10_000.0, 0.0, -1.0), feed=600.0)
    err, cpu, mb = _refused([line], EngineOptions(max_segment_length=1e-3))
    assert "10,000,000" in str(err) and cpu < 1.0 and mb < 50
    # many moves each under the limit add up to a refusal too, counted no further than the budget
    lines = [LinearMove((0.0, float(k), -1.0), (10.0, float(k), -1.0), feed=600.0) for k in range(1000)]
    err, cpu, mb = _refused(lines, EngineOptions(max_segment_length=1e-3), budget=Budget(max_cls=1_000_000))
    assert "more than 1,000,000 CL segments" in str(err) and cpu < 1.0 and mb < 50


def test_a_spiral_of_many_turns_is_refused_at_once():
    # end radius 1 µm off the start's: a spiral, followed by circular pieces of at most a half turn
    arc = ArcMove((0.0, 0.0, 0.0), (1e-3, 0.0, 0.0), feed=300.0, center=(5.0, 0.0, 0.0), turns=10_000_000)
    err, cpu, mb = _refused([arc], EngineOptions())
    assert "CL segments" in str(err) and cpu < 1.0 and mb < 50


def test_a_spiral_far_off_its_circle_is_refused_at_once():
    # a quarter turn whose end radius is 100 mm off its start's: 10 million circular pieces at a
    # chord tolerance of 1e-5 mm, counted without making them
    arc = ArcMove((5.0, 0.0, 0.0), (0.0, 105.0, 0.0), feed=300.0, center=(0.0, 0.0, 0.0))
    assert arc.circular_piece_count(1e-5) == 10_000_000
    err, cpu, mb = _refused([arc], EngineOptions(chord_tolerance=1e-5))
    assert "CL segments" in str(err) and cpu < 1.0 and mb < 50


def test_slices_snapshots_and_checkpoints_are_counted():
    lines = [LinearMove((0.0, 0.0, -1.0), (100.0, 0.0, -1.0), feed=600.0)]
    size = size_job(lines, EngineOptions(max_segment_length=1.0, slice_height=0.5), _flute, checkpoint_every=30,
                    snapshot_cls=[3, 3, 7])
    assert (size.cls, size.max_slices_per_cl, size.slices, size.snapshots, size.checkpoints) == (100, 24, 2400, 2, 4)
    err, cpu, mb = _refused(lines, EngineOptions(max_segment_length=1.0, slice_height=1e-3),
                            budget=Budget(max_slices=1_000_000))
    assert "12,000 a CL" in str(err) and cpu < 1.0 and mb < 50
    err, *_ = _refused(lines, EngineOptions(), snapshot_cls=range(1001))
    assert "snapshot_cls" in str(err)
    err, *_ = _refused(lines, EngineOptions(max_segment_length=1e-3), checkpoint_every=1,
                       budget=Budget(max_checkpoints=99_999))
    assert "checkpoint_every" in str(err)


@pytest.mark.parametrize("name", sorted(LOWER_BOUNDS))
def test_options_below_their_lower_bound_are_refused(name):
    low = LOWER_BOUNDS[name]
    EngineOptions(**{name: low})
    for bad in (low / 10, 0.0, -1.0, float("nan")):
        with pytest.raises(JobTooLarge, match=f"options.{name}"):
            EngineOptions(**{name: bad})


def test_cells_over_the_stock_are_counted():
    from fusioncut.engines.sizing import size_toolpath
    from fusioncut.model import BoxStock, CylinderStock, FlatEndMill, Toolpath

    tp = Toolpath((LinearMove((0.0, 0.0, -1.0), (10.0, 0.0, -1.0), feed=600.0, tool=1),), {1: FlatEndMill(6, 12)})
    box = BoxStock((0, 0, -10), (100, 50, 0))
    assert size_toolpath(tp, EngineOptions(), stock=box).cells == 5 * 3  # 20 mm cells
    assert size_toolpath(tp, EngineOptions(cell_size=None), stock=box).cells == 1
    assert size_toolpath(tp, EngineOptions(), stock=CylinderStock((0, 0, 0), 30, 10)).cells == 9
    # a 1 µm cell size (the job's options allow any positive size): 5e9 cells, refused at once
    tracemalloc.start()
    try:
        with pytest.raises(JobTooLarge, match="options.cell_size"):
            size_toolpath(tp, EngineOptions(cell_size=1e-3), stock=box)
        assert tracemalloc.get_traced_memory()[1] < 50e6
    finally:
        tracemalloc.stop()
    huge = BoxStock((0, 0, -10), (1e6, 1e6, 0))  # a 1 km stock in 20 mm cells
    with pytest.raises(JobTooLarge, match="2,500,000,000 cells"):
        size_toolpath(tp, EngineOptions(), stock=huge)
