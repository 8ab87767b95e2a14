"""Triangle meshes as files: binary STL.

A mesh here is a float array of shape (n, 3, 3): n triangles, their three corners, x y z in mm,
corners counter-clockwise seen from outside (the facet normal is the right-hand one). Binary STL
is 80 header bytes, a uint32 count, then per triangle the unit normal and the three corners as
little-endian float32 and a zero uint16. Written here with numpy in one structured array: the
format is those 50 bytes a triangle, and the libraries that write it (trimesh, numpy-stl) would be
a dependency of the engines for one ``tofile``.

>>> import numpy as np, tempfile, pathlib
>>> tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], dtype=float)
>>> path = pathlib.Path(tempfile.mkdtemp()) / "t.stl"
>>> write_stl(path, tri, "one facet").stat().st_size
134
>>> read_stl(path).tolist()
[[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]]
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["mesh_volume", "read_stl", "write_stl"]

_FACET = np.dtype([("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])


def write_stl(path: str | Path, triangles: np.ndarray, header: str = "") -> Path:
    """Write ``triangles`` ((n, 3, 3), mm) as a binary STL at ``path``; the header is ``header``
    cut to 80 ASCII bytes. Degenerate triangles get a zero normal."""
    path = Path(path)
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    facets = np.zeros(len(tri), dtype=_FACET)
    facets["normal"] = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    facets["corners"] = tri
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        f.write(header.encode("ascii", "replace")[:80].ljust(80, b" "))
        f.write(np.uint32(len(tri)).astype("<u4").tobytes())
        facets.tofile(f)
    tmp.replace(path)
    return path


def read_stl(path: str | Path) -> np.ndarray:
    """The triangles ((n, 3, 3), float64) of a binary STL written by :func:`write_stl`."""
    data = Path(path).read_bytes()
    n = int(np.frombuffer(data, "<u4", 1, 80)[0])
    if len(data) != 84 + n * _FACET.itemsize:
        raise ValueError(f"{path}: not a binary STL of {n} triangles ({len(data)} bytes)")
    return np.frombuffer(data, _FACET, n, 84)["corners"].astype(np.float64)


def mesh_volume(triangles: np.ndarray) -> float:
    """The volume (mm³) a closed, outward-oriented mesh encloses (the divergence theorem: the sum of
    the signed tetrahedra from the origin to each facet)."""
    tri = np.asarray(triangles, dtype=np.float64)
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)
