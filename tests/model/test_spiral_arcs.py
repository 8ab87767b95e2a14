"""Spirals (arcs whose end radius differs from the start's) swept as arcs of true circles."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusioncut.errors import InputError
from fusioncut.model import ArcMove
from fusioncut.model.moves import ArcPlane


def spiral(rho0, rho1, a0, sweep, plane=ArcPlane.XY, rise=0.0):
    a, b, n = plane.axes
    p0, p1, c = [0.0] * 3, [0.0] * 3, [1.0, -2.0, 0.5]
    p0[a], p0[b], p0[n] = c[a] + rho0 * math.cos(a0), c[b] + rho0 * math.sin(a0), c[n]
    p1[a], p1[b], p1[n] = c[a] + rho1 * math.cos(a0 + sweep), c[b] + rho1 * math.sin(a0 + sweep), c[n] + rise
    return ArcMove(tuple(p0), tuple(p1), feed=100.0, center=tuple(c), plane=plane, clockwise=sweep < 0)


@settings(max_examples=80, deadline=None)
@given(rho0=st.floats(0.5, 50), dr=st.floats(-0.05, 0.05).filter(lambda d: abs(d) > 1e-7),
       a0=st.floats(-math.pi, math.pi), sweep=st.floats(0.05, 6.2), cw=st.booleans(),
       plane=st.sampled_from(list(ArcPlane)), rise=st.sampled_from([0.0, -1.5]), tol=st.sampled_from([1e-3, 1e-4]))
def test_pieces_are_circles_about_the_centre_within_the_tolerance_of_the_spiral(rho0, dr, a0, sweep, cw, plane,
                                                                                 rise, tol):
    arc = spiral(rho0, rho0 + dr, a0, -sweep if cw else sweep, plane, rise)
    assert arc.is_spiral
    pieces = arc.circular_pieces(tol)
    a, b, n = plane.axes
    assert len(pieces) >= abs(dr) / tol and len(pieces) == arc.circular_piece_count(tol)
    assert pieces[0].start == arc.start
    assert math.dist(pieces[-1].end, arc.end) <= tol + 1e-12
    assert pieces[-1].end[n] == arc.end[n]
    for k, p in enumerate(pieces):
        assert p.center[a] == arc.center[a] and p.center[b] == arc.center[b]
        assert p.radius == pytest.approx(p.end_radius, rel=1e-12)  # a true circle
        assert p.clockwise == arc.clockwise and abs(p.sweep) <= math.pi + 1e-9
        # it ends within the tolerance of the spiral's point, and starts on the spiral
        assert math.dist(p.end, arc.point_at((k + 1) / len(pieces))) <= tol + 1e-12
        assert math.dist(p.start, arc.point_at(k / len(pieces))) <= 1e-9
    assert sum(p.sweep for p in pieces) == pytest.approx(arc.sweep, abs=1e-9)


def test_posted_arc_a_fraction_of_a_um_off_is_one_arc_about_its_centre():
    """A Fusion contour's G2 (1055_utab, line 6232): I/J and end rounded to 3 decimals, the end 0.26 µm
    inside the start's circle. One arc about the programmed centre (so the corner arc before it stays
    tangent), ending on the start's circle 0.26 µm from the programmed end."""
    arc = ArcMove((21.525, 40.356, -3.075), (16.794, 37.044, -3.075), center=(18.0, 40.356, -3.075), clockwise=True)
    assert arc.is_spiral and 2e-4 < arc.radius - arc.end_radius < 3e-4
    (piece,) = arc.circular_pieces(1e-3)
    assert piece.center == arc.center and piece.start == arc.start
    assert piece.end_radius == pytest.approx(arc.radius, abs=1e-12)
    assert math.dist(piece.end, arc.end) == pytest.approx(arc.radius - arc.end_radius, abs=1e-12)


def test_a_circle_is_left_as_it_is():
    arc = spiral(5.0, 5.0, 0.3, 2.0)
    assert arc.circular_pieces(1e-3) == [arc]


def test_a_spiral_too_wide_for_the_tolerance_is_refused_naming_its_line():
    from fusioncut.errors import SourceLocation
    arc = ArcMove((0.0, 0.0, 0.0), (0.0, 2000.0, 0.0), center=(0.0, 1.0, 0.0), clockwise=True,
                  source=SourceLocation("spiral.nc", 7))
    with pytest.raises(InputError, match="spiral.nc:7"):
        arc.circular_pieces(1e-3)
