"""Contact patches given in closed form (the layered cells' engaged arcs)."""
from __future__ import annotations

import math

import pytest

from fusioncut.engines.brep.contact import arc_contacts, slice_intervals
from fusioncut.model import FlatEndMill


def test_an_arc_over_flute_and_shank_is_split_by_zone_with_exact_areas():
    tool = FlatEndMill(10.0, 20.0, overall_length=50.0)  # shank of the flute's diameter above 20 mm
    tip = (3.0, -2.0, -15.0)
    contacts = arc_contacts([(5.5, 1.25, -12.0, 10.0)], tool, tip)  # machine heights: 3 to 25 mm above the tip
    assert [(c.surface.zone, c.z_range) for c in contacts] == [("flute", (3.0, 20.0)), ("shank", (20.0, 25.0))]
    assert [c.area for c in contacts] == pytest.approx([5.0 * 1.25 * 17.0, 5.0 * 1.25 * 5.0], rel=1e-12)
    flute = [c for c in contacts if c.surface.zone == "flute"]
    assert slice_intervals(flute, tip, 10.0) == [pytest.approx((5.5, 1.25))]
    assert slice_intervals(flute, tip, 3.0) == []  # half-open: the patch below a height holds it
    assert slice_intervals(flute, tip, 20.0) == [pytest.approx((5.5, 1.25))]


def test_arcs_of_stacked_layers_merge_and_wrap_round_zero():
    tool = FlatEndMill(8.0, 25.0)
    tip = (0.0, 0.0, -6.0)
    # one arc across +X (start 350 degrees, 20 degrees long) on the lower layer, and its
    # continuation on the upper one; at a height in both layers' ranges only the holder counts
    contacts = arc_contacts([(math.radians(350.0), math.radians(20.0), -6.0, -3.0),
                             (math.radians(10.0), math.radians(30.0), -6.0, -3.0),
                             (math.radians(100.0), math.radians(10.0), -3.0, 0.0)], tool, tip)
    (start, span), = slice_intervals(contacts, tip, 2.0)
    assert math.degrees(start) == pytest.approx(350.0) and math.degrees(span) == pytest.approx(50.0)
    assert [math.degrees(a) for arc in slice_intervals(contacts, tip, 4.0) for a in arc] == pytest.approx([100.0, 10.0])
