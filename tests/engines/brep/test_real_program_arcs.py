"""Arcs as a real post writes them keep their engagement (issue 23 item 1), and a drilling cycle of a
Fusion drill cuts its closed-form hole (item 7).

Invariant checked on a real program: every CL that removes material has engaged slices, unless its
map says why not (it ends clear of the material, or its slices only rub). The program is the first
600 lines of ``fusion-posted/1110_wall_265bit.nc`` (a Fusion 2D pocket with a 2.65 mm flat: G2/G3 with
I/J and end points at 3 decimals, so start and end radius differ by up to a µm), on the stock the
whole program infers. Before arcs were swept as spirals, 5,992 of the program's 6,351 engaged arc CLs
had no slices at all.
"""
from __future__ import annotations

import math

import pytest

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.io.gcode import parse_gcode_text, read_gcode
from fusioncut.io.stock import infer_stock
from fusioncut.model import ArcMove, BoxStock, CLStatus, Drill

from shared_data import DATA

WALL = DATA / "fusion-posted" / "1110_wall_265bit.nc"


@pytest.mark.skipif(not WALL.exists(), reason="shared data not available")
def test_every_cl_of_a_posted_pocket_that_removes_material_has_slices():
    lines = WALL.read_text().splitlines()
    head = parse_gcode_text("\n".join(lines[:600] + ["M30"]) + "\n", source=str(WALL))
    stock = infer_stock(read_gcode(WALL))
    engine = BRepEngine(EngineOptions())
    maps = list(engine.run(head, stock))
    arcs = {m.source for m in head.moves if isinstance(m, ArcMove)}
    removing = [m for m in maps if m.removed_volume > 0]
    silent = [(m.cl_index, m.source, m.removed_volume) for m in removing if not m.engaged_slices
              and not any("ends clear" in w or "only rub" in w for w in m.warnings)]
    assert silent == []
    on_arcs = [m for m in removing if m.source in arcs]
    assert len(on_arcs) > 150
    assert all(m.engaged_slices for m in on_arcs if m.removed_volume > 1e-3)
    assert [m.cl_index for m in maps if m.status == CLStatus.FAILED] == []
    assert stock.volume - engine.ipw_volume == pytest.approx(sum(m.removed_volume for m in maps), rel=1e-9)


@pytest.mark.parametrize("angle", [118.0, 140.0])
def test_a_fusion_drill_in_a_g81_cycle_cuts_its_closed_form_hole(angle):
    """A 6.8 mm drill (Fusion's comment gives its point angle as TAPER) drills 10 mm into a block:
    the hole is a cylinder down to where the point starts and the point's cone below it; every
    slice the drill's body fills is engaged all round."""
    text = (f"(T5 D=6.8 CR=0 TAPER={angle:g}deg - ZMIN=-10 - drill)\nG21\nT5 M6\nS1000 M3\n"
            "G0 X0 Y0 Z5\nG81 X0 Y0 Z-10 R2 F100\nG80\nG0 Z5\nM30\n")
    toolpath = parse_gcode_text(text, source="drill.nc")
    drill = toolpath.tools[5]
    assert isinstance(drill, Drill)
    stock = BoxStock((-10, -10, -20), (10, 10, 0))
    engine = BRepEngine(EngineOptions())
    maps = list(engine.run(toolpath, stock))
    r, cone = 3.4, 3.4 / math.tan(math.radians(angle / 2))
    hole = math.pi * r * r * (10 - cone) + math.pi * r * r * cone / 3
    assert sum(m.removed_volume for m in maps) == pytest.approx(hole, rel=1e-9)
    assert stock.volume - engine.ipw_volume == pytest.approx(hole, rel=1e-9)
    plunge = [m for m in maps if m.removed_volume > 0]
    assert len(plunge) == 1 and plunge[0].status == CLStatus.ENGAGED and plunge[0].ap == pytest.approx(10.0)
    body = [s for s in plunge[0].engaged_slices if s.z > cone]
    assert len(body) >= 7
    assert all([(i.entry, i.exit) for i in s.intervals] == [(0.0, 360.0)] for s in body)
