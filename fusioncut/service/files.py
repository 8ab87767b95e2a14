"""File names from users, and the files a job folder offers for download.

A job folder is ``<data>/jobs/<id>/`` with ``input/`` (the uploaded files and ``job.json``),
``results/`` (what the runner writes), ``progress.json`` (written by the worker), and the flags
the worker checks after each CL: ``cancel`` (stop for good) and ``suspend`` (stop to be resumed
when the service starts again). Every name that comes from a request (upload file names, the
paths inside a submitted job, the ``{name}`` of a download) is checked by :func:`check_name`: a
single plain file name, never a path, so nothing can be read or written outside the job folder.
"""
from __future__ import annotations

import re
import unicodedata
from dataclasses import dataclass
from pathlib import Path

from fusioncut.errors import InputError

# Letters and digits of any script (``résumé.nc``) and a few separators; must start with a letter or
# digit (no hidden files, no ".."). Checked on the NFC form, which is also the name kept, so that
# "é" typed as e + combining accent (as macOS names files) and as one letter is one name. NFC, not
# NFKC: NFKC would turn look-alikes such as the fullwidth solidus into "/", NFC leaves them as they
# are and the pattern refuses them, like control and direction-override characters.
_SAFE = re.compile(r"^[^\W_][\w.+()\- ]{0,127}$")
MAX_NAME_BYTES = 255  # a file name's limit on Linux file systems, in UTF-8 bytes

INPUT_DIR = "input"
RESULTS_DIR = "results"
PROGRESS_FILE = "progress.json"
CANCEL_FILE = "cancel"
SUSPEND_FILE = "suspend"  # the embedded cluster is stopping: checkpoint and stop, to be resumed
JOB_FILE = "_job.json"  # "_" first: no upload can have this name (see check_name)

# What a results folder may offer, and how it is served.
DOWNLOAD_TYPES = {
    ".csv": "text/csv",
    ".parquet": "application/vnd.apache.parquet",
    ".json": "application/json",
    ".png": "image/png",
    ".svg": "image/svg+xml",
    ".step": "model/step",
    ".stp": "model/step",
    ".stl": "model/stl",
    ".glb": "model/gltf-binary",
    ".log": "text/plain",
}


def check_name(name: str, what: str = "file name") -> str:
    """``name`` in its NFC form when that is a safe plain file name; else an :class:`InputError` saying why."""
    if not isinstance(name, str) or not name:
        raise InputError(f"{what} is empty")
    if "/" in name or "\\" in name or name in (".", ".."):
        raise InputError(f"{what} {name!r} is not a plain file name (no folders or '..' allowed)")
    name = unicodedata.normalize("NFC", name)
    if name != name.strip() or not _SAFE.match(name):
        raise InputError(f"{what} {name!r} has characters other than letters, digits and . _ - + ( ) space, "
                         "or does not start with a letter or digit")
    if len(name.encode("utf-8")) > MAX_NAME_BYTES:
        raise InputError(f"{what} {name[:40]!r}... is longer than {MAX_NAME_BYTES} bytes (UTF-8)")
    return name


@dataclass(frozen=True)
class ResultFile:
    name: str
    size: int
    media_type: str


def result_files(results_dir: Path) -> list[ResultFile]:
    """The downloadable files of a results folder (top level only, known types, no temporaries)."""
    if not results_dir.is_dir():
        return []
    out = []
    for p in sorted(results_dir.iterdir()):
        media = DOWNLOAD_TYPES.get(p.suffix.lower())
        if media is None or not p.is_file() or p.is_symlink() or not _SAFE.match(p.name):
            continue
        try:
            size = p.stat().st_size
        except OSError:  # replaced between listing and stat (a flush); it will be back next time
            continue
        out.append(ResultFile(p.name, size, media))
    return out


def find_result_file(results_dir: Path, name: str) -> ResultFile | None:
    """The listed file called ``name``: downloads are looked up in the listing, never joined blindly."""
    check_name(name)
    return next((f for f in result_files(results_dir) if f.name == name), None)
