"""Where a G-code program ends: ``%`` lines, M2/M30, and what reading leaves unread.

LinuxCNC's rule (rs274ngc ``Interp::open`` / ``read_text``): the first non-blank line may be a lone
``%``, and then a later lone ``%`` ends the program; a ``%`` with text after it is no delimiter
(rs274 refuses it: "Bad character '%' used"). Whenever reading stops before the file's end, a warning
names the line and counts what was left; a program without moves says why.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from fusioncut.errors import InputError
from fusioncut.io.gcode import GCodeInterpreter, parse_gcode_text, read_gcode
from fusioncut.model.moves import ArcMove, Toolpath

from shared_data import DATA
FUSION = DATA / "fusion-posted" / "1055_utab_265bit.nc"
needs_data = pytest.mark.skipif(not FUSION.is_file(), reason=f"shared test data not found at {DATA}")


def run(text: str, **kw) -> Toolpath:
    return parse_gcode_text(text, source="t.nc", **kw)


def hobby_post(vfd_line: str | None) -> tuple[str, int]:
    """A program shaped like a Fusion hobby post: a % line, the header comments, ``vfd_line`` on line
    38, then an adaptive-like pass with coordinates rounded to 3 decimals as the post writes them, an
    arc, M30 and the closing %. Returns the text and the number of moves it makes."""
    head = ["%", "(1055_utab_265bit)", "(T1  D=2.65 CR=0 - ZMIN=-2 - flat end mill)", "G90 G94", "G17", "G21",
            "(When using Fusion 360 for Personal Use, the feedrate of)",
            "(rapid moves is reduced to match the feedrate of cutting)",
            "(moves, which can increase machining time. Unrestricted rapid)",
            "(moves are available with a Fusion 360 Subscription.)", ""]
    head += [f"(Machine setup note {k})" for k in range(37 - len(head) - 4)]
    head += ["(2D Adaptive2)", "T1", "S5000 M3", "G54"]
    assert len(head) == 37
    body = ["G0 X22.646 Y41.373", "Z10", "G1 Z5 F1000", "Z-1.47"]
    for k in range(1, 41):
        body.append(f"X{22.646 + 0.3 * k:.3f} Y{41.373 - 0.017 * k * k:.3f}")
    # from (34.646, 14.173): a quarter circle of radius 2.362 about the point 2.362 mm west
    body += ["G3 X32.284 Y16.535 I-2.362 J0", "G1 X32.284 Y8.5", "G0 Z10", "M5", "M30", "%"]
    lines = head + ([vfd_line] if vfd_line is not None else []) + body
    return "\n".join(lines) + "\n", 4 + 40 + 2 + 1


def test_a_percent_line_with_text_is_ignored_with_a_warning_not_the_end() -> None:
    text, n_moves = hobby_post("% vfd enable")
    assert text.splitlines()[37] == "% vfd enable"  # line 38
    tp = run(text)
    assert len(tp.moves) == n_moves
    # ignoring the line is reading the program without it, move for move (one line further down)
    without = run(hobby_post(None)[0]).moves
    assert [replace(m, source=None) for m in tp.moves] == [replace(m, source=None) for m in without]
    assert [m.source.line for m in tp.moves] == [m.source.line + 1 for m in without]
    assert sum(isinstance(m, ArcMove) for m in tp.moves) == 1
    assert tp.moves[-1].end == (32.284, 8.5, 10.0)
    [warning] = [w for w in tp.warnings if "vfd" in w]
    assert warning.startswith("t.nc:38:1: '% vfd enable': ") and warning.endswith("(ignored)")
    assert not any("no moves" in w or "not read" in w for w in tp.warnings)


def test_strict_refuses_a_percent_line_with_text_as_linuxcnc_does() -> None:
    with pytest.raises(InputError, match=r"^t\.nc:38:1: '% vfd enable': a % line with text"):
        run(hobby_post("% vfd enable")[0], strict=True)
    with pytest.raises(InputError, match=r"^t\.nc:2:3: '%\(comment\)'"):
        run("%\n  %(comment)\nG0 X1\n%\n", strict=True)


@needs_data
def test_real_fusion_post_with_a_vfd_line_at_38_reads_every_move(tmp_path: Path) -> None:
    lines = FUSION.read_text().splitlines()
    original = read_gcode(FUSION)
    prog = tmp_path / "hobby.nc"
    prog.write_text("\n".join(lines[:37] + ["% vfd enable"] + lines[37:]) + "\n")
    tp = read_gcode(prog)
    assert len(tp.moves) == len(original.moves) == 6519
    assert [m.end for m in tp.moves] == [m.end for m in original.moves]
    assert [w for w in tp.warnings if "vfd" in w] == [f"{prog}:38:1: '% vfd enable': a % line with text after "
                                                      "the % is not a program start or end (only a lone % is) "
                                                      "(ignored)"]


def test_reading_stopped_by_m2_names_the_line_and_counts_what_is_left() -> None:
    tp = run("G0 X1\nM2\nG0 X5\n(a comment)\n\nG1 Y3 F100\nS100\n%\n")
    assert len(tp.moves) == 1
    assert tp.warnings == ("t.nc:2: M2 ends the program here: 3 lines with words are not read "
                           "(2 with axis words)",)


def test_closing_percent_with_lines_after_it_warns() -> None:
    tp = run("%\nG0 X1\n%\nG0 X500\n")
    assert [m.end for m in tp.moves] == [(1.0, 0.0, 0.0)]
    assert tp.warnings == ("t.nc:3: the closing % ends the program here: 1 line with words is not read "
                           "(1 with axis words)",)


@pytest.mark.parametrize("text", ["G0 X1\nM30\n%\n", "%\nG0 X1\nM30\n%\n\n", "%\nG0 X1\n%\n(end)\n  \n",
                                  "G0 X1\nM2\n/G0 X5\n"])
def test_nothing_left_after_the_end_no_warning(text: str) -> None:
    assert run(text).warnings == ()


def test_m2_in_a_subroutine_counts_from_the_furthest_line_executed() -> None:
    text = "o100 sub\nG0 X1\nM2\no100 endsub\no100 call\nG0 X9\nG0 Y9\n"
    tp = run(text)
    assert [m.end for m in tp.moves] == [(1.0, 0.0, 0.0)]
    assert tp.warnings == ("t.nc:3: M2 ends the program here: 2 lines with words after line 5 are not read "
                           "(2 with axis words)",)


def test_subroutines_after_m2_are_read_when_called() -> None:
    tp = run("o100 call\nM2\no100 sub\nG0 X1\no100 endsub\n")
    assert [m.end for m in tp.moves] == [(1.0, 0.0, 0.0)] and tp.warnings == ()


@pytest.mark.parametrize("text, reason", [
    ("%\n(header)\n%\nG0 X1\nG1 X2 F100\n", "the closing % at line 3 ends the program before any move"),
    ("M30\nG0 X1\n", "M30 at line 1 ends the program before any move"),
    ("", "the file is empty"),
    ("\n  \n", "the file is empty"),
    ("G21 G90\n(only settings)\n", "no block of the program moves the tool"),
    ("G0 X0 Y0\nG1 Z0 F100\n", "every move has zero length"),
])
def test_a_program_without_moves_says_why(text: str, reason: str) -> None:
    tp = run(text)
    assert tp.moves == ()
    assert tp.warnings[-1] == f"t.nc: no moves: {reason}"


def test_stray_percent_does_not_end_the_flow_scan() -> None:
    # the subroutine is defined after a '%' line with text: it is still found
    tp = run("%\no100 call\nG0 Y2\n% tool change\no100 sub\nG0 X1\no100 endsub\n%\n")
    assert [m.end for m in tp.moves] == [(1.0, 0.0, 0.0), (1.0, 2.0, 0.0)]


def test_interpreter_reports_the_same_warning_when_stepped() -> None:
    it = GCodeInterpreter("G0 X1\nM2\nG0 X5\n", source="t.nc")
    steps = list(it)
    assert [len(moves) for _, moves in steps] == [1, 0]
    assert it.warnings == ["t.nc:2: M2 ends the program here: 1 line with words is not read (1 with axis words)"]
