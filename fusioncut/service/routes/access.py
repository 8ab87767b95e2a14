"""Who may see what, and what the routes of one application share.

Every ``/api`` route needs an ``X-API-Key`` header (:func:`owner` gives the hash of the key, which the
store keeps instead of the key); a key sees only the jobs it submitted, and a job of another key
answers 404 exactly like one that does not exist (:meth:`Api.job`), so ids cannot be probed.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Any

from fastapi import Depends, HTTPException, Request
from fastapi.security import APIKeyHeader

from fusioncut.errors import FusionCutError
from fusioncut.service.core import Service
from fusioncut.service.models import JobStatus, Problem, ProgressInfo
from fusioncut.service.portable import portable
from fusioncut.service.settings import Settings, key_hash
from fusioncut.service.store import JobRecord

API_KEY = APIKeyHeader(name="X-API-Key", auto_error=False, description="an API key configured on the service")

PROBLEMS: dict[int | str, dict[str, Any]] = {
    401: {"model": Problem, "description": "no or unknown X-API-Key"},
    404: {"model": Problem, "description": "no such job for this key"},
}

RESULTS_CACHED = 8  # jobs whose loaded results are kept (the views of a job ask for them again and again)


class Api:
    """What the routes of one application share: its service and settings, the lookup of a key's
    jobs, their status, and the loaded results of the jobs viewed last (``app.state.api``)."""

    def __init__(self, service: Service, settings: Settings):
        self.service = service
        self.settings = settings
        self._results: OrderedDict[str, tuple[tuple, Any]] = OrderedDict()
        self._results_lock = threading.Lock()

    def job(self, job_id: str, who: str) -> JobRecord:
        """The job ``job_id`` of the key whose hash is ``who``; 404 when there is none."""
        assert self.service.store is not None
        rec = self.service.store.get(job_id, owner=who)
        if rec is None:
            raise HTTPException(404, f"no job {job_id!r}")
        return rec

    def status(self, rec: JobRecord) -> JobStatus:
        p = self.service.progress(rec)
        base = f"/api/jobs/{rec.id}"
        return JobStatus(id=rec.id, name=rec.name, state=rec.state, created_at=rec.created_at,  # type: ignore[arg-type]
                         started_at=rec.started_at, finished_at=rec.finished_at, message=rec.message,
                         progress=ProgressInfo(**p.__dict__),
                         links={"self": base, "events": f"{base}/events", "files": f"{base}/files",
                                "cancel": f"{base}/cancel", "scene": f"{base}/scene"})

    def results(self, rec: JobRecord) -> Any:
        """The job's results so far (:func:`fusioncut.io.results.load_results`, files named as the user
        named them); loaded again when a Parquet table changed. 404 when there are none yet."""
        from fusioncut.io.results import load_results

        d = self.service.results_dir(rec)
        stamp = tuple((p.name, p.stat().st_mtime_ns) for p in sorted(d.glob("*.parquet"))) if d.is_dir() else ()
        with self._results_lock:
            hit = self._results.get(rec.id)
            if hit is not None and hit[0] == stamp:
                self._results.move_to_end(rec.id)
                return hit[1]
        try:
            res = portable(load_results(d), self.service.job_dir(rec))
        except FusionCutError:
            raise HTTPException(404, f"job {rec.id} has no results yet") from None
        with self._results_lock:
            self._results[rec.id] = (stamp, res)
            while len(self._results) > RESULTS_CACHED:
                self._results.popitem(last=False)
        return res


def api(request: Request) -> Api:
    """The :class:`Api` of the application serving the request."""
    return request.app.state.api


def owner(key: str | None = Depends(API_KEY), a: Api = Depends(api)) -> str:
    """The hash of the request's API key; 401 without a key or with one the service does not know."""
    if not key:
        raise HTTPException(401, "missing X-API-Key header")
    h = key_hash(key)
    if h not in a.service.key_hashes:
        raise HTTPException(401, "unknown API key")
    return h
