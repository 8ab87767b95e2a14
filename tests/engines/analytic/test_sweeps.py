"""The analytic engine's sweep lower surfaces against brute force (dense t) and closed forms."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.analytic.sweeps import arc_row, brute_lower, line_row, sweep_lower
from fusioncut.model.tools import BallEndMill, BullNoseEndMill, ChamferMill, Drill, FlatEndMill, TaperedEndMill

TOOLS = {
    "flat": FlatEndMill(10, 20),
    "ball": BallEndMill(6, 20),
    "bullnose": BullNoseEndMill(10, 20, corner_radius=2),
    "tapered": TaperedEndMill(4, 20, taper_angle=10),
    "chamfer": ChamferMill(10, 20, taper_angle=45),
    "drill": Drill(6, 20),
}
N_BRUTE = 400_001
coord = st.floats(-8, 8, allow_nan=False)


@pytest.mark.parametrize("kind", TOOLS)
def test_lower_profile_matches_the_tool_outline(kind):
    """f is the tool's lowest point at each radius: radius_at(f(d)) = d inside the cutting part."""
    tool = TOOLS[kind]
    lp = lower_profile(tool)
    prof = tool.profile()
    for d in np.linspace(0.01, lp.radius - 0.01, 23):
        h = lp.f(d)
        if h > 1e-9:  # the flat bottom has no single radius at its height
            assert prof.radius_at(h) == pytest.approx(d, abs=1e-9)
            assert lp.rho(h) == pytest.approx(d, abs=1e-9)
    assert lp.rho(-1e-6) < 0  # below the tip: no tool


def _check(row, lp, px, py):
    L = sweep_lower(row, lp.pieces, lp.radius, px, py, 0.0)
    B = brute_lower(row, lp.pieces, lp.radius, px, py, N_BRUTE)
    if math.isinf(B):
        # the samples miss a footprint only at its very edge
        assert math.isinf(L) or abs(L - B) > 0
        return
    assert not math.isinf(L)
    assert L <= B + 1e-12  # the exact minimum is never above a sampled value
    # and the samples come within their step of it (slope x step; steep at a ball's rim)
    assert B - L <= 2e-3


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(sorted(TOOLS)), a=st.tuples(coord, coord, coord), b=st.tuples(coord, coord, coord),
       p=st.tuples(coord, coord))
def test_line_sweep_lower_surface_is_the_least_sampled_height(kind, a, b, p):
    lp = lower_profile(TOOLS[kind])
    _check(line_row(a, b, 0), lp, *p)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(sorted(TOOLS)), c=st.tuples(coord, coord), rho=st.floats(0.2, 8),
       a0=st.floats(-4, 4), sw=st.floats(-13, 13).filter(lambda v: abs(v) > 1e-3),
       z=st.tuples(coord, coord), p=st.tuples(coord, coord))
def test_arc_and_helix_sweep_lower_surface_is_the_least_sampled_height(kind, c, rho, a0, sw, z, p):
    lp = lower_profile(TOOLS[kind])
    start = (c[0] + rho * math.cos(a0), c[1] + rho * math.sin(a0), z[0])
    end = (c[0] + rho * math.cos(a0 + sw), c[1] + rho * math.sin(a0 + sw), z[1])
    _check(arc_row(start, end, c, rho, a0, sw, 0), lp, *p)


def test_ball_on_a_ramp_is_the_cylinder_about_the_centre_line():
    """A ball's centre moves on a line; inside the ramp's span the sweep's lower surface is the
    cylinder of radius R about that line: the lower root z of dist((x, y, z), line) = R."""
    R = 3.0
    lp = lower_profile(BallEndMill(2 * R, 20))
    a, b = np.array([-20.0, -3.0, 1.0]), np.array([25.0, 4.0, -2.5])
    row = line_row(a, b, 0)
    w = (b - a) / np.linalg.norm(b - a)
    c0 = a + [0, 0, R]
    rng = np.random.default_rng(7)
    for _ in range(200):
        t = rng.uniform(0.2, 0.8)
        off = rng.uniform(-0.95 * R, 0.95 * R)
        n = np.array([-(b - a)[1], (b - a)[0], 0.0])
        p = a + t * (b - a) + off * n / np.linalg.norm(n)
        # |(P - c0) - ((P - c0).w) w|^2 = R^2 with P = (px, py, z): quadratic in z
        e = np.array([0.0, 0.0, 1.0]) - w[2] * w
        g = np.array([p[0], p[1], 0.0]) - c0
        g = g - g.dot(w) * w
        qa, qb, qc = e.dot(e), 2 * e.dot(g), g.dot(g) - R * R
        z = (-qb - math.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)
        assert sweep_lower(row, lp.pieces, R, p[0], p[1], 0.0) == pytest.approx(z, abs=1e-12)


@pytest.mark.parametrize("kind", ["flat", "ball", "bullnose"])
def test_level_line_and_level_arc_closed_forms(kind):
    """Level moves: the lower surface at lateral distance y from the path is z + f(|y|)."""
    lp = lower_profile(TOOLS[kind])
    R = lp.radius
    line = line_row((-10.0, 2.0, -1.5), (10.0, 2.0, -1.5), 0)
    arc = arc_row((7.0, 0.0, -1.5), (-7.0, 0.0, -1.5), (0.0, 0.0), 7.0, 0.0, math.pi, 0)
    for y in np.linspace(-R + 1e-9, R - 1e-9, 41):
        assert sweep_lower(line, lp.pieces, R, 3.3, 2.0 + y, 0.0) == pytest.approx(-1.5 + lp.f(abs(y)), abs=1e-12)
        if abs(y) > R - 1e-6:
            continue  # at a ball's rim f' ~ 1e5: the arc's rounding of d (1e-15) is worth 1e-10 there
        ang = 1.1
        px, py = (7.0 + y) * math.cos(ang), (7.0 + y) * math.sin(ang)
        assert sweep_lower(arc, lp.pieces, R, px, py, 0.0) == pytest.approx(-1.5 + lp.f(abs(y)), abs=1e-11)
    # outside the footprint: nothing is removed; on its eps margin the edge's height holds
    assert math.isinf(sweep_lower(line, lp.pieces, R, 0.0, 2.0 + R + 1e-7, 0.0))
    assert sweep_lower(line, lp.pieces, R, 0.0, 2.0 + R + 1e-7, 1e-6) == pytest.approx(-1.5 + lp.f(R), abs=1e-12)


@pytest.mark.parametrize("sw, z", [(5.0, (0.0, -3.0)), (-9.0, (-1.0, 2.0)), (2 * math.pi, (0.5, -0.5))])
def test_flat_end_mill_helix_is_lowest_at_a_window_end(sw, z):
    """A flat end mill's helix (and a wider shank's, swept as one): its lower surface, taken at a
    window's end in closed form, is the sampled one's to the samples' rise per step."""
    lp = lower_profile(FlatEndMill(5, 20))
    c, rho, a0 = (1.0, -2.0), 4.0, 0.3
    start = (c[0] + rho * math.cos(a0), c[1] + rho * math.sin(a0), z[0])
    end = (c[0] + rho * math.cos(a0 + sw), c[1] + rho * math.sin(a0 + sw), z[1])
    row = arc_row(start, end, c, rho, a0, sw, 0)
    rng = np.random.default_rng(7)
    seen = 0
    for px, py in rng.uniform(-8, 10, (200, 2)):
        L = sweep_lower(row, lp.pieces, lp.radius, px, py, 0.0)
        B = brute_lower(row, lp.pieces, lp.radius, px, py, N_BRUTE)
        if math.isinf(B) or math.isinf(L):
            continue
        seen += 1
        assert B - 3.0 / N_BRUTE * 1.0001 <= L <= B + 1e-12
    assert seen > 60


@pytest.mark.parametrize("kind", ["ball", "bullnose", "tapered"])
@pytest.mark.parametrize("rho, sw, z", [(4.0, 5.0, (0.0, -3.0)), (2.0, -9.0, (-1.0, 2.0)), (6.0, 2 * math.pi, (0.5, -0.5)),
                                        (1.0, 12.0, (0.0, -6.0)), (2.0, -17.3, (0.5, -1.25))])
def test_helix_lower_surface_to_the_refined_samples(kind, rho, sw, z):
    """A helix: minimised from its slope where a window is provably convex, bounded on its far parts
    (a round tool round a point nearer the axis than R - rho), sampled elsewhere, on one turn of a longer
    helix; against samples refined about their least, to 1e-9 mm, at points all over its reach and near
    its axis."""
    lp = lower_profile(TOOLS[kind])
    c, a0 = (1.0, -2.0), 0.3
    start = (c[0] + rho * math.cos(a0), c[1] + rho * math.sin(a0), z[0])
    end = (c[0] + rho * math.cos(a0 + sw), c[1] + rho * math.sin(a0 + sw), z[1])
    row = arc_row(start, end, c, rho, a0, sw, 0)
    rng = np.random.default_rng(11)
    seen = 0
    reach = rho + lp.radius + 0.5
    near_axis = rng.uniform(-0.5 * rho, 0.5 * rho, (20, 2))
    for px, py in np.vstack([rng.uniform(-reach, reach, (60, 2)), near_axis]) + np.array(c):
        L = sweep_lower(row, lp.pieces, lp.radius, px, py, 0.0)
        B = brute_lower(row, lp.pieces, lp.radius, px, py, 100_001, refine=2)
        if math.isinf(B) or math.isinf(L):
            continue
        seen += 1
        assert L == pytest.approx(B, abs=1e-9)
    assert seen > 20


def test_flat_end_mill_arc_depth_closed_form_against_the_sampled_one():
    """A flat end mill's arc_depth is the least XY distance to the path's positions at or below the
    point less R (or that to those above plus 1): the same sign and, where it is below 0.5 mm, the
    same value (1e-6) as the sampled and refined minimum another tool gets, on arcs and helices up
    and down, and never above it; exactly -R at a position's own tip height and centre."""
    from fusioncut.engines.analytic.sweeps import _window_min, arc_depth

    P = lower_profile(FlatEndMill(6, 20)).pieces
    rng = np.random.default_rng(7)
    for i in range(2000):
        rho, a0, sw = rng.uniform(0.2, 8), rng.uniform(-4, 4), rng.uniform(-8, 8)
        z0 = rng.uniform(-3, 0)
        z1 = z0 + (0.0 if i % 3 == 0 else rng.uniform(-3, 3))
        c = (rng.uniform(-2, 2), rng.uniform(-2, 2))
        S = arc_row((c[0] + rho * math.cos(a0), c[1] + rho * math.sin(a0), z0),
                    (c[0] + rho * math.cos(a0 + sw), c[1] + rho * math.sin(a0 + sw), z1), c, rho, a0, sw, 0)
        p = (rng.uniform(-12, 12), rng.uniform(-12, 12), rng.uniform(-4, 1))
        exact, sampled = arc_depth(S, P, 3.0, *p), _window_min(1, S, P, 3.0, *p, 0.0, 1.0)
        assert (exact < -1e-9) == (sampled < -1e-9)
        assert exact <= sampled + 1e-12
        if exact < 0.5:
            assert exact == pytest.approx(sampled, abs=1e-6)
    S = arc_row((5.0, 0.0, -1.0), (0.0, 5.0, -2.0), (0.0, 0.0), 5.0, 0.0, math.pi / 2, 0)
    mid = (5 * math.sqrt(0.5), 5 * math.sqrt(0.5), -1.5)
    assert arc_depth(S, P, 3.0, *mid) == pytest.approx(-3.0, abs=1e-12)
    assert arc_depth(S, P, 3.0, mid[0], mid[1], -2.5) == pytest.approx(1.0, abs=1e-12)  # below every tip


def _corner_radius_at(r0, rc):
    """rho(h) of a flat bottom of radius r0 with a quarter round of radius rc outside it, straight up after."""
    return lambda h: np.where(h < rc, r0 + np.sqrt(np.clip(rc * rc - (rc - h) ** 2, 0.0, None)), r0 + rc)


_OUTLINE_RADIUS = {  # the tools' cross-section radius at a height above the tip, from their dimensions
    "ball": lambda t: _corner_radius_at(0.0, t.diameter / 2),
    "bullnose": lambda t: _corner_radius_at(t.diameter / 2 - t.corner_radius, t.corner_radius),
    "tapered": lambda t: lambda h: np.interp(h, [0.0, t.flute_length], [t.diameter / 2, t.diameter / 2 + t.flute_length
                                                                          * math.tan(math.radians(t.taper_angle))]),
}


def _dense_phi_min(S, radius_at, px, py, pz, n=200_001):
    """min over n even t of |p - c(t)| - rho(pz - z(t)) on an arc sweep, rho from the tool's outline
    (-1 below the tip): the oracle of arc_holds, sampled finely enough that its error (<= the step
    times the slope) stays far below the band the test leaves out."""
    t = np.linspace(0.0, 1.0, n)
    a = S[10] + t * S[11]
    d = np.hypot(S[7] + S[9] * np.cos(a) - px, S[8] + S[9] * np.sin(a) - py)
    h = pz - (S[3] + t * (S[6] - S[3]))
    return float(np.min(d - np.where(h < 0, -1.0, radius_at(np.maximum(h, 0.0)))))


@pytest.mark.parametrize("kind", ["ball", "bullnose", "tapered"])
def test_arc_holds_against_the_dense_minimum(kind):
    """Whether a point lies inside the tool at some position of an arc or helix (one or several
    turns, up, down, level): arc_holds against a dense minimum of |p - c(t)| - rho over t from the
    tool's own outline, on points within reach; those within 1e-4 mm of the answer's edge are left
    out (the oracle's step). Ball and bull-nose are decided from the convex gap d^2 - rho^2, the
    tapered mill (a cone: rho^2 convex) by sampling."""
    from fusioncut.engines.analytic.sweeps import arc_holds

    tool = TOOLS[kind]
    lp = lower_profile(tool)
    R = lp.radius
    radius_at = _OUTLINE_RADIUS[kind](tool)
    rng = np.random.default_rng(11)
    decided = inside = 0
    for i in range(300):
        rho, a0, sw = rng.uniform(0.5, 12), rng.uniform(-4, 4), rng.choice([-1, 1]) * rng.uniform(0.3, 14)
        z0 = rng.uniform(-3, 0)
        z1 = z0 + (0.0 if i % 4 == 0 else rng.uniform(-4, 4))
        c = (rng.uniform(-2, 2), rng.uniform(-2, 2))
        S = arc_row((c[0] + rho * math.cos(a0), c[1] + rho * math.sin(a0), z0),
                    (c[0] + rho * math.cos(a0 + sw), c[1] + rho * math.sin(a0 + sw), z1), c, rho, a0, sw, 0)
        for _ in range(6):
            ang, off = rng.uniform(0, 2 * math.pi), rng.uniform(-R, R)
            p = (c[0] + (rho + off) * math.cos(ang), c[1] + (rho + off) * math.sin(ang),
                 rng.uniform(min(z0, z1) - 0.5, max(z0, z1) + R))
            want = _dense_phi_min(S, radius_at, *p)
            if abs(want) < 1e-4:
                continue
            decided += 1
            inside += want < 0
            assert arc_holds(S, lp.pieces, R, *p, 1e-9) == (want < 0), (i, p, want)
    assert decided > 1500 and 0.2 * decided < inside < 0.8 * decided
