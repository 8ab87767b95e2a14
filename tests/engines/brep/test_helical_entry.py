"""A helical entry, the way adaptive programs start a pocket: closed-form volume, no CL lost.

The tool's radius (6 mm) exceeds the helix's (4 mm), as in the Titan-like benchmark where OCCT's
Booleans on oblique chord sweeps went silently wrong (0 mm³ removed by a chord that must remove
>= 5.6 mm³, then 7,193 mm³ by a later one). After the helix and one flat circle at the bottom,
the pocket is exactly a cylinder of radius r + R.
"""
from __future__ import annotations

import math

import pytest

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.model import ArcMove, BoxStock, CLStatus, FlatEndMill, LinearMove, Toolpath

R, RHO, PITCH, DEPTH = 6.0, 4.0, 2.0, 3.0
STOCK = BoxStock((-20, -20, -10), (20, 20, 0))


def helical_entry() -> Toolpath:
    top = 0.5  # the helix starts in air, above the stock
    start = (RHO, 0.0, top)
    turns_z = top + DEPTH
    moves = [LinearMove((RHO, 0.0, 5.0), start, feed=1000.0, tool=1)]
    # 1.75 turns clockwise (G2) down to -DEPTH: one whole turn plus three quarters
    moves.append(ArcMove(start, (0.0, RHO, -DEPTH), center=(0.0, 0.0, top), clockwise=True, turns=1,
                         feed=800.0, tool=1))
    # one flat turn at the bottom, in quarters, so the pocket's floor is flat
    pts = [(0.0, RHO), (RHO, 0.0), (0.0, -RHO), (-RHO, 0.0), (0.0, RHO)]
    for a, b in zip(pts, pts[1:]):
        moves.append(ArcMove((*a, -DEPTH), (*b, -DEPTH), center=(0.0, 0.0, -DEPTH), clockwise=True,
                             feed=800.0, tool=1))
    assert turns_z / (1.75 * 2 * math.pi * RHO) < 0.2  # a ramp, as CAM posts them
    return Toolpath(tuple(moves), {1: FlatEndMill(2 * R, 20.0, number=1)})


@pytest.mark.parametrize("layers", [True, False])
@pytest.mark.parametrize("cell_size", [None, 20.0])
def test_helical_entry_removes_the_closed_form_pocket(cell_size, layers):
    # with 20 mm cells the helix is centred on the corner of four cells and crosses their walls
    engine = BRepEngine(EngineOptions(ramp_step=0.05, cell_size=cell_size, layers=layers))
    maps = list(engine.run(helical_entry(), STOCK))
    assert [m.status for m in maps if m.status == CLStatus.FAILED] == []
    removed = sum(m.removed_volume for m in maps)
    assert removed == pytest.approx(math.pi * (RHO + R) ** 2 * DEPTH, rel=1e-6)
    assert STOCK.volume - engine.ipw_volume == pytest.approx(removed, rel=1e-9)
    # every step below the stock top goes deeper over the whole tool's bottom disk
    helix_steps = [m for m in maps if m.sweep_method == "step" and m.position[2] < 0]
    assert len(helix_steps) > 50
    for m in helix_steps:
        assert m.start[2] > m.position[2]  # the CL is the piece of the helix, on the path
        assert m.status == CLStatus.ENGAGED and m.removed_volume > 0


def test_r_format_helix_of_the_tool_radius_as_posted(tmp_path):
    """A Fusion hobby post's helical entry for a 3.175 mm end mill: R-format quarter arcs of the tool's
    radius, coordinates at 3 decimals, so the tool's edge passes within a µm of the helix axis at every
    step. The layers' 2D cuts left sub-µm islands of material there (edges of 1.7e-7 mm): their faces
    could not be built (a checkpoint ended the run with StdFail_NotDone) and four CLs failed. No CL
    fails now, a checkpoint after every CL is written, and the volume adds up."""
    from fusioncut.io.gcode import read_gcode

    r, cx, cy = 1.5875, 10.0, 7.047591954504442
    f = "{:.3f}".format
    lines = ["G90 G17 G21", f"G0 X{f(cx + r)} Y{f(cy)}", "G0 Z2", "G1 Z0.2 F300"]
    z, a = 0.2, 0.0
    while z > -2.0 + 1e-9:
        a, z = a + math.pi / 2, max(-2.0, z - 0.2)
        lines.append(f"G3 X{f(cx + r * math.cos(a))} Y{f(cy + r * math.sin(a))} Z{f(z)} R{f(r)} F600")
    for _ in range(4):
        a += math.pi / 2
        lines.append(f"G3 X{f(cx + r * math.cos(a))} Y{f(cy + r * math.sin(a))} R{f(r)}")
    lines += [f"G1 X{f(cx + 3)} Y{f(cy)} F800", f"G3 X{f(cx - 3)} Y{f(cy)} I-3 J0", "G0 Z5", "M30"]
    src = tmp_path / "helix.nc"
    src.write_text("\n".join(lines) + "\n")
    tool = FlatEndMill(3.175, 12, number=1)
    stock = BoxStock((0, 0, -6), (40, 40, 0))
    eng = BRepEngine(EngineOptions(max_segment_length=1.0, failure_dir=tmp_path / "failures"))
    maps = []
    for m in eng.run(read_gcode(src, tools={1: tool}), stock, default_tool=tool):
        maps.append(m)
        eng.save_checkpoint(tmp_path / "ck", m.cl_index + 1)
    assert [m.cl_index for m in maps if m.status == CLStatus.FAILED] == []
    assert sum(m.removed_volume for m in maps) == pytest.approx(stock.volume - eng.ipw_volume, rel=1e-9)
