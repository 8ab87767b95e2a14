"""Result tables: what FusionCut writes for a job, written incrementally and read back.

A results directory holds

* ``cl.parquet`` / ``cl.csv`` — one row per cutter location (CL segment),
* ``slices.parquet`` / ``slices.csv`` — one row per engaged arc (slice x interval),
* ``summary.csv`` — one row per operation,
* ``metadata.json`` — what the engine knew beyond the rows (the same JSON is stored in the Parquet
  schema metadata under the key ``fusioncut``; every Parquet field also carries its own ``unit`` and
  ``description``): ``engine_options`` (every :class:`~fusioncut.model.options.EngineOptions` field,
  enums and paths as text, tuples as lists), ``slice_height_mm``, ``tools`` (tool label -> the tool's
  full record, :mod:`fusioncut.io.tool_records`, from which :func:`load_results` rebuilds the
  :class:`~fusioncut.model.tools.MillingTool`), units, dtypes, angle convention, FusionCut version
  and job hash.

The CSV and Parquet files hold the same values: floats are written at full round-trip precision, an
empty CSV cell in a float column is NaN, and an empty cell in a text column is the empty string.

Angles are degrees. Columns named ``*_deg`` without ``machine`` are **immersion** angles (measured from
+y of the feed frame in the sense the teeth turn, see :mod:`fusioncut.model.angles`); columns named
``*_machine_deg`` are **machine** angles (counter-clockwise from +X seen from +Z). Heights ``z_tool_mm``
are measured along the tool axis from the tool tip at the CL. Each slice row carries its band
``[z_lo_mm, z_hi_mm]``: the engine cuts the flutes into bands ``[k, k+1) * slice_height`` above the tip,
clips each to the flute contact and evaluates it in its middle (``z_tool_mm``), so readers (forces,
plots, the 3D view) take the bands from the rows instead of guessing the spacing.

Results written before the metadata and columns above existed still load (:data:`ADDED_COLUMNS`): what
they do not record is NaN in its column and named in :attr:`Results.missing`, never guessed.

The machine columns follow the project's machine-interval convention (counter-clockwise bounds,
:func:`fusioncut.model.engagement.EngagementMap.machine_intervals`): for a counter-clockwise (M4)
spindle the tooth enters at ``entry_machine_deg``; for a clockwise (M3) spindle it enters at
``exit_machine_deg`` (mod 360) and leaves at ``entry_machine_deg``.

Writing is incremental and crash-safe: :class:`ResultWriter` appends CLs in memory and flushes them in
batches; every file is written to a temporary file in the same directory and moved into place with
``os.replace``, so a reader (or an interrupted run) only ever sees complete files. The slice files are
replaced before the CL files, so every CL present in ``cl.*`` has its slices on disk.

The column tables below are rendered from :mod:`fusioncut.io.result_columns` (the one description of
every column).
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from fusioncut._version import __version__
from fusioncut.errors import InputError
from fusioncut.io.result_columns import (
    ANGLE_KIND, CL_COLUMNS, SLICE_COLUMNS, STATUS_CATEGORIES, SUMMARY_COLUMNS, TABLES, Column, column_table,
)
from fusioncut.io.tool_records import tool_from_record, tool_record
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.tools import MillingTool

if __doc__:  # the column tables, rendered from their one description (absent under python -OO)
    __doc__ += "".join(f"\n``{name}`` table\n{'-' * (len(name) + 10)}\n\n{column_table(name, 'rst')}"
                       for name in TABLES)

FORMAT_NAME = "fusioncut-results"
# 2: metadata.json records engine_options, slice_height_mm and full tool records; cl has spindle_rpm,
# slices have z_lo_mm / z_hi_mm. 3: cl has engine (which engine computed each CL)
FORMAT_VERSION = 3
METADATA_KEY = b"fusioncut"

ANGLE_CONVENTION = (
    "Angles in degrees. Columns *_deg without 'machine' are immersion angles: in the feed frame (feed "
    "+x, tool axis +z) measured from +y in the sense the teeth turn (up-milling [0, arccos(1-ae/R)], "
    "down-milling [180-arccos(1-ae/R), 180], slot [0, 180]); an interval satisfies 0 <= entry < 360 "
    "and entry < exit <= entry + 360. Columns *_machine_deg are machine angles: counter-clockwise from "
    "+X seen from +Z; a machine interval is given counter-clockwise (entry_machine < exit_machine), so "
    "for a CW (M3) spindle the tooth enters at exit_machine_deg. See fusioncut.model.angles."
)

_ARROW_TYPES = {"int64": pa.int64(), "float64": pa.float64(), "string": pa.string(), "category": pa.string()}


def _arrow_schema(columns: tuple[Column, ...], metadata: Mapping[str, Any]) -> pa.Schema:
    fields = []
    for c in columns:
        meta = {"unit": c.unit, "description": c.description}
        if c.name in ANGLE_KIND:
            meta["angle"] = ANGLE_KIND[c.name]
        fields.append(pa.field(c.name, _ARROW_TYPES[c.dtype], nullable=c.dtype != "int64", metadata=meta))
    return pa.schema(fields, metadata={METADATA_KEY: json.dumps(metadata, sort_keys=True).encode()})


def _coerce(df: pd.DataFrame, columns: tuple[Column, ...]) -> pd.DataFrame:
    """Give ``df`` exactly the documented columns, in order, with the documented dtypes.

    Both readers (Parquet and CSV) and the writer go through here, so the two formats load to equal
    frames by construction of the dtypes; the values must still agree, which the tests check.
    """
    out = {}
    for c in columns:
        s = df[c.name] if c.name in df else pd.Series([], dtype="object")
        if c.dtype == "category":
            s = pd.Categorical(s.astype("string").fillna(""), categories=STATUS_CATEGORIES)
        elif c.dtype == "string":
            # text is never missing: an empty cell means the empty string, not NA
            s = s.astype("string").fillna("")
        else:
            s = s.astype(c.dtype)
        out[c.name] = s
    res = pd.DataFrame(out)
    return res.reset_index(drop=True)


# --------------------------------------------------------------------------------------------------
# rows from engagement maps


def _nan_if_none(v: float | None) -> float:
    return math.nan if v is None else float(v)


def cl_row(em: EngagementMap, length_mm: float | None = None, spindle_rpm: float | None = None) -> dict[str, Any]:
    """The ``cl`` table row of one engagement map.

    ``length_mm`` is the path length of the move (mm); the engagement map only knows the end points,
    so without it the chord length is used, which underestimates arcs (and so overestimates MRR).
    ``spindle_rpm`` is the program's spindle speed at the move (rev/min; ``None``: not programmed).
    """
    if length_mm is None:
        length_mm = math.dist(em.start, em.position)
    entries = [iv.entry for s in em.slices for iv in s.intervals]
    exits = [iv.exit for s in em.slices for iv in s.intervals]
    feed = _nan_if_none(em.feed)
    removed = float(em.removed_volume)
    # MRR needs a feed move of positive length with a trusted volume: rapids are not cuts (their
    # volume is an accident that is warned about) and a failed CL's volume is not known.
    mrr = math.nan
    if em.status not in (CLStatus.RAPID, CLStatus.FAILED) and feed > 0 and length_mm > 0:
        mrr = removed * feed / length_mm
    return {
        "cl": int(em.cl_index),
        "operation": em.operation,
        "file": str(em.source.file),
        "line": int(em.source.line),
        "tool": em.tool,
        "spindle": em.spindle.value,
        "spindle_rpm": _nan_if_none(spindle_rpm),
        "x": float(em.position[0]), "y": float(em.position[1]), "z": float(em.position[2]),
        "x0": float(em.start[0]), "y0": float(em.start[1]), "z0": float(em.start[2]),
        "feed_angle_machine_deg": float(em.feed_angle),
        "feed_mm_min": feed,
        "length_mm": float(length_mm),
        "status": em.status.value,
        "reason": em.reason,
        "warnings": " | ".join(em.warnings),
        "ap_mm": float(em.ap),
        "ae_mm": float(em.ae),
        "entry_min_deg": min(entries, default=math.nan),
        "entry_max_deg": max(entries, default=math.nan),
        "exit_min_deg": min(exits, default=math.nan),
        "exit_max_deg": max(exits, default=math.nan),
        "contact_area_mm2": float(em.contact_area),
        "shank_contact_area_mm2": float(em.shank_contact_area),
        "rubbing_slices": int(em.rubbing_slices),
        "removed_volume_mm3": removed,
        "mrr_mm3_min": mrr,
        "sweep_method": em.sweep_method,
        "time_ms": float(dict(em.timings_ms).get("total", sum(t for _, t in em.timings_ms))),
        "engine": em.engine,
    }


def slice_band(z: float, slice_height: float, axial_range: tuple[float, float]) -> tuple[float, float] | None:
    """The band (mm above the tip) of the slice at height ``z``, by the engine's slice rule
    (:func:`fusioncut.engines.brep.engine.slice_heights`): band ``k = floor(z / slice_height)`` is
    ``[k, k+1) * slice_height`` clipped to the flute contact ``axial_range``, and the slice sits in its
    middle. ``None`` when ``z`` does not sit there (to 1e-9 mm): a map the engine did not make."""
    k = math.floor(z / slice_height + 1e-9)
    lo, hi = max(k * slice_height, axial_range[0]), min((k + 1) * slice_height, axial_range[1])
    if hi <= lo or abs(0.5 * (lo + hi) - z) > 1e-9 * max(1.0, abs(z)):
        return None
    return lo, hi


def slice_rows(em: EngagementMap, slice_height: float | None = None) -> list[dict[str, Any]]:
    """The ``slices`` table rows of one engagement map: one per engaged arc. With the engine's
    ``slice_height`` (mm) each row carries its band (:func:`slice_band`); without, the band is NaN."""
    rows = []
    for s in em.slices:
        band = slice_band(s.z, slice_height, em.axial_range) if s.intervals and slice_height is not None else None
        lo, hi = band or (math.nan, math.nan)
        for k, (iv, (m0, m1)) in enumerate(zip(s.intervals, em.machine_intervals(s))):
            rows.append({
                "cl": int(em.cl_index), "z_tool_mm": float(s.z), "z_machine_mm": float(s.z_machine),
                "z_lo_mm": lo, "z_hi_mm": hi,
                "radius_mm": float(s.radius), "interval": k, "entry_deg": float(iv.entry),
                "exit_deg": float(iv.exit), "entry_machine_deg": float(m0), "exit_machine_deg": float(m1),
            })
    return rows


_SUMMARY_INPUTS = ("operation", "status", "time_ms", "removed_volume_mm3", "ae_mm", "ap_mm")


def summarize(cl: pd.DataFrame, expected_cls: Mapping[str, int] | None = None) -> pd.DataFrame:
    """Per-operation summary of a ``cl`` table (see the module docstring for the columns).

    ``expected_cls`` maps operation -> number of CLs in the program; operations listed there but not
    (yet) processed get a row of zeros, which is how an interrupted run shows what is missing.
    Only the columns ``operation, status, time_ms, removed_volume_mm3, ae_mm, ap_mm`` are used.
    """
    expected = dict(expected_cls or {})
    ops = list(dict.fromkeys(list(cl["operation"]) if len(cl) else []))
    ops += [op for op in expected if op not in ops]
    rows = []
    for op in ops:
        g = cl[cl["operation"] == op] if len(cl) else cl
        status = g["status"].astype("string") if len(g) else pd.Series([], dtype="string")
        counts = {s: int((status == s).sum()) for s in STATUS_CATEGORIES}
        rows.append({
            "operation": op,
            "cls": int(expected.get(op, len(g))),
            "processed": int(len(g)),
            **counts,
            "time_s": float(g["time_ms"].sum() / 1000.0) if len(g) else 0.0,
            "volume_removed_mm3": float(g["removed_volume_mm3"].sum()) if len(g) else 0.0,
            "max_ae_mm": float(g["ae_mm"].max()) if len(g) else 0.0,
            "max_ap_mm": float(g["ap_mm"].max()) if len(g) else 0.0,
        })
    return _coerce(pd.DataFrame(rows, columns=[c.name for c in SUMMARY_COLUMNS]), SUMMARY_COLUMNS)


# --------------------------------------------------------------------------------------------------
# atomic file writes


def _atomic_write(path: Path, write: Any) -> None:
    """Call ``write(fileobj)`` on a temporary file next to ``path``, fsync it and move it into place.

    ``os.replace`` is atomic on POSIX and Windows when both names are on one file system, which the
    same directory guarantees; the fsync makes sure the new name never points at unwritten data after
    a power loss.
    """
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _csv_bytes(df: pd.DataFrame, header: bool) -> bytes:
    # pandas writes floats with the shortest repr that round-trips; NaN becomes an empty cell
    return df.to_csv(index=False, header=header, na_rep="", lineterminator="\n").encode("utf-8")


# --------------------------------------------------------------------------------------------------
# the writer


class ResultWriter:
    """Writes a results directory incrementally as CLs arrive.

    Use it as a context manager; leaving the block, normally or by an exception (including
    ``KeyboardInterrupt``), flushes every CL added so far::

        with ResultWriter(out_dir, job_hash=h, expected_cls={"rough": 1200}) as w:
            for em, move in results:
                w.add(em, length_mm=move.length)

    CLs are kept in memory and written every ``batch_size`` CLs; if the process dies without leaving
    the block (SIGKILL, power loss) the files hold every CL of the last completed flush and are never
    corrupt. Each flush rewrites the Parquet files whole (Parquet cannot be appended to) and appends to
    copies of the CSV files, so its cost grows with the job; ``max_io_fraction`` postpones a due flush
    until the time since the last one is at least ``last flush duration / max_io_fraction``, which
    keeps writing below that fraction of the run time on huge jobs. ``None`` flushes on every batch.
    A flush that fails (disk full, ...) raises and keeps its CLs pending; the next flush retries them
    without writing any row twice.

    ``tools`` maps tool labels to the tools (:class:`~fusioncut.model.tools.MillingTool`, stored as
    their full records, :func:`~fusioncut.io.tool_records.tool_record`) or to JSON-serialisable
    descriptions; labels seen in the engagement maps without one are added with an empty description.
    ``options`` are the engine's options (:class:`~fusioncut.model.options.EngineOptions` or a mapping
    of its fields), stored as ``engine_options``; their ``slice_height`` is also ``slice_height_mm``
    and gives each slice row its band (:func:`slice_rows`). Without them the bands are NaN.

    ``keep_below`` resumes a run: the rows of CLs ``< keep_below`` already in the directory are kept
    and every later row is dropped, so CLs recomputed after a checkpoint are never listed twice
    (``written`` then counts the kept CLs; the caller checks they are the ones it expects).
    """

    def __init__(
        self,
        directory: str | os.PathLike[str],
        *,
        job_hash: str = "",
        tools: Mapping[str, MillingTool | Mapping[str, Any]] | None = None,
        options: Any = None,
        expected_cls: Mapping[str, int] | None = None,
        batch_size: int = 64,
        max_io_fraction: float | None = 0.1,
        keep_below: int = 0,
    ) -> None:
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        if max_io_fraction is not None and not (0 < max_io_fraction <= 1):
            raise ValueError(f"max_io_fraction must be in (0, 1], got {max_io_fraction}")
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.job_hash = job_hash
        self.tools: dict[str, Any] = {label: tool_record(t) if isinstance(t, MillingTool) else json_record(t)
                                      for label, t in (tools or {}).items()}
        self.options: dict[str, Any] | None = None if options is None else json_record(options)
        dz = (self.options or {}).get("slice_height")
        self.slice_height: float | None = float(dz) if dz is not None else None
        self.expected_cls = dict(expected_cls or {})
        self.batch_size = batch_size
        self.max_io_fraction = max_io_fraction
        self._pending_cl: list[dict[str, Any]] = []
        self._pending_slices: list[dict[str, Any]] = []
        self._cl_tables: list[pa.Table] = []
        self._slice_tables: list[pa.Table] = []
        self._written = 0
        self._last_flush_end = 0.0
        self._last_flush_duration = 0.0
        self._closed = False
        self._csv_sizes: dict[str, int] = {}  # bytes of each CSV as of the last complete flush
        # Replace whatever an earlier run left at once (by empty tables, or by the rows a resumed run
        # keeps), so the directory never mixes this job's CLs with another's and is loadable before
        # the first flush.
        kept_cl, kept_slices = _rows_below(self.directory, keep_below) if keep_below > 0 else ([], [])
        self._write_files(new_cl=kept_cl, new_slices=kept_slices, fresh=True)
        self._written = len(kept_cl)

    # context manager: always flush on the way out, also on errors and Ctrl-C
    def __enter__(self) -> ResultWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def written(self) -> int:
        """Number of CLs on disk."""
        return self._written

    @property
    def pending(self) -> int:
        """Number of CLs added but not yet on disk."""
        return len(self._pending_cl)

    def add(self, em: EngagementMap, *, length_mm: float | None = None, spindle_rpm: float | None = None) -> None:
        """Add one CL; ``length_mm`` is its path length (mm) and ``spindle_rpm`` the program's spindle
        speed at its move (rev/min), see :func:`cl_row`."""
        if self._closed:
            raise ValueError("ResultWriter is closed")
        self.tools.setdefault(em.tool, {})
        self._pending_cl.append(cl_row(em, length_mm, spindle_rpm))
        self._pending_slices.extend(slice_rows(em, self.slice_height))
        if len(self._pending_cl) >= self.batch_size and self._flush_allowed():
            self.flush()

    def _flush_allowed(self) -> bool:
        if self.max_io_fraction is None or self._written == 0:
            return True
        waited = time.monotonic() - self._last_flush_end
        return waited * self.max_io_fraction >= self._last_flush_duration

    def flush(self) -> None:
        """Write every pending CL now."""
        if not self._pending_cl:
            return
        t0 = time.monotonic()
        self._write_files(self._pending_cl, self._pending_slices)
        self._written += len(self._pending_cl)
        self._pending_cl, self._pending_slices = [], []
        self._last_flush_end = time.monotonic()
        self._last_flush_duration = self._last_flush_end - t0

    def close(self) -> None:
        """Flush and stop accepting CLs (idempotent)."""
        if not self._closed:
            try:
                self.flush()
            finally:
                self._closed = True

    # ------------------------------------------------------------------

    def metadata(self) -> dict[str, Any]:
        """The job metadata stored with the tables (JSON-serialisable)."""
        return {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "fusioncut_version": __version__,
            "job_hash": self.job_hash,
            "angle_convention": ANGLE_CONVENTION,
            "angle_columns": ANGLE_KIND,
            "engine_options": self.options,
            "slice_height_mm": self.slice_height,
            "tools": self.tools,
            "units": {t: {c.name: c.unit for c in cols} for t, cols in TABLES.items()},
            "dtypes": {t: {c.name: c.dtype for c in cols} for t, cols in TABLES.items()},
        }

    def _write_files(self, new_cl: list[dict[str, Any]], new_slices: list[dict[str, Any]],
                     fresh: bool = False) -> None:
        meta = self.metadata()
        cl_new = _coerce(pd.DataFrame(new_cl, columns=[c.name for c in CL_COLUMNS]), CL_COLUMNS)
        sl_new = _coerce(pd.DataFrame(new_slices, columns=[c.name for c in SLICE_COLUMNS]), SLICE_COLUMNS)
        cl_schema = _arrow_schema(CL_COLUMNS, meta)
        sl_schema = _arrow_schema(SLICE_COLUMNS, meta)
        # The in-memory Arrow tables are only extended once the files are safely replaced, so a flush
        # that fails half-way can simply be retried with the same pending rows.
        cl_tables = self._cl_tables + [_to_arrow(cl_new, cl_schema)]
        sl_tables = self._slice_tables + [_to_arrow(sl_new, sl_schema)]
        cl_all = pa.concat_tables([t.replace_schema_metadata(cl_schema.metadata) for t in cl_tables])
        sl_all = pa.concat_tables([t.replace_schema_metadata(sl_schema.metadata) for t in sl_tables])

        d = self.directory
        sizes: dict[str, int] = {}
        # slices first: the cl files are the commit point, every CL they list has its slices on disk
        sizes["slices.csv"] = self._write_csv(d / "slices.csv", sl_new, fresh)
        _atomic_write(d / "slices.parquet", lambda f: pq.write_table(sl_all, f))
        sizes["cl.csv"] = self._write_csv(d / "cl.csv", cl_new, fresh)
        _atomic_write(d / "cl.parquet", lambda f: pq.write_table(cl_all, f))
        # only the columns the summary needs: converting the whole table each flush would dominate
        summary = summarize(cl_all.select(list(_SUMMARY_INPUTS)).to_pandas(), self.expected_cls)
        _atomic_write(d / "summary.csv", lambda f: f.write(_csv_bytes(summary, header=True)))
        _atomic_write(d / "metadata.json",
                      lambda f: f.write(json.dumps(meta, indent=2, sort_keys=True).encode("utf-8")))
        # the flush is complete: only now does it become the base of the next one
        self._cl_tables, self._slice_tables = [pa.concat_tables(cl_tables)], [pa.concat_tables(sl_tables)]
        self._csv_sizes = sizes

    def _write_csv(self, path: Path, new_rows: pd.DataFrame, fresh: bool) -> int:
        """Replace ``path`` by its committed part plus ``new_rows``; returns the new size in bytes."""
        committed = 0 if fresh else self._csv_sizes.get(path.name, 0)

        def write(f: Any) -> None:
            if committed == 0:
                f.write(_csv_bytes(new_rows, header=True))
                return
            # Copy only the bytes of the last complete flush: a flush that died after replacing this
            # file but before the CL files may have left rows here that are still pending and are
            # about to be written again.
            with open(path, "rb") as old:
                left = committed
                while left:
                    chunk = old.read(min(left, 1 << 20))
                    if not chunk:
                        raise OSError(f"{path}: shorter than the {committed} bytes written before")
                    f.write(chunk)
                    left -= len(chunk)
            f.write(_csv_bytes(new_rows, header=False))

        _atomic_write(path, write)
        return path.stat().st_size


def json_record(value: Any) -> Any:
    """``value`` as plain JSON data: dataclasses as objects of their fields, enums as their values,
    paths as text, tuples as lists (what ``metadata.json`` records of options and tools)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = {f.name: getattr(value, f.name) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): json_record(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_record(v) for v in value]
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return value


def _rows_below(directory: Path, keep_below: int) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The ``cl`` and ``slices`` rows of CLs ``< keep_below`` in an existing results directory
    (none when it holds no results), in the order they were written."""
    try:
        old = load_results(directory)
    except InputError:
        return [], []
    cl = old.cl[old.cl["cl"] < keep_below]
    slices = old.slices[old.slices["cl"] < keep_below]
    return cl.to_dict("records"), slices.to_dict("records")


def _to_arrow(df: pd.DataFrame, schema: pa.Schema) -> pa.Table:
    plain = {}
    for name in schema.names:
        s = df[name]
        if isinstance(s.dtype, pd.CategoricalDtype) or isinstance(s.dtype, pd.StringDtype):
            plain[name] = pa.array(s.astype(object).tolist(), type=pa.string())
        else:
            plain[name] = pa.array(s.to_numpy(), type=schema.field(name).type)
    return pa.table(plain, schema=schema)


# --------------------------------------------------------------------------------------------------
# reading


@dataclass
class Results:
    """A loaded results directory: DataFrames with the documented columns and dtypes, and what the
    engine knew.

    ``cl`` (one row per CL), ``slices`` (one row per engaged arc), ``summary`` (one row per
    operation) and ``metadata`` (``metadata.json`` as read). ``source`` says which format was read:
    ``"parquet"`` or ``"csv"``. ``options``: the engine options as recorded (field -> JSON value;
    ``None`` when not recorded); ``slice_height``: the engine's slice height (mm; ``None`` when not
    recorded); ``tools``: tool label -> the :class:`~fusioncut.model.tools.MillingTool` rebuilt from
    its record. ``missing`` names what the folder does not record (results written before it was, or
    a tool without a full record) with why: ``engine_options``, ``slice_height``, ``spindle_rpm``
    (NaN column), ``slice_bands`` (NaN ``z_lo_mm``/``z_hi_mm``), ``engine`` (empty ``engine`` column:
    an older folder whose options do not say the engine either), ``tool <label>``.
    """

    cl: pd.DataFrame
    slices: pd.DataFrame
    summary: pd.DataFrame
    metadata: dict[str, Any] = field(default_factory=dict)
    source: str = "parquet"
    options: dict[str, Any] | None = None
    slice_height: float | None = None
    tools: dict[str, MillingTool] = field(default_factory=dict)
    missing: dict[str, str] = field(default_factory=dict)
    path: Path | None = None

    def row(self, cl: int) -> pd.Series:
        """The ``cl`` row of CL ``cl``; raises :class:`InputError` when it is not in the results."""
        hit = self.cl[self.cl["cl"] == cl]
        if hit.empty:
            lo, hi = (int(self.cl["cl"].min()), int(self.cl["cl"].max())) if len(self.cl) else (0, -1)
            rng = f"CLs {lo}..{hi}" if hi >= lo else "no CLs"
            raise InputError(f"CL {cl} is not in the results ({rng})")
        return hit.iloc[-1]  # a CL written twice (a re-run of one CL): the later result wins

    def slices_of(self, cl: int) -> pd.DataFrame:
        """Slice rows of CL ``cl``, sorted by height and arc index."""
        return self.slices[self.slices["cl"] == cl].sort_values(["z_tool_mm", "interval"])

    def tool(self, label: str) -> MillingTool:
        """The tool of label ``label``; :class:`InputError` naming the folder when it has no full record."""
        if label in self.tools:
            return self.tools[label]
        why = self.missing.get(f"tool {label}", "no such tool label in metadata.json")
        raise InputError(f"tool {label}: {why}", self.path)

    def require_slice_height(self) -> float:
        """:attr:`slice_height`, or an :class:`InputError` naming the folder when it is not recorded."""
        if self.slice_height is None:
            raise InputError(f"{self.missing.get('slice_height', 'the slice height is not recorded')}: give the "
                             "engine's slice height (--slice-height)", self.path)
        return self.slice_height


def _read_csv(path: Path, columns: tuple[Column, ...], filled: set[str] | None = None) -> pd.DataFrame:
    dtypes = {c.name: ("string" if c.dtype in ("string", "category") else c.dtype) for c in columns}
    floats = [c.name for c in columns if c.dtype == "float64"]
    kw: dict[str, Any] = {}
    if int(pd.__version__.split(".")[0]) < 3:  # pandas 3 parses floats exactly by default
        kw["float_precision"] = "round_trip"
    # only an empty float cell is NaN; text like "NA" or "" stays text
    df = pd.read_csv(path, dtype=dtypes, keep_default_na=False, na_values={c: [""] for c in floats},
                     encoding="utf-8", **kw)
    return _coerce(_with_later_columns(df, columns, path, filled), columns)


# Columns added after results were first written, with the value they mean in older results: such a
# folder still loads. A CL of an older run was never called rubbing (0); its spindle speed and its
# slices' bands were not recorded (NaN: unknown, and named in Results.missing). Its engine is the
# one engine_options names (an older run had no per-CL fallback), else unknown ("").
ADDED_COLUMNS: dict[str, Any] = {"rubbing_slices": 0, "spindle_rpm": math.nan, "z_lo_mm": math.nan,
                                 "z_hi_mm": math.nan, "engine": ""}
# what Results.missing calls an added column an older folder lacks, and why
_NOT_RECORDED = {"spindle_rpm": "spindle_rpm", "z_lo_mm": "slice_bands", "z_hi_mm": "slice_bands",
                 "engine": "engine"}


def _with_later_columns(df: pd.DataFrame, columns: tuple[Column, ...], path: Path,
                        filled: set[str] | None = None) -> pd.DataFrame:
    """``df`` with the :data:`ADDED_COLUMNS` it lacks filled in (their names added to ``filled``); any
    other missing column is an error."""
    missing = [c.name for c in columns if c.name not in df]
    if any(name not in ADDED_COLUMNS for name in missing):
        raise InputError(f"missing columns {', '.join(n for n in missing if n not in ADDED_COLUMNS)}", path)
    if filled is not None:
        filled.update(missing)
    return df.assign(**{name: ADDED_COLUMNS[name] for name in missing}) if missing else df


def _read_table(directory: Path, name: str, columns: tuple[Column, ...],
                filled: set[str]) -> tuple[pd.DataFrame, dict, str]:
    pq_path, csv_path = directory / f"{name}.parquet", directory / f"{name}.csv"
    if pq_path.exists():
        # one open file for every read: pyarrow given the path opens it again for the pages, and a
        # writer's os.replace between the opens hands it another file than its footer describes
        with open(pq_path, "rb") as f:
            table = pq.read_table(f)
        raw = (table.schema.metadata or {}).get(METADATA_KEY)
        df = _with_later_columns(table.to_pandas(), columns, pq_path, filled)
        return _coerce(df, columns), (json.loads(raw) if raw else {}), "parquet"
    if csv_path.exists():
        return _read_csv(csv_path, columns, filled), {}, "csv"
    raise InputError(f"no {name}.parquet or {name}.csv: not a FusionCut results directory", directory)


def load_results(path: str | os.PathLike[str], *, prefer: str = "parquet") -> Results:
    """Load a results directory written by :class:`ResultWriter`.

    Reads ``cl.parquet`` and ``slices.parquet`` when present, else the CSV files (``prefer="csv"``
    forces CSV). Columns and dtypes are those documented in this module; ``status`` is a categorical
    with the categories engaged, air, rapid, failed; text columns are pandas ``string`` without NA.
    The engine options, slice height and tools come from the metadata (:class:`Results`).
    """
    directory = Path(path)
    if not directory.is_dir():
        raise InputError("results directory not found", directory)
    if prefer not in ("parquet", "csv"):
        raise ValueError(f"prefer must be 'parquet' or 'csv', got {prefer!r}")
    filled: set[str] = set()
    if prefer == "csv":
        cl, meta, source = _read_csv_or_fail(directory, "cl", CL_COLUMNS, filled), {}, "csv"
        slices = _read_csv_or_fail(directory, "slices", SLICE_COLUMNS, filled)
    else:
        cl, meta, source = _read_table(directory, "cl", CL_COLUMNS, filled)
        slices, _, _ = _read_table(directory, "slices", SLICE_COLUMNS, filled)
    if not meta and (directory / "metadata.json").exists():
        meta = json.loads((directory / "metadata.json").read_text(encoding="utf-8"))
    # A reader racing a flush (or a run killed during one) can see slices of CLs whose cl rows are
    # not written yet: the cl table is the commit point, so drop them for a consistent snapshot.
    slices = slices[slices["cl"].isin(cl["cl"])].reset_index(drop=True)
    summary_path = directory / "summary.csv"
    summary = _read_csv(summary_path, SUMMARY_COLUMNS) if summary_path.exists() else summarize(cl)
    options = meta.get("engine_options")
    if not isinstance(options, dict):
        options = None
    if "engine" in filled:  # an older run ran one engine throughout: the one its options name
        ran = (options or {}).get("engine", "brep" if options is not None else "")
        if ran in ("brep", "analytic"):
            filled.discard("engine")
            cl["engine"] = pd.Series([ran] * len(cl), dtype="string")
    missing = {_NOT_RECORDED[name]: "results written before it was recorded"
               for name in sorted(filled) if name in _NOT_RECORDED}
    if options is None:
        missing["engine_options"] = "the engine options are not recorded"
    slice_height = meta.get("slice_height_mm")
    if not isinstance(slice_height, (int, float)) or isinstance(slice_height, bool) or not slice_height > 0:
        slice_height = None
        missing["slice_height"] = "the slice height is not recorded (results written before it was)"
    tools: dict[str, MillingTool] = {}
    for label, record in (meta.get("tools") or {}).items():
        try:
            tools[label] = tool_from_record(record)
        except InputError as exc:
            missing[f"tool {label}"] = f"metadata.json has no full record of it ({exc.reason})"
    return Results(cl=cl, slices=slices, summary=summary, metadata=meta, source=source, options=options,
                   slice_height=None if slice_height is None else float(slice_height), tools=tools,
                   missing=missing, path=directory)


def _read_csv_or_fail(directory: Path, name: str, columns: tuple[Column, ...], filled: set[str]) -> pd.DataFrame:
    path = directory / f"{name}.csv"
    if not path.exists():
        raise InputError(f"no {name}.csv", directory)
    return _read_csv(path, columns, filled)


__all__ = [
    "ADDED_COLUMNS", "ANGLE_CONVENTION", "CL_COLUMNS", "SLICE_COLUMNS", "SUMMARY_COLUMNS", "Column", "ResultWriter",
    "Results", "cl_row", "column_table", "json_record", "load_results", "slice_band", "slice_rows", "summarize",
    "tool_from_record", "tool_record",
]
