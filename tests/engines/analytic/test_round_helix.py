"""A ball and a bull-nose end mill down a helix into solid, then once round a level circle at its foot, with
coordinates exact and rounded to 3 decimals as posts write them (the helix's and the circle's end radii then
differ from their start radii by up to a micron). Closed form: the level circle's sweep holds every earlier
one's (each tool position of the helix is at least as high, and no nearer to a point, as the circle's
nearest), so the pocket is the material above ``z_end + f(|r - rho|)`` within ``rho + R`` of the axis, f
the tool's lower profile: V = 2 pi int r (top - z_end - f(|r - rho|))+ dr."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.base import EngineOptions
from fusioncut.model import ArcMove, BallEndMill, BoxStock, BullNoseEndMill, CLStatus, LinearMove, Toolpath

RHO, PITCH, TURNS, TOP = 2.0, 1.0, 1.25, 0.0
Z0 = TOP + 0.5  # the helix starts above the stock
Z_END = Z0 - PITCH * TURNS
TURN = 17.0  # degrees: the whole path turned about the axis, so that rounding moves its points
STOCK = BoxStock((-20, -20, -10), (20, 20, TOP))
SHIFT = 0.5e-3 * math.sqrt(2)  # mm: how far rounding to 3 decimals moves a point in XY
TOOLS = {"ball": BallEndMill(6, 20), "bullnose": BullNoseEndMill(8, 20, corner_radius=1.5)}


def _pocket(tool) -> float:
    """The closed form (module docstring) by Gauss-Legendre on the pieces of r where the integrand is smooth:
    split at rho, at rho +- the profile's joints and where f reaches the pocket's depth."""
    lp = lower_profile(tool)
    depth = TOP - Z_END
    f = np.vectorize(lp.f)
    lo, hi = 0.0, lp.radius  # f(d*) = depth by bisection: the pocket's edge
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if lp.f(mid) < depth else (lo, mid)
    cuts = {0.0, RHO, RHO + lo}
    for d in lp.pieces[:, 1]:
        cuts |= {RHO - d, RHO + d}
    cuts = sorted(c for c in cuts if 0.0 <= c <= RHO + lo)
    u, w = np.polynomial.legendre.leggauss(80)
    total = 0.0
    for a, b in zip(cuts, cuts[1:]):
        r = 0.5 * (a + b) + 0.5 * (b - a) * u
        total += 0.5 * (b - a) * np.sum(w * r * np.maximum(depth - f(np.abs(r - RHO)), 0.0))
    return 2 * math.pi * total


def _moves(decimals):
    """The helix down TURNS clockwise turns from angle TURN, one move (its turns are the whole ones besides the
    part from start to end angle), then the level circle in quarter arcs."""
    def pt(a_deg, z):
        a = math.radians(a_deg)
        p = (RHO * math.cos(a), RHO * math.sin(a), z)
        return p if decimals is None else tuple(round(c, decimals) for c in p)

    end_angle = TURN - 360.0 * TURNS
    moves = [LinearMove(pt(TURN, Z0 + 5), pt(TURN, Z0), feed=300.0, tool=1),
             ArcMove(pt(TURN, Z0), pt(end_angle, Z_END), center=(0.0, 0.0, Z0), clockwise=True, turns=int(TURNS),
                     feed=800.0, tool=1)]
    for k in range(4):
        moves.append(ArcMove(pt(end_angle - 90 * k, Z_END), pt(end_angle - 90 * (k + 1), Z_END),
                             center=(0.0, 0.0, Z_END), clockwise=True, feed=800.0, tool=1))
    return moves


def _run(kind, decimals):
    tp = Toolpath(tuple(_moves(decimals)), {1: TOOLS[kind]})
    return list(AnalyticEngine(EngineOptions(slice_height=0.25, max_segment_length=4.0)).run(tp, STOCK))


@pytest.mark.slow  # a minute a tool: the volume's integral on helices of round tools is not fast yet
@pytest.mark.parametrize("kind", TOOLS)
def test_a_round_tools_helical_bore_removes_the_closed_form_pocket_also_as_posted(kind):
    """Exact coordinates: the pocket to the volume's tolerance. Rounded to 3 decimals: every CL still
    computed by the analytic engine; the pocket, and each CL's volume against the exact run's, within
    what moving the sweeps' boundaries by SHIFT can change (SHIFT times the pocket's side and floor, or a
    CL's; each CL's sweep and the earlier ones it meets move, so three times that); the helix's last CL
    engaged over the same angles to 0.05 degrees."""
    exact, posted = _run(kind, None), _run(kind, 3)
    assert len(exact) == len(posted)
    for maps in (exact, posted):  # every CL computed here, none handed to the B-Rep engine
        assert all(m.status != CLStatus.FAILED and m.engine == "analytic" for m in maps)
    pocket = _pocket(TOOLS[kind])
    R = TOOLS[kind].diameter / 2
    depth = TOP - Z_END
    assert sum(m.removed_volume for m in exact) == pytest.approx(pocket, rel=1e-7)
    reach = RHO + R
    assert abs(sum(m.removed_volume for m in posted) - pocket) <= SHIFT * (2 * math.pi * reach * depth
                                                                          + math.pi * reach * reach)
    for e, p in zip(exact, posted):
        assert abs(e.removed_volume - p.removed_volume) <= 3 * SHIFT * (2 * R * depth + math.pi * R * R)
    helix = [k for k, m in enumerate(exact) if m.start[2] != m.position[2]]
    last = helix[-1]
    assert exact[last].status == CLStatus.ENGAGED and posted[last].status == CLStatus.ENGAGED
    for se, sp in zip(exact[last].slices, posted[last].slices):
        got, want = [(i.entry, i.exit) for i in sp.intervals], [(i.entry, i.exit) for i in se.intervals]
        assert len(got) == len(want)
        for (ge, gx), (we, wx) in zip(got, want):
            assert abs(ge - we) <= 0.05 and abs(gx - wx) <= 0.05
