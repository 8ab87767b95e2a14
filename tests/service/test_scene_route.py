"""The 3D scene after a chosen CL: ``GET /api/jobs/{id}/scene?cl=N`` and ``scene.glb?cl=N`` on a real
service, and the replay cache behind them (:mod:`fusioncut.service.scene_cache`) in process."""
from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from service_helpers import KEY_B, TINY_GCODE, TINY_JOB, tiny_submission, tiny_total, wait_for

from fusioncut.service.files import INPUT_DIR, JOB_FILE
from fusioncut.service.scene_cache import SCENES_DIR, build_scene, scene_name, state_spacing, want_name
from fusioncut.viz.scene import glb_json
from shared_data import DATA


def _extras(glb: bytes) -> dict:
    return glb_json(glb)["scenes"][0]["extras"]["fusioncut"]


def _nodes(glb: bytes) -> set[str]:
    return {n.get("name") for n in glb_json(glb)["nodes"]}


@pytest.fixture
def job_folder(tmp_path):
    """A job folder as the service keeps it: the tiny job's input, no results needed."""
    (tmp_path / INPUT_DIR).mkdir()
    (tmp_path / INPUT_DIR / "tiny.nc").write_text(TINY_GCODE)
    (tmp_path / INPUT_DIR / JOB_FILE).write_text(json.dumps(TINY_JOB))
    return tmp_path


def test_replays_start_from_saved_states_and_give_the_same_workpiece(job_folder, tmp_path_factory):
    last = tiny_total() - 1
    # from scratch, in another folder: the reference
    fresh = tmp_path_factory.mktemp("fresh")
    (fresh / INPUT_DIR).mkdir()
    for name in ("tiny.nc", JOB_FILE):
        (fresh / INPUT_DIR / name).write_bytes((job_folder / INPUT_DIR / name).read_bytes())
    ref = build_scene(str(fresh), last)
    assert ref["state"] == "ready" and ref["from"] == 0 and ref["replayed"] == last + 1

    first = build_scene(str(job_folder), 5)
    assert first["state"] == "ready" and first["from"] == 0 and first["replayed"] == 6
    second = build_scene(str(job_folder), last)
    assert second["state"] == "ready"
    assert second["from"] == 6 and second["replayed"] == last + 1 - 6  # from the state saved after CL 5
    a = (fresh / SCENES_DIR / scene_name(last)).read_bytes()
    b = (job_folder / SCENES_DIR / scene_name(last)).read_bytes()
    assert _extras(a)["ipw_volume_mm3"] == pytest.approx(_extras(b)["ipw_volume_mm3"], abs=1e-9)
    early = _extras((job_folder / SCENES_DIR / scene_name(5)).read_bytes())
    # the workpiece after CL 5 still holds what the later CLs remove
    assert early["ipw_volume_mm3"] > _extras(b)["ipw_volume_mm3"] + 10.0
    assert early["cl_index"] == 5 and _extras(b)["cl_index"] == last
    assert early["source"].startswith("tiny.nc:") and str(job_folder) not in json.dumps(early)  # no server paths
    # asked again: the cached file, nothing replayed
    assert build_scene(str(job_folder), 5)["replayed"] == 0
    assert state_spacing(tiny_total()) == 100 and state_spacing(1_000_000) == 15_625


FUSION = DATA / "fusion-posted" / "1055_utab_265bit.nc"


def _utab_folder(folder: Path) -> Path:
    (folder / INPUT_DIR).mkdir(parents=True)
    (folder / INPUT_DIR / FUSION.name).symlink_to(FUSION)
    job = {"name": "utab", "stock": {"kind": "box", "min": [-5, -5, -13], "max": [60, 40, 0]},
           "tools": [{"number": 1, "kind": "flat", "diameter": 2.65, "flute_length": 12}],
           "toolpaths": [FUSION.name], "options": {"slice_height": 1.0, "max_segment_length": 1.0}}
    (folder / INPUT_DIR / JOB_FILE).write_text(json.dumps(job))
    return folder


@pytest.mark.skipif(not FUSION.exists(), reason="shared data not available")
def test_a_real_program_replayed_from_a_saved_state_equals_one_from_scratch(tmp_path):
    # a Fusion 360 post of a 2.65 mm flat end mill (~12,400 CLs; states every 195 CLs)
    cached, fresh = _utab_folder(tmp_path / "cached"), _utab_folder(tmp_path / "fresh")
    assert build_scene(str(cached), 240)["from"] == 0
    r = build_scene(str(cached), 252)
    assert r["state"] == "ready" and r["from"] == 241 and r["replayed"] == 12
    ref = build_scene(str(fresh), 252)
    assert ref["from"] == 0 and ref["triangles"] == r["triangles"]
    a = _extras((cached / SCENES_DIR / scene_name(252)).read_bytes())
    b = _extras((fresh / SCENES_DIR / scene_name(252)).read_bytes())
    for key in ("ipw_volume_mm3", "removed_volume_mm3", "contact_area_mm2", "ae_mm", "ap_mm"):
        assert a[key] == pytest.approx(b[key], abs=1e-9), key
    assert a["status"] == b["status"] and a["cl_index"] == 252
    # the GLB goes to the user: files named as the user named them, no server folders
    assert a["source"].startswith(f"{FUSION.name}:") and str(tmp_path) not in json.dumps(a)


def test_an_engaged_cl_has_contact_faces_and_lines(job_folder):
    r = build_scene(str(job_folder), 5)  # in the slot
    glb = (job_folder / SCENES_DIR / scene_name(5)).read_bytes()
    assert {"machine_frame", "ipw", "tool", "contact_faces", "entry_lines", "exit_lines"} <= _nodes(glb)
    assert _extras(glb)["status"] == "engaged"
    assert 0 < r["triangles"] < 10_000


def test_meshes_are_bounded(job_folder):
    r = build_scene(str(job_folder), 5, max_triangles=200)
    assert r["state"] == "ready" and r["triangles"] <= 200 and r["deflection_mm"] > 0.03
    r = build_scene(str(job_folder), 9, max_triangles=10)
    assert r["state"] == "failed" and "more than 10 triangles" in r["message"]
    assert not (job_folder / SCENES_DIR / scene_name(9)).exists()


def test_a_superseded_replay_stops(job_folder, monkeypatch):
    from fusioncut.engines.brep.engine import BRepEngine

    scenes = job_folder / SCENES_DIR
    scenes.mkdir()
    want = scenes / want_name(20)
    want.touch()  # as the route does before it submits the task
    process, seen = BRepEngine.process, []

    def superseded_after_cl_2(self, *args, **kwargs):
        for m in process(self, *args, **kwargs):
            seen.append(m.cl_index)
            if m.cl_index == 2:
                want.unlink()  # as the route does when another CL of the job is asked for
            yield m

    monkeypatch.setattr(BRepEngine, "process", superseded_after_cl_2)
    r = build_scene(str(job_folder), 20)
    assert r["state"] == "superseded" and seen == [0, 1, 2]
    assert not (scenes / scene_name(20)).exists()


def test_failed_cls_save_their_shapes_in_the_job_folder(job_folder, monkeypatch):
    # the engine's default is a folder in the working directory: a worker's, shared by every job
    from fusioncut.engines.brep.engine import BRepEngine

    init, folders = BRepEngine.__init__, []

    def recording(self, options=None, *args, **kwargs):
        folders.append(options.failure_dir)
        init(self, options, *args, **kwargs)

    monkeypatch.setattr(BRepEngine, "__init__", recording)
    assert build_scene(str(job_folder), 3)["state"] == "ready"
    assert folders and all(f is not None and f.is_relative_to(job_folder / SCENES_DIR) for f in folders)


def test_bad_cl_is_a_message_without_server_paths(job_folder):
    r = build_scene(str(job_folder), 999)
    assert r["state"] == "failed"
    assert r["message"].startswith("tiny.nc: CL 999 is out of range") and str(job_folder) not in r["message"]


# -- through the service -------------------------------------------------------------------------


def _scene(client, job_id: str, cl: int, timeout: float = 120) -> dict:
    deadline = time.monotonic() + timeout
    while True:
        r = client.get(f"/api/jobs/{job_id}/scene", params={"cl": cl})
        assert r.status_code in (200, 202), r.text
        body = r.json()
        assert (r.status_code == 202) == (body["state"] == "pending")
        if body["state"] != "pending":
            return body
        assert time.monotonic() < deadline, f"the scene of CL {cl} was not built in {timeout} s"
        time.sleep(0.3)


def test_scene_after_a_cl_through_the_api(client, service):
    r = client.post("/api/jobs", json=tiny_submission("scene"))
    assert r.status_code == 201, r.text
    job = wait_for(client, r.json()["id"])
    assert job["state"] == "done", job
    last = tiny_total() - 1
    early = _scene(client, job["id"], 5)
    assert early["state"] == "ready", early
    assert early["cl"] == 5 and early["done"] == last + 1 == early["total"]
    row = early["contact"]
    assert early["tool"]["position_mm"] == [row["x"], row["y"], row["z"]] and row["cl"] == 5
    assert early["tool"]["kind"] == "flat" and early["tool"]["diameter_mm"] == 6
    assert early["contact"]["status"] == "engaged" and early["slices"]
    glb_early = client.get(early["mesh"])
    assert glb_early.status_code == 200 and glb_early.headers["content-type"] == "model/gltf-binary"
    final = _scene(client, job["id"], last)
    glb_last = client.get(final["mesh"]).content
    assert _extras(glb_early.content)["ipw_volume_mm3"] > _extras(glb_last)["ipw_volume_mm3"] + 10.0
    assert _extras(glb_last)["cl_index"] == last

    assert client.get(f"/api/jobs/{job['id']}/scene", params={"cl": last + 1}).status_code == 404
    assert client.get(f"/api/jobs/{job['id']}/scene", params={"cl": -1}).status_code == 422
    assert client.get(f"/api/jobs/{job['id']}/scene.glb", params={"cl": 3}).status_code == 404  # not built
    with service.client(KEY_B) as other:
        assert other.get(f"/api/jobs/{job['id']}/scene", params={"cl": 5}).status_code == 404
        assert other.get(early["mesh"]).status_code == 404
    # without cl: the whole job, as before
    whole = client.get(f"/api/jobs/{job['id']}/scene").json()
    assert len(whole["cls"]["cl"]) == last + 1 and whole["stock"]["kind"] == "box"


def test_openapi_documents_the_scene_at_a_cl(client):
    spec = client.get("/openapi.json").json()
    params = spec["paths"]["/api/jobs/{job_id}/scene"]["get"]["parameters"]
    cl = next(p for p in params if p["name"] == "cl")
    assert cl["in"] == "query" and "after this CL" in cl["description"]
    assert "202" in spec["paths"]["/api/jobs/{job_id}/scene"]["get"]["responses"]
    assert "SceneAtCl" in spec["components"]["schemas"]
    assert "model/gltf-binary" in spec["paths"]["/api/jobs/{job_id}/scene.glb"]["get"]["responses"]["200"]["content"]


# -- the route's bookkeeping, with a stand-in cluster ----------------------------------------------


class _Future:
    def __init__(self):
        self.finished, self.value, self.error, self.cancelled = False, None, None, False

    def done(self):
        return self.finished

    def result(self):
        if self.error is not None:
            raise self.error
        return self.value

    def cancel(self):
        self.cancelled = True

    def finish(self, value=None, error=None):
        self.finished, self.value, self.error = True, value, error


class _Cluster:
    def __init__(self, folder):
        from types import SimpleNamespace

        self.folder = folder
        self.submitted: list[tuple[int, int, _Future]] = []  # (CL, priority, future)
        self.executor = SimpleNamespace(client=self)

    def submit(self, fn, job_dir, cl, max_triangles, *, key, pure, priority):
        assert fn is build_scene and job_dir == str(self.folder) and not pure
        fut = _Future()
        self.submitted.append((cl, priority, fut))
        return fut

    def job_dir(self, rec):
        return self.folder


def test_one_replay_per_job_the_latest_cl_wins(tmp_path):
    from types import SimpleNamespace

    from fusioncut.service.routes.scenes import SCENE_PRIORITY, SceneReplays

    cluster = _Cluster(tmp_path)
    routes, rec = SceneReplays(cluster), SimpleNamespace(id="j1")
    scenes = tmp_path / SCENES_DIR
    assert routes._mesh_state(rec, 5)[0] == "pending"
    assert routes._mesh_state(rec, 5)[0] == "pending"  # asked again: the same task
    assert [(c, p) for c, p, _ in cluster.submitted] == [(5, SCENE_PRIORITY)] and SCENE_PRIORITY > 0
    assert (scenes / want_name(5)).exists()
    # the slider moved on: the replay to CL 5 is told to stop, CL 9's starts
    assert routes._mesh_state(rec, 9)[0] == "pending"
    first, second = cluster.submitted[0][2], cluster.submitted[1][2]
    assert first.cancelled and not (scenes / want_name(5)).exists() and (scenes / want_name(9)).exists()
    # a worker's exception is answered once, then tried again
    second.finish(error=RuntimeError("worker died"))
    state, message = routes._mesh_state(rec, 9)
    assert state == "failed" and "RuntimeError" in message
    assert routes._mesh_state(rec, 9)[0] == "pending" and len(cluster.submitted) == 3
    # the job's own failure is remembered: no new task
    cluster.submitted[2][2].finish({"state": "failed", "cl": 9, "message": "tiny.nc: CL 9 is out of range"})
    assert routes._mesh_state(rec, 9) == ("failed", "tiny.nc: CL 9 is out of range")
    assert routes._mesh_state(rec, 9)[0] == "failed" and len(cluster.submitted) == 3
    # a scene in the cache is ready without a task
    (scenes / scene_name(12)).write_bytes(b"glTF")
    assert routes._mesh_state(rec, 12) == ("ready", "") and len(cluster.submitted) == 3
