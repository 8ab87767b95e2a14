"""``fusioncut run PROGRAM``: a toolpath file run without a job file, and the engine option flags
generated from EngineOptions."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fusioncut.cli import app
from fusioncut.engines.base import EngineOptions
from fusioncut.io.job import ENGINE_ONLY, Options
from fusioncut.io.results import load_results

runner = CliRunner()
from shared_data import DATA as SHARED
FACE = SHARED / "fusion-posted" / "1072_face_otherside.nc"

PROGRAM = """\
(T1 D=6 CR=0 - ZMIN=-2 - flat end mill)
G21 G90 G17
(Slot and arc)
T1 M6
S10000 M3
G0 X-5 Y5 Z5
G1 Z-2 F300
G1 X10 F600
G3 X20 Y5 I5 J0
G1 X25
G0 Z5
M30
"""


def _tables(out: Path):
    res = load_results(out)
    return res.cl.drop(columns=["time_ms"]), res.slices


def _run(*args: str):
    res = runner.invoke(app, ["run", *map(str, args)])
    assert res.exit_code == 0, res.output
    return res


def test_a_program_runs_without_a_job_and_its_job_json_repeats_it(tmp_path):
    program = tmp_path / "prog.nc"
    program.write_text(PROGRAM)
    first = tmp_path / "first"
    _run(program, "--out", first, "--stock", "box:0,0,-10,30,20,0", "--max-segment-length", "3",
         "--no-ipw-export")
    job = json.loads((first / "job.json").read_text())
    assert job["toolpaths"] == [str(program)]
    assert job["stock"]["kind"] == "box" and job["stock"]["max"] == [30.0, 20.0, 0.0]
    assert job["options"]["max_segment_length"] == 3.0
    again = tmp_path / "again"
    _run(first / "job.json", "--out", again, "--no-ipw-export")
    cl, slices = _tables(first)
    cl2, slices2 = _tables(again)
    assert len(cl) > 5 and (cl["status"] == "engaged").sum() > 3
    assert cl.equals(cl2) and slices.equals(slices2)
    assert load_results(first).metadata["job_hash"] == load_results(again).metadata["job_hash"]


def test_the_flags_override_a_job_file(tmp_path):
    program = tmp_path / "prog.nc"
    program.write_text(PROGRAM)
    _run(program, "--out", tmp_path / "a", "--stock", "box:0,0,-10,30,20,0", "--no-ipw-export")
    out = tmp_path / "b"
    _run(tmp_path / "a" / "job.json", "--out", out, "--slice-height", "0.5", "--cell-size", "none",
         "--no-ipw-export")
    slices = load_results(out).slices
    # 2 mm deep in 0.5 mm slices (the analytic engine finds the contact's top to 1e-10 mm)
    assert sorted(set(slices["z_tool_mm"].round(9))) == [0.25, 0.75, 1.25, 1.75]
    assert not (out / "job.json").exists()  # a job file is not written again


@pytest.mark.parametrize("args, message", [
    (["--slice-height", "-1"], "--slice-height"),
    (["--slice-height", "none"], "--slice-height"),  # not an option that takes none
    (["--sweep", "step"], "--sweep"),
    (["--stock", "box:1,2"], "box needs"),
    (["--stock", "box:0,0,-10,30,20,0", "--stock-top", "1"], "--stock-top"),
    (["--tools", "missing.tbl"], "tool library not found"),
])
def test_bad_values_are_refused_in_one_line_naming_them(tmp_path, args, message):
    program = tmp_path / "prog.nc"
    program.write_text(PROGRAM)
    res = runner.invoke(app, ["run", str(program), "--out", str(tmp_path / "out"), *args])
    assert res.exit_code == 2, res.output
    assert message in res.output.replace("\n", "") and "Traceback" not in res.output


def test_one_flag_per_job_engine_option_with_the_engines_default_and_help():
    import typer.main

    command = typer.main.get_command(app).commands["run"]
    flags = {opt: p for p in command.params for opt in p.opts}
    job_fields = [f for f in dataclasses.fields(EngineOptions) if f.name not in ENGINE_ONLY]
    assert {f.name for f in job_fields} <= set(Options.model_fields)
    for f in job_fields:
        param = flags["--" + f.name.replace("_", "-")]
        default = getattr(f.default, "value", f.default)
        assert param.help == f"{f.metadata['help']} (default: {'none' if default is None else default})"
        assert Options.model_fields[f.name].default == default


@pytest.mark.skipif(not FACE.is_file(), reason=f"shared test data not found at {SHARED}")
def test_a_posted_facing_program_runs_with_its_stock_top(tmp_path):
    out = tmp_path / "face"
    res = _run(FACE, "--out", out, "--stock-top", "1", "--no-ipw-export")
    assert "relative error" in res.output
    cl = load_results(out).cl
    assert (cl["status"] == "failed").sum() == 0 and (cl["status"] == "engaged").sum() >= 30
    assert abs(cl["ap_mm"].max() - 1.0) < 1e-9  # the face pass takes the 1 mm above z = 0
    assert json.loads((out / "job.json").read_text())["stock"]["top"] == 1.0


def test_a_missing_extra_is_named_with_its_install_line(tmp_path, monkeypatch):
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "distributed" else
                        find_spec(name, *a))
    program = tmp_path / "prog.nc"
    program.write_text(PROGRAM)
    res = runner.invoke(app, ["run", str(program), "--out", str(tmp_path / "out"), "--workers", "2"])
    assert res.exit_code == 2, res.output
    text = " ".join(res.output.split())
    assert "[parallel] extra (distributed not installed): pip install 'fusioncut[parallel]'" in text
    assert not (tmp_path / "out").exists()  # refused before anything is written
