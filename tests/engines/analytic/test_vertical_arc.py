"""Arcs in the ZX and YZ planes (G18, G19: a contour's vertical lead-ins and lead-outs) swept exactly:
the lower surface against dense sampling, the CL segments against the B-Rep engine's chords, the removed
volume and the slices against closed forms, with coordinates as posts round them."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fusioncut.engines.analytic.engine import AnalyticEngine, _vertical_sweep_row
from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.analytic.sweeps import brute_lower, sweep_lower
from fusioncut.engines.analytic.vertical import is_vertical, vertical_positions
from fusioncut.engines.base import EngineOptions
from fusioncut.engines.cl_maps import cl_sequence
from fusioncut.engines.segments import as_chord, chords, cl_segments, quarter_pieces
from fusioncut.model import (ArcMove, ArcPlane, BallEndMill, BoxStock, BullNoseEndMill, CLStatus, FlatEndMill,
                             LinearMove, Toolpath)
from fusioncut.model.tools import TaperedEndMill

TOOLS = [FlatEndMill(6, 20), BallEndMill(6, 20), BullNoseEndMill(6, 20, corner_radius=1.0),
         TaperedEndMill(2, 10, taper_angle=10.0)]


def arc(plane: ArcPlane, centre, rho: float, phi0: float, sweep: float, decimals: int | None = None) -> ArcMove:
    """An arc of ``sweep`` rad from the in-plane angle ``phi0`` (RS274's: from the plane's first axis
    towards its second) about ``centre``, its numbers rounded to ``decimals`` as a post writes them."""
    a, b, n = plane.axes
    start, end = [0.0] * 3, [0.0] * 3
    for p, phi in ((start, phi0), (end, phi0 + sweep)):
        p[a], p[b], p[n] = centre[a] + rho * math.cos(phi), centre[b] + rho * math.sin(phi), centre[n]

    def r(v):
        return tuple(v) if decimals is None else tuple(round(c, decimals) for c in v)

    return ArcMove(r(start), r(end), center=r(centre), plane=plane, clockwise=sweep < 0, feed=600.0, tool=1)


@pytest.mark.parametrize("tool", TOOLS, ids=lambda t: t.kind)
@pytest.mark.parametrize("plane", [ArcPlane.ZX, ArcPlane.YZ])
def test_the_lower_surface_is_the_sampled_least(tool, plane):
    """On each quarter piece of random arcs, L(p) (closed forms for the flat and the ball, sampled and
    refined for the others) is the least over densely sampled tool positions, footprints widened and
    narrowed by eps too; the row's path is the move's."""
    rng = np.random.default_rng(7)
    prof = lower_profile(tool)
    R = prof.radius
    worst = 0.0
    for _ in range(6):
        move = arc(plane, tuple(rng.uniform(-3, 3, 3)), rng.uniform(0.3, 5), rng.uniform(-math.pi, math.pi),
                   rng.uniform(-3, 3), decimals=3)
        for piece in quarter_pieces(move.circular_pieces(1e-3)[0]):
            row, box, _ = _vertical_sweep_row(piece, R, 0)
            if not is_vertical(row):
                continue
            x, y, z = vertical_positions(row, np.linspace(0.0, 1.0, 5))
            for k, t in enumerate(np.linspace(0.0, 1.0, 5)):
                assert (x[k], y[k], z[k]) == pytest.approx(piece.point_at(t), abs=2e-6)  # a post's micron
            for _ in range(8):
                px, py = rng.uniform(box[0], box[2]), rng.uniform(box[1], box[3])
                for eps in (0.0, 1e-3, -1e-3):
                    got = sweep_lower(row, prof.pieces, R, px, py, eps)
                    want = brute_lower(row, prof.pieces, R, px, py, n=4001, refine=4, eps=eps)
                    if math.isinf(want):
                        assert math.isinf(got) or got >= want  # beyond the samples' reach: the rim itself
                        continue
                    assert got == pytest.approx(want, abs=1e-9)
                    worst = max(worst, abs(got - want))
    assert worst > 0.0 or tool.kind == "flat"


def test_the_pieces_are_the_chords_cl_segments_on_the_arc():
    """A half-circle lead arc passing its lowest point: both engines cut it there, then into the same CL
    segments, the analytic one's on the arc itself; each piece's chord is the B-Rep engine's CL."""
    move = arc(ArcPlane.ZX, (10.0, 2.0, 0.0), 2.0, math.pi / 2, math.pi)  # from x = 12 down to z = -2, up to x = 8
    quarters = quarter_pieces(move)
    assert len(quarters) == 2 and quarters[0].end == pytest.approx((10.0, 2.0, -2.0), abs=1e-12)
    for max_len in (None, 0.05):
        chorded, pieces = cl_segments([move], max_len, 1e-3, 0.05), cl_segments([move], max_len, 1e-3, 0.05,
                                                                                 exact_arcs=True)
        assert len(pieces) == len(chorded) >= 2 * len(chords(quarters[0], 1e-3))
        assert all(isinstance(p, ArcMove) for p in pieces) and all(isinstance(c, LinearMove) for c in chorded)
        assert pieces[-1].end == chorded[-1].end == move.end
        for p, c in zip(pieces, chorded):
            assert math.hypot(p.end[0] - 10.0, p.end[2]) == pytest.approx(2.0, abs=1e-12)
            assert math.dist(p.end, c.end) <= 1e-3
            assert as_chord(p) == LinearMove(p.start, p.end, feed=p.feed, tool=p.tool, source=p.source)


@pytest.mark.parametrize("plane", [ArcPlane.ZX, ArcPlane.YZ])
def test_a_flat_lead_in_removes_its_closed_form_volume(plane):
    """A flat end mill (R 3) from the stock's top down a quarter circle (rho 5) to its lowest point, in
    solid: with ``s`` along the plane from the lowest point and ``e`` across, the tool positions within
    R of a point are those with |s(t) - s| <= w = sqrt(R² - e²), the lowest of them the nearest the
    lowest point, so the depth is rho for s <= w and sqrt(rho² - (s - w)²) beyond: V = pi R² rho +
    (pi / 2) R rho². Chords of 1 µm sagitta would miss ~1e-4 of it."""
    R, rho = 3.0, 5.0
    lead = arc(plane, (12.0, 12.0, 0.0), rho, 0.0 if plane == ArcPlane.YZ else math.pi / 2,
               -math.pi / 2 if plane == ArcPlane.YZ else math.pi / 2)
    assert lead.point_at(0.5)[2] < 0.0 and lead.end[2] == pytest.approx(-rho)  # the lower quarter
    tp = Toolpath((LinearMove((*lead.start[:2], 5.0), lead.start, feed=300.0, tool=1), lead), {1: FlatEndMill(2 * R, 30)})
    engine = AnalyticEngine(EngineOptions(max_segment_length=1.0))
    maps = list(engine.run(tp, BoxStock((0, 0, -20), (30, 30, 0))))
    assert all(m.engine == "analytic" and m.status != CLStatus.FAILED for m in maps)
    assert engine._index.size == 2  # the plunge, and the lead's pieces as one sweep
    total = sum(m.removed_volume for m in maps)
    assert total == pytest.approx(math.pi * R * R * rho + math.pi / 2 * R * rho * rho, rel=1e-7)
    for m in maps[1:]:  # the front half of each slice below the top: the tool came from above, behind
        for s in m.engaged_slices:
            assert [(iv.entry, iv.exit) for iv in s.intervals] == [pytest.approx((0.0, 180.0), abs=1e-6)]


@pytest.mark.parametrize("decimals", [None, 3])
@pytest.mark.parametrize("plane", [ArcPlane.ZX, ArcPlane.YZ])
def test_a_ball_down_and_up_a_lower_half_circle_engages_by_the_slope(plane, decimals):
    """A ball (R 3) along a lower half circle (rho 6, from 0.3 rad below the stock's top's level down past
    the lowest point and up again), in solid. The path's height is convex along the plane, so a point of
    the sphere that the local front condition holds (cos theta >= -m (R - z) / r(z), ``m`` the path's
    slope down at the CL's end) lies on no earlier position: each slice below the top is one interval
    centred on the feed direction, as on a straight ramp. Rounded as a post writes them, the arc's end
    radius is off its start's by a micron."""
    R, rho = 3.0, 6.0
    lead = arc(plane, (1.2345, 2.3456, 0.0), rho, -0.3 if plane == ArcPlane.YZ else math.pi / 2 + 0.3,
               -(math.pi - 0.6) if plane == ArcPlane.YZ else math.pi - 0.6, decimals)
    assert min(p[2] for p in (lead.point_at(t) for t in np.linspace(0, 1, 9))) == pytest.approx(-rho, abs=1e-3)
    tp = Toolpath((LinearMove((*lead.start[:2], 5.0), lead.start, feed=300.0, tool=1), lead), {1: BallEndMill(2 * R, 30)})
    opts = EngineOptions(max_segment_length=1.5, slice_height=0.5)
    engine = AnalyticEngine(opts)
    maps = list(engine.run(tp, BoxStock((-20, -20, -20), (20, 20, 0))))
    cls = list(engine.cl_sequence(tp))
    assert len(cls) == len(list(cl_sequence(tp, opts))) > 10  # the B-Rep engine's CLs
    assert any(isinstance(c.move, ArcMove) and c.move.end[2] > c.move.start[2] for c in cls)  # it goes up too
    checked = 0
    for cl, m in zip(cls, maps):
        assert m.engine == "analytic" and m.status != CLStatus.FAILED
        if not isinstance(cl.move, ArcMove):
            continue  # the plunge
        tx, ty, tz = cl.move.tangent_at(1.0)
        slope = -tz / math.hypot(tx, ty)
        for s in m.engaged_slices:
            if s.z >= R:
                half = 90.0
            else:
                c = -slope * (R - s.z) / math.sqrt(R * R - (R - s.z) ** 2)
                if not -0.999 < c < 0.999:
                    continue  # a whole circle or a point: no ends to compare
                half = math.degrees(math.acos(c))
            assert len(s.intervals) == 1
            iv = s.intervals[0]
            tol = 0.005 if decimals else 1e-3
            assert (iv.entry - (90.0 - half) + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=tol)
            assert iv.exit - iv.entry == pytest.approx(2.0 * half, abs=tol)
            checked += 1
    assert checked > 50
