"""APT CL reader: Fusion's ISO 4343 post and the NX CLSF dialect."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusioncut.errors import FusionCutError, InputError, SourceLocation, ToolDefinitionError
from fusioncut.io.apt import read_apt
from fusioncut.io.apt_arcs import solve_arc
from fusioncut.io.cutters import cutter_from_parameters
from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove
from fusioncut.model.tools import (
    AptCutter,
    BallEndMill,
    BullNoseEndMill,
    ChamferMill,
    FlatEndMill,
    SpindleDirection,
    TaperedEndMill,
)

# What Fusion's "Common ISO 4343 APT" post writes for a small pocket: header comments, one section
# with its operation comment and notes, CUTTER/LOADTL/SPINDL, rapids, feeds, a half circle, a helix
# segment and a retract split over a continuation line.
FUSION_APT = """\
MODE/MILL
PARTNO/'1001'
PPRINT/'1001'
PPRINT/'bracket, first setup'
UNITS/MM
MULTAX/OFF
PPRINT/'2D Adaptive1'
PPRINT/'check clamps before start'
CUTTER/6.000000, 0.000000, 6.000000, 0.000000, 0.000000, 0.000000, 20.000000
LOADTL/1, 0, 30.000000, 1
SPINDL/10000.000000, RPM, CLW
COOLNT/ON
RAPID
GOTO/0.000000, 0.000000, 15.000000
RAPID
GOTO/10.000000, 0.000000, 5.000000
FEDRAT/500.000000, MMPM
GOTO/10.000000, 0.000000, -2.000000
FEDRAT/1200.000000, MMPM
GOTO/20.000000, 0.000000, -2.000000
MOVARC/20.000000, 5.000000, -2.000000, 0.000000, 0.000000, 1.000000, 5.000000, ANGLE, 180.000000
GOTO/20.000000, 10.000000, -2.000000
MOVARC/20.000000, 5.000000, -2.000000, 0.000000, 0.000000, -1.000000, 5.000000, ANGLE, 90.000000
GOTO/25.000000, 5.000000, -2.500000
GOTO/25.000000, $
  5.000000, 10.000000 $$ retract
PPRINT/'2D Contour1'
CUTTER/10.000000, 1.000000, 10.000000, 1.000000, 0.000000, 0.000000, 25.000000
LOADTL/2, 0, 40.000000, 2
SPINDL/8000.000000, RPM, CCLW
RAPID
GOTO/30.000000, 0.000000, 10.000000
FEDRAT/800.000000, MMPM
GOTO/30.000000, 0.000000, -1.000000
MOVARC/30.000000, 5.000000, -1.000000, 0.000000, 0.000000, 1.000000, 5.000000, ANGLE, 360.000000
GOTO/30.000000, 0.000000, -1.000000
COOLNT/OFF
END
FINI
"""

NX_CLSF = """\
TOOL PATH/FACE_MILLING,TOOL,D10_FLAT
TLDATA/MILL,10.0000,0.0000,75.0000,0.0000,0.0000
MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000
$$ centerline data
PAINT/PATH
LOAD/TOOL,1,ADJUST,1
SPINDL/RPM,8000,CLW
RAPID
GOTO/-10.0000,0.0000,50.0000,0.0000000,0.0000000,1.0000000
RAPID
GOTO/-10.0000,0.0000,3.0000,0.0000000,0.0000000,1.0000000
FEDRAT/MMPM,250.0000
GOTO/-10.0000,0.0000,-1.0000,0.0000000,0.0000000,1.0000000
FEDRAT/MMPM,1000.0000
GOTO/40.0000,0.0000,-1.0000,0.0000000,0.0000000,1.0000000
CIRCLE/40.0000,5.0000,-1.0000,0.0000000,0.0000000,-1.0000000,5.0000,0.0600,0.5000,10.0000,0.0000
GOTO/40.0000,10.0000,-1.0000,0.0000000,0.0000000,1.0000000
GOTO/-10.0000,10.0000,-1.0000,0.0000000,0.0000000,1.0000000
END-OF-PATH
TOOL PATH/CONTOUR_BALL,TOOL,B6
TLDATA/MILL,6.0000,3.0000,50.0000,0.0000,0.0000
LOAD/TOOL,2
RAPID
GOTO/0.0000,0.0000,10.0000
FEDRAT/MMPM,500.0000
GOTO/0.0000,0.0000,-0.5000
END-OF-PATH
"""


def write(tmp_path: Path, text: str, name: str = "prog.apt") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_fusion_post_moves_tools_and_operations(tmp_path):
    path = write(tmp_path, FUSION_APT)
    tp = read_apt(path)
    kinds = [type(m).__name__ + ("-rapid" if m.is_rapid else "") for m in tp.moves]
    # the first GOTO only sets the position
    assert kinds == [
        "LinearMove-rapid", "LinearMove", "LinearMove", "ArcMove", "ArcMove", "LinearMove",
        "LinearMove-rapid", "LinearMove", "ArcMove",
    ]
    m = tp.moves
    assert m[0].start == (0.0, 0.0, 15.0) and m[0].end == (10.0, 0.0, 5.0) and m[0].feed is None
    assert m[1].feed == 500.0 and m[2].feed == 1200.0
    assert {mv.operation for mv in m[:6]} == {"2D Adaptive1"}
    assert {mv.operation for mv in m[6:]} == {"2D Contour1"}
    assert m[1].source.line == 18 and m[1].source.file == str(path)
    # continuation: the retract is one record reported at its first line
    assert m[5].end == (25.0, 5.0, 10.0) and m[5].source.line == 25
    assert m[0].spindle_rpm == 10000.0 and m[7].spindle_rpm == 8000.0
    t1, t2 = tp.tools[1], tp.tools[2]
    assert isinstance(t1, FlatEndMill) and t1.diameter == 6.0 and t1.flute_length == 20.0
    assert isinstance(t2, BullNoseEndMill) and t2.corner_radius == 1.0 and t2.spindle is SpindleDirection.CCW
    assert [mv.tool for mv in m] == [1] * 6 + [2] * 3


def test_fusion_arcs_sense_helix_and_full_circle(tmp_path):
    tp = read_apt(write(tmp_path, FUSION_APT))
    half, quarter, full = tp.moves[3], tp.moves[4], tp.moves[8]
    assert isinstance(half, ArcMove) and half.plane is ArcPlane.XY and not half.clockwise
    assert math.isclose(half.sweep, math.pi) and math.isclose(half.radius, 5.0)
    assert half.point_at(0.5) == pytest.approx((25.0, 5.0, -2.0))  # counter-clockwise via 3 o'clock
    # axis -z with 90 degrees: clockwise from (20,10) round (20,5) to (25,5), dropping 0.5 mm
    assert quarter.clockwise and math.isclose(quarter.sweep, -math.pi / 2)
    assert quarter.is_helix and math.isclose(quarter.rise, -0.5)
    assert quarter.center == (20.0, 5.0, -2.0)
    assert math.isclose(full.sweep, 2 * math.pi) and full.turns == 0
    mid = full.point_at(0.5)
    assert mid == pytest.approx((30.0, 10.0, -1.0))


def test_nx_clsf_dialect(tmp_path):
    tp = read_apt(write(tmp_path, NX_CLSF, "op.cls"))
    ops = [m.operation for m in tp.moves]
    assert ops[0] == "FACE_MILLING" and ops[-1] == "CONTOUR_BALL"
    circle = next(m for m in tp.moves if isinstance(m, ArcMove))
    # NX states the axis for clockwise motion: clockwise about -z is counter-clockwise seen from +z,
    # from 6 o'clock through 3 o'clock to 12 o'clock, on from the feed along +x into the one along -x
    assert not circle.clockwise and math.isclose(circle.sweep, math.pi)
    assert circle.point_at(0.5) == pytest.approx((45.0, 5.0, -1.0))
    assert not any("CIRCLE read as" in w for w in tp.warnings)  # the file has NX's own records
    assert isinstance(tp.tools[1], FlatEndMill) and tp.tools[1].name == "D10_FLAT"
    assert isinstance(tp.tools[2], BallEndMill) and tp.tools[2].diameter == 6.0
    assert tp.moves[1].feed == 250.0
    assert any("no UNITS" in w for w in tp.warnings)
    axes = [w for w in tp.warnings if "tool axis read" in w]
    assert axes and "6 records" in axes[0]


def test_inch_program_is_scaled(tmp_path):
    text = """\
UNITS/INCHES
CUTTER/0.25, 0.125, 0, 0.125, 0, 0, 1
LOADTL/4
RAPID
GOTO/0, 0, 1
FEDRAT/10, IPM
GOTO/1, 0, -0.1
FEDRAT/20
GOTO/2, 0, -0.1
"""
    tp = read_apt(write(tmp_path, text))
    assert tp.moves[0].end == pytest.approx((25.4, 0.0, -2.54))
    assert tp.moves[0].feed == pytest.approx(254.0)
    assert tp.moves[1].feed == pytest.approx(508.0)  # no unit word: inches per minute
    tool = tp.tools[4]
    assert isinstance(tool, BallEndMill) and tool.diameter == pytest.approx(6.35)
    assert tool.flute_length == pytest.approx(25.4)


@pytest.mark.parametrize(
    "statement",
    ["GOTO/1, 2, 3, 0, 0.5, 0.8660254", "TLAXIS/0.7071068, 0, 0.7071068", "GOTO/1, 2, 3, 0, 0, -1"],
)
def test_five_axis_is_refused_with_file_and_line(tmp_path, statement):
    text = f"UNITS/MM\nCUTTER/6\nRAPID\nGOTO/0, 0, 10\n{statement}\n"
    path = write(tmp_path, text)
    with pytest.raises(InputError, match="5-axis not supported yet") as err:
        read_apt(path)
    assert f"{path}:5" in str(err.value)
    assert err.value.where.line == 5


def test_older_post_arc_sense_taken_from_end_point(tmp_path):
    # pre-2021 Autodesk posts wrote the plane normal (+z) for a clockwise arc as well
    text = """\
UNITS/MM
CUTTER/6, 0, 6, 0, 0, 0, 20
FEDRAT/100
GOTO/10, 0, 0
GOTO/10, 0, -1
MOVARC/0, 0, -1, 0, 0, 1, 10, ANGLE, 90
GOTO/0, -10, -1
"""
    tp = read_apt(write(tmp_path, text))
    arc = tp.moves[-1]
    assert arc.clockwise and math.isclose(arc.sweep, -math.pi / 2)
    assert any("against their stated axis" in w and ":6" in w for w in tp.warnings)


def test_full_turns_from_angle(tmp_path):
    text = """\
UNITS/MM
CUTTER/6
FEDRAT/100
GOTO/5, 0, 0
MOVARC/0, 0, 0, 0, 0, 1, 5, ANGLE, 720
GOTO/5, 0, -2
"""
    arc = read_apt(write(tmp_path, text)).moves[-1]
    assert arc.turns == 1 and math.isclose(arc.sweep, 4 * math.pi)
    assert math.isclose(arc.length, math.hypot(4 * math.pi * 5, 2))


def test_movarc_keyword_form(tmp_path):
    text = """\
UNITS/MM
CUTTER/6
FEDRAT/100
GOTO/5, 0, 0
MOVARC/ CENTER, 0, 0, 0, AXIS, 0, 0, -1, RADIUS, 5
GOTO/0, -5, 0
"""
    arc = read_apt(write(tmp_path, text)).moves[-1]
    assert arc.clockwise and math.isclose(arc.sweep, -math.pi / 2)


def test_drilling_cycle_is_expanded(tmp_path):
    text = """\
UNITS/MM
CUTTER/6
LOADTL/1
RAPID
GOTO/0, 0, 20
CYCLE/DRILL, 5.000000, MMPM, 100.000000, 10.000000, RAPTO, 5.000000
FEDRAT/100.000000, MMPM
GOTO/10, 0, -5
GOTO/20, 0, -5
CYCLE/OFF
RAPID
GOTO/20, 0, 30
"""
    tp = read_apt(write(tmp_path, text))
    zs = [(m.end, m.is_rapid) for m in tp.moves]
    assert zs[:4] == [((10, 0, 10), True), ((10, 0, 5), True), ((10, 0, -5), False), ((10, 0, 10), True)]
    assert tp.moves[2].feed == 100.0
    assert zs[-1] == ((20, 0, 30), True)
    assert any("canned cycles" in w for w in tp.warnings)


def test_feed_per_revolution_uses_spindle_speed(tmp_path):
    text = "UNITS/MM\nCUTTER/6\nSPINDL/RPM, 2000, CLW\nFEDRAT/MMPR, 0.05\nGOTO/0,0,0\nGOTO/10,0,0\n"
    assert read_apt(write(tmp_path, text)).moves[0].feed == pytest.approx(100.0)


def test_tool_numbers_are_never_shared_by_two_geometries(tmp_path):
    # NX numbers every tool 0 unless told otherwise; a later CUTTER keeps the loaded number
    text = """\
UNITS/MM
CUTTER/6
LOADTL/0
FEDRAT/100
GOTO/0,0,0
GOTO/1,0,0
CUTTER/8
LOADTL/0
GOTO/2,0,0
CUTTER/4
GOTO/3,0,0
CUTTER/6
GOTO/4,0,0
"""
    tp = read_apt(write(tmp_path, text))
    used = [m.tool for m in tp.moves]
    assert used[0] == used[3] == 0 and len(set(used)) == 3
    assert {n: t.diameter for n, t in tp.tools.items()} == {0: 6.0, 1: 8.0, 2: 4.0}
    assert sum("reused for a different cutter" in w for w in tp.warnings) == 2


def test_cutter_without_number_gets_a_free_one(tmp_path):
    tp = read_apt(write(tmp_path, "UNITS/MM\nCUTTER/6\nFEDRAT/100\nGOTO/0,0,0\nGOTO/1,0,0\n"))
    assert tp.moves[0].tool == 1 and tp.tools[1].number == 1
    assert any(":2: the cutter has no tool number" in w for w in tp.warnings)


@pytest.mark.parametrize(
    "params, kind, check",
    [
        ((10, 0, 0, 0), FlatEndMill, lambda t: t.diameter == 10),
        ((10, 5, 0, 0), BallEndMill, lambda t: t.radius == 5),
        ((10, 2, 0, 0), BullNoseEndMill, lambda t: t.corner_radius == 2),
        ((2, 0, 30, 0), ChamferMill, lambda t: math.isclose(t.taper_angle, 60) and t.diameter == 2),
        ((3, 0, 0, 10), TaperedEndMill, lambda t: t.taper_angle == 10 and t.diameter == 3),
        ((0, 0, 0, 45), ChamferMill, lambda t: math.isclose(t.diameter, 2 * 20) and t.tip_diameter == 0),
        ((6, 1, 0, 5), AptCutter, lambda t: t.apt_parameters.r == 1 and t.apt_parameters.beta == 5),
    ],
)
def test_cutter_parameters_become_named_families(params, kind, check):
    d, r, alpha, beta = params
    tool = cutter_from_parameters(d, r, alpha, beta, 20.0, SourceLocation("x.apt", 3))
    assert type(tool) is kind
    assert check(tool)


def test_iso_cutter_with_inconsistent_corner_is_refused():
    with pytest.raises(ToolDefinitionError, match="x.apt:3") as err:
        cutter_from_parameters(10, 1, 0, 10, 20.0, SourceLocation("x.apt", 3), e=1.0, f=1.0)
    assert "ISO 4343" in str(err.value)


def test_solve_arc_rejects_off_circle_and_skew_axis():
    where = SourceLocation("a.apt", 7)
    with pytest.raises(InputError, match="not on the circle"):
        solve_arc((5, 0, 0), (0, 6, 0), (0, 0, 0), (0, 0, 1), where)
    with pytest.raises(InputError, match="not in the XY, ZX or YZ plane"):
        solve_arc((5, 0, 0), (0, 5, 0), (0, 0, 0), (0, 0.6, 0.8), where)
    sol = solve_arc((0, 0, 5), (5, 0, 0), (0, 0, 0), (0, 1, 0), where, sweep_deg=90)
    assert sol.plane is ArcPlane.ZX and not sol.clockwise  # z towards x is counter-clockwise about +y


@pytest.mark.parametrize(
    "body, message, line",
    [
        ("GOTO/1, 2, x", "expected a number", 3),
        ("GOTO/1, 2", "without a known z", 3),
        ("MOVARC/0,0,0,0,0,1,5,ANGLE,90\nFEDRAT/10", "not followed by the GOTO", 3),
        ("MOVARC/0,0,0,0,0,1,5,ANGLE,90\nRAPID", "not followed by the GOTO", 4),
        ("GOTO/0,0,0\nGOTO/1,0,0", "before any FEDRAT", 4),
        ("P1=POINT/0,0,0", "part-program source", 3),
        ("GOFWD/C1", "not supported", 3),
        ("UNITS/FURLONGS", "expected MM or INCHES", 3),
        ("GOTO/1e999,0,0", "out of range", 3),
        ("FEDRAT/0\nGOTO/0,0,0", "feed must be > 0", 3),
        ("TLDATA/DRILL,MILL,10,0,80,118,35", "not modelled", 3),
        ("GOTO/1,,2,3", "empty field", 3),
        ("MOVARC/CENTER,0,0,0,AXIS,0,0\nGOTO/1,0,0", "AXIS needs 3 value", 3),
    ],
)
def test_malformed_records_name_file_and_line(tmp_path, body, message, line):
    path = write(tmp_path, f"UNITS/MM\nCUTTER/6\n{body}\n")
    with pytest.raises(InputError, match=message) as err:
        read_apt(path)
    assert err.value.where.file == str(path) and err.value.where.line == line


def test_empty_and_missing_files(tmp_path):
    with pytest.raises(InputError, match="no tool motion"):
        read_apt(write(tmp_path, "$$ nothing here\nPARTNO/'X'\nFINI\n"))
    with pytest.raises(InputError, match="cannot read"):
        read_apt(tmp_path / "absent.apt")


def test_statements_after_fini_are_ignored(tmp_path):
    tp = read_apt(write(tmp_path, "UNITS/MM\nCUTTER/6\nFEDRAT/5\nGOTO/0,0,0\nGOTO/1,0,0\nFINI\nGOTO/x\n"))
    assert len(tp.moves) == 1


# ---------------------------------------------------------------------------------------------------
# fuzzing: whatever the text, the reader answers with a Toolpath or a FusionCutError naming the file

_WORDS = ["GOTO/", "RAPID", "FEDRAT/", "MOVARC/", "CIRCLE/", "CUTTER/", "LOADTL/", "SPINDL/", "CYCLE/",
          "UNITS/", "TLDATA/MILL,", "GODLTA/", "FROM/", "TLAXIS/", "PPRINT/", "$$", "$", ",", "ANGLE", "MMPM",
          "IPM", "INCHES", "OFF", "DRILL", "RAPTO", "\n", " ", "'", "=", "FINI", "TOOL PATH/", "END-OF-PATH"]
_TOKENS = st.one_of(
    st.sampled_from(_WORDS),
    st.floats(allow_nan=True, allow_infinity=True, width=32).map(lambda v: f"{v:g}"),
    st.integers(-5, 400).map(str),
    st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=4),
)


@pytest.fixture(scope="module")
def fuzz_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("apt-fuzz")


def _check_reader_contract(path: Path) -> None:
    try:
        tp = read_apt(path)
    except FusionCutError as e:
        assert str(path) in str(e)
    else:
        assert tp.moves and all(isinstance(m, (LinearMove, ArcMove)) for m in tp.moves)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(_TOKENS, max_size=60))
def test_fuzz_random_apt_text(fuzz_dir, tokens):
    path = fuzz_dir / "random.apt"
    path.write_text("".join(tokens), encoding="utf-8")
    _check_reader_contract(path)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_fuzz_mutated_programs(fuzz_dir, data):
    lines = data.draw(st.sampled_from([FUSION_APT, NX_CLSF])).splitlines()
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(lines) - 1))
        op = data.draw(st.sampled_from(["drop", "dup", "swap", "edit"]))
        if op == "drop":
            del lines[i]
        elif op == "dup":
            lines.insert(i, lines[i])
        elif op == "swap":
            j = data.draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        else:
            at = data.draw(st.integers(0, len(lines[i])))
            lines[i] = lines[i][:at] + data.draw(_TOKENS) + lines[i][at + data.draw(st.integers(0, 3)):]
        if not lines:
            lines = [""]
    path = fuzz_dir / "mutated.apt"
    path.write_text("\n".join(lines), encoding="utf-8")
    _check_reader_contract(path)


def test_mixed_line_endings_and_latin1(tmp_path):
    text = "UNITS/MM\r\nPPRINT/'Fräsen'\r\nCUTTER/6\r\nFEDRAT/100\r\nGOTO/0,0,0\r\nGOTO/1,0,0\r\n"
    p = tmp_path / "latin.apt"
    p.write_bytes(text.encode("latin-1"))
    tp = read_apt(p)
    assert tp.moves[0].end == (1.0, 0.0, 0.0)

