"""The contact area's integral over the tool's surface (fusioncut.engines.analytic.area) and the
causes of the engaged arcs' ends it splits at (fusioncut.engines.analytic.contact)."""
from __future__ import annotations

import numpy as np
import pytest

from fusioncut.engines.analytic.area import Shape, contact_area
from fusioncut.engines.analytic.contact import material_blocker
from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.analytic.sweeps import line_row
from fusioncut.model import FlatEndMill

R = 2.0
FLAT = lower_profile(FlatEndMill(number=1, diameter=2 * R, flute_length=10.0)).pieces


@pytest.mark.parametrize("kink", [0.3137, 0.5, 0.9001])
def test_a_kink_the_arcs_shape_announces_is_split_at_and_integrated_to_round_off(kink):
    """W(z) = 1 rad up to the kink, then rising by 1 rad/mm: the flat end mill's flank (d = R) has
    the area R * integral of W. Told where the ends' causes change, the rule splits there and is
    exact on both sides (linear W), with a few dozen evaluations."""
    calls = []

    def width(z: float) -> tuple[float, Shape]:
        calls.append(z)
        return 1.0 + max(0.0, z - kink), (1, (0.0, 0.0) if z < kink else (0.0, 2.0))

    area, err = contact_area(width, FLAT, 0.0, 1.0, [], rel_tol=1e-12)
    expected = R * (1.0 + 0.5 * (1.0 - kink) ** 2)
    assert area == pytest.approx(expected, rel=1e-11)
    assert err <= 1e-12 * expected
    assert len(calls) < 120


def test_kinks_between_two_of_a_rules_nodes_are_found_one_after_the_other():
    """Eight kinks 0.007 mm apart, all between two neighbouring nodes of the first rule (a wall's end
    crossing the joints of an earlier pass's short moves): found in one cascade, each part then
    ruled once, instead of one rule per kink that finds the next."""
    kinks = [0.05 + 0.007 * i for i in range(8)]
    calls = []

    def width(z: float) -> tuple[float, Shape]:
        calls.append(z)
        return 1.0 + sum(max(0.0, z - k) for k in kinks), (1, (0.0, 2.0 * sum(z >= k for k in kinks)))

    area, _ = contact_area(width, FLAT, 0.0, 1.0, [], rel_tol=1e-12)
    assert area == pytest.approx(R * (1.0 + sum(0.5 * (1.0 - k) ** 2 for k in kinks)), rel=1e-13)
    assert len(calls) < 340


def test_an_end_whose_cause_flickers_costs_a_bounded_number_of_evaluations_and_no_accuracy():
    """Over the last 1e-4 of the flank the end's cause flips every 1e-9 mm between two codes (the
    lower surface and the wall of one earlier sweep, where they meet tangentially at a ball's
    equator): parts that narrow are not split at kinks and a change within CLUSTER of the last is
    no change of its own, so the rule ends within its budget, exact on the smooth W."""
    calls = []

    def width(z: float) -> tuple[float, Shape]:
        calls.append(z)
        return 1.0 + z * z, (1, (0.0, 2.0 if z < 1.0 - 1e-4 else 2.0 + int(z * 1e9) % 2))

    area, _ = contact_area(width, FLAT, 0.0, 1.0, [], rel_tol=1e-12)
    assert area == pytest.approx(R * 4.0 / 3.0, rel=1e-13)
    assert len(calls) < 1200


def test_material_blocker_names_the_stock_face_or_the_earlier_sweep():
    """-1 in the material; -2 - f outside the stock's face f (x0, y0, z0 = 0..2; x1, y1, z1 = 3..5);
    the row of the earlier sweep whose lower surface is at or below the point."""
    tool = lower_profile(FlatEndMill(number=1, diameter=2 * R, flute_length=10.0))
    stock = np.array([0.0, 0.0, -10.0, 50.0, 50.0, 0.0])
    row = line_row((10.0, 10.0, -2.0), (40.0, 10.0, -2.0), 0)  # a slot 2 mm deep along y = 10
    C = row[None, :]
    CB = np.array([[10.0 - R, 10.0 - R, 40.0 + R, 10.0 + R]])
    PP, NPC, RR = tool.pieces[None, :, :], np.array([len(tool.pieces)]), np.array([R])
    grid = (np.array([0.0, 0.0, 50.0, 1.0]), np.array([0, 1]), np.array([0]))

    def blocker(x, y, z):
        return material_blocker(x, y, z, C, CB, PP, NPC, RR, stock, 1e-10, *grid)

    assert blocker(25.0, 20.0, -1.0) == -1  # beside the slot
    assert blocker(25.0, 10.0, -1.0) == 0  # in the slot
    assert blocker(25.0, 10.0, -3.0) == -1  # below its floor
    assert [blocker(-1.0, 20.0, -1.0), blocker(25.0, -1.0, -1.0), blocker(25.0, 20.0, -11.0)] == [-2, -3, -4]
    assert [blocker(51.0, 20.0, -1.0), blocker(25.0, 51.0, -1.0), blocker(25.0, 20.0, 1.0)] == [-5, -6, -7]


@pytest.mark.parametrize("eps", [1e-3, 1e-4])
def test_a_near_singularity_beyond_a_parts_end_is_closed_in_on_geometrically(eps):
    """W(z) = sqrt(z + eps) over z in [0, 1]: a branch point eps below the range's end, as where an arc's
    end runs almost along the slice's circle. The flank's area R * (2/3) ((1 + eps)^1.5 - eps^1.5) comes
    to 1e-9, and the splits close in on z = 0 by eighths once a halving has found the error there
    (halvings alone took 165 and 255 evaluations)."""
    calls = []

    def width(z: float) -> tuple[float, Shape]:
        calls.append(z)
        return float(np.sqrt(z + eps)), (1, ())

    area, err = contact_area(width, FLAT, 0.0, 1.0, [])
    want = R * (2.0 / 3.0) * ((1.0 + eps) ** 1.5 - eps ** 1.5)
    assert area == pytest.approx(want, rel=1e-9) and err <= 1e-7 * area
    assert len(calls) <= 150 if eps == 1e-3 else len(calls) <= 180


def test_slices_within_round_off_of_a_bull_noses_tip_do_not_stall_the_rule():
    """A bull-nose (R 3, corner 1) whose slices are engaged all round up to 1e-5 mm above its tip, then on
    half the circle (W = 2 pi, then pi); below 1e-12 mm the classification flickers (none engaged between
    2e-14 and 1e-12, as where the tip's flat meets its corner level with the last pass's floor). The
    slices under :data:`.area.TIP_NOISE` are taken as the one there: the area meets its closed form,
    integral of d W ds over the corner (d = 2 + sin phi, z = 1 - cos phi) and the side up to 1.05, to 1e-9
    with its estimate, in a few hundred evaluations (the rule chased the flicker to MAX_EVALS and
    returned an estimate of 10 % of the area)."""
    from fusioncut.engines.analytic.area import MAX_EVALS
    from fusioncut.model import BullNoseEndMill

    z0 = 1e-5
    calls = []

    def width(z: float) -> tuple[float, Shape]:
        calls.append(z)
        if 2e-14 < z < 1e-12:
            return 0.0, (0, ())
        return (2 * np.pi, (-1, ())) if z < z0 else (np.pi, (1, (-8.0, -8.0)))

    pieces = lower_profile(BullNoseEndMill(6, 20, corner_radius=1)).pieces
    area, err = contact_area(width, pieces, 0.0, 1.05, [1.0])
    p0 = np.arccos(1 - z0)
    exact = (2 * np.pi * (2 * p0 + 1 - np.cos(p0)) + np.pi * (2 * (np.pi / 2 - p0) + np.cos(p0))
             + np.pi * 3 * 0.05)
    assert abs(area - exact) <= 1e-9 * exact and err <= 1e-7 * exact
    assert len(calls) < MAX_EVALS / 3
