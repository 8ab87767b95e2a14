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


# --------------------------------------------------------------------------------------------------
# fusioncut run: logs, IPW export, resume and --fresh

PROGRAM = """\
G21 G90 G17
(Slot)
T1 M6
S10000 M3
G0 X-5 Y5 Z5
G1 Z-2 F300
G1 X12 F600
G1 Y9
G0 Z5
M30
"""


def small_job_file(tmp_path, program: str = PROGRAM):
    (tmp_path / "prog.nc").write_text(program)
    job = {"name": "small", "stock": {"kind": "box", "min": [0, 0, -10], "max": [30, 20, 0]},
           "tools": [{"number": 1, "kind": "flat", "diameter": 6, "flute_length": 15}],
           "toolpaths": ["prog.nc"], "options": {"max_segment_length": 3.0, "checkpoint_every": 3}}
    path = tmp_path / "job.json"
    path.write_text(json.dumps(job))
    return path


def test_run_writes_a_per_cl_debug_log_and_no_ipw_when_asked(tmp_path):
    job = small_job_file(tmp_path)
    out, log = tmp_path / "out", tmp_path / "logs" / "run.log"
    res = runner.invoke(app, ["run", str(job), "--out", str(out), "--log-file", str(log), "--log-level", "DEBUG",
                              "--no-ipw-export"])
    assert res.exit_code == 0, res.output
    cl = load_results(out).cl
    text = log.read_text()
    for _, row in cl.iterrows():
        assert f"CL {row['cl']} {row['file']}:{row['line']} {row['status']} sweep_method=" in text
    assert "boolean=" in text and "slicing=" in text
    assert not (out / "ipw.step").exists() and not (out / "ipw.stl").exists()
    assert not (out / "fusioncut.log").exists()  # the log went where it was told


def test_run_exports_the_ipw_and_info_log_has_no_cl_lines(tmp_path):
    job = small_job_file(tmp_path)
    out = tmp_path / "out"
    res = runner.invoke(app, ["run", str(job), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert (out / "ipw.step").stat().st_size > 0 and (out / "ipw.stl").stat().st_size > 84
    assert "CL 0 " not in (out / "fusioncut.log").read_text()


def test_run_resumes_unless_fresh(tmp_path):
    from fusioncut.io.job import load_job
    from fusioncut.runner import run_job

    job_file = small_job_file(tmp_path)
    out = tmp_path / "out"
    job, base = load_job(job_file)

    def stop(m, total):
        if m.cl_index == 4:
            raise KeyboardInterrupt

    assert run_job(job, base, out, on_cl=stop, export_ipw=False).interrupted
    log = tmp_path / "resume.log"
    res = runner.invoke(app, ["run", str(job_file), "--out", str(out), "--log-file", str(log),
                              "--log-level", "debug", "--no-ipw-export"])
    assert res.exit_code == 0, res.output
    text = log.read_text()
    assert "resuming from the checkpoint" in text and "at CL 5 of" in text
    assert "CL 4 " not in text and "CL 5 " in text
    n = len(load_results(out).cl)
    assert list(load_results(out).cl["cl"]) == list(range(n))

    fresh_log = tmp_path / "fresh.log"
    res = runner.invoke(app, ["run", str(job_file), "--out", str(out), "--fresh", "--log-file", str(fresh_log),
                              "--log-level", "debug", "--no-ipw-export"])
    assert res.exit_code == 0, res.output
    text = fresh_log.read_text()
    assert "resuming" not in text and "CL 0 " in text


def test_run_with_bad_program_fails_cleanly_and_writes_no_results(tmp_path):
    job = small_job_file(tmp_path, PROGRAM.replace("T1 M6", "T4 M6"))
    out = tmp_path / "out"
    res = runner.invoke(app, ["run", str(job), "--out", str(out)])
    assert res.exit_code == 2
    assert "prog.nc:5" in res.output.replace("\n", "") and "T4" in res.output
    assert "Traceback" not in res.output
    assert not (out / "cl.csv").exists() and not (out / "cl.parquet").exists()


def test_run_rejects_an_unknown_log_level(tmp_path):
    res = runner.invoke(app, ["run", str(small_job_file(tmp_path)), "--log-level", "chatty"])
    assert res.exit_code == 2 and "chatty" in res.output
