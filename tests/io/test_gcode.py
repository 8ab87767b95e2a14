"""Unit and property tests of the G-code interpreter (fusioncut.io.gcode).

Small hand-written programs check each feature against values worked out by hand; the move-by-move
comparison with LinuxCNC's rs274 on real programs is in test_rs274_reference.py.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusioncut.errors import FusionCutError, InputError
from fusioncut.io.gcode import GCodeInterpreter, ModalState, parse_gcode_text, read_gcode
from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Toolpath
from fusioncut.model.tools import BallEndMill, BullNoseEndMill, ChamferMill, FlatEndMill

from shared_data import DATA
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"shared test data not found at {DATA}")

APPROX = dict(abs=1e-9)


def run(text: str, **kw) -> Toolpath:
    return parse_gcode_text(text, source="t.ngc", **kw)


def pts(tp: Toolpath) -> list[tuple[float, float, float]]:
    return [m.end for m in tp.moves]


def close(p, q, tol=1e-9) -> bool:
    return all(abs(a - b) <= tol for a, b in zip(p, q))


# ----------------------------------------------------------------------------- basics


def test_linear_moves_units_and_feeds() -> None:
    tp = run("G21 G90\nG0 X10 Y5\nG1 Z-1 F300\nG20\nG1 X1 F10\n")
    assert [type(m) for m in tp.moves] == [LinearMove] * 3
    m0, m1, m2 = tp.moves
    assert m0.rapid and m0.feed is None and m0.start == (0.0, 0.0, 0.0) and m0.end == (10.0, 5.0, 0.0)
    assert not m1.rapid and m1.feed == 300.0 and m1.end == (10.0, 5.0, -1.0)
    # G20: X1 is 25.4 mm, F10 in/min is 254 mm/min; the start is where the last move ended
    assert m2.start == m1.end and m2.end == pytest.approx((25.4, 5.0, -1.0)) and m2.feed == pytest.approx(254.0)


def test_incremental_and_modal_words() -> None:
    tp = run("G91 G1 X1 F100\nY2\nX-0.5 Y-0.5 Z-1\n")
    assert pts(tp) == [(1.0, 0.0, 0.0), (1.0, 2.0, 0.0), (0.5, 1.5, -1.0)]


def test_sources_name_file_line_column() -> None:
    tp = run("(header)\n  G0 X1\nN20 Y2\n")
    assert (tp.moves[0].source.file, tp.moves[0].source.line, tp.moves[0].source.column) == ("t.ngc", 2, 3)
    # a modal move is located at its first axis word
    assert (tp.moves[1].source.line, tp.moves[1].source.column) == (3, 5)


def test_syntax_case_spaces_comments_block_delete() -> None:
    text = "%\ng0 x 1 0.5 (comment) y2 ; trailing\n/G0 X99\nN5 g1 Z-1 f100\n%\nG0 X500\n"
    tp = run(text)
    # spaces inside numbers are ignored, '/' lines skipped, text after the closing % ignored
    assert pts(tp) == [(10.5, 2.0, 0.0), (10.5, 2.0, -1.0)]


def test_zero_length_moves_dropped_and_counted() -> None:
    tp = run("G0 X1\nG0 X1\nG0\nG1 X2 F100\n")
    assert len(tp.moves) == 2
    assert any("dropped 2 zero-length moves" in w for w in tp.warnings)
    it = GCodeInterpreter("G0 X1\nG0 X1\n", source="t.ngc").run()
    assert len(it.moves) == 2  # the interpreter keeps them (rs274 emits them too)


# ----------------------------------------------------------------------------- arcs


def test_arc_ijk_incremental_quarter_circle() -> None:
    (mv,) = run("G17 G0 X10 Y0\nG3 X0 Y10 I-10 J0 F100\n").moves[1:]
    assert isinstance(mv, ArcMove) and not mv.clockwise and mv.plane is ArcPlane.XY
    assert mv.center == (0.0, 0.0, 0.0) and mv.sweep == pytest.approx(math.pi / 2)
    assert mv.length == pytest.approx(5 * math.pi) and mv.feed == 100.0


@pytest.mark.parametrize("r, sweep", [(10.0, -math.pi / 2), (-10.0, -3 * math.pi / 2)])
def test_arc_r_format_short_and_long_way(r: float, sweep: float) -> None:
    mv = run(f"G0 X10 Y0\nG2 X0 Y-10 R{r} F100\n").moves[-1]
    assert isinstance(mv, ArcMove) and mv.clockwise
    assert mv.radius == pytest.approx(10.0) and mv.end_radius == pytest.approx(10.0)
    assert mv.sweep == pytest.approx(sweep)


def test_full_circle_and_p_turns_and_helix() -> None:
    tp = run("G0 X5 Y0 Z0\nG2 X5 Y0 Z-3 I-5 J0 P3 F50\n")
    mv = tp.moves[-1]
    assert isinstance(mv, ArcMove) and mv.turns == 2 and mv.start[:2] == mv.end[:2]
    assert mv.sweep == pytest.approx(-6 * math.pi) and mv.is_helix and mv.rise == -3.0
    assert mv.length == pytest.approx(math.hypot(6 * math.pi * 5, 3))


def test_arc_planes_map_to_model_planes() -> None:
    # G18: the plane is (Z, X) with normal +Y, G19: (Y, Z) with normal +X (model.moves.ArcPlane)
    tp = run("G0 X50 Y0 Z50\nG18 G3 X0 Z0 I-50 K0 F500\nG0 X0 Y50 Z50\nG19 G2 Y0 Z0 J-50 K0 F500\n")
    a18, a19 = tp.moves[1], tp.moves[3]
    assert a18.plane is ArcPlane.ZX and a18.center == (0.0, 0.0, 50.0) and not a18.clockwise
    assert a18.point_at(0.5) == pytest.approx((50 * math.cos(math.pi / 4), 0, 50 - 50 * math.sin(math.pi / 4)))
    assert a19.plane is ArcPlane.YZ and a19.center == (0.0, 0.0, 50.0) and a19.clockwise
    assert abs(a19.sweep) == pytest.approx(math.pi / 2)


def test_absolute_arc_centres_g90_1() -> None:
    tp = run("G0 X10 Y10\nG90.1 G2 X20 Y10 I15 J10 F10\nG91.1 G2 X10 Y10 I-5 J0\n")
    assert tp.moves[1].center == (15.0, 10.0, 0.0) and tp.moves[2].center == (15.0, 10.0, 0.0)


def test_arc_radius_mismatch_is_an_error() -> None:
    with pytest.raises(InputError, match=r"t\.ngc:2:1: radius to end of arc differs") as ei:
        run("G0 X10 Y0\nG3 X0 Y12 I-10 J0 F100\n")
    assert ei.value.where is not None and ei.value.where.line == 2


def test_absolute_centres_without_g90_1_detected() -> None:
    # centre (-24.273, 0.025) written as absolute I/J, like BOTTLE.NC
    text = "G0 X-22.135 Y-4.495\nG2 X-26.513 Y4.495 I-24.273 J0.025 F100\nG2 X-22.135 Y-4.495 I-24.273 J0.025\n"
    with pytest.raises(InputError, match=r"t\.ngc:2:1: .*absolute G90\.1 centre"):
        run(text, arc_centers="incremental")
    auto = run(text)
    assert any(w.startswith("t.ngc:2:1:") and "absolute" in w for w in auto.warnings)
    forced = run(text, arc_centers="absolute")
    for tp in (auto, forced):
        arcs = [m for m in tp.moves if isinstance(m, ArcMove)]
        assert [a.center[:2] for a in arcs] == [(-24.273, 0.025)] * 2
        assert all(abs(a.radius - a.end_radius) < 1e-3 for a in arcs)
    assert not any("absolute" in w for w in forced.warnings)
    with pytest.raises(ValueError):
        run(text, arc_centers="sometimes")  # type: ignore[arg-type]


def test_arc_errors() -> None:
    with pytest.raises(InputError, match="needs X or Y"):
        run("G2 I5 F10\n")
    with pytest.raises(InputError, match="R-format arc cannot end where it starts"):
        run("G0 X1\nG2 X1 R5 F10\n")
    with pytest.raises(InputError, match="too small"):
        run("G2 X10 R2 F10\n")


# ----------------------------------------------------------------------------- offsets and homing


def test_work_offsets_g10_g92_g53() -> None:
    text = (
        "G10 L2 P2 X10 Y20 Z5\nG55 G0 X1 Y1 Z1\n"  # 1: (11, 21, 6)
        "G92 X0 Y0\nG0 X1\n"  # G92 makes the current point 0,0: X1 is 12
        "G92.2\nG0 X1\n"  # suspended: back to G55 only -> 11
        "G92.3\nG0 X1\n"  # restored -> 12
        "G92.1\nG53 G0 Z0\n"  # machine Z 0
        "G54 G10 L20 P1 X5\nG0 X5\n"  # current point (12) becomes X5 in G54 -> stays at 12
    )
    it = GCodeInterpreter(text, source="t.ngc")
    states: list[ModalState] = []
    for _, _moves in it:
        states.append(it.state)
    tp = it.toolpath(drop_zero_length=False)
    assert [m.end for m in tp.moves] == [
        (11.0, 21.0, 6.0), (12.0, 21.0, 6.0), (11.0, 21.0, 6.0), (12.0, 21.0, 6.0), (12.0, 21.0, 0.0),
        (12.0, 21.0, 0.0),
    ]
    assert states[1].coordinate_system == "G55" and states[1].work_offset == (10.0, 20.0, 5.0)
    assert states[2].g92_applied and states[2].g92_offset == (1.0, 1.0, 0.0)
    assert states[-1].coordinate_system == "G54" and states[-1].work_offset == (7.0, 0.0, 0.0)


def test_g28_g30_via_intermediate_point() -> None:
    text = "G0 X5 Y5 Z5\nG28.1\nG0 X1 Y2 Z3\nG30.1\nG0 X9 Y9 Z9\nG91 G28 Z1\nG90 G30\n"
    tp = GCodeInterpreter(text, source="t.ngc").run().toolpath(drop_zero_length=False)
    ends = pts(tp)
    # G28 G91 Z1: up 1 (intermediate), then only Z to the stored 5
    assert ends[3:5] == [(9.0, 9.0, 10.0), (9.0, 9.0, 5.0)]
    # G30 without axis words: every axis to the G30 position
    assert ends[-1] == (1.0, 2.0, 3.0)
    assert all(m.rapid for m in tp.moves)


def test_tool_length_offset_recorded_not_applied() -> None:
    it = GCodeInterpreter("T1 M6\nG43 H1\nG0 Z10\nG53 G0 Z0\n", source="t.ngc", tool_lengths={1: 50.0})
    moves = [m for _, ms in it for m in ms]
    assert it.state.tool_length_offset == 1 and it.state.tool_length == 50.0
    # programmed points are tip points; a machine-coordinate target puts the spindle there
    assert moves[0].end == (0.0, 0.0, 10.0) and moves[1].end == (0.0, 0.0, -50.0)


# ----------------------------------------------------------------------------- tools, spindle, feeds


def test_tool_changes_and_spindle() -> None:
    text = "T1 M6\nS1000 M3\nG0 X1\nT2\nG0 X2\nM6\nM4 S500\nG1 X3 F100\nM5\n"
    it = GCodeInterpreter(text, source="t.ngc")
    seen: list[ModalState] = []
    for _, _moves in it:
        seen.append(it.state)
    tp = it.toolpath()
    assert [m.tool for m in tp.moves] == [1, 1, 2]  # T2 only prepares until M6
    assert [m.spindle_rpm for m in tp.moves] == [1000.0, 1000.0, 500.0]
    assert seen[1].spindle == "cw" and seen[6].spindle == "ccw" and seen[-1].spindle == "off"
    assert seen[3].prepared_tool == 2 and seen[3].tool == 1
    assert sum("M4" in w for w in tp.warnings) == 1


def test_t_without_m6_loads_until_first_m6() -> None:
    # Fusion's hobby posts never write M6
    tp = run("T3\nG0 X1\nT4\nG0 X2\n")
    assert [m.tool for m in tp.moves] == [3, 4]


def test_inverse_time_and_feed_per_rev() -> None:
    tp = run("G93 G1 X30 F2\nY40 F4\nG95 S1000 G1 X0 F0.1\nG94 F500 G1 Y0\n")
    assert tp.moves[0].feed == pytest.approx(60.0)  # 30 mm in 1/2 min
    assert tp.moves[1].feed == pytest.approx(160.0)
    assert tp.moves[2].feed == pytest.approx(100.0)  # 0.1 mm/rev * 1000 rpm
    assert tp.moves[3].feed == 500.0
    with pytest.raises(InputError, match="F word missing"):
        run("G93 G1 X1 F1\nX2\n")


def test_fusion_tool_comments_become_tools() -> None:
    text = (
        "(T1 D=2.65 CR=0 - ZMIN=-12.55 - flat end mill)\n"
        "(T2 D=6 CR=3 - ZMIN=-5 - ball end mill)\n"
        "(T3 D=10 CR=1 - ZMIN=-2 - bull nose end mill)\n"
        "(T4 D=6 CR=0 TAPER=45deg - ZMIN=-1 - chamfer mill)\n"
        "G21\nG0 X1\n"
    )
    tools = run(text).tools
    assert isinstance(tools[1], FlatEndMill) and tools[1].diameter == 2.65 and tools[1].flute_length == 12.55
    assert isinstance(tools[2], BallEndMill) and tools[2].radius == 3.0
    assert isinstance(tools[3], BullNoseEndMill) and tools[3].corner_radius == 1.0
    assert isinstance(tools[4], ChamferMill) and tools[4].taper_angle == 45.0
    assert {n: t.number for n, t in tools.items()} == {1: 1, 2: 2, 3: 3, 4: 4}
    # inch programs: the comment is in inches even when it comes before G20
    inch = run("(T3 D=0.125 CR=0.0625 - ZMIN=-0.54 - BALL END MILL)\nG20\nG0 X1\n").tools[3]
    assert isinstance(inch, BallEndMill) and inch.diameter == pytest.approx(3.175)
    # tools passed in win
    mine = {1: FlatEndMill(diameter=3.0, flute_length=9.0)}
    assert run(text, tools=mine).tools == mine


def test_operation_names_from_standalone_comments() -> None:
    text = (
        "(my part)\n(T1 D=3 CR=0 - ZMIN=-1 - flat end mill)\nG21\n"
        "(Fusion says hello)\n(2D Adaptive1)\nT1\nG0 X1 (inline)\nG1 X2 F100\n"
        "(MSG, operator message)\n(2D Contour1)\nG0 Z5\n"
    )
    tp = run(text)
    assert [m.operation for m in tp.moves] == ["2D Adaptive1", "2D Adaptive1", "2D Contour1"]


@needs_data
def test_fusion_file_operations_tools_and_extent() -> None:
    tp = read_gcode(DATA / "fusion-posted" / "1055_utab_265bit.nc")
    ops = [m.operation for m in tp.moves]
    assert list(dict.fromkeys(ops)) == ["2D Adaptive2", "2D Contour2", "2D Contour3"]
    assert isinstance(tp.tools[1], FlatEndMill) and tp.tools[1].diameter == 2.65
    assert {m.tool for m in tp.moves} == {1} and {m.spindle_rpm for m in tp.moves} == {5000.0}
    assert min(m.end[2] for m in tp.moves) == pytest.approx(-12.55)
    assert any(isinstance(m, ArcMove) and m.plane is ArcPlane.YZ for m in tp.moves)
    # consecutive moves connect
    assert all(close(a.end, b.start) for a, b in zip(tp.moves, tp.moves[1:]))


# ----------------------------------------------------------------------------- canned cycles


def test_g81_g98_and_g99_retract() -> None:
    tp = GCodeInterpreter("G0 Z10\nG98 G81 X1 Y1 Z-2 R2 F100\nX2\nG99 X3\nG80\n", source="t.ngc").run().toolpath(
        drop_zero_length=False)
    ends = [(m.end, m.rapid) for m in tp.moves]
    assert ends == [
        ((0.0, 0.0, 10.0), True),
        ((1.0, 1.0, 10.0), True), ((1.0, 1.0, 2.0), True), ((1.0, 1.0, -2.0), False), ((1.0, 1.0, 10.0), True),
        ((2.0, 1.0, 10.0), True), ((2.0, 1.0, 2.0), True), ((2.0, 1.0, -2.0), False), ((2.0, 1.0, 10.0), True),
        ((3.0, 1.0, 10.0), True), ((3.0, 1.0, 2.0), True), ((3.0, 1.0, -2.0), False), ((3.0, 1.0, 2.0), True),
    ]
    assert all(m.feed == 100.0 for m in tp.moves if not m.rapid)


def test_g83_pecks_and_g91_repeats() -> None:
    tp = run("G0 Z5\nG83 X0 Y0 Z-3 R1 Q1.5 F50\n")
    zs = [(m.end[2], m.rapid) for m in tp.moves[1:]]
    # feed to -0.5, rapid to R, rapid back to 0.254 above, feed to -2, ..., bottom, retract
    assert zs == [(1.0, True), (-0.5, False), (1.0, True), (-0.246, True), (-2.0, False), (1.0, True),
                  (-1.746, True), (-3.0, False), (5.0, True)]
    tp = run("G0 X0 Y0 Z2\nG91 G99 G81 X5 Z-3 R-1 L3 F100\n")
    bottoms = [m.end for m in tp.moves if not m.rapid]
    assert bottoms == [(5.0, 0.0, -2.0), (10.0, 0.0, -2.0), (15.0, 0.0, -2.0)]


def test_cycle_in_g18_drills_along_y() -> None:
    tp = run("G18 G0 X0 Y5 Z0\nG98 G81 X1 Z1 Y-1 R1 F10\n")
    assert [m.end for m in tp.moves[1:]] == [(1.0, 5.0, 1.0), (1.0, 1.0, 1.0), (1.0, -1.0, 1.0), (1.0, 5.0, 1.0)]


def test_cycle_errors_and_other_cycles() -> None:
    with pytest.raises(InputError, match="needs R"):
        run("G81 X1 Z-1 F10\n")
    with pytest.raises(InputError, match="needs a P"):
        run("G82 X1 Z-1 R1 F10\n")
    with pytest.raises(InputError, match="spindle turning clockwise"):
        run("G84 X1 Z-1 R1 F10\n")
    g85 = run("G0 Z5\nG98 G85 X1 Z-1 R1 F10\n").moves
    assert [(m.end[2], m.rapid) for m in g85[1:]] == [
        (5.0, True), (1.0, True), (-1.0, False), (1.0, False), (5.0, True)]
    g73 = run("G0 Z1\nG73 Z-2 R1 Q1 F10\n").moves
    assert [round(m.end[2], 3) for m in g73[1:]] == [0.0, 0.254, -1.0, -0.746, -2.0, 1.0]
    with pytest.raises(InputError, match="axis words with G80"):
        run("G80 X1\n")


@pytest.mark.parametrize(
    "cycle, path",
    [
        # G86: spindle stops at the bottom, rapid out; G89: dwell, feed out; G74: left-hand tap, feed out
        ("M3 S100\nG98 G86 X1 Z-3 R2 P0.5", [(2, "r"), (-3, "f"), (5, "r")]),
        ("M3 S100\nG98 G89 X1 Z-3 R2 P0.5", [(2, "r"), (-3, "f"), (5, "f")]),
        ("M4 S100\nG98 G74 X1 Z-3 R2", [(2, "r"), (-3, "f"), (5, "f")]),
        # G88: the operator retracts by hand, recorded as a rapid to the clearance level (R in G99)
        ("M3 S100\nG99 G88 X1 Z-3 R2 P1", [(2, "r"), (-3, "f"), (2, "r")]),
    ],
)
def test_other_cycles(cycle: str, path: list[tuple[float, str]]) -> None:
    moves = run(f"G0 Z5\n{cycle} F10\n").moves[2:]
    assert [(m.end[2], "r" if m.rapid else "f") for m in moves] == path
    assert all(m.end[:2] == (1.0, 0.0) for m in moves)


def test_g87_back_boring() -> None:
    moves = run("M3 S100 G0 Z5\nG98 G87 X1 Y1 Z-3 R2 I0.5 J0 K-1 F10\n").moves[1:]
    assert [(m.end, m.rapid) for m in moves] == [
        ((1.0, 1.0, 5.0), True), ((1.0, 1.0, 2.0), True),
        ((1.5, 1.0, 2.0), True), ((1.5, 1.0, -3.0), True), ((1.0, 1.0, -3.0), True),  # in off-centre
        ((1.0, 1.0, -1.0), False), ((1.0, 1.0, -3.0), False),  # bore up to K and back
        ((1.5, 1.0, -3.0), True), ((1.5, 1.0, 5.0), True), ((1.0, 1.0, 5.0), True),  # out off-centre
    ]


# ----------------------------------------------------------------------------- parameters and expressions


@pytest.mark.parametrize(
    "expr, value",
    [
        ("[1 + 2 * 3]", 7.0),
        ("[2 ** 3 ** 2]", 64.0),  # left to right within a level
        ("[10 - 4 - 3]", 3.0),
        ("[7 MOD 3]", 1.0),
        ("[-7 MOD 3]", 2.0),  # non-negative, as LinuxCNC
        ("[1 + 1 EQ 2]", 1.0),
        ("[2 GT 1 AND 0 OR 1]", 1.0),
        ("[1 XOR 1]", 0.0),
        ("[SIN[30] * 2]", 1.0),
        ("ATAN[1]/[-1]", 135.0),
        ("[SQRT[16] + ABS[-2] + EXP[0] + LN[1]]", 7.0),
        ("[ROUND[2.5] + ROUND[-2.5] + FIX[-1.5] + FUP[1.2]]", 0.0),
        ("[ACOS[0] + ASIN[1] + TAN[45]]", 181.0),
        ("-[2]", -2.0),
        ("[-SIN[90]]", -1.0),
    ],
)
def test_expressions(expr: str, value: float) -> None:
    it = GCodeInterpreter(f"G0 X{expr}\n", source="t.ngc").run()
    assert it.moves[0].end[0] == pytest.approx(value)


def test_parameters_named_numbered_indirect() -> None:
    text = (
        "#1 = 5\n#<len> = [#1 * 2]\n#<_glob> = 3\n#3 = 1\n"
        "#1 = 7 G0 X#1\n"  # settings on a line happen after the line is read: X is still 5
        "G0 Y#<len> Z##3\n"  # ##3 = #1 = 7
        "G0 X[EXISTS[#<len>] + EXISTS[#<nope>]] Y#<_glob>\n"
    )
    tp = run(text)
    assert pts(tp) == [(5.0, 0.0, 0.0), (5.0, 10.0, 7.0), (1.0, 3.0, 7.0)]
    with pytest.raises(InputError, match=r"t\.ngc:1:5: named parameter #<nope> is not defined"):
        run("G0 X#<nope>\n")
    with pytest.raises(InputError, match=r"t\.ngc:2:\d+: division by zero"):
        run("#1 = 0\nG0 X[1/#1]\n")


def test_system_parameters_follow_state() -> None:
    tp = run("G10 L2 P1 X3\nG0 X1\nG0 Y#5221 Z#5420\n#5221 = 0\nG0 X1\n")
    # #5221 = G54 X offset (3), #5420 = current X in program coordinates (1)
    assert pts(tp) == [(4.0, 0.0, 0.0), (4.0, 3.0, 1.0), (1.0, 3.0, 1.0)]


# ----------------------------------------------------------------------------- O-words


def test_subroutines_loops_and_conditions() -> None:
    text = """
o<square> sub
  #<s> = #1
  G1 X#<s> F100
  G1 Y#<s>
  o<square> return [#<s> * 2]
o<square> endsub
#<i> = 1
o10 while [#<i> LE 3]
  o<square> call [#<i>]
  #<i> = [#<i> + 1]
o10 endwhile
G0 X#<_value>
#2 = 0
o20 do
  #2 = [#2 + 1]
  o21 if [#2 EQ 2]
    o20 continue
  o21 elseif [#2 EQ 4]
    o20 break
  o21 else
    G0 Z#2
  o21 endif
o20 while [#2 LT 10]
o30 repeat [2]
  G0 Y-1
o30 endrepeat
M2
G0 X99 (never)
"""
    ends = pts(run(text))
    assert ends[:6] == [(1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (2.0, 1.0, 0.0), (2.0, 2.0, 0.0),
                        (3.0, 2.0, 0.0), (3.0, 3.0, 0.0)]
    assert ends[6] == (6.0, 3.0, 0.0)  # the last return value
    assert ends[7:9] == [(6.0, 3.0, 1.0), (6.0, 3.0, 3.0)]  # 2 skipped, 4 breaks
    assert ends[9:] == [(6.0, -1.0, 3.0)]  # the repeat's second pass is zero-length: dropped
    with pytest.raises(InputError, match="subroutine O<missing> is not defined"):
        run("o<missing> call\n")
    with pytest.raises(InputError, match="never closed"):
        run("o1 while [1]\nG0 X1\n")


def test_subroutine_arguments_are_local() -> None:
    text = "o1 sub\n#2 = 9\nG0 X#1\no1 endsub\n#2 = 4\no1 call [3]\nG0 Y#2\n"
    assert pts(run(text)) == [(3.0, 0.0, 0.0), (3.0, 4.0, 0.0)]


# ----------------------------------------------------------------------------- splines


def test_g5_1_quadratic_spline_flattened_within_tolerance() -> None:
    tp = run("G0 X0 Y0\nG1 F100\nG5.1 X10 Y0 I5 J5\n")
    segs = tp.moves[1:]
    assert len(segs) > 5 and segs[-1].end == (10.0, 0.0, 0.0)
    # control point (5, 5): the curve is y = x (10 - x) / 10, apex 2.5
    for m in segs:
        for t in (0.0, 0.5):
            x, y, _ = m.point_at(t)
            assert abs(y - x * (10 - x) / 10) <= 0.0011
    assert max(m.end[1] for m in segs) == pytest.approx(2.5, abs=0.002)
    with pytest.raises(InputError, match="NURBS"):
        run("G5.2 X1 Y1 P1 L3\n", strict=True)


def test_g5_cubic_spline_end_and_tangents() -> None:
    segs = run("G0 X0 Y0\nG5 X10 Y0 I0 J5 P0 Q5 F100\n").moves[1:]
    assert segs[-1].end == (10.0, 0.0, 0.0)
    assert segs[0].tangent_at(0)[0] < 0.2 and segs[0].tangent_at(0)[1] > 0.9  # leaves along +Y
    assert max(m.end[1] for m in segs) == pytest.approx(3.75, abs=0.002)


# ----------------------------------------------------------------------------- cutter compensation


def test_cutter_compensation_offsets_a_square() -> None:
    text = "G0 X-5 Y0\nG42.1 D2 G1 X0 Y0 F100\nX10\nY10\nX0\nY0\nG40 G1 X-5\n"
    tp = run(text)
    ends = pts(tp)
    # right of a counter-clockwise square: outside, radius 1; convex corners get arcs
    assert close(ends[1], (0.0, -1.0, 0.0))
    assert close(ends[2], (10.0, -1.0, 0.0))
    corner = tp.moves[3]
    assert isinstance(corner, ArcMove) and corner.center == (10.0, 0.0, 0.0) and corner.radius == pytest.approx(1)
    assert close(tp.moves[-1].end, (-5.0, 0.0, 0.0))
    assert all(close(a.end, b.start) for a, b in zip(tp.moves, tp.moves[1:]))
    with pytest.raises(InputError, match="radius of tool 1 unknown"):
        run("T1 M6\nG41 G1 X5 F10\n", strict=True)
    known = run("T1 M6\nG0 X-5\nG41 G1 X0 F10\nX5\n", tools={1: FlatEndMill(diameter=4.0, flute_length=8.0)})
    assert close(known.moves[-1].end, (5.0, 2.0, 0.0))


def test_cutter_compensation_inside_corner_shortens_the_move() -> None:
    # right of a clockwise-inside path: the first segment ends where the two offsets meet
    tp = run("G0 X0 Y-5\nG42.1 D2 G1 X0 Y0 F100\nX10\nY-10\nG40 X20\n")
    ends = pts(tp)
    assert close(ends[2], (9.0, -1.0, 0.0)) and close(ends[3], (9.0, -10.0, 0.0))


def test_compensated_moves_reported_once_by_steps() -> None:
    # the last move is held until the end of the program text and released by the final step
    text = "G0 X-5 Y0\nG42.1 D2 G1 X0 Y0 F100\nX10\nY10\n"
    it = GCodeInterpreter(text, source="t.ngc")
    steps = [(line, moves) for line, moves in it]
    assert [m for _, moves in steps for m in moves] == it.moves
    assert [len(moves) for _, moves in steps] == [1, 0, 1, 2, 1]  # entry held, corner arc + line, flush
    assert close(it.moves[-1].end, (11.0, 10.0, 0.0))


def test_fast_path_equals_general_path(monkeypatch: pytest.MonkeyPatch) -> None:
    lines = ["G21 G90 (setup)", "G0 X1 Y2 Z3", "G1 Z-1 F200", "X5", "N10 Y6 Z-2", "F300 X7", "G91", "X1 Y1",
             "G20", "X0.1", "G95 S1000 F0.01", "G1 X1", "G94 G90 G0 X0 Y0"]
    if DATA.is_dir():
        lines += (DATA / "camotics-examples/bear/bear.nc").read_text().splitlines()[:2000]
    text = "\n".join(lines)
    fast = GCodeInterpreter(text, source="t.ngc").run()
    assert any(b is not None and b.simple for b in fast.program.blocks)
    monkeypatch.setattr(GCodeInterpreter, "_execute", GCodeInterpreter._execute_general)
    general = GCodeInterpreter(text, source="t.ngc").run()
    assert fast.moves == general.moves and fast.state == general.state


# ----------------------------------------------------------------------------- strict / lenient


def test_unknown_codes_and_words_strict_and_lenient() -> None:
    for text, what in [("G0 X1 M11\n", "M11"), ("G0 X1 G77\n", "G77"), ("G0 X1 E5\n", "E word"),
                       ("G1 X1 F10 H2\n", "H word"), ("G0 U1\n", "U axis")]:
        with pytest.raises(InputError, match=re.escape(what)) as ei:
            run(text, strict=True)
        assert str(ei.value).startswith("t.ngc:1:")
        tp = run(text)
        assert any(w.startswith("t.ngc:1:") and what in w for w in tp.warnings)


def test_rotary_axes_parsed_but_motion_refused() -> None:
    tp = run("G0 X1 A0 B0 C0\n")  # no rotation: fine
    assert pts(tp) == [(1.0, 0.0, 0.0)]
    with pytest.raises(InputError, match=r"t\.ngc:2:1: 5-axis / rotary motion not supported yet"):
        run("G0 X1\nG1 X2 A10 F100\n")
    it = GCodeInterpreter("G1 X2 A10 F100\n", source="t.ngc", allow_rotary=True).run()
    assert it.rotary_ends == [(10.0, 0.0, 0.0)] and it.state.rotary == (10.0, 0.0, 0.0)


def test_errors_are_input_errors_with_locations() -> None:
    cases = ["G1 X1 Y", "G0 X[1 +", "G0 X1.2.3", "G0 X1 X2", "#1 =", "G2 X1 I1 R1 F1", "G1 X1 G0 Y1",
             "o<x> endsub", "(unclosed", "G0 X#9999"]
    for text in cases:
        with pytest.raises(InputError) as ei:
            run("G21\n" + text + "\n", strict=True)
        assert re.match(r"t\.ngc:2(:\d+)?: ", str(ei.value)), (text, str(ei.value))


def test_mdi_execute_and_state() -> None:
    it = GCodeInterpreter(source="mdi")
    assert it.state == ModalState()
    it.execute("G20 G91")
    assert it.state.units == "inch" and it.state.distance_mode == "incremental"
    moves = it.execute("G1 X1 F10")
    assert len(moves) == 1 and moves[0].end == pytest.approx((25.4, 0.0, 0.0))
    assert it.state.position == pytest.approx((25.4, 0.0, 0.0)) and it.state.motion_mode == "G1"
    with pytest.raises(InputError, match="O-word"):
        it.execute("o1 while [1]")


@needs_data
def test_read_gcode_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="cannot read"):
        read_gcode(tmp_path / "missing.nc")
    p = tmp_path / "bad.nc"
    p.write_text("G0 X1\nG1 X2 Q\n")
    with pytest.raises(InputError, match=r"bad\.nc:2:"):
        read_gcode(p)


# ----------------------------------------------------------------------------- performance


def test_35000_lines_read_completely() -> None:
    # the reader's speed is a benchmark matter (timed asserts are flaky on a shared machine)
    lines = ["G21 G90 G17", "G0 X0 Y0 Z5", "G1 Z-1 F300"]
    for k in range(35000 // 4):
        x, y = (k % 200) * 0.5, k * 0.01
        lines.append(f"N{k} G1 X{x:.3f} Y{y:.3f}")
        lines.append(f"X{x + 0.25:.3f} Y{y + 0.002:.3f}")
        lines.append(f"Z-1.{k % 10}")
        lines.append(f"G2 X{x + 1.25:.3f} Y{y + 0.002:.3f} I0.5 J0")
    text = "\n".join(lines)
    tp = parse_gcode_text(text, source="big.nc")
    assert len(tp.moves) > 30000
    assert tp.moves[-1].source.line == len(lines)


# ----------------------------------------------------------------------------- properties


def _sample_lines() -> list[str]:
    lines = [
        "G21 G90 G17", "G0 X10 Y5 Z2", "G1 Z-1 F300", "G2 X20 Y5 I5 J0", "G3 X10 Y5 R5", "G18 G2 X1 Z1 K1",
        "#1 = [SIN[30] * 2]", "G0 X#1", "#<d> = [#1 + 2]", "o100 sub", "o100 endsub", "o100 call [1] [2]",
        "G81 X1 Y1 Z-2 R1", "G83 Z-5 R1 Q1", "G80", "G10 L2 P1 X5", "G92 X0", "G28 G91 Z0", "T1 M6",
        "(T1 D=3 CR=0 - ZMIN=-1 - flat end mill)", "(2D Adaptive1)", "M3 S1000", "G93 G1 X1 F2", "G94",
        "G41.1 D2", "G40", "G5.1 X1 Y1 I1 J0", "N10 G43 H1 Z5", "%", "/G0 X1", "G0 A10", "M30",
    ]
    if DATA.is_dir():
        for f in sorted(DATA.rglob("*")):
            if f.suffix.lower() in (".nc", ".ngc", ".gcode"):
                lines.extend(f.read_text(errors="replace").splitlines()[:80])
    return lines


SAMPLE_LINES = _sample_lines()
_MUTATION_CHARS = "GXYZIJKRPQLFSMTNOHDAB0123456789.-+[]#<>=()/;% _*"


@st.composite
def mutated_programs(draw: st.DrawFn) -> str:
    lines = draw(st.lists(st.sampled_from(SAMPLE_LINES), min_size=1, max_size=6))
    out = []
    for line in lines:
        chars = list(line)
        for _ in range(draw(st.integers(0, 3))):
            pos = draw(st.integers(0, len(chars)))
            op = draw(st.sampled_from(["replace", "insert", "delete"]))
            if op == "insert" or not chars:
                chars.insert(pos, draw(st.sampled_from(_MUTATION_CHARS)))
            elif op == "replace":
                chars[min(pos, len(chars) - 1)] = draw(st.sampled_from(_MUTATION_CHARS))
            else:
                del chars[min(pos, len(chars) - 1)]
        out.append("".join(chars))
    return "\n".join(out)


def _check_only_fusioncut_errors(text: str, strict: bool) -> None:
    try:
        tp = parse_gcode_text(text, source="prop.ngc", strict=strict)
    except FusionCutError as e:
        assert re.match(r"prop\.ngc:[1-9]\d*[:\s]", str(e)), f"no file:line in {str(e)!r}"
        return
    for w in tp.warnings:
        assert w.startswith("prop.ngc"), w
    for m in tp.moves:
        assert all(math.isfinite(v) for v in m.start + m.end)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_programs(), st.booleans())
def test_mutated_real_lines_raise_only_fusioncut_errors(text: str, strict: bool) -> None:
    _check_only_fusioncut_errors(text, strict)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(alphabet=st.sampled_from(_MUTATION_CHARS + "\n\t\u00b2\u0663e"), max_size=80), st.booleans())
def test_random_text_raises_only_fusioncut_errors(text: str, strict: bool) -> None:
    _check_only_fusioncut_errors(text, strict)


@settings(max_examples=100, deadline=None)
@given(st.text(max_size=60))
def test_arbitrary_unicode_raises_only_fusioncut_errors(text: str) -> None:
    _check_only_fusioncut_errors(text, False)


@pytest.mark.parametrize("comment, kind, name", [
    ("(T1  D=2.65 CR=0 - ZMIN=-12.55 - flat end mill)", "flat", ""),
    # hobby posts append the tool's own comment after Fusion's type name
    ("(T1 D=2.4 CR=0 - ZMIN=-3 - flat end mill 2 flute [d2.4mm])", "flat", "2 flute [d2.4mm]"),
    ("(T1 D=6 CR=3 - ball end mill Ball 6)", "ball", "Ball 6"),
    ("(T1 D=6 CR=0 - my cutter)", "flat", "my cutter"),
])
def test_tool_comment_keeps_the_tools_own_words_as_its_name(comment: str, kind: str, name: str) -> None:
    tool = run(f"G21\n{comment}\nT1\nG1 X1 F100\n").tools[1]
    assert (tool.kind, tool.name) == (kind, name)
