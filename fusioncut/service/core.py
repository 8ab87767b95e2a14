"""The service without HTTP: job store, job folders, the Dask executor and the monitor thread.

The monitor thread is the only place that moves a job from one state to the next (queued → running
when its worker reports, running → done/failed/cancelled when its task ends), so the state machine
lives in one function, :meth:`Service.tick`. Requests only create jobs, set cancel flags and read.
"""
from __future__ import annotations

import fcntl
import logging
import os
import secrets
import shutil
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fusioncut.errors import FusionCutError, InputError
from fusioncut.service.executor import LIVE_TASK_STATES, Executor
from fusioncut.service.files import CANCEL_FILE, RESULTS_DIR, SUSPEND_FILE
from fusioncut.service.settings import Settings, load_keys
from fusioncut.service.store import ACTIVE_STATES, FINAL_STATES, JobRecord, JobStore
from fusioncut.service.submit import Checked, commit_folder
from fusioncut.service.worker import read_progress

log = logging.getLogger("fusioncut.service")

# A task that vanishes without a result (the scheduler restarted, the connection dropped) is
# submitted again this many times before the job is marked failed.
MAX_ATTEMPTS = 5


def _task_running(fut: Any) -> bool:
    """Whether a job's task may still be inside a CL (not finished, failed, cancelled or lost)."""
    try:
        return fut.status == "pending"
    except Exception:  # noqa: BLE001 - the scheduler is gone: nothing runs any more
        return False


class ClusterUnavailable(FusionCutError):
    """The job could not be handed to the Dask cluster (the API answers 503 with the message)."""


@dataclass(frozen=True)
class Progress:
    done: int
    total: int
    fraction: float
    eta_s: float | None
    rate_cl_s: float | None
    operation: str


class Service:
    def __init__(self, settings: Settings, executor: Executor | None = None):
        self.settings = settings
        self.data_dir = settings.data_dir.resolve()
        self.jobs_dir = self.data_dir / "jobs"
        self.store: JobStore | None = None
        self.executor = executor or Executor(settings)
        self.key_hashes: frozenset[str] = frozenset()
        self.created_key_file: Path | None = None
        self._lock_file: Any = None
        self._stop = threading.Event()
        self._monitor: threading.Thread | None = None
        self.stopping = False
        self.started = False

    # -- life cycle ---------------------------------------------------------------------------
    def start(self) -> None:
        """Lock the data folder, read the keys, open the store, start the cluster client, recover
        jobs, start the monitor. Idempotent: ``fusioncut serve`` starts the service before the web
        server, so that bad settings end with a clear message instead of a failed-startup trace."""
        if self.started:
            return
        self.started = True
        self.jobs_dir.mkdir(parents=True, exist_ok=True)
        self._take_lock()
        self.key_hashes, self.created_key_file = load_keys(self.settings.with_(data_dir=self.data_dir))
        self.store = JobStore(self.data_dir / "jobs.sqlite")
        for stale in self.jobs_dir.glob(".staging-*"):  # uploads of requests cut off by a stop
            shutil.rmtree(stale, ignore_errors=True)
        self.executor.start()
        if self.settings.warm_up:
            # the readers that check submissions import OpenCASCADE: seconds the first request should not wait
            from fusioncut.service.executor import warm_up

            threading.Thread(target=warm_up, name="fusioncut-warm-up", daemon=True).start()
        self.recover()
        self._monitor = threading.Thread(target=self._run_monitor, name="fusioncut-monitor", daemon=True)
        self._monitor.start()

    def stop(self) -> None:
        if not self.started or self.stopping:
            return
        self.stopping = True
        self._stop.set()
        if self._monitor is not None:
            self._monitor.join(timeout=10)
        if self.executor.cluster is not None:
            self._suspend_all(self.settings.stop_timeout_s)
        # Jobs stay queued/running in the store: the next start submits them again and they resume
        # from their checkpoints. Tasks on an external cluster just go on; the next start finds them.
        self.executor.close()
        if self.store is not None:
            self.store.close()
        if self._lock_file is not None:
            self._lock_file.close()
            self._lock_file = None

    def _suspend_all(self, timeout_s: float = 30.0, poll_s: float = 0.1) -> None:
        """Closing the embedded cluster would wait for running jobs to finish (hours, maybe): ask them
        to checkpoint and stop after their current CL instead, and give them ``timeout_s`` to do so
        (:attr:`Settings.stop_timeout_s`).

        The wait reads each task's own status (``distributed.wait`` needs a default client, and the
        service's client is deliberately not one: it raised at once, and the cluster was closed while
        jobs were inside a CL). A job still inside a CL at the deadline resumes from its last
        periodic checkpoint."""
        active = self.executor.active()
        if not active or self.store is None:
            return
        for job_id in active:
            rec = self.store.get(job_id)
            if rec is not None:
                (self.job_dir(rec) / SUSPEND_FILE).touch()
        log.info("suspending %d job(s) until the service starts again", len(active))
        deadline = time.monotonic() + timeout_s
        running = list(active.items())
        while running and time.monotonic() < deadline:
            running = [(job_id, fut) for job_id, fut in running if _task_running(fut)]
            if running:
                time.sleep(poll_s)
        if running:
            log.warning("%d job(s) did not reach a checkpoint within %.0f s: %s", len(running), timeout_s,
                        ", ".join(job_id for job_id, _ in running))
        else:
            log.info("every job stopped at a checkpoint")

    def _take_lock(self) -> None:
        f = open(self.data_dir / "service.lock", "a+")
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            raise InputError("another FusionCut service is using this data folder", self.data_dir) from None
        f.seek(0)
        f.truncate()
        f.write(f"{os.getpid()}\n")
        f.flush()
        self._lock_file = f

    # -- jobs ---------------------------------------------------------------------------------
    def job_dir(self, rec: JobRecord) -> Path:
        return self.data_dir / rec.folder

    def results_dir(self, rec: JobRecord) -> Path:
        return self.job_dir(rec) / RESULTS_DIR

    def new_job_id(self) -> str:
        return secrets.token_hex(8)

    def create(self, owner: str, name: str, staged_input: Path, checked: Checked, job_id: str) -> JobRecord:
        """Store the job and queue it; :class:`ClusterUnavailable` (nothing kept) when Dask refuses it."""
        assert self.store is not None
        job_dir = self.jobs_dir / job_id
        commit_folder(staged_input, job_dir, checked)
        rec = self.store.add(job_id, owner, name, str(job_dir.relative_to(self.data_dir)), checked.total_cls)
        try:
            self._submit(rec, 1)
        except Exception as exc:  # noqa: BLE001 - scheduler gone, connection closed, ...
            log.error("cannot submit job %s", job_id, exc_info=True)
            self._remove(rec)
            raise ClusterUnavailable(f"the Dask cluster did not take the job ({type(exc).__name__}); try again later") from None
        return self.store.get(job_id) or rec

    def _submit(self, rec: JobRecord, attempt: int) -> None:
        assert self.store is not None
        (self.job_dir(rec) / SUSPEND_FILE).unlink(missing_ok=True)
        self.store.update(rec.id, attempt=attempt, state="queued")
        self.executor.submit(rec.id, self.job_dir(rec), attempt)

    def progress(self, rec: JobRecord) -> Progress:
        p = read_progress(self.job_dir(rec)) or {}
        total = int(p.get("total") or rec.total_cls)
        done = min(int(p.get("done", 0)), total) if total else 0
        if rec.state == "done":
            done = total
        running = rec.state == "running"
        return Progress(done, total, (done / total) if total else (1.0 if rec.state == "done" else 0.0),
                        p.get("eta_s") if running else (0.0 if rec.state == "done" else None),
                        p.get("rate_cl_s") if running else None, str(p.get("operation", "")) if running else "")

    def cancel(self, rec: JobRecord) -> None:
        """Ask the job to stop: the flag for a running worker, and the queue for a task not started."""
        assert self.store is not None
        if rec.state not in ACTIVE_STATES:
            return
        (self.job_dir(rec) / CANCEL_FILE).touch()
        if rec.state == "queued":
            self.executor.cancel(rec.id)

    def delete(self, rec: JobRecord) -> None:
        """Remove the job; one still running is cancelled and removed when its worker has stopped."""
        assert self.store is not None
        if rec.state in ACTIVE_STATES and rec.id in self.executor.active():
            self.store.update(rec.id, deleted_at=time.time())
            self.cancel(rec)
            return
        self._remove(rec)

    def _remove(self, rec: JobRecord) -> None:
        assert self.store is not None
        self.executor.forget(rec.id)
        self.store.remove(rec.id)
        shutil.rmtree(self.job_dir(rec), ignore_errors=True)

    def _finish(self, rec: JobRecord, state: str, message: str) -> None:
        assert self.store is not None
        self.executor.forget(rec.id)
        if state not in FINAL_STATES:
            # suspended: at a stop the job waits for the next start; otherwise it goes on now
            if not self.stopping and rec.deleted_at is None:
                if rec.attempt < MAX_ATTEMPTS:
                    self._submit(rec, rec.attempt + 1)
                else:
                    self._finish(rec, "failed", "the job was interrupted too often")
            return
        if rec.deleted_at is not None:
            self._remove(rec)
            return
        values: dict[str, Any] = {"state": state, "finished_at": time.time(), "message": message}
        if rec.started_at is None:
            p = read_progress(self.job_dir(rec)) or {}
            values["started_at"] = p.get("started")
        self.store.update(rec.id, **values)
        log.info("job %s %s: %s", rec.id, state, message)

    # -- recovery and monitoring --------------------------------------------------------------
    def recover(self) -> None:
        """Jobs left queued or running by an earlier service: adopt what their workers wrote, follow
        tasks the cluster still runs, and resubmit the rest (they resume from their checkpoints)."""
        assert self.store is not None
        # oldest first: the cluster starts tasks in the order they come, so jobs keep their turn
        for rec in sorted(self.store.list(include_deleted=True), key=lambda r: (r.created_at, r.id)):
            if rec.state in FINAL_STATES:
                if rec.deleted_at is not None:
                    self._remove(rec)
                continue
            folder = self.job_dir(rec)
            p = read_progress(folder) or {}
            if p.get("state") in FINAL_STATES:
                self._finish(rec, p["state"], str(p.get("message", "")))
            elif (folder / CANCEL_FILE).exists() or rec.deleted_at is not None or not folder.is_dir():
                self._finish(rec, "cancelled", "cancelled while the service was down")
            elif self.executor.task_state(rec.id, rec.attempt) in LIVE_TASK_STATES:
                log.info("job %s: following its task on the cluster", rec.id)
                self.executor.attach(rec.id, rec.attempt)
            else:
                log.info("job %s: resubmitting (attempt %d)", rec.id, rec.attempt + 1)
                self._submit(rec, rec.attempt + 1)

    def _run_monitor(self) -> None:
        while not self._stop.wait(self.settings.poll_interval_s):
            try:
                self.tick()
            except Exception:  # noqa: BLE001 - the monitor must outlive any one job's trouble
                log.exception("monitor")

    def tick(self) -> None:
        assert self.store is not None
        for job_id, fut in self.executor.active().items():
            if self._stop.is_set():
                return
            rec = self.store.get(job_id)
            if rec is None:
                self.executor.forget(job_id)
                continue
            status = fut.status
            if status == "pending":
                p = read_progress(self.job_dir(rec)) or {}
                if p.get("attempt") != rec.attempt:
                    continue
                if p.get("state") in FINAL_STATES:
                    # the worker wrote its outcome; the task's own result follows (or, for a task
                    # followed after a restart, never comes): the folder is the record
                    self._finish(rec, p["state"], str(p.get("message", "")))
                elif p.get("state") == "running" and rec.state == "queued":
                    self.store.update(job_id, state="running", started_at=rec.started_at or p.get("started"))
            elif status == "finished":
                try:
                    res = fut.result(timeout=10)
                except Exception as exc:  # noqa: BLE001 - the result vanished (lost worker): treat as error
                    self._task_error(rec, exc)
                    continue
                self._finish(rec, res.get("state", "failed"), str(res.get("message", "")))
            elif status == "error":
                try:
                    exc = fut.exception(timeout=10)
                except Exception as e:  # noqa: BLE001
                    exc = e
                self._task_error(rec, exc)
            elif status in ("cancelled", "lost"):
                p = read_progress(self.job_dir(rec)) or {}
                if p.get("state") in FINAL_STATES:
                    self._finish(rec, p["state"], str(p.get("message", "")))
                elif (self.job_dir(rec) / CANCEL_FILE).exists() or rec.deleted_at is not None:
                    if p.get("state") == "running" and p.get("attempt") == rec.attempt and \
                            time.time() - float(p.get("updated", 0)) < 60:
                        continue  # the worker is still stopping; it writes the final state itself
                    self._finish(rec, "cancelled", "cancelled before it started" if rec.state == "queued"
                                 else "cancelled")
                elif rec.attempt < MAX_ATTEMPTS:
                    log.warning("job %s: task %s, resubmitting", job_id, status)
                    self._submit(rec, rec.attempt + 1)
                else:
                    self._finish(rec, "failed", "lost contact with the Dask cluster too often")

    def _task_error(self, rec: JobRecord, exc: BaseException | None) -> None:
        name = type(exc).__name__ if exc is not None else "unknown error"
        if name == "KilledWorker":
            message = ("the worker running this job died too many times (out of memory, or killed); "
                       "the results of the CLs finished so far are kept")
        else:
            message = f"worker error: {name}: {exc}"
        self._finish(rec, "failed", message)
