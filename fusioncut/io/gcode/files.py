"""Reading G-code programs from text or files into a :class:`~fusioncut.model.moves.Toolpath`.

Files are decoded as UTF-8, or as Latin-1 when they are not valid UTF-8: G-code is ASCII, and old
posts write Latin-1 comments, which should not make a program unreadable.
"""
from __future__ import annotations

from pathlib import Path

from fusioncut.errors import InputError
from fusioncut.io.gcode.budget import DEFAULT_MAX_MOVES
from fusioncut.io.gcode.interpreter import ArcCenters, GCodeInterpreter
from fusioncut.model.moves import Toolpath
from fusioncut.model.tools import MillingTool

__all__ = ["decode_gcode", "parse_gcode_text", "read_gcode", "read_gcode_text"]


def decode_gcode(raw: bytes) -> tuple[str, str]:
    """The text of a G-code file's bytes and the encoding it was read with (``utf-8`` or ``latin-1``)."""
    try:
        return raw.decode("utf-8"), "utf-8"
    except UnicodeDecodeError:
        return raw.decode("latin-1"), "latin-1"


def read_gcode_text(path: str | Path) -> str:
    """A G-code file's text (see :func:`decode_gcode`); an unreadable file is an :class:`InputError`."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise InputError(f"cannot read G-code file: {e.strerror}", p) from None
    return decode_gcode(raw)[0]


def parse_gcode_text(
    text: str,
    *,
    source: str = "<memory>",
    tools: dict[int, MillingTool] | None = None,
    strict: bool = False,
    arc_centers: ArcCenters = "auto",
    max_moves: int | None = DEFAULT_MAX_MOVES,
) -> Toolpath:
    """Interpret G-code text into a :class:`Toolpath` (mm, machine frame, tool tip); see the package doc."""
    interp = GCodeInterpreter(text, source=source, tools=tools, strict=strict, arc_centers=arc_centers,
                              max_moves=max_moves)
    interp.run()
    return interp.toolpath()


def read_gcode(
    path: str | Path,
    *,
    tools: dict[int, MillingTool] | None = None,
    strict: bool = False,
    arc_centers: ArcCenters = "auto",
    max_moves: int | None = DEFAULT_MAX_MOVES,
) -> Toolpath:
    """Read and interpret a G-code file into a :class:`Toolpath`; errors name ``file:line:column``."""
    return parse_gcode_text(read_gcode_text(path), source=str(path), tools=tools, strict=strict,
                            arc_centers=arc_centers, max_moves=max_moves)
