"""The mechanistic force model against closed forms (Altintas 2012, ch. 2), not golden files.

Oracles are written out here independently of the implementation: the textbook mean-force integrals,
the instantaneous force of a straight tooth, the helical-tooth force as an integral over the immersion,
and the ball-end slot integrals over the axial immersion angle.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fusioncut.analysis.forces import (
    CLForces,
    CuttingCoefficients,
    _radius_at_many,
    compute_cl_forces,
    compute_forces,
    feed_per_tooth,
    feed_per_tooth_from_map,
)
from fusioncut.analysis.materials import AL7075_T6_CARBIDE, MATERIALS, get_coefficients
from fusioncut.errors import GeometryError, InputError
from fusioncut.model import (
    AngleInterval,
    BallEndMill,
    BullNoseEndMill,
    ChamferMill,
    CLStatus,
    EngagementMap,
    FlatEndMill,
    SliceEngagement,
    SpindleDirection,
    TaperedEndMill,
)

K = AL7075_T6_CARBIDE
C = 0.05  # feed per tooth, mm
RPM = 8000.0


def slot_map(
    intervals: list[tuple[float, float]] | list[list[tuple[float, float]]],
    depth: float,
    n_slices: int,
    radius: float,
    *,
    spindle: SpindleDirection = SpindleDirection.CW,
    feed_angle: float = 0.0,
    feed: float | None = 1000.0,
    status: CLStatus = CLStatus.ENGAGED,
) -> EngagementMap:
    """Slices at the centres of ``n_slices`` equal bands over ``[0, depth]``, every slice with the same
    immersion intervals (deg)."""
    dz = depth / n_slices
    ivs = tuple(AngleInterval(a, b) for a, b in intervals)
    slices = tuple(
        SliceEngagement(z=(i + 0.5) * dz, z_machine=(i + 0.5) * dz, radius=radius, intervals=ivs)
        for i in range(n_slices)
    )
    return EngagementMap(
        cl_index=7, position=(10.0, 0.0, 0.0), start=(9.0, 0.0, 0.0), tool="T1", spindle=spindle,
        feed_angle=feed_angle, status=status, feed=feed, slices=slices, axial_range=(0.0, depth),
    )


# --- textbook closed forms (Altintas 2012, eqs. for the average milling forces) ----------------------

def textbook_mean(phi_st: float, phi_ex: float, n: int, a: float, c: float, k: CuttingCoefficients) -> np.ndarray:
    """Mean Fx, Fy, Fz (N) per tooth period, flat end mill, immersion [phi_st, phi_ex] (rad)."""
    def fx(p: float) -> float:
        return (n * a * c / (8 * math.pi)) * (k.ktc * math.cos(2 * p) - k.krc * (2 * p - math.sin(2 * p))) + (
            n * a / (2 * math.pi)
        ) * (-k.kte * math.sin(p) + k.kre * math.cos(p))

    def fy(p: float) -> float:
        return (n * a * c / (8 * math.pi)) * (k.ktc * (2 * p - math.sin(2 * p)) + k.krc * math.cos(2 * p)) - (
            n * a / (2 * math.pi)
        ) * (k.kte * math.cos(p) + k.kre * math.sin(p))

    def fz(p: float) -> float:
        return (n * a / (2 * math.pi)) * (-k.kac * c * math.cos(p) + k.kae * p)

    return np.array([f(phi_ex) - f(phi_st) for f in (fx, fy, fz)])


def textbook_mean_torque(
    phi_st: float, phi_ex: float, n: int, a: float, r: float, c: float, k: CuttingCoefficients
) -> float:
    """Mean torque (N*m): N a r / (2 pi) * int (Ktc c sin phi + Kte) dphi."""
    integral = k.ktc * c * (math.cos(phi_st) - math.cos(phi_ex)) + k.kte * (phi_ex - phi_st)
    return n * a * r / (2 * math.pi) * integral * 1e-3


def antiderivatives(p: np.ndarray, c: float, k: CuttingCoefficients) -> np.ndarray:
    """Primitives in phi of the straight-tooth force per unit axial length (N/mm), shape (3, ...)."""
    s, co = np.sin(p), np.cos(p)
    gx = -k.ktc * c * s * s / 2 - k.kte * s - k.krc * c * (p / 2 - np.sin(2 * p) / 4) + k.kre * co
    gy = k.ktc * c * (p / 2 - np.sin(2 * p) / 4) - k.kte * co - k.krc * c * s * s / 2 - k.kre * s
    gz = -k.kac * c * co + k.kae * p
    return np.stack((gx, gy, gz))


def straight_tooth(p: np.ndarray, c: float, k: CuttingCoefficients) -> np.ndarray:
    """Altintas's instantaneous straight-tooth force per unit axial length at immersion p (N/mm)."""
    ft = k.ktc * c * np.sin(p) + k.kte
    fr = k.krc * c * np.sin(p) + k.kre
    fa = k.kac * c * np.sin(p) + k.kae
    return np.stack((-ft * np.cos(p) - fr * np.sin(p), ft * np.sin(p) - fr * np.cos(p), fa))


def helical_instantaneous(theta: np.ndarray, st: float, ex: float, n: int, a: float, kb: float, c: float,
                          k: CuttingCoefficients) -> np.ndarray:
    """Force of a helical flat end mill (N), shape (3, S): for each tooth, (1/kb) times the integral of
    the straight-tooth force over the immersions its edge spans, [theta - kb a, theta], that lie in the
    engaged arc [st, ex] (mod 2 pi)."""
    out = np.zeros((3, len(theta)))
    for j in range(n):
        hi = theta + j * 2 * math.pi / n
        lo = hi - kb * a
        for m in range(-3, 4):  # the engaged arc and its copies a turn apart
            a0 = np.clip(lo, st + 2 * math.pi * m, ex + 2 * math.pi * m)
            a1 = np.clip(hi, st + 2 * math.pi * m, ex + 2 * math.pi * m)
            out += (antiderivatives(a1, c, k) - antiderivatives(a0, c, k)) / kb
    return out


CASES = {
    "slot": (0.0, 180.0),
    "half-up": (0.0, 90.0),
    "half-down": (90.0, 180.0),
    "up-ae2": (0.0, math.degrees(math.acos(1 - 2.0 / 6.0))),
    "down-ae3": (180.0 - math.degrees(math.acos(1 - 3.0 / 6.0)), 180.0),
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("helix", [0.0, 30.0, 45.0])
def test_mean_forces_match_textbook(case: str, helix: float) -> None:
    st, ex = CASES[case]
    n, depth = 4, 8.0
    tool = FlatEndMill(diameter=12.0, flute_length=30.0, flutes=n, helix_angle=helix)
    f = compute_cl_forces(slot_map([(st, ex)], depth, 40, 6.0), tool, K, rpm=RPM, feed_per_tooth=C)
    want = textbook_mean(math.radians(st), math.radians(ex), n, depth, C, K)
    np.testing.assert_allclose(f.mean_feed_frame, want, rtol=1e-3, atol=1e-9)
    t_want = textbook_mean_torque(math.radians(st), math.radians(ex), n, depth, 6.0, C, K)
    assert f.mean_torque == pytest.approx(t_want, rel=1e-3)
    assert f.power_mean == pytest.approx(t_want * RPM * 2 * math.pi / 60, rel=1e-3)


@pytest.mark.parametrize("case", sorted(CASES))
def test_sampled_mean_of_helical_tool_matches_textbook(case: str) -> None:
    """The time series itself (not only the exact mean) averages to the closed form: with a 30 deg
    helix the entry/exit jumps are spread over the flutes and 3600 samples suffice for 0.1%."""
    st, ex = CASES[case]
    tool = FlatEndMill(diameter=12.0, flute_length=30.0, flutes=3, helix_angle=30.0)
    f = compute_cl_forces(slot_map([(st, ex)], 8.0, 100, 6.0), tool, K, rpm=RPM, feed_per_tooth=C, samples=3600)
    want = textbook_mean(math.radians(st), math.radians(ex), 3, 8.0, C, K)
    np.testing.assert_allclose(f.feed_frame.mean(axis=0), want, rtol=1e-3)


@pytest.mark.parametrize("case", ["slot", "half-up", "down-ae3"])
def test_straight_tooth_instantaneous_matches_closed_form(case: str) -> None:
    """Zero helix: the force at each sample is the straight-tooth formula times the depth, summed over
    the teeth inside [entry, exit); also checks the sign conventions of Fx, Fy, Fz."""
    st, ex = CASES[case]
    n, depth = 2, 3.0
    tool = FlatEndMill(diameter=12.0, flute_length=30.0, flutes=n, helix_angle=0.0)
    f = compute_cl_forces(slot_map([(st, ex)], depth, 5, 6.0), tool, K, rpm=RPM, feed_per_tooth=C, samples=720)
    want = np.zeros((3, 720))
    for j in range(n):
        p = np.radians(f.angles) + j * 2 * math.pi / n
        deg = np.degrees(p) % 360
        inside = (deg >= st - 1e-9) & (deg < ex - 1e-9)
        want += np.where(inside, straight_tooth(p, C, K) * depth, 0.0)
    np.testing.assert_allclose(f.feed_frame.T, want, atol=1e-9 * np.abs(want).max())
    # conventions: in a slot the tool is pushed back against the feed and towards +y, and Fz = +Fa
    if case == "slot":
        assert f.mean_feed_frame[0] < 0 < f.mean_feed_frame[1]
        assert f.mean_feed_frame[2] > 0


@pytest.mark.parametrize("case", ["slot", "half-up", "half-down", "up-ae2"])
def test_helical_instantaneous_matches_closed_form(case: str) -> None:
    st, ex = (math.radians(v) for v in CASES[case])
    n, depth, helix, d = 3, 10.0, 30.0, 12.0
    tool = FlatEndMill(diameter=d, flute_length=30.0, flutes=n, helix_angle=helix)
    f = compute_cl_forces(slot_map([CASES[case]], depth, 400, 6.0), tool, K, rpm=RPM, feed_per_tooth=C)
    kb = 2 * math.tan(math.radians(helix)) / d
    want = helical_instantaneous(np.radians(f.angles), st, ex, n, depth, kb, C, K)
    # Discretisation bound: each band is wholly in or out of the cut, so at each entry / exit a tooth
    # miscounts at most half a band (dz/2) of edge carrying at most max|f| per mm: N teeth x 2 ends.
    dz = depth / 400
    f_max = np.abs(straight_tooth(np.linspace(0, 2 * math.pi, 3601), C, K)).max(axis=1)
    err = np.abs(f.feed_frame.T - want).max(axis=1)
    assert np.all(err <= n * f_max * dz), (err, n * f_max * dz)
    assert np.all(n * f_max * dz < 0.02 * np.abs(want).max())  # and the bound is a tight one


def test_helix_pitch_slot_gives_constant_force() -> None:
    """Depth = lead / N in a full slot: the edges always cover the slot once, so the force is constant
    (and equal to its mean); at half that depth it is not."""
    n, d, helix = 2, 12.0, 30.0
    tool = FlatEndMill(diameter=d, flute_length=50.0, flutes=n, helix_angle=helix)
    pitch = math.pi * d / math.tan(math.radians(helix)) / n
    f = compute_cl_forces(slot_map([(0.0, 180.0)], pitch, 600, 6.0), tool, K, rpm=RPM, feed_per_tooth=C)
    spread = np.abs(f.feed_frame - f.mean_feed_frame).max(axis=0)
    assert np.all(spread <= 2e-3 * np.abs(f.mean_feed_frame).max())
    g = compute_cl_forces(slot_map([(0.0, 180.0)], pitch / 2, 300, 6.0), tool, K, rpm=RPM, feed_per_tooth=C)
    assert np.abs(g.fy - g.mean_feed_frame[1]).max() > 0.1 * g.mean_feed_frame[1]


@pytest.mark.parametrize("helix", [0.0, 30.0])
def test_two_intervals_per_slice_add_up(helix: float) -> None:
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=4, helix_angle=helix)
    arcs = [(10.0, 50.0), (120.0, 170.0)]
    both = compute_cl_forces(slot_map(arcs, 5.0, 25, 5.0), tool, K, rpm=RPM, feed_per_tooth=C)
    parts = [compute_cl_forces(slot_map([arc], 5.0, 25, 5.0), tool, K, rpm=RPM, feed_per_tooth=C) for arc in arcs]
    scale = np.abs(both.feed_frame).max()
    np.testing.assert_allclose(both.feed_frame, parts[0].feed_frame + parts[1].feed_frame, atol=1e-12 * scale)
    np.testing.assert_allclose(both.torque, parts[0].torque + parts[1].torque, atol=1e-12 * both.torque.max())
    np.testing.assert_allclose(both.mean_feed_frame, parts[0].mean_feed_frame + parts[1].mean_feed_frame,
                               atol=1e-12 * scale)
    # and the sum is not trivially one part
    assert np.abs(parts[0].fy).max() > 0.1 * scale and np.abs(parts[1].fy).max() > 0.1 * scale


def test_interval_wrapping_through_zero() -> None:
    """An arc across phi = 0 (e.g. 330..390) is the union of 330..360 and 0..30."""
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=3, helix_angle=35.0)
    wrap = compute_cl_forces(slot_map([(330.0, 390.0)], 4.0, 20, 5.0), tool, K, rpm=RPM, feed_per_tooth=C)
    split = compute_cl_forces(slot_map([(330.0, 360.0), (0.0, 30.0)], 4.0, 20, 5.0), tool, K, rpm=RPM,
                              feed_per_tooth=C)
    np.testing.assert_allclose(wrap.feed_frame, split.feed_frame, atol=1e-9)
    np.testing.assert_allclose(wrap.mean_feed_frame, split.mean_feed_frame, atol=1e-9)


@pytest.mark.parametrize("feed_angle", [0.0, 30.0, 215.0])
def test_m4_is_the_mirror_image(feed_angle: float) -> None:
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=3, helix_angle=30.0)
    args = ([(0.0, 75.0)], 4.0, 20, 5.0)
    cw = compute_cl_forces(slot_map(*args, feed_angle=feed_angle), tool, K, rpm=RPM, feed_per_tooth=C)
    ccw = compute_cl_forces(slot_map(*args, feed_angle=feed_angle, spindle=SpindleDirection.CCW), tool, K,
                            rpm=RPM, feed_per_tooth=C)
    np.testing.assert_allclose(ccw.fx, cw.fx, atol=1e-9)
    np.testing.assert_allclose(ccw.fy, -cw.fy, atol=1e-9)
    np.testing.assert_allclose(ccw.fz, cw.fz, atol=1e-9)
    np.testing.assert_allclose(ccw.torque, cw.torque, atol=1e-12)
    assert np.abs(cw.fy).max() > 1.0  # the mirror is not trivial
    # machine frame: reflection across the feed line
    t = math.radians(2 * feed_angle)
    mirror = np.array([[math.cos(t), math.sin(t), 0], [math.sin(t), -math.cos(t), 0], [0, 0, 1]])
    np.testing.assert_allclose(ccw.machine_frame, cw.machine_frame @ mirror.T, atol=1e-9)
    np.testing.assert_allclose(ccw.mean_machine_frame, mirror @ cw.mean_machine_frame, atol=1e-9)


def test_machine_frame_rotation() -> None:
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=2, helix_angle=30.0)
    east = compute_cl_forces(slot_map([(0.0, 180.0)], 4.0, 20, 5.0), tool, K, rpm=RPM, feed_per_tooth=C)
    north = compute_cl_forces(slot_map([(0.0, 180.0)], 4.0, 20, 5.0, feed_angle=90.0), tool, K, rpm=RPM,
                              feed_per_tooth=C)
    np.testing.assert_allclose(north.feed_frame, east.feed_frame, atol=1e-12)
    np.testing.assert_allclose(east.machine_frame, east.feed_frame, atol=1e-12)
    # feeding +Y: the feed-frame x is machine +Y, the feed-frame y is machine -X
    np.testing.assert_allclose(north.fx_machine, -east.fy, atol=1e-9)
    np.testing.assert_allclose(north.fy_machine, east.fx, atol=1e-9)
    np.testing.assert_allclose(north.fz_machine, east.fz, atol=1e-12)
    np.testing.assert_allclose(north.resultant, east.resultant, atol=1e-9)


def test_ball_end_slot_matches_axial_immersion_integrals() -> None:
    """Ball end mill in a full slot of depth a < R: kappa runs from 0 at the tip to k_a = acos(1 - a/R).
    With int over the slot of sin^2 = pi/2, sin = 2, sin cos = cos = 0, and dz = R sin k dk:

        mean Fx = -(N c / 4)(Krc Is - Kac Ic) - (N / pi)(Kre a - Kae r_a)
        mean Fy = +(N c / 4) Ktc a + (N / pi) Kte L
        mean Fz = (N c / pi)(Krc Ic + Kac Is) + (N / 2)(Kre r_a + Kae a)

    Is = int sin k dz = R (k_a/2 - sin(2 k_a)/4), Ic = int cos k dz = R sin(k_a)^2 / 2, r_a = R sin k_a,
    L = R k_a the edge length."""
    r, a, n = 5.0, 3.0, 2
    tool = BallEndMill(diameter=2 * r, flute_length=20.0, flutes=n, helix_angle=30.0)
    m = 300
    dz = a / m
    slices = tuple(
        SliceEngagement((i + 0.5) * dz, (i + 0.5) * dz, tool.profile().radius_at((i + 0.5) * dz),
                        (AngleInterval(0.0, 180.0),))
        for i in range(m)
    )
    emap = EngagementMap(7, (0.0, 0.0, 0.0), (-1.0, 0.0, 0.0), "T2", SpindleDirection.CW, 0.0, CLStatus.ENGAGED,
                         feed=1000.0, slices=slices, axial_range=(0.0, a))
    f = compute_cl_forces(emap, tool, K, rpm=RPM, feed_per_tooth=C)
    ka = math.acos(1 - a / r)
    i_s = r * (ka / 2 - math.sin(2 * ka) / 4)
    i_c = r * math.sin(ka) ** 2 / 2
    r_a = r * math.sin(ka)
    want = np.array([
        -(n * C / 4) * (K.krc * i_s - K.kac * i_c) - (n / math.pi) * (K.kre * a - K.kae * r_a),
        (n * C / 4) * K.ktc * a + (n / math.pi) * K.kte * r * ka,
        (n * C / math.pi) * (K.krc * i_c + K.kac * i_s) + (n / 2) * (K.kre * r_a + K.kae * a),
    ])
    np.testing.assert_allclose(f.mean_feed_frame, want, rtol=1e-3)
    # the same slot with a flat end mill differs (the tip's kappa matters), so the test can fail
    flat = compute_cl_forces(emap, FlatEndMill(diameter=2 * r, flute_length=20.0, flutes=n), K, rpm=RPM,
                             feed_per_tooth=C)
    assert abs(flat.mean_feed_frame[2] - want[2]) > 0.05 * abs(want[2])


def test_band_heights_from_spacing_and_axial_range() -> None:
    """Slices sampled at the ends of the contact (z = 0, 1, ..., 10) still count 10 mm of edge: only
    Kae acts, mean Fz = N a Kae / 2 in a slot."""
    only_kae = CuttingCoefficients(0, 0, 0, 0, 0, 3.0)
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=3, helix_angle=30.0)
    slices = tuple(SliceEngagement(float(z), float(z), 5.0, (AngleInterval(0, 180),)) for z in range(11))
    emap = EngagementMap(1, (0, 0, 0), (-1, 0, 0), "T", SpindleDirection.CW, 0.0, CLStatus.ENGAGED, feed=500.0,
                         slices=slices, axial_range=(0.0, 10.0))
    f = compute_cl_forces(emap, tool, only_kae, rpm=RPM, feed_per_tooth=C)
    assert f.mean_feed_frame[2] == pytest.approx(3 * 10.0 * 3.0 / 2, rel=1e-12)
    # with dz the bands are the grid cells [k dz, (k+1) dz] holding the slices: [z, z + 0.5] here
    g = compute_cl_forces(emap, tool, only_kae, rpm=RPM, feed_per_tooth=C, dz=0.5)
    assert g.mean_feed_frame[2] == pytest.approx(3 * 5.0 * 3.0 / 2, rel=1e-12)
    # bands above the flute length (shank) do not cut
    short = FlatEndMill(diameter=10.0, flute_length=4.0, flutes=3, helix_angle=30.0)
    h = compute_cl_forces(emap, short, only_kae, rpm=RPM, feed_per_tooth=C)
    assert h.mean_feed_frame[2] == pytest.approx(3 * 4.0 * 3.0 / 2, rel=1e-12)


def test_engine_band_convention_with_dz() -> None:
    """The B-Rep engine cuts the flutes into bands [k dz, (k+1) dz] and puts each slice in the middle of
    its part in contact: contact 0.3..2.5 mm with dz = 1 gives slices at 0.65, 1.5, 2.25 standing for
    0.7, 1.0 and 0.5 mm. Each slice gets a different arc so that the split, not only the total, shows
    (only Kae acts: mean Fz = N Kae / (2 pi) * sum(band * span))."""
    only_kae = CuttingCoefficients(0, 0, 0, 0, 0, 2.0)
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=2, helix_angle=30.0)
    spans = {0.65: (0.0, 180.0), 1.5: (0.0, 60.0), 2.25: (0.0, 150.0)}
    slices = tuple(SliceEngagement(z, z, 5.0, (AngleInterval(*iv),)) for z, iv in spans.items())
    emap = EngagementMap(1, (0, 0, 0), (-1, 0, 0), "T", SpindleDirection.CW, 0.0, CLStatus.ENGAGED, feed=500.0,
                         slices=slices, axial_range=(0.3, 2.5))
    band = {0.65: 0.7, 1.5: 1.0, 2.25: 0.5}

    def expected(bands: dict[float, float]) -> float:
        return 2 * 2.0 / (2 * math.pi) * sum(bands[z] * math.radians(b - a) for z, (a, b) in spans.items())

    f = compute_cl_forces(emap, tool, only_kae, rpm=RPM, feed_per_tooth=C, dz=1.0)
    assert f.mean_feed_frame[2] == pytest.approx(expected(band), rel=1e-12)
    # without dz the midpoints split the same 2.2 mm differently (0.775, 0.8, 0.625)
    g = compute_cl_forces(emap, tool, only_kae, rpm=RPM, feed_per_tooth=C)
    assert g.mean_feed_frame[2] == pytest.approx(expected({0.65: 0.775, 1.5: 0.8, 2.25: 0.625}), rel=1e-12)
    assert abs(g.mean_feed_frame[2] - f.mean_feed_frame[2]) > 1e-3
    with pytest.raises(InputError, match="one band"):
        compute_cl_forces(emap, tool, only_kae, rpm=RPM, feed_per_tooth=C, dz=3.0)


def test_single_slice_needs_dz() -> None:
    tool = FlatEndMill(diameter=10.0, flute_length=20.0)
    emap = slot_map([(0.0, 180.0)], 1.0, 1, 5.0)
    with pytest.raises(InputError, match="pass dz"):
        compute_cl_forces(emap, tool, K, rpm=RPM, feed_per_tooth=C)
    f = compute_cl_forces(emap, tool, K, rpm=RPM, feed_per_tooth=C, dz=1.0)
    np.testing.assert_allclose(f.mean_feed_frame, textbook_mean(0, math.pi, 2, 1.0, C, K), rtol=1e-9)


@pytest.mark.parametrize(
    "tool",
    [
        FlatEndMill(diameter=10.0, flute_length=20.0),
        BallEndMill(diameter=10.0, flute_length=20.0),
        BullNoseEndMill(diameter=10.0, flute_length=20.0, corner_radius=1.5),
        TaperedEndMill(diameter=6.0, flute_length=20.0, taper_angle=5.0),
        ChamferMill(diameter=10.0, flute_length=20.0, taper_angle=45.0),
        ChamferMill(diameter=10.0, flute_length=20.0, tip_diameter=2.0, taper_angle=30.0),
    ],
    ids=lambda t: t.kind,
)
def test_vectorised_radius_matches_the_model(tool) -> None:
    from fusioncut.model.tools import ToolProfile

    z = np.linspace(0.0, tool.flute_length, 173)
    flutes = ToolProfile(tool.cutting_profile())
    np.testing.assert_allclose(_radius_at_many(tool, z), [flutes.radius_at(v) for v in z], atol=1e-12)


def test_samples_not_a_multiple_of_the_flutes() -> None:
    """The general path (S not divisible by N) agrees with the rolled single-tooth path."""
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=3, helix_angle=30.0)
    emap = slot_map([(20.0, 140.0)], 4.0, 20, 5.0)
    a = compute_cl_forces(emap, tool, K, rpm=RPM, feed_per_tooth=C, samples=360)
    b = compute_cl_forces(emap, tool, K, rpm=RPM, feed_per_tooth=C, samples=1000)
    assert a.angles[9] == b.angles[25] == 9.0
    np.testing.assert_allclose(a.feed_frame[::9], b.feed_frame[::25], atol=1e-9)


def test_peaks_summary_and_readonly() -> None:
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=2, helix_angle=30.0)
    f = compute_cl_forces(slot_map([(0.0, 90.0)], 4.0, 20, 5.0), tool, K, rpm=RPM, feed_per_tooth=C)
    assert isinstance(f, CLForces)
    np.testing.assert_allclose(f.peak_feed_frame, np.abs(f.feed_frame).max(axis=0))
    assert f.resultant_peak >= np.abs(f.feed_frame).max()
    assert f.torque_peak >= f.mean_torque > 0
    assert f.power_peak == pytest.approx(f.torque_peak * RPM * math.pi / 30)
    s = f.summary()
    assert s["fy_peak_N"] == pytest.approx(f.peak_feed_frame[1])
    assert s["power_mean_W"] == pytest.approx(f.power_mean)
    with pytest.raises(ValueError):
        f.feed_frame[0, 0] = 1.0


def test_feed_per_tooth_helpers() -> None:
    assert feed_per_tooth(1200.0, 6000.0, 2) == pytest.approx(0.1)
    flat = slot_map([(0.0, 180.0)], 2.0, 4, 5.0, feed=1200.0)
    assert feed_per_tooth_from_map(flat, 6000.0, 2) == pytest.approx(0.1)
    ramp = dataclasses.replace(flat, start=(9.0, 0.0, 1.0))  # a 45 deg ramp down to (10, 0, 0)
    assert feed_per_tooth_from_map(ramp, 6000.0, 2) == pytest.approx(0.1 / math.sqrt(2))
    with pytest.raises(InputError, match="CL 7"):
        feed_per_tooth_from_map(slot_map([(0.0, 180.0)], 2.0, 4, 5.0, feed=None), 6000.0, 2)
    with pytest.raises(InputError):
        feed_per_tooth(100.0, 0.0, 2)
    # compute_cl_forces uses the map's feed when none is given
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=2)
    f = compute_cl_forces(flat, tool, K, rpm=6000.0)
    assert f.feed_per_tooth == pytest.approx(0.1)


def test_failed_air_and_batch() -> None:
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=2)
    failed = slot_map([], 2.0, 4, 5.0, status=CLStatus.FAILED)
    with pytest.raises(GeometryError, match="CL 7"):
        compute_cl_forces(failed, tool, K, rpm=RPM)
    air = slot_map([], 2.0, 4, 5.0, status=CLStatus.AIR)
    f = compute_cl_forces(air, tool, K, rpm=RPM)
    assert not f.feed_frame.any() and f.mean_torque == 0.0 and f.resultant_peak == 0.0
    cut = slot_map([(0.0, 180.0)], 2.0, 4, 5.0)
    out = compute_forces([failed, air, cut], tool, K, rpm=RPM)
    assert out[0] is None and out[1] is not None and out[2] is not None
    assert out[2].mean_feed_frame[1] > 0


def test_coefficients_validation_and_library() -> None:
    with pytest.raises(InputError):
        CuttingCoefficients(math.nan, 1, 1, 1, 1, 1)
    assert get_coefficients(" AL7075-T6 ") is AL7075_T6_CARBIDE
    assert all(c.source for c in MATERIALS.values())
    with pytest.raises(InputError, match="known"):
        get_coefficients("unobtainium")
