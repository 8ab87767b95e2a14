"""Jobs: submit (JSON or a multipart upload, the demo included), list, status, cancel, delete.

A submission is staged in a folder of its own and checked before it is queued
(:mod:`fusioncut.service.submit`); whatever goes wrong on the way, the staged folder is removed.
"""
from __future__ import annotations

import shutil
import threading
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Depends, HTTPException, Request
from fastapi.responses import JSONResponse, Response
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import UploadFile

from fusioncut.demo import DEMO_FILE, demo_gcode, demo_job
from fusioncut.errors import FusionCutError
from fusioncut.io.job import Job
from fusioncut.service.core import ClusterUnavailable
from fusioncut.service.files import check_name
from fusioncut.service.models import JobList, JobStatus, Problem
from fusioncut.service.routes.access import PROBLEMS, Api, api, owner
from fusioncut.service.submit import (MULTIPART_SCHEMA, JobSubmission, SubmissionError, build_job_from_form, check_job,
                                      discard, parse_json_body, stage_folder, write_text_files)

router = APIRouter(tags=["jobs"])

UPLOAD_FIELDS = ("toolpath", "toolpaths", "tool_library", "stock")

# Reading a submission's toolpaths is CPU work (a G-code loop can expand to millions of blocks): a few
# at a time in a process, so that a burst of uploads cannot take every request thread.
_CHECKS_AT_ONCE = threading.Semaphore(4)


@router.post(
    "/api/jobs", status_code=201, response_model=JobStatus,
    responses={**PROBLEMS, 413: {"model": Problem, "description": "upload too large"},
               415: {"model": Problem, "description": "neither JSON nor a multipart form"},
               503: {"model": Problem, "description": "the Dask cluster cannot take jobs now"},
               422: {"model": Problem, "description": "the job or an input file is invalid; "
                                                      "the message names the file:line:column or field"}},
    openapi_extra={"requestBody": {"required": True, "content": {
        "application/json": {"schema": {"$ref": "#/components/schemas/JobSubmission"}},
        "multipart/form-data": {"schema": MULTIPART_SCHEMA}}}},
)
async def submit(request: Request, who: str = Depends(owner), a: Api = Depends(api)) -> JSONResponse:
    """Submit a job: JSON (`JobSubmission`: the demo, or a job with its files inline) or a
    multipart upload of toolpath files, tool library and STEP stock with job options. The job is
    checked before it is queued: every file is read once with FusionCut's readers."""
    service = a.service
    ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
    job_id = service.new_job_id()
    staged = stage_folder(service.jobs_dir, job_id)
    try:
        if ctype == "application/json":
            job = await _from_json(request, staged)
        elif ctype == "multipart/form-data":
            job = await _from_form(request, staged, a.settings.max_files)
        else:
            raise SubmissionError(415, "send the job as application/json or multipart/form-data")
        checked = await run_in_threadpool(_checked, job, staged, a)
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
    return JSONResponse(status_code=201, content=a.status(rec).model_dump(),
                        headers={"Location": f"/api/jobs/{rec.id}"})


def _checked(job: Job, staged: Path, a: Api) -> Any:
    with _CHECKS_AT_ONCE:
        return check_job(job, staged, a.settings.budget)


def _demo(name: str | None, staged: Path) -> Job:
    """The built-in demo (:mod:`fusioncut.demo`, the job ``fusioncut demo`` runs) as a job of files: its
    G-code is written into the staged folder, so that it is run, resumed, listed and downloaded
    exactly like an uploaded job."""
    write_text_files({DEMO_FILE: demo_gcode()}, staged)
    return Job.model_validate(demo_job(name or "demo"))


async def _from_json(request: Request, staged: Path) -> Job:
    sub: JobSubmission = parse_json_body(await request.body())
    if sub.demo:
        if sub.job is not None or sub.files:
            raise SubmissionError(422, "demo: the demo job takes no job or files")
        return _demo(sub.name, staged)
    if sub.job is None:
        raise SubmissionError(422, 'job: give a job with its files, or {"demo": true}')
    write_text_files(sub.files, staged)
    return sub.job.model_copy(update={"name": sub.name}) if sub.name else sub.job


async def _from_form(request: Request, staged: Path, max_files: int) -> Job:
    form = await request.form(max_files=max_files, max_fields=64, max_part_size=1024 * 1024)
    uploads: dict[str, list[str]] = {}
    fields: dict[str, str] = {}
    try:
        for key, value in form.multi_items():
            if not isinstance(value, UploadFile):
                fields[key] = str(value)
                continue
            if key not in UPLOAD_FIELDS:
                raise SubmissionError(422, f"unexpected file field {key!r} (toolpath, tool_library, stock)")
            try:
                name = check_name(value.filename or "", f"{key}: file name")
            except FusionCutError as exc:
                raise SubmissionError(422, str(exc)) from None
            if (staged / name).exists():
                raise SubmissionError(422, f"{key}: two files named {name!r}")
            await run_in_threadpool(_save_upload, value, staged / name)
            uploads.setdefault("toolpath" if key == "toolpaths" else key, []).append(name)
    finally:
        await form.close()
    if fields.get("demo", "").lower() in ("1", "true", "on", "yes"):
        if uploads:
            raise SubmissionError(422, "demo: the demo job takes no uploaded files")
        return _demo(fields.get("name"), staged)
    return build_job_from_form(fields.get("job"), uploads, fields)


def _save_upload(upload: UploadFile, dest: Path) -> None:
    upload.file.seek(0)
    with open(dest, "wb") as f:
        shutil.copyfileobj(upload.file, f, 1 << 20)


@router.get("/api/jobs", response_model=JobList, responses=PROBLEMS)
def list_jobs(who: str = Depends(owner), a: Api = Depends(api)) -> JobList:
    """The jobs of this key, newest first."""
    assert a.service.store is not None
    return JobList(jobs=[a.status(r) for r in a.service.store.list(owner=who)])


@router.get("/api/jobs/{job_id}", response_model=JobStatus, responses=PROBLEMS)
def get_job(job_id: str, who: str = Depends(owner), a: Api = Depends(api)) -> JobStatus:
    """State and progress (CLs done / total, ETA) of one job."""
    return a.status(a.job(job_id, who))


@router.post("/api/jobs/{job_id}/cancel", response_model=JobStatus, status_code=202,
             responses={**PROBLEMS, 409: {"model": Problem, "description": "the job has already finished"}})
def cancel_job(job_id: str, who: str = Depends(owner), a: Api = Depends(api)) -> JobStatus:
    """Stop a queued or running job; the results of the CLs finished so far are kept. The state
    becomes `cancelled` as soon as the worker has stopped (within one CL)."""
    rec = a.job(job_id, who)
    if rec.state in ("done", "failed"):
        raise HTTPException(409, f"job {job_id} has already finished ({rec.state})")
    a.service.cancel(rec)
    return a.status(a.job(job_id, who))


@router.delete("/api/jobs/{job_id}", status_code=204, responses=PROBLEMS)
def delete_job(job_id: str, who: str = Depends(owner), a: Api = Depends(api)) -> Response:
    """Delete a job and its files (a running job is cancelled first)."""
    a.service.delete(a.job(job_id, who))
    return Response(status_code=204)
