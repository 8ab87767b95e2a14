"""Writing a :class:`~fusioncut.model.moves.Toolpath` as an RS274/NGC program that this package reads
back to the same moves.

The program is in millimetres (G21), absolute coordinates (G90), feed per minute (G94) and absolute
arc centres (G90.1), framed by ``%`` lines and ended by ``M5 M30``. Coordinates are machine-frame mm
written with up to 6 decimals (trailing zeros trimmed), so a move reads back within 5e-7 mm. The
program starts at the origin: a rapid to the first move's start comes first (unless it starts
there), and a rapid bridges any gap between one move's end and the next one's start. A tool change
writes ``T<n> M6`` and ``M3``, a new spindle speed ``S`` (modal: a move without a speed after one
with it reads back with it), a new operation its name as a standalone comment (which the reader
takes as the operation of the following moves), a new feed an ``F`` word on the move. Arcs outside
G17 switch the plane (G18, G19) and write their centre words for it; extra turns are ``P``.
Parentheses in names become brackets, since comments do not nest.
"""
from __future__ import annotations

from fusioncut.io.gcode.modal import PLANE_GCODE, PLANE_OFFSET_WORDS
from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Toolpath

__all__ = ["format_number", "write_gcode"]


def format_number(v: float) -> str:
    """``v`` with up to 6 decimals and no float noise: ``8.000000000001`` -> ``8``, ``-0.0`` -> ``0``."""
    s = f"{v:.6f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _comment_text(text: str) -> str:
    return text.replace("(", "[").replace(")", "]")


def write_gcode(toolpath: Toolpath, *, title: str = "") -> str:
    """The program of ``toolpath`` (see the module doc). ``title`` goes into a comment on the header
    line, which has codes: a standalone comment would name an operation."""
    header = "G21 G90 G17 G94 G90.1"
    lines = ["%", f"{header} ({_comment_text(title)})" if title else header]
    num = format_number
    tool: int | None = None
    op: str | None = None
    feed: float | None = None
    rpm: float | None = None
    plane = ArcPlane.XY
    pos = (0.0, 0.0, 0.0)  # a program starts at the origin
    for m in toolpath.moves:
        if m.tool != tool:
            lines.append(f"T{m.tool} M6")
            lines.append("M3" if m.spindle_rpm is None else f"M3 S{num(m.spindle_rpm)}")
            tool, rpm = m.tool, m.spindle_rpm
        elif m.spindle_rpm is not None and m.spindle_rpm != rpm:
            lines.append(f"S{num(m.spindle_rpm)}")
            rpm = m.spindle_rpm
        if m.operation != op:
            lines.append(f"({_comment_text(m.operation)})")
            op = m.operation
        if pos != m.start:
            lines.append(f"G0 X{num(m.start[0])} Y{num(m.start[1])} Z{num(m.start[2])}")
        pos = m.end
        x, y, z = (num(c) for c in m.end)
        if isinstance(m, LinearMove) and m.rapid:
            lines.append(f"G0 X{x} Y{y} Z{z}")
            continue
        f = ""
        if m.feed is not None and m.feed != feed:
            f, feed = f" F{num(m.feed)}", m.feed
        if isinstance(m, ArcMove):
            if m.plane is not plane:
                lines.append(PLANE_GCODE[m.plane])
                plane = m.plane
            ia, ib, _ = m.plane.axes
            oa, ob, _ = PLANE_OFFSET_WORDS[m.plane]
            centre = f"{oa.upper()}{num(m.center[ia])} {ob.upper()}{num(m.center[ib])}"
            turns = f" P{m.turns + 1}" if m.turns else ""
            lines.append(f"{'G2' if m.clockwise else 'G3'} X{x} Y{y} Z{z} {centre}{turns}{f}")
        else:
            lines.append(f"G1 X{x} Y{y} Z{z}{f}")
    lines += ["M5", "M30", "%"]
    return "\n".join(lines) + "\n"
