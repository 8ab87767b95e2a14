"""Closed-form planar Booleans: against closed-form areas, and against OCCT's General Fuse on random
sequences of a flat end mill's cuts (what the layered cells do at every CL)."""
from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusioncut.engines.brep import planar
from fusioncut.engines.brep.layers import _cut_region, outline, outline_faces
from fusioncut.engines.brep.occ import area
from fusioncut.engines.brep.sweep import cylinder_region
from fusioncut.model import ArcMove, LinearMove
from fusioncut.model.moves import ArcPlane

Line, arc = planar.Line, planar.arc


def rectangle(x0, y0, x1, y1):
    return ((Line(x0, y0, x1, y0), Line(x1, y0, x1, y1), Line(x1, y1, x0, y1), Line(x0, y1, x0, y0)),)


def disk(cx, cy, r):
    return ((arc(cx, cy, r, 0.0, 2 * math.pi),),)


def segment_area(r, d):
    """Area of the part of a disk of radius r beyond a chord d from its centre."""
    return r * r * math.acos(d / r) - d * math.sqrt(r * r - d * d)


def test_a_hole_inside():
    d = planar.difference(rectangle(0, 0, 10, 10), disk(4, 5, 2))
    assert d.area == pytest.approx(100 - 4 * math.pi, rel=1e-14)
    assert d.lost == pytest.approx(4 * math.pi, rel=1e-14)
    assert sorted(round(planar.region_area((loop,)), 9) for loop in d.region) == [round(-4 * math.pi, 9), 100]
    (kept,) = d.b_pieces
    assert abs(kept.a1 - kept.a0) == pytest.approx(2 * math.pi)


def test_a_bite_from_the_side_and_the_tool_arc_it_leaves():
    # a disk of radius 3 whose centre lies 1 mm outside the wall x = 10
    d = planar.difference(rectangle(0, 0, 10, 10), disk(11, 5, 3))
    assert d.lost == pytest.approx(segment_area(3, 1), rel=1e-12)
    assert d.area == pytest.approx(100 - segment_area(3, 1), rel=1e-12)
    (kept,) = d.b_pieces  # the arc inside the square: 2 acos(1/3) of the circle, around -X
    assert abs(kept.a1 - kept.a0) == pytest.approx(2 * math.acos(1 / 3), rel=1e-12)
    mid = 0.5 * (kept.a0 + kept.a1)
    assert math.cos(mid) == pytest.approx(-1.0)


def test_shared_walls_in_either_direction():
    # the left half taken: the cut shares three walls' stretches, running with the square's
    d = planar.difference(rectangle(0, 0, 10, 10), rectangle(0, 0, 5, 10))
    assert (d.area, d.lost) == (pytest.approx(50.0, rel=1e-14), pytest.approx(50.0, rel=1e-14))
    assert len(d.region) == 1
    # a rectangle beside the square touches it along a wall, against its direction: nothing lost
    d = planar.difference(rectangle(0, 0, 10, 10), rectangle(10, 2, 15, 8))
    assert d.lost == pytest.approx(0.0, abs=1e-12) and d.area == pytest.approx(100.0, rel=1e-14)
    assert d.b_pieces == ()


def test_a_disk_tangent_to_the_wall_inside():
    # the hole touches the wall at one point: one loop pinched there, or a loop and a hole
    d = planar.difference(rectangle(0, 0, 10, 10), disk(2, 5, 2))
    assert d.area == pytest.approx(100 - 4 * math.pi, rel=1e-12)
    assert sum(planar.region_area((loop,)) for loop in d.region) == pytest.approx(d.area, rel=1e-14)


def test_the_whole_region_lost():
    d = planar.difference(rectangle(2, 2, 4, 4), disk(3, 3, 5))
    assert d.region == () and d.area == pytest.approx(0.0, abs=1e-12) and d.lost == pytest.approx(4.0, rel=1e-12)


def test_the_winding_number_counts_a_ray_through_vertices_once():
    square = [e for loop in rectangle(0, 0, 10, 10) for e in loop]
    assert planar.winding(square, 5, 0) == 1  # on the bottom wall's height: half-open
    assert planar.winding(square, 5, 5) == 1 and planar.winding(square, -1, 10) == 0
    round_ = [e for loop in disk(0, 0, 1) for e in loop]
    assert planar.winding(round_, 0, 0) == 1 and planar.winding(round_, 0.03, 0.999) == 1
    assert planar.winding(round_, -2, 1.0) == 0 and planar.winding(round_, -2, -1.0) == 0  # tangent rays


def test_an_ambiguous_piece_is_left_to_the_kernel():
    # the cut's top edge runs 5e-9 mm below the square's top wall, neither on it nor clearly off
    with pytest.raises(planar.Degenerate):
        planar.difference(rectangle(0, 0, 10, 10), rectangle(2, 2, 8, 10 - 5e-9))
    # 1e-6 mm below it is clear
    d = planar.difference(rectangle(0, 0, 10, 10), rectangle(2, 2, 8, 10 - 1e-6))
    assert d.lost == pytest.approx(6 * (8 - 1e-6), rel=1e-12)


def test_outlines_and_faces_go_both_ways():
    face = cylinder_region(3.0, LinearMove((5.0, 5.0, 0.0), (15.0, 9.0, 0.0)))
    loops = outline(face)
    assert planar.region_area(loops) == pytest.approx(area(face), rel=1e-12)
    d = planar.difference(rectangle(0, 0, 20, 12), loops)
    back = outline_faces(d.region)
    assert area(back) == pytest.approx(d.area, rel=1e-12)
    again = outline(back)
    assert planar.region_area(again) == pytest.approx(d.area, rel=1e-12)


# positions on a 1/8 mm grid and angles on a π/64 one: exact tangencies and shared walls come up
# often (a tool of radius 2 at x = 2 runs along the wall x = 0), near ones (1e-7 mm apart, where
# both kernels snap and may differ by that much times a length, and where OCCT's own faces from
# three-point arcs are off their vertices by that much) do not
grid = st.integers(-40, 360).map(lambda k: k / 8)


def pi_64ths(lo, hi):
    """Angles k·π/64 (rad) for k from lo to hi."""
    return st.integers(lo, hi).map(lambda k: k * math.pi / 64)


moves = st.one_of(
    st.tuples(grid, grid.map(lambda v: v * 0.75), grid, grid.map(lambda v: v * 0.75)).map(
        lambda t: LinearMove((t[0], t[1], 0.0), (t[2], t[3], 0.0))),
    st.tuples(st.integers(40, 280), st.integers(40, 200), st.integers(16, 64), pi_64ths(-64, 64),
              pi_64ths(4, 64), st.booleans()).map(
        lambda t: ArcMove((t[0] / 8 + t[2] / 8 * math.cos(t[3]), t[1] / 8 + t[2] / 8 * math.sin(t[3]), 0.0),
                          (t[0] / 8 + t[2] / 8 * math.cos(t[3] + (-t[4] if t[5] else t[4])),
                           t[1] / 8 + t[2] / 8 * math.sin(t[3] + (-t[4] if t[5] else t[4])), 0.0),
                          center=(t[0] / 8, t[1] / 8, 0.0), clockwise=t[5], plane=ArcPlane.XY)),
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(moves, st.sampled_from([2.0, 3.0, 5.0]), st.booleans()), min_size=1, max_size=6))
def test_random_cuts_agree_with_the_general_fuse(cuts):
    """Each cut of a running region equals OCCT's General Fuse of the same faces (areas 1e-9
    relative + 1e-9 mm²); where it cannot decide it says so, and the kernel's result goes on."""
    region = outline(outline_faces(rectangle(0, 0, 40, 30)))
    face = outline_faces(region)
    for move, r, open_start in cuts:
        tool_face = cylinder_region(r, move, open_start)
        if tool_face is None:
            continue
        new_face, new_area, _ = _cut_region(face, tool_face, area(face), (0.0, 1e-6, 1e-5))
        expected = area(face) if new_face is None else new_area
        try:
            d = planar.difference(region, outline(tool_face))
        except planar.Degenerate:
            d = None
        if d is not None:
            assert d.area == pytest.approx(expected, rel=1e-9, abs=1e-9)
            assert d.lost == pytest.approx(area(face) - expected, rel=1e-9, abs=1e-9)
            if d.region:
                assert area(outline_faces(d.region)) == pytest.approx(d.area, rel=1e-9, abs=1e-9)
        if new_face is None:
            continue
        face = new_face
        region = outline(face)
        assert region is not None


@settings(max_examples=60, deadline=None)
@given(moves, st.sampled_from([2.0, 3.0, 5.0]), st.booleans())
def test_the_cutting_region_built_without_the_kernel_is_the_kernels(move, r, open_start):
    from fusioncut.engines.brep.sweep import cylinder_region_outline

    face = cylinder_region(r, move, open_start)
    direct = cylinder_region_outline(r, move, open_start)
    if face is None:
        assert direct is None
        return
    read = outline(face)
    assert planar.region_area(direct) == pytest.approx(area(face), rel=1e-12)
    assert len(direct) == len(read) == 1 and len(direct[0]) == len(read[0])
    # the same edges, from the same start where the loop is read from one
    ends = {(round(e.x0, 9), round(e.y0, 9), type(e).__name__) for e in read[0]}
    assert {(round(e.x0, 9), round(e.y0, 9), type(e).__name__) for e in direct[0]} == ends
