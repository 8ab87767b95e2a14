"""Tool libraries: Fusion .json/.tools, LinuxCNC .tbl, CAMotics projects."""
from __future__ import annotations

import copy
import json
import math
import zipfile

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusioncut.errors import FusionCutError, InputError, ToolDefinitionError
from fusioncut.io.tool_library import ToolLibrary, read_camotics_project, read_tool_library
from fusioncut.model.stock import BoxStock
from fusioncut.model.tools import (
    AptCutter,
    BallEndMill,
    BullNoseEndMill,
    ChamferMill,
    Drill,
    FlatEndMill,
    SpindleDirection,
    TaperedEndMill,
)

from shared_data import DATA
TBL = DATA / "linuxcnc-tool-tables"
CAMOTICS = DATA / "camotics-examples"
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason="shared test data (../shared/data) not present")


def fusion_entry(type_: str, number: int, geometry: dict, unit: str = "millimeters", description: str = "") -> dict:
    """One tool as Fusion's library export writes it (presets and holder trimmed to what matters)."""
    return {
        "BMC": "carbide", "GRADE": "Mill Generic", "description": description or type_, "geometry": geometry,
        "guid": f"00000000-0000-0000-0000-{number:012d}",
        "holder": {"description": "ER32", "segments": [{"height": 20, "lower-diameter": 32, "upper-diameter": 40}],
                   "type": "holder", "unit": "millimeters"},
        "post-process": {"break-control": False, "comment": "", "diameter-offset": number,
                         "length-offset": number, "live": True, "manual-tool-change": False, "number": number,
                         "turret": 0},
        "start-values": {"presets": [{"name": "Default", "n": 12000, "v_f": 1000}]},
        "type": type_, "unit": unit, "vendor": "",
    }


LIBRARY = {"version": 1, "data": [
    fusion_entry("flat end mill", 1, {"CSP": False, "DC": 6, "HAND": True, "LB": 30, "LCF": 15, "NOF": 3,
                                      "OAL": 50, "RE": 0, "SFDM": 6, "shoulder-length": 18, "tip-diameter": 6}),
    fusion_entry("ball end mill", 2, {"DC": 4, "LB": 20, "LCF": 8, "NOF": 4, "OAL": 28, "RE": 2, "SFDM": 4,
                                      "tip-diameter": 0, "HAND": False}),
    fusion_entry("bull nose end mill", 3, {"DC": 10, "LB": 40, "LCF": 22, "NOF": 4, "OAL": 75, "RE": 1, "SFDM": 10}),
    fusion_entry("chamfer mill", 4, {"DC": 8.3, "LB": 50, "LCF": 16.6, "NOF": 3, "OAL": 66.6, "RE": 0, "SFDM": 6,
                                     "TA": 45, "tip-diameter": 2}),
    fusion_entry("face mill", 5, {"DC": 40, "LB": 40, "LCF": 5, "NOF": 5, "OAL": 60, "SFDM": 22}),
    fusion_entry("tapered mill", 6, {"DC": 6, "LCF": 20, "TA": 5, "tip-diameter": 1.5, "RE": 0}),
    fusion_entry("tapered mill", 7, {"DC": 0.25, "LCF": 0.75, "TA": 10, "RE": 0.015, "LB": 1, "OAL": 2.2},
                 unit="inches"),
    fusion_entry("spot drill", 8, {"DC": 4, "LB": 55, "LCF": 12, "NOF": 2, "OAL": 63, "SIG": 90, "tip-diameter": 0}),
    fusion_entry("drill", 9, {"DC": 3, "LB": 39, "LCF": 30, "NOF": 2, "OAL": 45, "SIG": 118}),
    fusion_entry("thread mill", 10, {"DC": 5, "LCF": 10, "TP": 1}),
    fusion_entry("chamfer mill", 11, {"DC": 0.25, "LB": 0.6, "LCF": 0.125, "OAL": 2, "TA": 45, "tip-diameter": 0},
                 unit="inches", description='90 deg V-bit 1/4"'),
    fusion_entry("chamfer mill", 12, {"DC": 0.25, "LB": 3, "LCF": 0.005, "OAL": 4, "TA": 60, "tip-diameter": 0},
                 unit="inches", description="diamond drag engraver"),
    {"type": "holder", "description": "BT30 ER20", "segments": [], "unit": "millimeters"},
]}


def check_library(lib: ToolLibrary) -> None:
    flat, ball, bull, chamfer, face = (lib[n] for n in (1, 2, 3, 4, 5))
    assert isinstance(flat, FlatEndMill) and flat.diameter == 6 and flat.flute_length == 15 and flat.flutes == 3
    assert flat.overall_length == 30  # stick-out below the holder
    assert isinstance(ball, BallEndMill) and ball.spindle is SpindleDirection.CCW
    assert isinstance(bull, BullNoseEndMill) and bull.corner_radius == 1
    assert isinstance(chamfer, ChamferMill) and chamfer.tip_diameter == 2 and chamfer.taper_angle == 45
    assert isinstance(face, FlatEndMill) and face.diameter == 40
    tapered = lib[6]
    assert isinstance(tapered, TaperedEndMill) and tapered.diameter == 1.5 and tapered.taper_angle == 5
    tb = lib[7]  # tapered ball nose, 0.015" ball on the axis, 10 deg per side
    assert isinstance(tb, AptCutter)
    assert tb.apt_parameters.r == pytest.approx(0.381) and tb.apt_parameters.beta == 10
    assert tb.profile().radius_at(0.0) == pytest.approx(0.0, abs=1e-9)
    spot = lib[8]
    assert isinstance(spot, ChamferMill) and spot.taper_angle == 45 and spot.tip_diameter == 0
    v = lib[11]
    assert v.diameter == pytest.approx(6.35) and v.flute_length == pytest.approx(3.175)
    engraver = lib[12]  # cone taller than the stated flute length: the flutes are stretched to it
    assert engraver.flute_length == pytest.approx(3.175 / math.tan(math.radians(60)))
    drill = lib[9]  # SIG is the point's included angle: a 118 deg point is a cone of half-angle 59 deg
    assert isinstance(drill, Drill) and drill.point_angle == 118 and drill.diameter == 3
    assert drill.cone_height == pytest.approx(1.5 / math.tan(math.radians(59)))
    assert set(lib) == {1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12}
    assert set(lib.refused) == {10}
    with pytest.raises(ToolDefinitionError, match="thread mill"):
        lib.require(10)
    with pytest.raises(ToolDefinitionError, match="T99 is not in the tool library"):
        lib.require(99)
    assert lib.require(1) is flat
    assert any("cone" in w and "data[11]" in w for w in lib.warnings)


def test_fusion_json_library(tmp_path):
    p = tmp_path / "library.json"
    p.write_text(json.dumps(LIBRARY, indent=2))
    lib = read_tool_library(p)
    check_library(lib)
    assert lib.source == str(p)


def test_fusion_tools_archive(tmp_path):
    p = tmp_path / "library.tools"
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("tools.json", json.dumps(LIBRARY))
    check_library(read_tool_library(p))


def test_bad_archive_and_bad_library(tmp_path):
    p = tmp_path / "broken.tools"
    p.write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(InputError, match="not a Fusion .tools archive"):
        read_tool_library(p)
    empty = tmp_path / "empty.tools"
    with zipfile.ZipFile(empty, "w") as zf:
        zf.writestr("readme.txt", "hello")
    with pytest.raises(InputError, match="no JSON tool library"):
        read_tool_library(empty)
    wrong = tmp_path / "wrong.tools"
    with zipfile.ZipFile(wrong, "w") as zf:
        zf.writestr("tools.json", json.dumps({"data": "none"}))
    with pytest.raises(InputError, match=r"tools\.json: data: Input should be a valid list") as err:
        read_tool_library(wrong)
    assert err.value.where.file == str(wrong)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"data": [{"type": "flat end mill", "geometry": {"DC": "six"}}]}))
    with pytest.raises(InputError, match=r"data\[0\]\.geometry\.DC: Input should be a valid number") as err:
        read_tool_library(bad)
    assert err.value.where.file == str(bad)
    syntax = tmp_path / "syntax.json"
    syntax.write_text('{"data": [\n  {"type": }\n]}')
    with pytest.raises(InputError, match="not valid JSON") as err:
        read_tool_library(syntax)
    assert err.value.where.line == 2
    with pytest.raises(InputError, match="unknown tool library type"):
        read_tool_library(tmp_path / "tools.xml")


def test_duplicate_numbers_keep_the_first(tmp_path):
    doc = {"data": [fusion_entry("flat end mill", 1, {"DC": 6, "LCF": 15}),
                    fusion_entry("ball end mill", 1, {"DC": 4, "LCF": 8, "RE": 2})]}
    p = tmp_path / "dup.json"
    p.write_text(json.dumps(doc))
    lib = read_tool_library(p)
    assert isinstance(lib[1], FlatEndMill)
    assert any("T1 is the number of 2 tools; data[0] 'flat end mill' is kept as T1, not data[1] 'ball end mill'"
               in w for w in lib.warnings)


def test_library_of_42_tools_numbered_t1_warns_once_and_serves_each_by_name_or_id(tmp_path):
    """Issue 23 item 6: a Fusion library whose 42 tools all say T1 keeps one; the warning says so
    once, naming the others, and every one of them can be picked by name or id."""
    data = [fusion_entry("flat end mill", 1, {"DC": 1 + k / 4, "LCF": 10}, description=f"{1 + k / 4:g} mm flat")
            for k in range(42)]
    for k, entry in enumerate(data):
        entry["guid"] = f"guid-{k:02d}"
    data.append({**fusion_entry("ball end mill", 1, {"DC": 2, "LCF": 6, "RE": 1}, description="unnumbered ball"),
                 "post-process": {"comment": ""}, "guid": "guid-ball"})
    data.append(fusion_entry("ball end mill", 5, {"DC": 3, "LCF": 6, "RE": 1.5}, description="1 mm flat"))
    data.append(fusion_entry("thread mill", 6, {"DC": 3, "LCF": 6}, description="threads"))
    p = tmp_path / "all_t1.tools"
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("tools.json", json.dumps({"data": data}))
    lib = read_tool_library(p)
    assert lib[1].diameter == 1.0 and lib[1].name == "1 mm flat"
    dup = [w for w in lib.warnings if "T1 is the number of" in w]
    assert len(dup) == 1 and "of 42 tools" in dup[0] and "data[1] '1.25 mm flat'" in dup[0] and "36 more" in dup[0]
    assert lib.pick(name="  3.5 MM FLAT ").diameter == 3.5
    assert lib.pick(id="guid-41").diameter == 11.25
    assert isinstance(lib.pick(name="unnumbered ball"), BallEndMill)
    assert any("data[42]: tool 'unnumbered ball' has no post-process number" in w for w in lib.warnings)
    with pytest.raises(ToolDefinitionError, match=r"all_t1\.tools: 2 tools have name '1 mm flat' in the tool "
                                                  r"library: data\[0\] \(id guid-00\), data\[43\] \(id 0{8}-0{4}-0{4}-0{4}-0{11}5\); "
                                                  r"pick one by its id"):
        lib.pick(name="1 mm flat")
    with pytest.raises(ToolDefinitionError, match=r"no tool with id 'guid-99'"):
        lib.pick(id="guid-99")
    with pytest.raises(ToolDefinitionError, match=r"data\[44\]: tool threads \(T6\) is a thread mill"):
        lib.pick(name="threads")


# ---------------------------------------------------------------------------------------------------
# LinuxCNC


@needs_data
def test_linuxcnc_sim_mm_table():
    lib = read_tool_library(TBL / "configs_sim_axis_sim_mm.tbl")
    assert isinstance(lib[1], FlatEndMill) and lib[1].diameter == 3
    assert lib[4].diameter == 16 and lib[24].diameter == 24
    assert 3 not in lib and "not a milling cutter" in str(lib.refused[3])  # ";5mm tap drill"
    assert any("no units" in w for w in lib.warnings)
    assumed = next(w for w in lib.warnings if "shape not stated" in w)
    assert "T6" in assumed and "T1," not in assumed  # ";3mm end mill" states its shape


@needs_data
def test_linuxcnc_gmoccapy_table_shapes_from_comments():
    lib = read_tool_library(TBL / "configs_sim_gmoccapy_tool.tbl")
    mill_drill = lib[9]  # ";90 deg 3/8 mill-drill"
    assert isinstance(mill_drill, ChamferMill) and mill_drill.taper_angle == 45
    assert isinstance(lib[3], FlatEndMill)  # face mill
    assert {7, 8, 15} <= set(lib.refused)  # drill chuck, V tool without angle, spot drill without angle
    assert "without its angle" in str(lib.refused[8])


@needs_data
def test_linuxcnc_lathe_table_has_no_milling_tools():
    lib = read_tool_library(TBL / "configs_sim_qtvcp_screens_qtaxis_lathe_lathe-wear.tbl")
    assert len(lib) == 0
    skipped = next(w for w in lib.warnings if "skipped" in w)
    assert "T1 (lathe)" in skipped and "T10001" in skipped


@needs_data
def test_linuxcnc_inch_table():
    lib = read_tool_library(TBL / "tests_interp_cam-nisley_test.tbl", tbl_units="inch")
    assert lib[1].diameter == pytest.approx(1.5875) and lib[4].diameter == pytest.approx(25.4)
    assert 32 in lib.refused  # D0.0


def test_linuxcnc_inline_shapes_and_errors(tmp_path):
    p = tmp_path / "t.tbl"
    p.write_text("T1 P1 D6 Z10 ;6mm ball nose\nT2 P2 D10 ;10mm bull nose R1.5\nT3 P3 D8 ;8 mm bull, radius unknown\n"
                 "; a comment line\n\nT4 P4 D12 ;60 deg v-bit\n")
    lib = read_tool_library(p)
    assert isinstance(lib[1], BallEndMill) and lib[1].diameter == 6
    assert isinstance(lib[2], BullNoseEndMill) and lib[2].corner_radius == 1.5
    assert isinstance(lib[3], FlatEndMill)
    assert isinstance(lib[4], ChamferMill) and lib[4].taper_angle == 30
    assert any("T3 is named a bull nose" in w for w in lib.warnings)
    bad = tmp_path / "bad.tbl"
    bad.write_text("T1 P1 D6\nT2 P2 K3 D4\n")
    with pytest.raises(InputError, match="unknown tool-table word K") as err:
        read_tool_library(bad)
    assert (err.value.where.line, err.value.where.column) == (2, 7)
    nonum = tmp_path / "nonum.tbl"
    nonum.write_text("P1 D6\n")
    with pytest.raises(InputError, match="without a T word") as err:
        read_tool_library(nonum)
    assert err.value.where.line == 1


# ---------------------------------------------------------------------------------------------------
# CAMotics


@needs_data
@pytest.mark.parametrize(
    "name, tools",
    [
        ("bear", {1: (BallEndMill, 3.175, 25.4)}),
        ("botomata_bottom", {1: (FlatEndMill, 6.35, 38.1), 2: (FlatEndMill, 3.175, 38.1),
                             3: (FlatEndMill, 1.5875, 38.1)}),
        ("cameo", {1: (BallEndMill, 2.0, 10.0)}),
        ("compass", {1: (FlatEndMill, 3.175, 25.4)}),
        ("flower_mold", {1: (FlatEndMill, 1.0, 10.0)}),
        ("wave", {1: (ChamferMill, 12.5, 15.088835), 2: (FlatEndMill, 3.125, 25.4), 3: (BallEndMill, 6.25, 30.125)}),
    ],
)
def test_camotics_projects(name, tools):
    project_file = CAMOTICS / name / f"{name}.camotics"
    raw = json.loads(project_file.read_text())
    project = read_camotics_project(project_file)
    got = {n: (type(t), t.diameter, t.flute_length) for n, t in project.tools.items()}
    assert got.keys() == tools.keys()
    for n, (cls, d, length) in tools.items():
        assert got[n][0] is cls and got[n][1] == pytest.approx(d) and got[n][2] == pytest.approx(length)
    bounds = raw["workpiece"]["bounds"]
    assert isinstance(project.stock, BoxStock)
    assert project.stock.minimum == tuple(bounds["min"]) and project.stock.maximum == tuple(bounds["max"])
    assert project.stock.inferred is raw["workpiece"]["automatic"]
    assert [p.name for p in project.programs] == raw["files"]
    for prog in project.programs:
        assert prog.exists() or any(prog.name in w and "not found" in w for w in project.warnings)


@needs_data
def test_camotics_conical_tool_half_angle():
    # wave's T1: a 45 degree V-bit (CAMotics shows "45deg"): half-angle atan(6.25 / 15.088835)
    tool = read_camotics_project(CAMOTICS / "wave" / "wave.camotics").tools[1]
    assert tool.taper_angle == pytest.approx(22.5, abs=1e-4)
    assert tool.cone_height == pytest.approx(tool.flute_length)


def test_camotics_inline_project(tmp_path):
    doc = {
        "units": "imperial",
        "tools": {
            "1": {"shape": "snubnose", "length": 0.5, "diameter": 0.5, "snub_diameter": 0.1},
            "2": {"units": "metric", "shape": "spheroid", "length": 10, "diameter": 6},
            "3": {"shape": "cylindrical", "length": 1, "diameter": 0.25},
        },
        "workpiece": {"automatic": False, "margin": 5, "bounds": {"min": [0, 0, -10], "max": [50, 40, 0]}},
        "files": ["part.nc"],
    }
    p = tmp_path / "part.camotics"
    p.write_text(json.dumps(doc))
    (tmp_path / "part.nc").write_text("G0 X0\n")
    project = read_camotics_project(p)
    snub = project.tools[1]
    assert isinstance(snub, ChamferMill) and snub.tip_diameter == pytest.approx(2.54)
    assert snub.cone_height == pytest.approx(12.7)
    assert project.tools[3].diameter == pytest.approx(6.35)  # tool without units: the project's (imperial)
    assert 2 not in project.tools and "spheroid" in str(project.tools.refused[2])
    assert project.stock == BoxStock((0, 0, -10), (50, 40, 0))
    assert project.programs == (tmp_path / "part.nc",) and project.units == "imperial"
    assert project.warnings == ()


@pytest.mark.parametrize(
    "doc, message",
    [
        ({"workpiece": {"bounds": {"min": [0, 0, 0], "max": [10, 10, -1]}}}, "workpiece.bounds: box stock needs"),
        ({"tools": {"1": {"shape": "ballnose", "diameter": 3}}}, r"tools\.1\.length: Field required"),
        ({"tools": {"x": {"shape": "ballnose", "diameter": 3, "length": 5}}},
         r"tools\.x: the key is not a tool number"),
        ({"units": "cubits"}, r"units: Input should be"),
    ],
)
def test_camotics_malformed(tmp_path, doc, message):
    p = tmp_path / "bad.camotics"
    p.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=message) as err:
        read_camotics_project(p)
    assert err.value.where.file == str(p)


def test_camotics_xml_is_refused(tmp_path):
    p = tmp_path / "old.camotics"
    p.write_text("<camotics><tool/></camotics>")
    with pytest.raises(InputError, match="XML CAMotics projects"):
        read_camotics_project(p)


# ---------------------------------------------------------------------------------------------------
# fuzzing: mutated libraries and projects give a library or a FusionCutError naming the file

_JUNK = st.one_of(
    st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=False), st.text(max_size=6),
    st.sampled_from(["drill", "ball end mill", "tapered mill", "inches", "conical", "snubnose", "tapered_ball"]),
    st.lists(st.integers(-3, 3), max_size=4),
)
CAM_DOC = {
    "units": "metric",
    "tools": {"1": {"units": "imperial", "shape": "ballnose", "length": 1, "diameter": 0.125},
              "2": {"shape": "snubnose", "length": 10, "diameter": 6, "snub_diameter": 1}},
    "workpiece": {"automatic": False, "margin": 0, "bounds": {"min": [0, 0, -20], "max": [80, 80, 0]}},
    "files": ["bear.nc"],
}


def _mutate(doc, data):
    doc = copy.deepcopy(doc)
    for _ in range(data.draw(st.integers(1, 3))):
        paths, stack = [], [((), doc)]
        while stack:
            prefix, node = stack.pop()
            items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
            for k, v in items:
                paths.append(prefix + (k,))
                stack.append((prefix + (k,), v))
        if not paths:
            break
        target = data.draw(st.sampled_from(paths))
        parent = doc
        for k in target[:-1]:
            parent = parent[k]
        if data.draw(st.booleans()):
            del parent[target[-1]]
        else:
            parent[target[-1]] = data.draw(_JUNK)
    return doc


@pytest.fixture(scope="module")
def fuzz_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("library-fuzz")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_fuzz_mutated_library_and_project(fuzz_dir, data):
    lib_path = fuzz_dir / "lib.json"
    lib_path.write_text(json.dumps(_mutate(LIBRARY, data)))
    cam_path = fuzz_dir / "p.camotics"
    cam_path.write_text(json.dumps(_mutate(CAM_DOC, data)))
    for path, read in ((lib_path, read_tool_library), (cam_path, read_camotics_project)):
        try:
            read(path)
        except FusionCutError as e:
            assert str(path) in str(e)


def test_fusion_reduced_neck_is_modelled(tmp_path):
    """Issue 23 item 7: a 4 mm cutter with a 4 mm neck to 18 mm and a 6 mm shank touches nothing with
    its shank below 18 mm (it got a 6 mm shank from the flute length, 12 mm, before)."""
    lib_doc = {"version": 1, "data": [
        fusion_entry("flat end mill", 1, {"DC": 4, "LCF": 12, "LB": 40, "OAL": 60, "SFDM": 6, "NOF": 3,
                                          "shoulder-length": 18, "shoulder-diameter": 4}),
        fusion_entry("ball end mill", 2, {"DC": 0.125, "RE": 0.0625, "LCF": 0.25, "LB": 1.5, "SFDM": 0.125,
                                          "shoulder-length": 0.875, "shoulder-diameter": 0.115}, unit="inches"),
        fusion_entry("flat end mill", 3, {"DC": 6, "LCF": 15, "LB": 30, "SFDM": 6, "shoulder-length": 15}),
        fusion_entry("flat end mill", 4, {"DC": 3, "LCF": 8, "LB": 20, "SFDM": 3, "shoulder-length": 25,
                                          "shoulder-diameter": 2.8}),
    ]}
    p = tmp_path / "necks.json"
    p.write_text(json.dumps(lib_doc))
    lib = read_tool_library(p)
    neck = lib[1].profile()
    assert neck.radius_at(15.0) == pytest.approx(2.0)  # the neck, not the 6 mm shank
    assert neck.radius_at(18.5) == pytest.approx(3.0)
    assert lib[1].shoulder_length == 18 and lib[1].length == 40
    assert [s.zone for s in neck.segments if min(s.start[1], s.end[1]) >= 12] == ["shank"] * len(
        [s for s in neck.segments if min(s.start[1], s.end[1]) >= 12])
    ball = lib[2]  # inch library: 0.115" neck to 0.875"
    assert ball.neck_diameter == pytest.approx(2.921) and ball.shoulder_length == pytest.approx(22.225)
    assert ball.profile().radius_at(10.0) == pytest.approx(1.4605)
    assert lib[3].shoulder_length is None  # a shoulder at the flute length is no neck
    capped = lib[4]  # shoulder beyond the stick-out: the neck ends with the modelled tool
    assert capped.shoulder_length == 20 and capped.profile().radius_at(19.0) == pytest.approx(1.4)
    assert any("data[3]" in w and "shoulder length 25 mm beyond the overall length 20 mm" in w
               for w in lib.warnings)
    assert lib[1].source == f"{p}: data[0] 'flat end mill'"


def test_fusion_drills_are_pointed_tools(tmp_path):
    lib_doc = {"version": 1, "data": [
        fusion_entry("drill", 1, {"DC": 6.8, "LCF": 60, "LB": 70, "SIG": 118}),
        fusion_entry("drill", 2, {"DC": 0.1875, "LCF": 1.5, "SIG": 135}, unit="inches"),
        fusion_entry("drill", 3, {"DC": 5, "LCF": 40}),
        fusion_entry("drill", 4, {"DC": 5, "LCF": 40, "SIG": 190}),
        fusion_entry("center drill", 5, {"DC": 5, "LCF": 4, "SIG": 60}),
    ]}
    p = tmp_path / "drills.json"
    p.write_text(json.dumps(lib_doc))
    lib = read_tool_library(p)
    d118, d135, default = lib[1], lib[2], lib[3]
    assert isinstance(d118, Drill) and d118.point_angle == 118
    assert d118.profile().segments[0].end == pytest.approx((3.4, 3.4 / math.tan(math.radians(59))))
    assert d135.diameter == pytest.approx(4.7625) and d135.cone_height == pytest.approx(
        4.7625 / 2 / math.tan(math.radians(67.5)))
    assert default.point_angle == 118
    assert any("data[2]" in w and "no point angle; assumed 118 deg" in w for w in lib.warnings)
    with pytest.raises(ToolDefinitionError, match=r"data\[3\]: drill .*point angle must be in \(0, 180\)"):
        lib.require(4)
    with pytest.raises(ToolDefinitionError, match=r"data\[4\]: tool .*\(T5\) is a centre drill"):
        lib.require(5)
