"""``fusioncut inspect FILE``: show what FusionCut reads from an input file, before running anything.

Toolpaths (G-code, APT/CLSF, Fusion JSON post), tool libraries (Fusion ``.json``/``.tools``,
LinuxCNC ``.tbl``) and CAMotics ``.camotics`` projects: tools, operations, move counts by type per
operation, extents, feeds, the units the file is written in and the reader's warnings. Everything
is reported after reading, i.e. in mm and mm/min whatever the file's units. ``--json`` prints the
same report as JSON (keys below) for scripts.

JSON keys: ``file``, ``format``, ``file_units`` (list, in order of use), ``units_note``,
``output_units``, ``tools`` (``number``, ``kind``, ``name``, ``diameter_mm``, ``flute_length_mm``,
``corner_radius_mm``, ``taper_angle_deg``, ``flutes``, ``used``), ``refused_tools`` (``number``,
``reason``), ``operations`` (``name``, ``tools``, ``moves`` by type, ``feed_mm_min`` [min, max] or
null), ``moves`` (totals by type), ``extents_mm`` (``all`` and ``feed`` moves: ``min``/``max``
[x, y, z], or null), ``feed_mm_min`` and ``spindle_rpm`` ([min, max] or null), ``stock`` and
``programs`` (CAMotics projects), ``warnings``.
"""
from __future__ import annotations

import gc
import json
import re
from pathlib import Path
from typing import Any, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from fusioncut.cli._errors import friendly_errors
from fusioncut.errors import FusionCutError, InputError, SourceLocation
from fusioncut.io.gcode import DEFAULT_MAX_MOVES
from fusioncut.io.readers import (DEFAULT_TOOLPATH_READER, TOOL_LIBRARY_READERS, TOOLPATH_READERS, read_tool_library,
                                  toolpath_format)
from fusioncut.model import BallEndMill, MillingTool, Move, Toolpath

console = Console()

MOVE_KINDS = ("rapid", "linear", "arc", "helix")
MAX_WARNINGS_SHOWN = 20  # the table view; --json lists them all


# --------------------------------------------------------------------------------------------------
# reading


def inspect_file(path: Path, tools_path: Path | None = None, strict: bool = False,
                 max_moves: int | None = DEFAULT_MAX_MOVES) -> dict[str, Any]:
    """The inspection report of ``path`` (see the module docstring); raises the readers' errors.
    ``max_moves`` bounds what a G-code program may expand to (:mod:`fusioncut.io.gcode.budget`).

    The format is the one :mod:`fusioncut.io.readers` reads the file with; a ``.json`` file is a
    Fusion tool library when it holds ``data`` and no ``toolpath``, else a Fusion JSON toolpath."""
    library = read_tool_library(tools_path) if tools_path is not None else None
    suffix = path.suffix.lower()
    if suffix in TOOL_LIBRARY_READERS and (suffix != ".json" or _is_tool_library_json(path)):
        return _library_report(path, read_tool_library(path))
    report = _TOOLPATH_REPORTS[toolpath_format(path).format]
    return report(path, library, strict, max_moves)


def _is_tool_library_json(path: Path) -> bool:
    doc = _peek_json(path)
    return isinstance(doc, dict) and "data" in doc and "toolpath" not in doc


def _fusion_json_report(path: Path, library: Any, strict: bool, max_moves: int | None) -> dict[str, Any]:
    from fusioncut.io.fusion_json import read_fusion_json

    tp = read_fusion_json(path)
    doc = _peek_json(path)
    unit = {"in": "inch"}.get(doc.get("unit"), doc.get("unit")) if isinstance(doc, dict) else None
    return _toolpath_report(path, "Fusion JSON toolpath", tp, [unit or "mm"], "from the document's \"unit\"",
                            library)


def _apt_report(path: Path, library: Any, strict: bool, max_moves: int | None) -> dict[str, Any]:
    from fusioncut.io.apt import read_apt

    tp = read_apt(path)
    units, note = _apt_units(path)
    return _toolpath_report(path, "APT / CLSF", tp, units, note, library)


def _gcode_report(path: Path, library: Any, strict: bool, max_moves: int | None) -> dict[str, Any]:
    tp, units = _read_gcode(path, library, strict, max_moves)
    return _toolpath_report(path, "G-code (RS274/NGC)", tp, units,
                            "as programmed by G20/G21; mm where the program states neither", library)


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as e:
        raise InputError(f"cannot read the file: {e.strerror or e}", SourceLocation(str(path))) from None


def _peek_json(path: Path) -> Any:
    """The parsed document, or None when it is not valid JSON (the reader then says where)."""
    try:
        return json.loads(_read_bytes(path).decode("utf-8-sig"))
    except (ValueError, RecursionError):
        return None


def _apt_units(path: Path) -> tuple[list[str], str]:
    text = _read_bytes(path).decode("latin-1")
    words = re.findall(r"^\s*UNITS\s*/\s*([A-Za-z]+)", text, re.IGNORECASE | re.MULTILINE)
    units: list[str] = []
    for w in words:
        u = "mm" if w.upper() == "MM" else "inch"
        if u not in units:
            units.append(u)
    if not units:
        return ["mm"], "no UNITS statement: millimetres assumed"
    return units, "from UNITS/"


def _read_gcode(path: Path, tools: dict[int, MillingTool] | None, strict: bool,
                max_moves: int | None) -> tuple[Toolpath, list[str]]:
    """Read G-code as :func:`fusioncut.io.gcode.read_gcode` does, noting the units of every block
    that moves (a program may switch between G20 and G21)."""
    from fusioncut.io.gcode import GCodeInterpreter, read_gcode_text

    interp = GCodeInterpreter(read_gcode_text(path), source=str(path), tools=tools or None, strict=strict, max_moves=max_moves)
    units: list[str] = []
    # as in GCodeInterpreter.run: the moves are acyclic, so the cyclic collector only costs time
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        for _line, moves in interp:
            if moves:
                u = "inch" if interp.inch else "mm"
                if u not in units:
                    units.append(u)
    finally:
        if was_enabled:
            gc.enable()
    return interp.toolpath(), units or ["inch" if interp.inch else "mm"]


# --------------------------------------------------------------------------------------------------
# reports


def _num(v: float | None) -> float | None:
    return None if v is None else round(float(v), 9)


def _corner_radius(t: MillingTool) -> float:
    if isinstance(t, BallEndMill):
        return t.radius
    cr = getattr(t, "corner_radius", None)
    if cr is not None:
        return float(cr)
    try:
        return float(t.apt().r)
    except FusionCutError:  # a flat-tipped chamfer mill has no APT form, and no corner radius
        return 0.0


def _tool_entry(number: int, t: MillingTool, used: bool | None) -> dict[str, Any]:
    taper = getattr(t, "taper_angle", None)
    return {"number": number, "kind": t.kind, "name": t.name, "diameter_mm": _num(t.diameter),
            "flute_length_mm": _num(t.flute_length), "corner_radius_mm": _num(_corner_radius(t)),
            "taper_angle_deg": _num(taper) if taper else None, "flutes": t.flutes, "used": used}


def _refused(library: Any) -> list[dict[str, Any]]:
    refused = getattr(library, "refused", {}) or {}
    return [{"number": n, "reason": str(e)} for n, e in sorted(refused.items())]


def _range(values: list[float]) -> list[float] | None:
    return [_num(min(values)), _num(max(values))] if values else None  # type: ignore[list-item]


def _extents(moves: list[Move]) -> dict[str, list[float]] | None:
    if not moves:
        return None
    lo = [float("inf")] * 3
    hi = [float("-inf")] * 3
    for m in moves:
        mlo, mhi = m.bounds
        for i in range(3):
            lo[i] = min(lo[i], mlo[i])
            hi[i] = max(hi[i], mhi[i])
    return {"min": [_num(v) for v in lo], "max": [_num(v) for v in hi]}  # type: ignore[misc]


def _library_report(path: Path, library: Any) -> dict[str, Any]:
    suffix = path.suffix.lower()
    if suffix == ".tbl":
        fmt, units, note = "LinuxCNC tool table", ["mm"], "tool tables state no units: read as mm"
    else:
        fmt = "Fusion tool library"
        units, note = _fusion_library_units(path) if suffix == ".json" else (["mm"], "per tool \"unit\"")
    return {
        "file": str(path), "format": fmt, "file_units": units, "units_note": note, "output_units": "mm",
        "tools": [_tool_entry(n, t, None) for n, t in sorted(library.items())],
        "refused_tools": _refused(library), "operations": [], "moves": None, "extents_mm": None,
        "feed_mm_min": None, "spindle_rpm": None, "warnings": list(library.warnings),
    }


def _fusion_library_units(path: Path) -> tuple[list[str], str]:
    doc = _peek_json(path)
    units: list[str] = []
    for entry in (doc.get("data") or []) if isinstance(doc, dict) else []:
        if isinstance(entry, dict):
            u = "inch" if entry.get("unit") == "inches" else "mm"
            if u not in units:
                units.append(u)
    return units or ["mm"], "per tool \"unit\""


def _toolpath_report(path: Path, fmt: str, tp: Toolpath, units: list[str], note: str, library: Any,
                     extra: dict[str, Any] | None = None) -> dict[str, Any]:
    ops: dict[str, dict[str, Any]] = {}
    feeds_by_op: dict[str, list[float]] = {}
    totals = dict.fromkeys(MOVE_KINDS, 0)
    feeds: list[float] = []
    rpms: list[float] = []
    used: set[int] = set()
    for m in tp.moves:
        op = ops.setdefault(m.operation, {"name": m.operation, "tools": [], "moves": dict.fromkeys(MOVE_KINDS, 0)})
        op["moves"][m.kind] += 1
        totals[m.kind] += 1
        if m.tool is not None:
            used.add(m.tool)
            if m.tool not in op["tools"]:
                op["tools"].append(m.tool)
        if not m.is_rapid and m.feed:
            feeds.append(m.feed)
            feeds_by_op.setdefault(m.operation, []).append(m.feed)
        if m.spindle_rpm:
            rpms.append(m.spindle_rpm)
    for name, op in ops.items():
        op["moves"]["total"] = sum(op["moves"].values())
        op["feed_mm_min"] = _range(feeds_by_op.get(name, []))
    totals["total"] = len(tp.moves)
    tools = [_tool_entry(n, t, n in used) for n, t in sorted(tp.tools.items())]
    warnings = list(getattr(library, "warnings", ())) + list(tp.warnings)
    if library is not None:  # the library's tools replaced the program's: say where they disagree
        from fusioncut.io.tool_sources import library_disagreements

        warnings += library_disagreements(tp, library)
    report = {
        "file": str(path), "format": fmt, "file_units": units, "units_note": note, "output_units": "mm, mm/min",
        "tools": tools, "refused_tools": _refused(library), "operations": list(ops.values()), "moves": totals,
        "extents_mm": {"all": _extents(list(tp.moves)), "feed": _extents([m for m in tp.moves if not m.is_rapid])},
        "feed_mm_min": _range(feeds), "spindle_rpm": _range(rpms), "warnings": warnings,
    }
    report.update(extra or {})
    return report


def _camotics_report(path: Path, library: Any, strict: bool, max_moves: int | None) -> dict[str, Any]:
    from fusioncut.io.tool_library import read_camotics_project

    project = read_camotics_project(path)
    tools = library if library is not None else project.tools
    moves: list[Move] = []
    warnings = list(project.warnings)
    units: list[str] = []
    programs = []
    for prog in project.programs:
        entry: dict[str, Any] = {"file": str(prog), "read": False}
        if prog.is_file() and prog.suffix.lower() != ".tpl":
            tp, prog_units = _read_gcode(prog, tools, strict, max_moves)
            moves.extend(tp.moves)
            warnings.extend(tp.warnings)
            units += [u for u in prog_units if u not in units]
            entry.update(read=True, moves=len(tp.moves), units=prog_units)
        programs.append(entry)
    stock = None
    if project.stock is not None:
        stock = {"min": list(project.stock.minimum), "max": list(project.stock.maximum),
                 "inferred_by_camotics": project.stock.inferred}
    project_units = "inch" if project.units == "imperial" else "mm"
    tp = Toolpath(tuple(moves), dict(tools), tuple(warnings), source=str(path))
    report = _toolpath_report(path, "CAMotics project", tp, units or [project_units],
                              f"project default {project.units}; programs as programmed", library,
                              {"stock": stock, "programs": programs})
    report["refused_tools"] = _refused(tools)
    return report


# a toolpath reader's format (fusioncut.io.readers) -> its report
_TOOLPATH_REPORTS = {
    DEFAULT_TOOLPATH_READER.format: _gcode_report,
    TOOLPATH_READERS[".apt"].format: _apt_report,
    TOOLPATH_READERS[".json"].format: _fusion_json_report,
    TOOLPATH_READERS[".camotics"].format: _camotics_report,
}


# --------------------------------------------------------------------------------------------------
# printing


def _fmt(v: float | None, digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}g}"


def _print_report(r: dict[str, Any]) -> None:
    # names from the files (paths, tools, operations, reasons) are escaped: "[d2.4mm]" is no markup
    console.print(f"[bold]{escape(r['file'])}[/]: {r['format']}", highlight=False)
    console.print(f"units in the file: {', '.join(r['file_units'])} ({r['units_note']}); "
                  f"shown here after reading, in {r['output_units']}", highlight=False)
    if r["tools"]:
        t = Table(title="tools")
        for col in ("T", "kind", "diameter mm", "flute length mm", "corner radius mm", "taper deg", "flutes",
                    "name"):
            t.add_column(col, justify="left" if col in ("kind", "name") else "right")
        if any(x["used"] is not None for x in r["tools"]):
            t.add_column("used")
        for x in r["tools"]:
            row = [str(x["number"]), x["kind"], _fmt(x["diameter_mm"]), _fmt(x["flute_length_mm"]),
                   _fmt(x["corner_radius_mm"]), _fmt(x["taper_angle_deg"]), str(x["flutes"]), escape(x["name"])]
            if x["used"] is not None:
                row.append("yes" if x["used"] else "")
            t.add_row(*row)
        console.print(t)
    if r["refused_tools"]:
        t = Table(title="tools that cannot be modelled (left out)")
        t.add_column("T", justify="right")
        t.add_column("reason")
        for x in r["refused_tools"]:
            t.add_row(str(x["number"]), escape(x["reason"]))
        console.print(t)
    if r["moves"] is not None:
        t = Table(title="operations (moves by type; feeds mm/min)")
        for col in ("operation", "tools", *MOVE_KINDS, "total", "feed range"):
            t.add_column(col, justify="left" if col in ("operation", "tools") else "right")
        for op in r["operations"]:
            mv, fr = op["moves"], op["feed_mm_min"]
            t.add_row(escape(op["name"]) or "(none)", ", ".join(f"T{n}" for n in op["tools"]),
                      *(str(mv[k]) for k in MOVE_KINDS), str(mv["total"]),
                      f"{_fmt(fr[0])} - {_fmt(fr[1])}" if fr else "-")
        mv = r["moves"]
        t.add_row("[bold]all[/]", "", *(str(mv[k]) for k in MOVE_KINDS), str(mv["total"]),
                  f"{_fmt(r['feed_mm_min'][0])} - {_fmt(r['feed_mm_min'][1])}" if r["feed_mm_min"] else "-")
        console.print(t)
        ext = r["extents_mm"]
        if ext and ext["all"]:
            t = Table(title="extents of the tool tip path (mm)")
            for col in ("moves", "x min", "x max", "y min", "y max", "z min", "z max"):
                t.add_column(col, justify="left" if col == "moves" else "right")
            for name in ("all", "feed"):
                e = ext[name]
                if e:
                    t.add_row(name, *(f"{e[k][i]:.4f}" for i in range(3) for k in ("min", "max")))
            console.print(t)
        if r["spindle_rpm"]:
            console.print(f"spindle speed {_fmt(r['spindle_rpm'][0])} - {_fmt(r['spindle_rpm'][1])} rpm")
    if r.get("stock"):
        s = r["stock"]
        console.print(f"stock (project workpiece): {s['min']} .. {s['max']} mm"
                      + (" (computed by CAMotics from the toolpath)" if s["inferred_by_camotics"] else ""),
                      highlight=False)
    for p in r.get("programs", []):
        what = f"{p['moves']} moves" if p["read"] else "not read (missing or not G-code)"
        console.print(f"program {escape(p['file'])}: {what}", highlight=False)
    if r["warnings"]:
        console.print(f"[yellow]{len(r['warnings'])} warning(s):[/]")
        for w in r["warnings"][:MAX_WARNINGS_SHOWN]:
            console.print(f"  {w}", highlight=False, markup=False)
        if len(r["warnings"]) > MAX_WARNINGS_SHOWN:
            console.print(f"  ... and {len(r['warnings']) - MAX_WARNINGS_SHOWN} more (see --json)")


def register(app: typer.Typer) -> None:
    @app.command("inspect")
    @friendly_errors
    def inspect_cmd(
        file: Path = typer.Argument(..., help="toolpath (G-code, .apt/.cls, Fusion .json), tool library "
                                              "(.json, .tools, .tbl) or CAMotics .camotics project"),
        tools: Optional[Path] = typer.Option(None, "--tools", help="tool library to read a toolpath with"),
        strict: bool = typer.Option(False, "--strict", help="G-code: unknown or unused words are errors"),
        max_moves: int = typer.Option(DEFAULT_MAX_MOVES, "--max-moves", min=0,
                                      help="G-code: refuse a program that expands to more moves (an arc's "
                                           "extra turns count as moves); 0: no limit"),
        as_json: bool = typer.Option(False, "--json", help="print the report as JSON"),
    ) -> None:
        """Show what FusionCut reads from a toolpath, tool library or CAMotics project (all in mm)."""
        report = inspect_file(file, tools, strict, max_moves or None)
        if as_json:
            typer.echo(json.dumps(report, indent=2, allow_nan=False))
        else:
            _print_report(report)
