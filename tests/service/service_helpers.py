"""Helpers of the service tests. A real FusionCut service on loopback: ``python -m fusioncut.service`` (which is
``fusioncut serve``) in a subprocess with its own data folder, embedded Dask cluster and API keys."""
from __future__ import annotations

import json
import os
import random
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

KEY_A = "key-a-0123456789abcdef"
KEY_B = "key-b-fedcba9876543210"

# A tiny job: a 6 mm flat end mill cutting a slot and a 2 mm side pass in a 30 x 20 x 5 block.
TINY_GCODE = """%
G21 G90 G17
T1 M6
S10000 M3
(Slot)
G0 X-5 Y10 Z5
G1 Z-1 F300
G1 X15 F600
(Side)
G0 Z5
G0 X31 Y-5
G1 Z-1.5 F300
G1 Y25 F600
G0 Z5
M30
%
"""
TINY_JOB = {
    "name": "tiny",
    "stock": {"kind": "box", "min": [0, 0, -5], "max": [30, 20, 0]},
    "tools": [{"number": 1, "kind": "flat", "diameter": 6, "flute_length": 12}],
    "toolpaths": ["tiny.nc"],
    "options": {"slice_height": 1.0, "max_segment_length": 5.0},
}


def tiny_submission(name: str = "tiny") -> dict:
    return {"job": {**TINY_JOB, "name": name}, "files": {"tiny.nc": TINY_GCODE}}


def tiny_total() -> int:
    """CL segments of the tiny job, counted the way the runner counts them (no kernel needed)."""
    from fusioncut.engines.segments import cl_segments
    from fusioncut.io.gcode import parse_gcode_text

    tp = parse_gcode_text(TINY_GCODE)
    return len(cl_segments(tp.moves, TINY_JOB["options"]["max_segment_length"], 1e-3))


def _ephemeral_range() -> tuple[int, int]:
    try:
        lo, hi = map(int, Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split())
        return lo, hi
    except (OSError, ValueError):
        return 32768, 60999


def free_port() -> int:
    """A free loopback port outside the kernel's ephemeral range, so that no socket bound to port 0 (the
    embedded Dask cluster's scheduler, nannies and workers start before the service binds) can take it
    between this choice and the service's bind. Falls back on a port the kernel hands out."""
    lo, hi = _ephemeral_range()
    candidates = [p for p in range(20000, 32000) if not lo <= p <= hi]
    for port in random.sample(candidates, min(50, len(candidates))):
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ServiceProcess:
    def __init__(self, data_dir: Path, *, workers: int = 1, env: dict[str, str] | None = None):
        self.data_dir = data_dir
        inherited = {k: v for k, v in os.environ.items() if not k.startswith("FUSIONCUT_")}  # no stray settings
        full_env = {**inherited, "FUSIONCUT_API_KEYS": f"{KEY_A},{KEY_B}", "PYTHONUNBUFFERED": "1", **(env or {})}
        for attempt in range(3):  # another process on the machine may still take the port first
            self.port = free_port()
            self.url = f"http://127.0.0.1:{self.port}"
            self.log_path = data_dir.parent / f"service-{self.port}.log"
            self._log = open(self.log_path, "w")
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "fusioncut.service", "--host", "127.0.0.1", "--port", str(self.port),
                 "--workers", str(workers), "--data-dir", str(data_dir), "--log-level", "info"],
                stdout=self._log, stderr=subprocess.STDOUT, env=full_env, start_new_session=True)
            try:
                self._wait_ready()
                return
            except RuntimeError:
                if attempt == 2 or "address already in use" not in self.log():
                    raise
                self.stop()

    def _wait_ready(self, timeout: float = 120) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"the service exited with {self.proc.returncode}:\n{self.log()}")
            try:
                r = httpx.get(f"{self.url}/api/info", headers={"X-API-Key": KEY_A}, timeout=2)
                if r.status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(0.2)
        self.stop()
        raise RuntimeError(f"the service did not start in {timeout} s:\n{self.log()}")

    def log(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors="replace")[-6000:]

    def client(self, key: str | None = KEY_A) -> httpx.Client:
        headers = {"X-API-Key": key} if key else {}
        return httpx.Client(base_url=self.url, headers=headers, timeout=60)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)  # the group we started: service and its workers
                self.proc.wait(timeout=10)
        self._log.close()


def wait_for(client: httpx.Client, job_id: str, states=("done", "failed", "cancelled"), timeout: float = 120,
             until=None) -> dict:
    """Poll the job until its state is one of ``states`` (or ``until(job)`` is true)."""
    deadline = time.monotonic() + timeout
    job = None
    while time.monotonic() < deadline:
        r = client.get(f"/api/jobs/{job_id}")
        assert r.status_code == 200, r.text
        job = r.json()
        if (until(job) if until else job["state"] in states):
            return job
        time.sleep(0.2)
    raise AssertionError(f"job {job_id} did not get there in {timeout} s: {json.dumps(job)}")


def comparable(df):
    """A result table without what legitimately differs between two runs of one job: compute times,
    and the folder part of source file names (each run reads its inputs from its own folder)."""
    out = df.drop(columns=[c for c in ("time_ms",) if c in df.columns]).copy()
    if "file" in out.columns:
        out["file"] = out["file"].map(lambda s: Path(s).name)
    return out.reset_index(drop=True)


def medium_submission(name: str = "medium", segment: float = 1.0, checkpoint_every: int = 10) -> dict:
    """The tiny job cut into short CLs (about 110 at 1 mm, 440 at 0.25 mm) by a ball end mill: to stop or kill
    mid-run, with checkpoints every ``checkpoint_every`` CLs so that a resumed run has something to
    resume from. (With the flat end mill the layered cells ran all its CLs before a stop landed.)"""
    job = {**TINY_JOB, "name": name, "tools": [{"number": 1, "kind": "ball", "diameter": 6, "flute_length": 12}],
           "options": {**TINY_JOB["options"], "max_segment_length": segment, "checkpoint_every": checkpoint_every}}
    return {"job": job, "files": {"tiny.nc": TINY_GCODE}}


def reference_results(submission: dict, folder: Path):
    """The results of an uninterrupted in-process run of a submission."""
    from fusioncut.io.job import Job
    from fusioncut.io.results import load_results
    from fusioncut.runner import run_job

    inputs = folder / "in"
    inputs.mkdir(parents=True)
    for name, text in submission["files"].items():
        (inputs / name).write_text(text)
    run_job(Job.model_validate(submission["job"]), inputs, folder / "out", resume=False)
    return load_results(folder / "out")
