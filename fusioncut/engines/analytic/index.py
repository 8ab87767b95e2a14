"""The earlier sweeps of a run, and a uniform grid of bins over XY to find those near a place.

Each sweep (a row of :data:`fusioncut.engines.analytic.sweeps.SWEEP_COLUMNS`) is stored with the
box of its footprint ``(x_min, y_min, x_max, y_max)`` (mm, the tool-tip path's XY bounds grown by
the tool's radius ``R``) and the lowest height of its lower surface (the path's lowest tip height,
mm: every lower profile is >= 0 above the tip). A sweep is registered in every bin its box
overlaps, so a query for a box meets only the sweeps registered in the bins the box overlaps,
then keeps those whose own box overlaps it: a point meets only sweeps that can contain it. A bin
holds its rows in a growing array; a query filters its bins' rows by box, height and life as arrays
and makes the survivors unique last (a bin of an adaptive clearing holds thousands of rows, most of
them in the query's other bins too).

A sweep that another one along the **same XY path** lies under is **retired**: no query meets it
again. Two sweeps have the same XY path when their kind, tool part and every column but the heights
are equal (a contour or an adaptive pattern repeated at several depths: the same numbers in the
program, so the same floats); then each tool position of one stands over the other's at the same
``t``, and the heights differ by a function linear in ``t`` (a line's, an XY arc's; a vertical arc's by a
constant), so one whose heights at both ends are at most the other's is at most it everywhere: its
lower surface is at most the other's wherever that one reaches, and the other never gives the least
lower surface (the material) again. A sweep is compared when it is complete, once the next one of
its tool part does not continue it.

Tool lower profiles (:mod:`fusioncut.engines.analytic.profile`) are kept in one padded table
``profiles[k, :counts[k]]`` with their radii ``radii[k]``, indexed by a sweep's ``tool`` column,
so that the numba kernels get every sweep's tool in flat arrays.
"""
from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
from numba import njit

from fusioncut.engines.analytic.profile import LowerProfile
from fusioncut.engines.analytic.sweeps import NCOL
from fusioncut.engines.analytic.vertical import is_vertical, within_quarter


class ProfileTable:
    """The lower profiles a run has met, as padded arrays for the kernels."""

    def __init__(self) -> None:
        self._index: dict[int, int] = {}
        self._profiles: list[LowerProfile] = []
        self.profiles = np.zeros((0, 1, 6))
        self.counts = np.zeros(0, dtype=np.int64)
        self.radii = np.zeros(0)

    def index_of(self, profile: LowerProfile) -> int:
        key = id(profile)
        k = self._index.get(key)
        if k is None:
            k = len(self._profiles)
            self._index[key] = k
            self._profiles.append(profile)
            self.profiles, self.counts, self.radii = _tables(self._profiles)
        return k

    def tables_with(self, profile: LowerProfile) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(profiles, counts, radii) of this table's profiles and then ``profile``, which is not
        added: its index there is ``len(self.counts)``."""
        return _tables([*self._profiles, profile])


def _tables(profiles: list[LowerProfile]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The padded arrays of ``profiles``, in order (module docstring)."""
    width = max(p.pieces.shape[0] for p in profiles)
    table = np.zeros((len(profiles), width, 6))
    for i, p in enumerate(profiles):
        table[i, :p.pieces.shape[0]] = p.pieces
    return (table, np.array([p.pieces.shape[0] for p in profiles], dtype=np.int64),
            np.array([p.radius for p in profiles]))


class SweepIndex:
    """Sweeps in the order they were cut, with their footprint boxes and a grid of bins (``bin_size`` mm)."""

    def __init__(self, bin_size: float) -> None:
        if not bin_size > 0:
            raise ValueError("bin_size must be > 0")
        self.bin_size = bin_size
        self.rows = np.zeros((64, NCOL))
        self.boxes = np.zeros((64, 4))
        self.z_low = np.zeros(64)
        self.size = 0
        self.alive = np.ones(64, dtype=bool)  # False: retired (module docstring)
        # per bin, its rows (a growing array and how much of it is filled); a retired row stays, and
        # near() leaves it out by ``alive``
        self._bins: dict[tuple[int, int], list] = {}
        self._everywhere: list[int] = []  # rows met by every query, in no bin (a round bar's outside)
        self._latest: dict[float, int] = {}  # per tool column, its latest row (a CL's parts interleave)
        self._paths: dict[tuple[float, ...], list[int]] = defaultdict(list)  # complete live rows per XY path

    def _bin_range(self, box) -> tuple[range, range]:
        s = self.bin_size
        return (range(math.floor(box[0] / s), math.floor(box[2] / s) + 1),
                range(math.floor(box[1] / s), math.floor(box[3] / s) + 1))

    def add(self, row: np.ndarray, box: tuple[float, float, float, float], z_low: float,
            everywhere: bool = False) -> int:
        """Store a sweep; one that continues the latest sweep of the same tool part (:func:`continues`,
        the ``tool`` column) is merged into it, so a move cut into many CLs stays one sweep per part
        of the tool (the union of the pieces' sweeps is the sweep of their joined path: the lower
        surface is a minimum over the path). ``everywhere``: a row whose box is the whole stock's is
        put in no bin (there would be as many as the stock holds) and every query meets it. The
        row's index."""
        if everywhere:
            k = self._append(row, box, z_low)
            self._everywhere.append(k)
            return k
        tool = float(row[12])
        k = self._latest.get(tool)
        if k is not None and continues(self.rows[k], row):
            last = self.rows[k]
            last[4:7] = row[4:7]
            last[11] += row[11]
            b = self.boxes[k]
            old = self._bin_range(b)
            box = (min(b[0], box[0]), min(b[1], box[1]), max(b[2], box[2]), max(b[3], box[3]))
            self.boxes[k] = box
            self.z_low[k] = min(self.z_low[k], z_low)
            xs, ys = self._bin_range(box)
            for i in xs:
                for j in ys:
                    if i not in old[0] or j not in old[1]:  # the bins the grown box newly covers
                        self._bin_add((i, j), k)
            return k
        if k is not None:
            self._complete(k)
        k = self._append(row, box, z_low)
        self._latest[tool] = k
        xs, ys = self._bin_range(box)
        for i in xs:
            for j in ys:
                self._bin_add((i, j), k)
        return k

    def _bin_add(self, key: tuple[int, int], k: int) -> None:
        got = self._bins.get(key)
        if got is None:
            self._bins[key] = [np.full(8, k, dtype=np.int64), 1]
            return
        rows, n = got
        if n == rows.shape[0]:
            rows = got[0] = np.concatenate([rows, np.empty(n, dtype=np.int64)])
        rows[n] = k
        got[1] = n + 1

    def _complete(self, k: int) -> None:
        """Row ``k`` is complete: retire it where a live row along the same XY path lies under it, else
        retire those along it that it lies under (module docstring)."""
        r = self.rows[k]
        key = (float(r[0]), float(r[12]), *r[1:3].tolist(), *r[4:6].tolist(), *r[7:12].tolist())
        same = self._paths[key]
        if any(self.rows[m, 3] <= r[3] and self.rows[m, 6] <= r[6] for m in same):
            self._retire(k)
            return
        for m in [m for m in same if r[3] <= self.rows[m, 3] and r[6] <= self.rows[m, 6]]:
            same.remove(m)
            self._retire(m)
        same.append(k)

    def _retire(self, k: int) -> None:
        self.alive[k] = False

    def _append(self, row: np.ndarray, box: tuple[float, float, float, float], z_low: float) -> int:
        if self.size == self.rows.shape[0]:
            grow = self.rows.shape[0]
            self.rows = np.concatenate([self.rows, np.zeros((grow, NCOL))])
            self.boxes = np.concatenate([self.boxes, np.zeros((grow, 4))])
            self.z_low = np.concatenate([self.z_low, np.zeros(grow)])
            self.alive = np.concatenate([self.alive, np.ones(grow, dtype=bool)])
        k = self.size
        self.rows[k], self.boxes[k], self.z_low[k] = row, box, z_low
        self.size += 1
        return k

    def near(self, box: tuple[float, float, float, float], z_max: float = math.inf) -> np.ndarray:
        """Indices (ascending) of the sweeps whose footprint box overlaps ``box`` and whose lower
        surface can be below ``z_max`` (mm)."""
        xs, ys = self._bin_range(box)
        if len(xs) * len(ys) > 4 * max(len(self._bins), 1):
            found = np.flatnonzero(self.alive[:self.size])  # a box over most of the grid: scan them all
        else:
            parts = [np.array(self._everywhere, dtype=np.int64)]
            for i in xs:
                for j in ys:
                    got = self._bins.get((i, j))
                    if got is not None:
                        parts.append(got[0][:got[1]])
            found = np.concatenate(parts)  # a row met in several bins comes once per bin: made unique last
        return _meeting(found, self.boxes, self.z_low, self.alive, *box, z_max)


@njit(cache=True)
def _meeting(found, boxes, z_low, alive, x0, y0, x1, y1, z_max):
    """The rows of ``found`` (a row may come more than once) that are alive, whose box meets [x0, x1] x [y0, y1]
    and whose lowest point is below ``z_max``: ascending, each once."""
    keep = np.empty(found.shape[0], dtype=np.int64)
    n = 0
    for k in found:
        b = boxes[k]
        if alive[k] and b[0] <= x1 and b[2] >= x0 and b[1] <= y1 and b[3] >= y0 and z_low[k] < z_max:
            keep[n] = k
            n += 1
    keep = np.sort(keep[:n])
    m = 0
    for i in range(n):
        if i == 0 or keep[i] != keep[i - 1]:
            keep[m] = keep[i]
            m += 1
    return keep[:m]


def continues(last: np.ndarray, row: np.ndarray) -> bool:
    """Whether sweep ``row`` carries on along ``last``'s path: same tool, starting where it ended
    (1e-12 mm), a line in the same direction or an arc about the same centre with the same radius,
    sense and pitch (rise per radian), to 1e-12 relative; a vertical arc on the same circle, the
    joined piece within one quarter of it (:mod:`.vertical`)."""
    if last[0] != row[0] or last[12] != row[12]:
        return False
    if abs(last[4] - row[1]) > 1e-12 or abs(last[5] - row[2]) > 1e-12 or abs(last[6] - row[3]) > 1e-12:
        return False
    if row[0] == 0.0:
        ux, uy, uz = (float(last[4] - last[1]), float(last[5] - last[2]), float(last[6] - last[3]))
        vx, vy, vz = (float(row[4] - row[1]), float(row[5] - row[2]), float(row[6] - row[3]))
        nu, nv = math.sqrt(ux * ux + uy * uy + uz * uz), math.sqrt(vx * vx + vy * vy + vz * vz)
        if nu == 0.0 or nv == 0.0:
            return False
        cross = math.sqrt((uy * vz - uz * vy) ** 2 + (uz * vx - ux * vz) ** 2 + (ux * vy - uy * vx) ** 2)
        return cross <= 1e-12 * nu * nv and ux * vx + uy * vy + uz * vz > 0
    if last[7] != row[7] or last[8] != row[8] or abs(last[9] - row[9]) > 1e-12 * max(1.0, last[9]):
        return False
    if last[11] * row[11] <= 0:
        return False
    if is_vertical(row):  # on the same circle (its centre's height too), the joined angles within one quarter
        zc_a, zc_b = last[3] - last[9] * math.sin(last[10]), row[3] - row[9] * math.sin(row[10])
        return abs(zc_a - zc_b) <= 1e-12 * max(1.0, last[9]) and within_quarter(last[10], last[11] + row[11])
    pitch_a = (last[6] - last[3]) / last[11]
    pitch_b = (row[6] - row[3]) / row[11]
    return abs(pitch_a - pitch_b) <= 1e-12 * max(1.0, abs(pitch_a))
