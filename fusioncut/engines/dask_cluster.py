"""A Dask client for the parallel engines: an embedded ``LocalCluster`` or a running scheduler.

Both parallel engines (:mod:`fusioncut.engines.brep.parallel`, :mod:`fusioncut.engines.analytic.parallel`)
open their workers here. The embedded cluster has ``workers`` processes of one thread each; a
scheduler address instead uses every worker that scheduler has. Worker processes ignore the
terminal's Ctrl-C (:func:`children_ignore_ctrl_c`): the runner's first Ctrl-C asks for a clean stop
with a checkpoint, which needs them alive. ``distributed`` is imported only when a client is opened:
it costs a second of start-up that a single-process run saves.
"""
from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from fusioncut.errors import InputError

log = logging.getLogger("fusioncut.parallel")

CONNECT_TIMEOUT_S = 10
WORKERS_TIMEOUT_S = 60


@contextmanager
def children_ignore_ctrl_c() -> Iterator[None]:
    """Worker processes started meanwhile ignore SIGINT (Python keeps an inherited SIG_IGN).

    A terminal's Ctrl-C reaches the whole process group; the runner's first Ctrl-C asks for a clean
    stop with a checkpoint, which needs the workers alive to hand over their state.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.getsignal(signal.SIGINT)
    if previous is None:  # set outside Python: it could not be put back
        yield
        return
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def open_client(workers: int, scheduler: str | None) -> tuple[Any, Any]:
    """(client, cluster): a client of the scheduler at ``scheduler`` (cluster None), else of a new
    embedded cluster of ``workers`` processes. An unreachable scheduler or one without workers is an
    :class:`InputError` (the address is the user's)."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        try:
            client.wait_for_workers(1, timeout=WORKERS_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            close_quietly(client)
            raise InputError(f"the Dask scheduler at {scheduler} has no workers "
                             f"(waited {WORKERS_TIMEOUT_S} s)") from exc
        log.info("connected to the Dask scheduler at %s (%d workers)", scheduler,
                 len(client.scheduler_info()["workers"]))
        return client, None
    import dask

    # Dask starts its worker processes with MALLOC_TRIM_THRESHOLD_=65536, so that glibc hands
    # freed memory back to the system at once; the kernel allocates and frees many small blocks
    # per Boolean, and trimming after each free slows it down; glibc's default is kept
    keep_malloc = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}
    with children_ignore_ctrl_c(), dask.config.set(keep_malloc):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=logging.ERROR)
    try:
        client = Client(cluster)
    except BaseException:
        cluster.close()
        raise
    log.info("started a Dask cluster of %d worker processes (dashboard %s)", workers, client.dashboard_link)
    return client, cluster


def close_quietly(*things: Any) -> None:
    """Close each of ``things`` (clients, clusters; None skipped). A failure to close is logged, not
    raised: this runs on errors and Ctrl-C too, and must not hide how the run ended."""
    for what in things:
        if what is None:
            continue
        try:
            what.close()
        except Exception:  # noqa: BLE001 - nothing is left to do with it
            log.warning("closing the Dask %s failed", type(what).__name__, exc_info=True)
