"""The command line end to end: the demo, and clear errors for bad job files."""
from __future__ import annotations

import json

from typer.testing import CliRunner

from fusioncut.cli import app
from fusioncut.io.results import load_results

runner = CliRunner()


def test_demo_runs_every_cl_and_conserves_volume(tmp_path):
    out = tmp_path / "demo"
    res = runner.invoke(app, ["demo", "--out", str(out)])
    assert res.exit_code == 0, res.output
    results = load_results(out)
    cl = results.cl
    assert list(cl["cl"]) == list(range(len(cl)))  # no CL lost, in order
    assert set(cl["operation"]) == {"Face", "Slot", "Trochoidal", "Contour", "Ball finish"}
    assert (cl["status"] == "failed").sum() == 0
    slot = cl[(cl["operation"] == "Slot") & (cl["status"] == "engaged")]
    full = slot[(slot["ae_mm"] > 9.999)]
    assert len(full) > 10
    assert (full["entry_min_deg"].abs() < 0.005).all() and ((full["exit_max_deg"] - 180).abs() < 0.005).all()
    # Σ removed equals stock minus final, both printed by the summary
    assert "relative error" in res.output
    err = float(res.output.split("relative error")[1].split(")")[0])
    assert err < 1e-6


def test_bad_job_json_names_the_file_and_line(tmp_path):
    bad = tmp_path / "job.json"
    bad.write_text('{"name": "x",\n "stock": {"kind": "box"\n')
    res = runner.invoke(app, ["run", str(bad)])
    assert res.exit_code == 2
    assert "job.json:3" in res.output.replace("\n", "")


def test_invalid_job_names_the_field(tmp_path):
    bad = tmp_path / "job.json"
    bad.write_text(json.dumps({"stock": {"kind": "box", "min": [0, 0, 0]}, "toolpaths": ["a.nc"]}))
    res = runner.invoke(app, ["run", str(bad)])
    assert res.exit_code == 2
    assert "stock" in res.output and "max" in res.output


def test_schema_is_json():
    res = runner.invoke(app, ["schema"])
    assert res.exit_code == 0
    assert "toolpaths" in json.loads(res.output)["properties"]
