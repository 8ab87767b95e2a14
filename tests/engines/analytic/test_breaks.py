"""The removed volume's break points: which curves part the integral, and which need not."""
from __future__ import annotations

import numpy as np
import pytest

from fusioncut.engines.analytic.breaks import boundary_curves, crossings_at_x, nothing_removed_near, x_breaks
from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.analytic.sweeps import line_row
from fusioncut.model import FlatEndMill

FLAT = lower_profile(FlatEndMill(6, 20))  # R = 3
PP, NPC, RR = FLAT.pieces[None], np.array([len(FLAT.pieces)]), np.array([FLAT.radius])


def _box(row, R=3.0):
    return [min(row[1], row[4]) - R, min(row[2], row[5]) - R, max(row[1], row[4]) + R, max(row[2], row[5]) + R]


def _case(own, *earlier):
    C = np.array(earlier).reshape(-1, 13)
    CB = np.array([_box(r) for r in C]).reshape(-1, 4)
    rows = np.vstack([own[None, :], C])
    circles, segments = boundary_curves(rows, [(FLAT.radius,)] * len(rows))
    return C, CB, circles, segments


def test_a_point_isnothing_removed_near_only_outside_the_cl_or_inside_a_deeper_sweep():
    """A CL 2 mm deep along x, a pass 5 mm deep along y across it (row 0) and one 1 mm deep beside
    it (row 1): nothing is removed near a point of the deep pass's footprint, whatever row 1 does,
    nor outside the CL's footprint; beside the deep pass the CL removes material."""
    own = line_row((-20, 0, -2), (20, 0, -2), 0)
    C, CB, _, _ = _case(own, line_row((0, -20, -5), (0, 20, -5), 0), line_row((10, -20, -1), (10, 20, -1), 0))
    args = (own, FLAT.pieces, FLAT.radius, C, CB, PP, NPC, RR, -10.0)
    assert nothing_removed_near(1, 1, 1.0, 1.0, *args)  # inside the deep pass
    assert not nothing_removed_near(0, 0, 1.0, 1.0, *args)  # the deep pass itself is the one let be
    assert not nothing_removed_near(1, 1, 3.0, 1.0, *args)  # on its wall: not strictly inside
    assert nothing_removed_near(1, 1, 5.0, 3.5, *args)  # outside the CL's footprint
    assert not nothing_removed_near(1, 1, 5.0, 1.0, *args)  # in the CL, beside the deep pass


def test_the_edge_of_a_pass_under_a_lower_one_is_no_break_point():
    """A raster: the CL 2 mm deep along y = 0, the last pass 1.5 mm deep along y = -2, the one before
    1 mm deep along y = -4. The older pass's edge (y = -1) runs inside the last pass, whose surface is
    below the older one's there: it gives the material's top nowhere near, and its edge parts
    nothing, though the CL removes material there. The last pass's own edge (y = 1) parts the line."""
    own = line_row((-20, 0, -2), (20, 0, -2), 0)
    older, last = line_row((-20, -4, -1), (20, -4, -1), 0), line_row((-20, -2, -1.5), (20, -2, -1.5), 0)
    C, CB, circles, segments = _case(own, older, last)
    args = (own, FLAT.pieces, FLAT.radius, C, CB, PP, NPC, RR, -10.0)
    assert nothing_removed_near(0, 0, 0.0, -1.0, *args)  # the older pass's edge, under the last pass
    assert not nothing_removed_near(1, 1, 0.0, 1.0, *args)  # the last pass's edge: it gives the top there
    pts, owners, _ = crossings_at_x(0.0, circles, segments, -10.0, 10.0, *args)
    assert pts.tolist() == [-10.0, -3.0, 1.0, 3.0, 10.0] and owners.tolist() == [-1.0, 0.0, 2.0, 0.0, -1.0]


def test_crossings_inside_a_deeper_sweep_are_no_break_points():
    """A 1 mm deep pass along the CL's path (its footprint's edges at y = +-3, as the CL's), and a
    5 mm deep pass along y: along x = 1, inside the deep pass, nothing is removed around the shallow
    pass's edges and they part nothing; the CL's own do. Beside the deep pass, at x = 5, they count."""
    own = line_row((-20, 0, -2), (20, 0, -2), 0)
    shallow = line_row((-20, 0, -1), (20, 0, -1), 0)
    deep = line_row((0, -20, -5), (0, 20, -5), 0)
    C, CB, circles, segments = _case(own, deep, shallow)
    pts, owners, _ = crossings_at_x(1.0, circles, segments, -10.0, 10.0, own, FLAT.pieces, FLAT.radius, C, CB, PP,
                                  NPC, RR, -10.0)
    assert pts.tolist() == [-10.0, -3.0, 3.0, 10.0] and owners.tolist() == [-1.0, 0.0, 0.0, -1.0]
    pts, owners, _ = crossings_at_x(5.0, circles, segments, -10.0, 10.0, own, FLAT.pieces, FLAT.radius, C, CB, PP,
                                  NPC, RR, -10.0)
    assert owners.tolist().count(2.0) == 2  # beside the deep pass the shallow one's edges count


def test_x_breaks_keep_what_meets_the_cell_and_a_wall_along_y_through_it():
    """A pass along y (its footprint's sides are segments x = const) through a cell it crosses with
    both its ends outside the cell: its sides' x are break points (no line x = const crosses them);
    ends, extremes and centres outside the cell are not."""
    own = line_row((-20, 0, -2), (20, 0, -2), 0)
    C, CB, circles, segments = _case(own, line_row((4, -30, -1), (4, -10, -1), 0))
    xs = x_breaks(circles, segments, -2.0, 10.0, -2.0, 2.0, own, FLAT.pieces, FLAT.radius, C, CB, PP, NPC, RR, -10.0)
    assert xs.tolist() == [-2.0, 10.0]  # the pass ends at y = -10 - 3: it misses the cell
    C, CB, circles, segments = _case(own, line_row((4, -30, -1), (4, 30, -1), 0))
    xs = x_breaks(circles, segments, -2.0, 10.0, -2.0, 2.0, own, FLAT.pieces, FLAT.radius, C, CB, PP, NPC, RR, -10.0)
    assert xs.tolist() == [-2.0, 1.0, 7.0, 10.0]


def test_a_sweeps_curves_are_at_its_radius_its_corners_and_where_a_level_sweep_crosses_the_stocks_faces():
    """:func:`sweep_curves` in a stock from z = -10 to 0: a flat end mill (R 3) has curves at R only; a
    ball end mill (R 2) moved level 1 mm deep also where its surface crosses the stock's top, at
    sqrt(R² - (R - 1)²) = sqrt(3) (no rim; R is its rim), and moved down a ramp at R only; a chamfer mill
    (tip radius 1 under a 45° cone to R 4) 1 mm deep at its tip's corner, R and 2 (the top). Each row's curves come in
    :func:`boundary_curves`' order, owned by the row's index."""
    import math

    from fusioncut.engines.analytic.breaks import sweep_curves
    from fusioncut.engines.analytic.sweeps import arc_row
    from fusioncut.model import BallEndMill, ChamferMill

    profiles = [FLAT, lower_profile(BallEndMill(4, 20)), lower_profile(ChamferMill(8, 20, taper_angle=45,
                                                                                  tip_diameter=2))]
    P = np.zeros((3, max(p.pieces.shape[0] for p in profiles), 6))
    for i, p in enumerate(profiles):
        P[i, :p.pieces.shape[0]] = p.pieces
    NP = np.array([p.pieces.shape[0] for p in profiles])
    rows = np.array([line_row((0, 0, -1), (5, 0, -1), 0), line_row((0, 0, -1), (5, 0, -1), 1),
                     line_row((0, 0, -1), (5, 0, -3), 1), arc_row((3, 0, -1), (0, 3, -1), (0, 0), 3.0, 0.0,
                                                                  math.pi / 2, 1),
                     line_row((0, 0, -1), (0, 5, -1), 2)])
    want_radii = [(3.0,), (2.0, math.sqrt(3.0)), (2.0,), (2.0, math.sqrt(3.0)), (1.0, 4.0, 2.0)]
    want_rims = [math.nan, 2.0, 2.0, 2.0, math.nan]
    circles, segments = sweep_curves(rows, P, NP, -10.0, 0.0)
    want = boundary_curves(rows, want_radii, want_rims)
    assert np.allclose(circles, want[0], rtol=0, atol=1e-12) and np.allclose(segments, want[1], rtol=0, atol=1e-12)
    assert sorted(set(circles[circles[:, 3] == 1, 2].round(12))) == [round(math.sqrt(3.0), 12), 2.0]
    assert set(circles[circles[:, 4] == 1, 3]) == {1, 2, 3}  # the ball's rims; the flat and chamfer mills have none
    for k in range(len(rows)):  # each row's curves in boundary_curves' order
        alone = sweep_curves(rows[k:k + 1], P, NP, -10.0, 0.0)
        assert np.array_equal(alone[0][:, [0, 1, 2, 4]], circles[circles[:, 3] == k][:, [0, 1, 2, 4]])
        assert np.array_equal(alone[1][:, [0, 1, 2, 3, 5]], segments[segments[:, 4] == k][:, [0, 1, 2, 3, 5]])


def test_a_ramps_edge_above_a_lower_pass_is_no_break_point():
    """The CL 3 mm deep along y = 0; a ramp along y = -4 from 0.5 down to 3.5 mm deep (its closed-form
    floor, the lowest tip, 3.5 deep); the last pass 2.5 mm deep along y = -2. Where the ramp's edge
    (y = -1) runs inside the last pass and the ramp's own surface there is above the last pass's (x < 10),
    the ramp gives the material's top nowhere near and its edge parts nothing, though its floor lies below
    the last pass; where the ramp has gone below the last pass (x = 15), its edge parts the line. Dropping
    those break points moves no volume: the adaptive integral over x break points with them added agrees."""
    from fusioncut.engines.analytic.volume import removed_volume

    own = line_row((-20, 0, -3), (20, 0, -3), 0)
    ramp, last = line_row((-20, -4, -0.5), (20, -4, -3.5), 0), line_row((-20, -2, -2.5), (20, -2, -2.5), 0)
    C, CB, circles, segments = _case(own, ramp, last)
    args = (own, FLAT.pieces, FLAT.radius, C, CB, PP, NPC, RR, -10.0)
    assert nothing_removed_near(0, 0, 0.0, -1.0, *args)  # the ramp at -2.0 there, the last pass at -2.5
    assert nothing_removed_near(0, 0, -10.0, -1.0, *args)
    assert not nothing_removed_near(0, 0, 15.0, -1.0, *args)  # the ramp at -3.125: it gives h there
    pts, owners, _ = crossings_at_x(0.0, circles, segments, -10.0, 10.0, *args)
    assert 1.0 not in owners.tolist()
    pts, owners, _ = crossings_at_x(15.0, circles, segments, -10.0, 10.0, *args)
    assert pts[owners == 1.0].tolist() == [-1.0]
    xs = x_breaks(circles, segments, -5.0, 16.0, -3.5, 3.5, *args)
    more = np.unique(np.concatenate([xs, np.linspace(-5.0, 16.0, 8)]))
    edges = np.zeros(0)
    v, _ = removed_volume(xs, -3.5, 3.5, circles, segments, *args[:-1], -10.0, 0.0, 1e-12, 1e-12, edges)
    w, _ = removed_volume(more, -3.5, 3.5, circles, segments, *args[:-1], -10.0, 0.0, 1e-12, 1e-12, edges)
    assert v > 10.0 and v == pytest.approx(w, rel=1e-10)


@pytest.mark.parametrize("shift, flagged", [(0.0, True), (0.5e-9, True), (1e-6, False), (-1e-6, False)])
def test_a_rim_running_on_a_cells_edge_flags_that_end(shift, flagged):
    """A ball end mill's level pass along x (R = 3): its footprint's sides y = +-3 are rims, where the lower
    surface rises as a square root. A line from y = -3 + shift to 3 - shift has them on its ends (shift 0, a
    cell cut from the footprint's box), or 0.5e-9 mm past them (shift 0.5e-9): the ends are flagged, so the inner
    rule's map is flat there. 1e-6 mm inside the line (shift -1e-6), the rims are break points of their own, flagged
    as such; 1e-6 mm past its ends they flag nothing."""
    from fusioncut.model import BallEndMill

    ball = lower_profile(BallEndMill(6, 20))
    own = line_row((-20, 0, -2), (20, 0, -2), 0)
    circles, segments = boundary_curves(own[None, :], [(ball.radius,)], [ball.radius])
    P1, N1, R1 = ball.pieces[None], np.array([len(ball.pieces)]), np.array([ball.radius])
    args = (own, ball.pieces, ball.radius, np.zeros((0, 13)), np.zeros((0, 4)), P1, N1, R1, -10.0)
    pts, owners, rims = crossings_at_x(0.0, circles, segments, -3.0 + shift, 3.0 - shift, *args)
    if shift < 0.0 and not flagged:
        assert pts.tolist() == [-3.0 + shift, -3.0, 3.0, 3.0 - shift] and rims.tolist() == [0.0, 1.0, 1.0, 0.0]
    else:
        assert pts.tolist() == [-3.0 + shift, 3.0 - shift]
        assert rims.tolist() == ([1.0, 1.0] if flagged else [0.0, 0.0])
