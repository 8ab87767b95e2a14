"""The sweep index: the CLs of one move merge into one sweep with the same lower surface; a query meets
the sweeps whose footprint box overlaps it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fusioncut.engines.analytic.index import SweepIndex, continues
from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.analytic.sweeps import arc_row, line_row, sweep_lower
from fusioncut.model.tools import BallEndMill

BALL = lower_profile(BallEndMill(6, 20))


def helix_piece(a0, a1, z0, z1, c=(1.0, 2.0), rho=4.0):
    p = lambda a, z: (c[0] + rho * math.cos(a), c[1] + rho * math.sin(a), z)  # noqa: E731
    return arc_row(p(a0, z0), p(a1, z1), c, rho, a0, a1 - a0, 0)


def box(row, R=3.0):
    xs, ys = [row[1], row[4]], [row[2], row[5]]
    if row[0] == 1.0:
        xs += [row[7] - row[9], row[7] + row[9]]
        ys += [row[8] - row[9], row[8] + row[9]]
    return (min(xs) - R, min(ys) - R, max(xs) + R, max(ys) + R)


@pytest.mark.parametrize("pieces", [
    [line_row((0, 0, 0), (2, 1, -0.5), 0), line_row((2, 1, -0.5), (6, 3, -1.5), 0)],
    [helix_piece(0.0, 1.0, 0.0, -0.2), helix_piece(1.0, 2.5, -0.2, -0.5), helix_piece(2.5, 7.0, -0.5, -1.4)],
])
def test_pieces_of_one_move_merge_into_their_joined_sweep(pieces):
    index = SweepIndex(5.0)
    for row in pieces:
        index.add(row.copy(), box(row), min(row[3], row[6]))
    assert index.size == 1
    merged = index.rows[0]
    rng = np.random.default_rng(3)
    for px, py in rng.uniform(-8, 10, (300, 2)):
        expected = min(sweep_lower(r, BALL.pieces, BALL.radius, px, py, 0.0) for r in pieces)
        got = sweep_lower(merged, BALL.pieces, BALL.radius, px, py, 0.0)
        assert got == pytest.approx(expected, abs=1e-11) or (math.isinf(got) and math.isinf(expected))
        if not math.isinf(got):
            assert list(index.near((px, py, px, py))) == [0]


def test_sweeps_that_do_not_carry_on_stay_apart():
    a = line_row((0, 0, 0), (2, 0, 0), 0)
    assert not continues(a, line_row((2, 0, 0), (0, 0, 0), 0))  # back along the same line
    assert not continues(a, line_row((2, 0, 0), (4, 0.1, 0), 0))  # a corner
    assert not continues(a, line_row((2, 0, 0), (4, 0, 0), 1))  # another tool
    h = helix_piece(0.0, 1.0, 0.0, -0.2)
    assert not continues(h, helix_piece(1.0, 2.0, -0.2, -0.3))  # another pitch
    assert not continues(h, helix_piece(1.0, 2.0, -0.2, -0.4, rho=4.5))  # another radius
    assert continues(h, helix_piece(1.0, 2.0, -0.2, -0.4))


def test_a_row_over_the_whole_stock_fills_no_bin_and_every_query_meets_it():
    """A round bar's outside over a 500 mm bar under a 0.2 mm tool's 0.4 mm bins would fill 1.5
    million bins; stored as met everywhere it fills none, every query meets it, and a later sweep of
    the same tool is binned and merged as before."""
    from fusioncut.engines.analytic.sweeps import outside_row

    index = SweepIndex(0.4)
    k = index.add(outside_row((0.0, 0.0), 250.0, -11.0, 0), (-250.0, -250.0, 250.0, 250.0), -11.0, everywhere=True)
    assert k == 0 and len(index._bins) == 0
    first = line_row((0, 0, -1), (1, 0, -1), 0)
    assert index.add(first, (-0.1, -0.1, 1.1, 0.1), -1.0) == 1
    assert index.add(line_row((1, 0, -1), (2, 0, -1), 0), (0.9, -0.1, 2.1, 0.1), -1.0) == 1  # merged
    assert index.near((100.0, 100.0, 100.5, 100.5)).tolist() == [0]
    assert index.near((0.5, 0.0, 0.6, 0.05)).tolist() == [0, 1]
    assert index.near((0.5, 0.0, 0.6, 0.05), z_max=-20.0).tolist() == []


def _lowest(index, rows, px, py):
    return min(sweep_lower(index.rows[k], BALL.pieces, BALL.radius, px, py, 0.0) for k in rows)


def test_a_sweep_under_another_along_the_same_path_retires_it():
    """A pass (two merged pieces) repeated along the same XY path deeper retires the first once complete;
    one repeated higher retires itself; one shifted a nanometre, or a ramp crossing the first's heights,
    stays. The least lower surface over the sweeps a query meets is the least over all of them."""
    def pass_at(z0, z1=None, dy=0.0):
        z1 = z0 if z1 is None else z1
        zm = 0.5 * (z0 + z1)
        return [line_row((0, dy, z0), (2, 1 + dy, zm), 0), line_row((2, 1 + dy, zm), (4, 2 + dy, z1), 0)]

    index = SweepIndex(5.0)
    moves = [pass_at(-1.0), pass_at(-2.0), pass_at(-0.5), pass_at(-1.5, dy=1e-9), pass_at(-3.0, -0.2),
             [line_row((9, 9, 0), (9, 9, -1), 0)]]  # the last completes the one before
    for rows in moves:
        for row in rows:
            index.add(row.copy(), box(row), min(row[3], row[6]))
    assert index.size == 6
    assert index.alive[:index.size].tolist() == [False, True, False, True, True, True]
    everything = np.arange(index.size)
    rng = np.random.default_rng(5)
    for px, py in rng.uniform(-4, 8, (300, 2)):
        near = index.near((px, py, px, py))
        assert not set(near) & {0, 2}
        if len(near):
            assert _lowest(index, near, px, py) == _lowest(index, everything, px, py)


def test_retiring_sweeps_leaves_every_map_as_it_was(monkeypatch):
    """A rounded-square contour with a bull-nose mill at three depths, then again higher, then a ball
    along it deeper: the maps with sweeps retired are those without (to the integrals' tolerances); the
    first depths' sweeps and the higher pass's are retired."""
    from fusioncut.engines.analytic.engine import AnalyticEngine
    from fusioncut.engines.base import EngineOptions
    from fusioncut.model import ArcMove, BallEndMill, BoxStock, BullNoseEndMill, LinearMove, Toolpath

    def contour(z, tool):
        pts = [(-5, -8), (5, -8), (8, -5), (8, 5), (5, 8), (-5, 8), (-8, 5), (-8, -5)]
        centres = [(5, -5), (5, 5), (-5, 5), (-5, -5)]
        out = [LinearMove((-5, -8, 5), (-5, -8, z), feed=300.0, tool=tool)]
        for i in range(4):
            a, b, c = pts[2 * i], pts[2 * i + 1], pts[(2 * i + 2) % 8]
            out.append(LinearMove((*a, z), (*b, z), feed=600.0, tool=tool))
            out.append(ArcMove((*b, z), (*c, z), center=(*centres[i], z), feed=600.0, tool=tool))
        return out + [LinearMove((-5, -8, z), (-5, -8, 5), feed=None, tool=tool, rapid=True)]

    moves = [m for z in (-1.0, -2.0, -3.0, -1.5) for m in contour(z, 1)] + contour(-3.5, 2)
    tp = Toolpath(tuple(moves), {1: BullNoseEndMill(6, 20, corner_radius=1.0), 2: BallEndMill(4, 20)})
    stock = BoxStock((-15, -15, -10), (15, 15, 0))

    def run():
        engine = AnalyticEngine(EngineOptions(max_segment_length=4.0, slice_height=0.5))
        return engine, list(engine.run(tp, stock))

    retiring, got = run()
    monkeypatch.setattr(SweepIndex, "_complete", lambda self, k: None)
    _, want = run()
    assert (~retiring._index.alive[:retiring._index.size]).sum() >= 27  # three passes of 9 sweeps at least
    assert sum(m.removed_volume for m in got[-12:]) > 1.0
    assert len(got) == len(want)
    for g, w in zip(got, want):
        assert g.removed_volume == pytest.approx(w.removed_volume, rel=1e-7, abs=1e-9)
        assert len(g.slices) == len(w.slices)
        for sg, sw in zip(g.slices, w.slices):
            assert [e for i in sg.intervals for e in (i.entry, i.exit)] == pytest.approx(
                [e for i in sw.intervals for e in (i.entry, i.exit)], abs=1e-6)


def test_near_is_the_brute_force_filter_each_row_once():
    """Random lines spanning up to a dozen 2 mm bins, some retired: for random query boxes and heights,
    ``near`` gives exactly the live rows whose box meets the query's and whose lowest tip is below
    ``z_max``, ascending and each once (a row is met once per bin it fills)."""
    rng = np.random.default_rng(11)
    index = SweepIndex(2.0)
    for _ in range(300):
        (x0, y0), (dx, dy) = rng.uniform(-20, 20, 2), rng.uniform(-6, 6, 2)
        z = float(rng.uniform(-5, 0))
        row = line_row((x0, y0, z), (x0 + dx, y0 + dy, z - 0.1), 0)  # no two continue each other
        index.add(row, box(row), z - 0.1)
    index.alive[rng.choice(index.size, 60, replace=False)] = False
    b, low, alive = index.boxes[:index.size], index.z_low[:index.size], index.alive[:index.size]
    for _ in range(200):
        (qx, qy), (w, h), z_max = rng.uniform(-25, 25, 2), rng.uniform(0, 8, 2), float(rng.uniform(-5, 1))
        q = (qx, qy, qx + w, qy + h)
        brute = np.flatnonzero(alive & (b[:, 0] <= q[2]) & (b[:, 2] >= q[0]) & (b[:, 1] <= q[3]) & (b[:, 3] >= q[1])
                               & (low < z_max))
        assert index.near(q, z_max).tolist() == brute.tolist()
