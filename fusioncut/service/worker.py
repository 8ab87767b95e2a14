"""What a Dask worker runs for one service job: :func:`fusioncut.runner.run_job`, the CLI's code.

The worker talks to the service only through the job folder, so it works the same in the embedded
cluster and on another host sharing the data folder:

* ``progress.json`` — rewritten atomically (temporary file + ``os.replace``) at most every
  ``progress_interval_s`` and once at the end, with the state, CLs done / total, rate, ETA, the
  current operation and the worker's pid and host. The final write carries the final state, so a
  service restarted while the job ran learns the outcome from the folder.
* ``cancel`` — a flag file the service creates; the ``on_cl`` callback checks it after every CL and
  stops the run the way Ctrl-C stops the CLI (``KeyboardInterrupt``), so the runner flushes the
  results of every finished CL before returning.

A job whose worker dies is run again by Dask on another worker; ``run_job(..., resume=True)``
continues from the checkpoint in the results folder, so the results equal an uninterrupted run.
"""
from __future__ import annotations

import json
import logging
import os
import socket
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fusioncut.errors import FusionCutError
from fusioncut.service.files import CANCEL_FILE, INPUT_DIR, JOB_FILE, PROGRESS_FILE, RESULTS_DIR, SUSPEND_FILE
from fusioncut.service.portable import job_folders, portable, portable_text

if TYPE_CHECKING:
    from fusioncut.io.job import Job

log = logging.getLogger("fusioncut.service.worker")

PLOTS = {"program.png": "plot_program", "heatmap.png": "plot_heatmap"}


class JobCancelled(KeyboardInterrupt):
    """Raised from ``on_cl`` when the cancel flag is set: a ``KeyboardInterrupt`` so that the runner
    stops exactly as on Ctrl-C and keeps every finished CL."""


class JobSuspended(KeyboardInterrupt):
    """Raised from ``on_cl`` when the suspend flag is set (the service is stopping its embedded
    cluster): the runner stops as on Ctrl-C, with a checkpoint at the CL reached, to be resumed."""


def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    # A unique temporary name: two attempts of the same job (a resubmit racing a slow dying worker)
    # must not write through each other's half-written file.
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_text(json.dumps(data), encoding="utf-8")
    os.replace(tmp, path)


def read_progress(job_dir: Path) -> dict[str, Any] | None:
    try:
        data = json.loads((job_dir / PROGRESS_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


class ProgressReporter:
    """The ``on_cl`` callback: throttled progress.json writes and the cancel check."""

    def __init__(self, job_dir: Path, attempt: int, interval_s: float):
        self.job_dir = job_dir
        self.path = job_dir / PROGRESS_FILE
        self.cancel_path = job_dir / CANCEL_FILE
        self.suspend_path = job_dir / SUSPEND_FILE
        self.interval_s = interval_s
        self.attempt = attempt
        self.started = time.time()
        # seconds of every earlier attempt (progress.json's spent_s), so that "N CLs in T s" counts
        # all the work on a job that was resumed, and of this attempt since it was handed over
        self.spent_before = 0.0
        self.attempt_started = time.time()
        self.done = 0
        self.total = 0
        self.first_done: int | None = None  # CLs already done when this attempt started (resume)
        self.operation = ""
        self.last_write = 0.0
        self.lock = threading.Lock()

    def snapshot(self, state: str, **extra: Any) -> dict[str, Any]:
        now = time.time()
        new = self.done - (self.first_done or 0)
        elapsed = max(now - self.started, 1e-9)
        rate = new / elapsed if new > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 and self.total else None
        return {"state": state, "done": self.done, "total": self.total, "operation": self.operation,
                "rate_cl_s": rate, "eta_s": eta, "attempt": self.attempt, "pid": os.getpid(),
                "host": socket.gethostname(), "started": self.started, "updated": now,
                "spent_s": self.spent(now), **extra}

    def spent(self, now: float | None = None) -> float:
        """Seconds spent on the job by every attempt so far, this one included."""
        return self.spent_before + max(0.0, (time.time() if now is None else now) - self.attempt_started)

    def write(self, state: str, **extra: Any) -> None:
        with self.lock:
            write_json_atomic(self.path, self.snapshot(state, **extra))
            self.last_write = time.monotonic()

    def on_start(self, plan: Any) -> None:
        """The runner's plan: the total, and how many CLs a checkpoint already holds."""
        self.total = plan.total
        self.done = self.first_done = plan.start_at
        self.started = time.time()
        self.write("running")

    def __call__(self, m: Any, total: int) -> None:
        if self.first_done is None:
            # CL indices are program order, so on a resumed run the first CL we see tells how many
            # were done before this attempt; the rate and ETA count only this attempt's work.
            self.first_done = m.cl_index
        self.total = total
        self.done = max(self.done, m.cl_index + 1)
        self.operation = m.operation
        if time.monotonic() - self.last_write >= self.interval_s:
            self.write("running")
        if self.cancel_path.exists():
            raise JobCancelled()
        if self.suspend_path.exists():
            raise JobSuspended()


class _ThreadFilter(logging.Filter):
    """Keep only records of one thread: a worker with several threads runs several jobs at once."""

    def __init__(self, ident: int):
        super().__init__()
        self.ident = ident

    def filter(self, record: logging.LogRecord) -> bool:
        return record.thread == self.ident


def _make_plots(results_dir: Path) -> None:
    from fusioncut.io.results import load_results
    from fusioncut.viz import plots

    results = portable(load_results(results_dir), results_dir.parent)
    if not len(results.cl):
        return
    for name, fn in PLOTS.items():
        getattr(plots, fn)(results, out=results_dir / name)


def single_process(job: Job) -> Job:
    """``job`` without the run options ``workers`` and ``scheduler``.

    A service job is already one Dask task with a worker process of its own: the service shares its
    workers out by jobs, and a LocalCluster cannot be started inside a (daemonic) Dask worker. The
    options change neither the job hash nor the results, so the job's checkpoints still resume.
    """
    if job.options.workers == 1 and job.options.scheduler is None:
        return job
    log.info("the service runs each job on one worker: options workers=%d, scheduler=%s ignored",
             job.options.workers, job.options.scheduler)
    return job.model_copy(update={"options": job.options.model_copy(update={"workers": 1, "scheduler": None})})


def execute_job(job_dir: str, attempt: int = 1, progress_interval_s: float = 0.25) -> dict[str, Any]:
    """Run the job in ``job_dir``; returns ``{"state": done|cancelled|failed|suspended, "message", "done",
    "total"}`` (``suspended``: stopped by the suspend flag with a checkpoint, to be submitted again).

    Input errors and failures inside the run are returned as a ``failed`` state with a one-line
    message (the traceback goes to the job's log file only); exceptions escape only for problems of
    the worker itself, which Dask reports.
    """
    from fusioncut.io.job import Job
    from fusioncut.runner import run_job

    folder = Path(job_dir)
    inputs, results_dir = folder / INPUT_DIR, folder / RESULTS_DIR
    results_dir.mkdir(parents=True, exist_ok=True)
    reporter = ProgressReporter(folder, attempt, progress_interval_s)
    prev = read_progress(folder) or {}
    reporter.done, reporter.total = int(prev.get("done", 0)), int(prev.get("total", 0))
    reporter.spent_before = float(prev.get("spent_s") or 0.0)

    handler = logging.FileHandler(results_dir / "fusioncut.log", mode="a", encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    handler.addFilter(_ThreadFilter(threading.get_ident()))
    pkg_log = logging.getLogger("fusioncut")
    old_level = pkg_log.level
    pkg_log.addHandler(handler)
    if pkg_log.getEffectiveLevel() > logging.INFO:
        pkg_log.setLevel(logging.INFO)
    try:
        if reporter.cancel_path.exists():
            reporter.write("cancelled", message="cancelled before it started")
            return {"state": "cancelled", "message": "cancelled before it started", "done": reporter.done,
                    "total": reporter.total}
        if reporter.suspend_path.exists():
            return {"state": "suspended", "message": "", "done": reporter.done, "total": reporter.total}
        reporter.write("running")
        log.info("attempt %d on %s pid %d", attempt, socket.gethostname(), os.getpid())
        try:
            job = single_process(Job.model_validate_json((inputs / JOB_FILE).read_text(encoding="utf-8")))
            result = run_job(job, inputs, results_dir, on_cl=reporter, resume=True, on_start=reporter.on_start)
        except FusionCutError as exc:
            message = portable_text(str(exc), *job_folders(folder))
            log.error("%s", message)
            reporter.write("failed", message=message)
            return {"state": "failed", "message": message, "done": reporter.done, "total": reporter.total}
        except Exception as exc:  # noqa: BLE001 - reported as the job's failure, not the worker's
            log.exception("job failed")
            message = portable_text(f"internal error: {type(exc).__name__}: {exc}", *job_folders(folder))
            reporter.write("failed", message=message)
            return {"state": "failed", "message": message, "done": reporter.done, "total": reporter.total}
        if result.interrupted and not reporter.cancel_path.exists():
            # suspended (or interrupted some other way): not an outcome, the job goes on next time
            message = f"suspended after {reporter.done} of {reporter.total} CLs"
            log.info("%s", message)
            reporter.write("suspended", message=message)
            return {"state": "suspended", "message": message, "done": reporter.done, "total": reporter.total}
        try:
            _make_plots(results_dir)
        except Exception:  # noqa: BLE001 - the tables are the result; a plot problem must not fail the job
            log.exception("plots failed")
        if result.interrupted:
            message = f"cancelled after {reporter.done} of {reporter.total} CLs; their results are kept"
            reporter.write("cancelled", message=message)
            return {"state": "cancelled", "message": message, "done": reporter.done, "total": reporter.total}
        failed = sum(op.failed for op in result.operations.values())
        # every CL of the job (those of a resumed checkpoint too) in the time of every attempt
        message = f"{sum(op.cls for op in result.operations.values())} CLs in {reporter.spent():.1f} s"
        if attempt > 1 or result.resumed_from:
            message += f" ({attempt} attempts)" if attempt > 1 else " (resumed)"
        if failed:
            message += f"; {failed} failed (see the cl table's reason column)"
        reporter.done = reporter.total = max(reporter.total, reporter.done)
        reporter.write("done", message=message)
        return {"state": "done", "message": message, "done": reporter.done, "total": reporter.total}
    finally:
        pkg_log.removeHandler(handler)
        pkg_log.setLevel(old_level)
        handler.close()
