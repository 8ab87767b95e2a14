"""The interpreter's work budget (fusioncut.io.gcode.budget): a short program cannot ask for unbounded
work. Programs of a few bytes that expand to millions of moves are refused before they expand (no
timing asserts: the peak allocation while refusing them shows that nothing was expanded). The refusal
is a JobTooLarge, as for the jobs the engine's sizing refuses."""
from __future__ import annotations

import tracemalloc

import pytest

from fusioncut.errors import JobTooLarge
from fusioncut.io.gcode import parse_gcode_text
from fusioncut.io.gcode.budget import BLOCKS_PER_MOVE, MIN_BLOCKS
from fusioncut.model.moves import ArcMove, Toolpath

PEAK_LIMIT = 50e6  # bytes; a million moves take hundreds of MB


def run(text: str, **kw) -> Toolpath:
    return parse_gcode_text(text, source="prog.nc", **kw)


def refused_within_memory(text: str, match: str, **kw) -> None:
    tracemalloc.start()
    try:
        with pytest.raises(JobTooLarge, match=match):
            run(text, **kw)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < PEAK_LIMIT, f"peak allocation {peak / 1e6:.0f} MB"


def test_arc_of_100000_turns_is_refused() -> None:
    text = "G21 G90 G94 F100\nG18 G2 X0 Z0 I5 K0 P100000\nM2\n"
    refused_within_memory(text, r"^prog\.nc:2:5: arc P100000: more than 1,000 turns in one block$")


def test_repeat_of_a_million_is_refused_after_its_first_pass() -> None:
    text = "G21 G90 F100\no100 repeat [1000000]\nG1 X1\nG1 X0\no100 endrepeat\nM2\n"
    assert len(text) < 90
    refused_within_memory(text, r"^prog\.nc:2:1: the program expands to more than 1,000,000 moves "
                                r"\(a repeat loop of 1,000,000 × 2\); raise max_moves to allow it$")


def test_nested_repeats_are_refused_at_the_outer_loop() -> None:
    text = "F100\no1 repeat [1000]\no2 repeat [1000]\nG1 X1\nG1 X0\no2 endrepeat\no1 endrepeat\n"
    refused_within_memory(text, r"^prog\.nc:2:1: the program expands to more than 1,000,000 moves "
                                r"\(a repeat loop of 1,000 × 2,000\)")


def test_a_repeat_loop_of_arcs_counts_their_turns() -> None:
    # 2,000 arcs of 1,000 turns: 2 million full circles for everything downstream
    text = "G0 X5\nF100\no1 repeat [2000]\nG2 X5 Y0 I-5 J0 P1000\no1 endrepeat\n"
    refused_within_memory(text, r"^prog\.nc:3:1: .* \(a repeat loop of 2,000 × 1,000\)")


def test_a_repeat_loop_under_the_limit_reads_and_the_limit_is_exact() -> None:
    text = "F100\no100 repeat [1000]\nG1 X1\nG1 X0\no100 endrepeat\nM2\n"
    tp = run(text)
    assert len(tp.moves) == 2000
    assert [m.end[0] for m in tp.moves[:4]] == [1.0, 0.0, 1.0, 0.0]
    assert len(run(text, max_moves=2000).moves) == 2000
    with pytest.raises(JobTooLarge, match=r"^prog\.nc:2:1: the program expands to more than 1,999 moves "
                                         r"\(a repeat loop of 1,000 × 2\)"):
        run(text, max_moves=1999)
    # no limit
    assert len(run(text, max_moves=None).moves) == len(run(text, max_moves=0).moves) == 2000


def test_a_loop_that_breaks_early_is_not_refused_in_advance() -> None:
    text = ("#1 = 1\nF100\no1 repeat [1000000]\nG1 X#1\n#1 = [#1 + 1]\no2 if [#1 gt 5]\no1 break\n"
            "o2 endif\no1 endrepeat\nG0 Y1\n")
    tp = run(text)
    assert [m.end for m in tp.moves] == [(float(k), 0.0, 0.0) for k in range(1, 6)] + [(5.0, 1.0, 0.0)]


def test_while_loops_stop_at_the_limit_itself() -> None:
    text = "#1 = 0\nF100\no1 while [#1 lt 2000]\nG1 X[#1 mod 2 + 1]\n#1 = [#1 + 1]\no1 endwhile\n"
    assert len(run(text, max_moves=2000).moves) == 2000
    with pytest.raises(JobTooLarge, match=r"^prog\.nc:4:1: the program expands to more than 1,999 moves "
                                         r"\(at this block\); raise max_moves"):
        run(text, max_moves=1999)


def test_blocks_that_move_nothing_are_bounded_too() -> None:
    limit = 10 * BLOCKS_PER_MOVE + MIN_BLOCKS
    with pytest.raises(JobTooLarge, match=rf"^prog\.nc:3:1: the program executes more than {limit:,} blocks "
                                         r"\(a repeat loop of 1,000,000 × 3\)"):
        run("#1 = 0\nG0 X1\no1 repeat [1000000]\n#1 = [#1 + 1]\no1 endrepeat\n", max_moves=10)
    with pytest.raises(JobTooLarge, match=rf"more than {limit:,} blocks \(an endless O-word loop\?\)"):
        run("o1 while [1]\n#1 = [#1 + 1]\no1 endwhile\n", max_moves=10)


def test_expanding_blocks_are_checked_against_the_program_budget() -> None:
    # a G81 with 30 repeats makes 8 moves a repeat here (LinuxCNC's expansion)
    cycle = "G0 X0 Y0 Z5\nG91 G81 X1 Z-2 R1 L30 F100\n"
    assert len(run(cycle).moves) > 30
    with pytest.raises(JobTooLarge, match=r"^prog\.nc:2:5: the program expands to more than 100 moves "
                                         r"\(this block makes 240\)"):
        run(cycle, max_moves=100)


def test_arc_turns_within_the_limits_read() -> None:
    tp = run("G0 X5\nG2 X5 Y0 I-5 J0 P1000 F100\n")
    arc = tp.moves[-1]
    assert isinstance(arc, ArcMove) and arc.turns == 999
    with pytest.raises(JobTooLarge, match=r"^prog\.nc:2:1: .*more than 500 moves \(an arc of 1,000 turns\)"):
        run("G0 X5\nG2 X5 Y0 I-5 J0 P1000 F100\n", max_moves=500)


@pytest.mark.parametrize("bad", [-1, 1.5, "many"])
def test_max_moves_must_be_a_whole_number(bad) -> None:
    with pytest.raises(ValueError, match="max_moves"):
        run("G0 X1\n", max_moves=bad)
