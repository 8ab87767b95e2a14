"""The minimum chip thickness's arithmetic (fusioncut.engines.chip), against hand-computed values."""
from __future__ import annotations

import math

import pytest

from fusioncut.engines.chip import band_volumes, cutting_range, horizontal_travel, rubbing_bands
from fusioncut.model import ArcMove, LinearMove


def test_horizontal_travel_of_lines_arcs_and_plunges():
    assert horizontal_travel(LinearMove((0, 0, -1), (3, 4, -2), feed=100.0)) == pytest.approx(5.0)
    assert horizontal_travel(LinearMove((1, 1, 0), (1, 1, -5), feed=100.0)) == 0.0
    quarter = ArcMove((10, 0, -1), (0, 10, -1), feed=100.0, center=(0, 0, -1))
    assert horizontal_travel(quarter) == pytest.approx(0.5 * math.pi * 10, rel=1e-12)
    helix = ArcMove((10, 0, -1), (0, 10, -2), feed=100.0, center=(0, 0, -1))
    assert horizontal_travel(helix) == pytest.approx(0.5 * math.pi * 10, rel=1e-12)


def test_band_volumes_split_each_prism_at_the_band_heights():
    # tip at z = -6; a prism of 2 mm² from -6 to -4.5 and one of 0.01 mm² from -4.5 to -2.7
    v = band_volumes([(-6.0, -4.5, 2.0), (-4.5, -2.7, 0.01)], -6.0, 1.0, 3.3)
    assert v == pytest.approx((2.0, 0.5 * 2.0 + 0.5 * 0.01, 0.01, 0.3 * 0.01))
    assert band_volumes([(-6.0 - 1e-7, -5.0, 1.0)], -6.0, 1.0, 1.0) == pytest.approx((1.0 + 1e-7,))


def test_bands_rub_below_the_minimum_width_only_where_it_is_known():
    vols = (200.0, 200.0, 0.01, 0.015)  # 20 mm of travel: 10 mm wide, then 0.5 and 0.75 µm
    assert rubbing_bands(vols, (0.0, 4.0), 1.0, 20.0, 1e-3) == {2, 3}
    # in contact over half of band 3: its volume lies in that half, 1.5 µm wide
    assert rubbing_bands(vols, (0.0, 3.5), 1.0, 20.0, 1e-3) == {2}
    assert rubbing_bands(vols, (0.0, 4.0), 1.0, 20.0, 0.0) == set()  # 0: off
    assert rubbing_bands(None, (0.0, 4.0), 1.0, 20.0, 1e-3) == set()  # unknown volumes
    assert rubbing_bands(vols, (0.0, 4.0), 1.0, 0.0, 1e-3) == set()  # a plunge
    assert rubbing_bands(vols, (0.0, 4.0), 1.0, None, 1e-3) == set()
    assert rubbing_bands((200.0,), (0.0, 2.0), 1.0, 20.0, 1e-3) == {1}  # nothing removed in band 1


def test_the_cutting_range_is_the_contact_within_the_bands_that_cut():
    assert cutting_range((0.2, 6.0), [0, 1, 2], 1.0) == (0.2, 3.0)
    assert cutting_range((0.2, 2.5), [2], 1.0) == (2.0, 2.5)
    assert cutting_range((0.0, 6.0), [], 1.0) == (0.0, 0.0)
