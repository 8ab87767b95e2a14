"""The analytic engine's workpiece as a height map and a closed mesh (its IPW STL)."""
from __future__ import annotations

import doctest
import math
from collections import Counter

import numpy as np
import pytest

from fusioncut.engines.analytic import heightmap
from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.analytic.heightmap import grid, ipw_mesh
from fusioncut.engines.base import EngineOptions
from fusioncut.io.mesh import mesh_volume
from fusioncut.model.moves import LinearMove, Toolpath
from fusioncut.model.stock import BoxStock
from fusioncut.model.tools import BallEndMill, FlatEndMill


def test_doctests():
    assert doctest.testmod(heightmap).failed == 0


def closed_and_outward(tri: np.ndarray) -> bool:
    """Every edge is used by exactly two facets, once in each direction (a closed surface whose facets
    all face the same side)."""
    corners = [tuple(map(float, p)) for p in tri.reshape(-1, 3)]
    edges = Counter()
    for i in range(len(tri)):
        a, b, c = corners[3 * i: 3 * i + 3]
        for e in ((a, b), (b, c), (c, a)):
            edges[e] += 1
    return all(n == 1 and edges[(b, a)] == 1 for (a, b), n in edges.items())


def slot_engine(tool, depth: float, decimals: int | None = None) -> AnalyticEngine:
    """A slot along x at y = 10 through a 40 x 20 x 10 mm box, its ends outside the stock."""
    p0, p1 = (-10.0, 10.0, -depth), (50.0, 10.0, -depth)
    if decimals is not None:  # as a post writes them
        p0, p1 = tuple(round(v, decimals) for v in p0), tuple(round(v, decimals) for v in p1)
    engine = AnalyticEngine(EngineOptions(max_segment_length=15.0))
    list(engine.run(Toolpath((LinearMove(p0, p1, feed=600.0, tool=1),), {1: tool}), BoxStock((0, 0, -10), (40, 20, 0))))
    return engine


@pytest.mark.parametrize("decimals", [None, 3])
def test_the_nodes_heights_are_the_ball_slots_closed_form(decimals):
    R, depth = 4.0, 1.5
    engine = slot_engine(BallEndMill(2 * R, 20), depth, decimals)
    tri = engine.ipw_mesh(step=0.25)
    corners = tri.reshape(-1, 3)
    top = corners[(corners[:, 2] > -10) & (corners[:, 0] > 0) & (corners[:, 0] < 40)
                  & (corners[:, 1] > 0) & (corners[:, 1] < 20)]
    y = top[:, 1] - 10.0
    expected = np.where(np.abs(y) < R, -depth + R - np.sqrt(np.maximum(R * R - y * y, 0.0)), 0.0)
    assert np.abs(top[:, 2] - np.minimum(expected, 0.0)).max() < 1e-12
    assert closed_and_outward(tri)


def test_the_mesh_volume_tends_to_the_runs_volume_as_the_grid_refines():
    """A flat slot: the mesh's walls slope over one grid step, so its volume is the exact one plus
    about half a step times the walls' area (2 walls of 40 x 2 mm) and converges linearly."""
    engine = slot_engine(FlatEndMill(8, 20), 2.0)
    exact = engine.ipw_volume
    assert exact == pytest.approx(40 * 20 * 10 - 40 * 8 * 2, rel=1e-9)
    errors = []
    for step in (0.4, 0.2, 0.1):
        tri = engine.ipw_mesh(step)
        assert closed_and_outward(tri)
        errors.append(abs(mesh_volume(tri) - exact))
        assert errors[-1] <= 0.5 * step * 2 * 40 * 2 + 1e-9
    assert errors[2] < errors[1] < errors[0]


def test_an_untouched_stock_is_its_box():
    engine = AnalyticEngine(EngineOptions())
    engine.start(BoxStock((1, 2, -3), (4, 6, 0)))
    tri = engine.ipw_mesh()
    assert mesh_volume(tri) == pytest.approx(3 * 4 * 3, rel=1e-12)
    assert closed_and_outward(tri)


def test_the_grid_keeps_to_its_bound_of_nodes():
    xs, ys = grid((0.0, 0.0, 1000.0, 500.0), 0.01, max_nodes=10_000)
    assert len(xs) * len(ys) <= 10_000
    assert (xs[0], xs[-1], ys[0], ys[-1]) == (0.0, 1000.0, 0.0, 500.0)
    assert np.diff(xs).max() == pytest.approx(np.diff(ys).max(), rel=0.05)
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="grid step"):
            grid((0.0, 0.0, 1.0, 1.0), bad)


def test_a_flat_top_mesh_encloses_its_prism():
    xs, ys = np.linspace(0, 2, 5), np.linspace(0, 1, 3)
    Z = np.full((3, 5), 1.5)
    tri = ipw_mesh(xs, ys, Z, -0.5)
    assert mesh_volume(tri) == pytest.approx(2 * 1 * 2, rel=1e-12)
    assert closed_and_outward(tri)
