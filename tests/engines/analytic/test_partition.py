"""The volume's cells: disjoint, inside the footprint's box, each with the sweeps that can shape it
lowest floor first and integrated the way its sweeps allow; a cell left out removes nothing."""
from __future__ import annotations

import math

import numpy as np

from fusioncut.engines.analytic.cells import cell_floor, footprint_ceilings, relevant_sweeps
from fusioncut.engines.analytic.engine import CELL_SWEEPS, FLAT_SWEEPS, MIN_CELL_RADII, POLAR_SWEEPS, TILE_RADII
from fusioncut.engines.analytic.flat import all_level_flat
from fusioncut.engines.analytic.partition import ADAPTIVE, FLAT, POLAR, volume_cells
from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.analytic.sweeps import arc_row, line_row
from fusioncut.model import BallEndMill, FlatEndMill

R = 3.0
ZB, ZT = -20.0, 0.0


def _case(tool, seed, n=40):
    """A CL along x at z = -4 among ``n`` earlier random level passes (a few ramps) of the same tool."""
    rng = np.random.default_rng(seed)
    prof = lower_profile(tool)
    P, NP, RR = prof.pieces[None], np.array([prof.pieces.shape[0]]), np.array([prof.radius])
    rows = []
    for _ in range(n):
        a, b = rng.uniform(-8, 8, 2), rng.uniform(-8, 8, 2)
        z0 = rng.uniform(-3, -0.5)
        z1 = z0 if rng.random() < 0.8 else z0 - rng.uniform(0, 1)
        rows.append(line_row((*a, z0), (*b, z1), 0))
    C = np.array(rows)
    CB = np.array([(min(r[1], r[4]) - R, min(r[2], r[5]) - R, max(r[1], r[4]) + R, max(r[2], r[5]) + R) for r in C])
    S = line_row((-4.0, 0.5, -4.0), (4.0, -0.5, -4.0), 0)
    return S, prof, C, CB, P, NP, RR


def test_the_cells_are_disjoint_inside_the_box_and_hold_their_relevant_sweeps():
    for tool in (FlatEndMill(2 * R, 20), BallEndMill(2 * R, 20)):
        for seed in range(4):
            S, prof, C, CB, P, NP, RR = _case(tool, seed)
            box = (-4 - R, -0.5 - R, 4 + R, 0.5 + R)
            cells, kinds, starts, items = volume_cells(*box, TILE_RADII * R, S, prof.pieces, R, C, CB, P, NP, RR, ZB,
                                                       ZT, MIN_CELL_RADII * R, CELL_SWEEPS, FLAT_SWEEPS, POLAR_SWEEPS,
                                                       48)
            assert len(cells) > 1
            area = 0.0
            for i, (x0, y0, x1, y1) in enumerate(cells):
                assert box[0] <= x0 < x1 <= box[2] and box[1] <= y0 < y1 <= box[3]
                area += (x1 - x0) * (y1 - y0)
                for j in range(i):  # disjoint: they overlap in no more than an edge
                    a = cells[j]
                    assert min(x1, a[2]) <= max(x0, a[0]) or min(y1, a[3]) <= max(y0, a[1])
                mine = items[starts[i]:starts[i + 1]]
                floors = [cell_floor(C[k], prof.pieces, R, x0, y0, x1, y1, 0.0) for k in mine]
                assert floors == sorted(floors)
                # every sweep that can shape the cell is there (random paths never hold one another, so
                # no dominated one is left out), and only sweeps whose boxes meet it
                empty, keep, _ = relevant_sweeps(x0, y0, x1, y1, S, prof.pieces, R, C, P, NP, RR, ZB, ZT, 0.0,
                                                 math.inf, 0, np.empty(0))
                assert not empty
                assert set(np.flatnonzero(keep)) <= set(mine.tolist())
                assert all(CB[k, 0] <= x1 and CB[k, 2] >= x0 and CB[k, 1] <= y1 and CB[k, 3] >= y0 for k in mine)
                flat = all_level_flat(S, prof.pieces, C[mine], P, NP)
                assert kinds[i] == (FLAT if flat else ADAPTIVE)
                if kinds[i] == ADAPTIVE and x1 - x0 > MIN_CELL_RADII * R:
                    assert len(mine) <= CELL_SWEEPS
            assert area <= (box[2] - box[0]) * (box[3] - box[1]) + 1e-9


def test_without_earlier_sweeps_each_tile_is_one_cell():
    _, prof, *_ = _case(FlatEndMill(2 * R, 20), 0)
    S = line_row((-27.0, 0.0, -4.0), (27.0, 0.0, -4.0), 0)
    empty = np.zeros((0, 13))
    cells, kinds, starts, items = volume_cells(-30.0, -3.0, 30.0, 3.0, TILE_RADII * R, S, prof.pieces, R, empty,
                                               np.zeros((0, 4)), prof.pieces[None], np.array([1]), np.array([R]), ZB,
                                               ZT, MIN_CELL_RADII * R, CELL_SWEEPS, FLAT_SWEEPS, POLAR_SWEEPS, 48)
    assert len(cells) == math.ceil(60 / (TILE_RADII * R)) and set(kinds.tolist()) == {FLAT} and len(items) == 0
    assert cells[:, 0].min() == -30.0 and cells[:, 2].max() == 30.0


def test_an_adaptive_cell_is_quartered_where_a_quarter_is_level_and_flat():
    """A level flat cut among level passes and one ramp reaching a corner of its footprint (a helical
    entry's last turn beside a contour): the quarters the ramp misses are computed in closed form, so
    every cell left to the adaptive integral holds the ramp."""
    prof = lower_profile(FlatEndMill(2 * R, 20))
    P, NP, RR = prof.pieces[None], np.array([prof.pieces.shape[0]]), np.array([prof.radius])
    ramp = line_row((6.0, 4.5, -1.0), (9.0, 4.5, -3.0), 0)
    C = np.array([line_row((-8.0, y, -2.0), (8.0, y, -2.0), 0) for y in (-2.0, 0.0, 2.0)] + [ramp])
    CB = np.array([(min(r[1], r[4]) - R, min(r[2], r[5]) - R, max(r[1], r[4]) + R, max(r[2], r[5]) + R) for r in C])
    S = line_row((-4.0, 0.0, -4.0), (4.0, 0.0, -4.0), 0)
    cells, kinds, starts, items = volume_cells(-7.0, -3.0, 7.0, 3.0, TILE_RADII * R, S, prof.pieces, R, C, CB, P, NP,
                                               RR, ZB, ZT, MIN_CELL_RADII * R, CELL_SWEEPS, FLAT_SWEEPS, POLAR_SWEEPS,
                                               48)
    assert FLAT in kinds.tolist() and ADAPTIVE in kinds.tolist()
    for i in np.flatnonzero(kinds == ADAPTIVE):
        assert 3 in items[starts[i]:starts[i + 1]].tolist()
    for x, y in ((1.0, -2.0), (1.0, 2.0), (5.0, -1.0)):  # beside the CL's path, beyond the ramp's reach
        inside = (cells[:, 0] <= x) & (x <= cells[:, 2]) & (cells[:, 1] <= y) & (y <= cells[:, 3])
        assert set(kinds[inside].tolist()) == {FLAT}


def test_a_flat_cut_beside_a_helical_entry_is_quartered_where_its_quarters_shed_sweeps():
    """The Titan-like program's CL 123 (a 12 mm flat end mill, the adaptive's first passes at z = -4 beside
    its helical entry, two turns of radius 4 from z = 0.5, under the facing passes at z = -1): no sweep
    gives h all over the 12 mm tile, and none is level flat in all of it. An adaptive cell wider than the
    tool's radius is quartered where a quarter leaves a sweep out (each of its quarters keeps all its
    sweeps), since an adaptive integral's cost grows with the sweeps it meets. (With the closed forms
    taken, the level CL's cells there are integrated about the helix's axis, .polar, and not quartered.)"""
    R6 = 6.0
    prof = lower_profile(FlatEndMill(2 * R6, 20))
    P, NP, RR = prof.pieces[None], np.array([prof.pieces.shape[0]]), np.array([prof.radius])
    chords = ((21.0, 22.0, 23.0, 22.0), (23.0, 22.0, 22.997, 22.479), (22.997, 22.479, 22.882, 22.929),
              (22.882, 22.929, 22.664, 23.326), (22.664, 23.326, 22.359, 23.646), (22.359, 23.646, 21.987, 23.87),
              (21.987, 23.87, 21.575, 23.985))
    rows = [arc_row((21.0, 22.0, 0.5), (21.0, 22.0, -4.0), (25.0, 22.0), 4.0, math.pi, -4 * math.pi, 0)]
    rows += [line_row((a, b, -4.0), (c, d, -4.0), 0) for a, b, c, d in chords]
    rows += [line_row((160.0, y, -1.0), (-10.0, y, -1.0), 0) for y in (13.0, 31.0)] + [
        line_row((-10.0, 22.0, -1.0), (160.0, 22.0, -1.0), 0)]
    C = np.array(rows)
    CB = np.array([(min(r[1], r[4]) - R6, min(r[2], r[5]) - R6, max(r[1], r[4]) + R6, max(r[2], r[5]) + R6)
                   for r in C])
    CB[0] = (25.0 - 10.0, 22.0 - 10.0, 25.0 + 10.0, 22.0 + 10.0)  # the helix's: its circle widened by R
    S = line_row((21.575, 23.985, -4.0), (21.148, 23.985, -4.0), 0)
    box = (15.148, 17.985, 27.575, 29.985)
    args = (*box, TILE_RADII * R6, S, prof.pieces, R6, C, CB, P, NP, RR, ZB, ZT, MIN_CELL_RADII * R6, CELL_SWEEPS,
            FLAT_SWEEPS, POLAR_SWEEPS, 48)
    assert volume_cells(*args)[1].tolist() == [POLAR]
    cells, kinds, starts, items = volume_cells(*args, True, False)
    foot = footprint_ceilings(S, R6, C, P, NP, RR)
    assert len(cells) > 1
    for i in np.flatnonzero(kinds == ADAPTIVE):
        x0, y0, x1, y1 = cells[i]
        if x1 - x0 <= R6:
            continue
        mine = items[starts[i]:starts[i + 1]]
        mx, my = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        for q in ((x0, y0, mx, my), (mx, y0, x1, my), (x0, my, mx, y1), (mx, my, x1, y1)):
            _, keep, _ = relevant_sweeps(*q, S, prof.pieces, R6, C[mine], P, NP, RR, ZB, ZT, 0.0, CELL_SWEEPS, 48,
                                         foot[mine])
            assert keep.all()
