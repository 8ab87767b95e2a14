"""What the service shows of a job names its files the way the user named them, never by server path.

The runner records the paths it read and wrote: in a service job these are in the job's folder,
``<data>/jobs/<id>/input/tiny.nc`` in the ``cl`` table's ``file`` column, ``<data>/jobs/<id>/results/
failures`` as the engine option ``failure_dir`` in ``metadata.json`` and in the Parquet tables'
metadata, and both in error messages. Every input of a job is one flat folder of checked names
(:func:`fusioncut.service.files.check_name`), so an input file's path relative to ``input/`` is the
name the user uploaded, and anything else in the job folder is named relative to the job folder.

The result files stay as the runner wrote them (a resumed run appends to them); the rewriting is done
where they leave the service: the messages of :mod:`~fusioncut.service.worker` and
:mod:`~fusioncut.service.submit`, the tables the API answers with (:func:`portable`) and the
downloads (:func:`portable_download`).
"""
from __future__ import annotations

import io
import json
import os
import threading
from collections import OrderedDict
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from fusioncut.service.files import INPUT_DIR

# result files whose text may hold a server path, by suffix; the others (images, meshes) do not
_REWRITTEN = (".csv", ".log", ".json", ".parquet")
_CHUNK_BYTES = 1 << 20
_SIZES_KEPT = 256  # versions of result files whose portable size is remembered
_sizes: OrderedDict[tuple, int] = OrderedDict()
_sizes_lock = threading.Lock()


def portable_text(text: str, *folders: Path | str) -> str:
    """``text`` with each of ``folders`` (innermost first) left out of the paths that start with it:
    ``<folder>/name`` becomes ``name`` and ``<folder>`` alone becomes ``.``."""
    for f in folders:
        text = text.replace(f"{f}{os.sep}", "").replace(str(f), ".")
    return text


def job_folders(job_dir: Path) -> tuple[Path, Path]:
    """The folders :func:`portable_text` leaves out for a job: its inputs, then the job folder."""
    return job_dir / INPUT_DIR, job_dir


def portable_value(value: Any, *folders: Path) -> Any:
    """A JSON value (dicts, lists, strings, numbers) with :func:`portable_text` applied to every string."""
    if isinstance(value, str):
        return portable_text(value, *folders)
    if isinstance(value, dict):
        return {k: portable_value(v, *folders) for k, v in value.items()}
    if isinstance(value, list):
        return [portable_value(v, *folders) for v in value]
    return value


def portable(results: Any, job_dir: Path) -> Any:
    """:class:`fusioncut.io.results.Results` of the job in ``job_dir`` with its text columns and its
    metadata named portably (changed in place, and returned)."""
    folders = job_folders(job_dir)
    cl = results.cl
    for col in ("file", "reason", "warnings"):
        for f in folders:  # portable_text, column-wise
            cl[col] = cl[col].str.replace(f"{f}{os.sep}", "", regex=False).str.replace(str(f), ".", regex=False)
    results.metadata = portable_value(results.metadata, *folders)
    if results.options is not None:
        results.options = portable_value(results.options, *folders)
    return results


def portable_download(path: Path, job_dir: Path) -> tuple[Iterator[bytes], int | None]:
    """The bytes of the result file ``path`` of the job in ``job_dir`` as the user may see them, and
    their number when known before sending (``None``: streamed without a length).

    Everything is read from one open descriptor: a running job replaces its result files atomically
    (new inode, ``os.replace``), so a download stays whole even when that happens mid-download.
    Raises ``FileNotFoundError`` when the file went away.
    """
    folders = job_folders(job_dir)
    f = open(path, "rb")
    suffix = path.suffix.lower()
    if suffix not in _REWRITTEN:
        return _chunks(f), os.fstat(f.fileno()).st_size
    if suffix == ".csv":
        # a quoted cell doubles the quotes of a path in it: rewrite that form of the folders too
        return _text_lines(f, tuple(x for d in folders for x in (str(d).replace('"', '""'), str(d)))), None
    if suffix == ".log":
        return _text_lines(f, folders), None
    with f:
        data = _json_bytes(f, folders) if suffix == ".json" else _parquet_bytes(f, folders)
    return iter((data,)), len(data)


def portable_size(path: Path, job_dir: Path) -> int:
    """The number of bytes :func:`portable_download` gives for ``path`` now (what a listing of the
    result files shows). Rewritten files are measured by rewriting them, once per version of the file
    (its inode, size and modification time)."""
    st = path.stat()
    if path.suffix.lower() not in _REWRITTEN:
        return st.st_size
    version = (str(path), str(job_dir), st.st_ino, st.st_size, st.st_mtime_ns)
    with _sizes_lock:
        if version in _sizes:
            _sizes.move_to_end(version)
            return _sizes[version]
    body, size = portable_download(path, job_dir)
    if size is None:
        size = sum(len(chunk) for chunk in body)
    with _sizes_lock:
        _sizes[version] = size
        while len(_sizes) > _SIZES_KEPT:
            _sizes.popitem(last=False)
    return size


def _chunks(f: Any) -> Iterator[bytes]:
    with f:
        while block := f.read(_CHUNK_BYTES):
            yield block


def _text_lines(f: Any, folders: tuple[Path | str, ...]) -> Iterator[bytes]:
    """Line by line: a path spans lines only where a folder's name holds a line break, which is then
    left as it is. A CSV cell keeps its quoting (a path out of a quoted cell leaves it quoted)."""
    with f:
        out = []
        size = 0
        for line in f:
            line = portable_text(line.decode("utf-8", errors="surrogateescape"), *folders).encode(
                "utf-8", errors="surrogateescape")
            out.append(line)
            size += len(line)
            if size >= _CHUNK_BYTES:
                yield b"".join(out)
                out, size = [], 0
        if out:
            yield b"".join(out)


def _json_bytes(f: Any, folders: tuple[Path, ...]) -> bytes:
    # the writer's own layout (fusioncut.io.results writes metadata.json indented, keys sorted)
    data = portable_value(json.load(f), *folders)
    return json.dumps(data, indent=2, sort_keys=True).encode("utf-8")


def _parquet_bytes(f: Any, folders: tuple[Path, ...]) -> bytes:
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    table = pq.read_table(f)
    for i, field in enumerate(table.schema):
        if pa.types.is_string(field.type) or pa.types.is_large_string(field.type):
            column = table.column(i)
            for folder in folders:
                column = pc.replace_substring(column, f"{folder}{os.sep}", "")
                column = pc.replace_substring(column, str(folder), ".")
            table = table.set_column(i, field, column)
    meta = {k: _portable_metadata(v, folders) for k, v in (table.schema.metadata or {}).items()}
    table = table.replace_schema_metadata(meta)
    buf = io.BytesIO()
    pq.write_table(table, buf)
    return buf.getvalue()


def _portable_metadata(value: bytes, folders: tuple[Path, ...]) -> bytes:
    """A Parquet schema metadata value: JSON (the results' own, keys sorted) or plain text."""
    try:
        data = json.loads(value)
    except ValueError:
        return portable_text(value.decode("utf-8", errors="surrogateescape"), *folders).encode(
            "utf-8", errors="surrogateescape")
    return json.dumps(portable_value(data, *folders), sort_keys=True).encode("utf-8")
