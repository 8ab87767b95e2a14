"""The compiled and reduced stability computations equal the reference ones they replace in the table and
the lobes: the ZOA limit and nearest stable speed of many CLs in one pass against ``zoa_a_lim`` and
``nearest_stable_rpm`` (vectorised NumPy, one CL at a time)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fusioncut.analysis.dynamics import Mode, ToolDynamics
from fusioncut.analysis.stability import (chatter_grid, nearest_stable_rpm, zoa_a_lim, zoa_a_lim_many,
                                          zoa_limit_and_nearest_many)
from fusioncut.errors import InputError

KTC = 600.0
BENCH = ToolDynamics((Mode(922.0, 0.011, 0.03993 * (2 * math.pi * 922.0) ** 2),), ())
EXAMPLE = ToolDynamics((Mode(600.0, 0.035, 5.6e6), Mode(1450.0, 0.02, 1.4e7)), (Mode(660.0, 0.03, 5.7e6),))


@pytest.mark.parametrize("dyn, flutes", [(BENCH, 2), (EXAMPLE, 3)])
def test_compiled_limits_and_nearest_speeds_equal_the_reference(dyn, flutes) -> None:
    """Random directional matrices, speeds and depths (about half of them unstable by ZOA, so that the
    nearest-speed search runs): limits to 1e-12, nearest speeds to 1e-9 (both NaN where no speed in the
    range is stable), the CL's own speed where it is stable."""
    rng = np.random.default_rng(11)
    grid = chatter_grid(dyn)
    count = 60
    alphas = rng.normal(0.0, 1.5, (count, 2, 2))
    speeds = rng.uniform(3000.0, 25000.0, count)
    lim_ref = np.array([zoa_a_lim(a, grid, KTC, flutes, n)[0] for a, n in zip(alphas, speeds)])
    depth = np.where(np.isfinite(lim_ref), lim_ref, 1.0) * rng.uniform(0.5, 3.0, count)
    lo, hi = 0.6 * speeds, 1.4 * speeds
    lim, near = zoa_limit_and_nearest_many(alphas, grid, KTC, flutes, speeds, depth, lo, hi)
    np.testing.assert_allclose(lim, lim_ref, rtol=1e-12)
    np.testing.assert_allclose(zoa_a_lim_many(alphas, grid, KTC, flutes, speeds), lim_ref, rtol=1e-12)
    ref = np.array([nearest_stable_rpm(a, grid, KTC, flutes, n, d, l, h)
                    for a, n, d, l, h in zip(alphas, speeds, depth, lo, hi)])
    unstable = ~(lim_ref > depth)
    assert 15 < unstable.sum() < count - 5 and np.isfinite(ref[unstable]).sum() > 10
    np.testing.assert_allclose(near, ref, rtol=1e-9, equal_nan=True)
    assert np.all(near[~unstable] == speeds[~unstable])


def test_compiled_nearest_speed_refuses_a_range_of_too_many_lobes() -> None:
    grid = chatter_grid(BENCH)
    slot = np.array([[[-math.pi / 3, -math.pi], [math.pi, -math.pi / 3]]])
    with pytest.raises(InputError, match="lobes; narrow it"):
        zoa_limit_and_nearest_many(slot, grid, KTC, 2, 300.0, 50.0, 1.0, 600.0)
    with pytest.raises(InputError, match="lobes; narrow it"):
        nearest_stable_rpm(slot[0], grid, KTC, 2, 300.0, 50.0, 1.0, 600.0)


def _cases():
    from fusioncut.analysis.stability import ModalSystem, cl_directional
    from fusioncut.analysis.forces import CuttingCoefficients
    from fusioncut.model import AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement, SpindleDirection

    def cl(entry: float, exit_: float, slices: int) -> EngagementMap:
        sl = tuple(SliceEngagement(0.25 + 0.5 * k, 0.0, 5.0, (AngleInterval(entry, exit_),)) for k in range(slices))
        return EngagementMap(0, (1, 0, 0), (0, 0, 0), "T1", SpindleDirection.CW, 0.0, CLStatus.ENGAGED, feed=1.0,
                             slices=sl, axial_range=(0.0, 0.5 * slices))

    coef = CuttingCoefficients(KTC, KTC / 3, 0.0, 0.0, 0.0, 0.0)
    two = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=2)
    three = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=3, helix_angle=30.0)
    low = 180.0 - math.degrees(math.acos(1 - 2 * 0.1))
    return [("1-DOF a/D 0.1 down", cl_directional(cl(low, 180.0, 1), two, coef, 0.5), ModalSystem.from_dynamics(BENCH)),
            ("1-DOF slot", cl_directional(cl(0.0, 180.0, 1), two, coef, 0.5), ModalSystem.from_dynamics(BENCH)),
            ("3 modes half immersion", cl_directional(cl(90.0, 180.0, 8), three, coef, 0.5),
             ModalSystem.from_dynamics(EXAMPLE))]


@pytest.mark.parametrize("case", range(3))
def test_sd_spectral_radius_equals_lapack(case) -> None:
    """The spectral radius with the unread delayed states left out and the largest multipliers by Arnoldi's
    method equals the largest modulus of LAPACK's eigenvalues of the whole monodromy matrix, to 1e-9, at
    stable and unstable depths (0.1 to 3 times the ZOA limit) and 30 to 70 steps."""
    from fusioncut.analysis.stability import sd_multipliers, sd_spectral_radius, zoa_a_lim

    _, cd, system = _cases()[case]
    dyn = BENCH if case < 2 else EXAMPLE
    grid = chatter_grid(dyn)
    rng = np.random.default_rng(case)
    for steps in (30, 50, 70):
        rpm = rng.uniform(5000.0, 25000.0, 12)
        ref = zoa_a_lim(cd.alpha0, grid, KTC, cd.flutes, rpm)
        depth = np.where(np.isfinite(ref), ref, 1.0) * np.geomspace(0.1, 3.0, 12)
        fast = sd_spectral_radius(cd, system, KTC, rpm, depth, steps=steps)
        full = np.abs(sd_multipliers(cd, system, KTC, rpm, depth, steps=steps)).max(axis=1)
        assert (full > 1).sum() >= 3 and (full < 1).sum() >= 3
        np.testing.assert_allclose(fast, full, rtol=1e-9)


def test_sd_interval_integrals_scaled_equal_unscaled() -> None:
    """The interval integrals from the series on the scaled matrix S A S^-1 equal the unscaled series', to
    1e-11 of each matrix's largest entry: the unscaled series needs q = 15 doublings here (1-norm of A dt
    up to 8e3), each squaring the rounding of the last, 2^15 x 2.2e-16 = 7e-12."""
    from fusioncut.analysis.stability_sd import interval_integrals

    rng = np.random.default_rng(3)
    w = 2 * math.pi * np.array([600.0, 1450.0, 660.0])
    a = np.zeros((20, 6, 6))
    a[:, :3, 3:] = np.eye(3)
    a[:, 3:, :3] = -np.diag(w ** 2) + rng.normal(0.0, 0.3, (20, 3, 3)) * w.max() ** 2
    a[:, 3:, 3:] = -np.diag(2 * 0.03 * w)
    dt = rng.uniform(2e-5, 1e-4, (20,))
    scale = np.r_[np.ones(3), np.full(3, 1 / w.max())]
    for got, want in zip(interval_integrals(a, dt, scale), interval_integrals(a, dt)):
        err = np.abs(got - want).max(axis=(1, 2)) / np.abs(want).max(axis=(1, 2))
        assert err.max() < 1e-11, err.max()


@pytest.mark.parametrize("case", [0, 2])
def test_sd_lobes_equal_those_with_lapack_eigenvalues(case, monkeypatch) -> None:
    """sd_a_lim on 8 speeds with the fast spectral radius equals sd_a_lim with LAPACK's eigenvalues of the
    whole monodromy matrix (the computation before) to 1e-6: the same depths are evaluated as long as no
    decision rho >= 1 flips, and the radii agree to 1e-9."""
    from fusioncut.analysis import stability
    from fusioncut.analysis.stability import sd_a_lim, zoa_a_lim

    _, cd, system = _cases()[case]
    grid = chatter_grid(BENCH if case < 2 else EXAMPLE)
    rpm = np.linspace(6000.0, 21000.0, 8)
    ref = zoa_a_lim(cd.alpha0, grid, KTC, cd.flutes, rpm)
    fast = sd_a_lim(cd, system, KTC, rpm, ref)
    from fusioncut.analysis.stability_sd import monodromy

    monkeypatch.setattr(stability, "spectral_radius",
                        lambda *steps: np.abs(np.linalg.eigvals(monodromy(*steps))).max(axis=1))
    slow = sd_a_lim(cd, system, KTC, rpm, ref)
    assert np.all(np.isfinite(fast))
    np.testing.assert_allclose(fast, slow, rtol=1e-6)


def _grid_reference(cd, system, rpm: np.ndarray, ref: np.ndarray, steps_of) -> tuple[np.ndarray, np.ndarray]:
    """The search before the probes: every point of the geometric grid ref x [0.05, 10] (14) up to the
    first unstable one; returns that point and the stable one below it (depths, mm)."""
    from fusioncut.analysis.stability import sd_spectral_radius

    ratios = np.geomspace(0.05, 10.0, 14)
    lo, hi = np.zeros(len(rpm)), np.full(len(rpm), np.inf)
    for i, (n, a) in enumerate(zip(rpm, ref)):
        rho = sd_spectral_radius(cd, system, KTC, np.full(14, n), a * ratios, steps=steps_of(n))
        bad = np.flatnonzero(rho >= 1)
        if len(bad):
            lo[i], hi[i] = (a * ratios[bad[0] - 1] if bad[0] else 0.0), a * ratios[bad[0]]
    return lo, hi


@pytest.mark.parametrize("case, speeds", [(0, 200), (2, 24)])
def test_sd_probed_grid_finds_the_limits_of_the_whole_grid(case, speeds) -> None:
    """sd_a_lim's probed depth grid against the whole grid evaluated (the search before the probes): at
    every speed its limit lies in the whole grid's first unstable interval and is a boundary there (the
    spectral radius below 1 at 0.999 times it, at least 1 at 1.001 times), at every speed of the 1-DOF
    benchmark's lobes at a/D 0.1, 5,000 to 25,000 rev/min (flip islands among them: at 10,628 rev/min
    the limit is an island at 0.51 of ZOA's with a stable depth at 0.87 of it above) and of the docs' 3
    modes at half immersion."""
    from fusioncut.analysis.stability import sd_a_lim, sd_spectral_radius, sd_steps, zoa_a_lim

    _, cd, system = _cases()[case]
    grid = chatter_grid(BENCH if case < 2 else EXAMPLE)
    rpm = np.linspace(5000.0, 25000.0 if case < 2 else 20000.0, speeds)
    ref = zoa_a_lim(cd.alpha0, grid, KTC, cd.flutes, rpm)
    ref = np.where(np.isfinite(ref), ref, cd.ap)
    got = sd_a_lim(cd, system, KTC, rpm, ref, max_steps=120)
    steps = np.array([sd_steps(system, cd.flutes, n, 30, 12.0) for n in rpm])
    lo, hi = _grid_reference(cd, system, rpm, ref, lambda n: sd_steps(system, cd.flutes, n, 30, 12.0))
    assert np.all(np.isfinite(hi)) and np.all(lo > 0)
    assert np.all(got >= lo) and np.all(got <= hi), np.flatnonzero((got < lo) | (got > hi))
    for m in np.unique(steps):
        i = np.flatnonzero(steps == m)
        below = sd_spectral_radius(cd, system, KTC, rpm[i], 0.999 * got[i], steps=int(m))
        above = sd_spectral_radius(cd, system, KTC, rpm[i], 1.001 * got[i], steps=int(m))
        assert np.all(below < 1) and np.all(above >= 1), rpm[i][(below >= 1) | (above < 1)]
    if case == 0:
        assert (got / ref < 0.6).sum() >= 5  # flip lobes well below ZOA's limit are among the speeds
        island = np.argmin(np.abs(rpm - 10628.0))
        assert got[island] / ref[island] < 0.6
