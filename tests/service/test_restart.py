"""Restarting the service on the same data folder: jobs are kept, and (slow) a job that was running
when the service stopped is submitted again and resumes from its checkpoint, without duplicated CLs
and with the results of an uninterrupted run."""
from __future__ import annotations

import io
import sqlite3

import pandas as pd
import pytest
from service_helpers import (KEY_B, ServiceProcess, comparable, medium_submission, reference_results, tiny_submission,
                             wait_for)


# CLs of 0.25 mm: ~440 CLs, ~8 s of work on this machine, so that the service's stop (SIGTERM, the
# monitor's last tick, the suspend flag) lands long before the job could end. With 2 mm CLs (57 CLs,
# 1.1 s) the job once ran to its end while the first service was stopping, and the restarted
# service found it done by its first attempt.
SHORT_CLS = 0.25


def _stop_mid_run(data, submission, at: int):
    """Start a service with one worker, submit a tiny job and ``submission`` (run in that order) and
    stop the service once ``submission`` has done ``at`` CLs."""
    a = ServiceProcess(data, workers=1)
    try:
        with a.client() as c:
            tiny = c.post("/api/jobs", json=tiny_submission()).json()["id"]
            med = c.post("/api/jobs", json=submission).json()["id"]
            wait_for(c, med, until=lambda j: j["state"] == "running" and j["progress"]["done"] >= at)
            assert c.get(f"/api/jobs/{tiny}").json()["state"] == "done"
    finally:
        a.stop()
    db = sqlite3.connect(data / "jobs.sqlite")
    states = dict(db.execute("SELECT id, state FROM jobs").fetchall())
    db.close()
    assert states == {tiny: "done", med: "running"}  # the stop left the job to be resumed
    return tiny, med


def _check_resumed(c, med, total):
    done = wait_for(c, med, timeout=180)
    assert done["state"] == "done", done
    assert done["progress"]["done"] == done["progress"]["total"] == total
    cl = pd.read_parquet(io.BytesIO(c.get(f"/api/jobs/{med}/files/cl.parquet").content))
    assert list(cl["cl"]) == list(range(total))  # every CL once: nothing lost, nothing duplicated
    log = c.get(f"/api/jobs/{med}/files/fusioncut.log").text
    assert "attempt 2" in log and "resuming from the checkpoint" in log
    return cl


def test_restart_keeps_jobs(tmp_path):
    data = tmp_path / "data"
    a = ServiceProcess(data, workers=1)
    try:
        with a.client() as c:
            tiny = c.post("/api/jobs", json=tiny_submission()).json()["id"]
            before = wait_for(c, tiny)
            assert before["state"] == "done"
            summary = c.get(f"/api/jobs/{tiny}/files/summary.csv").content
    finally:
        a.stop()
    b = ServiceProcess(data, workers=1)  # a new service on the same folder
    try:
        with b.client() as c:
            assert c.get("/api/jobs").json()["jobs"] == [before]  # same job, same state and times
            assert c.get(f"/api/jobs/{tiny}/files/summary.csv").content == summary
        with b.client(KEY_B) as other:  # ownership survived the restart too
            assert other.get("/api/jobs").json()["jobs"] == []
            assert other.get(f"/api/jobs/{tiny}").status_code == 404
    finally:
        b.stop()


@pytest.mark.slow
def test_restart_resumes_the_running_job_without_duplicates(tmp_path):
    data = tmp_path / "data"
    # short CLs with a checkpoint every 5: something to resume from after 10 CLs
    tiny, med = _stop_mid_run(data, medium_submission(segment=SHORT_CLS, checkpoint_every=5), at=10)
    b = ServiceProcess(data, workers=1)
    try:
        with b.client() as c:
            jobs = {j["id"]: j for j in c.get("/api/jobs").json()["jobs"]}
            assert set(jobs) == {tiny, med} and jobs[tiny]["state"] == "done"
            _check_resumed(c, med, jobs[med]["progress"]["total"])
    finally:
        b.stop()


@pytest.mark.slow
def test_resumed_job_equals_an_uninterrupted_run(tmp_path):
    data = tmp_path / "data"
    sub = medium_submission(segment=SHORT_CLS, checkpoint_every=20)
    _, med = _stop_mid_run(data, sub, at=45)
    b = ServiceProcess(data, workers=1)
    try:
        with b.client() as c:
            total = c.get(f"/api/jobs/{med}").json()["progress"]["total"]
            _check_resumed(c, med, total)
            got = _download_results(c, med, tmp_path / "got")
    finally:
        b.stop()
    _assert_equal_to_uninterrupted(got, sub, tmp_path / "ref")


@pytest.mark.slow
def test_a_graceful_stop_checkpoints_mid_job_and_resumes_there(tmp_path):
    """No periodic checkpoints (checkpoint_every 0): a resume can only start where the stop suspended
    the job, which it does only when the stop waits for the job to reach its next CL (it used to close
    the cluster at once, and the job started over)."""
    data = tmp_path / "data"
    sub = medium_submission(segment=SHORT_CLS, checkpoint_every=0)
    _, med = _stop_mid_run(data, sub, at=45)
    first_log = next(tmp_path.glob("service-*.log")).read_text()
    assert "every job stopped at a checkpoint" in first_log
    b = ServiceProcess(data, workers=1)
    try:
        with b.client() as c:
            total = c.get(f"/api/jobs/{med}").json()["progress"]["total"]
            _check_resumed(c, med, total)
            log = c.get(f"/api/jobs/{med}/files/fusioncut.log").text
            resumed_at = int(log.split("resuming from the checkpoint")[1].split(" at CL ")[1].split()[0])
            assert 45 <= resumed_at < total
            assert "(2 attempts)" in c.get(f"/api/jobs/{med}").json()["message"]
            got = _download_results(c, med, tmp_path / "got")
    finally:
        b.stop()
    _assert_equal_to_uninterrupted(got, sub, tmp_path / "ref")


def _download_results(c, job: str, folder):
    folder.mkdir()
    for name in ("cl.parquet", "slices.parquet", "metadata.json", "summary.csv"):
        (folder / name).write_bytes(c.get(f"/api/jobs/{job}/files/{name}").content)
    return folder


def _assert_equal_to_uninterrupted(got, sub, ref_dir) -> None:
    from fusioncut.io.results import load_results

    a, ref = load_results(got), reference_results(sub, ref_dir)
    pd.testing.assert_frame_equal(comparable(a.cl), comparable(ref.cl))
    pd.testing.assert_frame_equal(comparable(a.slices), comparable(ref.slices))
    pd.testing.assert_frame_equal(a.summary.drop(columns=["time_s"]), ref.summary.drop(columns=["time_s"]))
