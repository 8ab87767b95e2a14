"""Load and failure: many concurrent submissions, and a Dask worker killed in the middle of a job."""
from __future__ import annotations

import io
import json
import os
import signal
import time
from concurrent.futures import ThreadPoolExecutor

import pandas as pd
import pytest
from service_helpers import TINY_JOB, ServiceProcess, comparable, medium_submission, reference_results, wait_for

# three moves: a plunge, one slot pass and a retract (plus the first rapid): a job of a few CLs
LOAD_GCODE = "G21 G90\nT1 M6\nG0 X-5 Y10 Z5\nG1 Z-1 F300\nG1 X35 F600\nG0 Z5\nM30\n"


@pytest.mark.slow
def test_fifty_concurrent_jobs_all_finish(tmp_path):
    svc = ServiceProcess(tmp_path / "data", workers=2)
    try:
        def submit(k: int) -> str:
            with svc.client() as c:
                job = {**TINY_JOB, "name": f"load-{k}", "toolpaths": ["load.nc"],
                       "options": {"slice_height": 1.0}}
                r = c.post("/api/jobs", json={"job": job, "files": {"load.nc": LOAD_GCODE}})
                assert r.status_code == 201, r.text
                return r.json()["id"]

        with ThreadPoolExecutor(max_workers=16) as pool:
            ids = list(pool.map(submit, range(50)))
        assert len(set(ids)) == 50
        with svc.client() as c:
            listed = {j["id"]: j for j in c.get("/api/jobs").json()["jobs"]}
            assert set(listed) == set(ids)  # none lost between submission and the store
            deadline = time.monotonic() + 600
            while time.monotonic() < deadline:
                states = [j["state"] for j in c.get("/api/jobs").json()["jobs"]]
                if all(s in ("done", "failed", "cancelled") for s in states):
                    break
                time.sleep(1)
            jobs = c.get("/api/jobs").json()["jobs"]
            assert [j["state"] for j in jobs] == ["done"] * 50, [j for j in jobs if j["state"] != "done"][:3]
            totals = {j["progress"]["total"] for j in jobs}
            assert len(totals) == 1 and totals.pop() > 0
            for j in jobs[::7]:  # every job has its own complete results
                cl = pd.read_csv(io.BytesIO(c.get(f"/api/jobs/{j['id']}/files/cl.csv").content))
                assert list(cl["cl"]) == list(range(j["progress"]["total"]))
    finally:
        svc.stop()


@pytest.mark.slow
def test_killed_worker_job_completes_like_an_uninterrupted_run(tmp_path):
    sub = medium_submission()
    svc = ServiceProcess(tmp_path / "data", workers=2)
    try:
        with svc.client() as c:
            job_id = c.post("/api/jobs", json=sub).json()["id"]
            wait_for(c, job_id, until=lambda j: j["state"] == "running" and j["progress"]["done"] >= 15)
            progress = svc.data_dir / "jobs" / job_id / "progress.json"
            pid = json.loads(progress.read_text())["pid"]
            assert pid not in (os.getpid(), svc.proc.pid)
            os.kill(pid, signal.SIGKILL)
            done = wait_for(c, job_id, timeout=300)
            assert done["state"] == "done", (done, svc.log())
            final = json.loads(progress.read_text())
            assert final["pid"] != pid  # finished by another worker process
            got = tmp_path / "got"
            got.mkdir()
            for name in ("cl.parquet", "slices.parquet", "metadata.json", "summary.csv"):
                (got / name).write_bytes(c.get(f"/api/jobs/{job_id}/files/{name}").content)
            log = c.get(f"/api/jobs/{job_id}/files/fusioncut.log").text
            assert "resuming from the checkpoint" in log
    finally:
        svc.stop()
    from fusioncut.io.results import load_results

    a, ref = load_results(got), reference_results(sub, tmp_path / "ref")
    assert list(a.cl["cl"]) == list(range(len(ref.cl)))
    pd.testing.assert_frame_equal(comparable(a.cl), comparable(ref.cl))
    pd.testing.assert_frame_equal(comparable(a.slices), comparable(ref.slices))
