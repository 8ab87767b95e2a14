"""Results: the result files and their downloads, the summary, one CL, and plots.

Downloads name the job's files the way the user named them (:func:`fusioncut.service.portable.
portable_download`): the runner records server paths, which the user has no business seeing.
"""
from __future__ import annotations

import io
import threading
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Depends, HTTPException, Query
from fastapi.responses import FileResponse, Response, StreamingResponse

from fusioncut.errors import FusionCutError
from fusioncut.service.files import find_result_file, result_files
from fusioncut.service.models import ClDetail, FileInfo, FileList, Problem, SummaryTable, json_safe
from fusioncut.service.portable import portable_download, portable_size
from fusioncut.service.routes.access import PROBLEMS, Api, api, owner
from fusioncut.service.store import FINAL_STATES

router = APIRouter(tags=["results"])

PLOT_KINDS = ("program", "heatmap", "map", "polar")
CL_PLOTS = ("map", "polar")  # plots of one CL; the others show the whole job
# matplotlib renders are CPU-heavy: a few at a time in a process, so that the API stays responsive
_PLOTS_AT_ONCE = threading.Semaphore(2)


def records(df: Any) -> list[dict[str, Any]]:
    """The rows of a DataFrame as JSON-safe dicts."""
    return [{k: json_safe(v) for k, v in row.items()} for row in df.astype(object).to_dict(orient="records")]


@router.get("/api/jobs/{job_id}/files", response_model=FileList, responses=PROBLEMS)
def list_files(job_id: str, who: str = Depends(owner), a: Api = Depends(api)) -> FileList:
    """Result files so far: cl/slices tables (CSV, Parquet), summary.csv, metadata.json, plots
    (PNG), the IPW mesh and STEP/STL/GLB exports when written, and the run log."""
    rec = a.job(job_id, who)
    results_dir, job_dir = a.service.results_dir(rec), a.service.job_dir(rec)
    return FileList(files=[FileInfo(name=f.name, size=_size(results_dir / f.name, job_dir, f.size),
                                    media_type=f.media_type, url=f"/api/jobs/{job_id}/files/{f.name}")
                           for f in result_files(results_dir)])


def _size(path: Path, job_dir: Path, listed: int) -> int:
    """What the download of ``path`` gives, in bytes (``listed``, the size on disk, when it went away)."""
    try:
        return portable_size(path, job_dir)
    except OSError:
        return listed


@router.get("/api/jobs/{job_id}/files/{name}", response_class=StreamingResponse,
            responses={**PROBLEMS, 422: {"model": Problem, "description": "not a plain file name"}})
def get_file(job_id: str, name: str, who: str = Depends(owner), a: Api = Depends(api)) -> StreamingResponse:
    """Download one result file (names as listed by /files)."""
    rec = a.job(job_id, who)
    results_dir = a.service.results_dir(rec)
    try:
        f = find_result_file(results_dir, name)
    except FusionCutError as exc:
        raise HTTPException(422, str(exc)) from None
    if f is None:
        raise HTTPException(404, f"job {job_id} has no file {name!r}")
    return _download(results_dir / f.name, a.service.job_dir(rec), f.media_type)


def _download(path: Path, job_dir: Path, media_type: str) -> StreamingResponse:
    try:
        body, size = portable_download(path, job_dir)
    except FileNotFoundError:
        raise HTTPException(404, f"no file {path.name!r}") from None
    disposition = "inline" if media_type.startswith("image/") else "attachment"
    headers = {"Content-Disposition": f'{disposition}; filename="{path.name}"'}
    if size is not None:
        headers["Content-Length"] = str(size)
    return StreamingResponse(body, media_type=media_type, headers=headers)


@router.get("/api/jobs/{job_id}/summary", response_model=SummaryTable, responses=PROBLEMS)
def summary(job_id: str, who: str = Depends(owner), a: Api = Depends(api)) -> SummaryTable:
    """The per-operation summary (summary.csv) as JSON rows."""
    return SummaryTable(rows=records(a.results(a.job(job_id, who)).summary))


@router.get("/api/jobs/{job_id}/cls/{cl}", response_model=ClDetail, responses=PROBLEMS)
def cl_detail(job_id: str, cl: int, who: str = Depends(owner), a: Api = Depends(api)) -> ClDetail:
    """One CL: its row of the cl table and its engaged arcs (machine angles at z_machine_mm)."""
    res = a.results(a.job(job_id, who))
    try:
        row = res.row(cl)
    except FusionCutError as exc:
        raise HTTPException(404, str(exc)) from None
    return ClDetail(cl={k: json_safe(v) for k, v in row.astype(object).to_dict().items()},
                    slices=records(res.slices_of(cl)))


@router.get("/api/jobs/{job_id}/plots/{kind}", response_class=Response,
            responses={**PROBLEMS, 200: {"content": {"image/png": {}}}})
def plot(job_id: str, kind: str, cl: int | None = Query(None, description="CL index (map, polar)"),
         who: str = Depends(owner), a: Api = Depends(api)) -> Response:
    """A PNG plot drawn by fusioncut.viz.plots: `program` or `heatmap` of the whole job, `map`
    (engagement map) or `polar` (top view) of one CL."""
    rec = a.job(job_id, who)
    if kind not in PLOT_KINDS:
        raise HTTPException(404, f"no plot kind {kind!r} ({', '.join(PLOT_KINDS)})")
    if kind not in CL_PLOTS and rec.state in FINAL_STATES:
        f = a.service.results_dir(rec) / f"{kind}.png"  # drawn by the worker when the job ended
        if f.is_file():
            return FileResponse(f, media_type="image/png")
    if kind in CL_PLOTS and cl is None:
        raise HTTPException(422, f"the {kind} plot needs ?cl=<CL index>")
    res = a.results(rec)
    if not len(res.cl):
        raise HTTPException(404, f"job {job_id} has no results yet")
    from fusioncut.viz import plots

    with _PLOTS_AT_ONCE:
        try:
            fig = plots.PLOTS[kind](res, cl) if cl is not None and kind in CL_PLOTS else plots.PLOTS[kind](res)
        except FusionCutError as exc:
            raise HTTPException(404, str(exc)) from None
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=fig.dpi)
    return Response(buf.getvalue(), media_type="image/png", headers={"Cache-Control": "no-store"})
