"""Chatter stability: directional factors against Altintas's closed forms, ZOA against the 1-DOF closed
form and an independent solution of the characteristic equation, SD against the exact boundary of a
constant-coefficient delay equation and against ZOA for a slot, and SD's convergence with its steps.

The 1-DOF system is the milling benchmark of Insperger & Stepan (2002, 2004): fn = 922 Hz, zeta = 0.011,
modal mass 0.03993 kg, Kt = 6e8 N/m², Kn = 2e8 N/m² (Kr = 1/3), 2 flutes.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from fusioncut.analysis.dynamics import Mode, ToolDynamics
from fusioncut.analysis.forces import CuttingCoefficients
from fusioncut.analysis.stability import (ModalSystem, chatter_grid, cl_directional, sd_a_lim, sd_spectral_radius,
                                          zoa_a_lim, zoa_lobes)
from fusioncut.errors import GeometryError
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement, SpindleDirection

FN, ZETA, MASS = 922.0, 0.011, 0.03993
K = MASS * (2 * math.pi * FN) ** 2
KTC, KR = 600.0, 1.0 / 3.0  # N/mm²
COEF = CuttingCoefficients(KTC, KR * KTC, 0.0, 0.0, 0.0, 0.0)
BENCH_X = ToolDynamics((Mode(FN, ZETA, K),), ())


def emap(intervals, depth: float = 1.0, slices: int = 1, feed_angle: float = 0.0,
         spindle: SpindleDirection = SpindleDirection.CW, status: CLStatus = CLStatus.ENGAGED) -> EngagementMap:
    """A CL whose ``slices`` slices of height depth / slices all have ``intervals`` (immersion, deg)."""
    sl = tuple(SliceEngagement((i + 0.5) * depth / slices, 0.0, 5.0, tuple(AngleInterval(a, b) for a, b in intervals))
               for i in range(slices))
    return EngagementMap(0, (1, 0, 0), (0, 0, 0), "T1", spindle, feed_angle, status, feed=1.0, slices=sl,
                         axial_range=(0.0, depth))


def tool(flutes: int = 2, helix: float = 0.0) -> FlatEndMill:
    return FlatEndMill(diameter=10.0, flute_length=20.0, flutes=flutes, helix_angle=helix)


def altintas_alpha(st: float, ex: float, kr: float) -> np.ndarray:
    """Altintas (2012) eq. 3.xx: the directional factors integrated from st to ex (rad)."""
    def prim(p: float) -> np.ndarray:
        return 0.5 * np.array([[math.cos(2 * p) - 2 * kr * p + kr * math.sin(2 * p),
                                -math.sin(2 * p) - 2 * p + kr * math.cos(2 * p)],
                               [-math.sin(2 * p) + 2 * p + kr * math.cos(2 * p),
                                -math.cos(2 * p) - 2 * kr * p - kr * math.sin(2 * p)]])
    return prim(ex) - prim(st)


def test_directional_factors_closed_forms() -> None:
    slot = cl_directional(emap([(0, 180)]), tool(), COEF, dz=1.0).alpha0
    assert slot == pytest.approx(np.array([[-KR * math.pi, -math.pi], [math.pi, -KR * math.pi]]), abs=1e-12)
    # half-immersion down-milling: alpha_xx = 1 - Kr pi / 2 (hand-derived from the primitive)
    half = cl_directional(emap([(90, 180)]), tool(), COEF, dz=1.0).alpha0
    assert half[0, 0] == pytest.approx(1 - KR * math.pi / 2, abs=1e-12)
    assert half == pytest.approx(altintas_alpha(math.pi / 2, math.pi, KR), abs=1e-12)
    # up-milling at ae = 2.1 mm of R 5, the exit angle written with 4 decimals as a post would
    ex = round(math.degrees(math.acos(1 - 2.1 / 5.0)), 4)
    up = cl_directional(emap([(0.0, ex)]), tool(), COEF, dz=1.0).alpha0
    assert up == pytest.approx(altintas_alpha(0.0, math.radians(ex), KR), abs=1e-12)
    # depth-weighted: a CL of 3 mm, 2 mm slot and 1 mm half immersion, has the mean factors
    sl = (SliceEngagement(0.5, 0, 5, (AngleInterval(0, 180),)), SliceEngagement(1.5, 0, 5, (AngleInterval(0, 180),)),
          SliceEngagement(2.5, 0, 5, (AngleInterval(90, 180),)))
    mixed = EngagementMap(0, (1, 0, 0), (0, 0, 0), "T1", SpindleDirection.CW, 0.0, CLStatus.ENGAGED, feed=1.0,
                          slices=sl, axial_range=(0.0, 3.0))
    cd = cl_directional(mixed, tool(), COEF, dz=1.0)
    assert cd.ap == 3.0 and cd.alpha0 == pytest.approx((2 * slot + half) / 3, abs=1e-12)
    # two arcs in one slice add up
    two = cl_directional(emap([(0, 45), (120, 180)]), tool(), COEF, dz=1.0).alpha0
    want = altintas_alpha(0, math.pi / 4, KR) + altintas_alpha(2 * math.pi / 3, math.pi, KR)
    assert two == pytest.approx(want, abs=1e-12)
    # machine frame: feeding along +Y turns the matrix by 90 deg; an M4 spindle mirrors y
    turned = cl_directional(emap([(90, 180)], feed_angle=90.0), tool(), COEF, dz=1.0).alpha0
    rot = np.array([[0.0, -1.0], [1.0, 0.0]])
    assert turned == pytest.approx(rot @ half @ rot.T, abs=1e-12)
    m4 = cl_directional(emap([(90, 180)], spindle=SpindleDirection.CCW), tool(), COEF, dz=1.0).alpha0
    mir = np.diag([1.0, -1.0])
    assert m4 == pytest.approx(mir @ half @ mir, abs=1e-12)
    with pytest.raises(GeometryError):
        cl_directional(emap([(0, 180)], status=CLStatus.FAILED), tool(), COEF)


def characteristic_roots(alpha_xx: float, rpm: float, flutes: int) -> float:
    """Independent 1-DOF ZOA limit (mm): smallest real a > 0 solving
    1 - N Kt a alpha_xx Phi(i w) (1 - exp(-i w T)) / (4 pi) = 0, by scanning w."""
    w = 2 * math.pi * np.linspace(0.5 * FN, 2.0 * FN, 200_001)
    t = 60.0 / (flutes * rpm)
    f = BENCH_X.receptance("x", w) * (1 - np.exp(-1j * w * t))
    s = np.flatnonzero(np.sign(f.imag[:-1]) != np.sign(f.imag[1:]))
    frac = f.imag[s] / (f.imag[s] - f.imag[s + 1])
    re = f.real[s] + frac * (f.real[s + 1] - f.real[s])
    a = 4 * math.pi / (flutes * KTC * 1e6 * alpha_xx * re) * 1e3
    return float(a[a > 0].min())


def test_zoa_one_dof_closed_form() -> None:
    cd = cl_directional(emap([(0, 180)]), tool(), COEF, dz=1.0)
    grid = chatter_grid(BENCH_X)
    # lowest point of the lobes: a = 2 pi / (N Kt alpha_xx G_min), G_min = -1 / (4 k zeta (1 + zeta))
    a_min = 2 * math.pi / (2 * KTC * 1e6 * cd.alpha0[0, 0] * (-1 / (4 * K * ZETA * (1 + ZETA)))) * 1e3
    rpm, lobes = zoa_lobes(cd.alpha0, grid, KTC, 2, 3000.0, 30000.0, 800)
    assert lobes.min() == pytest.approx(a_min, rel=2e-3) and lobes.min() >= a_min * (1 - 1e-9)
    speeds = np.array([3100.0, 4700.0, 8000.0, 12500.0, 19000.0, 26000.0])
    got = zoa_a_lim(cd.alpha0, grid, KTC, 2, speeds)
    want = [characteristic_roots(cd.alpha0[0, 0], n, 2) for n in speeds]
    assert got == pytest.approx(want, rel=5e-4)


def test_zoa_frame_invariance() -> None:
    """x-only dynamics fed along +Y cut like y-only dynamics fed along +X; symmetric dynamics do not care
    about the spindle sense."""
    bench_y = ToolDynamics((), BENCH_X.x)
    speeds = np.linspace(4000.0, 25000.0, 15)
    a = cl_directional(emap([(20, 150)], feed_angle=90.0), tool(), COEF, dz=1.0)
    b = cl_directional(emap([(20, 150)], feed_angle=0.0), tool(), COEF, dz=1.0)
    lim_a = zoa_a_lim(a.alpha0, chatter_grid(BENCH_X), KTC, 2, speeds)
    lim_b = zoa_a_lim(b.alpha0, chatter_grid(bench_y), KTC, 2, speeds)
    assert np.all(np.isfinite(lim_a)) and lim_a == pytest.approx(lim_b, rel=1e-12)
    sym = ToolDynamics(BENCH_X.x, BENCH_X.x)
    m4 = cl_directional(emap([(20, 150)], spindle=SpindleDirection.CCW, feed_angle=33.0), tool(), COEF, dz=1.0)
    m3 = cl_directional(emap([(20, 150)], feed_angle=33.0), tool(), COEF, dz=1.0)
    g = chatter_grid(sym)
    assert zoa_a_lim(m4.alpha0, g, KTC, 2, speeds) == pytest.approx(zoa_a_lim(m3.alpha0, g, KTC, 2, speeds), rel=1e-9)
    air = cl_directional(emap([]), tool(), COEF, dz=1.0)
    assert not air.engaged and np.isinf(zoa_a_lim(air.alpha0, g, KTC, 2, speeds)).all()
    assert np.isinf(sd_a_lim(air, ModalSystem.from_dynamics(sym), KTC, speeds, 1.0)).all()


def test_sd_free_vibration_is_exact() -> None:
    """At zero depth the monodromy's eigenvalues are those of the damped oscillator over one tooth
    period, modulus exp(-zeta wn T) (the delayed states give zeros)."""
    cd = cl_directional(emap([(0, 180)]), tool(), COEF, dz=1.0)
    system = ModalSystem.from_dynamics(BENCH_X)
    for rpm in (5000.0, 17000.0):
        rho = sd_spectral_radius(cd, system, KTC, rpm, 0.0, steps=20)[0]
        assert rho == pytest.approx(math.exp(-ZETA * 2 * math.pi * FN * 60 / (2 * rpm)), rel=1e-9)


def _bisect_constant(cd, system, rpm: float, b: np.ndarray, steps: int) -> float:
    lo, hi = 0.01, 5.0
    for _ in range(40):
        mid = math.sqrt(lo * hi)
        if sd_spectral_radius(cd, system, KTC, rpm, mid, steps=steps, b_steps=b)[0] >= 1:
            hi = mid
        else:
            lo = mid
    return math.sqrt(lo * hi)


def test_sd_converges_to_the_exact_boundary_of_a_constant_delay_equation() -> None:
    """With a constant directional factor the milling equation is the autonomous delay equation
    m x'' + c x' + k x = (a Kt / 2) b (x(t) - x(t - T)), whose boundary ZOA gives exactly (alpha = 2 pi b / N):
    SD must converge to it as its steps grow."""
    cd = cl_directional(emap([(0, 180)]), tool(), COEF, dz=1.0)
    system = ModalSystem.from_dynamics(BENCH_X)
    bxx = -0.4
    alpha = np.array([[2 * math.pi * bxx / 2, 0.0], [0.0, 0.0]])
    grid = chatter_grid(BENCH_X)
    for rpm in (9000.0, 21000.0):
        exact = zoa_a_lim(alpha, grid, KTC, 2, rpm)[0]
        errors = []
        for steps in (20, 40, 80):
            b = np.broadcast_to(np.array([[bxx, 0.0], [0.0, 0.0]]), (steps, 2, 2))
            errors.append(abs(_bisect_constant(cd, system, rpm, b, steps) / exact - 1))
        # second order: each doubling of the steps divides the error by about 4
        assert errors[0] / errors[1] > 3 and errors[1] / errors[2] > 3 and errors[2] < 5e-3, errors


def test_sd_against_zoa_for_a_slot_and_its_convergence() -> None:
    """A 4-flute, 30 deg helix slot (directional factor nearly constant): SD and ZOA within 10 %; the
    2-flute straight slot of the benchmark: SD's limit settles as its steps grow."""
    system = ModalSystem.from_dynamics(BENCH_X)
    grid = chatter_grid(BENCH_X)
    speeds = np.array([5000.0, 9000.0, 14000.0, 20000.0])
    cd4 = cl_directional(emap([(0, 180)], depth=3.0, slices=6), tool(4, 30.0), COEF, dz=0.5)
    zoa = zoa_a_lim(cd4.alpha0, grid, KTC, 4, speeds)
    sd = sd_a_lim(cd4, system, KTC, speeds, zoa)
    assert np.all(np.isfinite(sd)) and sd == pytest.approx(zoa, rel=0.1)
    cd2 = cl_directional(emap([(0, 180)]), tool(2), COEF, dz=1.0)
    ref = zoa_a_lim(cd2.alpha0, grid, KTC, 2, 12000.0)
    lims = [sd_a_lim(cd2, system, KTC, 12000.0, ref, steps=s, per_vibration=0)[0] for s in (20, 40, 80)]
    gaps = np.abs(np.diff(lims))
    assert gaps[1] < 0.5 * gaps[0] and gaps[1] < 0.015 * lims[-1], lims
