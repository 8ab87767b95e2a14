"""Parallel runs (``workers`` / ``scheduler``): the single-process rows, checkpoints that resume in
either engine, the CLI flags, and service jobs that stay single-process inside their Dask worker.

One Dask cluster serves most tests through its scheduler address (starting one costs seconds of a
2-core budget); the CLI test starts the embedded one that ``--workers`` gives.
"""
from __future__ import annotations

import json
import logging
import socket
from pathlib import Path

import numpy as np
import pytest
from test_cli import runner
from test_cli import small_job_file as _small_job_file
from test_runner import PROGRAM, result_files, stop_after
from test_runner import small_job as _small_job

from fusioncut.cli import app
from fusioncut.errors import InputError
from fusioncut.io.job import RUN_OPTIONS, Options, job_hash, load_job, with_run_options
from fusioncut.io.results import load_results
from fusioncut.runner import PARALLEL_CELL_SIZE, RunResult, run_job

distributed = pytest.importorskip("distributed")

# the bounds of tests/engines/brep/test_cells_and_parallel.py: cells against the whole workpiece
ANGLE_TOL = 1e-3  # degrees
VOLUME_REL = 1e-6
ANGLES = ["entry_min_deg", "entry_max_deg", "exit_min_deg", "exit_max_deg"]


def assert_same_rows(got: Path, ref: Path) -> None:
    """The CL and slice tables of two runs agree row by row (status exactly, numbers to the bounds)."""
    a, b = load_results(got), load_results(ref)
    assert list(a.cl["cl"]) == list(b.cl["cl"])
    assert list(a.cl["status"]) == list(b.cl["status"])
    np.testing.assert_allclose(a.cl["removed_volume_mm3"], b.cl["removed_volume_mm3"], rtol=VOLUME_REL, atol=1e-9)
    np.testing.assert_allclose(a.cl["contact_area_mm2"], b.cl["contact_area_mm2"], rtol=VOLUME_REL, atol=1e-9)
    for col in ANGLES:
        np.testing.assert_allclose(a.cl[col], b.cl[col], atol=ANGLE_TOL, rtol=0, err_msg=col)  # NaN == NaN
    keys = ["cl", "z_tool_mm", "interval"]
    assert a.slices[keys].shape == b.slices[keys].shape
    np.testing.assert_allclose(a.slices[keys], b.slices[keys], atol=1e-9, rtol=0)
    for col in ("entry_deg", "exit_deg"):
        np.testing.assert_allclose(a.slices[col], b.slices[col], atol=ANGLE_TOL, rtol=0, err_msg=col)


def small_job(tmp_path: Path, **options):
    """The small job with the workpiece kept whole: the reference the cells of a parallel run meet."""
    return _small_job(tmp_path, **{"cell_size": None, **options})


def small_job_file(tmp_path: Path, **kwargs) -> Path:
    path = _small_job_file(tmp_path, **kwargs)
    doc = json.loads(path.read_text())
    doc["options"]["cell_size"] = None
    doc["options"].setdefault("engine", "brep")  # the parallel B-Rep engine's cells are what these tests are about
    path.write_text(json.dumps(doc))
    return path


def run_state(out: Path) -> dict:
    return json.loads((out / "checkpoint" / "run.json").read_text())


@pytest.fixture(scope="module")
def scheduler():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  silence_logs=logging.ERROR) as cluster:
        yield cluster.scheduler_address


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """The single-process run of the small job (whole workpiece, no cells)."""
    tmp = tmp_path_factory.mktemp("reference")
    job, base = small_job(tmp)
    r = run_job(job, base, tmp / "out", export_ipw=False)
    assert not r.interrupted and run_state(tmp / "out")["cell_size"] is None
    cl = load_results(tmp / "out").cl
    # the program crosses the wall of the 20 mm cells (x = 20) engaged: a line and the XY arc
    assert len(cl) == 41 and (cl["status"] == "engaged").sum() > 20
    assert ((cl["x"] - 3 < 20) & (cl["x"] + 3 > 20) & (cl["status"] == "engaged")).sum() >= 3
    return tmp / "out"


# --------------------------------------------------------------------------------------------------
# results, snapshots and exports


def test_parallel_run_equals_the_single_process_run(tmp_path, scheduler, reference, caplog):
    job, base = small_job(tmp_path, scheduler=scheduler, snapshot_cls=[8], checkpoint_every=4)
    out = tmp_path / "out"
    with caplog.at_level(logging.INFO, logger="fusioncut"):
        r = run_job(job, base, out)
    assert not r.interrupted
    assert_same_rows(out, reference)
    assert any("20 mm cells" in rec.getMessage() for rec in caplog.records)
    assert run_state(out)["cell_size"] == PARALLEL_CELL_SIZE
    state = json.loads((out / "checkpoint" / "state.json").read_text())
    assert state["next_cl"] == 41 and len(state["faces_at_merge"]) == 2  # 30 x 20 mm stock: two cells
    assert r.conservation_error < 1e-6
    cl = load_results(out).cl
    assert r.removed_volume == pytest.approx(cl["removed_volume_mm3"].sum(), rel=1e-12)

    # the workpiece comes back from the workers for the snapshot (after CL 8, mid-batch) and the end
    from fusioncut.engines.brep.occ import volume
    from fusioncut.engines.brep.stock import stock_solid
    from fusioncut.model import SolidStock

    assert {p.name for p in r.exported} == {"ipw.step", "ipw.stl", "ipw_cl000008.step"}
    assert volume(stock_solid(SolidStock(out / "ipw.step"))) == pytest.approx(r.final_volume, rel=1e-6)
    snap = volume(stock_solid(SolidStock(out / "ipw_cl000008.step")))
    assert snap == pytest.approx(r.stock_volume - cl.query("cl <= 8")["removed_volume_mm3"].sum(), rel=1e-6)


# --------------------------------------------------------------------------------------------------
# checkpoints across engines


def test_parallel_checkpoint_resumes_single_process(tmp_path, scheduler, reference, caplog):
    """Checkpoints fall inside the workers' batch (every 4 CLs, interrupted after 7): the workers
    hand over the workpiece as it was at that CL, not as far as they had cut."""
    job, base = small_job(tmp_path, scheduler=scheduler, checkpoint_every=4)
    out = tmp_path / "out"
    r1 = run_job(job, base, out, on_cl=stop_after(7), export_ipw=False)
    assert r1.interrupted
    assert json.loads((out / "checkpoint" / "state.json").read_text())["next_cl"] == 7

    single = job.model_copy(update={"options": job.options.model_copy(update={"scheduler": None})})
    seen: list[int] = []
    with caplog.at_level(logging.INFO, logger="fusioncut"):
        r2 = run_job(single, base, out, on_cl=lambda m, t: seen.append(m.cl_index), export_ipw=False)
    assert r2.resumed_from == 7 and seen[0] == 7
    assert any("goes on with them" in rec.getMessage() for rec in caplog.records)  # the 20 mm cells kept
    assert_same_rows(out, reference)
    assert r2.conservation_error < 1e-6


def test_single_process_checkpoint_resumes_in_parallel(tmp_path, scheduler, reference, caplog):
    job, base = small_job(tmp_path, checkpoint_every=4)
    out = tmp_path / "out"
    assert run_job(job, base, out, on_cl=stop_after(7), export_ipw=False).interrupted

    parallel = with_run_options(job, scheduler=scheduler)
    with caplog.at_level(logging.INFO, logger="fusioncut"):
        r = run_job(parallel, base, out, export_ipw=False)
    assert r.resumed_from == 7 and not r.interrupted
    # the checkpoint keeps the workpiece whole: it stays whole (one worker), and the user is told
    assert any("keeps the workpiece whole" in rec.getMessage() for rec in caplog.records)
    assert_same_rows(out, reference)
    assert r.conservation_error < 1e-6


# --------------------------------------------------------------------------------------------------
# the command line and the job options


def test_cli_workers_runs_on_an_embedded_cluster(tmp_path, reference):
    job_file = small_job_file(tmp_path, program=PROGRAM)  # the reference's job, checkpoints every 3 CLs
    out = tmp_path / "out"
    res = runner.invoke(app, ["run", str(job_file), "--out", str(out), "--workers", "2", "--no-ipw-export"])
    assert res.exit_code == 0, res.output
    assert_same_rows(out, reference)
    log = (out / "fusioncut.log").read_text()
    assert "started a Dask cluster of 2 worker processes" in log
    assert run_state(out)["cell_size"] == PARALLEL_CELL_SIZE


def test_cli_flags_override_the_job_file(tmp_path, monkeypatch):
    import fusioncut.runner

    job_file = small_job_file(tmp_path)
    doc = json.loads(job_file.read_text())
    doc["options"].update(workers=3, scheduler="tcp://10.0.0.1:8786")
    job_file.write_text(json.dumps(doc))
    seen = []

    def fake_run_job(job, base, out, **kw):
        seen.append(job.options)
        return RunResult({}, 1.0, 1.0, 0.0, 0.0, Path(out))

    monkeypatch.setattr(fusioncut.runner, "run_job", fake_run_job)
    for flags, workers, scheduler in [([], 3, "tcp://10.0.0.1:8786"),
                                      (["--workers", "2", "--scheduler", "tcp://127.0.0.1:9999"], 2,
                                       "tcp://127.0.0.1:9999")]:
        res = runner.invoke(app, ["run", str(job_file), "--out", str(tmp_path / "out"), *flags])
        assert res.exit_code == 0, res.output
        assert (seen[-1].workers, seen[-1].scheduler) == (workers, scheduler)


@pytest.mark.parametrize("flags, where", [(["--workers", "0"], "--workers"), (["--workers", "two"], "--workers"),
                                          (["--scheduler", "tcp://a b"], "--scheduler")])
def test_cli_bad_run_option_is_one_line_exit_2(tmp_path, flags, where):
    job_file = small_job_file(tmp_path)
    out = tmp_path / "out"
    res = runner.invoke(app, ["run", str(job_file), "--out", str(out), *flags])
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and where in lines[0], res.output
    assert result_files(out) == []


def test_run_options_stay_out_of_the_job_hash(tmp_path):
    job, base = small_job(tmp_path)
    assert {"workers", "scheduler"} <= RUN_OPTIONS
    assert job_hash(with_run_options(job, workers=4, scheduler="tcp://h:8786"), base) == job_hash(job, base)
    assert with_run_options(job, workers=None, scheduler=None) is job
    with pytest.raises(InputError, match="--workers"):
        with_run_options(job, workers=-1)
    assert Options().workers == 1 and Options().scheduler is None
    path = tmp_path / "job.json"
    path.write_text(json.dumps({"stock": {"kind": "infer"}, "toolpaths": ["p.nc"], "options": {"workers": 0}}))
    with pytest.raises(InputError, match="options.workers"):
        load_job(path)


def test_unreachable_scheduler_fails_before_writing(tmp_path, monkeypatch):
    import fusioncut.engines.dask_cluster as dask_cluster

    monkeypatch.setattr(dask_cluster, "CONNECT_TIMEOUT_S", 1)
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    job, base = small_job(tmp_path, scheduler=f"tcp://127.0.0.1:{port}")
    out = tmp_path / "out"
    with pytest.raises(InputError, match="cannot reach the Dask scheduler"):
        run_job(job, base, out)
    assert result_files(out) == [] and not (out / "checkpoint").exists()


# --------------------------------------------------------------------------------------------------
# inside a Dask worker (the service's jobs)


def test_service_job_drops_the_parallel_options(tmp_path):
    from fusioncut.service.worker import single_process

    job, _ = small_job(tmp_path, workers=4, scheduler="tcp://h:8786")
    options = single_process(job).options
    assert (options.workers, options.scheduler) == (1, None)
    plain, _ = small_job(tmp_path)
    assert single_process(plain) is plain


def test_a_run_inside_a_dask_worker_stays_single_process(tmp_path, scheduler, reference):
    """No LocalCluster is started from inside a worker (a daemonic process cannot start one)."""
    job, base = small_job(tmp_path, workers=2)
    out = tmp_path / "out"
    with distributed.Client(scheduler, set_as_default=False) as client:
        r = client.submit(run_job, job, base, out, export_ipw=False, pure=False).result()
    assert not r.interrupted
    assert run_state(out)["cell_size"] is None  # no parallel cells: the single-process engine ran
    assert_same_rows(out, reference)
