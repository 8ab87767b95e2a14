"""The volume's conservation: the workpiece integrated in one piece from the sweeps
(:meth:`AnalyticEngine.material_volume`) against the CLs' removed volumes, which it never reads.
Closed forms first, then a mixed program on coordinates rounded as a post writes them, then a real
program's window."""
from __future__ import annotations

import math

import pytest

from fusioncut.engines.analytic.conservation import window_material
from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.base import EngineOptions
from fusioncut.errors import InputError
from fusioncut.model import (ArcMove, BallEndMill, BoxStock, BullNoseEndMill, CylinderStock, FlatEndMill, LinearMove,
                             Toolpath)
from tests.engines.analytic.test_engine import feed, run

VOLUME_REL = AnalyticEngine.volume_rel  # each integral's relative tolerance
STOCK = BoxStock((-15, -15, -10), (15, 15, 0))


def test_untouched_stock_is_its_volume():
    for stock, volume in ((STOCK, 30 * 30 * 10), (CylinderStock((1.0, -2.0, -10.0), 20.0, 10.0), math.pi * 400 * 10)):
        eng = AnalyticEngine(EngineOptions())
        eng.start(stock)
        assert eng.material_volume() == pytest.approx(volume, rel=1e-12)
    with pytest.raises(InputError, match="start"):
        AnalyticEngine(EngineOptions()).material_volume()
    with pytest.raises(InputError, match="start"):  # not a CL failing on an empty stock
        next(AnalyticEngine(EngineOptions()).process(Toolpath((feed((0, 0, 5), (0, 0, -1)),), {1: FlatEndMill(6, 20)})))


def test_a_slot_closed_form():
    """A flat end mill of radius 3 slotting 20 mm at 2 mm deep takes (20 x 6 + 9 pi) x 2 mm³: the
    material left is the stock's less that, over the whole stock and over a box around one end."""
    eng, maps = run([feed((-10, 0, 5), (-10, 0, -2)), feed((-10, 0, -2), (10, 0, -2))], {1: FlatEndMill(6, 20)},
                    STOCK, max_segment_length=4.0)
    slot = (20 * 6 + 9 * math.pi) * 2
    assert sum(m.removed_volume for m in maps) == pytest.approx(slot, rel=1e-9)
    assert eng.material_volume() == pytest.approx(30 * 30 * 10 - slot, rel=1e-12)
    # the box x in [8, 20], y in [-5, 5]: the slot's last 2 mm and its round end
    assert eng.material_volume((8.0, -5.0, 20.0, 5.0)) == pytest.approx(7 * 10 * 10 - (2 * 6 + 4.5 * math.pi) * 2,
                                                                        rel=1e-12)


def mixed_program() -> Toolpath:
    """A ball end mill plunging, ramping, cutting a line, an XY arc, a 3D line and a helix, then a
    bull-nose crossing its grooves: every kind of sweep, its coordinates rounded to 3 decimals as a
    post writes them (the arc's end radius then differs from its start's by up to 1e-3)."""
    a = math.radians(23.0)
    ramp_end = (round(-10 + 3 * math.cos(a), 3), round(-6 + 3 * math.sin(a), 3), -1.5)
    arc_end = (round(6 + 3 * math.sqrt(0.5), 3), round(-3 - 3 * math.sqrt(0.5), 3), -1.5)
    moves = [
        feed((-10, -6, 5), (-10, -6, -1)),
        feed((-10, -6, -1), ramp_end),  # shallow: stepped
        feed(ramp_end, (6.0, -6.0, -1.5)),
        ArcMove((6.0, -6.0, -1.5), arc_end, feed=600.0, tool=1, center=(6.0, -3.0, -1.5), clockwise=False),
        feed(arc_end, (-6.0, 1.0, -6.0)),  # a 3D line, steeper than the stepped ramps
        ArcMove((-6.0, 1.0, -6.0), (-8.333, 3.333, -6.2), feed=600.0, tool=1, center=(-6.0, 3.333, -6.0),
                clockwise=True),  # a quarter turn of a helix, down 0.2
        feed((-8.333, 3.333, -6.2), (-8.333, 3.333, 5.0)),
        LinearMove((-13.0, -9.0, 5.0), (-13.0, -9.0, -2.0), feed=600.0, tool=2),
        LinearMove((-13.0, -9.0, -2.0), (9.123, 4.457, -2.0), feed=600.0, tool=2),
    ]
    return Toolpath(tuple(moves), {1: BallEndMill(4, 20), 2: BullNoseEndMill(6, 20, corner_radius=1.0)})


def test_a_mixed_program_conserves_its_volume():
    """Over the whole program the stock is the material left plus the CLs' removed volumes, and over
    a window of CLs the box around their footprints loses what they removed, each to the integrals'
    tolerance (the engine's ``volume_rel`` of each)."""
    options = EngineOptions(max_segment_length=20.0)
    toolpath = mixed_program()
    eng = AnalyticEngine(options)
    maps = list(eng.run(toolpath, STOCK))
    removed = sum(m.removed_volume for m in maps)
    assert removed > 100 and eng.removed_total == removed
    material = eng.material_volume()
    assert abs(eng.stock_volume - material - removed) <= VOLUME_REL * (material + removed)

    # the window: the 3D line and the helix, from the first CL that goes below the arc's height
    cls = list(eng.cl_sequence(toolpath))
    first = next(c.index for c in cls if c.move.end[2] < -1.5 - 1e-9)
    last = next(c.index for c in cls if c.move.end == (-8.333, 3.333, -6.2))
    window = maps[first:last + 1]
    assert sum(m.removed_volume > 0 for m in window) >= 3
    m0, m1 = window_material(toolpath, STOCK, options, first, last + 1)
    taken = sum(m.removed_volume for m in window)
    assert abs(m0 - m1 - taken) <= VOLUME_REL * (m0 + m1 + taken)
