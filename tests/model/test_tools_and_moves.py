from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fusioncut.errors import ToolDefinitionError
from fusioncut.model import (AptCutter, AptParameters, ArcMove, ArcPlane, BallEndMill, BullNoseEndMill, FlatEndMill,
                             LinearMove, SpindleDirection)
from fusioncut.model.angles import immersion_from_machine, machine_from_immersion


def test_families_are_apt_special_cases():
    bull = BullNoseEndMill(12, 30, corner_radius=2)
    apt = AptCutter(12, 30, apt_parameters=AptParameters(12, 2, 4, 2, 0, 0, 30))
    assert bull.profile().segments[:3] == apt.profile().segments[:3]
    ball = BallEndMill(10, 20)
    assert ball.profile().radius_at(2.0) == pytest.approx(math.sqrt(25 - 9))


@pytest.mark.parametrize("make", [
    lambda: FlatEndMill(-1, 10),
    lambda: FlatEndMill(10, 0),
    lambda: BallEndMill(10, 3),
    lambda: BullNoseEndMill(10, 20, corner_radius=5),
    lambda: AptCutter(10, 20, apt_parameters=AptParameters(11, 2, 3, 2, 0, 0, 20)),
])
def test_impossible_tools_are_refused_with_our_error(make):
    with pytest.raises(ToolDefinitionError):
        make()


def test_arc_sweep_signs_and_full_circles():
    ccw = ArcMove((1, 0, 0), (0, 1, 0), center=(0, 0, 0))
    cw = ArcMove((1, 0, 0), (0, 1, 0), center=(0, 0, 0), clockwise=True)
    assert ccw.sweep == pytest.approx(math.pi / 2)
    assert cw.sweep == pytest.approx(-3 * math.pi / 2)
    full = ArcMove((1, 0, 0), (1, 0, 0), center=(0, 0, 0), turns=1)
    assert full.sweep == pytest.approx(4 * math.pi)
    # G18: a positive (counter-clockwise seen from +Y) rotation takes +Z to +X
    zx = ArcMove((0, 0, 1), (1, 0, 0), center=(0, 0, 0), plane=ArcPlane.ZX)
    assert zx.point_at(0.5) == pytest.approx((math.sqrt(0.5), 0, math.sqrt(0.5)))
    zx_cw = ArcMove((0, 0, 1), (1, 0, 0), center=(0, 0, 0), plane=ArcPlane.ZX, clockwise=True)
    assert zx_cw.sweep == pytest.approx(-1.5 * math.pi)


def test_split_keeps_the_path():
    m = LinearMove((0, 0, 0), (10, 0, -1))
    parts = m.split(3.0)
    assert len(parts) == 4 and parts[0].start == m.start and parts[-1].end == m.end
    assert sum(p.length for p in parts) == pytest.approx(m.length)


@given(st.floats(0, 360, exclude_max=True), st.floats(0, 360, exclude_max=True), st.sampled_from(list(SpindleDirection)))
def test_angle_conventions_round_trip(theta, feed, spindle):
    phi = immersion_from_machine(theta, feed, spindle)
    assert 0 <= phi < 360
    back = machine_from_immersion(phi, feed, spindle)
    assert math.isclose(math.remainder(back - theta, 360), 0, abs_tol=1e-9)


def test_immersion_convention_cardinal_points():
    # feed +x, CW spindle: +y is 0, ahead (+x) is 90, -y is 180
    assert immersion_from_machine(90, 0, SpindleDirection.CW) == 0
    assert immersion_from_machine(0, 0, SpindleDirection.CW) == 90
    assert immersion_from_machine(270, 0, SpindleDirection.CW) == 180
    # CCW spindle mirrors: -y is 0
    assert immersion_from_machine(270, 0, SpindleDirection.CCW) == 0
    assert immersion_from_machine(0, 0, SpindleDirection.CCW) == 90
