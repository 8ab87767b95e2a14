"""Running jobs on Dask distributed: an embedded ``LocalCluster`` or an external scheduler.

Each job is one Dask task, :func:`fusioncut.service.worker.execute_job`, keyed
``fusioncut-job-<id>-<attempt>``. Worker *processes* with one thread each: OpenCASCADE work holds
the GIL, and one job per process keeps a crash (or a kill) of one job from taking others with it.

Tasks are submitted fire-and-forget: when the service stops, a task on an external cluster keeps
running instead of being released with the service's client, and a restarted service finds it again
by its key (:meth:`Executor.task_state`) instead of starting a second run into the same folder.
A worker that dies mid-job is replaced by Dask (the nanny restarts it) and the task runs again
elsewhere, up to ``distributed.scheduler.allowed-failures`` times; the runner resumes from its
checkpoint, so nothing is computed twice.
"""
from __future__ import annotations

import logging
import threading
from pathlib import Path
from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

from fusioncut.service.settings import Settings

log = logging.getLogger("fusioncut.service")

LIVE_TASK_STATES = {"released", "waiting", "queued", "no-worker", "processing", "memory"}


WARM_MODULES = ("fusioncut.runner", "fusioncut.io.results", "fusioncut.viz.plots")


def warm_up() -> None:
    """Import what a job needs (OpenCASCADE, pandas, matplotlib: seconds) before the first job asks."""
    import importlib

    for name in WARM_MODULES:
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001 - the job itself will report a broken install
            log.warning("warm-up: cannot import %s", name, exc_info=True)


class WarmUp(WorkerPlugin):
    """Worker plugin: every worker, also one the nanny restarts, imports in the background at start."""

    name = "fusioncut-warm-up"
    idempotent = True

    def setup(self, worker: Any) -> None:
        threading.Thread(target=warm_up, name="fusioncut-warm-up", daemon=True).start()


def task_key(job_id: str, attempt: int) -> str:
    return f"fusioncut-job-{job_id}-{attempt}"


class Executor:
    def __init__(self, settings: Settings):
        self.settings = settings
        self.client: Any = None
        self.cluster: Any = None
        self.futures: dict[str, Any] = {}
        self._lock = threading.Lock()

    @property
    def address(self) -> str:
        return self.client.scheduler.address if self.client is not None else ""

    def start(self) -> None:
        from distributed import Client, LocalCluster

        if self.settings.scheduler:
            log.info("connecting to the Dask scheduler at %s", self.settings.scheduler)
            self.client = Client(self.settings.scheduler, timeout="30s", set_as_default=False)
        else:
            n = self.settings.worker_count
            log.info("starting an embedded Dask cluster of %d worker process(es)", n)
            # ":0": the scheduler always serves HTTP (health, metrics); a free port avoids clashes
            self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                        dashboard_address=":0", silence_logs=logging.ERROR)
            self.client = Client(self.cluster, set_as_default=False)
        try:
            self.client.register_plugin(WarmUp())
        except Exception:  # noqa: BLE001 - only a speed-up
            log.warning("could not register the warm-up worker plugin", exc_info=True)

    def close(self) -> None:
        with self._lock:
            self.futures.clear()
        if self.client is not None:
            try:
                self.client.close(timeout=10)
            except Exception:  # noqa: BLE001 - closing down; nothing left to tell anyone
                log.debug("closing the Dask client", exc_info=True)
        if self.cluster is not None:
            try:
                self.cluster.close(timeout=20)
            except Exception:  # noqa: BLE001
                log.debug("closing the Dask cluster", exc_info=True)
        self.client = self.cluster = None

    def submit(self, job_id: str, job_dir: Path, attempt: int) -> None:
        from distributed import fire_and_forget

        from fusioncut.service.worker import execute_job

        fut = self.client.submit(execute_job, str(job_dir), attempt, self.settings.progress_interval_s,
                                 key=task_key(job_id, attempt), pure=False)
        fire_and_forget(fut)
        with self._lock:
            self.futures[job_id] = fut

    def attach(self, job_id: str, attempt: int) -> None:
        """Follow a task submitted by an earlier run of the service (see :class:`FollowedTask`)."""
        with self._lock:
            self.futures[job_id] = FollowedTask(self, job_id, attempt)

    def task_state(self, job_id: str, attempt: int) -> str | None:
        """The scheduler's state of the job's task, None when the scheduler does not know it."""
        key = task_key(job_id, attempt)

        def state(dask_scheduler: Any, key: str = key) -> str | None:
            ts = dask_scheduler.tasks.get(key)
            return ts.state if ts is not None else None

        try:
            return self.client.run_on_scheduler(state)
        except Exception:  # noqa: BLE001 - a scheduler refusing remote code: treat the task as gone
            log.warning("cannot ask the scheduler about %s", key, exc_info=True)
            return None

    def cancel(self, job_id: str) -> None:
        fut = self.futures.get(job_id)
        if fut is not None and not isinstance(fut, FollowedTask):  # a followed task sees the cancel flag
            self.client.cancel([fut], force=True)

    def forget(self, job_id: str) -> None:
        with self._lock:
            self.futures.pop(job_id, None)

    def active(self) -> dict[str, Any]:
        with self._lock:
            return dict(self.futures)

    def worker_pids(self) -> dict[str, int]:
        import os

        return self.client.run(os.getpid)


class FollowedTask:
    """Stands in for the Future of a task that an earlier service process submitted.

    Dask gives no way to re-create a Future that receives updates for an existing key, so the
    scheduler is asked for the task's state instead (at most every ``check_s`` seconds): ``pending``
    while it is alive, ``lost`` once it is not. The job's outcome itself comes from the
    ``progress.json`` the worker writes before its task ends.
    """

    def __init__(self, executor: Executor, job_id: str, attempt: int, check_s: float = 5.0):
        self.executor = executor
        self.job_id = job_id
        self.attempt = attempt
        self.check_s = check_s
        self._checked = 0.0
        self._status = "pending"

    @property
    def status(self) -> str:
        import time

        now = time.monotonic()
        if self._status == "pending" and now - self._checked >= self.check_s:
            self._checked = now
            state = self.executor.task_state(self.job_id, self.attempt)
            if state not in LIVE_TASK_STATES - {"memory"}:
                self._status = "lost"  # finished (its result went with the old client), erred or gone
        return self._status
