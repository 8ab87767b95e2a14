"""Kernel calls under a wall-time budget they cannot ignore (``EngineOptions.kernel_budget_s``).

An OCCT Boolean runs in C++ without returning to Python: a thread cannot stop it, a signal handler
written in Python only runs once it returns, and on a real program one ran for over ten minutes, deaf
to Ctrl-C. So a guarded call runs in a **child process** that the caller can kill:

1. The process forks one child at its first guarded call and keeps it (:func:`stop_worker` ends it;
   the engine does at the end of a run). Each call is sent to it as a length-prefixed pickle over a
   pipe, shapes as binary BRep (:func:`shape_bytes`: doubles and tolerances kept exactly, so the
   child's Boolean is the one this process would run); the answer comes back the same way.
2. The caller waits on the answer with ``select`` until the CL's :class:`Deadline`; past it, the
   child is killed (SIGKILL: no cooperation needed) and reaped, :class:`KernelBudgetExceeded` is
   raised, and the next call forks a fresh child.
3. A Ctrl-C while the caller waits (main thread only) kills the child at once, runs the handler that
   was installed (the runner's first Ctrl-C only asks to stop after the CL) and raises
   ``KeyboardInterrupt`` out of the engine: the CL cannot finish without its child, it is not
   recorded and nothing of it is applied (see :mod:`~fusioncut.engines.brep.solid_cut`), so a resumed
   run computes it again. The child ignores SIGINT itself (the terminal sends it to the whole process
   group), dies with its parent (``PR_SET_PDEATHSIG``) and leaves when its request pipe closes.

Why one kept child and not a fork per call: a fork of a 375 MB process cost 20-35 ms here (the page
tables, then the exit's unmapping), as much as a typical cell's Boolean; sending a cell of a few
hundred faces costs about a millisecond each way (``docs/kernel-budget.md``).

Invariants: at most one child per process, and none once the engine's run ended or a call was
killed. The child runs the kernel on one thread: OCCT's thread pool, once started in the parent, has
no threads in a forked child, and a parallel Boolean there waited forever (measured: it ran into the
budget). An exception in the child comes back as the same class where it pickles, else as
``RuntimeError`` naming it; a child that died is a :class:`~fusioncut.errors.KernelFailure`.

Why not OCCT's cooperative break (``Message_ProgressIndicator::UserBreak``, which BOPAlgo polls
between its stages): OCP exposes the class without a constructor, so Python cannot subclass it; and
a poll only helps where the kernel polls, while a hang inside one intersection of two surfaces never
reaches the next poll. The child is the guarantee.

Where ``os.fork`` does not exist the calls run in this process, unguarded (logged once).
"""
from __future__ import annotations

import contextvars
import io
import logging
import os
import pickle
import select
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TypeVar

from OCP.BinTools import BinTools
from OCP.TopoDS import TopoDS_Shape

from fusioncut.errors import FusionCutError, KernelFailure

__all__ = ["Deadline", "KernelBudgetExceeded", "current_deadline", "guarded", "in_child", "shape_bytes",
           "shape_from_bytes", "stop_worker", "within"]

log = logging.getLogger("fusioncut.engine")
T = TypeVar("T")

# True in the kernel's child: a guarded call made there runs in place
_IN_CHILD = False
_warned_no_fork = False


class KernelBudgetExceeded(FusionCutError):
    """A guarded kernel call ran past its budget and was killed (``what``: the call; seconds).

    Not a ``RuntimeError`` nor a :class:`~fusioncut.errors.BooleanFailure`: the retry ladders,
    which catch those, must not run the call again (it would only hang again; the CL's budget is spent).
    """

    def __init__(self, what: str, budget_s: float, elapsed_s: float) -> None:
        self.what, self.budget_s, self.elapsed_s = what, budget_s, elapsed_s
        super().__init__(f"{what} ran past the kernel budget of {budget_s:g} s (kernel_budget_s; killed after "
                         f"{elapsed_s:.3g} s)")

    def __reduce__(self):
        return type(self), (self.what, self.budget_s, self.elapsed_s)


@dataclass
class Deadline:
    """The wall-time budget (s) of one CL's guarded kernel calls, counted from ``start``
    (``time.monotonic``); ``budget_s`` None: unlimited, the calls run in this process."""

    budget_s: float | None
    start: float = field(default_factory=time.monotonic)

    @property
    def guards(self) -> bool:
        """Whether calls run in a killable child (a budget, fork available, not already in a child)."""
        return self.budget_s is not None and not _IN_CHILD and _can_fork()

    def left(self) -> float:
        """Seconds left (may be ≤ 0); infinite without a budget."""
        return float("inf") if self.budget_s is None else self.budget_s - (time.monotonic() - self.start)


def in_child() -> bool:
    """Whether this process is the kernel's child."""
    return _IN_CHILD


_DEADLINE: contextvars.ContextVar[Deadline | None] = contextvars.ContextVar("fusioncut_kernel_deadline", default=None)


@contextmanager
def within(deadline: Deadline) -> Iterator[None]:
    """Kernel calls made inside that guard themselves (:func:`current_deadline`: the sweeps' fuses of
    tool copies, :func:`~fusioncut.engines.brep.occ.fuse_all`) run under ``deadline``; for the
    constructions whose Booleans sit deep in helpers, where passing a deadline down every call
    would reach functions that mostly run none."""
    token = _DEADLINE.set(deadline)
    try:
        yield
    finally:
        _DEADLINE.reset(token)


def current_deadline() -> Deadline | None:
    """The deadline of the innermost :func:`within`, or None."""
    return _DEADLINE.get()


def _can_fork() -> bool:
    global _warned_no_fork
    if hasattr(os, "fork"):
        return True
    if not _warned_no_fork:
        _warned_no_fork = True
        log.warning("no os.fork on this platform: kernel calls run without their time budget")
    return False


def shape_bytes(shape: TopoDS_Shape) -> bytes:
    """``shape`` as binary BRep (doubles kept exactly, sub-shape sharing kept within the shape)."""
    stream = io.BytesIO()
    BinTools.Write_s(shape, stream)
    return stream.getvalue()


def shape_from_bytes(data: bytes) -> TopoDS_Shape:
    shape = TopoDS_Shape()
    BinTools.Read_s(shape, io.BytesIO(data))
    return shape


def guarded(call: Callable[..., T], args: tuple, deadline: Deadline, what: str) -> T:
    """``call(*args)`` in the kernel's child process when ``deadline.guards``, else here.

    ``call`` is a module-level function and ``args`` and what it returns are picklable (shapes as
    :func:`shape_bytes`). Raises :class:`KernelBudgetExceeded` when the deadline passes first (at
    once when it already has), the child's exception when it raised one, ``KeyboardInterrupt`` on
    Ctrl-C (the child killed).
    """
    if not deadline.guards:
        return call(*args)
    if deadline.left() <= 0.0:
        raise KernelBudgetExceeded(what, deadline.budget_s, time.monotonic() - deadline.start)
    with _LOCK:  # one child, one pipe: the calls of runs in several threads of a process take turns
        return _worker().call(call, args, deadline, what)


def stop_worker() -> None:
    """End this process's kernel child (it is forked again at the next guarded call)."""
    global _WORKER
    with _LOCK:
        if _WORKER is not None and _WORKER.parent == os.getpid():
            _WORKER.stop()
        _WORKER = None


_WORKER: _KernelChild | None = None
_LOCK = threading.RLock()


def _worker() -> _KernelChild:
    global _WORKER
    if _WORKER is None or _WORKER.parent != os.getpid():  # none yet, or the one of the process we forked from
        _WORKER = _KernelChild()
    return _WORKER


class _KernelChild:
    """The child process that runs this process's guarded calls, one at a time, each sent as a
    length-prefixed pickle over a pipe and answered the same way; forked at the first call, again
    after it was killed or died."""

    def __init__(self) -> None:
        self.parent = os.getpid()
        self.pid: int | None = None
        self.requests = self.answers = -1

    def call(self, call: Callable[..., T], args: tuple, deadline: Deadline, what: str) -> T:
        request = pickle.dumps((call, args), protocol=pickle.HIGHEST_PROTOCOL)
        for attempt in (0, 1):
            if self.pid is None:
                self._fork()
            try:
                with _killing_on_sigint(self):
                    _write_frame(self.requests, request)
                    answer = _read_frame(self.answers, deadline)
            except BrokenPipeError:  # the child died between calls: fork a fresh one, once
                self.stop()
                if attempt:
                    raise KernelFailure(f"{what}: the kernel's child process died") from None
                continue
            except BaseException:
                self.stop()
                raise
            if answer is None:
                self.stop()
                raise KernelBudgetExceeded(what, deadline.budget_s, time.monotonic() - deadline.start)
            if not answer:
                self.stop()
                raise KernelFailure(f"{what}: the kernel's child process ended without an answer "
                                    "(killed or crashed)")
            ok, value = pickle.loads(answer)
            if ok:
                return value
            raise value
        raise AssertionError("unreachable")

    def _fork(self) -> None:
        to_child, requests = os.pipe()
        answers, from_child = os.pipe()
        pid = os.fork()
        if pid == 0:  # never returns
            os.close(requests)
            os.close(answers)
            _serve(to_child, from_child)
        os.close(to_child)
        os.close(from_child)
        self.pid, self.requests, self.answers = pid, requests, answers

    def stop(self) -> None:
        """Kill the child (it may be in a call) and reap it; close the pipes."""
        if self.pid is None:
            return
        for fd in (self.requests, self.answers):
            try:
                os.close(fd)
            except OSError:
                pass
        try:
            os.kill(self.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        try:
            os.waitpid(self.pid, 0)
        except ChildProcessError:
            pass
        self.pid, self.requests, self.answers = None, -1, -1


def _serve(requests: int, answers: int) -> None:
    """The child's loop: answer each request until the parent closes the pipe; never returns."""
    global _IN_CHILD
    _IN_CHILD = True
    code = 0
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        _die_with_parent()
        while True:
            request = _read_frame(requests, None)
            if not request:
                break
            try:
                call, args = pickle.loads(request)
                answer = pickle.dumps((True, call(*args)), protocol=pickle.HIGHEST_PROTOCOL)
            except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
                try:
                    answer = pickle.dumps((False, exc), protocol=pickle.HIGHEST_PROTOCOL)
                    pickle.loads(answer)
                except Exception:  # noqa: BLE001 - an exception that does not pickle
                    answer = pickle.dumps((False, RuntimeError(f"{type(exc).__name__}: {exc}")))
            _write_frame(answers, answer)
    except BaseException:  # noqa: BLE001 - the parent sees the pipe closed without an answer
        code = 1
    finally:
        os._exit(code)


def _write_frame(fd: int, payload: bytes) -> None:
    view = memoryview(len(payload).to_bytes(8, "little") + payload)
    while view:
        view = view[os.write(fd, view):]


def _read_frame(fd: int, deadline: Deadline | None) -> bytes | None:
    """One length-prefixed payload from ``fd``; b"" at the end of the pipe, None when ``deadline``
    (None: no deadline) passes first."""
    head = _read_exactly(fd, 8, deadline)
    if not head:
        return head
    return _read_exactly(fd, int.from_bytes(head, "little"), deadline)


def _read_exactly(fd: int, n: int, deadline: Deadline | None) -> bytes | None:
    chunks, got = [], 0
    while got < n:
        if deadline is not None:
            left = deadline.left()
            if left <= 0.0:
                return None
            ready, _, _ = select.select([fd], [], [], left)
            if not ready:
                continue
        chunk = os.read(fd, min(n - got, 1 << 20))
        if not chunk:
            return b""
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def _die_with_parent() -> None:
    """Linux: the child is sent SIGKILL when its parent dies (so none is left running)."""
    if _LIBC is not None:
        _LIBC.prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG


def _libc():
    """The C library, loaded once here in the parent, not by each child after its fork."""
    try:
        import ctypes

        return ctypes.CDLL(None, use_errno=True)
    except Exception:  # noqa: BLE001 - not Linux: the budget still ends a child
        return None


_LIBC = _libc()


class _killing_on_sigint:
    """While active (main thread only), SIGINT kills the child first, then runs the handler that was
    installed (the runner's asks to stop after the CL; it is asked, and the wait ends with
    ``KeyboardInterrupt`` as well: the CL cannot finish without its child)."""

    def __init__(self, child: _KernelChild) -> None:
        self.child = child
        self.previous = None

    def __enter__(self) -> _killing_on_sigint:
        if threading.current_thread() is threading.main_thread() \
                and signal.getsignal(signal.SIGINT) not in (signal.SIG_IGN, None):
            self.previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum, frame) -> None:
        self.child.stop()
        if callable(self.previous):
            self.previous(signum, frame)  # the runner's first Ctrl-C only asks; a second one raises
        raise KeyboardInterrupt

    def __exit__(self, *exc: object) -> None:
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
