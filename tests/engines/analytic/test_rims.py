"""A footprint's rim, where a round tool's sweep rises like the square root of the distance to its edge:
which tools have one, which boundary curves are rims, and why the inner integral's node map bends only
there."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fusioncut.engines.analytic.breaks import boundary_curves
from fusioncut.engines.analytic.profile import corner_radii, lower_profile, rim_radius
from fusioncut.engines.analytic.sweeps import arc_row, line_row
from fusioncut.engines.analytic.volume import _ends_map, _node
from fusioncut.model.tools import BallEndMill, BullNoseEndMill, ChamferMill, Drill, FlatEndMill, TaperedEndMill


@pytest.mark.parametrize("tool, rim", [(BallEndMill(6, 20), 3.0), (BullNoseEndMill(10, 20, corner_radius=2), 5.0),
                                       (FlatEndMill(10, 20), None), (TaperedEndMill(4, 20, taper_angle=10), None),
                                       (ChamferMill(10, 20, taper_angle=45), None), (Drill(6, 20), None)])
def test_only_a_profile_ending_in_a_vertical_arc_has_a_rim(tool, rim):
    r = rim_radius(lower_profile(tool).pieces)
    assert (math.isnan(r) if rim is None else r == pytest.approx(rim, abs=1e-12))


def test_the_rim_curves_are_the_footprints_edges_at_the_rim_radius():
    """A bull-nose's (R 5, corner 2) line and arc: the curves at R (a line's end circles and sides, an arc's
    circles about its centre and about its ends) are rims; its tangential joint at 3 (were it a break radius)
    and an arc's end radii, where the end tool's disc meets the swept ring, are not; a flat end mill has none."""
    bull = lower_profile(BullNoseEndMill(10, 20, corner_radius=2))
    rows = np.array([line_row((0, 0, 0), (10, 0, -1), 0), arc_row((10, 0, 0), (0, 10, 0), (0, 0), 10.0, 0.0,
                                                                   math.pi / 2, 0)])
    rim = rim_radius(bull.pieces)
    circles, segments = boundary_curves(rows, [(3.0, *corner_radii(bull.pieces))] * 2, [rim, rim])
    assert circles.shape[1] == 5 and segments.shape[1] == 6
    assert np.all((circles[:, 4] == 1) == (circles[:, 2] == 5.0) | (circles[:, 2] == 15.0))  # an arc's rho +- R
    assert np.all(circles[circles[:, 2] == 3.0, 4] == 0)
    line_sides, arc_ends = segments[segments[:, 4] == 0], segments[segments[:, 4] == 1]
    assert list(line_sides[:, 5]) == [0, 0, 1, 1] and np.all(arc_ends[:, 5] == 0)
    flat = lower_profile(FlatEndMill(10, 20))
    circles, segments = boundary_curves(rows[:1], [corner_radii(flat.pieces)], [rim_radius(flat.pieces)])
    assert not circles[:, 4].any() and not segments[:, 5].any()


def _gk(f, a, b, ra, rb):
    """(the 15-point Kronrod sum of ``f`` over [a, b] under :func:`.volume._ends_map`, QUADPACK's raw error
    estimate |Kronrod - Gauss|, which decides whether the adaptive rule splits the part)."""
    k = g = 0.0
    for i in range(15):
        u, wk, wg = _node(i)
        y, w = _ends_map.py_func(a, b, u, ra, rb)
        k += wk * w * f(y)
        g += wg * w * f(y)
    return k, abs(k - g)


def test_the_node_map_bends_where_a_square_root_starts_or_lies_just_beyond():
    """A square root starting at an end (a rim) is integrated to round-off by one rule when that end is
    flagged, and far worse under the linear map. One starting 0.04 mm past an end (a kink where the removed
    height begins, the CL's rim just beyond it) is estimated best with only that end flagged: a zero slope at
    the other end (a halving point's, where nothing is singular) spends nodes there and the estimate grows."""
    a, b = 0.3, 0.58
    exact = 2 / 3 * (b - a) ** 1.5
    at_a = lambda y: math.sqrt(y - a)  # noqa: E731
    for rb in (False, True):
        assert abs(_gk(at_a, a, b, True, rb)[0] - exact) < 1e-13 * exact
    assert abs(_gk(at_a, a, b, False, False)[0] - exact) > 1e-5 * exact
    beyond = lambda y: math.sqrt(b + 0.04 - y)  # noqa: E731
    exact = 2 / 3 * ((b + 0.04 - a) ** 1.5 - 0.04 ** 1.5)
    one, linear, both = _gk(beyond, a, b, False, True), _gk(beyond, a, b, False, False), _gk(beyond, a, b, True, True)
    assert abs(one[0] - exact) < 1e-12 * exact
    assert one[1] < 0.5 * linear[1] and one[1] < 0.1 * both[1]
    for ra in (False, True):
        for rb in (False, True):  # every map covers [a, b]: its weights add up to the length
            assert _gk(lambda y: 1.0, a, b, ra, rb)[0] == pytest.approx(b - a, rel=1e-14)
