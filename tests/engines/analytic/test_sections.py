"""The removed height's integral along a line x = const in closed form for level ball and flat lines
(.sections): against the adaptive inner integral (.volume) line by line, and CL by CL in the engine."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

import fusioncut.engines.analytic.engine as analytic
from fusioncut.engines.analytic.breaks import sweep_curves
from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.analytic.sections import _flat_interval, section_integral, sections_apply
from fusioncut.engines.analytic.sweeps import line_row, sweep_lower
from fusioncut.engines.analytic.volume import _workspace, height_and_cause, inner_integral
from fusioncut.model import BallEndMill, BoxStock, FlatEndMill, LinearMove
from tests.engines.analytic.test_engine import assert_maps_agree, run

BALL, FLAT3, FLAT5 = 0, 1, 2  # the tools' indices in the tables below
_PIECES = [lower_profile(t).pieces for t in (BallEndMill(6, 20), FlatEndMill(6, 20), FlatEndMill(10, 20))]
PP = np.stack(_PIECES)
NPC = np.array([p.shape[0] for p in _PIECES])
RR = np.array([3.0, 3.0, 5.0])


def _box(row):
    r = RR[int(row[12])]
    return (min(row[1], row[4]) - r, min(row[2], row[5]) - r, max(row[1], row[4]) + r, max(row[2], row[5]) + r)


def _random_case(rng):
    """A level ball line along x (the CL, or its plunge), and earlier ball lines along x and y, flat
    lines in any direction and a ball plunge about it, at heights around its own."""
    z = -2.0
    x0, y0 = rng.uniform(-1, 1, 2)
    length = 0.0 if rng.random() < 0.2 else rng.uniform(0.2, 2.0)
    S = line_row((x0, y0, z + (0.7 if length == 0.0 else 0.0)), (x0 + length, y0, z), BALL)
    rows = []
    for _ in range(rng.integers(1, 4)):
        a, dy, zz = rng.uniform(-6, 2), rng.uniform(-4, 4), z + rng.uniform(-0.5, 1.0)
        rows.append(line_row((a, y0 + dy, zz), (a + rng.uniform(0.5, 8), y0 + dy, zz), BALL))
    for _ in range(rng.integers(0, 3)):
        dx, b, zz = rng.uniform(-4, 4), rng.uniform(-6, 2), z + rng.uniform(-0.5, 1.0)
        rows.append(line_row((x0 + dx, b, zz), (x0 + dx, b + rng.uniform(0.5, 8), zz), BALL))
    for _ in range(rng.integers(0, 4)):
        p, ang, zz = rng.uniform(-5, 5, 2), rng.uniform(0, 2 * math.pi), z + rng.uniform(-0.3, 2.0)
        span = rng.uniform(0, 6)
        rows.append(line_row((p[0], p[1], zz), (p[0] + span * math.cos(ang), p[1] + span * math.sin(ang), zz),
                             int(rng.choice([FLAT3, FLAT5]))))
    if rng.random() < 0.5:
        p = rng.uniform(-3, 3, 2)
        rows.append(line_row((p[0], p[1], z + 3.0), (p[0], p[1], z + rng.uniform(-0.4, 0.8)), BALL))
    C = np.array(rows)
    CB = np.array([_box(r) for r in C])
    return S, C, CB


@njit
def _midpoint_bands(x, ylo, yhi, n, S, P, R, C, CB, PP, NPC, RR, zb, zt, edges):
    """The midpoint rule's sums (n nodes) of the removed height within each band along the line."""
    out = np.zeros(edges.shape[0] - 1)
    w = (yhi - ylo) / n
    for i in range(n):
        v, _, own = height_and_cause(x, ylo + (i + 0.5) * w, S, P, R, C, CB, PP, NPC, RR, zb, zt)
        if v > 0.0:
            low = max(own, zb)
            for e in range(out.shape[0]):
                a, b = max(low, edges[e]), min(low + v, edges[e + 1])
                if b > a:
                    out[e] += w * (b - a)
    return out


def test_flat_intervals_are_where_the_line_crosses_the_footprint():
    """_flat_interval: the points of a line x = const within R of a segment (any direction, a point) form
    the interval it gives, to 1e-12 on a fine sampling of the line."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        a, b = rng.uniform(-3, 3, 2), rng.uniform(-3, 3, 2)
        if rng.random() < 0.2:
            b = a.copy()
        if rng.random() < 0.2:
            b[1] = a[1]
        if rng.random() < 0.2:
            b[0] = a[0]
        R, x = rng.uniform(0.5, 3), rng.uniform(-6, 6)
        S = line_row((a[0], a[1], 0.0), (b[0], b[1], 0.0), FLAT3)
        lo, hi = _flat_interval(S, R, x)
        ys = np.linspace(-10, 10, 20001)
        u = b - a
        uu = u @ u
        t = np.clip(((x - a[0]) * u[0] + (ys - a[1]) * u[1]) / uu, 0, 1) if uu > 0 else np.zeros_like(ys)
        inside = np.hypot(x - a[0] - t * u[0], ys - a[1] - t * u[1]) <= R
        if not inside.any():
            assert lo > hi or hi - lo < 2e-3
            continue
        assert lo <= ys[inside].min() + 1e-12 and hi >= ys[inside].max() - 1e-12
        assert ys[inside].min() - lo < 1e-3 + 1e-12 and hi - ys[inside].max() < 1e-3 + 1e-12


@pytest.mark.parametrize("seed", range(6))
def test_a_lines_closed_form_is_the_adaptive_inner_integral(seed):
    """On random level ball lines along x and y, flat lines in any direction and plunges about a ball's
    level line (or plunge), at random x across its footprint, with the stock's bottom above or below its
    tip: the closed form and the adaptive inner integral at a tight budget agree to 1e-9 mm². Within each
    band of heights (whose sum is the whole here) the closed form meets a midpoint rule of 2,000,000 nodes to
    1e-6 mm² (the adaptive integral's bands share its nodes, their error not controlled: 6e-5 off on some
    of these lines)."""
    rng = np.random.default_rng(seed)
    checked = 0
    for _ in range(20):
        S, C, CB = _random_case(rng)
        P, R = PP[BALL, :NPC[BALL]], 3.0
        assert sections_apply(S, P, R, C, PP, NPC, RR)
        zb = S[6] + (0.2 if rng.random() < 0.3 else -5.0)
        zt = -0.5
        edges = np.array([-3.0, -2.0, -1.6, -1.2, -0.5])
        circles, segments = sweep_curves(np.vstack([S[None, :], C]), PP, NPC, zb, zt)
        box = _box(S)
        for x in rng.uniform(box[0], box[2], 6):
            ylo, yhi = (box[1], box[3]) if rng.random() < 0.6 else (S[2] - 1.1, S[2] + 0.7)
            exact_bands = np.zeros(edges.shape[0] - 1)
            exact = section_integral(x, ylo, yhi, S, P, R, C, CB, PP, NPC, RR, zb, zt, edges, exact_bands)
            adaptive = inner_integral(x, ylo, yhi, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt,
                                      1e-14, 1e-14, edges, _workspace(edges.shape[0] - 1))[0]
            assert exact == pytest.approx(adaptive, abs=1e-9), (seed, x)
            assert exact_bands.sum() == pytest.approx(exact, rel=1e-12, abs=1e-12)
            if checked < 4 and exact > 1e-3:
                reference = _midpoint_bands(x, ylo, yhi, 2_000_000, S, P, R, C, CB, PP, NPC, RR, zb, zt, edges)
                np.testing.assert_allclose(exact_bands, reference, atol=1e-6)
            checked += exact > 1e-3
    assert checked > 20  # lines that remove something


def test_other_sweeps_are_left_to_the_adaptive_integral():
    """A ball's line off the axes, a ramp, a bull-nose's line: no closed form."""
    from fusioncut.model import BullNoseEndMill

    P, R = PP[BALL, :NPC[BALL]], 3.0
    S = line_row((0.0, 0.0, -2.0), (1.0, 0.0, -2.0), BALL)
    for row in (line_row((0.0, 1.0, -2.0), (1.0, 2.0, -2.0), BALL), line_row((0.0, 1.0, -2.0), (1.0, 1.0, -2.1), BALL)):
        assert not sections_apply(S, P, R, row[None], PP, NPC, RR)
    bull = lower_profile(BullNoseEndMill(6, 20, corner_radius=1)).pieces
    assert not sections_apply(S, bull, R, np.zeros((0, 13)), PP, NPC, RR)
    assert sweep_lower(S, P, R, 0.5, 0.0, 0.0) == pytest.approx(-2.0)


def _raster(direction: str, stepover: float, decimals: int | None) -> list:
    """A flat end mill (R 3) clears a pocket floor at z = -1 in chords of a loop, then a ball end mill
    (tool 2, R 2) rasters it along ``direction`` 0.3 mm deeper in 1 mm moves, ``stepover`` apart,
    coordinates rounded to ``decimals`` as posts write them (None: not)."""
    def q(v: float) -> float:
        return v if decimals is None else round(v, decimals)

    moves = [LinearMove((0.0, 0.0, 5.0), (0.0, 0.0, -1.0), rapid=True, tool=1)]
    p = (0.0, 0.0, -1.0)
    for i in range(1, 25):  # a loop of chords about (4, 4)
        a = 2 * math.pi * i / 24
        nxt = (q(4 - 4 * math.cos(a)), q(4 - 4 * math.sin(a)), -1.0)
        moves.append(LinearMove(p, nxt, feed=600.0, tool=1))
        p = nxt
    moves.append(LinearMove(p, (p[0], p[1], 5.0), rapid=True, tool=1))
    z = -1.3
    for k in range(4):
        c = q(2.0 + k * stepover)
        for i in range(6):
            a, b = (q(1.0 + i), c), (q(2.0 + i), c)
            if direction == "y":
                a, b = (a[1], a[0]), (b[1], b[0])
            if i == 0:
                moves.append(LinearMove((a[0], a[1], 5.0), (a[0], a[1], z), rapid=True, tool=2))
            moves.append(LinearMove((a[0], a[1], z), (b[0], b[1], z), feed=600.0, tool=2))
        moves.append(LinearMove((b[0], b[1], z), (b[0], b[1], 5.0), rapid=True, tool=2))
    return moves


@pytest.mark.parametrize("direction,stepover,decimals", [("x", 0.6, None), ("y", 0.45, 3), ("x", 0.7, 3)])
def test_a_ball_raster_over_a_pocket_floor_as_the_adaptive_integral(monkeypatch, direction, stepover, decimals):
    """A ball end mill's level raster 0.3 mm under a flat end mill's pocket floor (chords of a loop), along
    x and along y, exact and rounded as posts write them: each CL's volume, contact areas and rubbing
    slices as the adaptive inner integral finds them, with the closed form taken in most of its cells."""
    moves = _raster(direction, stepover, decimals)
    tools, stock = {1: FlatEndMill(6, 20), 2: BallEndMill(4, 20)}, BoxStock((-4, -4, -6), (12, 12, 0))
    calls = []
    volume = analytic.removed_volume
    monkeypatch.setattr(analytic, "removed_volume", lambda *a: calls.append(a[-1]) or volume(*a))
    _, exact = run(moves, tools, stock, slice_height=0.25)
    assert sum(calls) > 20  # cells whose inner integrals are in closed form
    monkeypatch.setattr(analytic, "SECTION_FORMS", False)
    _, adaptive = run(moves, tools, stock, slice_height=0.25)
    assert sum(m.removed_volume for m in exact) > 5
    assert_maps_agree(exact, adaptive)

