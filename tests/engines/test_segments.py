"""CL segments: ramps and helices are swept as horizontal steps within ``ramp_step`` of the path."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusioncut.engines.segments import STAIRCASE_SLOPE, cl_segments, staircase, step_motion
from fusioncut.model import ArcMove, ArcPlane, LinearMove


def _distance_to_line(q, a, b) -> float:
    ab = [b[i] - a[i] for i in range(3)]
    t = sum((q[i] - a[i]) * ab[i] for i in range(3)) / sum(c * c for c in ab)
    t = min(1.0, max(0.0, t))
    return math.dist(q, [a[i] + t * ab[i] for i in range(3)])


def _check_chain(move, pieces) -> list:
    """Pieces follow each other along the path; their swept motions are level at the piece's end
    height and start above or below the piece's start. Returns the motions."""
    assert pieces[0].start == move.start and pieces[-1].end == move.end
    for a, b in zip(pieces, pieces[1:]):
        assert b.start == pytest.approx(a.end, abs=1e-12)
    motions = [step_motion(p) for p in pieces]
    for p, m in zip(pieces, motions):
        assert m.start[2] == m.end[2] == p.end[2] and m.end == p.end
        assert m.start[:2] == p.start[:2]
    return motions


@settings(max_examples=60, deadline=None)
@given(st.floats(-50, 50), st.floats(-50, 50), st.floats(0.5, 40), st.floats(0, 2 * math.pi),
       st.floats(-0.99 * STAIRCASE_SLOPE, 0.99 * STAIRCASE_SLOPE).filter(lambda s: abs(s) > 1e-3), st.sampled_from([0.002, 0.01, 0.05]))
def test_line_ramp_steps_stay_within_ramp_step(x, y, length, heading, slope, step):
    a = (x, y, -1.0)
    b = (x + length * math.cos(heading), y + length * math.sin(heading), -1.0 + slope * length)
    move = LinearMove(a, b, feed=500.0)
    steps = _check_chain(move, staircase(move, step))
    for s in steps:
        assert _distance_to_line(s.end, a, b) < 1e-9  # every CL lies on the path
        for k in range(11):
            assert _distance_to_line(s.point_at(k / 10), a, b) <= step + 1e-9


@settings(max_examples=40, deadline=None)
@given(st.floats(0.5, 20), st.floats(0.2, 3.0), st.booleans(), st.integers(0, 2), st.sampled_from([0.01, 0.05]))
def test_helix_steps_are_xy_arcs_within_ramp_step(radius, pitch, clockwise, turns, step):
    start = (radius, 0.0, 1.0)
    rise = -pitch * (turns + 0.75)
    end = (0.0, -radius if clockwise else radius, 1.0 + rise)
    helix = ArcMove(start, end, center=(0.0, 0.0, 1.0), clockwise=clockwise, turns=turns, feed=500.0)
    if abs(rise) > STAIRCASE_SLOPE * abs(helix.sweep) * radius:
        assert staircase(helix, step) == [helix]  # steeper than a ramp: left to the oblique sweep
        return
    steps = _check_chain(helix, staircase(helix, step))
    n = len(steps)
    for k, s in enumerate(steps):
        assert isinstance(s, ArcMove) and s.plane == ArcPlane.XY and not s.is_helix
        assert abs(s.sweep) <= math.pi / 2 + 1e-9
        assert s.end == pytest.approx(helix.point_at((k + 1) / n), abs=1e-9)  # the CL lies on the helix
        # the helix's points near this step, densely (spacing << ramp_step)
        near = [helix.point_at(min(1.0, max(0.0, (k + j / 100) / n))) for j in range(-100, 201)]
        spacing = max(math.dist(near[j], near[j + 1]) for j in range(len(near) - 1))
        for u in (0.0, 0.25, 0.5, 0.75, 1.0):
            q = s.point_at(u)
            assert min(math.dist(q, p) for p in near) <= step + spacing
    assert sum(abs(s.sweep) for s in steps) == pytest.approx(abs(helix.sweep))


def test_steep_moves_plunges_and_rapids_are_kept():
    steep = LinearMove((0, 0, 0), (1, 0, -1), feed=500.0)
    plunge = LinearMove((0, 0, 0), (0, 0, -5), feed=500.0)
    rapid = LinearMove((0, 0, 50), (100, 80, -1), rapid=True)
    flat = LinearMove((0, 0, -1), (10, 0, -1), feed=500.0)
    for m in (steep, plunge, rapid, flat):
        assert staircase(m, 0.01) == [m] and step_motion(m) is m


def test_zx_arcs_become_chords_then_steps():
    arc = ArcMove((0, 0, 0), (20, 0, 0), center=(10, 0, 0), plane=ArcPlane.ZX, clockwise=True, feed=500.0)
    segs = cl_segments([arc], None, 1e-3, 0.01)
    assert segs[-1].end == arc.end
    assert all(isinstance(s, LinearMove) for s in segs)
    for s in segs:  # every CL ends on a chord, within chord_tolerance of the arc
        assert math.hypot(s.end[0] - 10, s.end[2]) == pytest.approx(10, abs=1e-3 + 1e-9)
    stepped = [s for s in segs if step_motion(s) is not s]
    steep = [s for s in segs if step_motion(s) is s]
    assert stepped and steep  # the flat top of the arc is stepped, its steep sides are chords


def test_steep_helices_become_chords_on_the_helix():
    # 0.2 mm down over a 0.4 mm arc: a 1:2 slope, too steep for steps (1055_utab posts such arcs)
    helix = ArcMove((0.25, 0.0, 0.0), (0.0, 0.25, -0.2), center=(0.0, 0.0, 0.0), feed=500.0)
    assert staircase(helix, 0.01) == [helix]
    segs = cl_segments([helix], None, 1e-3, 0.01)
    assert len(segs) > 1 and all(isinstance(s, LinearMove) for s in segs) and segs[-1].end == helix.end
    for s in segs:
        assert math.hypot(s.end[0], s.end[1]) == pytest.approx(0.25, abs=1e-9)
        assert step_motion(s) is s  # steep chords keep the oblique sweep
