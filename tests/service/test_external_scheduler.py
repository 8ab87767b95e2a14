"""The service on an external Dask cluster (``dask scheduler`` + ``dask worker`` processes): jobs run
there, and a service restarted while a job runs follows the same task instead of starting it again."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import httpx
import pytest
from service_helpers import KEY_A, ServiceProcess, free_port, medium_submission, tiny_submission, wait_for


def _dask(*args: str, log) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_" + args[0], *args[1:]],
                            stdout=log, stderr=subprocess.STDOUT, start_new_session=True)


@pytest.fixture
def cluster(tmp_path):
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    log = open(tmp_path / "dask.log", "w")
    procs = [_dask("scheduler", "--host", "127.0.0.1", "--port", str(port), "--dashboard-address", ":0", log=log)]
    procs.append(_dask("worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard",
                       "--local-directory", str(tmp_path / "dask-worker"), log=log))
    from distributed import Client

    deadline = time.monotonic() + 90
    while True:
        try:
            with Client(address, timeout=5) as c:
                if c.scheduler_info()["workers"]:
                    break
        except OSError:
            pass
        assert time.monotonic() < deadline, (tmp_path / "dask.log").read_text()
        time.sleep(0.5)
    yield address
    for p in procs[::-1]:
        os.killpg(p.pid, signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
    log.close()


@pytest.mark.slow
def test_jobs_run_on_the_external_cluster_and_survive_a_service_restart(tmp_path, cluster):
    data = tmp_path / "data"
    env = {"FUSIONCUT_SCHEDULER": cluster}
    a = ServiceProcess(data, env=env)
    try:
        with a.client() as c:
            info = c.get("/api/info").json()
            assert info["scheduler"] == cluster and info["embedded_cluster"] is False
            tiny = c.post("/api/jobs", json=tiny_submission()).json()["id"]
            assert wait_for(c, tiny)["state"] == "done"
            # 0.25 mm CLs (~440, ~8 s of work): still running well after the service has stopped
            med = c.post("/api/jobs", json=medium_submission(segment=0.25)).json()["id"]
            wait_for(c, med, until=lambda j: j["state"] == "running" and j["progress"]["done"] >= 10)
    finally:
        a.stop()
    # the service is gone; the job goes on on the cluster
    progress = data / "jobs" / med / "progress.json"
    before = progress.stat().st_mtime
    time.sleep(1.5)
    assert progress.stat().st_mtime > before
    b = ServiceProcess(data, env=env)
    try:
        with b.client() as c:
            done = wait_for(c, med, timeout=300)
            assert done["state"] == "done", done
            log = c.get(f"/api/jobs/{med}/files/fusioncut.log").text
            assert "attempt 1" in log and "attempt 2" not in log  # followed, never started twice
    finally:
        b.stop()
    with httpx.Client(base_url=b.url) as gone:  # stopped for real
        with pytest.raises(httpx.HTTPError):
            gone.get("/api/info", headers={"X-API-Key": KEY_A}, timeout=2)
