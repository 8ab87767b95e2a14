"""The built-in demo (:mod:`fusioncut.demo`) as an ordinary service job: a G-code file and a job.

The service runs only jobs made of files, so that a demo job is run, resumed, listed and downloaded
exactly like an uploaded one. The demo toolpath is written out as RS274 G-code (absolute arc centres,
operation names as standalone comments, which is how the G-code reader takes operation names) and
the tools and the stock go into the job, so reading the file back gives the demo's moves.
"""
from __future__ import annotations

from typing import Any

from fusioncut.model import ArcMove, BallEndMill, FlatEndMill, LinearMove, MillingTool

DEMO_FILE = "demo.ngc"
# the CLI demo's segment length: short CLs give smooth engagement curves
DEMO_OPTIONS = {"slice_height": 1.0, "max_segment_length": 2.0}


def _num(v: float) -> str:
    # repr-exact for the demo's decimal coordinates, without float noise like 8.000000000001
    s = f"{v:.6f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _tool_spec(t: MillingTool) -> dict[str, Any]:
    kind = "ball" if isinstance(t, BallEndMill) else "flat" if isinstance(t, FlatEndMill) else None
    if kind is None:
        raise ValueError(f"demo tool {t.label} is neither flat nor ball")
    return {"number": t.number, "kind": kind, "diameter": t.diameter, "flute_length": t.flute_length,
            "flutes": t.flutes, "helix_angle": t.helix_angle, "spindle": t.spindle.value, "name": t.name}


def demo_gcode() -> str:
    """The demo toolpath as G-code, preceded by one rapid from the origin to the demo's start point."""
    from fusioncut.demo import demo_toolpath

    tp = demo_toolpath()
    # the title shares its line with codes: a standalone comment would name an operation
    lines = ["%", "G21 G90 G17 G94 G90.1 (FusionCut demo: face, slot, trochoidal, contour, ball finish)"]
    tool, op, feed = None, None, None
    for k, m in enumerate(tp.moves):
        if m.tool != tool:
            lines.append(f"T{m.tool} M6")
            lines.append("M3")
            tool = m.tool
        if m.operation != op:
            lines.append(f"({m.operation})")
            op = m.operation
        if k == 0:  # a program starts at the origin; go to the demo's start point first
            lines.append(f"G0 X{_num(m.start[0])} Y{_num(m.start[1])} Z{_num(m.start[2])}")
        x, y, z = (_num(c) for c in m.end)
        if isinstance(m, LinearMove) and m.rapid:
            lines.append(f"G0 X{x} Y{y} Z{z}")
            continue
        f = ""
        if m.feed is not None and m.feed != feed:
            f, feed = f" F{_num(m.feed)}", m.feed
        if isinstance(m, ArcMove):
            g = "G2" if m.clockwise else "G3"
            lines.append(f"{g} X{x} Y{y} Z{z} I{_num(m.center[0])} J{_num(m.center[1])}{f}")
        else:
            lines.append(f"G1 X{x} Y{y} Z{z}{f}")
    lines += ["M5", "M30", "%"]
    return "\n".join(lines) + "\n"


def demo_job(name: str = "demo") -> dict[str, Any]:
    """The demo's job JSON (tools and stock from :mod:`fusioncut.demo`), reading :data:`DEMO_FILE`."""
    from fusioncut.demo import demo_stock, demo_toolpath

    tp, stock = demo_toolpath(), demo_stock()
    return {"name": name, "stock": {"kind": "box", "min": list(stock.minimum), "max": list(stock.maximum)},
            "tools": [_tool_spec(t) for _, t in sorted(tp.tools.items())],
            "toolpaths": [DEMO_FILE], "options": dict(DEMO_OPTIONS)}
