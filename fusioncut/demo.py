"""The built-in demo: an aluminium block milled with a flat and a ball end mill.

Operations (all feeds in mm/min): a face pass, a full slot, trochoidal clearing, a contour with
arcs, and a ball-end finishing pass with a ramp entry. Geometry in mm, block 80 x 50 x 20, top z=0.
"""
from __future__ import annotations

from typing import Any

from fusioncut.io.gcode.writer import write_gcode
from fusioncut.io.job import ToolSpec
from fusioncut.model import ArcMove, BallEndMill, BoxStock, FlatEndMill, LinearMove, Move, Toolpath

STOCK = BoxStock((0.0, 0.0, -20.0), (80.0, 50.0, 0.0))
FLAT = FlatEndMill(10.0, 25.0, flutes=3, helix_angle=35.0, number=1, name="T1 10mm flat")
BALL = BallEndMill(6.0, 15.0, flutes=2, helix_angle=30.0, number=2, name="T2 6mm ball")
SAFE = 5.0


class _Path:
    def __init__(self) -> None:
        self.moves: list[Move] = []
        self.pos = (0.0, 0.0, 30.0)
        self.op = ""
        self.tool = 1

    def rapid(self, x: float, y: float, z: float) -> None:
        self.moves.append(LinearMove(self.pos, (x, y, z), tool=self.tool, operation=self.op, rapid=True))
        self.pos = (x, y, z)

    def feed(self, x: float, y: float, z: float, f: float = 900.0) -> None:
        self.moves.append(LinearMove(self.pos, (x, y, z), feed=f, tool=self.tool, operation=self.op))
        self.pos = (x, y, z)

    def arc(self, x: float, y: float, cx: float, cy: float, cw: bool, f: float = 900.0) -> None:
        self.moves.append(ArcMove(self.pos, (x, y, self.pos[2]), center=(cx, cy, self.pos[2]), clockwise=cw,
                                  feed=f, tool=self.tool, operation=self.op))
        self.pos = (x, y, self.pos[2])

    def go_down(self, x: float, y: float, z: float) -> None:
        self.rapid(self.pos[0], self.pos[1], SAFE)
        self.rapid(x, y, SAFE)
        self.feed(x, y, z, 300.0)


def demo_toolpath() -> Toolpath:
    p = _Path()
    p.op, p.tool = "Face", 1
    for k, y in enumerate((4.0, 12.0, 20.0, 28.0, 36.0, 44.0)):
        xs = (-6.0, 86.0) if k % 2 == 0 else (86.0, -6.0)
        if k == 0:
            p.go_down(xs[0], y, -0.5)
        else:
            p.feed(xs[0], y, -0.5)
        p.feed(xs[1], y, -0.5, 1500.0)
    p.op = "Slot"
    p.go_down(-6.0, 25.0, -3.5)
    p.feed(86.0, 25.0, -3.5)
    p.op = "Trochoidal"
    p.go_down(-6.0, 8.0, -4.5)
    p.feed(8.0, 8.0, -4.5)
    r, step = 2.5, 1.5
    x = 8.0
    while x < 40.0:  # each loop: a half circle of radius r out, a smaller one back, net advance `step`
        p.arc(x + 2 * r, 8.0, x + r, 8.0, cw=False)
        p.arc(x + step, 8.0, x + r + step / 2, 8.0, cw=False)
        x += step
    p.op = "Contour"
    p.go_down(60.0, -5.5, -6.0)
    p.feed(74.0, -5.5, -6.0)
    p.arc(85.5, 6.0, 74.0, 6.0, cw=False)
    p.feed(85.5, 44.0, -6.0)
    p.arc(74.0, 55.5, 74.0, 44.0, cw=False)
    p.feed(55.0, 55.5, -6.0)
    p.op, p.tool = "Ball finish", 2
    p.go_down(20.0, 40.0, 1.0)
    p.feed(30.0, 40.0, -2.0, 400.0)  # ramp entry
    p.feed(60.0, 40.0, -2.0, 1200.0)
    p.feed(60.0, 34.0, -2.0, 1200.0)
    p.feed(20.0, 34.0, -2.0, 1200.0)
    p.rapid(p.pos[0], p.pos[1], SAFE)
    return Toolpath(tuple(p.moves), {1: FLAT, 2: BALL}, source="<demo>")


def demo_stock() -> BoxStock:
    return STOCK


# -------------------------------------------------------------------------------------------------
# The demo as a job of files: the CLI's `fusioncut demo` and the service's demo job run this one job,
# so both read the same G-code and make the same CLs (the G-code's first rapid from the origin is a
# CL the moves above do not have).

DEMO_FILE = "demo.ngc"
# the demo's job options, for `fusioncut demo`, `fusioncut view demo` and the service's demo alike:
# short CLs give smooth engagement curves
DEMO_OPTIONS = {"slice_height": 1.0, "max_segment_length": 2.0}


def demo_gcode() -> str:
    """The demo toolpath as G-code (:func:`fusioncut.io.gcode.writer.write_gcode`: a rapid from the
    origin to the demo's start point first)."""
    return write_gcode(demo_toolpath(), title="FusionCut demo: face, slot, trochoidal, contour, ball finish")


def demo_job(name: str = "demo", **options: Any) -> dict[str, Any]:
    """The demo's job JSON (its tools and stock), reading :data:`DEMO_FILE` (:func:`demo_gcode`): the
    one job that ``fusioncut demo`` runs and that the service's demo submits."""
    tp, stock = demo_toolpath(), demo_stock()
    return {"name": name, "stock": {"kind": "box", "min": list(stock.minimum), "max": list(stock.maximum)},
            "tools": [ToolSpec.of(t, n).model_dump(exclude_defaults=True) for n, t in sorted(tp.tools.items())],
            "toolpaths": [DEMO_FILE], "options": {**DEMO_OPTIONS, **options}}


__all__ = ["DEMO_FILE", "DEMO_OPTIONS", "demo_gcode", "demo_job", "demo_stock", "demo_toolpath"]
