"""Where a tool's definition comes from: the job, the tool library or the program (issue 23 item 6),
and drills in G-code tool comments (item 7)."""
from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import pytest

from fusioncut.errors import InputError, ToolDefinitionError
from fusioncut.io.gcode import parse_gcode_text
from fusioncut.io.job import Job, StockSpec, ToolSpec, load_job
from fusioncut.io.tool_sources import resolve_tools
from fusioncut.model.moves import LinearMove
from fusioncut.model.tools import BallEndMill, ChamferMill, Drill, FlatEndMill
from fusioncut.runner import prepare_job

PROGRAM = """%
(T2 D=3.175 CR=0 - ZMIN=-1 - flat end mill)
G21 G90
T2 M6
S10000 M3
G0 X0 Y0 Z5
G1 Z-1 F100
G1 X10
G0 Z5
M30
%
"""


def entry(type_: str, number: int | None, geometry: dict, description: str, guid: str) -> dict:
    """A Fusion library tool entry, trimmed to what the reader uses."""
    e = {"type": type_, "unit": "millimeters", "description": description, "guid": guid, "geometry": geometry}
    if number is not None:
        e["post-process"] = {"number": number}
    return e


LIBRARY = {"data": [
    entry("flat end mill", 2, {"DC": 4, "LCF": 12, "LB": 30, "SFDM": 4}, "4 mm flat", "g-4"),
    entry("flat end mill", 2, {"DC": 3.175, "LCF": 12, "LB": 30, "SFDM": 3.175}, "1/8 flat", "g-125"),
    entry("flat end mill", 3, {"DC": 6, "LCF": 15}, "6 mm flat", "g-6"),
]}


def job_in(tmp_path: Path, program: str = PROGRAM, library: dict | None = None, **fields) -> tuple[Job, Path]:
    (tmp_path / "prog.nc").write_text(program)
    if library is not None:
        (tmp_path / "lib.json").write_text(json.dumps(library))
        fields.setdefault("tool_library", "lib.json")
    doc = {"stock": {"kind": "box", "min": [-5, -5, -5], "max": [15, 5, 0]}, "toolpaths": ["prog.nc"], **fields}
    (tmp_path / "job.json").write_text(json.dumps(doc))
    return load_job(tmp_path / "job.json")


def tool_warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if ": T2: " in r.getMessage()]


def test_library_overriding_the_programs_tool_is_warned_naming_both(tmp_path, caplog):
    job, base = job_in(tmp_path, library=LIBRARY)
    with caplog.at_level(logging.WARNING, logger="fusioncut"):
        p = prepare_job(job, base)
    assert p.toolpath.tools[2].diameter == 4  # the library wins by default, as before
    [w] = tool_warnings(caplog)
    assert w.startswith(f"{base / 'prog.nc'}:6:1: T2: ")  # the first move with T2
    assert f"the tool library ({base / 'lib.json'}: data[0] '4 mm flat') says flat D=4" in w
    assert f"the program ({base / 'prog.nc'}:2:1) says flat D=3.175" in w
    assert "0.4125 mm apart" in w and "using the tool library's;" in w and "tool_source 'library'" in w
    assert w in p.toolpath.warnings  # kept with the reader warnings (results, inspect-style reports)


def test_tool_source_program_puts_the_programs_tool_first(tmp_path, caplog):
    job, base = job_in(tmp_path, library=LIBRARY, tool_source="program")
    with caplog.at_level(logging.WARNING, logger="fusioncut"):
        p = prepare_job(job, base)
    assert p.toolpath.tools[2].diameter == 3.175
    [w] = tool_warnings(caplog)
    assert "using the program's;" in w and "tool_source 'program'" in w
    # a library refusal does not matter when the program's own tool is used
    refused = {"data": [entry("thread mill", 2, {"DC": 3, "LCF": 6}, "threads", "g-t")]}
    job, base = job_in(tmp_path, library=refused, tool_source="program")
    assert prepare_job(job, base).toolpath.tools[2].diameter == 3.175
    job, base = job_in(tmp_path, library=refused)
    with pytest.raises(ToolDefinitionError, match=r"prog\.nc:6:1: the program uses T2 here, but .*thread mill"):
        prepare_job(job, base)


def test_job_picks_a_library_tool_by_name_or_id(tmp_path, caplog):
    for pick in ({"name": "1/8 FLAT"}, {"id": "g-125"}):
        job, base = job_in(tmp_path, library=LIBRARY, tools=[{"number": 2, "library": pick}])
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="fusioncut"):
            p = prepare_job(job, base)
        tool = p.toolpath.tools[2]
        assert tool.diameter == 3.175 and tool.number == 2 and tool.name == "1/8 flat"
        assert tool_warnings(caplog) == []  # agrees with the program's comment
        assert any("T2 is the number of 2 tools" in r.getMessage() for r in caplog.records)
    job, base = job_in(tmp_path, library=LIBRARY, tools=[{"number": 2, "library": {"name": "6 mm flat"}}])
    with caplog.at_level(logging.WARNING, logger="fusioncut"):
        p = prepare_job(job, base)
    assert p.toolpath.tools[2].diameter == 6  # the job's choice wins; the program disagrees
    assert any("the job's tools" in w and "says flat D=6" in w for w in tool_warnings(caplog))
    job, base = job_in(tmp_path, library=LIBRARY, tools=[{"number": 2, "library": {"name": "nothing"}}])
    with pytest.raises(ToolDefinitionError, match=r"tools\[0\] \(T2\): .*no tool with name 'nothing'"):
        prepare_job(job, base)
    job, base = job_in(tmp_path, tools=[{"number": 2, "library": {"id": "g-125"}}])
    with pytest.raises(InputError, match="picked from the tool library, but the job has no 'tool_library'"):
        prepare_job(job, base)


@pytest.mark.parametrize("doc, message", [
    ({"number": 2, "library": {"name": "a", "id": "b"}}, "give exactly one of 'name' and 'id'"),
    ({"number": 2, "library": {}}, "give exactly one of 'name' and 'id'"),
    ({"number": 2, "library": {"name": "a"}, "diameter": 3}, "takes only 'number' and 'library', not diameter"),
    ({"number": 2, "kind": "flat"}, "a tool needs diameter, flute_length"),
    ({"number": 2, "library": {"guid": "x"}}, "Extra inputs are not permitted"),
])
def test_job_tool_entries_are_validated(tmp_path, doc, message):
    with pytest.raises(InputError, match=message):
        job_in(tmp_path, tools=[doc])


def test_tool_source_is_validated(tmp_path):
    with pytest.raises(InputError, match="tool_source"):
        job_in(tmp_path, tool_source="library first")


def test_sizes_rounded_as_posts_write_them_agree(tmp_path, caplog):
    """An inch program's D=0.125 is the library's 3.175 mm; 3-decimal rounding is no disagreement."""
    inch = PROGRAM.replace("D=3.175", "D=0.125").replace("G21", "G20").replace("ZMIN=-1", "ZMIN=-0.04")
    inch = inch.replace("Z-1", "Z-0.04").replace("X10", "X0.4").replace("Z5", "Z0.2")
    library = {"data": [entry("flat end mill", 2, {"DC": 3.175, "LCF": 12}, "1/8 flat", "g-1")]}
    job, base = job_in(tmp_path, program=inch, library=library,
                       stock={"kind": "box", "min": [-5, -5, -5], "max": [15, 5, 0]})
    with caplog.at_level(logging.WARNING, logger="fusioncut"):
        prepare_job(job, base)
    assert tool_warnings(caplog) == []
    rounded = PROGRAM.replace("D=3.175", "D=3.1754")
    job, base = job_in(tmp_path, program=rounded, library=library)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="fusioncut"):
        prepare_job(job, base)
    assert tool_warnings(caplog) == []


def test_program_first_compensates_with_the_programs_radius(tmp_path):
    comp = PROGRAM.replace("G1 X10\n", "G41 D2 G1 X5\nG1 X10\nG40 G0 Z5\n")
    job, base = job_in(tmp_path, program=comp, library=LIBRARY)
    by_library = prepare_job(job, base).toolpath.moves
    job, base = job_in(tmp_path, program=comp, library=LIBRARY, tool_source="program")
    by_program = prepare_job(job, base).toolpath.moves
    y_lib = {round(m.end[1], 6) for m in by_library if m.end[0] == 10 and m.end[2] == -1}
    y_prog = {round(m.end[1], 6) for m in by_program if m.end[0] == 10 and m.end[2] == -1}
    assert y_lib == {2.0} and y_prog == {1.5875}  # left of +x: +y by the radius of the tool used


def test_resolve_tools_orders_and_defaults():
    moves = [LinearMove((0, 0, 0), (1, 0, 0), feed=100, tool=1)]
    program = {1: FlatEndMill(3, 9, source="p.nc:3")}
    job = {1: BallEndMill(3, 9)}
    tools, default, warnings = resolve_tools(moves, job, None, program)
    assert isinstance(tools[1], BallEndMill) and default is None
    assert len(warnings) == 1 and "the job's tools says ball D=3, the program (p.nc:3) says flat D=3" in warnings[0]
    # a drill and a pointed chamfer of half its point angle are the same cutter: no warning
    same = {1: ChamferMill(3, 9, taper_angle=59)}
    _, _, quiet = resolve_tools(moves, same, None, {1: Drill(3, 9, point_angle=118)})
    assert quiet == []
    with pytest.raises(InputError, match="no tool definition for T1"):
        resolve_tools(moves, {}, None, {})


# ------------------------------------------------------------------------------- G-code tool comments


@pytest.mark.parametrize("comment, angle", [
    ("(T5 D=6.8 CR=0 TAPER=118deg - ZMIN=-20 - drill)", 118.0),
    ("(T5 D=6.8 CR=0 TAPER=140deg - ZMIN=-20 - drill)", 140.0),
    ("(T5 D=6.8 CR=0 - ZMIN=-20 - drill)", 118.0),
    ("(T5 D=6.8 CR=0 TAPER=90deg - ZMIN=-2 - spot drill)", 90.0),
])
def test_drill_comment_taper_is_the_point_angle(comment, angle):
    """Issue 23 item 7: Fusion writes a drill's point angle as TAPER=118deg; it was refused as a
    chamfer half-angle outside (0, 90) and the drilling cycle had no tool."""
    tp = parse_gcode_text(f"{comment}\nG21\nT5 M6\nG0 X0 Y0 Z5\nG81 X0 Y0 Z-20 R2 F100\nG80\n", source="d.nc")
    drill = tp.tools[5]
    assert isinstance(drill, Drill) and drill.point_angle == angle and drill.diameter == 6.8
    assert drill.cone_height == pytest.approx(3.4 / math.tan(math.radians(angle / 2)))
    assert drill.source == "d.nc:1:1"
    assert not any("not usable" in w for w in tp.warnings)


def test_given_tools_keep_the_programs_own():
    given = {2: FlatEndMill(4, 12)}
    tp = parse_gcode_text(PROGRAM, source="p.nc", tools=given)
    assert tp.tools == given
    assert tp.program_tools is not None and tp.program_tools[2].diameter == 3.175
    assert tp.program_tools[2].source == "p.nc:2:1"
    assert parse_gcode_text(PROGRAM, source="p.nc").program_tools is None


def test_job_tool_kinds_drill_and_neck():
    drill = ToolSpec(number=4, kind="drill", diameter=5, flute_length=40, point_angle=135).build()
    assert isinstance(drill, Drill) and drill.point_angle == 135
    neck = ToolSpec(number=1, kind="flat", diameter=4, flute_length=12, neck_diameter=3.8, shoulder_length=18,
                    shank_diameter=6, overall_length=40).build()
    assert neck.profile().radius_at(15) == pytest.approx(1.9)
    assert Job(stock=StockSpec(kind="infer"), toolpaths=["p.nc"]).tool_source == "library"


def test_inspect_with_a_library_reports_the_disagreement(tmp_path):
    from fusioncut.cli.inspect import inspect_file

    (tmp_path / "prog.nc").write_text(PROGRAM)
    (tmp_path / "lib.json").write_text(json.dumps(LIBRARY))
    report = inspect_file(tmp_path / "prog.nc", tmp_path / "lib.json")
    [w] = [w for w in report["warnings"] if ": T2: " in w]
    assert w.startswith(f"{tmp_path / 'prog.nc'}:6:1: T2: the tool library (") and "says flat D=3.175" in w
    agreeing = {"data": [LIBRARY["data"][1]]}
    (tmp_path / "lib.json").write_text(json.dumps(agreeing))
    assert not any(": T2: " in w for w in inspect_file(tmp_path / "prog.nc", tmp_path / "lib.json")["warnings"])


def test_table_tools_name_their_line_in_warnings(tmp_path, caplog):
    (tmp_path / "t.tbl").write_text("T1 P1 D1.5 ;1.5mm end mill\nT2 P2 D4 ;4mm end mill\n")
    job, base = job_in(tmp_path, tool_library="t.tbl")
    with caplog.at_level(logging.WARNING, logger="fusioncut"):
        prepare_job(job, base)
    [w] = tool_warnings(caplog)
    assert f"the tool library ({base / 't.tbl'}:2) says flat D=4" in w
