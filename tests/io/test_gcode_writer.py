"""The G-code writer (fusioncut.io.gcode.writer): what it writes reads back to the same moves."""
from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from fusioncut.demo import demo_gcode, demo_toolpath
from fusioncut.io.gcode import parse_gcode_text, write_gcode
from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Move, Toolpath

TOL = 1e-6  # mm: the writer's 6 decimals


def _close(a, b) -> bool:
    return all(abs(x - y) <= TOL for x, y in zip(a, b))


def test_the_demo_program_is_the_written_demo_toolpath() -> None:
    assert write_gcode(demo_toolpath(), title="FusionCut demo: face, slot, trochoidal, contour, ball finish") \
        == demo_gcode()


@st.composite
def toolpaths(draw) -> Toolpath:
    """Contiguous toolpaths of rapids, feeds and arcs (all planes, helices, extra turns) with tool,
    operation, spindle speed and feed changes (a program's speed is modal: none, or one on every move)."""
    coord = st.floats(-200, 200, allow_nan=False).map(lambda v: round(v, 3))
    pos = (draw(coord), draw(coord), draw(coord))
    speeds = draw(st.sampled_from([[None], [8000.0, 12000.0]]))
    moves: list[Move] = []
    for _ in range(draw(st.integers(1, 12))):
        common = dict(tool=draw(st.integers(1, 3)), operation=draw(st.sampled_from(["Face", "Slot (2)", "Contour"])),
                      spindle_rpm=draw(st.sampled_from(speeds)))
        kind = draw(st.sampled_from(["rapid", "feed", "arc"]))
        if kind == "arc":
            plane = draw(st.sampled_from(list(ArcPlane)))
            ia, ib, n = plane.axes
            r = draw(st.floats(1, 50))
            a0 = draw(st.floats(0, 2 * math.pi))
            sweep = draw(st.floats(0.1, 2 * math.pi - 0.1))
            cw = draw(st.booleans())
            a1 = a0 - sweep if cw else a0 + sweep
            c = [0.0, 0.0, 0.0]
            c[ia], c[ib], c[n] = pos[ia] - r * math.cos(a0), pos[ib] - r * math.sin(a0), pos[n]
            end = list(pos)
            end[ia], end[ib] = c[ia] + r * math.cos(a1), c[ib] + r * math.sin(a1)
            end[n] = pos[n] + draw(st.sampled_from([0.0, -1.5]))
            moves.append(ArcMove(pos, tuple(end), feed=float(draw(st.integers(10, 5000))), center=tuple(c),
                                 plane=plane, clockwise=cw, turns=draw(st.integers(0, 2)), **common))
        else:
            end = (draw(coord), draw(coord), draw(coord))
            if math.dist(pos, end) < 1e-2:  # a zero-length move is not read back
                end = (pos[0] + 1.0, pos[1], pos[2])
            feed = None if kind == "rapid" else float(draw(st.integers(10, 5000)))
            moves.append(LinearMove(pos, end, feed=feed, rapid=kind == "rapid", **common))
        pos = moves[-1].end
    return Toolpath(tuple(moves))


@settings(max_examples=60, deadline=None)
@given(toolpaths())
def test_written_programs_read_back_to_the_same_moves(tp: Toolpath) -> None:
    text = write_gcode(tp, title="round (trip)")
    back = parse_gcode_text(text, source="w.ngc", strict=True)
    assert not back.warnings
    # the program starts at the origin: a rapid to the first move's start comes first
    first, *rest = back.moves if tp.moves[0].start != (0.0, 0.0, 0.0) else (None, *back.moves)
    assert first is None or (first.is_rapid and _close(first.end, tp.moves[0].start))
    assert len(rest) == len(tp.moves)
    for a, b in zip(tp.moves, rest):
        assert type(a) is type(b) and _close(a.start, b.start) and _close(a.end, b.end)
        assert (a.tool, a.operation, a.spindle_rpm, a.is_rapid) == (b.tool, b.operation.replace("[", "(").replace(
            "]", ")"), b.spindle_rpm, b.is_rapid)
        if not a.is_rapid:
            assert b.feed == a.feed
        if isinstance(a, ArcMove):
            ia, ib, _ = a.plane.axes
            assert (b.plane, b.clockwise, b.turns) == (a.plane, a.clockwise, a.turns)
            assert _close((a.center[ia], a.center[ib]), (b.center[ia], b.center[ib]))
