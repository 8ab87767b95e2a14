"""``fusioncut view`` and ``fusioncut export-ipw`` end to end, on a small job file and on the demo."""
from __future__ import annotations

import json

import pytest
import trimesh
from typer.testing import CliRunner

from fusioncut.cli import app
from fusioncut.cli.view import load_inputs
from fusioncut.engines.brep.export import replay
from fusioncut.engines.brep.occ import volume
from fusioncut.engines.brep.stock import stock_solid
from fusioncut.engines.segments import segments_for
from fusioncut.model.stock import SolidStock
from fusioncut.viz.scene import glb_json

runner = CliRunner()


GCODE = """(small job: a side pass, then a slot that stops inside the block)
G21 G90 G17
T1 M6
S8000 M3
G0 X-5 Y5 Z5
G1 Z-2 F300
G1 X12 F600
G0 Z5
G0 X-5 Y12
G1 Z-3 F300
G1 X20 F600
G0 Z5
M30
"""


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    d = tmp_path_factory.mktemp("job")
    (d / "part.nc").write_text(GCODE)
    (d / "job.json").write_text(json.dumps({
        "name": "small",
        "stock": {"kind": "box", "min": [0, 0, -10], "max": [30, 20, 0]},
        "tools": [{"number": 1, "kind": "flat", "diameter": 6, "flute_length": 15}],
        "toolpaths": ["part.nc"],
        "options": {"slice_height": 0.5},
    }))
    return d / "job.json"


@pytest.fixture(scope="module")
def slot_end(job) -> int:
    """CL index of the end of the slot (the tool at X20 Y12 Z-3)."""
    toolpath, _, options, _, _ = load_inputs(str(job))
    ends = [m.end for m in segments_for(toolpath.moves, options)]
    return ends.index((20.0, 12.0, -3.0))


def _ok(args):
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    return res.output.replace("\n", "")


def test_view_writes_page_and_glb(job, slot_end, tmp_path, frontend_packages):
    html, glb = tmp_path / "scene.html", tmp_path / "scene.glb"
    res = _ok(["view", str(job), "--cl", str(slot_end), "--out", str(html), "--glb", str(glb)])
    assert f"CL {slot_end} of" in res and "engaged" in res
    tree = glb_json(glb.read_bytes())
    names = {n["name"] for n in tree["nodes"]}
    assert {"ipw", "tool", "contact_faces", "entry_lines", "exit_lines", "engaged_arcs"} <= names
    extras = tree["scenes"][0]["extras"]["fusioncut"]
    assert extras["cl_index"] == slot_end and extras["position_mm"] == [20.0, 12.0, -3.0]
    assert "part.nc:11:" in extras["source"]  # the slot's G1 X20 line
    page = html.read_text(encoding="utf-8")
    assert '<script type="importmap">' in page and "part.nc:11" in page
    # the scene of the page is the GLB written next to it
    scene = trimesh.load(glb)
    assert set(scene.graph.nodes_geometry) >= {"ipw", "tool", "contact_faces"}


def test_view_demo(tmp_path, frontend_packages):
    html = tmp_path / "demo.html"
    res = _ok(["view", "demo", "--cl", "30", "--out", str(html)])  # the first face pass, in the block
    assert "CL 30 of" in res and "engaged" in res
    assert html.stat().st_size > 100_000  # three.js and the scene are inside


@pytest.mark.parametrize("suffix", [".step", ".stl"])
def test_export_ipw(job, slot_end, tmp_path, suffix):
    out = tmp_path / f"ipw{suffix}"
    res = _ok(["export-ipw", str(job), "--cl", str(slot_end), "--out", str(out), "--deflection", "0.01"])
    assert f"the workpiece after CL {slot_end}" in res
    toolpath, stock, options, tool, _ = load_inputs(str(job))
    expected = replay(toolpath, stock, slot_end, options, tool).engine.ipw_volume
    if suffix == ".step":
        assert volume(stock_solid(SolidStock(out))) == pytest.approx(expected, rel=1e-6)
    else:
        mesh = trimesh.load(out)
        assert mesh.is_watertight
        assert mesh.volume == pytest.approx(expected, rel=0.01)
        assert mesh.volume != pytest.approx(30 * 20 * 10, rel=0.01)  # material was removed


def test_export_ipw_of_the_analytic_height_map(job, slot_end, tmp_path):
    """--engine analytic: the sweeps up to the CL, meshed through their exact heights (no replay).
    The side pass and the slot (2 and 3 mm deep, 3 walls each, 12 and 20 mm long) slope over one
    grid step of 0.25 mm: the mesh holds the B-Rep workpiece's volume to half a step times their area."""
    out = tmp_path / "ipw.stl"
    res = _ok(["export-ipw", str(job), "--cl", str(slot_end), "--out", str(out), "--engine", "analytic",
               "--grid", "0.25"])
    assert f"the workpiece after CL {slot_end}" in res and "height map" in res
    toolpath, stock, options, tool, _ = load_inputs(str(job))
    expected = replay(toolpath, stock, slot_end, options, tool).engine.ipw_volume
    mesh = trimesh.load(out)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert abs(mesh.volume - expected) < 0.5 * 0.25 * (2 * (2 * 12 + 6) + 3 * (2 * 20 + 6))


@pytest.mark.parametrize("args, message", [
    (["view", "{job}", "--cl", "999", "--out", "{tmp}/x.html"], "CL 999 is out of range"),
    (["view", "{job}", "--cl", "1", "--out", "{tmp}/x.png"], "written as .html"),
    (["view", "{job}", "--cl", "1", "--out", "{tmp}/x.html", "--glb", "{tmp}/x.gltf"], "written as .glb"),
    (["view", "{tmp}/nope.json", "--cl", "1", "--out", "{tmp}/x.html"], "job file not found"),
    (["export-ipw", "{job}", "--cl", "1", "--out", "{tmp}/x.obj"], "unsupported workpiece format"),
    (["export-ipw", "{job}", "--cl", "1", "--out", "{tmp}/no/x.step"], "output folder does not exist"),
    (["export-ipw", "{job}", "--cl", "1", "--out", "{tmp}/x.step", "--engine", "analytic"], "with --engine analytic, .stl"),
    (["export-ipw", "{job}", "--cl", "1", "--out", "{tmp}/x.stl", "--engine", "nope"], "use brep or analytic"),
])
def test_errors_are_one_clear_line(job, tmp_path, args, message):
    res = runner.invoke(app, [a.format(job=job, tmp=tmp_path) for a in args])
    assert res.exit_code == 2, res.output
    assert message in res.output.replace("\n", "")
    assert "Traceback" not in res.output


def test_view_without_three_js(job, tmp_path, monkeypatch):
    monkeypatch.setenv("FUSIONCUT_THREE_DIR", str(tmp_path))
    res = runner.invoke(app, ["view", str(job), "--cl", "1", "--out", str(tmp_path / "x.html")])
    assert res.exit_code == 2
    assert "three.js not found" in res.output.replace("\n", "")
    assert not (tmp_path / "x.html").exists()
