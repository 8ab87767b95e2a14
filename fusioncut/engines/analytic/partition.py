"""The cells a CL's removed volume is integrated over: its footprint tiled, each tile quartered until
each cell's integral is cheap, in one kernel.

Machine frame, mm. The footprint's box within the stock is cut into equal tiles no wider than
``tile`` (a long CL's footprint meets hundreds of earlier sweeps, a point in it only those of its
tile). A cell keeps the earlier sweeps :func:`.cells.relevant_sweeps` leaves it (footprint boxes
meeting the cell first); one it proves empty is dropped. A cell wider than ``min_cell`` is quartered
where more than ``cell_sweeps`` sweeps are left, where a quarter is proven empty (its area then costs
nothing) or, in a cell left to the adaptive integral, where a quarter's sweeps are all level and flat (its
closed form then replaces a share of the adaptive integral: a helical entry or a lead-in reaching into a
corner of a level cut's footprint) or where a quarter sheds the cell's sweeps (an adaptive integral's
break points and probes grow with the sweeps it meets): for a flat end mill's CL in a cell wider than its
radius, a quarter that leaves one out; for a round tool's, in a cell wider than twice its radius, one that
leaves half of them out (its surfaces bend all over a cell, and smaller quarters cost more than they shed),
unless its closed form costs less: all sweeps level and flat
(:func:`.flat.all_level_flat`) and at most ``flat_sweeps`` of them, or its polar integral skips what is empty
(:func:`.polar.polar_applies`, at most ``polar_sweeps`` and an annulus an earlier helix holds,
:func:`.polar.held_annuli`). A quarter needs only its cell's sweeps: one left out there gives ``h``
nowhere in the cell (its floor over the cell is at least what ``h`` is at most). Cells are taken last
in, first out, as a stack: the order the integrals are summed in.

Each cell's sweeps come lowest floor first: the least lower surface is then met early, and the
others' closed-form floors skip them (:func:`.volume.height_and_cause`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.cells import cell_ceiling, cell_floor, footprint_ceilings, relevant_sweeps
from fusioncut.engines.analytic.flat import all_level_flat
from fusioncut.engines.analytic.polar import held_annuli, polar_applies
from fusioncut.engines.analytic.profile import is_flat

ADAPTIVE, FLAT, POLAR = 0, 1, 2  # how a cell is integrated (.volume, .flat, .polar)


@njit(cache=True)
def _cull(x0, y0, x1, y1, rows, S, P, R, C, CB, PP, NPC, RR, zb, zt, cell_sweeps, most, foot):
    """(whether nothing is removed in the cell, the rows of ``rows`` (indices into ``C``) it keeps, their
    floors): the rows whose boxes meet the cell, then :func:`.cells.relevant_sweeps` of them. A row whose
    box holds the cell and whose ceiling over it, or whose bound over the CL's whole footprint (``foot``,
    :func:`.cells.footprint_ceilings`), is at most the CL's own floor there makes the cell empty
    whatever the others do (relevant_sweeps' cap is at most that ceiling): the rows are first searched for
    one, latest first (the pass before this one, as a trochoid's return runs inside its last loop), and
    an empty cell's rows are not kept (nobody reads them)."""
    own = max(zb, cell_floor(S, P, R, x0, y0, x1, y1, 0.0))
    for i in range(rows.shape[0] - 1, -1, -1):
        j = rows[i]
        if foot[j] <= own:
            return True, rows[:0], np.empty(0)
        if CB[j, 0] <= x0 and CB[j, 2] >= x1 and CB[j, 1] <= y0 and CB[j, 3] >= y1:
            k = int(C[j, 12])
            if cell_ceiling(C[j], PP[k, :NPC[k]], RR[k], x0, y0, x1, y1) <= own:
                return True, rows[:0], np.empty(0)
    meet = np.empty(rows.shape[0], dtype=np.int64)
    m = 0
    for i in range(rows.shape[0]):
        j = rows[i]
        if CB[j, 0] <= x1 and CB[j, 2] >= x0 and CB[j, 1] <= y1 and CB[j, 3] >= y0:
            meet[m] = j
            m += 1
    meet = meet[:m]
    empty, keep, floors = relevant_sweeps(x0, y0, x1, y1, S, P, R, C[meet], PP, NPC, RR, zb, zt, 0.0, cell_sweeps,
                                          most, foot[meet])
    return empty, meet[keep], floors[keep]


@njit(cache=True)
def volume_cells(x0, y0, x1, y1, tile, S, P, R, C, CB, PP, NPC, RR, zb, zt, min_cell, cell_sweeps, flat_sweeps,
                 polar_sweeps, most, flat_forms=True, polar_forms=True):
    """(cells (n, 4) as (x0, y0, x1, y1), how each is integrated (:data:`FLAT`, :data:`POLAR`,
    :data:`ADAPTIVE`), starts (n + 1), items: cell ``i``'s sweeps are ``C[items[starts[i]:starts[i + 1]]]``,
    lowest floor first) for the rectangle (module docstring). ``most``: :func:`.cells.relevant_sweeps`'
    bound on the dominance search for cells wider than ``min_cell``. ``flat_forms``, ``polar_forms``: whether
    the closed forms are taken where they apply (else those cells are adaptive ones: a differential check)."""
    nx, ny = max(1, math.ceil((x1 - x0) / tile)), max(1, math.ceil((y1 - y0) / tile))
    stack = []
    flat_tool = is_flat(P)
    everything = np.arange(C.shape[0])
    foot = footprint_ceilings(S, R, C, PP, NPC, RR)
    for i in range(nx):
        for j in range(ny):
            cx0 = x0 + (x1 - x0) * i / nx
            cx1 = x0 + (x1 - x0) * (i + 1) / nx if i + 1 < nx else x1
            cy0 = y0 + (y1 - y0) * j / ny
            cy1 = y0 + (y1 - y0) * (j + 1) / ny if j + 1 < ny else y1
            wide = most if cx1 - cx0 > min_cell else np.iinfo(np.int64).max
            empty, keep, floors = _cull(cx0, cy0, cx1, cy1, everything, S, P, R, C, CB, PP, NPC, RR, zb, zt,
                                        cell_sweeps, wide, foot)
            stack.append((cx0, cy0, cx1, cy1, empty, keep, floors))
    cells = []
    kinds = []
    lists = []
    while len(stack):
        cx0, cy0, cx1, cy1, empty, keep, floors = stack.pop()
        if empty:
            continue
        Ck = C[keep]
        n = keep.shape[0]
        flat = flat_forms and all_level_flat(S, P, Ck, PP, NPC)
        polar = polar_forms and not flat and polar_applies(S, P, Ck, PP, NPC)
        if cx1 - cx0 > min_cell and not (flat and n <= flat_sweeps) and not (
                polar and n <= polar_sweeps and held_annuli(S, P, Ck, PP, NPC, RR).shape[0] > 0):
            mx, my = 0.5 * (cx0 + cx1), 0.5 * (cy0 + cy1)
            wide = most if 0.5 * (cx1 - cx0) > min_cell else np.iinfo(np.int64).max
            quarters = []
            any_empty = False
            any_flat = False
            for qx0, qy0, qx1, qy1 in ((cx0, cy0, mx, my), (mx, cy0, cx1, my), (cx0, my, mx, cy1), (mx, my, cx1, cy1)):
                e, k, f = _cull(qx0, qy0, qx1, qy1, keep, S, P, R, C, CB, PP, NPC, RR, zb, zt, cell_sweeps, wide,
                                foot)
                any_empty = any_empty or e
                if flat_forms and not flat and not polar and not e and k.shape[0] < n:
                    any_flat = any_flat or all_level_flat(S, P, C[k], PP, NPC)
                quarters.append((qx0, qy0, qx1, qy1, e, k, f))
            shed = False
            if not flat and not polar and cx1 - cx0 > (R if flat_tool else 2.0 * R):
                for q in quarters:
                    shed = shed or (q[5].shape[0] < n if flat_tool else 2 * q[5].shape[0] <= n)
            if n > cell_sweeps or any_empty or any_flat or shed:
                for q in quarters:
                    stack.append(q)
                continue
        cells.append((cx0, cy0, cx1, cy1))
        kinds.append(FLAT if flat else (POLAR if polar else ADAPTIVE))
        lists.append(keep[np.argsort(floors, kind="mergesort")])
    out = np.empty((len(cells), 4))
    starts = np.zeros(len(cells) + 1, dtype=np.int64)
    for i in range(len(cells)):
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = cells[i]
        starts[i + 1] = starts[i] + lists[i].shape[0]
    items = np.empty(starts[-1], dtype=np.int64)
    for i in range(len(cells)):
        items[starts[i]:starts[i + 1]] = lists[i]
    return out, np.array(kinds, dtype=np.int64), starts, items
