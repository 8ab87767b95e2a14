"""The lower profile of a tool of revolution, as the analytic engine sweeps it.

Tool frame as in :mod:`fusioncut.model.tools`: axis +z, ``z = 0`` at the tip, mm. The **lower
profile** is the height of the tool's lowest point at radial distance ``d`` from the axis,
``f(d)`` for ``0 <= d <= R``, walked along the cutting profile from the tip while the radius grows.
Above it the engine takes the tool to extend straight up at radius ``R`` (the radius where the
walk stops: a flat or ball end mill's diameter / 2, a tapered mill's radius at the flute length).
That is the 3-axis model of issue 26: a point is removed by a sweep iff it lies above the sweep's
lower surface within its footprint.

A neck or shank **wider** than everything below it makes the tool's outline step outward, and its
lower profile stops being convex. The tool is then the union of convex parts, each swept on its
own (:func:`upper_parts`): the cutting part taken straight up at ``R``, and each wider cylinder a
flat-bottomed part from its height above the tip straight up. A point is removed by the CL iff one
part's sweep removes it, so the lower surface of the whole sweep is the least of the parts' and
stays exact. A neck or shank **narrower** than what is below it is taken at that width (its sweep
would leave an overhang, which no height field holds: the contact it would not make is reported as
shank contact).

``f`` is stored as pieces in increasing ``d``, one row of :data:`PIECE_COLUMNS` each:

* a line (kind 0): ``f(d) = a + b * (d - d0)`` with slope ``b >= 0`` (a flat bottom: ``b = 0``);
* an arc (kind 1): the lower branch ``f(d) = b - sqrt(c**2 - (d - a)**2)`` of the circle of radius
  ``c`` about ``(a, b)`` (ball: about the axis; bull-nose: the corner's centre).

The engine needs ``f`` convex (slopes never decrease outward: flat, ball, bull-nose, tapered,
chamfer, drill, every APT cutter whose solid is convex): then the height of a sweep along a line
is a convex function of the path parameter and has one minimum. A profile whose slope falls
outward is refused (:class:`UnsupportedTool`). ``rho(h)``, the inverse of ``f`` (the radius of the
tool's cross-section ``h`` above the tip; ``R`` above the profile), is concave and non-decreasing.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from fusioncut.errors import ToolDefinitionError
from fusioncut.model.tools import MillingTool, ProfileArc, ProfileLine

PIECE_COLUMNS = ("kind", "d0", "d1", "a", "b", "c")
LINE, ARC = 0.0, 1.0
_EPS = 1e-12


class UnsupportedTool(ToolDefinitionError):
    """A tool the analytic engine cannot sweep exactly (a lower profile that is not convex)."""


@dataclass(frozen=True)
class LowerProfile:
    """``pieces``: float64 array (n, 6) as in the module docstring; ``radius``: R (mm)."""

    pieces: np.ndarray
    radius: float

    def f(self, d: float) -> float:
        return profile_height(self.pieces, d)

    def rho(self, h: float) -> float:
        return profile_radius(self.pieces, h)


def lower_profile(tool: MillingTool) -> LowerProfile:
    """The lower profile of ``tool``'s cutting part (cached on the tool, which is immutable)."""
    cached = tool.__dict__.get("_analytic_lower_profile")
    if cached is not None:
        return cached
    rows: list[tuple[float, ...]] = []
    for seg in tool.cutting_profile():
        (r0, z0), (r1, z1) = seg.start, seg.end
        if isinstance(seg, ProfileLine):
            if r1 < r0 - _EPS:
                break  # the radius falls: an undercut; the tool is taken straight up from here
            if r1 - r0 <= _EPS:
                if z1 > z0 + _EPS:
                    break  # the side: straight up from here
                continue
            rows.append((LINE, r0, r1, z0, (z1 - z0) / (r1 - r0), 0.0))
        elif isinstance(seg, ProfileArc):
            (ca, cb), c = seg.center, seg.radius
            # the lower branch reaches outward up to the arc's widest point (its centre's height)
            r_top = ca + c if z1 >= cb - _EPS else r1
            if r_top <= r0 + _EPS:
                break
            rows.append((ARC, r0, r_top, ca, cb, c))
            if z1 > cb + _EPS:
                break  # the arc turns inward above its equator: straight up from its widest point
    if not rows:
        raise UnsupportedTool(f"tool {tool.label}: no lower profile to sweep")
    pieces = np.array(rows, dtype=np.float64)
    # convexity: the slope at each piece's start is at least the slope at the previous one's end
    prev = -math.inf
    for row in pieces:
        s0, s1 = profile_slope(row[None, :], row[1] + 1e-12), profile_slope(row[None, :], row[2] - 1e-12)
        if s0 < prev - 1e-9:
            raise UnsupportedTool(f"tool {tool.label}: its lower profile is not convex (slope {prev:.6g} "
                                  f"then {s0:.6g} at r = {row[1]:.6g} mm); the analytic engine needs a convex one")
        prev = s1
    out = LowerProfile(pieces, float(pieces[-1, 2]))
    object.__setattr__(tool, "_analytic_lower_profile", out)
    return out


@dataclass(frozen=True)
class UpperPart:
    """A cylinder of the tool wider than everything below it, from ``height`` mm above the tip straight
    up: swept as a flat end mill (``profile``: flat, of the cylinder's radius) whose tip is
    ``height`` above the tool's."""

    height: float
    profile: LowerProfile


def upper_parts(tool: MillingTool) -> tuple[UpperPart, ...]:
    """The non-cutting cylinders (neck, shank) wider than the lower profile's ``R`` and than the
    cylinders below them, by increasing height (cached on the tool); empty for a tool as wide as its
    flutes up its shank. A cylinder counts where the tool models it (the shank up to its length)."""
    cached = tool.__dict__.get("_analytic_upper_parts")
    if cached is not None:
        return cached
    cylinders = []
    shank_from = tool.flute_length
    if tool.neck_radius is not None and tool.shoulder_length is not None:
        cylinders.append((tool.flute_length, tool.neck_radius))
        shank_from = tool.shoulder_length
    if tool.length > shank_from + _EPS:
        cylinders.append((shank_from, tool.shank_radius))
    widest, parts = lower_profile(tool).radius, []
    for height, radius in cylinders:
        if radius > widest + 1e-9:
            flat = LowerProfile(np.array([[LINE, 0.0, radius, 0.0, 0.0, 0.0]]), float(radius))
            parts.append(UpperPart(float(height), flat))
            widest = radius
    out = tuple(parts)
    object.__setattr__(tool, "_analytic_upper_parts", out)
    return out


@njit(cache=True, inline="always")
def _piece_slope(piece, d):
    """The slope of one piece's ``f`` at ``d`` (inf where an arc stands vertical)."""
    if piece[0] == LINE:
        return piece[4]
    u = d - piece[3]
    s = piece[5] * piece[5] - u * u
    return u / math.sqrt(s) if s > 0.0 else math.inf


@njit(cache=True)
def corner_radii(pieces, tol=1e-9):
    """The radii (mm, ascending) where ``f`` has a corner (its slope jumps by more than ``tol``: a
    chamfer's flat tip meeting its cone, a drill's point) and ``R``, the footprint's edge: where a
    sweep's lower surface bends or ends. Joints where two pieces meet tangentially (a bull-nose's
    flat and corner, an APT cutter's corner and side) are left out: ``f`` is continuously
    differentiable there and only its curvature jumps, which the integrals' adaptive rules take in
    their stride."""
    out = np.empty(pieces.shape[0])
    n = 0
    for i in range(pieces.shape[0] - 1):
        d = pieces[i, 2]
        if d > 0 and abs(_piece_slope(pieces[i + 1], d) - _piece_slope(pieces[i], d)) > tol:
            out[n] = d
            n += 1
    out[n] = pieces[pieces.shape[0] - 1, 2]
    return out[:n + 1]


@njit(cache=True)
def rim_radius(pieces, tol=1e-9):
    """``R`` where ``f`` ends standing vertical (a ball's or bull-nose's corner arc reaching its
    rightmost point there: a sweep's lower surface then rises like the square root of the distance
    to its footprint's edge), else nan (a flat bottom or a cone meeting the wall at an angle)."""
    last = pieces[pieces.shape[0] - 1]
    if last[0] == ARC and abs(last[3] + last[5] - last[2]) <= tol * max(1.0, last[2]):
        return last[2]
    return math.nan


@njit(cache=True, inline="always")
def profile_height(P, d):
    """f(d): height (mm above the tip) of the tool's lowest point at radial distance ``d``; d beyond
    R takes the outermost piece's end."""
    n = P.shape[0]
    for i in range(n):
        if d <= P[i, 2] or i == n - 1:
            if d > P[i, 2]:
                d = P[i, 2]
            if P[i, 0] == 0.0:
                return P[i, 3] + P[i, 4] * (d - P[i, 1])
            u = d - P[i, 3]
            s = P[i, 5] * P[i, 5] - u * u
            return P[i, 4] - math.sqrt(s if s > 0.0 else 0.0)
    return 0.0


@njit(cache=True, inline="always")
def profile_slope(P, d):
    """f'(d) (dimensionless); infinite where an arc stands vertical."""
    n = P.shape[0]
    for i in range(n):
        if d <= P[i, 2] or i == n - 1:
            if P[i, 0] == 0.0:
                return P[i, 4]
            u = d - P[i, 3]
            s = P[i, 5] * P[i, 5] - u * u
            if s <= 0.0:
                return math.inf
            return u / math.sqrt(s)
    return 0.0


@njit(cache=True)
def profile_radius(P, h):
    """rho(h): radius (mm) of the tool's cross-section ``h`` mm above the tip; -1 below the tip,
    R above the profile (the tool goes straight up)."""
    if h < 0.0:
        return -1.0
    n = P.shape[0]
    for i in range(n):
        d0, d1 = P[i, 1], P[i, 2]
        if P[i, 0] == 0.0:
            z1 = P[i, 3] + P[i, 4] * (d1 - d0)
            if h <= z1:
                if P[i, 4] <= 0.0:
                    return d1
                d = d0 + (h - P[i, 3]) / P[i, 4]
                return d0 if d < d0 else d
        else:
            a, b, c = P[i, 3], P[i, 4], P[i, 5]
            u1 = d1 - a
            z1 = b - math.sqrt(max(c * c - u1 * u1, 0.0))
            if h <= z1:
                v = b - h
                d = a + math.sqrt(max(c * c - v * v, 0.0))
                return d0 if d < d0 else (d1 if d > d1 else d)
    return P[n - 1, 2]


@njit(cache=True, inline="always")
def profile_radius_slope(P, h):
    """rho'(h): growth of the cross-section's radius with height (0 above the profile, inf on a
    flat bottom's height)."""
    if h < 0.0:
        return 0.0
    n = P.shape[0]
    top = profile_height(P, P[n - 1, 2])
    if h >= top:
        return 0.0
    s = profile_slope(P, profile_radius(P, h))
    if s <= 0.0:
        return math.inf
    return 1.0 / s


@njit(cache=True, inline="always")
def is_flat(P):
    """Whether the lower profile ``P`` is a flat end mill's: one line piece of slope 0 (f = 0 out to R)."""
    return P.shape[0] == 1 and P[0, 0] == 0.0 and P[0, 4] == 0.0


@njit(cache=True, inline="always")
def is_ball(P, R):
    """Whether the lower profile ``P`` (radius ``R``) is a ball's: one arc of radius R about (0, R)."""
    return P.shape[0] == 1 and P[0, 0] == ARC and P[0, 3] == 0.0 and P[0, 4] == R and P[0, 5] == R
