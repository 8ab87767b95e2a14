"""The 3D view: ``GET /api/jobs/{id}/scene`` (the stock, the final workpiece's mesh and every CL
point), ``GET .../scene?cl=N`` (the scene after CL N) and ``GET .../scene.glb?cl=N``.

The answer with ``?cl=N`` describes the workpiece *after* CL N, the tool at N and its contact: the tool and the
CL's contact (its row of the ``cl`` table and its engaged arcs) come from the results at once; the
workpiece's mesh (a GLB with the nodes of :mod:`fusioncut.viz.scene`: ``ipw``, ``contact_faces``,
``tool``, entry/exit lines and engaged arcs, under ``machine_frame``) is built by a replay of the
job to N on a Dask worker of the service (:func:`fusioncut.service.scene_cache.build_scene`) and
cached in the job folder. While it is being built the answer is ``202`` with ``state: pending``:
ask again. A CL must be finished (in the results) to be shown, so a running job shows up to its
latest finished CL.

Bounds: one replay per job at a time (a request for another CL of the same job supersedes the one
in flight, which stops after its current CL); replays run before queued jobs (Dask priority) but
never stop a running job, so with every worker busy a scene waits for one; a replay is at most the
job's own length and starts from the engine states earlier replays saved (see
:mod:`fusioncut.service.scene_cache`); meshes are capped at ``max_triangles``.
"""
from __future__ import annotations

import itertools
import json
import logging
import threading
from collections import OrderedDict
from typing import Any, Literal

from fastapi import APIRouter, Depends, HTTPException, Query, Request
from fastapi.responses import FileResponse, JSONResponse
from pydantic import BaseModel, Field

from fusioncut.errors import FusionCutError
from fusioncut.service.files import result_files
from fusioncut.service.models import Scene, json_safe
from fusioncut.service.routes.access import PROBLEMS, Api, api, owner
from fusioncut.service.scene_cache import DEFAULT_MAX_TRIANGLES, SCENES_DIR, build_scene, scene_name, want_name
from fusioncut.service.submit import SCENE_FILE

log = logging.getLogger("fusioncut.service")

router = APIRouter(tags=["results"])

SCENE_PRIORITY = 10  # above the jobs' default 0: a scene waits for a free worker, not for the queue
GLB_MEDIA_TYPE = "model/gltf-binary"
CL_QUERY = Query(None, ge=0, description=(
    "CL index: describe the workpiece after this CL, the tool at it and its contact (the CL must be "
    "finished). Without it: the stock, the final workpiece's mesh and every CL point."))


class SceneAtCl(BaseModel):
    """The 3D view after one CL. ``mesh`` is the address of the GLB once ``state`` is ``ready``."""

    cl: int = Field(description="CL index")
    state: Literal["ready", "pending", "failed"] = Field(
        description="ready: mesh is the GLB; pending: a worker is replaying the job to this CL (ask again); "
                    "failed: message says why")
    message: str = ""
    mesh: str | None = Field(None, description="address of the scene as glTF binary (nodes ipw, contact_faces, "
                                               "tool, entry_lines, exit_lines, engaged_arcs under machine_frame)")
    done: int = Field(description="CLs finished so far; the latest finished CL is done - 1")
    total: int = Field(description="CL segments of the job")
    tool: dict[str, Any] = Field(description="label, kind, diameter_mm, flute_length_mm and the tip's "
                                             "position_mm (machine frame) at the CL")
    contact: dict[str, Any] = Field(description="the CL's row of the cl table (status, ae_mm, ap_mm, "
                                                "removed_volume_mm3, contact_area_mm2, ...)")
    slices: list[dict[str, Any]] = Field(description="its engaged arcs (rows of the slices table)")


SCENE_RESPONSES: dict[int | str, dict[str, Any]] = {
    202: {"model": SceneAtCl, "description": "with ?cl=: the workpiece's mesh is being built; ask again"},
    422: {"description": "cl is not a CL index"},
}


class SceneReplays:
    """The scene replays of one application (``app.state.scenes``): in flight by job, failures remembered."""

    def __init__(self, service: Any, max_triangles: int = DEFAULT_MAX_TRIANGLES):
        self.service = service
        self.max_triangles = max_triangles
        self.in_flight: dict[str, tuple[int, Any]] = {}  # job id -> (CL, Dask future)
        self.failed: OrderedDict[tuple[str, int], str] = OrderedDict()
        self.lock = threading.Lock()
        self.counter = itertools.count()

    def at_cl(self, rec: Any, res: Any, cl: int) -> JSONResponse:
        try:
            row = res.row(cl)
        except FusionCutError:
            p = self.service.progress(rec)
            raise HTTPException(404, f"CL {cl} is not finished: job {rec.id} has {p.done} of {p.total} CLs done"
                                ) from None
        state, message = self._mesh_state(rec, cl)
        p = self.service.progress(rec)
        done = max(p.done, int(res.cl["cl"].max()) + 1)
        row_d = {k: json_safe(v) for k, v in row.astype(object).to_dict().items()}
        spec = (res.metadata.get("tools") or {}).get(row_d.get("tool"), {})
        tool = {"label": row_d.get("tool"), **spec, "position_mm": [row_d["x"], row_d["y"], row_d["z"]]}
        slices = [{k: json_safe(v) for k, v in r.items()}
                  for r in res.slices_of(cl).astype(object).to_dict(orient="records")]
        body = SceneAtCl(cl=cl, state=state, message=message,
                         mesh=f"/api/jobs/{rec.id}/scene.glb?cl={cl}" if state == "ready" else None,
                         done=done, total=max(p.total, done), tool=tool, contact=row_d, slices=slices)
        return JSONResponse(status_code=202 if state == "pending" else 200, content=body.model_dump())

    def _mesh_state(self, rec: Any, cl: int) -> tuple[str, str]:
        scenes = self.service.job_dir(rec) / SCENES_DIR
        if (scenes / scene_name(cl)).is_file():
            return "ready", ""
        with self.lock:
            if (rec.id, cl) in self.failed:
                return "failed", self.failed[(rec.id, cl)]
            running = self.in_flight.get(rec.id)
            if running is not None and running[0] == cl:
                fut = running[1]
                if not fut.done():
                    return "pending", "the workpiece after this CL is being computed"
                del self.in_flight[rec.id]
                outcome = self._outcome(rec, cl, fut)
                if outcome is not None:
                    return outcome
            elif running is not None:  # the view moved on: stop the replay to the other CL
                (scenes / want_name(running[0])).unlink(missing_ok=True)
                self._cancel(running[1])
                del self.in_flight[rec.id]
            if (scenes / scene_name(cl)).is_file():
                return "ready", ""
            self._submit(rec, cl, scenes)
        return "pending", "the workpiece after this CL is being computed"

    def _outcome(self, rec: Any, cl: int, fut: Any) -> tuple[str, str] | None:
        """What a finished task says; None to submit it again (it was superseded, then asked for). The
        job's own failures (its input, its geometry, a mesh too large) are remembered; a worker's
        exception is not, so the next request tries again."""
        try:
            result = fut.result()
        except Exception as exc:  # noqa: BLE001 - a worker's problem: logged, answered once, asked again next time
            log.error("scene of job %s at CL %d failed", rec.id, cl, exc_info=exc)
            return "failed", f"internal error building the scene ({type(exc).__name__}); see the service log"
        if result.get("state") == "ready":
            log.info("scene of job %s at CL %d: %s", rec.id, cl, result)
            return "ready", ""
        if result.get("state") == "failed":
            self.failed[(rec.id, cl)] = str(result.get("message", "failed"))
            while len(self.failed) > 256:
                self.failed.popitem(last=False)
            return "failed", self.failed[(rec.id, cl)]
        return None

    def _submit(self, rec: Any, cl: int, scenes: Any) -> None:
        client = self.service.executor.client
        if client is None:
            raise HTTPException(503, "the Dask cluster is not available")
        scenes.mkdir(parents=True, exist_ok=True)
        (scenes / want_name(cl)).touch()
        try:
            fut = client.submit(build_scene, str(self.service.job_dir(rec)), cl, self.max_triangles,
                                key=f"fusioncut-scene-{rec.id}-{cl}-{next(self.counter)}", pure=False,
                                priority=SCENE_PRIORITY)
        except Exception as exc:  # noqa: BLE001 - scheduler gone, connection closed, ...
            log.error("cannot submit the scene of job %s at CL %d", rec.id, cl, exc_info=exc)
            raise HTTPException(503, "the Dask cluster did not take the scene; try again later") from None
        self.in_flight[rec.id] = (cl, fut)

    def _cancel(self, fut: Any) -> None:
        try:
            fut.cancel()
        except Exception:  # noqa: BLE001 - already gone
            log.debug("cancelling a scene task", exc_info=True)

    def glb(self, rec: Any, cl: int) -> FileResponse:
        path = self.service.job_dir(rec) / SCENES_DIR / scene_name(cl)
        if not path.is_file():
            raise HTTPException(404, f"the scene of CL {cl} is not built: ask /api/jobs/{rec.id}/scene?cl={cl} first")
        return FileResponse(path, media_type=GLB_MEDIA_TYPE, headers={"Cache-Control": "private, max-age=3600"})


def scene_replays(request: Request) -> SceneReplays:
    return request.app.state.scenes


@router.get("/api/jobs/{job_id}/scene.glb", response_class=FileResponse,
            responses={**PROBLEMS, 200: {"content": {GLB_MEDIA_TYPE: {}},
                                         "description": "the scene after the CL, glTF binary"}})
def scene_glb(job_id: str, cl: int = Query(..., ge=0, description="CL index"), who: str = Depends(owner),
              a: Api = Depends(api), scenes: SceneReplays = Depends(scene_replays)) -> FileResponse:
    """The scene after CL `cl` as glTF binary, once `/scene?cl=` says `ready` (mm in the
    `machine_frame` node's children; that node scales to glTF's metres, Y up)."""
    return scenes.glb(a.job(job_id, who), cl)


@router.get("/api/jobs/{job_id}/scene", response_model=Scene | SceneAtCl,
            responses={**PROBLEMS, **SCENE_RESPONSES})
def scene(job_id: str, cl: int | None = CL_QUERY, who: str = Depends(owner), a: Api = Depends(api),
          scenes: SceneReplays = Depends(scene_replays)) -> Any:
    """Data for the 3D view: stock outline, IPW mesh file (if any), tools, CL points; with `?cl=N`
    the workpiece after CL N (a GLB, replayed on a worker and cached), the tool at N and its contact."""
    rec = a.job(job_id, who)
    res = a.results(rec)
    if cl is not None:
        return scenes.at_cl(rec, res, cl)
    stock = res.metadata.get("stock") if isinstance(res.metadata.get("stock"), dict) else None
    if stock is None:
        try:
            stock = json.loads((a.service.job_dir(rec) / SCENE_FILE).read_text(encoding="utf-8")).get("stock")
        except (OSError, ValueError):
            stock = None
    names = {f.name for f in result_files(a.service.results_dir(rec))}
    cols = {c: [json_safe(v) for v in res.cl[c].astype(object).tolist()]
            for c in ("cl", "x", "y", "z", "tool", "status", "operation")}
    return Scene(stock=stock, ipw="ipw.stl" if "ipw.stl" in names else None,
                 tools=res.metadata.get("tools", {}), cls=cols)
