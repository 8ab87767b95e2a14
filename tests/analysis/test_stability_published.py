"""Stability against published models and examples: ZOA on the data of a two-mode example (last test) and
semi-discretization against a published closed form, the stability boundaries of highly interrupted
milling in the impulsive limit (Davies, Pratt, Dutterer & Burns, "Stability prediction for low radial
immersion milling", J. Manuf. Sci. Eng. 124 (2002) 217-225: the tooth is in the cut for a vanishing
fraction of the tooth period, so the regenerative force is an impulse once per period and the motion a
free damped vibration between impulses), on the 1-DOF benchmark of Insperger & Stepan (fn 922 Hz,
zeta 0.011, m 0.03993 kg, Kt 6e8 N/m², Kn 2e8 N/m², 2 flutes, down-milling).

The map of that model, written out here from its assumptions: over one tooth period ``T`` the free
vibration takes ``(x, v)`` to ``Phi (x, v)``, ``Phi = exp([[0, 1], [-wn², -2 zeta wn]] T)``; the impulse
changes the velocity by ``-kappa (x_j - x_{j-1})`` with ``kappa = -a Kt alpha_xx / (2 m Omega)`` (``a`` the
depth, ``alpha_xx`` the directional factor integrated over the arc, ``Omega`` the spindle speed in rad/s:
``int B_xx dt = alpha_xx / Omega`` per tooth period). Multipliers ``mu`` solve ``mu² - tr(Phi) mu + det(Phi)
+ Phi_12 kappa (mu - 1) = 0``, stable inside the triangle ``det - 1 < Phi_12 kappa < (1 + tr + det) / 2``:

* period doubling (flip, ``mu = -1``) where ``Phi_12 kappa = (1 + tr(Phi) + det(Phi)) / 2``;
* secondary Hopf (Neimark-Sacker, ``|mu| = 1`` complex) where ``Phi_12 kappa = det(Phi) - 1``, the pair at
  ``Re mu = (1 + tr(Phi) - det(Phi)) / 2``.

SD of the real cut (the arc's time-varying directional factor, no impulse) must approach these
boundaries as the radial immersion goes to 0; the gap is first order in the time in cut.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from fusioncut.analysis.dynamics import Mode, ToolDynamics
from fusioncut.analysis.forces import CuttingCoefficients
from fusioncut.analysis.stability import ModalSystem, cl_directional, sd_a_lim, sd_critical_multiplier
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement, SpindleDirection

FN, ZETA, MASS = 922.0, 0.011, 0.03993
KTC = 600.0  # N/mm² (6e8 N/m²), Kr = 1/3
SYSTEM = ModalSystem.from_dynamics(ToolDynamics((Mode(FN, ZETA, MASS * (2 * math.pi * FN) ** 2),), ()))


def down_milling(a_over_d: float):
    """The CL of a 10 mm 2-flute straight end mill down-milling at radial immersion ``a_over_d``."""
    arc = math.degrees(math.acos(1 - 2 * a_over_d))
    emap = EngagementMap(0, (1, 0, 0), (0, 0, 0), "T1", SpindleDirection.CW, 0.0, CLStatus.ENGAGED, feed=1.0,
                         slices=(SliceEngagement(0.5, 0.0, 5.0, (AngleInterval(180.0 - arc, 180.0),)),),
                         axial_range=(0.0, 1.0))
    return cl_directional(emap, FlatEndMill(diameter=10.0, flute_length=20.0, flutes=2),
                          CuttingCoefficients(KTC, KTC / 3, 0.0, 0.0, 0.0, 0.0), dz=1.0)


def impulsive_boundaries(rpm: float, alpha_xx: float) -> tuple[float, float, float]:
    """Flip and Neimark-Sacker depths (mm; the one of the two that is positive is the boundary at this
    speed) of the impulsive model (module docstring), and ``Re mu`` of the Neimark-Sacker pair."""
    wn = 2 * math.pi * FN
    wd = wn * math.sqrt(1 - ZETA ** 2)
    t = 60.0 / (2 * rpm)
    decay = math.exp(-ZETA * wn * t)
    phi12, trace, det = decay * math.sin(wd * t) / wd, 2 * decay * math.cos(wd * t), decay * decay
    kappa_per_m = -KTC * 1e6 * alpha_xx / (2 * MASS * 2 * math.pi * rpm / 60.0)
    flip = (1 + trace + det) / (2 * phi12) / kappa_per_m * 1e3
    hopf = (det - 1) / phi12 / kappa_per_m * 1e3
    return flip, hopf, (1 + trace - det) / 2


def test_sd_approaches_the_impulsive_flip_boundary() -> None:
    """16,000 rev/min (sin(wd T) < 0: the flip boundary bounds the stable depths): at a/D 0.04, 0.01 and
    0.0025 SD loses stability through a multiplier -1 below the impulsive model's depth, and the gap
    shrinks as the time in cut does, about in proportion to the arc (each quartering of a/D halves it:
    17 %, 12 %, 7 %), so that the first-order extrapolation 2 e(0.0025) - e(0.01) is within 3 % of 0."""
    errors = []
    for a_over_d, steps in ((0.04, 400), (0.01, 400), (0.0025, 800)):
        cd = down_milling(a_over_d)
        flip, hopf, _ = impulsive_boundaries(16000.0, cd.alpha0[0, 0])
        assert flip > 0 > hopf
        sd = sd_a_lim(cd, SYSTEM, KTC, 16000.0, flip, steps=steps, per_vibration=0, rel_tol=1e-5)[0]
        mu = sd_critical_multiplier(cd, SYSTEM, KTC, 16000.0, 1.001 * sd, steps=steps)
        assert mu.real < -1 and abs(mu.imag) < 1e-9, (a_over_d, mu)
        errors.append(sd / flip - 1)
    assert all(e < 0 for e in errors), errors
    assert 0.45 < errors[1] / errors[0] < 0.8 and 0.45 < errors[2] / errors[1] < 0.8, errors
    assert abs(2 * errors[2] - errors[1]) < 0.03, errors


def test_sd_approaches_the_impulsive_hopf_boundary() -> None:
    """24,000 rev/min (sin(wd T) > 0: the Neimark-Sacker boundary): SD's limit at a/D 0.01 and 0.0025 is
    within 0.6 % and 0.3 % of the impulsive model's depth, and the critical pair of multipliers is at the
    model's Re mu within 2e-3."""
    errors = []
    for a_over_d, steps in ((0.01, 400), (0.0025, 800)):
        cd = down_milling(a_over_d)
        flip, hopf, re_mu = impulsive_boundaries(24000.0, cd.alpha0[0, 0])
        assert hopf > 0 > flip
        sd = sd_a_lim(cd, SYSTEM, KTC, 24000.0, hopf, steps=steps, per_vibration=0, rel_tol=1e-5)[0]
        mu = sd_critical_multiplier(cd, SYSTEM, KTC, 24000.0, 1.001 * sd, steps=steps)
        assert abs(mu.imag) > 0.1 and mu.real == pytest.approx(re_mu, abs=2e-3), (a_over_d, mu, re_mu)
        errors.append(abs(sd / hopf - 1))
    assert errors[0] < 6e-3 and errors[1] < 3e-3 and errors[1] < errors[0], errors


def test_impulsive_boundaries_are_those_of_the_map() -> None:
    """The closed forms themselves: the map's multipliers at the flip depth include -1, at the
    Neimark-Sacker depth a pair of modulus 1 with the stated real part (so a wrong sign or factor in the
    closed forms cannot pass the two tests above by accident)."""
    for rpm in (16000.0, 24000.0):
        alpha_xx = down_milling(0.01).alpha0[0, 0]
        flip, hopf, re_mu = impulsive_boundaries(rpm, alpha_xx)
        wn = 2 * math.pi * FN
        t = 60.0 / (2 * rpm)
        gen = np.array([[0.0, 1.0], [-wn * wn, -2 * ZETA * wn]]) * t
        w, v = np.linalg.eig(gen)
        phi = (v @ np.diag(np.exp(w)) @ np.linalg.inv(v)).real
        kappa_per_mm = -KTC * 1e6 * alpha_xx / (2 * MASS * 2 * math.pi * rpm / 60.0) * 1e-3
        for depth, want in ((flip, "flip"), (hopf, "hopf")):
            if depth <= 0:
                continue
            mu = np.linalg.eigvals(_impulse_map(phi, kappa_per_mm * depth))
            top = mu[np.argmax(np.abs(mu))]
            assert abs(top) == pytest.approx(1.0, abs=1e-9), (rpm, want, mu)
            if want == "flip":
                assert top.real == pytest.approx(-1.0, abs=1e-9)
            else:
                assert top.real == pytest.approx(re_mu, abs=1e-9) and abs(top.imag) > 0.1


def _impulse_map(phi: np.ndarray, kappa: float) -> np.ndarray:
    """(x_j, v_j^-, x_{j-1}) -> (x_{j+1}, v_{j+1}^-, x_j): the impulse, then a tooth period of free vibration."""
    kick = np.array([[1.0, 0.0, 0.0], [-kappa, 1.0, kappa]])  # (x_j, v_j^+)
    out = np.zeros((3, 3))
    out[:2] = phi @ kick
    out[2, 0] = 1.0
    return out


def test_zoa_reproduces_the_two_mode_shaping_example_solution() -> None:
    """The two-mode example of orthogonal cutting (shaping) in the style of Altintas's *Manufacturing
    Automation* (ch. 3), with its data as transcribed in github.com/leekunhwee/Dynamics
    (Cutting/Stability/FrequencyDomain/Turning/Two DOF Example/README.md): modes 250 and 150 Hz, damping
    1.2 and 1.0 %, stiffness 2.26e8 and 2.13e8 N/m, oriented 30 and -45 deg from the force, Kf = 1000
    MPa. Its printed results were not found, so the comparison is with the example's solution procedure,
    computed here on a fine frequency grid: the oriented receptance G + iH = sum cos² theta_j Phi_j,
    a_lim = -1 / (2 Kf G) where G < 0, eps = 2 pi - 2 atan(G / H) (H < 0), n = 60 f_c / (k + eps / 2 pi).
    ZOA takes it as one cutting edge (N = 1, Ktc = Kf) on the two modes along x with stiffness k_j /
    cos² theta_j and the directional factor alpha_xx = -4 pi (so that 2 pi / (N Ktc alpha_xx) = -1 /
    (2 Kf)); its lobes' minimum equals the example's -1 / (2 Kf min G) and its limit at six speeds equals
    the example's lobes (the smallest a_lim whose n_k passes through the speed) within 2e-4."""
    from fusioncut.analysis.stability import chatter_grid, zoa_a_lim, zoa_lobes

    kf = 1000.0  # N/mm²
    modes = ((250.0, 0.012, 2.26e8, 30.0), (150.0, 0.010, 2.13e8, -45.0))
    dyn = ToolDynamics(tuple(Mode(f, z, k / math.cos(math.radians(t)) ** 2) for f, z, k, t in modes), ())
    alpha = np.array([[-4 * math.pi, 0.0], [0.0, 0.0]])
    # the example's solution: oriented receptance on a fine grid, both lobes' branches
    f = np.linspace(100.0, 400.0, 600_001)
    phi = sum(math.cos(math.radians(t)) ** 2 / (k * (1 - (f / fn) ** 2 + 2j * z * f / fn)) for fn, z, k, t in modes)
    g, h = phi.real, phi.imag
    ok = (g < 0) & (h < 0)
    a_ex = np.where(ok, -1.0 / (2 * kf * 1e6 * np.where(ok, g, -1.0)) * 1e3, np.nan)  # mm
    eps = 2 * math.pi - 2 * np.arctan(g / h)
    grid = chatter_grid(dyn)
    _, lobes = zoa_lobes(alpha, grid, kf, 1, 300.0, 3000.0, 2000)
    a_min = float(np.nanmin(a_ex))
    assert lobes.min() == pytest.approx(a_min, rel=2e-3) and lobes.min() >= a_min * (1 - 1e-9)
    for rpm in (400.0, 700.0, 1100.0, 1600.0, 2200.0, 2900.0):
        best = math.inf
        for k in range(0, 60):
            n = 60.0 * f / (k + eps / (2 * math.pi))
            # neighbouring grid points with a depth on either side of the speed
            cross = np.flatnonzero((np.diff(np.sign(n - rpm)) != 0) & ok[:-1] & ok[1:])
            if len(cross):
                w = (rpm - n[cross]) / (n[cross + 1] - n[cross])
                best = min(best, float((a_ex[cross] + w * (a_ex[cross + 1] - a_ex[cross])).min()))
        assert math.isfinite(best)
        assert zoa_a_lim(alpha, grid, kf, 1, rpm)[0] == pytest.approx(best, rel=2e-4), rpm
