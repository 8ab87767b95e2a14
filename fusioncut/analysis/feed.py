"""Feed advice: per CL, the feed that keeps the cutting load at a limit (feed-rate optimisation).

What VERICUT's optimiser and similar tools do, on our engagement maps and force model
(:mod:`fusioncut.analysis.forces`): for every CL segment find the largest feed at which

* the peak resultant force ``max |F|`` over a spindle revolution stays at most ``max_force`` (N),
* the peak uncut chip thickness stays at most ``max_chip_thickness`` (mm; the "chip thinning" method:
  at small radial engagement the chip is thinner than the feed per tooth, so the feed can rise),
* the peak spindle cutting power stays at most ``max_power`` (W),
* the material removal rate stays at most ``max_mrr`` (mm³/min; the "volume removal" method),

whichever of them are given (the smallest feed wins), clamped to ``[min_feed, max_feed]`` (mm/min).

How the feed is found (exactly, no iteration)
---------------------------------------------
Every force, the torque and the chip are linear in the feed per tooth ``c``: ``F(phi) = c A(phi) +
E(phi)`` (cutting part plus edge part), ``c = k * feed`` with ``k = (horizontal fraction) / (rpm *
flutes)``. ``|F|`` is not linear because of the vector sum, but at each of the ``samples`` spindle
angles ``|c A + E| <= L`` is a quadratic inequality in ``c`` whose solutions form an interval; the
feeds meeting the limit at every angle are the intersection of those intervals, and the advice is
its upper end. The peak force at that feed equals the limit (at the binding angle), which the tests
check. Power is the same with one component (torque), chip thickness and MRR scale exactly.

Which CLs get advice
--------------------
* rapids: none (``advised_feed_mm_min`` NaN); the rewriter never touches them.
* air CLs (nothing touched): keep the programmed feed, or get ``max_feed`` with ``air_feed=True``.
* failed CLs (engagement unknown), feed moves without a feed or spindle speed: keep the programmed
  feed and are flagged in ``note``.
* engaged CLs whose chip the model does not see are never *raised* above the programmed feed: pure
  plunges (no horizontal feed: the model's chip comes from the horizontal feed only), CLs that move
  down (ramps, unless ``raise_ramps=True``: the axial load of the descent is not modelled), and CLs
  that removed material but have no contact left at their end point (the engine reports the
  engagement at the end of a segment; split long moves with ``max_segment_length`` for finer advice).
* a CL where no feed meets the limits (e.g. the edge forces alone exceed ``max_force``) gets
  ``min_feed`` and the note ``unreachable`` - except a plunge, whose modelled load does not depend
  on its feed: it keeps the programmed feed (note ``unreachable plunge``).

Smoothing (so the program does not get an F word on every tiny segment)
-----------------------------------------------------------------------
1. **Quantisation**: a feed set by a limit is rounded *down* to a multiple of ``quantum`` (default
   5 %) of the programmed feed, like steps of a feed-override knob; consecutive CLs with similar
   loads then share one feed, and a change is at least one step.
2. **Minimum run**: every stretch of consecutive CLs at one feed lasts at least ``min_run_length``
   mm of path (default: the tool diameter), unless it is lower than the feed on each side: a shorter
   stretch is lowered to the higher of its lower neighbours and merged with it, shortest first
   (:func:`merge_short_runs`). So smoothing only ever *lowers* a feed - never above what the limits
   allow - and keeps every dip a limit needs, however short; a staircase of small steps on tiny
   segments (a ramp into the material) becomes one step. Stretches end at rapids.
Fixed CLs (failed, programmed-feed air CLs, missing data) keep their feed after smoothing.

Units: feeds mm/min, forces N, power W, chip thickness mm, MRR mm³/min, lengths mm. The engagement
is that of the end point of each CL segment; forces are sampled at ``samples`` spindle angles per
revolution (the peak between samples can be slightly higher).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

from fusioncut.analysis.forces import CuttingCoefficients, compute_cl_forces, peak_chip_thickness
from fusioncut.analysis.result_maps import engagement_maps_from_results, results_slice_height
from fusioncut.errors import InputError
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.tools import MillingTool

__all__ = ["FEED_COLUMNS", "FeedAdvice", "FeedLimit", "advise_feeds", "largest_feasible", "merge_short_runs", "same_source_file"]

QUANTITIES = ("force", "chip", "power", "mrr")
_LIMIT_FIELDS = {"force": "max_force", "chip": "max_chip_thickness", "power": "max_power", "mrr": "max_mrr"}
_TINY = 1e-12


@dataclass(frozen=True)
class FeedLimit:
    """What the advice must respect; give at least one of the four limits.

    ``max_force`` (N): peak resultant force on the tool over a revolution. ``max_chip_thickness``
    (mm): peak uncut chip thickness. ``max_power`` (W): peak spindle cutting power. ``max_mrr``
    (mm³/min): material removal rate. ``min_feed``, ``max_feed`` (mm/min) clamp the advice; when not
    given they default to 10 % of the smallest and to the largest programmed feed of the engaged
    CLs (so by default the advice never feeds faster than the program ever does). ``air_feed``: air
    CLs get ``max_feed`` instead of their programmed feed. ``raise_ramps``: allow CLs moving down to
    be fed faster than programmed.
    """

    max_force: float | None = None
    max_chip_thickness: float | None = None
    max_power: float | None = None
    max_mrr: float | None = None
    min_feed: float | None = None
    max_feed: float | None = None
    air_feed: bool = False
    raise_ramps: bool = False

    def __post_init__(self) -> None:
        for name in ("max_force", "max_chip_thickness", "max_power", "max_mrr", "min_feed", "max_feed"):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InputError(f"{name} must be a finite number > 0, got {v!r}")
        if all(getattr(self, f) is None for f in _LIMIT_FIELDS.values()):
            raise InputError("give at least one limit: max_force, max_chip_thickness, max_power or max_mrr")
        if self.min_feed is not None and self.max_feed is not None and self.min_feed > self.max_feed:
            raise InputError(f"min_feed {self.min_feed:g} mm/min is above max_feed {self.max_feed:g} mm/min")

    def value(self, quantity: str) -> float | None:
        """The limit on ``quantity`` (one of ``force``, ``chip``, ``power``, ``mrr``)."""
        return getattr(self, _LIMIT_FIELDS[quantity])

    @property
    def active(self) -> tuple[str, ...]:
        return tuple(q for q in QUANTITIES if self.value(q) is not None)


FEED_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("cl", "", "CL index"),
    ("file", "", "source file of the move"),
    ("line", "", "1-based source line"),
    ("operation", "", "operation"),
    ("status", "", "engagement status (engaged, air, rapid, failed)"),
    ("length_mm", "mm", "path length of the CL segment"),
    ("programmed_feed_mm_min", "mm/min", "feed in the program; NaN for rapids"),
    ("limit_feed_mm_min", "mm/min", "largest feed meeting every limit (before clamping, rounding, smoothing); "
                                    "inf: no limit binds, 0: none meets them"),
    ("advised_feed_mm_min", "mm/min", "advised feed; NaN for rapids"),
    ("reason", "", "what set the advised feed: force, chip, power, mrr (a limit, rounded down to the quantum), "
                   "max_feed, min_feed, smoothing, programmed (kept), air_feed, rapid"),
    ("note", "", "why a CL is special: failed, unreachable, plunge, ramp, no-contact-at-end, no-feed, no-rpm"),
    ("limiting_quantity", "", "active limit closest to (or furthest over) its value at the advised feed"),
    ("limiting_ratio", "", "that quantity at the advised feed / its limit (<= 1 unless unreachable or kept)"),
    *((f"{q}_{w}_{u}", u.replace("_", "/") if q == "mrr" else u, f"{d} at the {w} feed")
      for q, u, d in (("force_peak", "N", "peak resultant force |F|"), ("chip_peak", "mm", "peak chip thickness"),
                      ("power_peak", "W", "peak spindle cutting power"), ("mrr", "mm3_min", "material removal rate"))
      for w in ("programmed", "advised")),
)
"""Columns of :attr:`FeedAdvice.table`: (name, unit, meaning)."""


@dataclass(frozen=True, eq=False)
class FeedAdvice:
    """Per-CL feed advice (:data:`FEED_COLUMNS`, one row per CL in input order) and the settings it
    was made with (``limit`` with ``min_feed``/``max_feed`` resolved, ``quantum``, ``min_run_length``
    in mm, ``slice_height`` in mm when the maps came from result tables)."""

    table: pd.DataFrame
    limit: FeedLimit
    quantum: float
    min_run_length: float
    slice_height: float | None = None
    settings: dict[str, Any] = field(default_factory=dict)

    def line_feeds(self, file: str | None = None) -> dict[int, float]:
        """Advised feed (mm/min) per 1-based source line, for :func:`fusioncut.io.gcode_rewrite.rewrite_feeds`.

        Only CLs with an advised feed (not rapids); a line split into several CLs gets the smallest
        of their feeds (the safe one). ``file`` keeps only the CLs of that source file (by file name,
        see :func:`same_source_file`)."""
        t = self.table[self.table["advised_feed_mm_min"].notna() & (self.table["line"] > 0)]
        if file is not None:
            t = t[[same_source_file(f, file) for f in t["file"]]]
        return {int(k): float(v) for k, v in t.groupby("line")["advised_feed_mm_min"].min().items()}

    def cycle_time_s(self, which: str = "advised") -> float:
        """Feed time (s) of the non-rapid CLs at the ``programmed`` or ``advised`` feeds."""
        t = self.table
        feed = t[f"{which}_feed_mm_min"].to_numpy(dtype=float)
        ok = np.isfinite(feed) & (feed > 0)
        return float(np.sum(t["length_mm"].to_numpy(dtype=float)[ok] / feed[ok]) * 60.0)

    def feed_changes(self, which: str = "advised") -> int:
        """How many times the feed changes from one non-rapid CL to the next (F words a post would need)."""
        f = self.table[f"{which}_feed_mm_min"].to_numpy(dtype=float)
        f = f[np.isfinite(f)]
        return int(np.count_nonzero(f[1:] != f[:-1]))


def same_source_file(a: str, b: str) -> bool:
    """Whether two source file names mean the same program: the same resolved path or, since results
    outlive the folder they were computed in, the same file name."""
    from pathlib import Path

    return Path(a).name == Path(b).name


# --------------------------------------------------------------------------------------------------
# one CL: linear parts and exact bounds


def largest_feasible(a: np.ndarray, e: np.ndarray, limit: float) -> float:
    """Largest ``c >= 0`` with ``|c a_s + e_s| <= limit`` at every sample ``s`` (rows of ``a``, ``e``,
    shape (S, D)); ``inf`` when no sample bounds it, ``nan`` when no ``c >= 0`` meets the limit.

    Each sample's condition ``|a|² c² + 2 a.e c + |e|² - limit² <= 0`` holds on an interval of
    ``c``; the answer is the upper end of the intersection of those intervals, if it is not empty.
    """
    a = np.atleast_2d(np.asarray(a, dtype=float))
    e = np.atleast_2d(np.asarray(e, dtype=float))
    if a.shape != e.shape:
        raise ValueError(f"a and e must have the same shape, got {a.shape} and {e.shape}")
    qa = np.einsum("sd,sd->s", a, a)
    qb = 2.0 * np.einsum("sd,sd->s", a, e)
    qc = np.einsum("sd,sd->s", e, e) - limit * limit
    scale = float(qa.max(initial=0.0))
    flat = qa <= _TINY * max(scale, _TINY)  # samples where the cutting part vanishes (tooth out of the cut)
    if np.any(flat & (qc > 0)):
        return math.nan  # the edge part alone exceeds the limit there, whatever the feed
    q = ~flat
    if not np.any(q):
        return math.inf
    qa, qb, qc = qa[q], qb[q], qc[q]
    disc = qb * qb - 4.0 * qa * qc
    if np.any(disc < 0):
        return math.nan
    root = np.sqrt(disc)
    # numerically stable roots of a c² + b c + c0
    t = -0.5 * (qb + np.copysign(root, qb))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(t != 0, t / qa, 0.0)
        r2 = np.where(t != 0, qc / t, 0.0)
    lo = float(np.max(np.minimum(r1, r2)))
    hi = float(np.min(np.maximum(r1, r2)))
    if hi < max(lo, 0.0) - 1e-12 * max(1.0, abs(hi)):
        return math.nan
    return hi


@dataclass(frozen=True)
class _Linear:
    """The load of one CL as a function of its feed (mm/min): ``c = k * feed``."""

    k: float  # feed per tooth per unit feed: mm / (mm/min)
    force_a: np.ndarray  # (S, 3) N per mm of c
    force_e: np.ndarray  # (S, 3) N
    torque_a: np.ndarray  # (S, 1) N*m per mm of c
    torque_e: np.ndarray  # (S, 1) N*m
    omega: float  # rad/s
    chip_per_c: float  # peak chip thickness per mm of c
    mrr_per_feed: float  # mm³/min per mm/min: removed volume / length

    def force_peak(self, feed: float) -> float:
        c = self.k * feed
        return float(np.linalg.norm(c * self.force_a + self.force_e, axis=1).max(initial=0.0))

    def power_peak(self, feed: float) -> float:
        c = self.k * feed
        return float(np.abs(c * self.torque_a + self.torque_e).max(initial=0.0)) * self.omega

    def chip_peak(self, feed: float) -> float:
        return self.k * feed * self.chip_per_c

    def mrr(self, feed: float) -> float:
        return self.mrr_per_feed * feed

    def value(self, quantity: str, feed: float) -> float:
        return {"force": self.force_peak, "chip": self.chip_peak, "power": self.power_peak,
                "mrr": self.mrr}[quantity](feed)

    def bound(self, quantity: str, limit: float) -> float:
        """Largest feed (mm/min) keeping ``quantity`` at most ``limit``: inf unbounded, nan unreachable."""
        if quantity == "mrr":
            return limit / self.mrr_per_feed if self.mrr_per_feed > 0 else math.inf
        if quantity == "chip":
            per_feed = self.k * self.chip_per_c
            return limit / per_feed if per_feed > 0 else math.inf
        if self.k <= 0:  # the feed does not change the (modelled) load: it is met or it is not
            return math.inf if self.value(quantity, 0.0) <= limit else math.nan
        if quantity == "force":
            c = largest_feasible(self.force_a, self.force_e, limit)
        else:
            c = largest_feasible(self.torque_a, self.torque_e, limit / self.omega)
        return c if math.isnan(c) else c / self.k


def _linear(emap: EngagementMap, tool: MillingTool, coefficients: CuttingCoefficients, rpm: float | None,
            length: float, dz: float | None, samples: int, need_rpm: bool) -> _Linear:
    d = np.subtract(emap.position, emap.start, dtype=float)
    chord = float(np.linalg.norm(d))
    horizontal = 1.0 if chord < 1e-9 else float(math.hypot(d[0], d[1])) / chord
    mrr_per_feed = emap.removed_volume / length if length > 0 else 0.0
    if not need_rpm:
        z = np.zeros((1, 3))
        return _Linear(0.0, z, z, z[:, :1], z[:, :1], 0.0, 0.0, mrr_per_feed)
    assert rpm is not None
    k = horizontal / (rpm * tool.flutes)
    f0 = compute_cl_forces(emap, tool, coefficients, rpm=rpm, feed_per_tooth=0.0, dz=dz, samples=samples)
    f1 = compute_cl_forces(emap, tool, coefficients, rpm=rpm, feed_per_tooth=1.0, dz=dz, samples=samples)
    return _Linear(
        k=k,
        force_a=np.asarray(f1.feed_frame) - np.asarray(f0.feed_frame),
        force_e=np.asarray(f0.feed_frame),
        torque_a=(np.asarray(f1.torque) - np.asarray(f0.torque))[:, None],
        torque_e=np.asarray(f0.torque)[:, None],
        omega=f0.omega,
        chip_per_c=peak_chip_thickness(emap, tool, 1.0, dz=dz),
        mrr_per_feed=mrr_per_feed,
    )


# --------------------------------------------------------------------------------------------------
# smoothing


def merge_short_runs(values: np.ndarray, lengths: np.ndarray, width: float) -> np.ndarray:
    """Smooth a sequence of feeds so that every run of consecutive CLs at one feed is at least
    ``width`` long (sum of ``lengths``), except runs lower than each neighbouring run.

    Shortest first, a run shorter than ``width`` that is higher than a neighbouring run is lowered to
    the higher of its lower neighbours and merged with it; this repeats until no such run is left.
    Feeds are only ever lowered (the result is never above ``values``) and a dip - a run lower than
    both neighbours, which a limit needs - is never removed, however short.
    """
    import heapq

    vals = np.asarray(values, dtype=float)
    n = len(vals)
    if n == 0 or width <= 0:
        return vals.copy()
    # runs of equal values as a doubly linked list
    starts = [0] + [k for k in range(1, n) if vals[k] != vals[k - 1]]
    m = len(starts)
    value = [float(vals[a]) for a in starts]
    bounds = starts + [n]
    length = [float(np.sum(lengths[bounds[r]: bounds[r + 1]])) for r in range(m)]
    first = list(starts)
    last = [bounds[r + 1] - 1 for r in range(m)]
    prev = list(range(-1, m - 1))
    nxt = list(range(1, m + 1))
    nxt[-1] = -1
    alive = [True] * m
    version = [0] * m
    heap = [(length[r], r, 0) for r in range(m) if length[r] < width]
    heapq.heapify(heap)

    def lower_neighbours(r: int) -> list[int]:
        return [q for q in (prev[r], nxt[r]) if q >= 0 and value[q] < value[r]]

    while heap:
        _, r, ver = heapq.heappop(heap)
        if not alive[r] or ver != version[r] or length[r] >= width:
            continue
        low = lower_neighbours(r)
        if not low:
            continue  # a dip (or the whole stretch): kept
        value[r] = max(value[q] for q in low)
        # merge with the neighbours now at the same value
        for q in (prev[r], nxt[r]):
            if q >= 0 and value[q] == value[r]:
                alive[q] = False
                length[r] += length[q]
                first[r], last[r] = min(first[r], first[q]), max(last[r], last[q])
                if q == prev[r]:
                    prev[r] = prev[q]
                    if prev[r] >= 0:
                        nxt[prev[r]] = r
                else:
                    nxt[r] = nxt[q]
                    if nxt[r] >= 0:
                        prev[nxt[r]] = r
        # this run and its neighbours may be candidates now
        for q in (r, prev[r], nxt[r]):
            if q >= 0 and length[q] < width:
                version[q] += 1
                heapq.heappush(heap, (length[q], q, version[q]))
    out = vals.copy()
    for r in range(m):
        if alive[r]:
            out[first[r]: last[r] + 1] = value[r]
    return np.minimum(out, vals)


# --------------------------------------------------------------------------------------------------
# the advice


def _is_results(obj: object) -> bool:
    return hasattr(obj, "cl") and hasattr(obj, "slices") and isinstance(getattr(obj, "cl"), pd.DataFrame)


def advise_feeds(
    source: Any,
    tool: MillingTool,
    coefficients: CuttingCoefficients,
    limit: FeedLimit,
    *,
    rpm: float | Sequence[float | None] | None = None,
    dz: float | None = None,
    lengths: Sequence[float] | None = None,
    quantum: float = 0.05,
    min_run_length: float | None = None,
    samples: int = 360,
) -> FeedAdvice:
    """Feed advice for every CL of ``source`` (see the module docstring for the rules).

    ``source`` is a sequence of :class:`~fusioncut.model.engagement.EngagementMap` (one tool) or
    loaded results (:func:`fusioncut.io.results.load_results`; maps rebuilt by
    :func:`~fusioncut.analysis.result_maps.engagement_maps_from_results`, path lengths, spindle speeds
    and the slice height from what the folder records).
    ``rpm`` (rev/min): one spindle speed or one per CL (``None`` where unknown; results: the recorded
    speeds by default); needed for the force, chip and power limits. ``dz`` (mm): the engine's slice
    height (results: the recorded one, :func:`~fusioncut.analysis.result_maps.results_slice_height`;
    see :func:`~fusioncut.analysis.forces.compute_cl_forces`). ``lengths`` (mm): path length per CL
    (default: the chord). ``quantum``: feed step as a fraction of the programmed feed (0: none).
    ``min_run_length`` (mm): shortest stretch a raised feed must last (default: the tool diameter;
    0: no smoothing). ``samples``: spindle angles per revolution.
    """
    slice_height = None
    if _is_results(source):
        dz = slice_height = results_slice_height(source, dz)
        maps = engagement_maps_from_results(source, dz)
        if lengths is None:
            lengths = source.cl["length_mm"].to_numpy(dtype=float)
        if rpm is None:
            rpm = [None if math.isnan(n) else float(n) for n in source.cl["spindle_rpm"].to_numpy(dtype=float)]
    else:
        maps = list(source)
    n = len(maps)
    if lengths is None:
        lengths = [math.dist(m.start, m.position) for m in maps]
    lengths = np.asarray(lengths, dtype=float)
    if len(lengths) != n:
        raise InputError(f"{len(lengths)} lengths for {n} CLs")
    if isinstance(rpm, (int, float)) or rpm is None:
        rpms: list[float | None] = [rpm] * n  # type: ignore[list-item]
    else:
        rpms = [None if r is None or not math.isfinite(r) or r <= 0 else float(r) for r in rpm]
        if len(rpms) != n:
            raise InputError(f"{len(rpms)} spindle speeds for {n} CLs")
    if rpm is not None and isinstance(rpm, (int, float)) and not (math.isfinite(rpm) and rpm > 0):
        raise InputError(f"spindle speed must be > 0 rev/min, got {rpm}")
    if not (0 <= quantum < 1):
        raise InputError(f"feed quantum must be in [0, 1), got {quantum}")
    width = tool.diameter if min_run_length is None else float(min_run_length)
    if not (width >= 0 and math.isfinite(width)):
        raise InputError(f"minimum run length must be >= 0 mm, got {min_run_length}")
    need_c = any(q in limit.active for q in ("force", "chip", "power"))

    # resolve the feed range from the program's cutting feeds
    cutting = [m.feed for m in maps if m.status == CLStatus.ENGAGED and m.feed]
    if limit.min_feed is None or limit.max_feed is None:
        if not cutting:
            raise InputError("no engaged CL with a programmed feed: give min_feed and max_feed")
        limit = replace(limit,
                        min_feed=limit.min_feed if limit.min_feed is not None else 0.1 * min(cutting),
                        max_feed=limit.max_feed if limit.max_feed is not None else max(cutting))
    lo_feed, hi_feed = float(limit.min_feed), float(limit.max_feed)  # type: ignore[arg-type]
    if lo_feed > hi_feed:
        raise InputError(f"min_feed {lo_feed:g} mm/min is above max_feed {hi_feed:g} mm/min")

    names = [c[0] for c in FEED_COLUMNS]
    rows: list[dict[str, Any]] = []
    models: list[_Linear | None] = []
    fixed = np.zeros(n, dtype=bool)
    for i, (emap, r, length) in enumerate(zip(maps, rpms, lengths)):
        prog = emap.feed if emap.feed is not None and emap.feed > 0 else None
        row: dict[str, Any] = dict.fromkeys(names, math.nan)
        row.update(cl=emap.cl_index, file=str(emap.source.file), line=int(emap.source.line),
                   operation=emap.operation, status=emap.status.value, length_mm=float(length),
                   programmed_feed_mm_min=math.nan if emap.feed is None else float(emap.feed),
                   reason="programmed", note="", limiting_quantity="")
        model = None
        if emap.status == CLStatus.RAPID or emap.feed is None and emap.status != CLStatus.FAILED:
            row.update(reason="rapid" if emap.status == CLStatus.RAPID else "programmed",
                       note="" if emap.status == CLStatus.RAPID else "no-feed")
            fixed[i] = True
        elif emap.status == CLStatus.FAILED:
            row.update(advised_feed_mm_min=emap.feed, note="failed")
            fixed[i] = True
        elif prog is None:
            row.update(advised_feed_mm_min=emap.feed, note="no-feed")
            fixed[i] = True
        elif emap.status == CLStatus.AIR:
            if limit.air_feed:
                row.update(advised_feed_mm_min=hi_feed, reason="air_feed")
            else:
                row.update(advised_feed_mm_min=prog)
                fixed[i] = True
        elif need_c and r is None:
            row.update(advised_feed_mm_min=prog, note="no-rpm")
            fixed[i] = True
        else:
            model = _linear(emap, tool, coefficients, r, float(length), dz, samples, need_c)
            bounds = {q: model.bound(q, limit.value(q)) for q in limit.active}  # type: ignore[arg-type]
            plunge = bool(emap.engaged_slices) and need_c and model.k <= 0
            unreachable = [q for q, b in bounds.items() if math.isnan(b)]
            over = bool(unreachable)
            if plunge:
                # the modelled load of a plunge does not depend on its feed: slowing down would not
                # help, so a limit it exceeds is reported but does not set the feed
                unreachable = []
                bounds = {q: (math.inf if math.isnan(b) else b) for q, b in bounds.items()}
            finite = {q: b for q, b in bounds.items() if not math.isnan(b)}
            if unreachable:
                best_q, best = unreachable[0], 0.0
            else:
                best_q = min(finite, key=lambda q: finite[q])
                best = finite[best_q]
            row["limit_feed_mm_min"] = best
            notes = []
            cap = math.inf
            if plunge:
                notes.append("plunge")
                cap = prog
            elif emap.position[2] < emap.start[2] - 1e-9 and not limit.raise_ramps:
                notes.append("ramp")
                cap = prog
            if not emap.engaged_slices and emap.removed_volume > 0:
                notes.append("no-contact-at-end")
                cap = prog
            value, reason = best, best_q
            if cap < value:
                value, reason = cap, "programmed"
            if over:
                notes.insert(0, "unreachable")
            if value > hi_feed:
                value, reason = hi_feed, "max_feed"
            elif value < lo_feed:
                value, reason = lo_feed, "min_feed"
            elif reason in QUANTITIES and quantum > 0:
                # round down to whole steps of the programmed feed: never over the limit
                steps = math.floor(value / prog / quantum + 1e-9)
                value = max(lo_feed, steps * quantum * prog)
            row.update(advised_feed_mm_min=value, reason=reason, note=" ".join(notes))
        models.append(model)
        rows.append(row)

    table = pd.DataFrame(rows, columns=names)
    advised = table["advised_feed_mm_min"].to_numpy(dtype=float).copy()
    before = advised.copy()
    # smoothing per stretch between rapids (and feed moves without a feed)
    ok = np.isfinite(advised)
    i = 0
    while i < n:
        if not ok[i]:
            i += 1
            continue
        j = i
        while j < n and ok[j]:
            j += 1
        advised[i:j] = merge_short_runs(advised[i:j], lengths[i:j], width)
        i = j
    advised[fixed] = before[fixed]
    smoothed = ok & (advised < before - 1e-9 * np.maximum(before, 1.0))
    table.loc[smoothed, "reason"] = "smoothing"
    table["advised_feed_mm_min"] = advised

    # the loads at the programmed and advised feeds
    for k, model in enumerate(models):
        if model is None:
            continue
        worst, worst_ratio = "", -math.inf
        for q, unit in (("force_peak", "N"), ("chip_peak", "mm"), ("power_peak", "W"), ("mrr", "mm3_min")):
            quantity = q.split("_")[0]
            if quantity != "mrr" and not need_c:
                continue
            for w in ("programmed", "advised"):
                f = table.at[k, f"{w}_feed_mm_min"]
                table.at[k, f"{q}_{w}_{unit}"] = model.value(quantity, float(f))
            lim = limit.value(quantity)
            if lim is not None:
                ratio = model.value(quantity, float(advised[k])) / lim
                if ratio > worst_ratio:
                    worst, worst_ratio = quantity, ratio
        table.at[k, "limiting_quantity"] = worst
        table.at[k, "limiting_ratio"] = worst_ratio if worst else math.nan
    table = table.astype({"cl": "int64", "line": "int64", "file": "string", "operation": "string",
                          "status": "string", "reason": "string", "note": "string",
                          "limiting_quantity": "string"})
    return FeedAdvice(table=table, limit=limit, quantum=quantum, min_run_length=width, slice_height=slice_height,
                      settings={"samples": samples, "dz": dz})
