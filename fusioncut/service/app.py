"""The HTTP API and the front end: ``create_app(settings)`` gives the FastAPI application.

The routes are in routers by concern (:mod:`fusioncut.service.routes`); this module assembles them
with what every route shares: the service's life cycle, the request body limit
(:mod:`~fusioncut.service.body_limit`), and the errors. Errors are JSON ``{"detail": "..."}`` with a
4xx status and one line of text; nothing answers with a traceback.
"""
from __future__ import annotations

import logging
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.concurrency import run_in_threadpool

from fusioncut import __version__
from fusioncut.service.body_limit import BodyLimit
from fusioncut.service.core import Service
from fusioncut.service.routes import events, front, jobs, results, scenes
from fusioncut.service.routes.access import Api
from fusioncut.service.settings import Settings
from fusioncut.service.submit import JobSubmission

log = logging.getLogger("fusioncut.service")

DESCRIPTION = (
    "Cutter-workpiece engagement jobs on a Dask cluster. Submit a job (JSON with inline files, "
    "or a multipart upload), follow its progress (polling or server-sent events), download its "
    "result tables, plots and meshes. Every /api route needs the `X-API-Key` header; each key "
    "sees only its own jobs.")


def create_app(settings: Settings | None = None, service: Service | None = None) -> FastAPI:
    settings = settings or Settings.from_env()
    service = service or Service(settings)

    @asynccontextmanager
    async def lifespan(app: FastAPI):  # type: ignore[no-untyped-def]
        await run_in_threadpool(service.start)  # nothing to do when `fusioncut serve` started it
        try:
            yield
        finally:
            await run_in_threadpool(service.stop)

    app = FastAPI(title="FusionCut service", version=__version__, lifespan=lifespan, docs_url=None, redoc_url=None,
                  description=DESCRIPTION)
    app.state.api = Api(service, settings)
    app.state.events = events.EventStreams(app.state.api)
    app.state.scenes = scenes.SceneReplays(service)
    app.add_middleware(BodyLimit, limit=settings.max_upload_bytes)
    app.add_exception_handler(RequestValidationError, _invalid)  # type: ignore[arg-type]
    app.add_exception_handler(Exception, _internal)
    for router in (front.router, jobs.router, events.router, results.router, scenes.router):
        app.include_router(router)
    app.openapi = lambda: _openapi(app)  # type: ignore[method-assign]
    front.add_front_end(app, settings.frontend_dir)
    return app


async def _invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
    first = exc.errors()[0] if exc.errors() else {"loc": (), "msg": "invalid request"}
    loc = ".".join(str(p) for p in first.get("loc", ()))
    return JSONResponse(status_code=422, content={"detail": f"{loc}: {first.get('msg')}"})


async def _internal(request: Request, exc: Exception) -> JSONResponse:
    log.error("internal error on %s %s", request.method, request.url.path, exc_info=exc)
    return JSONResponse(status_code=500, content={"detail": "internal server error (details are in the service log)"})


def _openapi(app: FastAPI) -> dict[str, Any]:
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
