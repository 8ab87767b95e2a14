"""The service itself: ``/api/info``, the browser front end at ``/`` and the API pages at ``/docs``.

The front end (``frontend/``: plain ES modules and three.js through an import map) is served from
its folder; FastAPI's own API pages would load Swagger UI from a CDN, these serve it from the front
end's npm packages (no network needed at run time), and ReDoc is left out.
"""
from __future__ import annotations

import logging
from pathlib import Path

from fastapi import APIRouter, Depends, FastAPI
from fastapi.responses import FileResponse, Response
from fastapi.staticfiles import StaticFiles

from fusioncut import __version__
from fusioncut.service.models import ServiceInfo
from fusioncut.service.routes.access import PROBLEMS, Api, api, owner

log = logging.getLogger("fusioncut.service")

router = APIRouter(tags=["service"])


@router.get("/api/info", response_model=ServiceInfo, responses=PROBLEMS)
def info(who: str = Depends(owner), a: Api = Depends(api)) -> ServiceInfo:
    """Version, Dask scheduler and limits of this service."""
    settings = a.settings
    return ServiceInfo(version=__version__, scheduler=a.service.executor.address,
                       embedded_cluster=a.service.executor.cluster is not None,
                       max_upload_bytes=settings.max_upload_bytes, max_cls=settings.max_cls,
                       max_slices=settings.max_slices)


def add_front_end(app: FastAPI, front: Path) -> None:
    """Serve the front end in ``front`` (its sources, three.js and Swagger UI from its npm packages)."""
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
