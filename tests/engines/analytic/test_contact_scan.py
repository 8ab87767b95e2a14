"""The engaged arcs' scan (fusioncut.engines.analytic.contact): what a block of scan angles is
certified to be must be what each of its points is."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fusioncut.engines.analytic.contact import block_state, material_at, sweep_grid
from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.analytic.sweeps import arc_row, line_row
from fusioncut.model import BallEndMill, BullNoseEndMill, FlatEndMill

EPS = 1e-6
STOCK = np.array([-10.0, -10.0, -15.0, 10.0, 10.0, 0.0])


def _tools():
    tools = (BallEndMill(6.0, 20.0), FlatEndMill(4.0, 20.0), BullNoseEndMill(8.0, 20.0, corner_radius=1.5))
    profiles = [lower_profile(t) for t in tools]
    width = max(len(p.pieces) for p in profiles)
    PP = np.zeros((len(profiles), width, 6))
    for i, p in enumerate(profiles):
        PP[i, :len(p.pieces)] = p.pieces
    return PP, np.array([len(p.pieces) for p in profiles]), np.array([p.radius for p in profiles])


def test_a_block_certified_all_material_or_none_is_so_at_every_point():
    """Earlier sweeps of three tools (level, ramped and 3D lines and a helix) in a box; random arcs
    of 2 to 90 degrees of random circles at random heights. Where
    ``block_state`` says 1 every one of 256 points of the arc is in the material (``material_at``),
    where it says 0 none is; both certificates are given often (the scan saves nothing otherwise)."""
    PP, NPC, RR = _tools()
    C = np.array([
        line_row((-15.0, -2.0, -3.0), (15.0, -2.0, -3.0), 0),  # a level ball pass beside the CL
        line_row((-15.0, 4.0, -1.0), (15.0, 5.0, -4.0), 0),  # a ramp
        line_row((-3.0, -15.0, -6.0), (2.0, 15.0, -2.0), 2),  # a bull-nose 3D line across
        line_row((8.0, -10.0, -2.0), (8.0, 10.0, -2.0), 1),  # a flat end mill's slot
        arc_row((-6.0, 0.0, -5.0), (-6.0, 0.0, -3.0), (-10.0, 0.0), 4.0, 0.0, 2.0 * math.pi, 0),  # a helix
    ])
    reach = [RR[int(r[12])] + 2 * EPS for r in C]
    CB = np.array([[min(r[1], r[4]) - e, min(r[2], r[5]) - e, max(r[1], r[4]) + e, max(r[2], r[5]) + e]
                   for r, e in zip(C, reach)])
    CB[4] = [-10.0 - 4.0 - reach[4], -4.0 - reach[4], -10.0 + 4.0 + reach[4], 4.0 + reach[4]]
    S = line_row((-4.0, 0.0, -2.5), (0.0, 0.0, -2.5), 0)
    grid = sweep_grid(-12.0, -12.0, 24.0, 8, S, PP[0, :NPC[0]], 3.0, C, PP, NPC, RR, STOCK[2], STOCK[5],
                      2 * EPS)
    rng = np.random.default_rng(7)
    seen = {-1: 0, 0: 0, 1: 0}
    for _ in range(6000):
        (x, y), r = rng.uniform(-9.0, 9.0, 2), rng.uniform(0.2, 3.0)
        pz, t0 = rng.uniform(-9.0, 0.5), rng.uniform(0.0, 2 * math.pi)
        t1 = t0 + math.radians(rng.uniform(2.0, 90.0))
        state = block_state(t0, t1, x, y, pz, r, C, CB, PP, NPC, RR, STOCK, EPS, *grid)
        seen[state] += 1
        if state == -1:
            continue
        inside = [material_at(x + r * math.cos(t), y + r * math.sin(t), pz, C, CB, PP, NPC, RR, STOCK, EPS, *grid)
                  for t in np.linspace(t0, t1, 256)]
        assert all(inside) if state == 1 else not any(inside), (x, y, r, pz, t0, state)
    assert min(seen.values()) > 200, seen


def test_an_arc_narrower_than_the_scan_step_between_two_walls_is_found():
    """A flat end mill (R = 3) ends a level move 1e-5 mm past the axis of an earlier slot of its width, its
    path turned 0.25 degrees off the slot's normal: its circle reaches beyond the slot's far wall over
    2 acos(1 - (1e-5 - eps) / 3) = 0.296 degrees about the path's direction, between two of the scan's even angles
    (every 0.5 degrees), and both ends of that arc are the wall. Every slice has that one arc, to 1e-6 degrees."""
    from fusioncut.engines.analytic.engine import WALL_EPS
    from fusioncut.model import BoxStock, LinearMove
    from tests.engines.analytic.test_engine import feed, rot, run

    turn, past = 0.25, 1e-5
    moves = [LinearMove(rot((0.0, -12.0, 5.0), turn), rot((0.0, -12.0, -2.0), turn), tool=1),
             feed(rot((0.0, -12.0, -2.0), turn), rot((0.0, 12.0, -2.0), turn)),
             LinearMove(rot((0.0, 12.0, -2.0), turn), rot((0.0, 12.0, 5.0), turn), rapid=True, tool=1),
             LinearMove(rot((0.0, 12.0, 5.0), turn), rot((past - 2.0, 0.0, 5.0), turn), rapid=True, tool=1),
             LinearMove(rot((past - 2.0, 0.0, 5.0), turn), rot((past - 2.0, 0.0, -2.0), turn), tool=1),
             feed(rot((past - 2.0, 0.0, -2.0), turn), rot((past, 0.0, -2.0), turn))]
    _, maps = run(moves, {1: FlatEndMill(6.0, 12.0)}, BoxStock((-20, -20, -6), (20, 20, 0)), slice_height=1.0,
                  min_chip_thickness=0.0)  # the arc's chip is thinner than any: kept to be seen
    last = maps[-1]
    width = 2 * math.degrees(math.acos(1 - (past - WALL_EPS) / 3.0))  # the slot's footprint widened by eps
    assert last.removed_volume > 0
    assert len(last.slices) == 2
    for s in last.slices:
        assert len(s.intervals) == 1
        assert s.intervals[0].exit - s.intervals[0].entry == pytest.approx(width, abs=1e-6)


@pytest.mark.parametrize("onset", [0.8430017176747031, 0.37, 2.0 / 3.0])
def test_a_tangential_onset_is_found_by_halving_where_the_margin_below_it_is_round_off(monkeypatch, onset):
    """Below a ball's tangential onset the slices' margin is round-off, ~1e-13 mm either side of 0 (as on
    CAMotics bear), above it grows linearly. contact_range finds the onset to its Z_TOL, and halves the
    bracket there: a regula falsi step would land within ~1e-13 of the round-off end each time (the old
    rule took ~120 margins; halving from the quarter-mm candidate spacing to 1e-10 takes ~32)."""
    from fusioncut.engines.analytic import contact

    calls = []

    def margin(row, pieces, R, zs, *rest):
        calls.append(zs)
        return zs - onset if zs > onset else -1e-13 * (1.0 + math.sin(1e7 * zs)) - 1e-14

    monkeypatch.setattr(contact, "slice_margin", margin)
    ball = lower_profile(BallEndMill(6.0, 20.0))
    row = line_row((0.0, 0.0, -5.0), (10.0, 0.0, -5.0), 0)
    args = (row, ball.pieces, ball.radius, *([None] * 5), STOCK, *([None] * 4))
    lo, hi = contact.contact_range(args, 0.0, 4.0, 1.0, [])
    assert abs(lo - onset) <= contact.Z_TOL and hi == 4.0
    assert len(calls) <= 50


def test_a_grid_filled_on_a_ring_answers_on_its_circle_as_the_whole_grid():
    """The end grid of a flat end mill (R = 2) filled only on the ring of its radius (as the engine builds it for a
    flat profile, whose slices all lie on that circle): at 4,000 points of the circle at random heights the
    material test is the full grid's, and the cells wholly inside or outside the ring hold no sweeps."""
    PP, NPC, RR = _tools()
    C = np.array([
        line_row((-15.0, -2.0, -3.0), (15.0, -2.0, -3.0), 0),
        line_row((-15.0, 4.0, -1.0), (15.0, 5.0, -4.0), 0),
        line_row((-3.0, -15.0, -6.0), (2.0, 15.0, -2.0), 2),
        line_row((1.0, -10.0, -2.0), (1.0, 10.0, -2.0), 1),
        arc_row((-1.0, 0.0, -5.0), (-1.0, 0.0, -3.0), (-3.0, 0.0), 2.0, 0.0, 2.0 * math.pi, 1),
    ])
    reach = [RR[int(r[12])] + 2 * EPS for r in C]
    CB = np.array([[min(r[1], r[4]) - e, min(r[2], r[5]) - e, max(r[1], r[4]) + e, max(r[2], r[5]) + e]
                   for r, e in zip(C, reach)])
    CB[4] = [-3.0 - 2.0 - reach[4], -2.0 - reach[4], -3.0 + 2.0 + reach[4], 2.0 + reach[4]]
    R, ex, ey = 2.0, 0.5, 0.25
    S = line_row((-2.0, ey, -2.5), (ex, ey, -2.5), 1)
    side = R + 2 * EPS
    args = (ex - side, ey - side, 2 * side, 8, S, PP[1, :NPC[1]], R, C, PP, NPC, RR, STOCK[2], STOCK[5], 2 * EPS)
    whole, ring = sweep_grid(*args), sweep_grid(*args, R - 2 * EPS, side)
    assert ring[2].size < whole[2].size
    w = ring[0][2]
    for i in range(8):
        for j in range(8):
            x0, y0 = (i * w - side, (i + 1) * w - side), (j * w - side, (j + 1) * w - side)  # about the centre
            far = math.hypot(max(map(abs, x0)), max(map(abs, y0)))
            near = math.hypot(max(x0[0], 0.0, -x0[1]), max(y0[0], 0.0, -y0[1]))
            if far < R - 1e-9 or near > R + 1e-9:
                assert ring[1][i * 8 + j + 1] == ring[1][i * 8 + j], (i, j)  # a cell off the ring: no sweeps
    rng = np.random.default_rng(3)
    for t, pz in zip(rng.uniform(0.0, 2 * math.pi, 4000), rng.uniform(-8.0, 0.5, 4000)):
        x, y = ex + R * math.cos(t), ey + R * math.sin(t)
        assert material_at(x, y, pz, C, CB, PP, NPC, RR, STOCK, EPS, *ring) == \
            material_at(x, y, pz, C, CB, PP, NPC, RR, STOCK, EPS, *whole), (t, pz)


def test_the_contact_range_passes_over_a_wall_s_untouched_heights_as_the_walk_finds_them(monkeypatch):
    """A ball end mill's level raster 0.3 mm under a flat end mill's pocket floor, 20 mm below the stock's top,
    beside a shelf the flat end mill left 3 mm higher (the ball's wall touches it up to 3.3 mm above the tip):
    the contact's height range, slices and areas with the wall's candidates passed over are those of the walk
    down every candidate (the wall's start taken as infinite)."""
    from fusioncut.engines.analytic import contact
    from fusioncut.engines.analytic import engine as analytic
    from fusioncut.model import BoxStock, LinearMove
    from tests.engines.analytic.test_engine import feed, run

    moves = [LinearMove((-12.0, -6.0, 5.0), (-12.0, -6.0, -20.0), rapid=True, tool=1)]
    for k, (y, z) in enumerate(((-6.0, -20.0), (-3.0, -20.0), (0.0, -20.0), (7.0, -17.0))):  # floor, then shelf
        a, b = (-12.0, y, z), (12.0, y, z)
        moves.append(feed(moves[-1].end, (a, b)[k % 2]) if k else None)
        moves.append(feed(*((a, b) if k % 2 == 0 else (b, a))))
    moves = [m for m in moves if m is not None]
    moves.append(LinearMove(moves[-1].end, (-8.0, -3.0, 5.0), rapid=True, tool=1))
    moves.append(LinearMove((-8.0, -3.0, 5.0), (-8.0, -3.0, -20.3), rapid=True, tool=2))
    for k, y in enumerate((-3.0, -1.0, 1.0, 3.0)):  # the ball's raster, 1 mm moves
        xs = np.arange(-8.0, 8.01, 1.0)
        xs = xs if k % 2 == 0 else xs[::-1]
        if k:
            moves.append(feed(moves[-1].end, (xs[0], y, -20.3), tool=2))
        moves += [feed((x0, y, -20.3), (x1, y, -20.3), tool=2) for x0, x1 in zip(xs[:-1], xs[1:])]
    tools = {1: FlatEndMill(8.0, 30.0), 2: BallEndMill(4.0, 30.0)}
    stock = BoxStock((-15.0, -10.0, -30.0), (15.0, 10.0, 0.0))
    calls = []
    walk = analytic.contact_range
    monkeypatch.setattr(analytic, "contact_range", lambda *a: calls.append(1) or walk(*a))
    _, passed = run(moves, tools, stock, slice_height=1.0)
    monkeypatch.setattr(contact, "profile_height", lambda P, d: math.inf)
    _, walked = run(moves, tools, stock, slice_height=1.0)
    ball = [(a, b) for a, b in zip(passed, walked, strict=True) if a.tool == walked[-1].tool and b.removed_volume > 0]
    assert len(ball) > 40 and len(calls) > 40
    assert max(b.axial_range[1] for a, b in ball) > 3.0  # the shelf's wall, on the ball's wall
    for a, b in ball:
        assert a.axial_range == b.axial_range and a.contact_area == b.contact_area, a.cl_index
        assert [s.intervals for s in a.slices] == [s.intervals for s in b.slices], a.cl_index


def test_a_wall_left_out_of_a_slice_s_scan_changes_no_point_s_material_there():
    """``standing_walls`` keeps a footprint's edge only where its sweep may hold the slice's points there.
    Random level, ramped and plunging lines of a ball, a flat and a bull-nose end mill; at random slice
    heights, every point of a left-out edge (sampled along the curves, those at distance R from the path:
    the edge, not an end circle's inner half) is below the sweep's lower surface (eps-widened, as the
    material test takes it) by more than eps, on the edge and just beyond it: the sweep cuts none of them, so the
    edge ends no arc. A flat end mill's edges are left out only where the slice is below its path's lowest
    tip; a round bar's outside is always kept. Both kinds of answer are given often."""
    from fusioncut.engines.analytic.breaks import curves_at
    from fusioncut.engines.analytic.contact import standing_walls
    from fusioncut.engines.analytic.sweeps import outside_row, point_segment_distance, sweep_lower

    PP, NPC, RR = _tools()
    rng = np.random.default_rng(11)
    rows = []
    for _ in range(40):
        a = rng.uniform(-8.0, 8.0, 3)
        b = a + rng.uniform(-4.0, 4.0, 3) * rng.integers(0, 2, 3)  # some level, some plunges, some 3D
        rows.append(line_row(tuple(a), tuple(b), int(rng.integers(0, 3))))
    rows.append(outside_row((0.0, 0.0), 9.0, -20.0, 0))
    C = np.array(rows)
    circles, segments = curves_at(C, RR[C[:, 12].astype(np.int64)][:, None], np.ones(len(C), dtype=np.int64),
                                  np.full(len(C), math.nan))
    kept_flat_above = dropped = kept = 0
    for pz in rng.uniform(-12.0, 12.0, 60):
        for curves, owner in ((circles, 3), (segments, 4)):
            left = standing_walls(curves, owner, pz, C, PP, NPC, RR, EPS)
            keys = {tuple(c) for c in left}
            for c in curves:
                j = int(c[owner])
                if C[j, 0] == 2.0:
                    assert tuple(c) in keys
                    continue
                if tuple(c) in keys:
                    kept += 1
                    kept_flat_above += int(C[j, 12]) == 1 and pz >= min(C[j, 3], C[j, 6])
                    continue
                dropped += 1
                assert not (int(C[j, 12]) == 1 and pz >= min(C[j, 3], C[j, 6])), "a flat end mill's wall"
                k = int(C[j, 12])
                for s in np.linspace(0.0, 1.0, 41):
                    if owner == 3:
                        t = 2 * math.pi * s
                        px, py = c[0] + c[2] * math.cos(t), c[1] + c[2] * math.sin(t)
                    else:
                        px, py = c[0] + s * (c[2] - c[0]), c[1] + s * (c[3] - c[1])
                    d = point_segment_distance(px, py, C[j, 1], C[j, 2], C[j, 4], C[j, 5])
                    if d < RR[k] - 1e-9:
                        continue  # inside the footprint: the curve is no edge here
                    for q in (px, px + 0.5 * EPS):
                        low = sweep_lower(C[j], PP[k, :NPC[k]], RR[k], q, py, EPS)
                        assert low > pz + EPS, (j, pz, px, py, low)
    assert dropped > 1000 and kept > 1000 and kept_flat_above > 100, (dropped, kept, kept_flat_above)


@pytest.mark.parametrize("n_scan", [720, 360, 90, 30])
def test_the_scan_s_angles_are_the_even_ones_and_the_extra_ones_in_order_with_their_cosines(n_scan):
    """``scan_angles``: the even angles and the extra ones (some equal to even ones), merged in order; the
    cosines and sines from the first quarter's by symmetry within 2e-15 of each angle's own."""
    from fusioncut.engines.analytic.contact import scan_angles

    extra = np.sort(np.concatenate([np.random.default_rng(n_scan).uniform(0.0, 2 * math.pi, 9),
                                    2 * math.pi * np.array([0, 3, n_scan // 2]) / n_scan]))
    th, cs, sn = scan_angles(n_scan, extra)
    assert th.tolist() == sorted([2 * math.pi * i / n_scan for i in range(n_scan)] + extra.tolist())
    assert np.abs(cs - np.cos(th)).max() < 2e-15 and np.abs(sn - np.sin(th)).max() < 2e-15
