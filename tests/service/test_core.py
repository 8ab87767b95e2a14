"""The job life cycle of the service core with a stand-in for Dask: what a (re)start does with the
jobs it finds, how task outcomes move job states, and a cluster that refuses a job."""
from __future__ import annotations

import json
import time

import pytest

from fusioncut.service.core import MAX_ATTEMPTS, ClusterUnavailable, Service
from fusioncut.service.settings import Settings
from fusioncut.service.submit import Checked


class FakeFuture:
    def __init__(self, status="pending", result=None, exception=None):
        self.status, self._result, self._exception = status, result, exception

    def result(self, timeout=None):
        return self._result

    def exception(self, timeout=None):
        return self._exception


class FakeExecutor:
    """Records what the service asks of the cluster; ``live`` are (job, attempt) tasks it still runs."""

    cluster = object()  # an embedded cluster
    address = "fake://"

    def __init__(self, live=()):
        self.futures, self.submitted, self.attached, self.cancelled = {}, [], [], []
        self.live = set(live)
        self.refuse = False

    def start(self):
        pass

    def close(self):
        pass

    def submit(self, job_id, job_dir, attempt):
        if self.refuse:
            raise OSError("scheduler gone")
        self.submitted.append((job_id, attempt))
        self.futures[job_id] = FakeFuture()

    def attach(self, job_id, attempt):
        self.attached.append((job_id, attempt))
        self.futures[job_id] = FakeFuture()

    def task_state(self, job_id, attempt):
        return "processing" if (job_id, attempt) in self.live else None

    def cancel(self, job_id):
        self.cancelled.append(job_id)
        self.futures[job_id].status = "cancelled"

    def forget(self, job_id):
        self.futures.pop(job_id, None)

    def active(self):
        return dict(self.futures)


def _service(tmp_path, executor):
    # no monitor ticks of its own (poll once an hour): the tests call tick() themselves
    # a stop waits up to 2 s for tasks still pending (the fakes of most tests never end)
    return Service(Settings(data_dir=tmp_path, api_keys=("key-0123456789abcdef",), warm_up=False,
                            poll_interval_s=3600, stop_timeout_s=2.0), executor)


def _job(svc, job_id, state, attempt=1, progress=None, flags=(), deleted=False):
    folder = svc.jobs_dir / job_id
    (folder / "input").mkdir(parents=True)
    svc.store.add(job_id, "owner", job_id, f"jobs/{job_id}", 10)
    svc.store.update(job_id, state=state, attempt=attempt, deleted_at=1.0 if deleted else None)
    if progress is not None:
        (folder / "progress.json").write_text(json.dumps({"attempt": attempt, "done": 3, "total": 10, **progress}))
    for f in flags:
        (folder / f).touch()
    return folder


def test_a_start_adopts_outcomes_follows_live_tasks_and_resubmits_the_rest(tmp_path):
    first = _service(tmp_path, FakeExecutor())
    first.start()
    _job(first, "adopt", "running", progress={"state": "done", "message": "10 CLs in 1 s", "started": 5.0})
    _job(first, "flagged", "running", progress={"state": "running"}, flags=("cancel",))
    resub = _job(first, "resub", "running", attempt=2, progress={"state": "suspended"}, flags=("suspend",))
    _job(first, "live", "running", progress={"state": "running"})
    gone = _job(first, "gone", "done", deleted=True)
    first.stop()

    ex = FakeExecutor(live={("live", 1)})
    svc = _service(tmp_path, ex)
    svc.start()
    try:
        states = {r.id: (r.state, r.attempt) for r in svc.store.list()}
        assert states == {"adopt": ("done", 1), "flagged": ("cancelled", 1), "resub": ("queued", 3),
                          "live": ("running", 1)}
        assert svc.store.get("adopt").message == "10 CLs in 1 s" and svc.store.get("adopt").started_at == 5.0
        assert ex.submitted == [("resub", 3)] and not (resub / "suspend").exists()
        assert ex.attached == [("live", 1)]  # still running on the cluster: followed, not started twice
        assert svc.store.get("gone") is None and not gone.exists()
    finally:
        svc.stop()


def test_task_outcomes_move_the_job(tmp_path):
    ex = FakeExecutor()
    svc = _service(tmp_path, ex)
    svc.start()
    try:
        for job_id in ("ok", "suspended", "killed", "early"):
            _job(svc, job_id, "running")
            ex.futures[job_id] = FakeFuture()
        ex.futures["ok"] = FakeFuture("finished", {"state": "done", "message": "fine"})
        ex.futures["suspended"] = FakeFuture("finished", {"state": "suspended"})
        killed = type("KilledWorker", (Exception,), {})("worker died")
        ex.futures["killed"] = FakeFuture("error", exception=killed)
        # the worker wrote its outcome before its task's result arrived
        (svc.jobs_dir / "early" / "progress.json").write_text(json.dumps({"attempt": 1, "state": "failed",
                                                                           "message": "x.nc:3: bad"}))
        svc.tick()
        got = {j: (svc.store.get(j).state, svc.store.get(j).message) for j in ("ok", "killed", "early")}
        assert got["ok"] == ("done", "fine") and got["early"] == ("failed", "x.nc:3: bad")
        assert got["killed"][0] == "failed" and "died too many times" in got["killed"][1]
        assert svc.store.get("suspended").state == "queued" and ("suspended", 2) in ex.submitted
        assert svc.store.get("ok").finished_at <= time.time()
        assert set(ex.futures) == {"suspended"}  # finished tasks are let go
    finally:
        svc.stop()


def test_a_job_interrupted_too_often_fails(tmp_path):
    ex = FakeExecutor()
    svc = _service(tmp_path, ex)
    svc.start()
    try:
        _job(svc, "flaky", "running", attempt=MAX_ATTEMPTS)
        ex.futures["flaky"] = FakeFuture("cancelled")  # lost by the cluster, no outcome written
        svc.tick()
        assert svc.store.get("flaky").state == "failed"
    finally:
        svc.stop()


def test_a_refused_job_leaves_nothing_behind(tmp_path):
    ex = FakeExecutor()
    svc = _service(tmp_path, ex)
    svc.start()
    try:
        ex.refuse = True
        staged = svc.jobs_dir / ".staging-x" / "input"
        staged.mkdir(parents=True)
        from fusioncut.io.job import Job

        job = Job.model_validate({"stock": {"kind": "infer"}, "toolpaths": ["a.nc"]})
        with pytest.raises(ClusterUnavailable, match="try again"):
            svc.create("owner", "j", staged, Checked(job, 5, None), "abc123")
        assert svc.store.list(include_deleted=True) == []
        assert not (svc.jobs_dir / "abc123").exists()
    finally:
        svc.stop()


def test_two_services_cannot_share_a_data_folder(tmp_path):
    from fusioncut.errors import InputError

    a = _service(tmp_path, FakeExecutor())
    a.start()
    try:
        with pytest.raises(InputError, match="another FusionCut service"):
            _service(tmp_path, FakeExecutor()).start()
    finally:
        a.stop()
    b = _service(tmp_path, FakeExecutor())  # free again once the first has stopped
    b.start()
    b.stop()


def test_a_restart_resubmits_jobs_oldest_first(tmp_path):
    first = _service(tmp_path, FakeExecutor())
    first.start()
    for job_id in ("c", "a", "b"):  # created in this order: neither the ids' nor the reverse order
        _job(first, job_id, "queued")
        time.sleep(0.01)
    first.stop()
    ex = FakeExecutor()
    svc = _service(tmp_path, ex)
    svc.start()
    try:
        assert ex.submitted == [("c", 2), ("a", 2), ("b", 2)]
    finally:
        svc.stop()


class _StoppingFuture(FakeFuture):
    """A task that reaches its next CL (and checkpoint) ``after_s`` after its suspend flag appears."""

    def __init__(self, flag, after_s):
        super().__init__()
        self.flag, self.after_s, self.seen = flag, after_s, None

    @property
    def status(self):
        if self.flag.exists() and self.seen is None:
            self.seen = time.monotonic()
        return "finished" if self.seen is not None and time.monotonic() - self.seen >= self.after_s else "pending"

    @status.setter
    def status(self, value):
        pass


def test_a_stop_waits_for_running_jobs_to_reach_a_checkpoint(tmp_path):
    ex = FakeExecutor()
    svc = _service(tmp_path, ex)
    svc.start()
    folder = _job(svc, "busy", "running")
    fut = ex.futures["busy"] = _StoppingFuture(folder / "suspend", after_s=0.5)
    t0 = time.monotonic()
    svc.stop()
    # the cluster is closed only once the job has stopped at its checkpoint (it used to be at once)
    assert fut.status == "finished" and time.monotonic() - t0 >= 0.5


def test_a_stop_waits_for_a_job_stuck_in_a_cl_no_longer_than_its_bound(tmp_path):
    ex = FakeExecutor()
    svc = _service(tmp_path, ex)
    svc.start()
    try:
        _job(svc, "stuck", "running")
        ex.futures["stuck"] = FakeFuture()  # never reaches its next CL
        t0 = time.monotonic()
        svc._suspend_all(timeout_s=0.5)
        assert 0.5 <= time.monotonic() - t0 < 5
    finally:
        ex.futures.clear()
        svc.stop()
