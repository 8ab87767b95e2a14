"""Server-sent events: live progress of one job, or of every job of a key on one connection.

Bounds: at most ``Settings.max_streams_per_key`` streams open per key (429 beyond), and one snapshot
of a key's job states per poll interval shared by all its streams (:meth:`EventStreams.snapshot`), so
that the cost grows with the keys and jobs, not with the connections.
"""
from __future__ import annotations

import asyncio
import json
import threading
import time
from collections.abc import Callable
from typing import Any

from fastapi import APIRouter, Depends, HTTPException, Request
from fastapi.responses import StreamingResponse

from fusioncut.service.models import Problem
from fusioncut.service.routes.access import PROBLEMS, Api, api, owner
from fusioncut.service.store import FINAL_STATES

router = APIRouter(tags=["jobs"])

KEEP_ALIVE_S = 15.0  # a comment line after this long without events, so that proxies keep the connection
TOO_MANY = {"model": Problem, "description": "too many event streams open for this key"}

# what one poll of a stream gives: the events to send, and whether the stream is finished
Poll = Callable[[], tuple[list[str], bool]]


def sse(event: str, data: Any) -> str:
    return f"event: {event}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n"


class EventStreams:
    """The event streams of one application (``app.state.events``): open streams and the latest
    snapshot of each key's jobs."""

    def __init__(self, a: Api):
        self.api = a
        self.open: dict[str, int] = {}
        self.snapshots: dict[str, tuple[float, dict[str, tuple[str, dict[str, Any]]]]] = {}
        self.lock = threading.Lock()

    def snapshot(self, who: str) -> dict[str, tuple[str, dict[str, Any]]]:
        """id -> (state, JobStatus as a dict) of the key's jobs, newest first; at most one poll
        interval old."""
        now = time.monotonic()
        with self.lock:
            hit = self.snapshots.get(who)
            if hit is not None and now - hit[0] < 0.9 * self.api.settings.poll_interval_s:
                return hit[1]
        store = self.api.service.store
        snap = {r.id: (r.state, self.api.status(r).model_dump()) for r in (store.list(owner=who) if store else [])}
        with self.lock:
            self.snapshots[who] = (now, snap)
        return snap

    def response(self, request: Request, poll: Poll, who: str) -> StreamingResponse:
        """An SSE response that calls ``poll()`` every poll interval, with a comment line after
        :data:`KEEP_ALIVE_S` without events."""
        limit = self.api.settings.max_streams_per_key
        if self.open.get(who, 0) >= limit:
            raise HTTPException(429, f"this key has {limit} event streams open already; "
                                     "close one (GET /api/events follows every job of the key in one stream)")
        return StreamingResponse(self._stream(request, poll, who), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})

    async def _stream(self, request: Request, poll: Poll, who: str):  # type: ignore[no-untyped-def]
        settings, service = self.api.settings, self.api.service
        with self.lock:
            over = self.open.get(who, 0) >= settings.max_streams_per_key
            if not over:
                self.open[who] = self.open.get(who, 0) + 1
        if over:  # several opened at once: the check in response() let them all through
            yield sse("error", {"detail": "too many event streams for this key"})
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
                if idle >= KEEP_ALIVE_S:
                    yield ": keep-alive\n\n"
                    idle = 0.0
                if await request.is_disconnected():
                    return
                await asyncio.sleep(settings.poll_interval_s)
                idle += settings.poll_interval_s
        finally:
            with self.lock:
                self.open[who] -= 1


def streams(request: Request) -> EventStreams:
    return request.app.state.events


@router.get("/api/jobs/{job_id}/events", responses={
    **PROBLEMS, 429: TOO_MANY,
    200: {"content": {"text/event-stream": {}},
          "description": "`status` events (a JobStatus as JSON) whenever it changes, then `end`"}})
async def job_events(job_id: str, request: Request, who: str = Depends(owner), a: Api = Depends(api),
                     s: EventStreams = Depends(streams)) -> StreamingResponse:
    """Server-sent events with live progress of one job; the stream ends when the job does."""
    a.job(job_id, who)
    last: list[Any] = [None]

    def poll() -> tuple[list[str], bool]:
        hit = s.snapshot(who).get(job_id)
        if hit is None:  # not in the shared snapshot: deleted, or newer than the snapshot
            rec = a.service.store.get(job_id, owner=who) if a.service.store else None
            if rec is None:
                return [sse("deleted", {"id": job_id})], True
            hit = (rec.state, a.status(rec).model_dump())
        state, now = hit
        events = []
        if now != last[0]:
            events.append(sse("status", now))
            last[0] = now
        if state in FINAL_STATES:
            return events + [sse("end", {"id": job_id, "state": state})], True
        return events, False

    return s.response(request, poll, who)


@router.get("/api/events", responses={
    **PROBLEMS, 429: TOO_MANY,
    200: {"content": {"text/event-stream": {}},
          "description": "`job` events (JobStatus) for every job of the key that changes, "
                         "`deleted` events ({id}) for jobs that went away"}})
async def all_events(request: Request, who: str = Depends(owner),
                     s: EventStreams = Depends(streams)) -> StreamingResponse:
    """Server-sent events for all jobs of this key (one connection for the whole job list)."""
    last: dict[str, Any] = {}

    def poll() -> tuple[list[str], bool]:
        events = []
        snap = s.snapshot(who)
        for job_id, (_, now) in snap.items():
            if last.get(job_id) != now:
                last[job_id] = now
                events.append(sse("job", now))
        for gone in set(last) - set(snap):
            del last[gone]
            events.append(sse("deleted", {"id": gone}))
        return events, False

    return s.response(request, poll, who)
