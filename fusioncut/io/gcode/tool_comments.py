"""Tool descriptions in the comments Fusion 360 / HSM posts write, such as
``(T1 D=2.65 CR=0 - ZMIN=-12.55 - flat end mill)``, read into model tools.

A comment names the tool number, the diameter ``D``, optionally the corner radius ``CR`` and a
``TAPER=..deg`` angle, the deepest Z the tool reaches (``ZMIN``) and Fusion's type name, which hobby
posts follow with the tool's own comment (``flat end mill 2 flute [d2.4mm]``). Numbers are in the
program's units (its first G20/G21). The kind follows the words and numbers: ball (the words, or
``CR = D/2``), drill (``TAPER`` is its point's included angle, 118 degrees if absent), chamfer / spot /
engraving (``TAPER``, 45 degrees if absent), tapered, bull-nose (``CR > 0``), else flat. The comment
gives no flute length: it is taken as :data:`~fusioncut.model.tools.ASSUMED_FLUTE_LENGTH_DIAMETERS`
diameters, or ``-ZMIN`` when the tool reaches deeper.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace

from fusioncut.errors import SourceLocation, ToolDefinitionError
from fusioncut.model.tools import (
    ASSUMED_FLUTE_LENGTH_DIAMETERS,
    BallEndMill,
    BullNoseEndMill,
    ChamferMill,
    Drill,
    FlatEndMill,
    MillingTool,
    TaperedEndMill,
)
from fusioncut.model.units import length_scale

__all__ = ["ToolComment", "parse_tool_comment", "tools_from_comments"]

_TOOL_RE = re.compile(
    r"^\s*T\s*(\d+)\s+D\s*=\s*(\d*\.?\d+)(?:\s+CR\s*=\s*(\d*\.?\d+))?"
    r"(?:\s+TAPER\s*=\s*(\d*\.?\d+)\s*deg)?\s*(.*)$",
    re.I,
)
_ZMIN_RE = re.compile(r"ZMIN\s*=\s*(-?\d*\.?\d+)", re.I)

# Fusion's tool type names (getToolTypeName), longest first: hobby posts append the tool's own
# comment after them, "flat end mill 2 flute [d2.4mm]"
_FUSION_TOOL_TYPES = tuple(sorted((
    "flat end mill", "ball end mill", "bull nose end mill", "face mill", "chamfer mill", "tapered mill",
    "slot mill", "radius mill", "dovetail mill", "lollipop mill", "thread mill", "form mill", "spot drill",
    "center drill", "drill", "reamer", "boring bar", "counter bore", "counter sink", "right tap",
    "left tap", "probe"), key=len, reverse=True))


@dataclass(frozen=True)
class ToolComment:
    """One tool comment as written: lengths in program units, ``taper`` in degrees, ``kind`` the text
    after the numbers (Fusion's type name and the tool's own comment); ``where`` is its place."""

    number: int
    diameter: float
    corner_radius: float | None
    taper: float | None
    zmin: float | None
    kind: str
    where: SourceLocation | None = None


def parse_tool_comment(text: str) -> ToolComment | None:
    """``T1 D=2.65 CR=0 - ZMIN=-12.55 - flat end mill`` -> its :class:`ToolComment`; ``None`` when
    the comment is not a tool description."""
    m = _TOOL_RE.match(text)
    if not m:
        return None
    try:
        d = float(m.group(2))
        cr = float(m.group(3)) if m.group(3) else None
        taper = float(m.group(4)) if m.group(4) else None
    except ValueError:
        return None
    rest = m.group(5) or ""
    zm = _ZMIN_RE.search(rest)
    zmin = float(zm.group(1)) if zm else None
    parts = [p.strip() for p in rest.split(" - ") if p.strip()]
    kind = parts[-1] if parts else ""
    if kind.upper().startswith("ZMIN"):
        kind = ""
    return ToolComment(int(m.group(1)), d, cr, taper, zmin, kind)


def tools_from_comments(comments: dict[int, ToolComment], inch: bool,
                        warnings: list[str]) -> dict[int, MillingTool]:
    """The tools of a program's comments (``inch``: the program's first units were G20), each with its
    ``file:line`` as source; a comment that makes no valid tool is left out with a warning."""
    scale = length_scale(inch)
    tools: dict[int, MillingTool] = {}
    for number, c in comments.items():
        try:
            tool = _make_tool(number, c.diameter * scale, (c.corner_radius or 0.0) * scale, c.taper,
                              None if c.zmin is None else c.zmin * scale, c.kind)
            tools[number] = replace(tool, source=str(c.where), name=_tool_name(c.kind))
        except ToolDefinitionError as e:
            warnings.append(f"{c.where}: tool comment not usable: {e.reason}")
    return tools


def _tool_name(kind: str) -> str:
    """A tool comment's own words, as written: what follows Fusion's type name, or all of the text
    when it starts with no type name Fusion writes."""
    text = kind.strip().lstrip("-").strip()  # a comment without ZMIN keeps the " - " before the type
    low = text.lower()
    for t in _FUSION_TOOL_TYPES:
        if low.startswith(t):
            return text[len(t):].strip()
    return text


def _make_tool(number: int, d: float, cr: float, taper: float | None, zmin: float | None, kind: str) -> MillingTool:
    """A model tool from a post's tool comment (mm); see the module doc for the rules."""
    flute = ASSUMED_FLUTE_LENGTH_DIAMETERS * d
    if zmin is not None and zmin < 0:
        flute = max(flute, -zmin)
    words = kind.lower()
    if "ball" in words or (cr > 0 and abs(cr - d / 2) < 1e-9):
        return BallEndMill(diameter=d, flute_length=max(flute, d / 2), number=number)
    if "drill" in words:  # Fusion's TAPER= of a drill is its point's included angle (118 typical)
        return Drill(diameter=d, flute_length=flute, point_angle=taper or 118.0, number=number)
    if any(k in words for k in ("chamfer", "spot", "engrav", "countersink", "v-bit", "vbit")):
        return ChamferMill(diameter=d, flute_length=flute, taper_angle=taper or 45.0, number=number)
    if "taper" in words and taper:
        return TaperedEndMill(diameter=d, flute_length=flute, taper_angle=taper, number=number)
    if cr > 0:
        return BullNoseEndMill(diameter=d, flute_length=flute, corner_radius=cr, number=number)
    return FlatEndMill(diameter=d, flute_length=flute, number=number)
