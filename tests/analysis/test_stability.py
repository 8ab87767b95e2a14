"""Chatter stability: directional factors against Altintas's closed forms, ZOA against the 1-DOF closed
form and an independent solution of the characteristic equation, SD against the exact boundary of a
constant-coefficient delay equation and against ZOA for a slot, and SD's convergence with its steps.

The 1-DOF system is the milling benchmark of Insperger & Stepan (2002, 2004): fn = 922 Hz, zeta = 0.011,
modal mass 0.03993 kg, Kt = 6e8 N/m², Kn = 2e8 N/m² (Kr = 1/3), 2 flutes.
"""
from __future__ import annotations

import math
from dataclasses import replace as dataclasses_replace
from pathlib import Path

import numpy as np
import pytest

from fusioncut.analysis.dynamics import Mode, ToolDynamics
from fusioncut.analysis.forces import CuttingCoefficients
from fusioncut.analysis.stability import (ModalSystem, chatter_grid, cl_directional, nearest_stable_rpm, sd_a_lim,
                                          sd_spectral_radius, zoa_a_lim, zoa_lobes)
from fusioncut.analysis.stability_table import STABILITY_COLUMNS
from fusioncut.errors import GeometryError
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement, SpindleDirection
from test_forces_real_program import PROGRAM, run  # noqa: F401  (the fixture: one engine run of a real program)

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
    # on a ball the band [1, 2] mm runs from radius 3 to 4 mm: lead angle 45 deg, Kr = (Krc - Kac) / (sqrt 2 Ktc)
    from fusioncut.analysis.materials import AL7075_T6_CARBIDE as AL
    from fusioncut.model import BallEndMill

    ball = EngagementMap(0, (1, 0, 0), (0, 0, 0), "T2", SpindleDirection.CW, 0.0, CLStatus.ENGAGED, feed=1.0,
                         slices=(SliceEngagement(1.5, 0.0, 3.5, (AngleInterval(90, 180),)),), axial_range=(1.0, 2.0))
    got = cl_directional(ball, BallEndMill(diameter=10.0, flute_length=20.0), AL, dz=1.0).alpha0
    assert got == pytest.approx(altintas_alpha(math.pi / 2, math.pi, (AL.krc - AL.kac) / (math.sqrt(2) * AL.ktc)),
                                abs=1e-12)


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


def test_zoa_many_cls_equal_one_at_a_time() -> None:
    """The compiled pass over many CLs (each at its own speed) gives each CL's zoa_a_lim, and the real
    arithmetic of the curves equals the eigenvalues of Phi alpha0 computed by LAPACK."""
    from fusioncut.analysis.stability import zoa_a_lim_many, zoa_curves

    rng = np.random.default_rng(5)
    dyn = ToolDynamics((Mode(600.0, 0.035, 5.6e6), Mode(1450.0, 0.02, 1.4e7)), (Mode(660.0, 0.03, 5.7e6),))
    grid = chatter_grid(dyn)
    alphas = rng.normal(0.0, 2.0, (40, 2, 2))
    speeds = rng.uniform(2000.0, 30000.0, 40)
    many = zoa_a_lim_many(alphas, grid, KTC, 3, speeds)
    one = np.array([zoa_a_lim(a, grid, KTC, 3, n)[0] for a, n in zip(alphas, speeds)])
    assert np.isfinite(one).sum() > 30
    np.testing.assert_allclose(many, one, rtol=1e-12)
    lam = np.linalg.eigvals(grid.phi @ alphas[0])
    a, _ = zoa_curves(alphas[0], grid, KTC, 3)
    re = 2e3 * math.pi / (3 * KTC * 1e6) / a  # Re lambda where positive
    want = np.sort(lam.real, axis=1)
    both = np.isfinite(re).all(axis=1)
    np.testing.assert_allclose(np.sort(re[both], axis=1), want[both], rtol=1e-9, atol=1e-12 * np.abs(want).max())


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


def _full_monodromy_radius(cd, system, rpm: float, a_mm: float, steps: int) -> float:
    """Reference SD: every modal coordinate kept as a delayed state (2 n + steps n), each interval's
    matrices from the exponential of Van Loan's augmented generator [[A, I, 0], [0, 0, I], [0, 0, 0]] dt
    by a plain Taylor series with scaling and squaring, the monodromy matrix built as a product."""
    from fusioncut.analysis.stability import _step_matrices

    def expm(x: np.ndarray) -> np.ndarray:
        s = max(0, math.ceil(math.log2(max(np.abs(x).sum(axis=0).max(), 1e-300) / 0.25)))
        y, term, out = x / 2.0 ** s, np.eye(len(x)), np.eye(len(x))
        for k in range(1, 30):
            term = term @ y / k
            out = out + term
        for _ in range(s):
            out = out @ out
        return out

    n, m = len(system.m), steps
    b = _step_matrices(cd, steps, 8)
    dt = 60.0 / (cd.flutes * rpm) / m
    dim = 2 * n + m * n
    z = np.eye(dim)
    for i in range(m):
        w = 0.5 * KTC * 1e6 * system.p.T @ b[i] @ system.p * a_mm * 1e-3 / system.m[:, None]
        a = np.zeros((2 * n, 2 * n))
        a[:n, n:] = np.eye(n)
        a[n:, :n] = -np.diag(system.k / system.m) + w
        a[n:, n:] = -np.diag(system.c / system.m)
        gen = np.zeros((6 * n, 6 * n))
        gen[:2 * n, :2 * n], gen[:2 * n, 2 * n:4 * n], gen[2 * n:4 * n, 4 * n:] = a, np.eye(2 * n), np.eye(2 * n)
        e = expm(gen * dt)
        phi0, phi1, phi2 = e[:2 * n, :2 * n], e[:2 * n, 2 * n:4 * n], e[:2 * n, 4 * n:] / dt
        step = np.zeros((dim, dim))
        step[:2 * n, :2 * n] = phi0
        step[:2 * n, 2 * n + (m - 1) * n:] = (phi1 - phi2)[:, n:] @ -w        # q(t_i - T)
        newer = (2 * n + (m - 2) * n) if m > 1 else 0
        step[:2 * n, newer:newer + n] += phi2[:, n:] @ -w                      # q(t_i - T + dt)
        step[2 * n:3 * n, :n] = np.eye(n)
        step[3 * n:, 2 * n:2 * n + (m - 1) * n] = np.eye((m - 1) * n)
        z = step @ z
    return float(np.abs(np.linalg.eigvals(z)).max())


def test_sd_equals_a_reference_keeping_every_modal_coordinate() -> None:
    """Three modes in two directions (docs' example) on a 30 deg helix half-immersion cut: the monodromy
    that keeps only the delayed displacement along x and y, with its interval integrals from Taylor
    series and interval doubling, has the spectral radius of the plain construction."""
    dyn = ToolDynamics((Mode(600.0, 0.035, 5.6e6), Mode(1450.0, 0.02, 1.4e7)), (Mode(660.0, 0.03, 5.7e6),))
    system = ModalSystem.from_dynamics(dyn)
    cd = cl_directional(emap([(90, 180)], depth=2.0, slices=4), tool(3, 30.0), COEF, dz=0.5)
    for rpm, a in ((6000.0, 0.5), (11000.0, 1.5), (17000.0, 3.0)):
        got = sd_spectral_radius(cd, system, KTC, rpm, a, steps=12)[0]
        assert got == pytest.approx(_full_monodromy_radius(cd, system, rpm, a, 12), rel=1e-9), (rpm, a)


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


def test_zoa_of_coupled_modes_is_the_exact_boundary_sd_converges_to() -> None:
    """Modes in x and y (two in x, one in y: docs/stability_modes_example.json) coupled by a constant
    directional matrix with cross terms (a slot's mean, b = N/2 [[-Kr, -1], [1, -Kr]]): the milling
    equation is then the autonomous delay equation whose boundary the ZOA eigenvalue problem gives exactly
    (alpha0 = 2 pi b / N), so SD, a time-domain method sharing nothing with it but the modes, must
    converge to ZOA's limit at second order. This stands in for the two-mode example of Altintas's
    Manufacturing Automation, whose tabulated numbers are not at hand."""
    dyn = ToolDynamics((Mode(600.0, 0.035, 5.6e6), Mode(1450.0, 0.02, 1.4e7)), (Mode(660.0, 0.03, 5.7e6),))
    system = ModalSystem.from_dynamics(dyn)
    grid = chatter_grid(dyn)
    b = np.array([[-KR, -1.0], [1.0, -KR]])  # N = 2
    cd = cl_directional(emap([(0, 180)]), tool(), COEF, dz=1.0)
    for rpm in (7000.0, 16000.0):
        exact = zoa_a_lim(2 * math.pi * b / 2, grid, KTC, 2, rpm)[0]
        assert 0.01 < exact < 5.0
        errors = []
        for steps in (20, 40, 80):
            bs = np.broadcast_to(b, (steps, 2, 2))
            errors.append(abs(_bisect_constant(cd, system, rpm, bs, steps) / exact - 1))
        assert errors[0] / errors[1] > 3 and errors[1] / errors[2] > 3 and errors[2] < 5e-3, (rpm, errors)


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


def test_sd_finds_the_flip_lobes_zoa_misses() -> None:
    """Down-milling at a/D = 0.05 on the benchmark (Insperger, Mann, Stepan & Bayly, Int. J. Mach. Tools
    Manuf. 43 (2003) 25-34, describe this picture): at 16000 rev/min SD loses stability well below ZOA's
    limit through a real multiplier -1 (period doubling, which ZOA's averaged model cannot show); at
    24000 rev/min through a complex pair (secondary Hopf) with SD and ZOA within 2 %."""
    from fusioncut.analysis.stability import sd_critical_multiplier

    system = ModalSystem.from_dynamics(BENCH_X)
    grid = chatter_grid(BENCH_X)
    entry = round(180.0 - math.degrees(math.acos(1 - 2 * 0.05)), 4)
    cd = cl_directional(emap([(entry, 180.0)]), tool(2), COEF, dz=1.0)
    for rpm, flip in ((16000.0, True), (24000.0, False)):
        zoa = zoa_a_lim(cd.alpha0, grid, KTC, 2, rpm)[0]
        sd = sd_a_lim(cd, system, KTC, rpm, zoa, steps=30, per_vibration=0)[0]
        above = sd_critical_multiplier(cd, system, KTC, rpm, 1.002 * sd, steps=30)
        below = sd_critical_multiplier(cd, system, KTC, rpm, 0.998 * sd, steps=30)
        assert abs(above) > 1 > abs(below)
        if flip:
            assert sd < 0.6 * zoa and above.real < -1 and abs(above.imag) < 1e-9
        else:
            assert sd == pytest.approx(zoa, rel=0.02) and abs(above.imag) > 0.1


def test_sd_not_computed_beyond_its_step_limit() -> None:
    """At 3000 rev/min a tooth period holds 9.2 periods of the 922 Hz mode: 12 steps each need 120 > 60
    steps, so no SD limit (NaN) and the table's margin is ZOA's; at 20000 rev/min 30 steps suffice."""
    from fusioncut.analysis.stability_table import stability_table

    cd = cl_directional(emap([(0, 180)]), tool(), COEF, dz=1.0)
    system = ModalSystem.from_dynamics(BENCH_X)
    lim = sd_a_lim(cd, system, KTC, [3000.0, 20000.0], 1.0, max_steps=60)
    assert math.isnan(lim[0]) and np.isfinite(lim[1])
    t = stability_table([emap([(0, 180)])], tool(), COEF, BENCH_X, [3000.0], dz=1.0, sd_max_steps=60)
    zoa = zoa_a_lim(cd.alpha0, chatter_grid(BENCH_X), KTC, 2, 3000.0)[0]
    assert math.isnan(t.loc[0, "a_lim_sd_mm"]) and t.loc[0, "margin"] == pytest.approx(1.0 / zoa, rel=1e-12)


def test_table_shares_only_equal_computations() -> None:
    """A slot's mean factors do not change with the feed direction, its time-varying ones do (3 flutes:
    turning the frame is no time shift): with modes along x only, slots along X and along Y have one ZOA
    limit and two SD limits, each the direct one."""
    from fusioncut.analysis.stability_table import stability_table

    maps = [emap([(0, 180)], feed_angle=0.0), emap([(0, 180)], feed_angle=90.0)]
    t = stability_table(maps, tool(3), COEF, BENCH_X, [14000.0, 14000.0], dz=1.0)
    system = ModalSystem.from_dynamics(BENCH_X)
    grid = chatter_grid(BENCH_X)
    direct = []
    for m in maps:
        cd = cl_directional(m, tool(3), COEF, dz=1.0)
        direct.append(sd_a_lim(cd, system, KTC, 14000.0, zoa_a_lim(cd.alpha0, grid, KTC, 3, 14000.0))[0])
    assert t.loc[0, "a_lim_zoa_mm"] == pytest.approx(t.loc[1, "a_lim_zoa_mm"], rel=1e-12)
    assert abs(direct[0] / direct[1] - 1) > 0.01
    assert list(t["a_lim_sd_mm"]) == pytest.approx(direct, rel=1e-12)


# --------------------------------------------------------------------------------------------------
# nearest stable speed, a whole results directory and the command


def test_nearest_stable_speed_is_the_nearest() -> None:
    """Between the CL's speed and the speed returned every speed is unstable; there it is stable."""
    cd = cl_directional(emap([(0, 180)]), tool(), COEF, dz=1.0)
    grid = chatter_grid(BENCH_X)
    ap = 0.5
    for rpm in (5000.0, 10000.0, 16000.0):
        lim = zoa_a_lim(cd.alpha0, grid, KTC, 2, rpm)[0]
        assert lim < ap  # unstable where we start
        near = nearest_stable_rpm(cd.alpha0, grid, KTC, 2, rpm, ap, 0.5 * rpm, 1.5 * rpm)
        assert zoa_a_lim(cd.alpha0, grid, KTC, 2, near)[0] > ap
        between = np.linspace(rpm, rpm + (near - rpm) * (1 - 1e-5), 300)
        assert np.all(zoa_a_lim(cd.alpha0, grid, KTC, 2, between) <= ap)
        other = np.linspace(rpm, rpm - (near - rpm), 300)  # the other side is no nearer
        assert np.all(zoa_a_lim(cd.alpha0, grid, KTC, 2, other[:-1]) <= ap)
    # stable: the speed itself; nothing stable in the range: NaN
    assert nearest_stable_rpm(cd.alpha0, grid, KTC, 2, 9300.0, 0.1, 5000.0, 15000.0) == 9300.0
    assert math.isnan(nearest_stable_rpm(cd.alpha0, grid, KTC, 2, 9300.0, 50.0, 5000.0, 15000.0))


def _results(out):
    """A results directory: a 2 mm slot, a 2 mm half-immersion cut, air and a rapid (10 mm flat mill)."""
    from fusioncut.errors import SourceLocation
    from fusioncut.io.results import ResultWriter

    def cl(i, intervals, status=CLStatus.ENGAGED, feed=600.0):
        sl = tuple(SliceEngagement(0.25 + 0.5 * k, -2.0 + 0.25 + 0.5 * k, 5.0,
                                   tuple(AngleInterval(a, b) for a, b in intervals)) for k in range(4))
        return EngagementMap(i, (i + 1.0, 0, -2.0), (float(i), 0, -2.0), "T1", SpindleDirection.CW, 0.0, status,
                             source=SourceLocation("prog.nc", 10 + i), feed=feed, operation="op",
                             slices=sl if intervals else (), axial_range=(0.0, 2.0) if intervals else (0.0, 0.0))

    maps = [cl(0, [(0.0, 180.0)]), cl(1, [(90.0, 180.0)]), cl(2, [], CLStatus.AIR), cl(3, [], CLStatus.RAPID, None)]
    with ResultWriter(out, tools={"T1": {"kind": "flat", "diameter_mm": 10.0, "flute_length_mm": 20.0}}) as w:
        for m in maps:
            w.add(m, length_mm=1.0)
    return maps


def test_stability_command(tmp_path) -> None:
    import json

    import matplotlib.image as mpimg
    import pandas as pd
    import typer
    from typer.testing import CliRunner

    from fusioncut.analysis.dynamics import read_modes_json
    from fusioncut.cli.stability import register

    app = typer.Typer()
    register(app)
    app.command("noop")(lambda: None)
    maps = _results(tmp_path / "res")
    modes = Path(__file__).parents[2] / "docs" / "stability_modes_example.json"
    out = tmp_path / "stab"
    args = ["stability", str(tmp_path / "res"), "--modes", str(modes), "--rpm", "9000", "--flutes", "4",
            "--helix", "30", "--slice-height", "0.5", "--out", str(out)]
    r = CliRunner().invoke(app, args + ["--no-plot"])
    assert r.exit_code == 0, r.output
    csv = pd.read_csv(out / "stability.csv")
    pq = pd.read_parquet(out / "stability.parquet")
    assert list(csv.columns) == [c for c, _, _ in STABILITY_COLUMNS]
    np.testing.assert_allclose(csv["a_lim_zoa_mm"], pq["a_lim_zoa_mm"], rtol=1e-12)
    # the engaged rows are the direct computation's
    dyn = read_modes_json(modes)
    t = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=4, helix_angle=30.0)
    from fusioncut.analysis.materials import AL7075_T6_CARBIDE as AL

    grid, system = chatter_grid(dyn), ModalSystem.from_dynamics(dyn)
    for i in (0, 1):
        cd = cl_directional(maps[i], t, AL, 0.5)
        zoa = zoa_a_lim(cd.alpha0, grid, AL.ktc, 4, 9000.0)[0]
        sd = sd_a_lim(cd, system, AL.ktc, 9000.0, zoa)[0]
        assert csv.loc[i, "a_lim_zoa_mm"] == pytest.approx(zoa, rel=1e-9)
        assert csv.loc[i, "a_lim_sd_mm"] == pytest.approx(sd, rel=1e-9)
        assert csv.loc[i, "margin"] == pytest.approx(2.0 / min(zoa, sd), rel=1e-9)
        assert csv.loc[i, "ap_mm"] == pytest.approx(2.0)
    assert csv.loc[2, "margin"] == 0 and np.isinf(csv.loc[2, "a_lim_zoa_mm"])   # air
    assert csv.loc[3, ["a_lim_zoa_mm", "a_lim_sd_mm", "margin"]].isna().all()     # rapid
    # a coefficients file: twice the cutting coefficients halve the ZOA limit
    coef = tmp_path / "k.json"
    coef.write_text(json.dumps({k: 2 * v for k, v in AL.as_dict().items()}))
    r = CliRunner().invoke(app, args[:-1] + [str(tmp_path / "stab2"), "--coefficients", str(coef), "--no-sd",
                                              "--stick-out", "30"])
    assert r.exit_code == 0, r.output
    assert not (out / "lobes.png").exists()
    for png in ("lobes.png", "margin.png", "deflection.png"):
        assert mpimg.imread(tmp_path / "stab2" / png).shape[0] > 100
    half = pd.read_csv(tmp_path / "stab2" / "stability.csv")
    np.testing.assert_allclose(half["a_lim_zoa_mm"][:2], csv["a_lim_zoa_mm"][:2] / 2, rtol=1e-9)
    assert half["a_lim_sd_mm"][:2].isna().all()
    # --stick-out: the static deflection of the tool (twice the coefficients) on a 30 mm cantilever
    from fusioncut.analysis.deflection import SteppedCantilever, cl_deflection
    from fusioncut.analysis.forces import CuttingCoefficients

    double = CuttingCoefficients(**{k: 2 * v for k, v in AL.as_dict().items()})
    d = cl_deflection(maps[1], t, double, SteppedCantilever.for_tool(t, 30.0), rpm=9000.0, dz=0.5)
    assert half.loc[1, "tip_deflection_peak_um"] == pytest.approx(1e3 * d.tip_peak_mm, rel=1e-9)
    assert half.loc[1, "sle_max_um"] == pytest.approx(1e3 * np.nanmax(d.sle_mm), rel=1e-9)
    assert half.loc[3, ["tip_deflection_peak_um", "sle_max_um"]].isna().all() and "sle_min_um" not in csv
    # bad input: one line naming the file, exit code 2
    coef.write_text('{"ktc": 1}')
    bad_modes = tmp_path / "bad.json"
    bad_modes.write_text('{"x": [{"fn_hz": 600, "zeta": 0.03, "k_n_per_m": 0}]}')
    with_bad_modes = [str(bad_modes) if a == str(modes) else a for a in args]
    for given, msg in ((args + ["--coefficients", str(coef)], f"{coef}: missing key(s)"),
                       (with_bad_modes, f"{bad_modes}: x[0]: mode k_n_per_m"),
                       (args + ["--rpm-min", "100"], "give both --rpm-min and --rpm-max"),
                       (args + ["--stick-out", "0"], "stick-out must be > 0 mm")):
        r = CliRunner().invoke(app, given)
        assert r.exit_code == 2 and msg in " ".join(r.output.split()), r.output


# --------------------------------------------------------------------------------------------------
# a real program: the first CLs of the Fusion-posted 2D adaptive 1055_utab_265bit.nc (2.65 mm flat end
# mill, S5000), run once per session by the force tests' fixture


@pytest.mark.skipif(not PROGRAM.exists(), reason="shared test data not available")
def test_real_program_limits_from_saved_tables(run) -> None:  # noqa: F811  (the fixture)
    from fusioncut.analysis.forces import engagement_maps_from_results, results_slice_height
    from fusioncut.analysis.stability_table import stability_table
    from fusioncut.io.results import load_results
    from test_forces_real_program import SLICE, _is_slot

    full, maps, out = run
    t = full.tools[1]
    iso = ToolDynamics((Mode(3200.0, 0.02, 1.5e7),), (Mode(3200.0, 0.02, 1.5e7),))
    rpm = [5000.0] * len(maps)
    direct = stability_table(maps, t, COEF, iso, rpm, dz=SLICE, sd=False)
    results = load_results(out)
    dz = results_slice_height(results)
    assert dz == SLICE
    rebuilt = stability_table(engagement_maps_from_results(results, dz), t, COEF, iso, rpm, dz=dz, sd=False)
    for col in ("a_lim_zoa_mm", "margin", "nearest_stable_rpm", "ap_mm"):
        np.testing.assert_allclose(rebuilt[col], direct[col], rtol=1e-9, equal_nan=True)
    # every full slot (2 mm, one arc 0..180 deg per slice), whatever its feed direction, has the limit of
    # the closed-form slot factors: with the same modes along x and y the feed direction cannot matter
    slots = [i for i, m in enumerate(maps) if _is_slot(m)]
    assert len(slots) > 20 and len({round(maps[i].feed_angle, 3) for i in slots}) >= 2
    alpha = np.array([[-KR * math.pi, -math.pi], [math.pi, -KR * math.pi]])
    want = zoa_a_lim(alpha, chatter_grid(iso), KTC, t.flutes, 5000.0)[0]
    np.testing.assert_allclose(direct.loc[slots, "a_lim_zoa_mm"], want, rtol=1e-9)
    np.testing.assert_allclose(direct.loc[slots, "margin"], 2.0 / want, rtol=1e-9)
    engaged = direct["status"] == "engaged"
    assert np.all(np.isfinite(direct.loc[engaged, "margin"])) and direct.loc[~engaged, "margin"].fillna(0).eq(0).all()


def test_stability_command_modes_per_tool(tmp_path) -> None:
    """--modes FILE for every tool and --modes TOOL=FILE for one: each tool's rows use its own modes."""
    import pandas as pd
    import typer
    from typer.testing import CliRunner

    from fusioncut.analysis.dynamics import read_modes_json
    from fusioncut.analysis.materials import AL7075_T6_CARBIDE as AL
    from fusioncut.analysis.stability_table import stability_table
    from fusioncut.cli.stability import register
    from fusioncut.io.results import ResultWriter

    app = typer.Typer()
    register(app)
    app.command("noop")(lambda: None)
    maps = [dataclasses_replace(m, tool=label) for m, label in zip(_results(tmp_path / "one")[:2], ("T1", "T2"))]
    with ResultWriter(tmp_path / "res", tools={label: {"kind": "flat", "diameter_mm": 10.0, "flute_length_mm": 20.0}
                                               for label in ("T1", "T2")}) as w:
        for m in maps:
            w.add(m, length_mm=1.0)
    every = Path(__file__).parents[2] / "docs" / "stability_modes_example.json"
    stiff = tmp_path / "stiff.json"
    stiff.write_text('{"x": [{"fn_hz": 900, "zeta": 0.05, "k_n_per_m": 2e7}], "y": [{"fn_hz": 950, "zeta": 0.05, '
                     '"k_n_per_m": 2e7}]}')
    base = ["stability", str(tmp_path / "res"), "--rpm", "9000", "--flutes", "4", "--slice-height", "0.5",
            "--no-sd", "--no-plot", "--out", str(tmp_path / "out")]
    r = CliRunner().invoke(app, base + ["--modes", str(every), "--modes", f"T2={stiff}"])
    assert r.exit_code == 0, r.output
    got = pd.read_csv(tmp_path / "out" / "stability.csv")
    t = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=4)
    for i, dyn in ((0, read_modes_json(every)), (1, read_modes_json(stiff))):
        want = stability_table([maps[i]], t, AL, dyn, [9000.0], dz=0.5, sd=False)
        assert got.loc[i, "a_lim_zoa_mm"] == pytest.approx(want.loc[0, "a_lim_zoa_mm"], rel=1e-12)
    for extra, msg in ((["--modes", f"T2={stiff}"], "no --modes for tool 'T1'"),
                       (["--modes", str(every), "--modes", str(stiff)], "a second file for every tool")):
        r = CliRunner().invoke(app, base + extra)
        assert r.exit_code == 2 and msg in " ".join(r.output.split()), r.output


def test_stability_command_notes_cls_without_a_spindle_speed(tmp_path) -> None:
    """A folder whose program sets no S word (the demo's) records no speed: the engaged CLs get no limit,
    and the command says how many and what to give instead of reporting 'stability of 0 CL(s)' alone."""
    import typer
    from typer.testing import CliRunner

    from fusioncut.cli.stability import register

    app = typer.Typer()
    register(app)
    app.command("noop")(lambda: None)
    _results(tmp_path / "res")
    modes = Path(__file__).parents[2] / "docs" / "stability_modes_example.json"
    args = ["stability", str(tmp_path / "res"), "--modes", str(modes), "--slice-height", "0.5", "--no-sd",
            "--no-plot", "--out", str(tmp_path / "stab")]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0, r.output
    text = " ".join(r.output.split())
    assert "stability of 0 CL(s)" in text
    assert "2 engaged CL(s) without a spindle speed have no limit" in text and "give --rpm" in text, r.output
    r = CliRunner().invoke(app, args + ["--rpm", "9000"])
    assert r.exit_code == 0 and "without a spindle speed" not in r.output, r.output


def _speed_benchmark():
    import importlib.util

    path = Path(__file__).parents[2] / "benchmarks" / "stability_speed.py"
    spec = importlib.util.spec_from_file_location("stability_speed_bench", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def test_speed_benchmark_reads_a_results_folder(tmp_path) -> None:
    """benchmarks/stability_speed.py --results rebuilds a folder's CLs at the slice height it records or,
    for an older folder, the one given, and refuses to guess (it imported a slice-height guesser that no
    longer exists, so --results failed with an ImportError)."""
    from fusioncut.errors import InputError

    bench = _speed_benchmark()
    maps = _results(tmp_path / "res")
    got, dz = bench.results_maps(tmp_path / "res", 0.5)
    assert dz == 0.5 and [m.cl_index for m in got] == [m.cl_index for m in maps]
    assert [m.slices for m in got[:2]] == [m.slices for m in maps[:2]]
    with pytest.raises(InputError, match="slice"):
        bench.results_maps(tmp_path / "res")


@pytest.mark.slow
def test_speed_benchmark_runs_on_a_results_folder(tmp_path, capsys) -> None:
    """The benchmark end to end on a folder's 4 CLs and 2 speeds (the baseline its own revision): every
    timing line is printed. Seconds: the ZOA pass is compiled for both copies."""
    bench = _speed_benchmark()
    _results(tmp_path / "res")
    bench.main(["--results", str(tmp_path / "res"), "--slice-height", "0.5", "--speeds", "2", "--baseline", "HEAD"])
    out = capsys.readouterr().out
    assert f"ZOA per CL, {tmp_path / 'res'} (4 CLs)" in out and out.count("SD lobes, 2 speeds") == 2, out
