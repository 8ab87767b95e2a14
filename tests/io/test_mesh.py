"""Triangle meshes as binary STL."""
from __future__ import annotations

import doctest

import numpy as np
import pytest

from fusioncut.io import mesh
from fusioncut.io.mesh import mesh_volume, read_stl, write_stl


def test_doctests():
    assert doctest.testmod(mesh).failed == 0


def unit_cube() -> np.ndarray:
    """The unit cube's 12 facets, counter-clockwise seen from outside."""
    v = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=float)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return np.array([[v[a], v[b], v[c]] for q in quads for a, b, c in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))])


def test_a_cube_round_trips_with_its_volume_and_outward_normals(tmp_path):
    cube = unit_cube() * 2.0 + 1.0
    assert mesh_volume(cube) == pytest.approx(8.0, rel=1e-12)
    path = write_stl(tmp_path / "cube.stl", cube, "cube")
    back = read_stl(path)
    assert np.array_equal(back, cube.astype(np.float32).astype(np.float64))
    raw = path.read_bytes()
    assert len(raw) == 84 + 12 * 50 and raw[:4] == b"cube"
    normals = np.frombuffer(raw, np.dtype([("n", "<f4", (3,)), ("c", "<f4", (3, 3)), ("a", "<u2")]), 12, 84)["n"]
    centres = back.mean(axis=1) - 2.0  # from the cube's centre (2, 2, 2)
    assert (np.einsum("ij,ij->i", normals, centres) > 0).all()


def test_a_truncated_file_is_refused_naming_it(tmp_path):
    path = write_stl(tmp_path / "t.stl", unit_cube())
    path.write_bytes(path.read_bytes()[:-7])
    with pytest.raises(ValueError, match="t.stl: not a binary STL of 12 triangles"):
        read_stl(path)
