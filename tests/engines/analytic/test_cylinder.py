"""A flat end mill's side contact area as one integral around it (.cylinder), against the integral of the
engaged span over its height (.area.contact_area) and closed forms."""
from __future__ import annotations

import math
import random
import sys
from pathlib import Path

import numpy as np
import pytest
from numba import njit

import fusioncut.engines.analytic.engine as analytic
from fusioncut.engines.analytic.contact import _engaged, contact_range, front_limits
from fusioncut.engines.analytic.cylinder import side_area
from fusioncut.engines.analytic.polar import ring_breaks
from fusioncut.engines.analytic.sweeps import end_velocity
from fusioncut.engines.analytic.volume import _node
from fusioncut.model import ArcMove, BoxStock, FlatEndMill, LinearMove
from tests.engines.analytic.test_engine import AREA_REL, feed, run
from tests.engines.analytic.test_polar import _bore

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))


def _program(seed: int, decimals: int | None) -> list:
    """Random moves of a flat end mill over a 40 x 30 mm box: level lines, ramps (down and up), plunges,
    XY arcs and helices, each reached by a rapid from above; coordinates rounded to ``decimals`` as a
    post writes them (None: not)."""
    rnd = random.Random(seed)

    def q(v: float) -> float:
        return v if decimals is None else round(v, decimals)

    moves = []
    for _ in range(12):
        z = q(rnd.uniform(-4.5, -0.5))
        p = (q(rnd.uniform(-16, 16)), q(rnd.uniform(-11, 11)), z)
        moves.append(LinearMove((p[0], p[1], 5.0), p, rapid=True, tool=1))
        kind = rnd.choice(("line", "ramp", "plunge", "arc", "helix"))
        if kind == "plunge":
            e = (p[0], p[1], q(z - rnd.uniform(0.5, 2)))
            moves.append(feed(p, e))
        elif kind in ("line", "ramp"):
            dz = 0.0 if kind == "line" else rnd.uniform(-1.5, 1.5)
            e = (q(rnd.uniform(-16, 16)), q(rnd.uniform(-11, 11)), q(z + dz))
            moves.append(feed(p, e))
        else:
            r, a0 = rnd.uniform(1, 6), rnd.uniform(0, 2 * math.pi)
            c = (q(p[0] - r * math.cos(a0)), q(p[1] - r * math.sin(a0)), z)
            rr = math.hypot(p[0] - c[0], p[1] - c[1])
            turn = rnd.uniform(0.5, 1.8) * math.pi
            dz = 0.0 if kind == "arc" else -rnd.uniform(0.2, 1.5)
            e = (q(c[0] + rr * math.cos(a0 + turn)), q(c[1] + rr * math.sin(a0 + turn)), q(z + dz))
            moves.append(ArcMove(p, e, feed=600.0, tool=1, center=c))
        e = moves[-1].end
        moves.append(LinearMove(e, (e[0], e[1], 5.0), rapid=True, tool=1))
    return moves


@njit
def _engaged_height(theta, S, P, R, z0, z1, C, CB, PP, NPC, RR, stock, eps, G, gstart, gitems):
    """The engaged heights' length (mm) at angle ``theta`` on the side between machine heights z0 and z1,
    by the slices' own test (.contact._engaged): scanned at 400 heights, crowded towards z0 (the
    engaged heights shrink to nothing there where a wall or the front ends them), the lowest and the
    highest engaged ones' ends bisected (they are one interval, .cylinder)."""
    vx, vy, _ = end_velocity(S)
    n = 400
    zs = np.empty(n + 2)
    for i in range(n + 2):
        zs[i] = z0 + (z1 - z0) * (max(i - 0.5, 0.0) / (n + 0.5)) ** 3 if i <= n else z1
    first, last = -1, -1
    for i in range(1, n + 1):
        if _engaged(theta, vx, vy, 0.0, S, P, R, S[4], S[5], zs[i], R, C, CB, PP, NPC, RR, stock, eps, G, gstart,
                    gitems):
            if first < 0:
                first = i
            last = i
    if last < 0:
        return 0.0
    ends = np.empty(2)
    for k in range(2):
        i = last if k == 0 else first
        a, b = zs[i], zs[i + 1] if k == 0 else zs[i - 1]  # engaged at a, not (or the range's end) at b
        for _ in range(80):
            m = 0.5 * (a + b)
            if _engaged(theta, vx, vy, 0.0, S, P, R, S[4], S[5], m, R, C, CB, PP, NPC, RR, stock, eps, G, gstart,
                        gitems):
                a = m
            else:
                b = m
        ends[k] = a
    return ends[0] - ends[1]


def _oracle(ts, S, P, R, z0, z1, *args) -> float:
    """R times the integral of :func:`_engaged_height` over the angles ahead, between the angles ``ts``:
    Gauss-Kronrod (7, 15) on each part, the part whose two rules differ most halved until they differ
    by 1e-12 of the whole (the heights bend where a wall, the front or the range's top takes over)."""
    vx, vy, _ = end_velocity(S)

    def gk(a: float, b: float) -> tuple[float, float]:
        k = g = 0.0
        for i in range(15):
            u, wk, wg = _node(i)
            f = _engaged_height(0.5 * (a + b) + 0.5 * (b - a) * u, S, P, R, z0, z1, *args)
            k, g = k + wk * f, g + wg * f
        return 0.5 * (b - a) * k, 0.5 * (b - a) * abs(k - g)

    parts = [(a, b, *gk(a, b)) for a, b in zip(ts[:-1], ts[1:])
             if b > a and math.cos(0.5 * (a + b)) * vx + math.sin(0.5 * (a + b)) * vy >= 0.0]
    while parts:
        k = max(range(len(parts)), key=lambda i: parts[i][3])
        a, b, _, err = parts[k]
        if sum(p[3] for p in parts) <= 1e-12 * max(abs(sum(p[2] for p in parts)), 1.0) or b - a < 1e-12:
            break
        m = 0.5 * (a + b)
        parts[k] = (a, m, *gk(a, m))
        parts.append((m, b, *gk(m, b)))
    return R * sum(p[2] for p in parts)


@pytest.mark.parametrize("seed,decimals", [(1, None), (2, 3), (3, 4)])
def test_the_side_area_as_the_slices_test_finds_it(monkeypatch, seed, decimals):
    """Random level cuts, ramps, plunges, arcs and helices of a flat end mill with a wider shank above
    its flutes, exact and rounded as posts write them: the side's contact area of CLs, flutes and
    shank, against the integral around the tool of the engaged heights found by the slices' own test
    (.contact._engaged, scanned and bisected at each angle): to 1e-9. (The integral of the engaged
    span over the height, .area.contact_area, is off by up to 1.6e-6 of the area on these programs.)"""
    calls = []
    area = analytic.AnalyticEngine._area
    monkeypatch.setattr(analytic.AnalyticEngine, "_area",
                        lambda self, args, near, part, z_range, *rest: calls.append((args, near, part, z_range))
                        or area(self, args, near, part, z_range, *rest))
    tools = {1: FlatEndMill(6, 3, shank_diameter=8, shoulder_length=4)}
    _, maps = run(_program(seed, decimals), tools, BoxStock((-20, -15, -6), (20, 15, 0)), slice_height=1.0)
    assert sum(m.contact_area for m in maps) > 50
    assert sum(m.shank_contact_area for m in maps) > 1
    engine = analytic.AnalyticEngine()
    engine.stock = (-20, -15, -6, 20, 15, 0)
    checked = 0
    for args, near, part, (z_lo, z_hi) in calls[::7]:
        S, P, R = part.row, part.profile.pieces, part.profile.radius
        C, CB = args[3][near], args[4][near]
        circles, segments = engine._curves(np.vstack([S[None, :], C]), args[5], args[6])
        got = side_area(S, P, R, z_lo, z_hi, C, CB, *args[5:10], circles, segments, 1e-9)[0]
        stock = args[8]
        ts = ring_breaks(R, S[4], S[5], stock[0], stock[3], stock[1], stock[4], np.zeros((0, 2)), np.zeros((0, 2)),
                         circles, segments)
        vx, vy, _ = end_velocity(S)
        lim = (front_limits(vx, vy, 0.0) + math.pi) % (2 * math.pi) - math.pi
        expected = _oracle(np.sort(np.concatenate((ts, lim))), S, P, R, S[6] + z_lo, S[6] + z_hi, *args[3:13])
        assert got == pytest.approx(expected, rel=1e-9, abs=1e-9)
        checked += got > 0
    assert checked >= 5


@pytest.mark.parametrize("seed,decimals", [(1, None), (2, 3), (3, 4)])
def test_the_side_contact_range_as_the_slices_find_it(monkeypatch, seed, decimals):
    """The same random programs: the heights where a flat end mill's side touches material, flutes, neck and
    shank (.cylinder.side_range, from the engaged heights around the tool), against the slices' own search
    (.contact.contact_range: quarter slices walked up and down, their material margin's sign change found
    by regula falsi): the same touching parts, their ends to 1e-9 mm."""
    calls = []
    found = analytic.AnalyticEngine._range
    monkeypatch.setattr(analytic.AnalyticEngine, "_range",
                        lambda self, args, near, part, lo, hi, levels: calls.append(
                            (args, lo, hi, levels, found(self, args, near, part, lo, hi, levels)))
                        or calls[-1][-1])
    tools = {1: FlatEndMill(6, 3, shank_diameter=8, shoulder_length=4)}
    run(_program(seed, decimals), tools, BoxStock((-20, -15, -6), (20, 15, 0)), slice_height=1.0)
    touching = 0
    for args, lo, hi, levels, got in calls:
        expected = contact_range(args, lo, hi, 1.0, levels)
        assert (got is None) == (expected is None)
        if got is not None:
            assert got == pytest.approx(expected, abs=1e-9)
            touching += 1
    assert touching >= 20


def test_a_helical_bore_in_solid_touches_its_half_circle_ahead():
    """A flat end mill (R = 3) on a helix of radius 1 going down 1 mm a turn into solid, a turn below the
    top: the material ahead stands up to the last turn's floor above, so the side touches it over the
    half circle ahead, from the tip up to where the tool a turn before stood: on the far side of the
    centre that is the pitch; the engaged heights around the tool, integrated independently here from
    the helix's geometry (a flat end mill at angle a holds the side's point q iff |q - c(a)| <= R)."""
    R, rho, pitch = 3.0, 1.0, 1.0
    _, maps = run(_bore(rho, turns=3, pitch=pitch, z0=0.0), {1: FlatEndMill(2 * R, 20)},
                  BoxStock((-12, -12, -10), (12, 12, 0)))
    m = next(m for m in maps if m.position[2] == pytest.approx(-2.5, abs=1e-9))
    cx, cy = 1.0, 2.0
    a_end = math.atan2(m.position[1] - cy, m.position[0] - cx)
    vx, vy = -math.sin(a_end), math.cos(a_end)  # counter-clockwise

    def engaged_height(theta: float) -> float:
        """From the tip to the lowest tip of the earlier turns' positions holding the side's point."""
        qx, qy = m.position[0] + R * math.cos(theta), m.position[1] + R * math.sin(theta)
        best = math.inf
        for i in range(1, 20001):  # the last turn before, finely: the lowest tip holding q
            a = a_end - 2 * math.pi * i / 20000
            if math.hypot(qx - cx - rho * math.cos(a), qy - cy - rho * math.sin(a)) <= R:
                best = min(best, pitch * (2 * math.pi * i / 20000) / (2 * math.pi))
        return best

    n = 2000
    expected = 0.0
    for k in range(n):
        theta = 2 * math.pi * (k + 0.5) / n
        if math.cos(theta) * vx + math.sin(theta) * vy >= 0:
            expected += R * engaged_height(theta) * 2 * math.pi / n
    assert m.contact_area == pytest.approx(expected, rel=2e-4)


def test_real_ramps_and_helices_around_the_tool_as_over_its_height(monkeypatch):
    """fusion-posted/1055_utab_265bit.nc CLs 0-39 (a flat end mill's lead-in ramps) and 1110_wall CLs
    2495-2534 (Bore1's lead-in and helix): contact areas as the integral over the height finds them."""
    import real_programs
    from shared_data import DATA

    for name in ("1055_utab_265bit.nc", "1110_wall_265bit.nc"):
        if not (DATA / "fusion-posted" / name).is_file():
            pytest.skip("shared data missing")

    def window(program: str, start: int, n: int) -> list:
        toolpath, stock, default = real_programs.load(next(p for p in real_programs.PROGRAMS if p.name == program))
        engine = analytic.AnalyticEngine(analytic.EngineOptions())
        engine.start(stock)
        maps = engine.process(toolpath, default, start_at=start)
        return [next(maps) for _ in range(n)]

    around = window("1055_utab", 0, 40) + window("1110_wall", 2495, 40)
    monkeypatch.setattr(analytic, "is_flat", lambda pieces: False)  # the integral over the height
    over = window("1055_utab", 0, 40) + window("1110_wall", 2495, 40)
    assert sum(m.contact_area for m in around) > 100
    for a, b in zip(around, over, strict=True):
        assert a.contact_area == pytest.approx(b.contact_area, rel=AREA_REL, abs=1e-9), a.cl_index
