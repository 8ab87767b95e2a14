"""Fusion JSON-post toolpath reader."""
from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusioncut.errors import FusionCutError, InputError, ToolDefinitionError
from fusioncut.io.fusion_json import read_fusion_json
from fusioncut.model.moves import ArcMove, ArcPlane
from fusioncut.model.tools import BallEndMill, BullNoseEndMill, ChamferMill, Drill, SpindleDirection


def section(tool: dict, *, speed=12000, direction="cw", feed_mode="per min", forward=(0, 0, 1)) -> dict:
    """A section entry as json.cps writes it (jobId/patternId/wcs/fcs included for realism)."""
    frame = {"right": [1, 0, 0], "up": [0, 1, 0], "forward": list(forward), "origin": [0, 0, 0]}
    return {"section": {
        "jobId": 1, "patternId": 0, "type": "milling", "spindle": {"speed": speed, "direction": direction},
        "feedMode": feed_mode, "tool": tool, "wcs": frame, "fcs": frame, "work": frame, "workOffset": 1,
    }}


BULL = {"type": "bullnose mill", "number": 3, "lengthOffset": 3, "diameterOffset": 3, "diameter": 10,
        "cornerRadius": 1, "tipDiameter": 8, "fluteLength": 22, "bodyLength": 40, "live": True}
BALL = {"type": "ball mill", "number": 5, "lengthOffset": 5, "diameterOffset": 5, "diameter": 6,
        "cornerRadius": 3, "tipDiameter": 0, "fluteLength": 15, "bodyLength": 30, "live": True}
CHAMFER = {"type": "chamfer mill", "number": 7, "diameter": 8.3, "cornerRadius": 0, "tipDiameter": 2,
           "taperAngle": 45, "fluteLength": 16.6, "bodyLength": 50}
DRILL = {"type": "drill", "number": 9, "diameter": 4.2, "cornerRadius": 0, "tipDiameter": 0, "taperAngle": 118,
         "fluteLength": 30, "bodyLength": 40}


def program(unit: str = "mm") -> dict:
    return {"type": "hsm", "version": 1, "unit": unit, "name": "1001", "comment": "bracket", "toolpath": [
        {"p": {"name": "job-description", "value": "Setup1"}},
        {"p": {"name": "operation-comment", "value": "2D Contour1"}},
        section(BULL),
        {"coolant": {"active": True}},
        {"coolant": {"mode": "flood"}},
        {"lf": [0, 0, 15]},
        {"lf": [10, 0, 5]},
        {"f": 300},
        {"l": [10, 0, -2]},
        {"f": 1000},
        {"l": [20, 0, -2]},
        {"c": {"e": [20, 10, -2], "c": [20, 5, -2], "n": [0, 0, 1], "a": 180}},
        {"c": {"e": [20, 0, -3], "c": [20, 5, -2], "n": [0, 0, -1], "a": 180}},
        {"lf": [20, 0, 15]},
        {"p": {"name": "operation-comment", "value": "Parallel1"}},
        section(BALL, speed=15000, direction="ccw"),
        {"lf": [0, 0, 15]},
        {"f": 800},
        {"m": {"e": [0, 0, 1], "z": [0, 0, 1]}},
        {"c": {"e": [0, 2, 3], "c": [0, 0, 3], "n": [1, 0, 0], "a": 90}},
        {"lf": [0, 2, 15]},
        {"p": {"name": "operation-comment", "value": "Drill1"}},
        section(CHAMFER),
        {"cycle": {"clearance": 10, "retract": 5, "stock": 0, "depth": 1, "feedrate": 100, "type": "drilling",
                   "points": [{"p": [30, 0, -1]}, {"p": [40, 0, -1]}]}},
        {"lf": [40, 0, 20]},
    ]}


ARC = {"e": [20, 10, -2], "c": [20, 5, -2], "n": [0, 0, 1], "a": 180}


def write(tmp_path: Path, doc: dict | str, name: str = "prog.json", *, pretty: bool = False) -> Path:
    p = tmp_path / name
    p.write_text(doc if isinstance(doc, str) else json.dumps(doc, indent=1 if pretty else None))
    return p


def test_sample_program(tmp_path):
    path = write(tmp_path, program())
    tp = read_fusion_json(path)
    first = tp.moves[0]  # the first rapid only sets the position
    assert first.start == (0.0, 0.0, 15.0) and first.end == (10.0, 0.0, 5.0) and first.is_rapid
    plunge, cut, arc1, arc2 = tp.moves[1:5]
    assert plunge.feed == 300.0 and cut.feed == 1000.0 and not plunge.is_rapid
    assert isinstance(arc1, ArcMove) and not arc1.clockwise and arc1.point_at(0.5) == pytest.approx((25, 5, -2))
    # clockwise from 12 o'clock passes 3 o'clock, descending 1 mm over the half turn
    assert arc2.clockwise and arc2.point_at(0.5) == pytest.approx((25, 5, -2.5))
    assert {m.operation for m in tp.moves} == {"2D Contour1", "Parallel1", "Drill1"}
    assert isinstance(tp.tools[3], BullNoseEndMill) and tp.tools[3].corner_radius == 1.0
    assert tp.tools[3].overall_length == 40.0
    ball = tp.tools[5]
    assert isinstance(ball, BallEndMill) and ball.spindle is SpindleDirection.CCW
    chamfer = tp.tools[7]
    assert isinstance(chamfer, ChamferMill) and chamfer.tip_diameter == 2.0 and chamfer.taper_angle == 45.0
    assert {m.spindle_rpm for m in tp.moves if m.tool == 5} == {15000.0}


def test_yz_arc_from_rotation_axis(tmp_path):
    tp = read_fusion_json(write(tmp_path, program()))
    arc = next(m for m in tp.moves if isinstance(m, ArcMove) and m.plane is not ArcPlane.XY)
    # about +x from (0,0,1) round (0,0,3) to (0,2,3): y towards z is counter-clockwise in YZ
    assert arc.plane is ArcPlane.YZ and not arc.clockwise
    assert arc.point_at(0.5) == pytest.approx((0, 2 * math.sin(math.pi / 4), 3 - 2 * math.cos(math.pi / 4)))
    assert math.isclose(abs(arc.sweep), math.pi / 2)
    assert arc.tool == 5 and arc.feed == 800.0


def test_cycle_expanded_to_plunges(tmp_path):
    tp = read_fusion_json(write(tmp_path, program()))
    drill = [m for m in tp.moves if m.operation == "Drill1"]
    ends = [(m.end, m.is_rapid) for m in drill]
    assert ends[:4] == [((30, 0, 10), True), ((30, 0, 5), True), ((30, 0, -1), False), ((30, 0, 10), True)]
    assert ends[4:8] == [((40, 0, 10), True), ((40, 0, 5), True), ((40, 0, -1), False), ((40, 0, 10), True)]
    assert drill[2].feed == 100.0
    assert any("canned cycles" in w for w in tp.warnings)


def test_entry_positions_are_line_and_column(tmp_path):
    doc = program()
    path = write(tmp_path, doc, pretty=True)
    tp = read_fusion_json(path)
    lines = path.read_text().splitlines()
    plunge = tp.moves[1]
    # the pretty-printed entry {"l": [10, 0, -2]} starts at the reported line:column
    assert lines[plunge.source.line - 1][plunge.source.column - 1] == "{"
    assert '"l"' in lines[plunge.source.line]
    one_line = read_fusion_json(write(tmp_path, doc, "flat.json"))
    assert {m.source.line for m in one_line.moves} == {1}
    assert len({m.source.column for m in one_line.moves}) > 5


def test_inch_program(tmp_path):
    doc = program("in")
    tp = read_fusion_json(write(tmp_path, doc))
    assert tp.moves[1].end == pytest.approx((254.0, 0.0, -50.8))
    assert tp.moves[1].feed == pytest.approx(300 * 25.4)
    assert tp.tools[3].diameter == pytest.approx(254.0)


def test_per_revolution_feed(tmp_path):
    doc = program()
    doc["toolpath"][2] = section(BULL, speed=2000, feed_mode="per rev")
    doc["toolpath"][7] = {"f": 0.05}
    assert read_fusion_json(write(tmp_path, doc)).moves[1].feed == pytest.approx(100.0)


def test_fast_feed_makes_linear_moves_rapid(tmp_path):
    doc = program()
    doc["toolpath"].insert(13, {"f": "fast"})
    doc["toolpath"].insert(14, {"l": [20, 0, 30]})
    tp = read_fusion_json(write(tmp_path, doc))
    assert any(m.end == (20, 0, 30) and m.is_rapid for m in tp.moves)


def test_tilted_tool_axis_is_refused(tmp_path):
    doc = program()
    doc["toolpath"][18] = {"m": {"e": [0, 0, 1], "z": [0, 0.6, 0.8]}}
    path = write(tmp_path, doc)
    with pytest.raises(InputError, match=r"5-axis not supported yet") as err:
        read_fusion_json(path)
    assert "toolpath[18].m.z" in str(err.value) and str(path) in str(err.value)


def test_tilted_work_plane_is_refused(tmp_path):
    doc = program()
    doc["toolpath"][15] = section(BALL, forward=(0, -1, 0))
    with pytest.raises(InputError, match=r"toolpath\[15\]\.section\.work\.forward: 5-axis not supported yet"):
        read_fusion_json(write(tmp_path, doc))


def test_drill_sections_cut_with_a_pointed_drill(tmp_path):
    """Issue 23 item 7: a drill's taperAngle is its point angle (118), not a chamfer half-angle."""
    doc = program()
    doc["toolpath"][22] = section(DRILL)
    tp = read_fusion_json(write(tmp_path, doc))
    drill = tp.tools[9]
    assert isinstance(drill, Drill) and drill.point_angle == 118 and drill.diameter == 4.2
    assert drill.cone_height == pytest.approx(2.1 / math.tan(math.radians(59)))
    plunges = [m for m in tp.moves if m.operation == "Drill1" and not m.is_rapid]
    assert [m.end for m in plunges] == [(30, 0, -1), (40, 0, -1)] and {m.tool for m in plunges} == {9}


def test_unsupported_tool_refused_or_skipped(tmp_path):
    doc = program()
    doc["toolpath"][22] = section({**DRILL, "type": "right tap"})
    doc["toolpath"] += [{"p": {"name": "operation-comment", "value": "Finish"}}, section(BALL), {"lf": [50, 0, 20]}]
    path = write(tmp_path, doc)
    with pytest.raises(ToolDefinitionError, match=r"toolpath\[22\]\.section\.tool: tool right tap \(T9\) is a tap"):
        read_fusion_json(path)
    tp = read_fusion_json(path, skip_unsupported_tools=True)
    assert not any(m.operation == "Drill1" for m in tp.moves)
    # the skipped section still moves the tool: the next section starts where it ended
    assert tp.moves[-1].start == (40.0, 0.0, 20.0) and tp.moves[-1].end == (50.0, 0.0, 20.0)
    assert any("section skipped" in w for w in tp.warnings)


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: d.update(type="nc"), r"type: Input should be 'hsm'"),
        (lambda d: d.pop("toolpath"), r"toolpath: missing"),
        (lambda d: d.update(toolpath={"l": [1, 2, 3]}), r"toolpath: not an array"),
        (lambda d: d.update(unit="furlong"), r"unit: Input should be 'mm' or 'in'"),
        (lambda d: d["toolpath"].__setitem__(8, {"l": [10, 0]}), r"toolpath\[8\]\.l\[2\]: Field required"),
        (lambda d: d["toolpath"].__setitem__(8, {"l": [10, "0", 1]}),
         r"toolpath\[8\]\.l\[1\]: Input should be a valid number"),
        (lambda d: d["toolpath"].__setitem__(8, {"l": [1, 2, 3], "f": 5}), r"toolpath\[8\]: expected one key"),
        (lambda d: d["toolpath"].__setitem__(8, [1, 2, 3]), r"toolpath\[8\]: expected an object"),
        (lambda d: d["toolpath"].__setitem__(7, {"f": -3}), r"toolpath\[7\]\.f: feed must be > 0"),
        (lambda d: d["toolpath"].__setitem__(11, {"c": {**ARC, "e": [20, 11, -2]}}),
         r"toolpath\[11\]\.c: arc end point is not on the circle"),
        (lambda d: d["toolpath"].__setitem__(11, {"c": {**ARC, "a": 90}}),
         r"toolpath\[11\]\.c: arc end point does not lie 90 degrees"),
        (lambda d: d["toolpath"].__setitem__(8, {"l": [1e300, 0, 0]}), r"out of range"),
        (lambda d: d["toolpath"][2]["section"].update(type="turning"), r"milling only"),
        (lambda d: d["toolpath"].pop(7), r"toolpath\[7\]\.l: feed move before any feed"),
    ],
)
def test_malformed_programs_name_the_json_path(tmp_path, mutate, message):
    doc = program()
    mutate(doc)
    path = write(tmp_path, doc)
    with pytest.raises(InputError, match=message) as err:
        read_fusion_json(path)
    assert err.value.where.file == str(path)


@pytest.mark.parametrize(
    "text, line, column",
    [
        ('{"type": "hsm",\n "toolpath": [{"l": [1, 2, 3]},\n {"l": [1, 2 3]}]}', 3, 14),
        ('{"type": "hsm", "toolpath": [{"l": [NaN, 2, 3]}]}', 1, 30),
        ('[1, 2]', 1, 1),
        ('', 1, 1),
        ('{"type": "hsm", "unit": "mm", "version": 1, "toolpath": []} trailing', 1, 61),
    ],
)
def test_json_syntax_errors_have_line_and_column(tmp_path, text, line, column):
    path = write(tmp_path, text)
    with pytest.raises(InputError, match="not valid JSON") as err:
        read_fusion_json(path)
    assert (err.value.where.line, err.value.where.column) == (line, column)


def test_unreadable_files(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        read_fusion_json(tmp_path / "absent.json")
    bad = tmp_path / "bad.json"
    bad.write_bytes(b'{"type": "hsm", "name": "\xff"}')
    with pytest.raises(InputError, match="not UTF-8"):
        read_fusion_json(bad)


def test_unknown_entries_are_reported_once(tmp_path):
    doc = program()
    doc["toolpath"][4:4] = [{"laser": {"power": 3}}, {"laser": {"power": 4}}]
    tp = read_fusion_json(write(tmp_path, doc))
    assert sum("unknown entry" in w for w in tp.warnings) == 1


# ---------------------------------------------------------------------------------------------------
# fuzzing


@pytest.fixture(scope="module")
def fuzz_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("json-fuzz")


_JUNK = st.one_of(
    st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=False, allow_infinity=False),
    st.text(max_size=5), st.lists(st.integers(-5, 5), max_size=4),
    st.dictionaries(st.sampled_from(["e", "c", "n", "a", "l", "f", "type", "p", "z"]), st.integers(-3, 3), max_size=3),
)


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, prefix + (i,))


def _check(path: Path) -> None:
    try:
        read_fusion_json(path)
    except FusionCutError as e:
        assert str(path) in str(e)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_fuzz_structural_mutations(fuzz_dir, data):
    doc = copy.deepcopy(program(data.draw(st.sampled_from(["mm", "in"]))))
    for _ in range(data.draw(st.integers(1, 3))):
        paths = [p for p in _paths(doc) if p]
        target = data.draw(st.sampled_from(paths))
        parent = doc
        for k in target[:-1]:
            parent = parent[k]
        if data.draw(st.booleans()) and isinstance(parent, (dict, list)):
            del parent[target[-1]]
        else:
            parent[target[-1]] = data.draw(_JUNK)
    path = fuzz_dir / "mutated.json"
    path.write_text(json.dumps(doc))
    _check(path)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_fuzz_text_mutations(fuzz_dir, data):
    text = json.dumps(program())
    for _ in range(data.draw(st.integers(1, 3))):
        at = data.draw(st.integers(0, len(text)))
        cut = data.draw(st.integers(0, 4))
        text = text[:at] + data.draw(st.text(alphabet='{}[],:"0123456789.-eE abcfl', max_size=4)) + text[at + cut:]
    path = fuzz_dir / "text.json"
    path.write_text(text)
    _check(path)
