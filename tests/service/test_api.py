"""The HTTP API against a real service on loopback (embedded Dask cluster, one worker process)."""
from __future__ import annotations

import io
import json
import math

import pandas as pd
import pytest

from service_helpers import (KEY_A, KEY_B, TINY_GCODE, TINY_JOB, comparable, tiny_submission, tiny_total,
                                    wait_for)


def _events(client, path: str, limit: int = 10_000) -> list[tuple[str, dict]]:
    """Read a server-sent event stream to its end."""
    out: list[tuple[str, dict]] = []
    event, data = "message", []
    with client.stream("GET", path, timeout=120) as r:
        assert r.status_code == 200, r.read()
        assert r.headers["content-type"].startswith("text/event-stream")
        for line in r.iter_lines():
            if line.startswith("event:"):
                event = line[6:].strip()
            elif line.startswith("data:"):
                data.append(line[5:].strip())
            elif line == "" and data:
                out.append((event, json.loads("\n".join(data))))
                event, data = "message", []
                if out[-1][0] == "end" or len(out) >= limit:
                    break
    return out


@pytest.fixture(scope="module")
def tiny_done(service):
    """One tiny job, run to the end while its event stream is followed."""
    with service.client() as c:
        r = c.post("/api/jobs", json=tiny_submission())
        assert r.status_code == 201, r.text
        assert r.headers["location"] == f"/api/jobs/{r.json()['id']}"
        job_id = r.json()["id"]
        events = _events(c, f"/api/jobs/{job_id}/events")
        return job_id, events


def test_submitted_job_reports_progress_and_finishes(client, tiny_done):
    job_id, events = tiny_done
    total = tiny_total()
    statuses = [d for e, d in events if e == "status"]
    assert events[-1] == ("end", {"id": job_id, "state": "done"})
    assert statuses[0]["state"] in ("queued", "running", "done")
    fractions = [s["progress"]["fraction"] for s in statuses]
    assert fractions == sorted(fractions)  # progress never goes back
    last = statuses[-1]
    assert last["state"] == "done" and last["progress"]["done"] == last["progress"]["total"] == total
    assert last["progress"]["fraction"] == 1.0
    job = client.get(f"/api/jobs/{job_id}").json()
    assert job["state"] == "done" and job["started_at"] <= job["finished_at"]
    assert f"{total} CLs" in job["message"]
    listed = client.get("/api/jobs").json()["jobs"]
    assert job_id in [j["id"] for j in listed]


def test_results_download_equal_a_direct_run(client, tiny_done, tmp_path):
    from fusioncut.io.job import Job
    from fusioncut.io.results import load_results
    from fusioncut.runner import run_job

    job_id, _ = tiny_done
    files = {f["name"]: f for f in client.get(f"/api/jobs/{job_id}/files").json()["files"]}
    for name in ("cl.csv", "cl.parquet", "slices.csv", "slices.parquet", "summary.csv", "metadata.json",
                 "program.png", "heatmap.png"):
        assert name in files, sorted(files)
    got = tmp_path / "got"
    got.mkdir()
    for name in ("cl.parquet", "slices.parquet", "summary.csv", "metadata.json"):
        r = client.get(files[name]["url"])
        assert r.status_code == 200
        assert len(r.content) == files[name]["size"]
        (got / name).write_bytes(r.content)
    assert client.get(files["program.png"]["url"]).content[:8] == b"\x89PNG\r\n\x1a\n"
    csv = client.get(files["cl.csv"]["url"])
    assert csv.headers["content-type"].startswith("text/csv")
    assert len(pd.read_csv(io.BytesIO(csv.content))) == tiny_total()

    ref = tmp_path / "ref"
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "tiny.nc").write_text(TINY_GCODE)
    run_job(Job.model_validate(TINY_JOB), tmp_path / "in", ref)
    a, b = load_results(got), load_results(ref)
    pd.testing.assert_frame_equal(comparable(a.cl), comparable(b.cl))
    pd.testing.assert_frame_equal(comparable(a.slices), comparable(b.slices))
    assert a.metadata["job_hash"] == b.metadata["job_hash"]


def test_result_views_for_the_front_end(client, tiny_done):
    job_id, _ = tiny_done
    summary = client.get(f"/api/jobs/{job_id}/summary").json()["rows"]
    assert [r["operation"] for r in summary] == ["Slot", "Side"]
    assert sum(r["processed"] for r in summary) == tiny_total()
    scene = client.get(f"/api/jobs/{job_id}/scene").json()
    assert scene["stock"] == {"kind": "box", "min": [0, 0, -5], "max": [30, 20, 0]}
    assert len(scene["cls"]["cl"]) == tiny_total() == len(scene["cls"]["x"])
    assert scene["tools"]  # the 3D view sizes the tool from here
    engaged = [c for c, s in zip(scene["cls"]["cl"], scene["cls"]["status"]) if s == "engaged"]
    assert engaged
    with_arcs = 0
    for cl in engaged:  # an engaged CL has arcs exactly when the tool touches material at its end
        detail = client.get(f"/api/jobs/{job_id}/cls/{cl}").json()
        assert detail["cl"]["cl"] == cl and detail["cl"]["status"] == "engaged"
        assert detail["cl"]["file"] == "tiny.nc"  # no server folders in what users see
        assert bool(detail["slices"]) == (detail["cl"]["ae_mm"] > 0), detail
        with_arcs += bool(detail["slices"])
        for s in detail["slices"]:
            assert s["cl"] == cl
            assert 0 <= s["entry_machine_deg"] < s["exit_machine_deg"] <= s["entry_machine_deg"] + 360
            assert math.isclose(s["radius_mm"], 3.0)
    assert with_arcs >= 2
    png = client.get(f"/api/jobs/{job_id}/plots/polar", params={"cl": engaged[0]})
    assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
    assert client.get(f"/api/jobs/{job_id}/cls/99999").status_code == 404
    assert client.get(f"/api/jobs/{job_id}/plots/polar").status_code == 422
    assert client.get(f"/api/jobs/{job_id}/plots/nope").status_code == 404


def test_multipart_upload_runs_like_json(client):
    job = {k: v for k, v in TINY_JOB.items() if k not in ("toolpaths", "name")}
    r = client.post("/api/jobs", files=[("toolpath", ("slot.nc", TINY_GCODE.encode(), "text/plain"))],
                    data={"job": json.dumps(job), "name": "uploaded", "slice_height": "0.5"})
    assert r.status_code == 201, r.text
    done = wait_for(client, r.json()["id"])
    assert done["state"] == "done", done
    assert done["name"] == "uploaded" and done["progress"]["done"] == tiny_total()
    cl = pd.read_csv(io.BytesIO(client.get(f"/api/jobs/{done['id']}/files/cl.csv").content))
    assert set(cl["file"].map(lambda s: s.rsplit("/", 1)[-1])) == {"slot.nc"}
    # the slice_height field overrode the job's: slices are 0.5 mm apart
    sl = pd.read_csv(io.BytesIO(client.get(f"/api/jobs/{done['id']}/files/slices.csv").content))
    heights = sorted(set(sl["z_tool_mm"].round(6)))
    assert min(b - a for a, b in zip(heights, heights[1:])) == pytest.approx(0.5)


BAD_GCODE = "G21 G90\nT1 M6\nG1 X10 Y0 Z-1 F300\nG1 X20 Q#<\n"


@pytest.mark.parametrize("body, status, needle", [
    ('{"job": {"name": "x",\n "stock": ', 422, "not valid JSON"),
    (json.dumps({"job": {**TINY_JOB, "toolpaths": ["bad.nc"]}, "files": {"bad.nc": BAD_GCODE}}), 422, "bad.nc:4"),
    (json.dumps({"job": {**TINY_JOB, "tools": [{**TINY_JOB["tools"][0], "number": 2}]},
                 "files": {"tiny.nc": TINY_GCODE}}), 422, "T1"),
    (json.dumps({"job": {**TINY_JOB, "toolpaths": ["../../etc/passwd"]}, "files": {"tiny.nc": TINY_GCODE}}),
     422, "not a plain file name"),
    (json.dumps({"job": TINY_JOB, "files": {"../evil.nc": TINY_GCODE}}), 422, "not a plain file name"),
    (json.dumps({"job": TINY_JOB, "files": {}}), 422, "was not uploaded"),
    (json.dumps({"job": {**TINY_JOB, "stock": {"kind": "box", "min": [0, 0, 0]}}, "files": {}}), 422, "job.stock"),
    (json.dumps(TINY_JOB), 422, "wrapped"),
    (json.dumps({"job": {**TINY_JOB, "options": {"max_segment_length": 0.01}}, "files": {"tiny.nc": TINY_GCODE}}),
     422, "CL segments"),
], ids=["broken-json", "malformed-gcode", "unknown-tool", "traversal-in-job", "traversal-in-files", "missing-file",
        "invalid-field", "unwrapped-job", "too-many-cls"])
def test_bad_submissions_are_refused_with_a_message(client, service, body, status, needle):
    before = len(client.get("/api/jobs").json()["jobs"])
    r = client.post("/api/jobs", content=body, headers={"content-type": "application/json"})
    assert r.status_code == status, r.text
    detail = r.json()["detail"]
    assert needle in detail, detail
    assert "Traceback" not in detail and str(service.data_dir) not in detail  # no server paths either
    assert len(client.get("/api/jobs").json()["jobs"]) == before  # nothing was queued
    assert not list((service.data_dir / "jobs").glob(".staging-*"))  # nor left behind


def test_unknown_tool_names_the_line(client):
    r = client.post("/api/jobs", json={"job": {**TINY_JOB, "tools": []}, "files": {"tiny.nc": TINY_GCODE}})
    assert r.status_code == 422
    assert "T1" in r.json()["detail"] and "tiny.nc" in r.json()["detail"]


def test_upload_limits_and_unsafe_names(client, service):
    big = b"(" + b"x" * (1024 * 1024 + 10) + b")\n"
    r = client.post("/api/jobs", files=[("toolpath", ("big.nc", big, "text/plain"))])
    assert r.status_code == 413 and "limit" in r.json()["detail"]

    def chunks():  # no Content-Length: the limit is enforced while reading
        for _ in range(40):
            yield b"x" * 65536

    r = client.post("/api/jobs", content=chunks(), headers={"content-type": "application/json"})
    assert r.status_code == 413, r.text
    r = client.post("/api/jobs", files=[("toolpath", ("../evil.nc", TINY_GCODE.encode(), "text/plain"))],
                    data={"job": json.dumps({"tools": TINY_JOB["tools"]})})
    assert r.status_code == 422 and "not a plain file name" in r.json()["detail"]
    assert not (service.data_dir / "jobs" / "evil.nc").exists() and not (service.data_dir / "evil.nc").exists()
    r = client.post("/api/jobs", content=b"<job/>", headers={"content-type": "application/xml"})
    assert r.status_code == 415


def test_downloads_only_listed_files(client, tiny_done):
    job_id, _ = tiny_done
    for name in ("..%2Fprogress.json", "checkpoint", "nope.csv", ".hidden.csv"):
        r = client.get(f"/api/jobs/{job_id}/files/{name}")
        assert r.status_code in (404, 422), (name, r.status_code)
        assert "detail" in r.json()
    r = client.get(f"/api/jobs/{job_id}/files/..%2F..%2Fjobs.sqlite")
    assert r.status_code == 404


def test_keys_see_only_their_own_jobs(service, tiny_done):
    job_id, _ = tiny_done
    with service.client(None) as anon:
        r = anon.get("/api/jobs")
        assert r.status_code == 401 and "X-API-Key" in r.json()["detail"]
    with service.client("not-a-key-0123456789") as wrong:
        assert wrong.get("/api/jobs").status_code == 401
    with service.client(KEY_B) as b:
        assert job_id not in [j["id"] for j in b.get("/api/jobs").json()["jobs"]]
        for method, path in [("GET", ""), ("GET", "/files"), ("GET", "/files/cl.csv"), ("GET", "/events"),
                             ("GET", "/scene"), ("GET", "/summary"), ("POST", "/cancel"), ("DELETE", "")]:
            r = b.request(method, f"/api/jobs/{job_id}{path}")
            assert r.status_code == 404, (method, path, r.status_code)
    with service.client(KEY_A) as a:  # B's attempts changed nothing
        assert a.get(f"/api/jobs/{job_id}").json()["state"] == "done"


def test_cancel_keeps_finished_results(client):
    r = client.post("/api/jobs", json={"demo": True, "name": "to cancel"})
    assert r.status_code == 201, r.text
    job_id = r.json()["id"]
    running = wait_for(client, job_id, until=lambda j: j["state"] == "running" and j["progress"]["done"] >= 3)
    total = running["progress"]["total"]
    r = client.post(f"/api/jobs/{job_id}/cancel")
    assert r.status_code == 202
    job = wait_for(client, job_id)
    assert job["state"] == "cancelled", job
    assert "kept" in job["message"]
    cl = pd.read_parquet(io.BytesIO(client.get(f"/api/jobs/{job_id}/files/cl.parquet").content))
    assert 3 <= len(cl) < total
    assert list(cl["cl"]) == list(range(len(cl)))  # the finished CLs, in order, none twice
    assert client.post(f"/api/jobs/{job_id}/cancel").status_code == 202  # already cancelled: no error


def test_finished_jobs_cannot_be_cancelled_and_can_be_deleted(client, service):
    r = client.post("/api/jobs", json=tiny_submission("to delete"))
    job_id = r.json()["id"]
    assert wait_for(client, job_id)["state"] == "done"
    r = client.post(f"/api/jobs/{job_id}/cancel")
    assert r.status_code == 409 and "already finished" in r.json()["detail"]
    folder = service.data_dir / "jobs" / job_id
    assert folder.is_dir()
    assert client.delete(f"/api/jobs/{job_id}").status_code == 204
    assert client.get(f"/api/jobs/{job_id}").status_code == 404
    assert not folder.exists()
    assert client.delete(f"/api/jobs/{job_id}").status_code == 404


def test_openapi_documents_the_api(client):
    spec = client.get("/openapi.json").json()
    for path in ("/api/jobs", "/api/jobs/{job_id}", "/api/jobs/{job_id}/events", "/api/jobs/{job_id}/cancel",
                 "/api/jobs/{job_id}/files", "/api/jobs/{job_id}/files/{name}"):
        assert path in spec["paths"], path
    body = spec["paths"]["/api/jobs"]["post"]["requestBody"]["content"]
    assert set(body) == {"application/json", "multipart/form-data"}
    assert "JobSubmission" in spec["components"]["schemas"] and "JobStatus" in spec["components"]["schemas"]
    schemes = spec["components"]["securitySchemes"]
    assert any(s.get("name") == "X-API-Key" and s.get("in") == "header" for s in schemes.values())


def test_api_docs_page_serves_swagger_ui_from_the_front_ends_packages(client, frontend_packages):
    docs = client.get("/docs")  # Swagger UI from the front end's packages, not from a CDN
    assert docs.status_code == 200 and "/vendor/swagger-ui/swagger-ui-bundle.js" in docs.text
    assert "cdn" not in docs.text.lower()
    assert client.get("/vendor/swagger-ui/swagger-ui-bundle.js").status_code == 200


def test_front_end_is_served_with_an_import_map(client, frontend_packages):
    page = client.get("/")
    assert page.status_code == 200 and "importmap" in page.text
    imports = json.loads(page.text.split('<script type="importmap">')[1].split("</script>")[0])["imports"]
    for url in (imports["three"], imports["three/addons/"] + "controls/OrbitControls.js", "/src/main.js"):
        r = client.get(url)
        assert r.status_code == 200, url
        assert "javascript" in r.headers["content-type"], (url, r.headers["content-type"])
    assert client.get("/vendor/three/package.json").status_code == 404  # only build/ and examples/jsm


def test_all_jobs_event_stream(client, tiny_done):
    job_id, _ = tiny_done
    with client.stream("GET", "/api/events", timeout=30) as r:
        assert r.status_code == 200
        for line in r.iter_lines():
            if line.startswith("data:") and job_id in line:
                assert json.loads(line[5:])["state"] == "done"
                break


def test_deleting_a_running_job_stops_it_and_removes_its_folder(client, service):
    import time

    job_id = client.post("/api/jobs", json={"demo": True, "name": "to delete"}).json()["id"]
    wait_for(client, job_id, until=lambda j: j["state"] == "running" and j["progress"]["done"] >= 1)
    folder = service.data_dir / "jobs" / job_id
    assert client.delete(f"/api/jobs/{job_id}").status_code == 204
    assert client.get(f"/api/jobs/{job_id}").status_code == 404  # gone for the user at once
    assert job_id not in [j["id"] for j in client.get("/api/jobs").json()["jobs"]]
    deadline = time.monotonic() + 60
    while folder.exists() and time.monotonic() < deadline:  # removed once the worker has stopped
        time.sleep(0.2)
    assert not folder.exists()
