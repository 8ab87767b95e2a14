"""Service settings: where jobs live, which Dask cluster runs them, who may use the API, and limits.

Settings come from (later wins): defaults, a JSON config file (``FUSIONCUT_CONFIG`` or ``--config``),
environment variables, and ``fusioncut serve`` options. Environment variables:

=========================== ==================================================================
``FUSIONCUT_DATA_DIR``      folder for the job database and job folders (default ``fusioncut-data``)
``FUSIONCUT_SCHEDULER``     address of an external Dask scheduler (``tcp://host:8786``); unset:
                            an embedded ``LocalCluster`` of worker processes
``FUSIONCUT_WORKERS``       worker processes of the embedded cluster (default: CPU count)
``FUSIONCUT_API_KEYS``      API keys, separated by commas
``FUSIONCUT_API_KEYS_FILE`` file with one API key per line (``#`` starts a comment)
``FUSIONCUT_MAX_UPLOAD_MB`` largest request body accepted, MiB (default 64)
``FUSIONCUT_MAX_CLS``       largest job accepted, in CL segments (default 200000)
``FUSIONCUT_MAX_SLICES``    largest job accepted, in slice evaluations: per CL the tool's flute
                            length over ``slice_height`` (default 10000000)
``FUSIONCUT_MAX_STREAMS``   event streams open at once per API key (default 8)
``FUSIONCUT_FRONTEND_DIR``  the front end folder (default: ``frontend/`` next to the package)
=========================== ==================================================================

The config file holds the same settings under their field names, e.g.
``{"scheduler": "tcp://10.0.0.5:8786", "api_keys_file": "/etc/fusioncut/keys", "max_cls": 50000}``.

Keys are never stored: the job database keeps the SHA-256 of the key that owns each job. When no
key is configured at all, the service creates ``<data_dir>/api_keys.txt`` with one random key and
uses it, so that a fresh install is never open to anyone who can reach the port.
"""
from __future__ import annotations

import hashlib
import json
import os
import secrets
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from fusioncut.engines.sizing import Budget
from fusioncut.errors import InputError

MIN_KEY_LENGTH = 16  # shorter keys are guessable; refuse them rather than run with them


def default_frontend_dir() -> Path:
    """``frontend/`` of the source tree (the package is installed editable, or run from a checkout)."""
    return Path(__file__).resolve().parents[2] / "frontend"


@dataclass(frozen=True)
class Settings:
    data_dir: Path = Path("fusioncut-data")
    scheduler: str | None = None
    workers: int = 0  # 0: one per CPU
    api_keys: tuple[str, ...] = ()
    api_keys_file: Path | None = None
    max_upload_bytes: int = 64 * 1024 * 1024
    max_cls: int = 200_000
    # 200,000 CLs of a tool with 50 slices (a 50 mm flute at the default 1 mm slice height)
    max_slices: int = 10_000_000
    # Event streams a key may hold open; each polls the store every poll interval.
    max_streams_per_key: int = 8
    max_files: int = 32
    frontend_dir: Path = field(default_factory=default_frontend_dir)
    # How often the worker rewrites progress.json, seconds: often enough for a smooth bar, rarely
    # enough that a job of thousands of tiny CLs does not spend its time writing JSON.
    progress_interval_s: float = 0.25
    # Polling period of the service's monitor thread and of the event streams, seconds.
    poll_interval_s: float = 0.25
    # At a stop, how long running jobs of the embedded cluster get to reach their next CL and write
    # a checkpoint before the cluster is closed, seconds (a CL takes milliseconds to seconds).
    stop_timeout_s: float = 30.0
    # Import the readers and the kernel in the background at start, so the first upload is not slow.
    warm_up: bool = True

    @property
    def budget(self) -> Budget:
        """The most work one job may make (checked when it is submitted, before it is queued)."""
        return Budget(max_cls=self.max_cls, max_slices=self.max_slices,
                      raise_hint="this service's limits are its settings max_cls / max_slices "
                                 "(FUSIONCUT_MAX_CLS / FUSIONCUT_MAX_SLICES); split the job")

    @property
    def worker_count(self) -> int:
        return self.workers if self.workers > 0 else max(1, os.cpu_count() or 1)

    @classmethod
    def from_env(cls, env: dict[str, str] | None = None, config: Path | None = None, **overrides: Any) -> Settings:
        """Defaults, then the config file, then the environment, then ``overrides`` (not None)."""
        env = dict(os.environ if env is None else env)
        values: dict[str, Any] = {}
        config = config or (Path(env["FUSIONCUT_CONFIG"]) if env.get("FUSIONCUT_CONFIG") else None)
        if config is not None:
            values.update(_read_config(config))
        mapping = {
            "FUSIONCUT_DATA_DIR": ("data_dir", Path),
            "FUSIONCUT_SCHEDULER": ("scheduler", str),
            "FUSIONCUT_WORKERS": ("workers", int),
            "FUSIONCUT_API_KEYS": ("api_keys", lambda s: tuple(k.strip() for k in s.split(",") if k.strip())),
            "FUSIONCUT_API_KEYS_FILE": ("api_keys_file", Path),
            "FUSIONCUT_MAX_UPLOAD_MB": ("max_upload_bytes", lambda s: int(float(s) * 1024 * 1024)),
            "FUSIONCUT_MAX_CLS": ("max_cls", int),
            "FUSIONCUT_MAX_SLICES": ("max_slices", int),
            "FUSIONCUT_MAX_STREAMS": ("max_streams_per_key", int),
            "FUSIONCUT_FRONTEND_DIR": ("frontend_dir", Path),
        }
        for var, (name, conv) in mapping.items():
            if env.get(var):
                try:
                    values[name] = conv(env[var])
                except ValueError:
                    raise InputError(f"environment variable {var}={env[var]!r} is not valid") from None
        values.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**values)

    def with_(self, **changes: Any) -> Settings:
        return replace(self, **changes)


def _read_config(path: Path) -> dict[str, Any]:
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("config file not found", path) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", f"{path}:{exc.lineno}:{exc.colno}") from None
    if not isinstance(raw, dict):
        raise InputError("the config file must hold a JSON object", path)
    known = {f.name: f for f in fields(Settings)}
    out: dict[str, Any] = {}
    for key, value in raw.items():
        if key not in known:
            raise InputError(f"unknown setting {key!r} (known: {', '.join(sorted(known))})", path)
        if key in ("data_dir", "api_keys_file", "frontend_dir"):
            value = (path.parent / value) if value is not None else None
        elif key == "api_keys":
            value = tuple(value)
        out[key] = value
    return out


def key_hash(key: str) -> str:
    """What the job store keeps instead of a key: enough to match owners, useless to an attacker."""
    return hashlib.sha256(key.encode("utf-8")).hexdigest()


def read_key_file(path: Path) -> list[str]:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError("API key file not found", path) from None
    keys = []
    for line in text.splitlines():
        key = line.split("#", 1)[0].strip()
        if key:
            keys.append(key)
    return keys


def load_keys(settings: Settings) -> tuple[frozenset[str], Path | None]:
    """The hashes of every accepted key, and the key file created when none was configured."""
    keys = list(settings.api_keys)
    if settings.api_keys_file is not None:
        keys += read_key_file(settings.api_keys_file)
    created = None
    if not keys:
        created = settings.data_dir / "api_keys.txt"
        if created.exists():
            keys = read_key_file(created)
        if not keys:
            created.parent.mkdir(parents=True, exist_ok=True)
            key = secrets.token_urlsafe(24)
            fd = os.open(created, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write("# FusionCut API keys, one per line (created because none was configured)\n")
                f.write(key + "\n")
            keys = [key]
    short = [k for k in keys if len(k) < MIN_KEY_LENGTH]
    if short:
        raise InputError(f"{len(short)} API key(s) shorter than {MIN_KEY_LENGTH} characters; use longer random keys")
    return frozenset(key_hash(k) for k in keys), created
