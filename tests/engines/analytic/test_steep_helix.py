"""A helix too steep to be stepped: the B-Rep engine sweeps its chords, the analytic engine the same
CL segments on the helix itself (:func:`fusioncut.engines.segments.helix_pieces`), one sweep in its
index. Closed form: once the first turn is down, each turn of a helical bore lowers the whole
bottom by the pitch, so a turn removes the hole's area times the pitch."""
from __future__ import annotations

import math

import pytest

from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.base import EngineOptions
from fusioncut.engines.cl_maps import cl_sequence
from fusioncut.engines.segments import as_chord, cl_segments, helix_pieces
from fusioncut.model import ArcMove, BoxStock, FlatEndMill, LinearMove, Toolpath

R, RHO, PITCH = 3.0, 1.0, 2.0  # tool radius, helix radius, mm down a turn: slope 0.32, steeper than stepped
STOCK = BoxStock((-20, -20, -20), (20, 20, 0))


def bore(turns: int, decimals: int | None = None) -> list:
    """A plunge to the top, then ``turns`` full turns counter-clockwise about the origin, one move a
    turn, each ``PITCH`` lower (the start's coordinates rounded to ``decimals`` as a post writes them)."""
    start = (RHO, 0.0, 0.0) if decimals is None else (round(RHO * math.cos(0.3), decimals),
                                                        round(RHO * math.sin(0.3), decimals), 0.0)
    moves = [LinearMove((start[0], start[1], 5.0), start, feed=300.0, tool=1)]
    for k in range(turns):
        s = (start[0], start[1], -PITCH * k)
        moves.append(ArcMove(s, (s[0], s[1], s[2] - PITCH), feed=600.0, tool=1, center=(0.0, 0.0, s[2]),
                             clockwise=False))
    return moves


def test_the_pieces_are_the_chords_cl_segments_on_the_helix():
    arc = bore(1)[1]
    for max_len in (None, 0.02):
        chords, pieces = cl_segments([arc], max_len), cl_segments([arc], max_len, exact_arcs=True)
        assert len(pieces) == len(chords) > 60
        assert all(isinstance(p, ArcMove) for p in pieces)
        # the CL ends on the helix are the chords' ends, but for sub-pieces of a chord (on the chord)
        assert pieces[-1].end == chords[-1].end == arc.end
        ends = [p.end for p in pieces]
        assert all(math.hypot(e[0], e[1]) == pytest.approx(RHO, abs=1e-12) for e in ends)
        if max_len is None:
            assert max(math.dist(c.end, e) for c, e in zip(chords, ends)) <= 1e-12
            assert all(as_chord(p) == c for p, c in zip(pieces, chords))
    assert helix_pieces(arc, 1e-3, None)[0].start == arc.start
    assert as_chord(bore(1)[0]) == bore(1)[0]  # a line stays itself


@pytest.mark.parametrize("decimals", [None, 3])
def test_a_helical_bore_removes_the_holes_area_a_turn(decimals):
    """Turn 2 of a flat end mill's helical bore removes pi (R + rho)² p, to 1e-7, whatever the pieces
    (a chord tolerance of 0.01 mm: 23 a turn): they follow the helix, where chords would leave the
    hole's wall polygonal."""
    moves = bore(2, decimals)
    rho = math.hypot(*moves[1].start[:2])
    toolpath = Toolpath(tuple(moves), {1: FlatEndMill(2 * R, 20)})
    options = EngineOptions(chord_tolerance=0.01)
    engine = AnalyticEngine(options)
    maps = list(engine.run(toolpath, STOCK))
    cls = list(engine.cl_sequence(toolpath))
    assert len(cls) == len(list(cl_sequence(toolpath, options))) == 47  # the B-Rep engine's CLs
    assert all(m.engine == "analytic" and m.status.value != "failed" for m in maps)
    assert engine._index.size == 2  # the plunge, and the helix's pieces as one sweep
    second = sum(m.removed_volume for m, c in zip(maps, cls) if -2 * PITCH - 1e-9 <= c.move.end[2] < -PITCH - 1e-9)
    assert second == pytest.approx(math.pi * (R + rho) ** 2 * PITCH, rel=1e-7)
