"""The analytic engine's workpiece as a height map and as a closed mesh (its IPW STL).

Machine frame, mm. The in-process workpiece is ``stock ∩ {z <= h(x, y)}`` with ``h`` the least
lower surface of the sweeps cut so far (:mod:`.engine`). :func:`height_map` evaluates ``h`` exactly
(:func:`.sweeps.sweep_lower`, each sweep over the grid nodes its footprint box holds, skipped where
its closed-form floor is not below the node's height so far) and clips it to the stock's bottom and
top, at the nodes of a regular grid over the stock's XY box; :func:`ipw_mesh` joins the nodes into
the workpiece's closed surface: two triangles a grid square on top, the stock's four sides from the
bottom up to the boundary nodes' heights, and the bottom as a fan about its centre, so that every
edge is shared by exactly two facets, all facing out.

The heights at the nodes are exact; between them the surface is linear. A vertical wall (a flat
end mill's side) becomes a slope one grid step wide and a cusp between two nodes is cut off by a
chord, so the mesh is a picture of the workpiece: its volume differs from the exact one the results
count by about half a grid step times the walls' area. The step is :data:`NODE_RADII` of the
smallest tool radius cut so far, coarsened until the grid has at most :data:`MAX_NODES` nodes (the
file holds two triangles a node, 50 bytes each).

>>> import numpy as np
>>> from fusioncut.io.mesh import mesh_volume
>>> xs, ys = np.array([0.0, 1.0]), np.array([0.0, 2.0])
>>> tri = ipw_mesh(xs, ys, np.full((2, 2), 3.0), 0.0)
>>> len(tri), round(float(mesh_volume(tri)), 12)
(14, 6.0)
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from fusioncut.engines.analytic.sweeps import sweep_floor, sweep_lower

__all__ = ["MAX_NODES", "NODE_RADII", "grid", "height_map", "ipw_mesh"]

MAX_NODES = 500_000  # grid nodes of a mesh, a bound
NODE_RADII = 0.125  # the grid step, in radii of the smallest tool


def grid(box: tuple[float, ...], step: float, max_nodes: int = MAX_NODES) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (xs, ys) over the XY box ``(x0, y0, x1, y1)`` (mm), both ends included, at most ``step``
    apart, or as far apart as ``max_nodes`` nodes in all allow."""
    x0, y0, x1, y1 = box
    if not step > 0 or not math.isfinite(step):
        raise ValueError(f"the grid step must be a positive number of mm, got {step}")
    w, h = x1 - x0, y1 - y0
    step = max(step, math.sqrt(w * h / max_nodes))
    while (math.ceil(w / step) + 1) * (math.ceil(h / step) + 1) > max_nodes:
        step *= 1.01
    return np.linspace(x0, x1, math.ceil(w / step) + 1), np.linspace(y0, y1, math.ceil(h / step) + 1)


@njit(cache=True)
def _lower_envelope(rows, boxes, PP, NPC, RR, xs, ys, zt):
    """min(zt, least lower surface of ``rows`` at each node), shape (len(ys), len(xs))."""
    nx, ny = xs.shape[0], ys.shape[0]
    Z = np.full((ny, nx), zt)
    dx = (xs[-1] - xs[0]) / max(nx - 1, 1)
    dy = (ys[-1] - ys[0]) / max(ny - 1, 1)
    for j in range(rows.shape[0]):
        S = rows[j]
        if min(S[3], S[6]) >= zt:
            continue
        k = int(S[12])
        P, R = PP[k, :NPC[k]], RR[k]
        # the nodes of the footprint's box, one more each way (sweep_lower is inf beyond the footprint)
        i0 = max(int(math.floor((boxes[j, 0] - xs[0]) / dx)) - 1, 0) if nx > 1 else 0
        i1 = min(int(math.ceil((boxes[j, 2] - xs[0]) / dx)) + 1, nx - 1) if nx > 1 else 0
        j0 = max(int(math.floor((boxes[j, 1] - ys[0]) / dy)) - 1, 0) if ny > 1 else 0
        j1 = min(int(math.ceil((boxes[j, 3] - ys[0]) / dy)) + 1, ny - 1) if ny > 1 else 0
        for b in range(j0, j1 + 1):
            for a in range(i0, i1 + 1):
                if sweep_floor(S, P, R, xs[a], ys[b], 0.0) >= Z[b, a]:
                    continue
                h = sweep_lower(S, P, R, xs[a], ys[b], 0.0)
                if h < Z[b, a]:
                    Z[b, a] = h
    return Z


def height_map(rows: np.ndarray, boxes: np.ndarray, profiles: np.ndarray, counts: np.ndarray, radii: np.ndarray,
               xs: np.ndarray, ys: np.ndarray, bottom: float, top: float) -> np.ndarray:
    """The workpiece's height (mm) at each node (shape (len(ys), len(xs))): the least lower surface
    of the sweeps ``rows`` (footprint boxes ``boxes``, tools in the padded ``profiles`` table,
    :class:`.index.ProfileTable`) clipped to [bottom, top]."""
    Z = _lower_envelope(np.ascontiguousarray(rows, dtype=np.float64), np.ascontiguousarray(boxes, dtype=np.float64),
                        profiles, counts, radii, np.asarray(xs, dtype=np.float64), np.asarray(ys, dtype=np.float64),
                        float(top))
    return np.maximum(Z, bottom)


def ipw_mesh(xs: np.ndarray, ys: np.ndarray, Z: np.ndarray, bottom: float) -> np.ndarray:
    """The closed surface (triangles (n, 3, 3), mm, facing out) of ``{bottom <= z <= Z}`` over the
    grid ``xs`` x ``ys`` (``Z`` of shape (len(ys), len(xs)), linear between the nodes)."""
    X, Y = np.meshgrid(xs, ys)
    V = np.stack([X, Y, Z], axis=-1)
    p00, p10, p11, p01 = V[:-1, :-1], V[:-1, 1:], V[1:, 1:], V[1:, :-1]
    top = np.concatenate([np.stack([p00, p10, p11], axis=-2).reshape(-1, 3, 3),
                          np.stack([p00, p11, p01], axis=-2).reshape(-1, 3, 3)])
    nx, ny = len(xs), len(ys)
    # the boundary nodes counter-clockwise seen from above, closed
    loop = np.concatenate([np.stack([np.arange(nx), np.zeros(nx, int)], 1),
                           np.stack([np.full(ny - 1, nx - 1), np.arange(1, ny)], 1),
                           np.stack([np.arange(nx - 2, -1, -1), np.full(nx - 1, ny - 1)], 1),
                           np.stack([np.zeros(ny - 1, int), np.arange(ny - 2, -1, -1)], 1)])
    T = V[loop[:, 1], loop[:, 0]]
    B = T.copy()
    B[:, 2] = bottom
    Tu, Tw, Bu, Bw = T[:-1], T[1:], B[:-1], B[1:]
    centre = np.broadcast_to([0.5 * (xs[0] + xs[-1]), 0.5 * (ys[0] + ys[-1]), bottom], Bu.shape)
    sides = np.concatenate([np.stack([Bu, Bw, Tw], axis=1), np.stack([Bu, Tw, Tu], axis=1)])
    floor = np.stack([centre, Bw, Bu], axis=1)
    return np.concatenate([top, sides, floor])
