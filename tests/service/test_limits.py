"""The service cannot be exhausted by one request: every limit refuses at once, with no memory growth
(the service with its workers), and event streams are limited per key."""
from __future__ import annotations

import json
import time

import httpx
import psutil
import pytest
from service_helpers import KEY_A, KEY_B, TINY_GCODE, TINY_JOB


def _rss_mb(service) -> float:
    """Resident memory of the service process and its Dask workers, MB."""
    proc = psutil.Process(service.proc.pid)
    procs = [proc, *proc.children(recursive=True)]
    total = 0
    for p in procs:
        try:
            total += p.memory_info().rss
        except psutil.NoSuchProcess:
            pass
    return total / 1e6


def _settled_rss_mb(service, timeout_s: float = 60.0) -> float:
    """The service's memory once it has stopped growing on its own: a fresh service's Dask workers
    import the kernel, pandas and matplotlib in the background (hundreds of MB) for a while."""
    last = _rss_mb(service)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        time.sleep(0.5)
        now = _rss_mb(service)
        if abs(now - last) < 2:
            return now
        last = now
    return last


def _job(gcode: str = TINY_GCODE, **options) -> dict:
    return {"job": {**TINY_JOB, "options": {**TINY_JOB["options"], **options}}, "files": {"tiny.nc": gcode}}


ATTACKS = {
    # below a lower bound: once 57 s and +1.8 GB before its 422
    "segment-below-bound": (json.dumps(_job(max_segment_length=1e-5)), "options.max_segment_length"),
    # 1 µm segments of the tiny job: 53,000 CL segments, over the service's 2,000
    "too-many-cls": (json.dumps(_job(max_segment_length=1e-3)), "more than 2,000 CL segments"),
    # a 90-byte arc of 1,000 turns at the finest chord tolerance: 1.57 million chords
    "arc-turns": (json.dumps(_job("T1 M6\nG0 X0 Y0 Z0\nG18 G2 X0 Z0 I5 K0 P1000 F300\nM30\n", chord_tolerance=1e-5)),
                  "tiny.nc:3"),
    # 12,000 slices a CL (12 mm flutes over 1 µm)
    "too-many-slices": (json.dumps(_job(slice_height=1e-3)), "slices"),
    "too-many-snapshots": (json.dumps(_job(snapshot_cls=list(range(1001)))), "snapshot_cls"),
    # Python's JSON parser recurses per level: once a 500 RecursionError
    "nested-json": ("[" * 100_000, "nests too deeply"),
    "nested-json-in-job": ('{"job": ' + "[" * 100_000, "nests too deeply"),
}


@pytest.mark.parametrize("name", sorted(ATTACKS))
def test_each_limit_refuses_at_once_without_memory_growth(client, service, name):
    body, needle = ATTACKS[name]
    # a refused request first: the request path and the readers are imported before measuring
    client.post("/api/jobs", json={"job": {**TINY_JOB, "tools": []}, "files": {"tiny.nc": TINY_GCODE}})
    before = _settled_rss_mb(service)
    t0 = time.monotonic()
    r = client.post("/api/jobs", content=body, headers={"content-type": "application/json"})
    elapsed = time.monotonic() - t0
    grown = _rss_mb(service) - before
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert needle in detail and "Traceback" not in detail, detail
    assert elapsed < 1.0, f"{name}: refused in {elapsed:.2f} s"
    assert grown < 50, f"{name}: the service grew by {grown:.0f} MB"


def test_multipart_job_field_nesting_is_refused(client):
    r = client.post("/api/jobs", files=[("toolpath", ("tiny.nc", TINY_GCODE.encode(), "text/plain"))],
                    data={"job": "[" * 100_000})
    assert r.status_code == 422 and "nests too deeply" in r.json()["detail"]


def test_a_lying_tools_archive_upload_is_refused_without_memory_growth(client, service, tmp_path, lying_archive):
    """A Fusion .tools whose zip header says 1,000 bytes and that inflates to 200 MB: once 6 s and
    +150-2,000 MB in an upload. Refused at once naming the member, the service's memory flat."""
    bomb = tmp_path / "lib.tools"
    lying_archive(bomb, "tools.json", 200 << 20, 1000)
    files = [("toolpath", ("tiny.nc", TINY_GCODE.encode(), "text/plain")),
             ("tool_library", ("lib.tools", bomb.read_bytes(), "application/octet-stream"))]
    client.post("/api/jobs", json={"job": {**TINY_JOB, "tools": []}, "files": {"tiny.nc": TINY_GCODE}})
    before = _settled_rss_mb(service)
    t0 = time.monotonic()
    r = client.post("/api/jobs", files=files, data={"job": json.dumps({k: v for k, v in TINY_JOB.items()
                                                                       if k != "toolpaths"})})
    elapsed = time.monotonic() - t0
    assert r.status_code == 422, r.text
    assert "tools.json" in r.json()["detail"] and "Traceback" not in r.json()["detail"]
    assert elapsed < 1.0 and _rss_mb(service) - before < 50


def test_info_states_the_limits(client):
    info = client.get("/api/info").json()
    assert info["max_cls"] == 2000 and info["max_slices"] == 100_000


def test_event_streams_are_limited_per_key(service):
    limit = 8  # Settings.max_streams_per_key
    with httpx.Client(base_url=service.url, headers={"X-API-Key": KEY_A}, timeout=30) as c, \
            httpx.Client(base_url=service.url, headers={"X-API-Key": KEY_B}, timeout=30) as other:
        streams = [c.stream("GET", "/api/events") for _ in range(limit)]
        opened = [s.__enter__() for s in streams]
        lines = [resp.iter_lines() for resp in opened]  # kept: a dropped iterator closes its stream
        try:
            for resp, it in zip(opened, lines):
                assert resp.status_code == 200
                next(it)  # the stream's first line: it is counted now
            with c.stream("GET", "/api/events") as r:
                assert r.status_code == 429 and "event streams" in json.loads(r.read())["detail"]
            with other.stream("GET", "/api/events") as resp:  # another key is not affected
                assert resp.status_code == 200
            t0 = time.monotonic()
            assert c.get("/api/info").status_code == 200 and time.monotonic() - t0 < 1.0
        finally:
            for s in streams:
                s.__exit__(None, None, None)
        # closed streams are given back (the service notices a disconnect within a poll interval)
        deadline = time.monotonic() + 10
        while True:
            with c.stream("GET", "/api/events") as resp:
                if resp.status_code == 200:
                    break
            assert time.monotonic() < deadline, "closed streams were not given back"
            time.sleep(0.2)
