"""Static deflection: the stepped cantilever against its closed forms, and a CL's deflection against the
force model's per-band forces applied through the compliance."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fusioncut.analysis.deflection import SteppedCantilever, cl_deflection
from fusioncut.analysis.forces import compute_cl_forces
from fusioncut.analysis.materials import AL7075_T6_CARBIDE as AL
from fusioncut.errors import InputError
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement, SpindleDirection

E = 6.0e5  # N/mm²


def inertia(d: float) -> float:
    return math.pi * d ** 4 / 64


def test_uniform_cantilever_closed_forms() -> None:
    d, length = 7.938, 31.75  # 5/16 in and 1.25 in, as an inch post writes them (3 decimals)
    beam = SteppedCantilever(((length, d),), E)
    ei = E * inertia(d)
    # tip load at the tip: P L^3 / (3 E I)
    assert beam.compliance([0.0], [0.0])[0, 0] == pytest.approx(length ** 3 / (3 * ei), rel=1e-12)
    # load at height a, tip deflection: P (L - a)^2 (2 L + a) / (6 E I); deflection under the load
    # (L - a)^3 / (3 E I)
    for a in (0.0, 5.2, 17.001, 30.0):
        assert beam.compliance([0.0], [a])[0, 0] == pytest.approx((length - a) ** 2 * (2 * length + a) / (6 * ei),
                                                                  rel=1e-12)
        assert beam.compliance([a], [a])[0, 0] == pytest.approx((length - a) ** 3 / (3 * ei), rel=1e-12)
    # Maxwell's reciprocity: the matrix is symmetric; nothing moves at the clamp
    z = np.array([0.0, 3.3, 9.1, 20.0, length])
    c = beam.compliance(z, z)
    assert c == pytest.approx(c.T, rel=1e-12) and np.all(c[-1] == 0) and np.all(c[:, -1] == 0)


def test_stepped_cantilever_closed_form() -> None:
    """Tip load on flutes (L1, d1) under a shank (L2, d2): P/(3E) (L1^3/I1 + ((L1+L2)^3 - L1^3)/I2)."""
    l1, d1, l2, d2 = 22.225, 0.8 * 9.525, 15.875, 9.525
    beam = SteppedCantilever(((l1, d1), (l2, d2)), E)
    want = (l1 ** 3 / inertia(d1) + ((l1 + l2) ** 3 - l1 ** 3) / inertia(d2)) / (3 * E)
    assert beam.compliance([0.0], [0.0])[0, 0] == pytest.approx(want, rel=1e-12)
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, shoulder_length=25.0, neck_diameter=9.0)
    assert SteppedCantilever.for_tool(tool, 35.0).sections == ((20.0, 8.0), (5.0, 9.0), (10.0, 10.0))
    assert SteppedCantilever.for_tool(tool, 15.0).sections == ((15.0, 8.0),)
    with pytest.raises(InputError):
        SteppedCantilever(((10.0, 0.0),))
    with pytest.raises(InputError):
        beam.compliance([0.0], [40.0])


def _map(depth: float, slices: int, iv: tuple[float, float], spindle=SpindleDirection.CW) -> EngagementMap:
    dz = depth / slices
    sl = tuple(SliceEngagement((k + 0.5) * dz, 0.0, 5.0, (AngleInterval(*iv),)) for k in range(slices))
    return EngagementMap(0, (1.0, 0, 0), (0.0, 0, 0), "T1", spindle, 0.0, CLStatus.ENGAGED, feed=1200.0, slices=sl,
                         axial_range=(0.0, depth))


def test_cl_deflection_is_the_band_forces_through_the_compliance() -> None:
    """Each band's forces (the force model on a map of that band alone) times the compliance, summed."""
    tool = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=3, helix_angle=30.0)
    beam = SteppedCantilever.for_tool(tool, 30.0)
    z = np.array([(k + 0.5) * 0.5 for k in range(8)])
    lag = np.degrees(2 * math.tan(math.radians(30.0)) * z / 10.0)
    # down-milling (wall at 180 deg, on -y: SLE = +dy) and up-milling (wall at 0, on +y: SLE = -dy)
    for iv, wall, phi_wall, sign in (((120.0, 180.0), "down", 180.0, 1.0), ((0.0, 60.0), "up", 0.0, -1.0)):
        emap = _map(4.0, 8, iv)
        got = cl_deflection(emap, tool, AL, beam, rpm=8000.0, dz=0.5)
        per_band = []
        for s in emap.slices:
            lo = s.z - 0.25
            one = dataclasses.replace(emap, slices=(s,), axial_range=(lo, lo + 0.5))
            per_band.append(compute_cl_forces(one, tool, AL, rpm=8000.0, dz=0.5).feed_frame[:, :2])
        forces = np.stack(per_band, axis=1)  # (S, M, 2)
        want = np.einsum("ij,sjk->sik", beam.compliance(z, z), forces)
        assert got.deflection == pytest.approx(want, rel=1e-9, abs=1e-15)
        tip = np.einsum("j,sjk->sk", beam.compliance([0.0], z)[0], forces)
        assert got.tip_peak_mm == pytest.approx(np.hypot(tip[:, 0], tip[:, 1]).max(), rel=1e-9)
        assert got.wall == (wall,) * 8
        for m in range(8):
            t = (phi_wall + lag[m]) % 360
            dy = np.interp(t, np.r_[got.angles, 360.0], np.r_[want[:, m, 1], want[0, m, 1]])
            assert got.sle_mm[m] == pytest.approx(sign * dy, rel=1e-9)
        if wall == "down":
            assert np.all(got.sle_mm > 0)  # pushed away from the wall: material left
            # M4 mirrors the feed-frame y deflection and keeps the SLE
            m4 = cl_deflection(_map(4.0, 8, iv, SpindleDirection.CCW), tool, AL, beam, rpm=8000.0, dz=0.5)
            assert m4.deflection[..., 1] == pytest.approx(-got.deflection[..., 1], rel=1e-12)
            assert m4.sle_mm == pytest.approx(got.sle_mm, rel=1e-12)
    # a band whose arcs reach neither wall angle finishes no wall
    mid = cl_deflection(_map(4.0, 8, (30.0, 150.0)), tool, AL, beam, rpm=8000.0, dz=0.5)
    assert mid.wall == ("",) * 8 and np.isnan(mid.sle_mm).all() and mid.tip_peak_mm > 0
