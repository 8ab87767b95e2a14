"""The columns of the result tables: names, dtypes, units and meanings, and their tables as text.

One list per table (:data:`CL_COLUMNS`, :data:`SLICE_COLUMNS`, :data:`SUMMARY_COLUMNS`) is the only
place a column is described: the writer makes the files from it (every Parquet field carries its
``unit`` and ``description``), the loader coerces to its dtypes, and :func:`column_table` renders it
for :mod:`fusioncut.io.results`' docstring (reStructuredText) and the README (Markdown).

Units: ``mm``, ``mm^2``, ``mm^3``, ``deg``, ``mm/min``, ``rev/min``, ``ms``, ``s``; an empty unit is a
count, an index or text. Angles ``*_deg`` without ``machine`` are immersion angles, ``*_machine_deg``
machine angles (:data:`ANGLE_KIND`).
"""
from __future__ import annotations

from typing import NamedTuple

from fusioncut.model.engagement import CLStatus

STATUS_CATEGORIES = [s.value for s in CLStatus]


class Column(NamedTuple):
    """One documented column: ``dtype`` is the pandas dtype after loading."""

    name: str
    dtype: str  # "int64" | "float64" | "string" | "category"
    unit: str  # "" for dimensionless / text
    description: str


def _c(name: str, dtype: str, unit: str, description: str) -> Column:
    return Column(name, dtype, unit, description)


CL_COLUMNS: tuple[Column, ...] = (
    _c("cl", "int64", "", "CL index (0-based, program order)"),
    _c("operation", "string", "", "operation (program section) the move belongs to"),
    _c("file", "string", "", "source file of the move"),
    _c("line", "int64", "", "1-based source line (0: unknown)"),
    _c("tool", "string", "", "tool label (name, `T<n>` or kind); its record is metadata.json's tools[label]"),
    _c("spindle", "string", "", "spindle sense: cw (M3) or ccw (M4)"),
    _c("spindle_rpm", "float64", "rev/min", "the program's spindle speed (S) at the move; NaN: none programmed, "
       "or results written before it was recorded"),
    _c("x", "float64", "mm", "CL point (tool tip) at the end of the segment, machine frame"),
    _c("y", "float64", "mm", "CL point (tool tip) at the end of the segment, machine frame"),
    _c("z", "float64", "mm", "CL point (tool tip) at the end of the segment, machine frame"),
    _c("x0", "float64", "mm", "CL point at the start of the segment, machine frame"),
    _c("y0", "float64", "mm", "CL point at the start of the segment, machine frame"),
    _c("z0", "float64", "mm", "CL point at the start of the segment, machine frame"),
    _c("feed_angle_machine_deg", "float64", "deg", "machine angle of the horizontal feed direction (the immersion "
       "frame's +x)"),
    _c("feed_mm_min", "float64", "mm/min", "programmed feed; NaN for rapids and unknown feeds"),
    _c("length_mm", "float64", "mm", "path length of the segment (arc length for arcs)"),
    _c("status", "category", "", "engaged, air, rapid or failed"),
    _c("reason", "string", "", "why the CL failed (empty otherwise)"),
    _c("warnings", "string", "", "engine warnings joined with ' | '"),
    _c("ap_mm", "float64", "mm", "axial depth of cut (height range of the flute contact that cuts)"),
    _c("ae_mm", "float64", "mm", "radial depth of cut (largest slice radial width)"),
    _c("entry_min_deg", "float64", "deg", "smallest entry angle over all slices (immersion); NaN: no contact"),
    _c("entry_max_deg", "float64", "deg", "largest entry angle over all slices (immersion)"),
    _c("exit_min_deg", "float64", "deg", "smallest exit angle over all slices (immersion)"),
    _c("exit_max_deg", "float64", "deg", "largest exit angle over all slices (immersion)"),
    _c("contact_area_mm2", "float64", "mm^2", "flute contact area"),
    _c("shank_contact_area_mm2", "float64", "mm^2", "shank contact area (rubbing, not cutting)"),
    _c("rubbing_slices", "int64", "", "slices whose contact only rubs (removed width across the path under "
       "min_chip_thickness): no slices rows, not in ap/ae"),
    _c("removed_volume_mm3", "float64", "mm^3", "material removed by the segment"),
    _c("mrr_mm3_min", "float64", "mm^3/min",
       "removed volume / (length / feed); NaN for rapids, failed CLs, unknown feed or zero length"),
    _c("sweep_method", "string", "", "how the swept volume was built: exact, step (ramp or helix piece swept level at its "
       "end height, within ramp_step) or sampled; empty when no sweep was built (no material within reach)"),
    _c("time_ms", "float64", "ms", "engine compute time of the CL (its total timing)"),
    _c("engine", "string", "", "which engine computed the CL: analytic, or brep (the B-Rep engine, also where "
       "the analytic engine handed it a CL it could not compute); empty: not recorded"),
)

SLICE_COLUMNS: tuple[Column, ...] = (
    _c("cl", "int64", "", "CL index (joins the cl table)"),
    _c("z_tool_mm", "float64", "mm", "slice height above the tool tip along the tool axis"),
    _c("z_machine_mm", "float64", "mm", "slice height in the machine frame"),
    _c("z_lo_mm", "float64", "mm", "bottom of the slice's band above the tip: the engine's band [k, k+1) * "
       "slice_height clipped to the flute contact (the slice sits in its middle); NaN: results written before "
       "bands were recorded"),
    _c("z_hi_mm", "float64", "mm", "top of the slice's band above the tip (see z_lo_mm)"),
    _c("radius_mm", "float64", "mm", "tool radius at the slice height"),
    _c("interval", "int64", "", "0-based index of the arc within its slice"),
    _c("entry_deg", "float64", "deg", "immersion angle where the tooth enters (0 <= entry < 360)"),
    _c("exit_deg", "float64", "deg", "immersion angle where the tooth leaves (entry < exit <= entry + 360)"),
    _c("entry_machine_deg", "float64", "deg", "machine angle where the arc starts counter-clockwise (0 <= . < 360)"),
    _c("exit_machine_deg", "float64", "deg", "machine angle where the arc ends counter-clockwise (entry_machine "
       "< . <= entry_machine + 360)"),
)

SUMMARY_COLUMNS: tuple[Column, ...] = (
    _c("operation", "string", "", "operation name"),
    _c("cls", "int64", "", "CLs of the operation (the caller's expected count, else processed)"),
    _c("processed", "int64", "", "CLs with a result written"),
    _c("engaged", "int64", "", "CLs with status engaged"),
    _c("air", "int64", "", "CLs with status air"),
    _c("rapid", "int64", "", "CLs with status rapid"),
    _c("failed", "int64", "", "CLs with status failed"),
    _c("time_s", "float64", "s", "engine compute time (sum of time_ms)"),
    _c("volume_removed_mm3", "float64", "mm^3", "material removed (sum of removed_volume_mm3)"),
    _c("max_ae_mm", "float64", "mm", "largest ae_mm"),
    _c("max_ap_mm", "float64", "mm", "largest ap_mm"),
)

TABLES: dict[str, tuple[Column, ...]] = {"cl": CL_COLUMNS, "slices": SLICE_COLUMNS, "summary": SUMMARY_COLUMNS}

# Which angle convention each angle column uses; stored in the metadata so no column is ambiguous.
ANGLE_KIND: dict[str, str] = {
    **{c.name: "immersion" for c in CL_COLUMNS + SLICE_COLUMNS if c.unit == "deg" and "machine" not in c.name},
    **{c.name: "machine" for c in CL_COLUMNS + SLICE_COLUMNS if c.unit == "deg" and "machine" in c.name},
}


def column_table(table: str, fmt: str = "markdown") -> str:
    """The column table of ``table`` (``"cl"``, ``"slices"`` or ``"summary"``) as text: a Markdown pipe
    table (``fmt="markdown"``, for the README) or a reStructuredText grid table (``fmt="rst"``, for
    docstrings). Columns: column, dtype, unit (``-`` when none), meaning."""
    if table not in TABLES:
        raise ValueError(f"unknown table {table!r} (known: {', '.join(TABLES)})")
    rows = [("column", "dtype", "unit", "meaning")]
    rows += [(f"``{c.name}``" if fmt == "rst" else f"`{c.name}`", c.dtype, c.unit or "-", c.description)
             for c in TABLES[table]]
    if fmt == "markdown":
        lines = ["| " + " | ".join(cell.replace("|", r"\|") for cell in r) + " |" for r in rows]
        lines.insert(1, "|" + "|".join("---" for _ in rows[0]) + "|")
        return "\n".join(lines) + "\n"
    if fmt == "rst":
        widths = [max(len(r[k]) for r in rows) for k in range(4)]
        rule = " ".join("=" * w for w in widths)
        body = [" ".join(cell.ljust(w) for cell, w in zip(r, widths)).rstrip() for r in rows]
        return "\n".join([rule, body[0], rule, *body[1:], rule]) + "\n"
    raise ValueError(f"fmt must be 'markdown' or 'rst', got {fmt!r}")


__all__ = ["ANGLE_KIND", "CL_COLUMNS", "SLICE_COLUMNS", "SUMMARY_COLUMNS", "STATUS_CATEGORIES", "TABLES", "Column",
           "column_table"]
