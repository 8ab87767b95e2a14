"""Which reader reads a file: toolpaths and tool libraries, chosen by the file's suffix.

Two registries, suffix (lower case, with the dot) -> :class:`Reader`:

* :data:`TOOLPATH_READERS`: APT/CLSF, Fusion JSON post, CAMotics project and G-code. A suffix not
  listed is read as RS274/NGC G-code (:data:`DEFAULT_TOOLPATH_READER`): posts name their files
  ``.mpf``, ``.eia``, ``.h``, ``.cnc`` and more.
* :data:`TOOL_LIBRARY_READERS`: Fusion ``.json`` / ``.tools`` and LinuxCNC ``.tbl``.

A new format is one entry here (and its reader module under ``fusioncut/io``); :func:`read_toolpath`,
``fusioncut run``, ``fusioncut inspect``, the job's ``toolpaths`` and :func:`fusioncut.simulate` all
read through these tables. The reader modules are imported when a file of theirs is read.
Everything a reader returns is in mm and mm/min.
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

from fusioncut.errors import InputError, SourceLocation
from fusioncut.model.moves import Toolpath
from fusioncut.model.tools import MillingTool

if TYPE_CHECKING:
    from fusioncut.io.tool_library import ToolLibrary

__all__ = ["DEFAULT_TOOLPATH_READER", "TOOLPATH_READERS", "TOOL_LIBRARY_READERS", "Reader", "is_job_file",
           "read_tool_library", "read_toolpath", "toolpath_format"]

ToolpathFunction = Callable[[Path, "dict[int, MillingTool] | None", bool], Toolpath]


class Reader(NamedTuple):
    """A file format: its name as reports show it, and the function that reads it."""

    format: str
    read: Callable[..., object]


# --------------------------------------------------------------------------------------------------
# toolpaths: read(path, tools, strict) -> Toolpath. ``tools`` replace the tools a G-code program
# describes in its comments and give cutter compensation its radii; APT, Fusion JSON and CAMotics
# projects state their own cutters (a CAMotics project's tools are given to its G-code programs).


def _gcode(path: Path, tools: dict[int, MillingTool] | None, strict: bool) -> Toolpath:
    from fusioncut.io.gcode import read_gcode

    return read_gcode(path, tools=tools or None, strict=strict)


def _apt(path: Path, tools: dict[int, MillingTool] | None, strict: bool) -> Toolpath:
    from fusioncut.io.apt import read_apt

    return read_apt(path)


def _fusion_json(path: Path, tools: dict[int, MillingTool] | None, strict: bool) -> Toolpath:
    from fusioncut.io.fusion_json import read_fusion_json

    return read_fusion_json(path)


def _camotics(path: Path, tools: dict[int, MillingTool] | None, strict: bool) -> Toolpath:
    """The G-code programs a ``.camotics`` project names, in order, read with the project's tools
    (or ``tools`` when given); its workpiece is a stock (:func:`fusioncut.io.stock.parse_stock`)."""
    from fusioncut.io.tool_library import read_camotics_project

    project = read_camotics_project(path)
    own = dict(project.tools)
    given = tools or own
    moves, warnings = [], list(project.warnings)
    for program in project.programs:
        if not program.is_file() or program.suffix.lower() == ".tpl":
            continue  # the project's warnings name it
        tp = _gcode(program, given, strict)
        moves.extend(tp.moves)
        warnings.extend(tp.warnings)
    if not moves:
        raise InputError("the CAMotics project names no G-code program that could be read", SourceLocation(str(path)))
    return Toolpath(tuple(moves), dict(given), tuple(warnings), source=str(path),
                    program_tools=own if tools else None)


DEFAULT_TOOLPATH_READER = Reader("G-code (RS274/NGC)", _gcode)
_APT = Reader("APT / CLSF", _apt)
TOOLPATH_READERS: dict[str, Reader] = {
    **dict.fromkeys((".nc", ".ngc", ".tap", ".gcode", ".cnc"), DEFAULT_TOOLPATH_READER),
    **dict.fromkeys((".apt", ".cls", ".clsf", ".aptsource"), _APT),
    ".json": Reader("Fusion JSON toolpath", _fusion_json),
    ".camotics": Reader("CAMotics project", _camotics),
}


def toolpath_format(path: str | Path) -> Reader:
    """The reader of a toolpath file, by its suffix (G-code for a suffix not in the registry)."""
    return TOOLPATH_READERS.get(Path(path).suffix.lower(), DEFAULT_TOOLPATH_READER)


def read_toolpath(path: str | Path, tools: dict[int, MillingTool] | None = None, strict: bool = False) -> Toolpath:
    """Read a toolpath file with the reader its suffix names (:data:`TOOLPATH_READERS`); moves in mm
    and mm/min, errors an :class:`~fusioncut.errors.InputError` naming ``file:line``.

    ``tools`` (G-code and CAMotics projects) replace the tools the program describes and give cutter
    compensation its radii; ``strict`` refuses what G-code readers otherwise only warn about."""
    p = Path(path)
    return toolpath_format(p).read(p, tools, strict)  # type: ignore[return-value]


def is_job_file(path: str | Path) -> bool:
    """Whether ``path`` is a FusionCut job (a ``.json`` object naming ``toolpaths``) rather than a
    toolpath; a file that is not valid JSON is not a job (its reader then says what is wrong)."""
    p = Path(path)
    if p.suffix.lower() != ".json" or not p.is_file():
        return False
    import json

    try:
        data = p.read_bytes()
        if b'"toolpaths"' not in data:  # a Fusion JSON post (megabytes) is not parsed twice
            return False
        doc = json.loads(data.decode("utf-8-sig"))
    except (OSError, ValueError, RecursionError):
        return False
    return isinstance(doc, dict) and "toolpaths" in doc


# --------------------------------------------------------------------------------------------------
# tool libraries: read(path) -> ToolLibrary (a dict[int, MillingTool] in mm with its warnings)


def _library(path: Path) -> ToolLibrary:
    from fusioncut.io.tool_library import read_tool_library as read

    return read(path)


TOOL_LIBRARY_READERS: dict[str, Reader] = {
    ".json": Reader("Fusion tool library", _library),
    ".tools": Reader("Fusion tool library archive", _library),
    ".tbl": Reader("LinuxCNC tool table", _library),
}


def read_tool_library(path: str | Path) -> ToolLibrary:
    """Read a tool library with the reader its suffix names (:data:`TOOL_LIBRARY_READERS`); an unknown
    suffix is an :class:`~fusioncut.errors.InputError` listing the known ones."""
    p = Path(path)
    reader = TOOL_LIBRARY_READERS.get(p.suffix.lower())
    if reader is None:
        raise InputError(f"unknown tool library type {p.suffix!r} (expected {', '.join(TOOL_LIBRARY_READERS)})",
                         SourceLocation(str(p)))
    return reader.read(p)  # type: ignore[return-value]
