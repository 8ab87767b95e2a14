"""The job store: one SQLite file holding every job's owner, state, timestamps and folder.

SQLite because the service is one process and a job record is tiny: no server to run, and the file
survives restarts next to the job folders. The schema has a version (table ``schema_version``);
:data:`MIGRATIONS` are applied in order on open, each in its own transaction, so an old database is
brought forward and a database from a newer FusionCut is refused instead of being misread.

Only the service writes the store. Workers (possibly on other hosts) report through files in the job
folder (``progress.json``), which the service reads and copies into the store.
"""
from __future__ import annotations

import sqlite3
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from fusioncut.errors import InputError

STATES = ("queued", "running", "done", "failed", "cancelled")
ACTIVE_STATES = ("queued", "running")
FINAL_STATES = ("done", "failed", "cancelled")

Migration = Callable[[sqlite3.Connection], None]


def _v1(db: sqlite3.Connection) -> None:
    db.execute(
        """CREATE TABLE jobs (
            id TEXT PRIMARY KEY,
            owner TEXT NOT NULL,             -- SHA-256 of the API key that submitted the job
            name TEXT NOT NULL,
            state TEXT NOT NULL CHECK (state IN ('queued','running','done','failed','cancelled')),
            created_at REAL NOT NULL,
            started_at REAL,
            finished_at REAL,
            folder TEXT NOT NULL,            -- job folder, relative to the data folder
            total_cls INTEGER NOT NULL DEFAULT 0,
            message TEXT NOT NULL DEFAULT '',
            attempt INTEGER NOT NULL DEFAULT 0,  -- submissions to the cluster (resubmits after restarts)
            deleted_at REAL                  -- set when deletion was asked for while a worker still ran
        )"""
    )
    db.execute("CREATE INDEX jobs_owner ON jobs (owner, created_at)")
    db.execute("CREATE INDEX jobs_state ON jobs (state)")


MIGRATIONS: list[Migration] = [_v1]


@dataclass(frozen=True)
class JobRecord:
    id: str
    owner: str
    name: str
    state: str
    created_at: float
    started_at: float | None
    finished_at: float | None
    folder: str
    total_cls: int
    message: str
    attempt: int
    deleted_at: float | None

    @property
    def active(self) -> bool:
        return self.state in ACTIVE_STATES


_COLUMNS = "id, owner, name, state, created_at, started_at, finished_at, folder, total_cls, message, attempt, deleted_at"


class JobStore:
    """Thread-safe access to the jobs table (one connection, one lock: writes are rare and small)."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.RLock()
        self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None, timeout=30)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=NORMAL")
        self.migrate()

    # -- schema -------------------------------------------------------------------------------
    @property
    def version(self) -> int:
        with self._lock:
            has = self._db.execute(
                "SELECT name FROM sqlite_master WHERE type='table' AND name='schema_version'").fetchone()
            if not has:
                return 0
            row = self._db.execute("SELECT version FROM schema_version").fetchone()
            return int(row[0]) if row else 0

    def migrate(self) -> None:
        with self._lock:
            current = self.version
            if current > len(MIGRATIONS):
                raise InputError(f"job database has schema version {current}, newer than this FusionCut "
                                 f"understands ({len(MIGRATIONS)}); upgrade FusionCut", self.path)
            for target in range(current + 1, len(MIGRATIONS) + 1):
                with self._transaction() as db:
                    if target == 1:
                        db.execute("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)")
                    MIGRATIONS[target - 1](db)
                    db.execute("DELETE FROM schema_version")
                    db.execute("INSERT INTO schema_version (version) VALUES (?)", (target,))

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                yield self._db
            except BaseException:
                self._db.execute("ROLLBACK")
                raise
            self._db.execute("COMMIT")

    def close(self) -> None:
        with self._lock:
            self._db.close()

    # -- jobs ---------------------------------------------------------------------------------
    def add(self, job_id: str, owner: str, name: str, folder: str, total_cls: int) -> JobRecord:
        with self._transaction() as db:
            db.execute("INSERT INTO jobs (id, owner, name, state, created_at, folder, total_cls) "
                       "VALUES (?, ?, ?, 'queued', ?, ?, ?)", (job_id, owner, name, time.time(), folder, total_cls))
        rec = self.get(job_id)
        assert rec is not None
        return rec

    def get(self, job_id: str, owner: str | None = None) -> JobRecord | None:
        """The job, or None when it does not exist, belongs to another owner, or is being deleted."""
        with self._lock:
            row = self._db.execute(f"SELECT {_COLUMNS} FROM jobs WHERE id = ?", (job_id,)).fetchone()
        if row is None:
            return None
        rec = JobRecord(*row)
        if owner is not None and (rec.owner != owner or rec.deleted_at is not None):
            return None
        return rec

    def list(self, owner: str | None = None, states: tuple[str, ...] | None = None,
             include_deleted: bool = False) -> list[JobRecord]:
        sql, args = f"SELECT {_COLUMNS} FROM jobs WHERE 1=1", []
        if owner is not None:
            sql += " AND owner = ?"
            args.append(owner)
        if states:
            sql += f" AND state IN ({','.join('?' * len(states))})"
            args.extend(states)
        if not include_deleted:
            sql += " AND deleted_at IS NULL"
        sql += " ORDER BY created_at DESC, id"
        with self._lock:
            return [JobRecord(*r) for r in self._db.execute(sql, args).fetchall()]

    def update(self, job_id: str, **values: object) -> None:
        allowed = {"state", "started_at", "finished_at", "message", "attempt", "deleted_at", "total_cls"}
        bad = set(values) - allowed
        if bad:
            raise ValueError(f"cannot update {sorted(bad)}")
        if "state" in values and values["state"] not in STATES:
            raise ValueError(f"unknown state {values['state']!r}")
        cols = ", ".join(f"{k} = ?" for k in values)
        with self._transaction() as db:
            db.execute(f"UPDATE jobs SET {cols} WHERE id = ?", (*values.values(), job_id))

    def remove(self, job_id: str) -> None:
        with self._transaction() as db:
            db.execute("DELETE FROM jobs WHERE id = ?", (job_id,))
