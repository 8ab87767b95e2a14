"""The FusionCut web service: a job API and a browser front end over a Dask cluster.

``fusioncut serve`` runs it (see ``docs/deploy.md``). Jobs run :func:`fusioncut.runner.run_job`, the
same code as ``fusioncut run``, in Dask worker processes; the service keeps a SQLite job store and one
folder per job under its data folder. Modules, from the bottom up:

* :mod:`~fusioncut.service.settings` — configuration (environment, config file, options), API keys;
* :mod:`~fusioncut.service.store` — the SQLite job store with schema migrations;
* :mod:`~fusioncut.service.files` — safe file names and the downloadable files of a job;
* :mod:`~fusioncut.service.worker` — what a Dask worker runs (progress file, cancel flag);
* :mod:`~fusioncut.service.executor` — the Dask client (embedded LocalCluster or external scheduler);
* :mod:`~fusioncut.service.portable` — the job's files named as the user named them, not by server path;
* :mod:`~fusioncut.service.submit` — parsing and checking submissions before they are queued;
* :mod:`~fusioncut.service.scene_cache` — the workpiece after a CL, replayed on a worker and cached;
* :mod:`~fusioncut.service.core` — job life cycle, restart recovery, the monitor thread;
* :mod:`~fusioncut.service.routes` — the HTTP API in routers by concern (jobs, events, results,
  scenes, front end) and :mod:`~fusioncut.service.body_limit`, the request body limit;
* :mod:`~fusioncut.service.app` — the FastAPI application: the routers assembled.

The service never imports OpenCASCADE itself; only the runner it calls does, in the workers (and,
to check toolpath files with the project's readers, the reader modules).
"""
from __future__ import annotations

from fusioncut.service.settings import Settings

__all__ = ["Settings", "create_app"]


def create_app(settings: Settings | None = None):  # type: ignore[no-untyped-def]
    """The FastAPI application (imported lazily: FastAPI and Dask are not needed by the rest)."""
    from fusioncut.service.app import create_app as _create

    return _create(settings)
