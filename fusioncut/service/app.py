"""The HTTP API and the front end: ``create_app(settings)`` gives the FastAPI application.

Every ``/api`` route needs an ``X-API-Key`` header; a key sees only the jobs it submitted, and a job
of another key answers 404 exactly like one that does not exist (so ids cannot be probed). Errors
are JSON ``{"detail": "..."}`` with a 4xx status and one line of text; nothing answers with a
traceback. The front end (``frontend/``: plain ES modules and three.js through an import map) is
served by the same application at ``/``.
"""
from __future__ import annotations

import asyncio
import io
import json
import logging
import os
import shutil
import threading
import time
from collections import OrderedDict
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from fastapi import Depends, FastAPI, HTTPException, Query, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse, Response, StreamingResponse
from fastapi.security import APIKeyHeader
from fastapi.staticfiles import StaticFiles
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import UploadFile

from fusioncut import __version__
from fusioncut.errors import FusionCutError
from fusioncut.io.job import Job
from fusioncut.service.core import ClusterUnavailable, Service
from fusioncut.service.demo import DEMO_FILE, demo_gcode, demo_job
from fusioncut.service.files import check_name, find_result_file, result_files
from fusioncut.service.models import (ClDetail, FileInfo, FileList, JobList, JobStatus, Problem, ProgressInfo,
                                      Scene, ServiceInfo, SummaryTable, json_safe)
from fusioncut.service.scene_route import CL_QUERY, SCENE_RESPONSES, SceneAtCl, SceneRoutes
from fusioncut.service.settings import Settings, key_hash
from fusioncut.service.store import FINAL_STATES, JobRecord
from fusioncut.service.worker import portable
from fusioncut.service.submit import (MULTIPART_SCHEMA, SCENE_FILE, JobSubmission, SubmissionError, build_job_from_form,
                                      check_job, discard, parse_json_body, stage_folder, write_text_files)

log = logging.getLogger("fusioncut.service")

# -------------------------------------------------------------------------------------------------
# request body limit


class BodyTooLarge(Exception):
    pass


class BodyLimit:
    """Refuse request bodies over ``limit`` bytes with 413: at once when Content-Length says so, and
    while reading when the body is streamed without one (the form parser would spool it all first)."""

    def __init__(self, app: Any, limit: int):
        self.app = app
        self.limit = limit

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] != "http" or scope["method"] not in ("POST", "PUT", "PATCH"):
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        length = headers.get(b"content-length")
        if length is not None and length.isdigit() and int(length) > self.limit:
            await _send_problem(send, 413, self._message())
            return
        received = 0
        started = False

        async def limited_receive() -> dict:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.limit:
                    raise BodyTooLarge()
            return message

        async def tracking_send(message: dict) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, limited_receive, tracking_send)
        except BodyTooLarge:
            if not started:
                await _send_problem(send, 413, self._message())

    def _message(self) -> str:
        return f"request body larger than the limit of {self.limit / 1024 / 1024:.1f} MiB"


async def _send_problem(send: Any, status: int, detail: str) -> None:
    body = json.dumps({"detail": detail}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})


# -------------------------------------------------------------------------------------------------
# helpers


def _records(df: Any) -> list[dict[str, Any]]:
    return [{k: json_safe(v) for k, v in row.items()} for row in df.astype(object).to_dict(orient="records")]


PROBLEMS: dict[int | str, dict[str, Any]] = {
    401: {"model": Problem, "description": "no or unknown X-API-Key"},
    404: {"model": Problem, "description": "no such job for this key"},
}


def create_app(settings: Settings | None = None, service: Service | None = None) -> FastAPI:
    settings = settings or Settings.from_env()
    service = service or Service(settings)
    results_cache: OrderedDict[str, tuple[tuple, Any]] = OrderedDict()
    cache_lock = threading.Lock()
    plot_lock = threading.Semaphore(2)  # matplotlib renders are CPU-heavy; keep the API responsive
    # Reading a submission's toolpaths is CPU work too (a G-code loop can expand to millions of
    # blocks): a few at a time, so that a burst of uploads cannot take every request thread.
    check_lock = threading.Semaphore(4)

    def _checked(job: Job, staged: Path) -> Any:
        with check_lock:
            return check_job(job, staged, settings.budget)

    @asynccontextmanager
    async def lifespan(app: FastAPI):  # type: ignore[no-untyped-def]
        await run_in_threadpool(service.start)  # nothing to do when `fusioncut serve` started it
        try:
            yield
        finally:
            await run_in_threadpool(service.stop)

    # FastAPI's own /docs pages load Swagger UI from a CDN; ours serves it from the front end's npm
    # packages (no network needed at run time) and ReDoc is left out.
    app = FastAPI(
        title="FusionCut service", version=__version__, lifespan=lifespan, docs_url=None, redoc_url=None,
        description=(
            "Cutter-workpiece engagement jobs on a Dask cluster. Submit a job (JSON with inline files, "
            "or a multipart upload), follow its progress (polling or server-sent events), download its "
            "result tables, plots and meshes. Every /api route needs the `X-API-Key` header; each key "
            "sees only its own jobs."),
    )
    app.state.service = service
    app.add_middleware(BodyLimit, limit=settings.max_upload_bytes)
    api_key = APIKeyHeader(name="X-API-Key", auto_error=False, description="an API key configured on the service")

    # -- errors ---------------------------------------------------------------------------------
    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        first = exc.errors()[0] if exc.errors() else {"loc": (), "msg": "invalid request"}
        loc = ".".join(str(p) for p in first.get("loc", ()))
        return JSONResponse(status_code=422, content={"detail": f"{loc}: {first.get('msg')}"})

    @app.exception_handler(Exception)
    async def _internal(request: Request, exc: Exception) -> JSONResponse:
        log.error("internal error on %s %s", request.method, request.url.path, exc_info=exc)
        return JSONResponse(status_code=500, content={"detail": "internal server error (details are in the service log)"})

    # -- auth and lookup ------------------------------------------------------------------------
    def owner(key: str | None = Depends(api_key)) -> str:
        if not key:
            raise HTTPException(401, "missing X-API-Key header")
        h = key_hash(key)
        if h not in service.key_hashes:
            raise HTTPException(401, "unknown API key")
        return h

    def lookup(job_id: str, who: str) -> JobRecord:
        assert service.store is not None
        rec = service.store.get(job_id, owner=who)
        if rec is None:
            raise HTTPException(404, f"no job {job_id!r}")
        return rec

    def status_of(rec: JobRecord) -> JobStatus:
        p = service.progress(rec)
        base = f"/api/jobs/{rec.id}"
        return JobStatus(id=rec.id, name=rec.name, state=rec.state, created_at=rec.created_at,  # type: ignore[arg-type]
                         started_at=rec.started_at, finished_at=rec.finished_at, message=rec.message,
                         progress=ProgressInfo(**p.__dict__),
                         links={"self": base, "events": f"{base}/events", "files": f"{base}/files",
                                "cancel": f"{base}/cancel", "scene": f"{base}/scene"})

    # -- service --------------------------------------------------------------------------------
    @app.get("/api/info", response_model=ServiceInfo, tags=["service"], responses=PROBLEMS)
    def info(who: str = Depends(owner)) -> ServiceInfo:
        """Version, Dask scheduler and limits of this service."""
        return ServiceInfo(version=__version__, scheduler=service.executor.address,
                           embedded_cluster=service.executor.cluster is not None,
                           max_upload_bytes=settings.max_upload_bytes, max_cls=settings.max_cls,
                           max_slices=settings.max_slices)

    # -- jobs -----------------------------------------------------------------------------------
    @app.post(
        "/api/jobs", status_code=201, response_model=JobStatus, tags=["jobs"],
        responses={**PROBLEMS, 413: {"model": Problem, "description": "upload too large"},
                   415: {"model": Problem, "description": "neither JSON nor a multipart form"},
                   503: {"model": Problem, "description": "the Dask cluster cannot take jobs now"},
                   422: {"model": Problem, "description": "the job or an input file is invalid; "
                                                          "the message names the file:line:column or field"}},
        openapi_extra={"requestBody": {"required": True, "content": {
            "application/json": {"schema": {"$ref": "#/components/schemas/JobSubmission"}},
            "multipart/form-data": {"schema": MULTIPART_SCHEMA}}}},
    )
    async def submit(request: Request, who: str = Depends(owner)) -> JSONResponse:
        """Submit a job: JSON (`JobSubmission`: the demo, or a job with its files inline) or a
        multipart upload of toolpath files, tool library and STEP stock with job options. The job is
        checked before it is queued: every file is read once with FusionCut's readers."""
        ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
        job_id = service.new_job_id()
        staged = stage_folder(service.jobs_dir, job_id)
        try:
            if ctype == "application/json":
                job = await _from_json(request, staged)
            elif ctype == "multipart/form-data":
                job = await _from_form(request, staged)
            else:
                raise SubmissionError(415, "send the job as application/json or multipart/form-data")
            checked = await run_in_threadpool(_checked, job, staged)
            rec = await run_in_threadpool(service.create, who, job.name, staged, checked, job_id)
        except SubmissionError as exc:
            discard(staged)
            raise HTTPException(exc.status, exc.message) from None
        except ClusterUnavailable as exc:
            discard(staged)
            raise HTTPException(503, str(exc)) from None
        except BaseException:  # BodyTooLarge (answered 413 by BodyLimit), a dropped client, a bug
            discard(staged)
            raise
        return JSONResponse(status_code=201, content=status_of(rec).model_dump(),
                            headers={"Location": f"/api/jobs/{rec.id}"})

    async def _from_json(request: Request, staged: Path) -> Job:
        sub = parse_json_body(await request.body())
        if sub.demo:
            if sub.job is not None or sub.files:
                raise SubmissionError(422, "demo: the demo job takes no job or files")
            job = Job.model_validate(demo_job(sub.name or "demo"))
            write_text_files({DEMO_FILE: demo_gcode()}, staged)
            return job
        if sub.job is None:
            raise SubmissionError(422, 'job: give a job with its files, or {"demo": true}')
        write_text_files(sub.files, staged)
        return sub.job.model_copy(update={"name": sub.name}) if sub.name else sub.job

    async def _from_form(request: Request, staged: Path) -> Job:
        form = await request.form(max_files=settings.max_files, max_fields=64, max_part_size=1024 * 1024)
        uploads: dict[str, list[str]] = {}
        fields: dict[str, str] = {}
        try:
            for key, value in form.multi_items():
                if isinstance(value, UploadFile):
                    if key not in ("toolpath", "toolpaths", "tool_library", "stock"):
                        raise SubmissionError(422, f"unexpected file field {key!r} (toolpath, tool_library, stock)")
                    try:
                        name = check_name(value.filename or "", f"{key}: file name")
                    except FusionCutError as exc:
                        raise SubmissionError(422, str(exc)) from None
                    if (staged / name).exists():
                        raise SubmissionError(422, f"{key}: two files named {name!r}")
                    await run_in_threadpool(_save_upload, value, staged / name)
                    uploads.setdefault("toolpath" if key == "toolpaths" else key, []).append(name)
                else:
                    fields[key] = str(value)
        finally:
            await form.close()
        if fields.get("demo", "").lower() in ("1", "true", "on", "yes"):
            if uploads:
                raise SubmissionError(422, "demo: the demo job takes no uploaded files")
            write_text_files({DEMO_FILE: demo_gcode()}, staged)
            return Job.model_validate(demo_job(fields.get("name") or "demo"))
        return build_job_from_form(fields.get("job"), uploads, fields)

    @app.get("/api/jobs", response_model=JobList, tags=["jobs"], responses=PROBLEMS)
    def list_jobs(who: str = Depends(owner)) -> JobList:
        """The jobs of this key, newest first."""
        assert service.store is not None
        return JobList(jobs=[status_of(r) for r in service.store.list(owner=who)])

    @app.get("/api/jobs/{job_id}", response_model=JobStatus, tags=["jobs"], responses=PROBLEMS)
    def get_job(job_id: str, who: str = Depends(owner)) -> JobStatus:
        """State and progress (CLs done / total, ETA) of one job."""
        return status_of(lookup(job_id, who))

    @app.post("/api/jobs/{job_id}/cancel", response_model=JobStatus, status_code=202, tags=["jobs"],
              responses={**PROBLEMS, 409: {"model": Problem, "description": "the job has already finished"}})
    def cancel_job(job_id: str, who: str = Depends(owner)) -> JobStatus:
        """Stop a queued or running job; the results of the CLs finished so far are kept. The state
        becomes `cancelled` as soon as the worker has stopped (within one CL)."""
        rec = lookup(job_id, who)
        if rec.state in ("done", "failed"):
            raise HTTPException(409, f"job {job_id} has already finished ({rec.state})")
        service.cancel(rec)
        return status_of(lookup(job_id, who))

    @app.delete("/api/jobs/{job_id}", status_code=204, tags=["jobs"], responses=PROBLEMS)
    def delete_job(job_id: str, who: str = Depends(owner)) -> Response:
        """Delete a job and its files (a running job is cancelled first)."""
        service.delete(lookup(job_id, who))
        return Response(status_code=204)

    # -- events ---------------------------------------------------------------------------------
    def _sse(event: str, data: Any) -> str:
        return f"event: {event}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n"

    # Event streams: at most settings.max_streams_per_key open per key (429 beyond), and one
    # snapshot of a key's job states per poll interval shared by all its streams, so that the cost
    # grows with the keys and jobs, not with the connections (200 streams on 28 jobs used to read
    # every job's progress 800 times a second on the event loop, and /api/info took 1.5 s).
    open_streams: dict[str, int] = {}
    snapshots: dict[str, tuple[float, dict[str, tuple[str, dict[str, Any]]]]] = {}
    stream_lock = threading.Lock()

    def key_snapshot(who: str) -> dict[str, tuple[str, dict[str, Any]]]:
        """id -> (state, JobStatus as a dict) of the key's jobs, newest first; at most one poll
        interval old."""
        now = time.monotonic()
        with stream_lock:
            hit = snapshots.get(who)
            if hit is not None and now - hit[0] < 0.9 * settings.poll_interval_s:
                return hit[1]
        recs = service.store.list(owner=who) if service.store else []
        snap = {r.id: (r.state, status_of(r).model_dump()) for r in recs}
        with stream_lock:
            snapshots[who] = (now, snap)
        return snap

    def _event_stream(request: Request, poll, who: str) -> StreamingResponse:  # type: ignore[no-untyped-def]
        """An SSE response that calls ``poll()`` -> (events, finished) every poll interval, with a
        comment line after 15 s without events so that proxies keep the connection open."""
        if open_streams.get(who, 0) >= settings.max_streams_per_key:
            raise HTTPException(429, f"this key has {settings.max_streams_per_key} event streams open already; "
                                     "close one (GET /api/events follows every job of the key in one stream)")

        async def stream():  # type: ignore[no-untyped-def]
            with stream_lock:
                over = open_streams.get(who, 0) >= settings.max_streams_per_key
                if not over:
                    open_streams[who] = open_streams.get(who, 0) + 1
            if over:  # several opened at once: the check above let them all through
                yield _sse("error", {"detail": "too many event streams for this key"})
                return
            try:
                yield "retry: 2000\n\n"
                idle = 0.0
                while not service.stopping:
                    events, finished = poll()
                    for event in events:
                        yield event
                    if events:
                        idle = 0.0
                    if finished:
                        return
                    if idle >= 15:
                        yield ": keep-alive\n\n"
                        idle = 0.0
                    if await request.is_disconnected():
                        return
                    await asyncio.sleep(settings.poll_interval_s)
                    idle += settings.poll_interval_s
            finally:
                with stream_lock:
                    open_streams[who] -= 1

        return StreamingResponse(stream(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})

    @app.get("/api/jobs/{job_id}/events", tags=["jobs"], responses={
        **PROBLEMS, 429: {"model": Problem, "description": "too many event streams open for this key"},
        200: {"content": {"text/event-stream": {}},
              "description": "`status` events (a JobStatus as JSON) whenever it changes, then `end`"}})
    async def job_events(job_id: str, request: Request, who: str = Depends(owner)) -> StreamingResponse:
        """Server-sent events with live progress of one job; the stream ends when the job does."""
        lookup(job_id, who)
        last: list[Any] = [None]

        def poll() -> tuple[list[str], bool]:
            hit = key_snapshot(who).get(job_id)
            if hit is None:  # not in the shared snapshot: deleted, or newer than the snapshot
                rec = service.store.get(job_id, owner=who) if service.store else None
                if rec is None:
                    return [_sse("deleted", {"id": job_id})], True
                hit = (rec.state, status_of(rec).model_dump())
            state, now = hit
            events = []
            if now != last[0]:
                events.append(_sse("status", now))
                last[0] = now
            if state in FINAL_STATES:
                return events + [_sse("end", {"id": job_id, "state": state})], True
            return events, False

        return _event_stream(request, poll, who)

    @app.get("/api/events", tags=["jobs"], responses={
        **PROBLEMS, 429: {"model": Problem, "description": "too many event streams open for this key"},
        200: {"content": {"text/event-stream": {}},
              "description": "`job` events (JobStatus) for every job of the key that changes, "
                             "`deleted` events ({id}) for jobs that went away"}})
    async def all_events(request: Request, who: str = Depends(owner)) -> StreamingResponse:
        """Server-sent events for all jobs of this key (one connection for the whole job list)."""
        last: dict[str, Any] = {}

        def poll() -> tuple[list[str], bool]:
            events = []
            snap = key_snapshot(who)
            for job_id, (_, now) in snap.items():
                if last.get(job_id) != now:
                    last[job_id] = now
                    events.append(_sse("job", now))
            for gone in set(last) - set(snap):
                del last[gone]
                events.append(_sse("deleted", {"id": gone}))
            return events, False

        return _event_stream(request, poll, who)

    # -- results --------------------------------------------------------------------------------
    @app.get("/api/jobs/{job_id}/files", response_model=FileList, tags=["results"], responses=PROBLEMS)
    def list_files(job_id: str, who: str = Depends(owner)) -> FileList:
        """Result files so far: cl/slices tables (CSV, Parquet), summary.csv, metadata.json, plots
        (PNG), the IPW mesh and STEP/STL/GLB exports when written, and the run log."""
        rec = lookup(job_id, who)
        return FileList(files=[FileInfo(name=f.name, size=f.size, media_type=f.media_type,
                                        url=f"/api/jobs/{job_id}/files/{f.name}")
                               for f in result_files(service.results_dir(rec))])

    @app.get("/api/jobs/{job_id}/files/{name}", tags=["results"], response_class=StreamingResponse,
             responses={**PROBLEMS, 422: {"model": Problem, "description": "not a plain file name"}})
    def get_file(job_id: str, name: str, who: str = Depends(owner)) -> StreamingResponse:
        """Download one result file (names as listed by /files)."""
        rec = lookup(job_id, who)
        try:
            f = find_result_file(service.results_dir(rec), name)
        except FusionCutError as exc:
            raise HTTPException(422, str(exc)) from None
        if f is None:
            raise HTTPException(404, f"job {job_id} has no file {name!r}")
        return _file_response(service.results_dir(rec) / f.name, f.media_type, f.name)

    def results_of(rec: JobRecord) -> Any:
        from fusioncut.io.results import load_results

        d = service.results_dir(rec)
        stamp = tuple((p.name, p.stat().st_mtime_ns) for p in sorted(d.glob("*.parquet"))) if d.is_dir() else ()
        with cache_lock:
            hit = results_cache.get(rec.id)
            if hit is not None and hit[0] == stamp:
                results_cache.move_to_end(rec.id)
                return hit[1]
        try:
            res = portable(load_results(d))
        except FusionCutError:
            raise HTTPException(404, f"job {rec.id} has no results yet") from None
        with cache_lock:
            results_cache[rec.id] = (stamp, res)
            while len(results_cache) > 8:
                results_cache.popitem(last=False)
        return res

    @app.get("/api/jobs/{job_id}/summary", response_model=SummaryTable, tags=["results"], responses=PROBLEMS)
    def summary(job_id: str, who: str = Depends(owner)) -> SummaryTable:
        """The per-operation summary (summary.csv) as JSON rows."""
        return SummaryTable(rows=_records(results_of(lookup(job_id, who)).summary))

    scenes = SceneRoutes(service)  # ?cl= and scene.glb: fusioncut/service/scene_route.py
    scenes.register(app, owner, lookup, PROBLEMS)

    @app.get("/api/jobs/{job_id}/scene", response_model=Scene | SceneAtCl, tags=["results"],
             responses={**PROBLEMS, **SCENE_RESPONSES})
    def scene(job_id: str, cl: int | None = CL_QUERY, who: str = Depends(owner)) -> Any:
        """Data for the 3D view: stock outline, IPW mesh file (if any), tools, CL points; with `?cl=N`
        the workpiece after CL N (a GLB, replayed on a worker and cached), the tool at N and its contact."""
        rec = lookup(job_id, who)
        res = results_of(rec)
        if cl is not None:
            return scenes.at_cl(rec, res, cl)
        stock = res.metadata.get("stock") if isinstance(res.metadata.get("stock"), dict) else None
        if stock is None:
            try:
                stock = json.loads((service.job_dir(rec) / SCENE_FILE).read_text(encoding="utf-8")).get("stock")
            except (OSError, ValueError):
                stock = None
        names = {f.name for f in result_files(service.results_dir(rec))}
        cl = res.cl
        cols = {c: [json_safe(v) for v in cl[c].astype(object).tolist()]
                for c in ("cl", "x", "y", "z", "tool", "status", "operation")}
        return Scene(stock=stock, ipw="ipw.stl" if "ipw.stl" in names else None,
                     tools=res.metadata.get("tools", {}), cls=cols)

    @app.get("/api/jobs/{job_id}/cls/{cl}", response_model=ClDetail, tags=["results"], responses=PROBLEMS)
    def cl_detail(job_id: str, cl: int, who: str = Depends(owner)) -> ClDetail:
        """One CL: its row of the cl table and its engaged arcs (machine angles at z_machine_mm)."""
        res = results_of(lookup(job_id, who))
        try:
            row = res.row(cl)
        except FusionCutError as exc:
            raise HTTPException(404, str(exc)) from None
        return ClDetail(cl={k: json_safe(v) for k, v in row.astype(object).to_dict().items()},
                        slices=_records(res.slices_of(cl)))

    @app.get("/api/jobs/{job_id}/plots/{kind}", tags=["results"], response_class=Response,
             responses={**PROBLEMS, 200: {"content": {"image/png": {}}}})
    def plot(job_id: str, kind: str, cl: int | None = Query(None, description="CL index (map, polar)"),
             who: str = Depends(owner)) -> Response:
        """A PNG plot drawn by fusioncut.viz.plots: `program` or `heatmap` of the whole job, `map`
        (engagement map) or `polar` (top view) of one CL."""
        rec = lookup(job_id, who)
        if kind not in ("program", "heatmap", "map", "polar"):
            raise HTTPException(404, f"no plot kind {kind!r} (program, heatmap, map, polar)")
        if kind in ("program", "heatmap") and rec.state in FINAL_STATES:
            f = service.results_dir(rec) / f"{kind}.png"
            if f.is_file():
                return FileResponse(f, media_type="image/png")
        if kind in ("map", "polar") and cl is None:
            raise HTTPException(422, f"the {kind} plot needs ?cl=<CL index>")
        res = results_of(rec)
        if not len(res.cl):
            raise HTTPException(404, f"job {job_id} has no results yet")
        from fusioncut.viz import plots

        with plot_lock:
            try:
                fig = plots.PLOTS[kind](res, cl) if cl is not None and kind in ("map", "polar") else plots.PLOTS[kind](res)
            except FusionCutError as exc:
                raise HTTPException(404, str(exc)) from None
            buf = io.BytesIO()
            fig.savefig(buf, format="png", dpi=fig.dpi)
        return Response(buf.getvalue(), media_type="image/png", headers={"Cache-Control": "no-store"})

    def openapi() -> dict[str, Any]:
        """FastAPI's document plus the JSON submission model, which the submit route parses itself
        (it takes JSON or a multipart form, so it cannot declare a typed body parameter)."""
        if app.openapi_schema is None:
            from fastapi.openapi.utils import get_openapi

            spec = get_openapi(title=app.title, version=app.version, description=app.description, routes=app.routes)
            schema = JobSubmission.model_json_schema(ref_template="#/components/schemas/{model}")
            components = spec.setdefault("components", {}).setdefault("schemas", {})
            for name, sub in schema.pop("$defs", {}).items():
                components.setdefault(name, sub)
            components["JobSubmission"] = schema
            app.openapi_schema = spec
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]

    # -- front end --------------------------------------------------------------------------------
    front = settings.frontend_dir
    three = front / "node_modules" / "three"
    if (three / "build").is_dir():
        app.mount("/vendor/three/build", StaticFiles(directory=three / "build"), name="three-build")
        app.mount("/vendor/three/examples/jsm", StaticFiles(directory=three / "examples" / "jsm"), name="three-addons")
    else:
        log.warning("three.js not found in %s: run `npm ci` in %s for the 3D view", three, front)
    if (front / "src").is_dir():
        app.mount("/src", StaticFiles(directory=front / "src"), name="frontend-src")

    @app.get("/", include_in_schema=False)
    def index() -> Response:
        page = front / "index.html"
        if not page.is_file():
            return Response("FusionCut service: the front end is not installed (see docs/deploy.md).",
                            media_type="text/plain")
        return FileResponse(page, media_type="text/html", headers={"Cache-Control": "no-cache"})

    swagger = front / "node_modules" / "swagger-ui-dist"
    if (swagger / "swagger-ui-bundle.js").is_file():
        app.mount("/vendor/swagger-ui", StaticFiles(directory=swagger), name="swagger-ui")

        @app.get("/docs", include_in_schema=False)
        def docs() -> Response:
            from fastapi.openapi.docs import get_swagger_ui_html

            return get_swagger_ui_html(openapi_url="/openapi.json", title="FusionCut service API",
                                       swagger_js_url="/vendor/swagger-ui/swagger-ui-bundle.js",
                                       swagger_css_url="/vendor/swagger-ui/swagger-ui.css",
                                       swagger_favicon_url="/vendor/swagger-ui/favicon-32x32.png")

    @app.get("/favicon.ico", include_in_schema=False)
    def favicon() -> Response:
        return Response(status_code=204)

    return app


def _file_response(path: Path, media_type: str, name: str) -> StreamingResponse:
    """Stream the file from one open descriptor. A running job replaces its result files atomically
    (new inode, os.replace); reading size and bytes from the same descriptor keeps a download whole
    and its Content-Length right even when that happens mid-download."""
    try:
        f = open(path, "rb")
    except FileNotFoundError:
        raise HTTPException(404, f"no file {name!r}") from None
    size = os.fstat(f.fileno()).st_size

    def chunks():  # type: ignore[no-untyped-def]
        with f:
            while True:
                block = f.read(1 << 20)
                if not block:
                    return
                yield block

    disposition = "inline" if media_type.startswith("image/") else "attachment"
    return StreamingResponse(chunks(), media_type=media_type, headers={
        "Content-Length": str(size), "Content-Disposition": f'{disposition}; filename="{name}"'})


def _save_upload(upload: UploadFile, dest: Path) -> None:
    upload.file.seek(0)
    with open(dest, "wb") as f:
        shutil.copyfileobj(upload.file, f, 1 << 20)
