"""Service parts without a server: job store and migrations, file names, settings and keys, the demo
as G-code, the worker's progress and cancel handling."""
from __future__ import annotations

import json
import sqlite3
from types import SimpleNamespace

import pytest

from fusioncut.errors import InputError
from fusioncut.service import store as store_mod
from fusioncut.service.files import check_name, find_result_file, result_files
from fusioncut.service.settings import Settings, key_hash, load_keys
from fusioncut.service.store import JobStore
from fusioncut.service.worker import JobCancelled, ProgressReporter, read_progress


# -- job store -----------------------------------------------------------------------------------

def test_store_keeps_jobs_across_connections(tmp_path):
    db = tmp_path / "jobs.sqlite"
    s = JobStore(db)
    s.add("a1", key_hash("k1"), "first", "jobs/a1", 10)
    s.add("b2", key_hash("k2"), "second", "jobs/b2", 20)
    s.update("a1", state="running", started_at=5.0)
    s.close()
    s = JobStore(db)
    assert s.version == len(store_mod.MIGRATIONS)
    a = s.get("a1")
    assert (a.state, a.started_at, a.total_cls, a.owner) == ("running", 5.0, 10, key_hash("k1"))
    assert [r.id for r in s.list(owner=key_hash("k2"))] == ["b2"]
    assert s.get("a1", owner=key_hash("k2")) is None  # another owner's job does not exist for it
    assert [r.id for r in s.list(states=("running",))] == ["a1"]
    s.update("a1", deleted_at=1.0)
    assert s.get("a1", owner=key_hash("k1")) is None and s.list(owner=key_hash("k1")) == []
    with pytest.raises(ValueError):
        s.update("a1", state="exploded")
    with pytest.raises(sqlite3.IntegrityError):  # the schema itself refuses unknown states
        s._db.execute("UPDATE jobs SET state = 'exploded' WHERE id = 'b2'")


def test_store_migrates_forward_and_refuses_newer_schemas(tmp_path, monkeypatch):
    db = tmp_path / "jobs.sqlite"
    s = JobStore(db)
    s.add("a1", "owner", "old job", "jobs/a1", 3)
    s.close()

    def v2(conn):
        conn.execute("ALTER TABLE jobs ADD COLUMN priority INTEGER NOT NULL DEFAULT 0")

    monkeypatch.setattr(store_mod, "MIGRATIONS", [*store_mod.MIGRATIONS, v2])
    s = JobStore(db)
    assert s.version == 2
    assert s.get("a1").name == "old job"  # data kept
    assert s._db.execute("SELECT priority FROM jobs WHERE id='a1'").fetchone() == (0,)
    s.close()
    monkeypatch.setattr(store_mod, "MIGRATIONS", store_mod.MIGRATIONS[:1])
    with pytest.raises(InputError, match="newer"):
        JobStore(db)


def test_a_failing_migration_leaves_the_database_as_it_was(tmp_path, monkeypatch):
    db = tmp_path / "jobs.sqlite"
    JobStore(db).close()

    def broken(conn):
        conn.execute("ALTER TABLE jobs ADD COLUMN x INTEGER")
        raise RuntimeError("half way")

    monkeypatch.setattr(store_mod, "MIGRATIONS", [*store_mod.MIGRATIONS, broken])
    with pytest.raises(RuntimeError):
        JobStore(db)
    conn = sqlite3.connect(db)
    assert conn.execute("SELECT version FROM schema_version").fetchone() == (1,)
    assert "x" not in [r[1] for r in conn.execute("PRAGMA table_info(jobs)")]


# -- file names ----------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["part.nc", "Job 1 (rough).ngc", "T1-lib.tools", "a+b.apt"])
def test_plain_names_pass(name):
    assert check_name(name) == name


@pytest.mark.parametrize("name", ["", "..", "../x.nc", "a/b.nc", "a\\b.nc", ".hidden", "/etc/passwd",
                                  "nul\x00.nc", " lead.nc", "a" * 256, "C:\\x.nc"])
def test_unsafe_names_are_refused(name):
    with pytest.raises(InputError):
        check_name(name)


def test_downloads_are_looked_up_in_the_listing(tmp_path):
    (tmp_path / "cl.csv").write_text("x")
    (tmp_path / "notes.exe").write_text("x")  # not a result type
    (tmp_path / "checkpoint").mkdir()
    (tmp_path / ".cl.csv.tmp").write_text("x")
    (tmp_path / "link.csv").symlink_to(tmp_path / "cl.csv")
    assert [f.name for f in result_files(tmp_path)] == ["cl.csv"]
    assert find_result_file(tmp_path, "cl.csv").media_type == "text/csv"
    assert find_result_file(tmp_path, "notes.exe") is None and find_result_file(tmp_path, "link.csv") is None
    with pytest.raises(InputError):
        find_result_file(tmp_path, "../cl.csv")


# -- settings and keys ---------------------------------------------------------------------------

def test_settings_from_config_env_and_options(tmp_path):
    cfg = tmp_path / "fc.json"
    cfg.write_text(json.dumps({"scheduler": "tcp://cfg:8786", "max_cls": 10, "data_dir": "d"}))
    s = Settings.from_env({"FUSIONCUT_CONFIG": str(cfg), "FUSIONCUT_MAX_CLS": "20", "FUSIONCUT_MAX_UPLOAD_MB": "2"},
                          workers=3)
    assert (s.scheduler, s.max_cls, s.max_upload_bytes, s.workers) == ("tcp://cfg:8786", 20, 2 * 1024 * 1024, 3)
    assert s.data_dir == tmp_path / "d"  # relative to the config file
    cfg.write_text(json.dumps({"shceduler": "x"}))
    with pytest.raises(InputError, match="unknown setting 'shceduler'"):
        Settings.from_env({"FUSIONCUT_CONFIG": str(cfg)})
    with pytest.raises(InputError, match="FUSIONCUT_MAX_CLS"):
        Settings.from_env({"FUSIONCUT_MAX_CLS": "lots"})


def test_keys_from_env_and_file_and_a_generated_one(tmp_path):
    keyfile = tmp_path / "keys"
    keyfile.write_text("# team keys\nfile-key-0123456789abcdef  # alice\n\n")
    hashes, created = load_keys(Settings(data_dir=tmp_path / "d", api_keys=("env-key-0123456789abcdef",),
                                         api_keys_file=keyfile))
    assert hashes == {key_hash("env-key-0123456789abcdef"), key_hash("file-key-0123456789abcdef")}
    assert created is None
    hashes, created = load_keys(Settings(data_dir=tmp_path / "d"))
    assert created is not None and (created.stat().st_mode & 0o777) == 0o600
    key = [line for line in created.read_text().splitlines() if not line.startswith("#")][0]
    assert hashes == {key_hash(key)}
    assert load_keys(Settings(data_dir=tmp_path / "d"))[0] == hashes  # the same key after a restart
    with pytest.raises(InputError, match="shorter"):
        load_keys(Settings(data_dir=tmp_path, api_keys=("short",)))


# -- the demo as a job ---------------------------------------------------------------------------

def test_demo_gcode_reads_back_as_the_demo_toolpath():
    from fusioncut.demo import demo_toolpath
    from fusioncut.io.gcode import parse_gcode_text
    from fusioncut.io.job import Job
    from fusioncut.demo import demo_gcode, demo_job

    job = Job.model_validate(demo_job())
    tp = parse_gcode_text(demo_gcode(), tools={t.number: t.build() for t in job.tools})
    demo = demo_toolpath()
    first, moves = tp.moves[0], tp.moves[1:]  # a program starts at the origin: one rapid to the start
    assert first.rapid and first.end == demo.moves[0].start
    assert len(moves) == len(demo.moves)
    for got, want in zip(moves, demo.moves):
        assert type(got) is type(want)
        assert got.start == pytest.approx(want.start, abs=1e-9) and got.end == pytest.approx(want.end, abs=1e-9)
        assert (got.feed, got.tool, got.operation) == (want.feed, want.tool, want.operation)
        if hasattr(want, "center"):
            assert got.center[:2] == pytest.approx(want.center[:2]) and got.clockwise == want.clockwise
    assert {n: t.build() for n, t in ((t.number, t) for t in job.tools)} == demo.tools


# -- worker progress and cancel --------------------------------------------------------------------

def test_progress_is_throttled_resumable_and_cancel_stops(tmp_path):
    rep = ProgressReporter(tmp_path, attempt=2, interval_s=3600)
    rep.on_start(SimpleNamespace(total=10, start_at=4))  # a resumed run: 4 CLs were done before
    p = read_progress(tmp_path)
    assert (p["state"], p["done"], p["total"], p["attempt"]) == ("running", 4, 10, 2)
    for k in range(4, 7):
        rep(SimpleNamespace(cl_index=k, operation="Slot"), 10)
    assert read_progress(tmp_path)["done"] == 4  # throttled: nothing written within the interval
    rep.write("running")
    p = read_progress(tmp_path)
    assert p["done"] == 7 and p["operation"] == "Slot" and p["eta_s"] > 0
    (tmp_path / "cancel").touch()
    with pytest.raises(KeyboardInterrupt):  # the runner's Ctrl-C path: finished CLs are kept
        rep(SimpleNamespace(cl_index=7, operation="Slot"), 10)
    assert issubclass(JobCancelled, KeyboardInterrupt)
    assert not list(tmp_path.glob(".*tmp"))  # atomic writes leave no temporaries


def test_the_cli_demo_runs_the_service_demo_job(tmp_path, monkeypatch):
    """`fusioncut demo` and the service's demo are one job (they once made 753 and 768 CLs)."""
    import fusioncut.runner
    from typer.testing import CliRunner

    from fusioncut.cli import app
    from fusioncut.demo import demo_gcode, demo_job
    from fusioncut.io.job import Job

    ran = {}

    class Ran(Exception):
        pass

    def fake_run_job(job, base, out, **kw):
        ran.update(job=job, base=base, gcode=(base / job.toolpaths[0]).read_text())
        raise Ran()

    monkeypatch.setattr(fusioncut.runner, "run_job", fake_run_job)
    res = CliRunner().invoke(app, ["demo", "--out", str(tmp_path / "demo")])
    assert isinstance(res.exception, Ran), res.output
    assert ran["job"] == Job.model_validate(demo_job()) and ran["gcode"] == demo_gcode()


def test_a_resumed_job_reports_the_time_of_every_attempt(tmp_path):
    """"N CLs in T s" counts the seconds of the earlier attempts (progress.json's spent_s) too."""
    from service_helpers import TINY_GCODE, TINY_JOB

    from fusioncut.io.job import Job
    from fusioncut.service.files import JOB_FILE
    from fusioncut.service.worker import execute_job

    (tmp_path / "input").mkdir()
    (tmp_path / "input" / "tiny.nc").write_text(TINY_GCODE)
    (tmp_path / "input" / JOB_FILE).write_text(Job.model_validate(TINY_JOB).model_dump_json())
    (tmp_path / "progress.json").write_text(json.dumps({"state": "suspended", "attempt": 1, "spent_s": 1000.0}))
    out = execute_job(str(tmp_path), attempt=2, progress_interval_s=3600)
    assert out["state"] == "done", out
    seconds = float(out["message"].split(" CLs in ")[1].split(" s")[0])
    assert 1000 < seconds < 1300 and "2 attempts" in out["message"]
    assert read_progress(tmp_path)["spent_s"] == pytest.approx(seconds, abs=0.1)


def test_view_demo_numbers_the_demo_jobs_cls():
    """`fusioncut view demo --cl N` shows CL N of the demo job that `fusioncut demo` and the service run."""
    from fusioncut.cli.view import load_inputs
    from fusioncut.demo import demo_gcode
    from fusioncut.engines.segments import segments_for
    from fusioncut.io.gcode import parse_gcode_text

    toolpath, _, options, _, _ = load_inputs("demo")
    job_moves = parse_gcode_text(demo_gcode(), source="demo.ngc").moves
    assert [m.end for m in segments_for(toolpath.moves, options)] == \
        [m.end for m in segments_for(job_moves, options)]
    assert len(segments_for(toolpath.moves, options)) == 768


# -- the upload form's option fields ---------------------------------------------------------------

def test_the_forms_option_fields_are_the_jobs_engine_options():
    from fusioncut.io.job import Options, engine_option_fields
    from fusioncut.service.submit import MULTIPART_SCHEMA, OPTION_FIELDS

    names = [f.name for f in engine_option_fields()]
    assert list(OPTION_FIELDS) == names and set(names) <= set(Options.model_fields)
    for f in engine_option_fields():
        field = MULTIPART_SCHEMA["properties"][f.name]
        assert field["description"] == f.description and f.help in field["description"]
    assert MULTIPART_SCHEMA["properties"]["sweep"]["enum"] == ["exact", "sampled"]


def test_form_options_are_converted_and_validated_like_a_job_file():
    from fusioncut.service.submit import SubmissionError, build_job_from_form

    uploads = {"toolpath": ["a.nc"]}
    job = build_job_from_form(None, uploads, {"slice_height": "0.5", "cell_size": "none", "sweep": "sampled",
                                              "min_chip_thickness": ""})
    assert (job.options.slice_height, job.options.cell_size, job.options.sweep) == (0.5, None, "sampled")
    assert job.options.min_chip_thickness == 1e-3  # left empty: the default
    with pytest.raises(SubmissionError, match="ramp_step: 'fine' is not a number"):
        build_job_from_form(None, uploads, {"ramp_step": "fine"})
    with pytest.raises(SubmissionError, match="job.options.slice_height"):
        build_job_from_form(None, uploads, {"slice_height": "-1"})
    with pytest.raises(SubmissionError, match="slice_height: 'none' is not a number"):
        build_job_from_form(None, uploads, {"slice_height": "none"})  # only options whose None means something
