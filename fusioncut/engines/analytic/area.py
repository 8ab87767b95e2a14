"""Contact area of the tool at a CL's end: the engaged part of its surface of revolution.

Tool frame as in :mod:`.profile` (z above the tip, mm); angles in rad. The contact is the set of
points of the tool's surface (at the CL's end) that are engaged in the sense of
:mod:`.contact`: in the material before the CL and on the sweep's front. Its slice at height
``z`` is a set of arcs of total span ``W(z)`` on the circle of radius ``rho(z)``, so

    area = integral over the profile's arc length s of  d(s) * W(z(s))  ds          (mm²)

with ``(d(s), z(s))`` the generating curve: the lower profile's pieces (a line ``z = a + b (d -
d0)``, ``ds = sqrt(1 + b²) dd``; an arc of radius ``c`` about ``(a, b)``, parametrised by its angle
``phi`` with ``d = a + c sin phi``, ``z = b - c cos phi``, ``ds = c dphi``, so that a corner's
vertical tangent is not a singularity) and, above them, the cylinder ``d = R`` (``ds = dz``). A
horizontal piece (a flat end mill's end face) has no angular extent and is not counted, as the
B-Rep engine's contact faces leave it out.

``W`` jumps where an arc appears or vanishes (at the stock's top, at an earlier level pass's
floor) and bends where what bounds an arc's end changes (it passes from one earlier sweep's surface
to another's, or leaves the front's limit). ``width(z)`` gives ``W`` with the **shape** of the
arcs: their number and the causes of their ends. The heights where ``W`` jumps or bends that are
known beforehand (``breaks``: the stock's top, an earlier level sweep's floor and the heights where
its profile's pieces meet) start the integral's parts; a part whose rule nodes see more than one
shape is split where the shape changes: between each two neighbouring nodes that differ, the
changes are found one after the other (an end crossing the joints of an earlier pass's short moves
changes its cause many times between two nodes), each by bisection to :data:`MIN_PART` where the
number of arcs changes (a jump) and to :data:`KINK_PART` of the narrower part beside it where only
the causes do (a kink: a split that far off costs the rule an error of the order of its square).
A part narrower than :data:`KINK_SPAN` of its piece is not split at kinks, and a change within
:data:`CLUSTER` of the last is not one of its own: where two causes' surfaces meet tangentially (a
ball's equator, where its sweep's lower surface turns into its wall) the classification of an end
flickers between them, and W is smooth there.
Within the parts it is adaptive Gauss-Kronrod (7, 15) with a global error budget
(QUADPACK's QAG and its error estimate from the two rules and the integrand's spread about its
mean, as :mod:`.volume`): the part with the largest estimate is halved (or split near the end
where its last split found its error: :func:`_graded_split`) until the estimates add up to ``rel_tol``
of the area, parts reach :data:`MIN_PART`, or :data:`MAX_EVALS`
evaluations of ``W`` are spent (from then on a change of shape no longer splits a part either); the
estimate left is returned with the area. A slice within :data:`TIP_NOISE` of the tip is taken as the one
at that height: round-off, not the material, decides which of its points are engaged.
"""
from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Sequence

import numpy as np

from fusioncut.engines.analytic.volume import _WG, _WK, _XK, _error

MIN_PART = 1e-9  # along the generating curve (mm, or rad of a corner's angle)
KINK_PART = 1e-5  # the place of a kink of W (a change of what bounds an arc's end), in parts of the narrower
# part beside it: inside the rule's nodes nearest a part's ends (5.5e-5 of it), so that the parts either side
# do not see the change again
KINK_SPAN = 1e-5  # parts narrower than this share of their piece are not split at kinks, only at jumps
MAX_CHANGES = 8  # changes of shape located one after the other between two of a rule's nodes
CLUSTER = 1e-5  # ... each at least this share of those nodes' spacing past the last
GRADE = 1 / 8  # a part whose error lies at one end is split this share of its width from that end
DOMINANT = 8.0  # ... where its last split found one side's error over this many times the other's
MAX_EVALS = 1500  # evaluations of W(z) one CL's area may take: a bound, not the usual stop (the error estimate)
TIP_NOISE = 1e-9  # mm above the tip: a slice lower than this is taken as the one at this height. There the slice's
# circle runs within round-off of the tip's own surface and of a floor level with the tip (a bull-nose's flat meets
# its corner with zero slope), and its engaged arcs flicker between none and all from one height to the next
_LINE = 0.0
Shape = tuple[int, tuple[float, ...]]  # the engaged arcs' number and their ends' causes (engine._width)
# Gauss-Kronrod (7, 15) on [-1, 1] (:mod:`.volume`'s nodes): the Kronrod nodes, 0 among them, and
# the Kronrod and Gauss weights (0 at the Kronrod-only nodes)
_NODES = np.concatenate([_XK, -_XK[:7]])
_KRONROD = np.concatenate([_WK, _WK[:7]])
_GAUSS = np.zeros(15)
_GAUSS[[1, 3, 5, 7, 9, 11, 13]] = [_WG[0], _WG[1], _WG[2], _WG[3], _WG[0], _WG[1], _WG[2]]


def _differ(a: Shape, b: Shape, kinks: bool) -> bool:
    """Whether two shapes of the engaged arcs differ: in anything where ``kinks``, else in their number."""
    return a != b if kinks else a[0] != b[0]


class SurfacePiece:
    """One piece of the generating curve over the parameter ``[u0, u1]``: ``at(u)`` gives ``(d, z,
    ds/du)`` (mm, mm, mm per unit of u)."""

    def __init__(self, u0: float, u1: float, at: Callable[[float], tuple[float, float, float]],
                 u_of_z: Callable[[float], float]) -> None:
        self.u0, self.u1, self.at, self.u_of_z = u0, u1, at, u_of_z


def surface_pieces(pieces: np.ndarray, z_top: float) -> list[SurfacePiece]:
    """The generating curve of the tool the analytic engine sweeps (:mod:`.profile`'s lower profile,
    then straight up at ``R``) up to ``z_top`` mm above the tip, less its horizontal pieces."""
    out: list[SurfacePiece] = []
    z_end = 0.0
    for kind, d0, d1, a, b, c in pieces:
        if kind == _LINE:
            z0, z1 = a, a + b * (d1 - d0)
            z_end = z1
            if b <= 0.0:
                continue  # horizontal: no angular extent
            k = math.sqrt(1.0 + b * b) / b  # ds/dz

            def at_line(u: float, d0=d0, a=a, b=b, k=k) -> tuple[float, float, float]:
                return d0 + (u - a) / b, u, k

            out.append(SurfacePiece(z0, min(z1, z_top), at_line, lambda z: z))
        else:
            p0 = math.asin(max(-1.0, min(1.0, (d0 - a) / c)))
            p1 = math.asin(max(-1.0, min(1.0, (d1 - a) / c)))
            z_end = b - c * math.cos(p1)

            def at_arc(u: float, a=a, b=b, c=c) -> tuple[float, float, float]:
                return a + c * math.sin(u), b - c * math.cos(u), c

            def u_of_z(z: float, b=b, c=c, p0=p0, p1=p1) -> float:
                return min(p1, max(p0, math.acos(max(-1.0, min(1.0, (b - z) / c)))))

            out.append(SurfacePiece(p0, min(p1, u_of_z(z_top)), at_arc, u_of_z))
        if z_end >= z_top:
            break
    radius = float(pieces[-1, 2])
    if z_top > z_end:
        out.append(SurfacePiece(z_end, z_top, lambda u: (radius, u, 1.0), lambda z: z))
    return [p for p in out if p.u1 > p.u0]


def contact_area(width: Callable[[float], tuple[float, Shape]], pieces: np.ndarray, z_lo: float,
                 z_hi: float, breaks: Sequence[float], rel_tol: float = 1e-7) -> tuple[float, float]:
    """(area, error estimate) in mm² of the contact between heights ``z_lo`` and ``z_hi`` (mm above
    the tip); ``width(z)`` is ``(W(z) in rad, the arcs' shape: (their number, their ends' causes))``
    and ``breaks`` the heights where ``W`` may jump."""
    if z_hi <= z_lo:
        return 0.0, 0.0
    # (-err, a, b, value, end, piece): ``end`` is where the part's error lies, as its last split showed
    # (-1 at a, 1 at b, 0 not known; _graded_split)
    parts: list[tuple[float, float, float, float, int, SurfacePiece]] = []
    evals = 0

    def at(p: SurfacePiece, u: float) -> tuple[float, Shape]:
        nonlocal evals
        evals += 1
        d, z, ds = p.at(u)
        w, shape = width(max(z, TIP_NOISE))
        return d * ds * w, shape

    def narrow(p: SurfacePiece, lo: float, hi: float, s_lo: Shape, s_hi: Shape, tol: float, kinks: bool
               ) -> tuple[float, float, Shape]:
        """The bracket [lo, hi] of a change of shape from ``s_lo`` bisected to ``tol`` (to MIN_PART
        where the number of arcs changes), and the shape at its new ``hi``; where ``kinks`` is False only
        the number of arcs counts."""
        while hi - lo > (MIN_PART if s_lo[0] != s_hi[0] else tol):
            m = 0.5 * (lo + hi)
            sm = at(p, m)[1]
            if not _differ(sm, s_lo, kinks):
                lo = m
            else:
                hi, s_hi = m, sm
        return lo, hi, s_hi

    def events(p: SurfacePiece, a: float, b: float, sa: Shape, sb: Shape, tol: float, kinks: bool
               ) -> list[tuple[float, float, Shape, Shape]]:
        """Brackets (lo, hi, shape at lo, shape at hi) no wider than ``tol`` of the changes of shape on
        the way from ``sa`` (at ``a``) to ``sb`` (at ``b``), found one after the other, each at least
        :data:`CLUSTER` of ``b - a`` past the last (at most :data:`MAX_CHANGES`, none once
        :data:`MAX_EVALS` are spent); where ``kinks`` is False only changes of the number of arcs."""
        out: list[tuple[float, float, Shape, Shape]] = []
        gap = CLUSTER * (b - a)
        while len(out) < MAX_CHANGES and evals < MAX_EVALS and _differ(sa, sb, kinks):
            lo, hi, s_hi = narrow(p, a, b, sa, sb, tol, kinks)
            out.append((lo, hi, sa, s_hi))
            # the next change lies between here and b; one closer than the gap is a flicker of the
            # classification (an end where two causes' surfaces meet tangentially), not a change of its own
            a = min(hi + gap, b)
            if a >= b:
                break
            sa = s_hi if a == hi else at(p, a)[1]
        return out

    def add(p: SurfacePiece, a: float, b: float) -> list[tuple[float, float, float, float, int, SurfacePiece]]:
        """Rule on [a, b], or, where the arcs' shape differs between its nodes, the parts between the
        changes: the parts, in order along [a, b], to be put in the heap."""
        if b - a <= MIN_PART:
            return []
        n = len(_NODES)
        fk, us, shapes = np.empty(n), np.empty(n), [(0, ())] * n
        for i in range(n):
            # y = a + (b - a) s^2 (3 - 2 s): a square root at either end (an arc born from a point) is
            # smooth in s
            t = 0.5 * (_NODES[i] + 1.0)
            us[i] = a + (b - a) * t * t * (3.0 - 2.0 * t)
            f, shapes[i] = at(p, us[i])
            fk[i] = f * 3.0 * (b - a) * t * (1.0 - t)
        order = np.argsort(us)
        kinks = b - a > KINK_SPAN * (p.u1 - p.u0)
        change = [k for k in range(n - 1) if _differ(shapes[order[k]], shapes[order[k + 1]], kinks)]
        if change and evals < MAX_EVALS:
            found = [e for k in change for e in events(p, us[order[k]], us[order[k + 1]], shapes[order[k]],
                                                       shapes[order[k + 1]], max(KINK_PART * (b - a), MIN_PART),
                                                       kinks)]
            cuts = [a, *(0.5 * (lo + hi) for lo, hi, _, _ in found), b]
            for i, (lo, hi, s_lo, s_hi) in enumerate(found, 1):
                # to KINK_PART of the narrower part beside it, lest that part's rule see the change again
                tol = KINK_PART * min(cuts[i] - cuts[i - 1], cuts[i + 1] - cuts[i])
                if hi - lo > tol:
                    lo, hi, _ = narrow(p, lo, hi, s_lo, s_hi, max(tol, MIN_PART), kinks)
                    cuts[i] = 0.5 * (lo + hi)
            return [q for c0, c1 in zip(cuts[:-1], cuts[1:]) for q in add(p, c0, c1)]
        k, g = _KRONROD @ fk, _GAUSS @ fk
        resasc = _KRONROD @ np.abs(fk - 0.5 * k)
        return [(-_error(abs(k - g), resasc), a, b, k, 0, p)]

    for p in surface_pieces(pieces, z_hi):
        lo = max(p.u0, p.u_of_z(z_lo))
        hi = min(p.u1, p.u_of_z(z_hi))
        if hi <= lo:
            continue
        cuts = sorted({lo, hi, *(u for u in (p.u_of_z(z) for z in breaks if z_lo < z < z_hi) if lo < u < hi)})
        for a, b in zip(cuts[:-1], cuts[1:]):
            for q in add(p, a, b):
                heapq.heappush(parts, q)
    while parts:
        total = sum(q[3] for q in parts)
        err = -sum(q[0] for q in parts)
        if err <= rel_tol * abs(total) or evals >= MAX_EVALS:
            return total, err
        e, a, b, v, end, p = heapq.heappop(parts)
        if b - a <= 2 * MIN_PART:
            heapq.heappush(parts, (0.0, a, b, v, 0, p))  # as fine as it gets: its estimate is dropped
            if all(q[0] == 0.0 for q in parts):
                break
            continue
        for q in _graded_split(a, b, end, lambda c0, c1: add(p, c0, c1)):
            heapq.heappush(parts, q)
    return sum(q[3] for q in parts), -sum(q[0] for q in parts)


def _graded_split(a: float, b: float, end: int, rule: Callable[[float, float], list]) -> list:
    """The parts of [a, b] split once: at the middle, or :data:`GRADE` of the way from the end where
    its error was found (``end``: -1 at a, 1 at b). Where one side's error is over :data:`DOMINANT`
    times the other's, its outer end is marked as where its error lies (a near-singularity just
    beyond a part's end, as where an arc's end runs almost along a slice's circle, is then closed in
    on geometrically: a halving would take one rule pair per factor 2); a split that finds the
    error away from the marked end marks nothing."""
    m = a + GRADE * (b - a) if end < 0 else (b - GRADE * (b - a) if end > 0 else 0.5 * (a + b))
    left, right = rule(a, m), rule(m, b)
    e_left, e_right = -sum(q[0] for q in left), -sum(q[0] for q in right)
    if left and e_left > DOMINANT * e_right and end <= 0:
        left[0] = (*left[0][:4], -1, left[0][5])
    elif right and e_right > DOMINANT * e_left and end >= 0:
        right[-1] = (*right[-1][:4], 1, right[-1][5])
    return left + right
