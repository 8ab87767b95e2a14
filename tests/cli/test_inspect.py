"""``fusioncut inspect``: what the readers produced, in mm, as a table and as JSON; clear errors."""
from __future__ import annotations

import json
import math

import pytest
from typer.testing import CliRunner

from fusioncut.cli import app
from fusioncut.io.gcode import read_gcode
from fusioncut.model import ArcMove

from shared_data import DATA
FUSION = DATA / "fusion-posted" / "1055_utab_265bit.nc"
TBL = DATA / "linuxcnc-tool-tables" / "configs_sim_axis_sim_mm.tbl"
CAMOTICS = DATA / "camotics-examples" / "flower_mold" / "flower_mold.camotics"
needs_data = pytest.mark.skipif(not FUSION.exists(), reason="shared data not available")

runner = CliRunner()


def inspect_json(*args: str) -> dict:
    res = runner.invoke(app, ["inspect", *args, "--json"])
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


@needs_data
def test_fusion_post_tools_operations_counts_and_extents():
    r = inspect_json(str(FUSION))
    assert r["format"].startswith("G-code") and r["file_units"] == ["mm"]
    [tool] = r["tools"]
    assert tool == {"number": 1, "kind": "flat", "name": "", "diameter_mm": 2.65, "flute_length_mm": 12.55,
                    "corner_radius_mm": 0.0, "taper_angle_deg": None, "flutes": 2, "used": True}
    # independent count from the reader's moves
    moves = read_gcode(FUSION).moves
    assert r["moves"]["total"] == len(moves) == 6519
    assert r["moves"]["rapid"] == sum(m.is_rapid for m in moves)
    helices = sum(isinstance(m, ArcMove) and m.is_helix for m in moves)
    assert helices > 0  # the adaptive's helical entries
    assert r["moves"]["helix"] == helices
    assert r["moves"]["arc"] == sum(isinstance(m, ArcMove) for m in moves) - helices
    assert [op["name"] for op in r["operations"]] == ["2D Adaptive2", "2D Contour2", "2D Contour3"]
    for kind in ("rapid", "linear", "arc", "helix", "total"):
        assert sum(op["moves"][kind] for op in r["operations"]) == r["moves"][kind]
    ext = r["extents_mm"]["all"]
    assert ext["min"][2] == pytest.approx(-12.55)  # the post's ZMIN
    assert ext["max"][2] == pytest.approx(max(max(m.start[2], m.end[2]) for m in moves))
    assert ext["min"][0] <= min(min(m.start[0], m.end[0]) for m in moves)
    feeds = [m.feed for m in moves if not m.is_rapid and m.feed]
    assert r["feed_mm_min"] == [pytest.approx(min(feeds)), pytest.approx(max(feeds))]
    assert r["spindle_rpm"] == [5000, 5000]


@needs_data
def test_table_output_names_operations_and_units():
    res = runner.invoke(app, ["inspect", str(FUSION)], env={"COLUMNS": "160"})
    assert res.exit_code == 0, res.output
    for text in ("2D Adaptive2", "2D Contour3", "2.65", "12.55", "units in the file: mm", "-12.55"):
        assert text in res.output


def test_inch_program_is_reported_in_mm(tmp_path):
    prog = tmp_path / "inch.ngc"
    prog.write_text("G20 G90\n(Cut)\nT1 M6\nG0 X0 Y0 Z0.5\nG1 Z-0.1 F10\nG2 X1 Y0 I0.5 J0\nM30\n")
    r = inspect_json(str(prog))
    assert r["file_units"] == ["inch"]
    assert r["extents_mm"]["all"]["max"][0] == pytest.approx(25.4)
    assert r["extents_mm"]["all"]["max"][1] == pytest.approx(12.7)  # the half circle bulges by its radius
    assert r["extents_mm"]["all"]["min"][2] == pytest.approx(-2.54)
    assert r["feed_mm_min"] == [pytest.approx(254.0), pytest.approx(254.0)]
    assert r["operations"][0]["moves"] == {"rapid": 1, "linear": 1, "arc": 1, "helix": 0, "total": 3}


def test_apt_file(tmp_path):
    prog = tmp_path / "part.apt"
    prog.write_text("UNITS/INCHES\nPPRINT/'Face1'\nCUTTER/0.5, 0.05\nLOADTL/3\nFEDRAT/20, IPM\nRAPID\n"
                    "GOTO/0, 0, 1\nGOTO/0, 0, 0\nGOTO/2, 0, 0\nFINI\n")
    r = inspect_json(str(prog))
    assert r["format"].startswith("APT") and r["file_units"] == ["inch"]
    [tool] = r["tools"]
    assert tool["number"] == 3 and tool["kind"] == "bullnose"
    assert tool["diameter_mm"] == pytest.approx(12.7) and tool["corner_radius_mm"] == pytest.approx(1.27)
    assert r["operations"][0]["name"] == "Face1"
    assert r["extents_mm"]["all"]["max"][0] == pytest.approx(50.8)
    assert r["feed_mm_min"] == [pytest.approx(508.0), pytest.approx(508.0)]


@needs_data
def test_linuxcnc_tool_table_lists_tools_refusals_and_assumptions():
    r = inspect_json(str(TBL))
    assert r["format"] == "LinuxCNC tool table" and r["moves"] is None
    numbers = [t["number"] for t in r["tools"]]
    assert 3 not in numbers and {1, 2, 4, 24} <= set(numbers)
    t2 = next(t for t in r["tools"] if t["number"] == 2)
    assert t2["diameter_mm"] == 1.5 and t2["flute_length_mm"] == pytest.approx(4.5)  # assumed 3 x D
    [refused] = r["refused_tools"]
    assert refused["number"] == 3 and "tap drill" in refused["reason"] and "tbl:3" in refused["reason"]
    assert any("state no units" in w for w in r["warnings"])


@needs_data
def test_tools_option_replaces_the_program_tools(tmp_path):
    prog = tmp_path / "p.nc"
    prog.write_text("G21\nT2 M6\nG0 X0 Y0 Z1\nG1 Z-1 F100\nM30\n")
    r = inspect_json(str(prog), "--tools", str(TBL))
    used = [t for t in r["tools"] if t["used"]]
    assert [(t["number"], t["diameter_mm"]) for t in used] == [(2, 1.5)]
    assert any(f["number"] == 3 for f in r["refused_tools"])


@needs_data
def test_camotics_project_tools_stock_and_program_units():
    r = inspect_json(str(CAMOTICS))
    assert r["format"] == "CAMotics project"
    assert r["file_units"] == ["inch"]  # flower_mold.nc is a G20 program
    assert r["stock"]["max"][2] == 0.0 and r["stock"]["min"][2] < -9
    [prog] = r["programs"]
    assert prog["read"] and prog["moves"] == r["moves"]["total"] > 10000
    assert r["tools"][0]["number"] == 1


def test_fusion_tool_library_json(tmp_path):
    lib = tmp_path / "lib.json"
    lib.write_text(json.dumps({"version": 1, "data": [
        {"type": "ball end mill", "unit": "inches", "description": "1/4 ball",
         "geometry": {"DC": 0.25, "LCF": 0.75, "NOF": 2}, "post-process": {"number": 4}},
        {"type": "right tap", "unit": "millimeters", "geometry": {"DC": 5}, "post-process": {"number": 9}},
    ]}))
    r = inspect_json(str(lib))
    assert r["format"] == "Fusion tool library" and r["file_units"] == ["inch", "mm"]
    [ball] = r["tools"]
    assert ball["kind"] == "ball" and ball["diameter_mm"] == pytest.approx(6.35)
    assert ball["corner_radius_mm"] == pytest.approx(3.175) and ball["name"] == "1/4 ball"
    assert [f["number"] for f in r["refused_tools"]] == [9]


def test_json_has_no_nan(tmp_path):
    prog = tmp_path / "rapids.nc"
    prog.write_text("G21\nG0 X1 Y2 Z3\nM30\n")
    res = runner.invoke(app, ["inspect", str(prog), "--json"])
    assert res.exit_code == 0, res.output
    r = json.loads(res.stdout)
    assert r["feed_mm_min"] is None and r["extents_mm"]["feed"] is None
    assert r["moves"]["rapid"] == 1
    assert all(not (isinstance(v, float) and math.isnan(v)) for v in r["extents_mm"]["all"]["max"])


def test_malformed_program_is_one_line_with_file_and_line(tmp_path):
    prog = tmp_path / "bad.nc"
    prog.write_text("G21\nG1 X[1 + F100\n")
    res = runner.invoke(app, ["inspect", str(prog)])
    assert res.exit_code == 2
    assert "bad.nc:2" in res.output.replace("\n", "")
    assert "Traceback" not in res.output


def test_missing_file_and_bad_library_are_errors(tmp_path):
    res = runner.invoke(app, ["inspect", str(tmp_path / "nope.nc")])
    assert res.exit_code == 2 and "nope.nc" in res.output and "Traceback" not in res.output
    lib = tmp_path / "lib.tbl"
    lib.write_text("T1 P1 D3 ;ok\nT2 P2 D% ;broken\n")
    res = runner.invoke(app, ["inspect", str(lib)])
    assert res.exit_code == 2 and "lib.tbl:2" in res.output.replace("\n", "")


@pytest.fixture
def wide_consoles(monkeypatch):
    """The CLI's consoles 300 columns wide, whatever the terminal: rich reads COLUMNS when a console is
    made (at import), so a COLUMNS given to the command does nothing, and CI's 80 columns wrap paths."""
    from fusioncut.cli import _errors, inspect as inspect_cli

    for console in (inspect_cli.console, _errors.err_console):
        monkeypatch.setattr(console, "width", 300)


def test_names_with_brackets_are_shown_literally(tmp_path, wide_consoles):
    # rich reads "[d2.4mm]" as a style tag and drops it unless the text is escaped
    prog = tmp_path / "part[v2].nc"
    prog.write_text("G21\n(T1 D=2.4 CR=0 - ZMIN=-3 - flat end mill [d2.4mm])\n(Contour [d2.4mm])\nT1\n"
                    "G0 X0 Y0 Z1\nG1 Z-1 F100\nX5\nM30\n")
    r = inspect_json(str(prog))
    assert [t["name"] for t in r["tools"]] == ["[d2.4mm]"] and r["tools"][0]["kind"] == "flat"
    assert [op["name"] for op in r["operations"]] == ["Contour [d2.4mm]"]
    res = runner.invoke(app, ["inspect", str(prog)])
    assert res.exit_code == 0, res.output
    assert "part[v2].nc" in res.output
    # the table cells: the tool's name and the operation's
    assert "│ [d2.4mm] │" in res.output and "│ Contour [d2.4mm] │" in res.output


def test_errors_show_bracketed_paths_literally(tmp_path, wide_consoles):
    prog = tmp_path / "bad[d2.4mm].nc"
    prog.write_text("G21\nG1 X[1 + F100\n")
    res = runner.invoke(app, ["inspect", str(prog)])
    assert res.exit_code == 2
    assert "bad[d2.4mm].nc:2" in res.output


def test_percent_line_with_text_is_reported_not_the_end(tmp_path, wide_consoles):
    prog = tmp_path / "hobby.nc"
    prog.write_text("%\n(2D Contour1)\nG21 G90\nG0 X0 Y0 Z5\n% vfd enable\nG1 Z-1 F300\nX10\nY10\nM30\n%\n")
    r = inspect_json(str(prog))
    assert r["moves"]["total"] == 4
    assert r["warnings"] == [f"{prog}:5:1: '% vfd enable': a % line with text after the % is not a program "
                             "start or end (only a lone % is) (ignored)"]
    res = runner.invoke(app, ["inspect", str(prog)])
    assert res.exit_code == 0 and "'% vfd enable'" in res.output


def test_a_program_without_moves_says_why(tmp_path):
    prog = tmp_path / "early.nc"
    prog.write_text("G21\nM30\nG0 X1\nG1 X2 F100\n")
    r = inspect_json(str(prog))
    assert r["moves"]["total"] == 0
    assert r["warnings"] == [f"{prog}:2: M30 ends the program here: 2 lines with words are not read "
                             "(2 with axis words)", f"{prog}: no moves: M30 at line 2 ends the program before any move"]


def test_max_moves_bounds_what_a_program_expands_to(tmp_path, wide_consoles):
    prog = tmp_path / "loop.nc"
    prog.write_text("F100\no1 repeat [100]\nG1 X1\nG1 X0\no1 endrepeat\n")
    assert inspect_json(str(prog))["moves"]["total"] == 200
    assert inspect_json(str(prog), "--max-moves", "0")["moves"]["total"] == 200
    res = runner.invoke(app, ["inspect", str(prog), "--max-moves", "199"])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "loop.nc:2:1: the program expands to more than 199 moves (a repeat loop of 100 × 2)" in res.output
