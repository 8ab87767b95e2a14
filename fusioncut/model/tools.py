"""Milling tools as axial profiles.

Frame of a tool: the tool axis is +z, ``z = 0`` is the tool tip (the lowest point), lengths in mm,
angles in degrees unless a name ends in ``_rad``. A profile is the outline of the tool's half-section
in the (r, z) half-plane (r >= 0), walked from the axis at the bottom, out and up, and back to the axis
at the top; revolving it about the z axis gives the tool solid.

Every cutting-part geometry is an APT / ISO 3592 7-parameter cutter ``(d, r, e, f, alpha, beta, h)``:
``r`` corner radius, ``(e, f)`` the corner centre (radial, axial), ``alpha`` the angle of the bottom
line above the horizontal, ``beta`` the angle of the side line from the vertical (positive: wider at
the top), ``h`` the height of the cutting part. ``d`` is the diameter where the side line meets the
corner (``2*(e + r*cos(beta))``); it is checked against the other parameters. The named families
(flat, ball, bull-nose, tapered, chamfer, drill) are special cases, so one profile builder serves all.
Above the cutting part (the flute length) the tool does not cut (profile zone ``"shank"``): contact
there is rubbing and is flagged in the results. A reduced neck (``neck_diameter``, up to
``shoulder_length`` from the tip) may come first; then a cylindrical shank of ``shank_diameter`` runs
up to ``overall_length``. Each change of radius is a horizontal step in the profile.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Literal

from fusioncut.errors import ToolDefinitionError

_EPS = 1e-9
# When a source gives no flute length, the fluted part is assumed this many diameters long.
ASSUMED_FLUTE_LENGTH_DIAMETERS = 3.0


class SpindleDirection(str, Enum):
    """Sense of rotation seen from the spindle looking down the tool axis at the work (from +z)."""

    CW = "cw"  # M3
    CCW = "ccw"  # M4


@dataclass(frozen=True)
class ProfileLine:
    """Straight piece of a profile from ``start`` to ``end``, points as (r, z) in mm."""

    start: tuple[float, float]
    end: tuple[float, float]
    zone: Literal["flute", "shank"] = "flute"


@dataclass(frozen=True)
class ProfileArc:
    """Circular piece of a profile (less than a half circle) about ``center`` (r, z), mm.

    Walked from ``start`` to ``end`` counter-clockwise in the (r, z) plane, which is the sense of a
    corner radius walked from the bottom up.
    """

    center: tuple[float, float]
    radius: float
    start: tuple[float, float]
    end: tuple[float, float]
    zone: Literal["flute", "shank"] = "flute"

    @property
    def midpoint(self) -> tuple[float, float]:
        a0 = math.atan2(self.start[1] - self.center[1], self.start[0] - self.center[0])
        a1 = math.atan2(self.end[1] - self.center[1], self.end[0] - self.center[0])
        if a1 < a0:
            a1 += 2 * math.pi
        am = 0.5 * (a0 + a1)
        return (self.center[0] + self.radius * math.cos(am), self.center[1] + self.radius * math.sin(am))


ProfileSegment = ProfileLine | ProfileArc


@dataclass(frozen=True)
class ToolProfile:
    """A closed half-section outline: segments from the axis at z=0 back to the axis at the top."""

    segments: tuple[ProfileSegment, ...]

    @property
    def height(self) -> float:
        return max(max(s.start[1], s.end[1]) for s in self.segments)

    def radius_at(self, z: float) -> float:
        """Radius (mm) of the tool's cross-section at height ``z`` above the tip; 0 outside."""
        best = 0.0
        for s in self.segments:
            if isinstance(s, ProfileLine):
                (r0, z0), (r1, z1) = s.start, s.end
                lo, hi = min(z0, z1), max(z0, z1)
                if lo - _EPS <= z <= hi + _EPS:
                    if abs(z1 - z0) < _EPS:
                        best = max(best, r0, r1)
                    else:
                        best = max(best, r0 + (r1 - r0) * (z - z0) / (z1 - z0))
            else:
                (rc, zc), rr = s.center, s.radius
                lo = min(s.start[1], s.end[1])
                hi = max(s.start[1], s.end[1])
                if lo - _EPS <= z <= hi + _EPS:
                    dz = min(abs(z - zc), rr)
                    best = max(best, rc + math.sqrt(max(rr * rr - dz * dz, 0.0)))
        return best


@dataclass(frozen=True)
class MillingTool:
    """A rotating milling cutter. Subclasses fix the cutting-part geometry.

    Common attributes (mm, degrees): ``flute_length`` is the cutting length from the tip;
    ``shank_diameter`` (default: the cutting diameter) and ``overall_length`` (tip to the end of the
    shank, default ``flute_length + 2*diameter``) describe the non-cutting part; ``flutes`` the number
    of teeth; ``helix_angle`` the flute helix angle; ``spindle`` the rotation sense.
    ``shoulder_length`` (tip to the shoulder, mm, > flute length) ends a non-cutting neck of
    ``neck_diameter`` (default: the diameter at the top of the flutes) above the flutes; the shank
    starts there instead of at the flute length. ``source`` says where the definition came from
    (``file:line``, a library entry) for messages; it takes no part in comparisons.
    """

    diameter: float
    flute_length: float
    flutes: int = 2
    helix_angle: float = 30.0
    spindle: SpindleDirection = SpindleDirection.CW
    shank_diameter: float | None = None
    overall_length: float | None = None
    number: int | None = None  # the T number in the program, when known
    name: str = ""
    neck_diameter: float | None = None
    shoulder_length: float | None = None
    source: str = field(default="", compare=False, repr=False)
    kind: str = field(default="generic", init=False)

    def __post_init__(self) -> None:
        if not (self.diameter > 0):
            raise ToolDefinitionError(f"tool {self.label}: diameter must be > 0, got {self.diameter}")
        if not (self.flute_length > 0):
            raise ToolDefinitionError(f"tool {self.label}: flute length must be > 0, got {self.flute_length}")
        if self.flutes < 1:
            raise ToolDefinitionError(f"tool {self.label}: needs at least one flute, got {self.flutes}")
        if not (0 <= self.helix_angle < 90):
            raise ToolDefinitionError(f"tool {self.label}: helix angle must be in [0, 90) degrees")
        if self.overall_length is not None and self.overall_length < self.flute_length:
            raise ToolDefinitionError(f"tool {self.label}: overall length shorter than the flute length")
        if self.neck_diameter is not None:
            if not (self.neck_diameter > 0):
                raise ToolDefinitionError(f"tool {self.label}: neck diameter must be > 0, got {self.neck_diameter}")
            if self.shoulder_length is None:
                raise ToolDefinitionError(f"tool {self.label}: a neck diameter needs the shoulder length")
        if self.shoulder_length is not None:
            if not (self.shoulder_length > self.flute_length):
                raise ToolDefinitionError(f"tool {self.label}: shoulder length {self.shoulder_length:g} mm must "
                                          f"exceed the flute length {self.flute_length:g} mm")
            if self.overall_length is not None and self.overall_length < self.shoulder_length:
                raise ToolDefinitionError(f"tool {self.label}: overall length shorter than the shoulder length")
        if not getattr(self, "_skip_apt", False):
            self.apt()  # validates the geometry of the family

    @property
    def label(self) -> str:
        return self.name or (f"T{self.number}" if self.number is not None else self.kind)

    @property
    def radius(self) -> float:
        return 0.5 * self.diameter

    @property
    def shank_radius(self) -> float:
        """Shank radius, mm; by default the radius at the top of the fluted part."""
        if self.shank_diameter is not None:
            return 0.5 * self.shank_diameter
        return self.cutting_profile()[-1].end[0]

    @property
    def neck_radius(self) -> float | None:
        """Radius of the neck between the flutes and the shoulder, mm; None without a neck."""
        if self.shoulder_length is None:
            return None
        if self.neck_diameter is not None:
            return 0.5 * self.neck_diameter
        return self.cutting_profile()[-1].end[0]

    @property
    def length(self) -> float:
        """Tip to the end of the modelled shank, mm (by default at least to the shoulder)."""
        if self.overall_length is not None:
            return self.overall_length
        return max(self.flute_length + 2 * self.diameter, self.shoulder_length or 0.0)

    def apt(self) -> AptParameters:
        raise NotImplementedError

    def cutting_profile(self) -> tuple[ProfileSegment, ...]:
        """The fluted part's outline from the tip (z=0) up to the flute length."""
        return self.apt().cutting_profile()

    def profile(self) -> ToolProfile:
        """The whole tool outline: cutting part from the APT parameters, then the shank."""
        # built once per tool: the engine asks for it several times per CL (~0.2 ms a CL)
        cached = self.__dict__.get("_profile")
        if cached is None:
            cached = self._build_profile()
            object.__setattr__(self, "_profile", cached)
        return cached

    def _build_profile(self) -> ToolProfile:
        segs = list(self.cutting_profile())
        r, z = segs[-1].end[0], self.flute_length
        top = self.length
        zone: Literal["flute", "shank"] = "flute"
        rn = self.neck_radius
        if rn is not None and self.shoulder_length is not None:
            # the neck: a cylinder of its own radius from the flutes up to the shoulder, not cutting
            if abs(rn - r) > _EPS:
                segs.append(ProfileLine((r, z), (rn, z), "shank"))
            segs.append(ProfileLine((rn, z), (rn, self.shoulder_length), "shank"))
            r, z, zone = rn, self.shoulder_length, "shank"
        rs = self.shank_radius
        if top > z + _EPS:
            if abs(rs - r) > _EPS:
                segs.append(ProfileLine((r, z), (rs, z), "shank"))
            segs.append(ProfileLine((rs, z), (rs, top), "shank"))
            segs.append(ProfileLine((rs, top), (0.0, top), "shank"))
        else:
            segs.append(ProfileLine((r, z), (0.0, z), zone))
        return ToolProfile(tuple(segs))

    @property
    def is_convex(self) -> bool:
        """True when the tool solid is convex (what exact ramp sweeps assume)."""
        pts: list[tuple[float, float]] = []
        for seg in self.profile().segments:
            pts.append(seg.start)
            if isinstance(seg, ProfileArc):
                pts.append(seg.midpoint)
        pts.append(self.profile().segments[-1].end)
        ring = [(-r, z) for r, z in reversed(pts)] + pts
        sign = 0.0
        n = len(ring)
        for k in range(n):
            (x0, y0), (x1, y1), (x2, y2) = ring[k], ring[(k + 1) % n], ring[(k + 2) % n]
            c = (x1 - x0) * (y2 - y1) - (y1 - y0) * (x2 - x1)
            if abs(c) < 1e-12:
                continue
            if sign == 0.0:
                sign = c
            elif c * sign < 0:
                return False
        return True


@dataclass(frozen=True)
class AptParameters:
    """The 7 APT cutter parameters (mm and degrees), see the module docstring."""

    d: float
    r: float
    e: float
    f: float
    alpha: float
    beta: float
    h: float

    def __post_init__(self) -> None:
        if self.r < 0 or self.e < 0 or self.h <= 0:
            raise ToolDefinitionError(f"APT cutter {self}: r, e must be >= 0 and h > 0")
        if not (-90 < self.beta < 90) or not (0 <= self.alpha < 90):
            raise ToolDefinitionError(f"APT cutter {self}: need 0 <= alpha < 90 and |beta| < 90 degrees")
        if abs(self.d - 2 * (self.e + self.r * math.cos(math.radians(self.beta)))) > 1e-6 * max(1.0, self.d):
            raise ToolDefinitionError(
                f"APT cutter {self}: d={self.d} disagrees with 2*(e + r*cos(beta))="
                f"{2 * (self.e + self.r * math.cos(math.radians(self.beta))):.6g}"
            )
        if self.side_start[1] > self.h + _EPS:
            raise ToolDefinitionError(f"APT cutter {self}: the corner ends above the height h")
        if self.tip_z < -_EPS:
            raise ToolDefinitionError(f"APT cutter {self}: the bottom reaches below the tip (z<0)")

    @property
    def bottom_end(self) -> tuple[float, float]:
        a = math.radians(self.alpha)
        return (self.e + self.r * math.sin(a), self.f - self.r * math.cos(a))

    @property
    def side_start(self) -> tuple[float, float]:
        b = math.radians(self.beta)
        return (self.e + self.r * math.cos(b), self.f - self.r * math.sin(b))

    @property
    def tip_z(self) -> float:
        """Height of the bottom line on the axis (0 for every standard tool)."""
        r0, z0 = self.bottom_end
        return z0 - r0 * math.tan(math.radians(self.alpha))

    @property
    def top_radius(self) -> float:
        r1, z1 = self.side_start
        return r1 + (self.h - z1) * math.tan(math.radians(self.beta))

    def cutting_profile(self) -> tuple[ProfileSegment, ...]:
        """Bottom line, corner arc, side line; z measured from the lowest point of the tool."""
        shift = self.tip_z if abs(self.tip_z) > _EPS else 0.0
        def p(pt: tuple[float, float]) -> tuple[float, float]:
            return (pt[0], pt[1] - shift)

        segs: list[ProfileSegment] = []
        b0 = (0.0, shift)
        b1 = self.bottom_end
        s0 = self.side_start
        s1 = (self.top_radius, self.h)
        if math.dist(b0, b1) > _EPS:
            segs.append(ProfileLine(p(b0), p(b1)))
        if self.r > _EPS and math.dist(b1, s0) > _EPS:
            segs.append(ProfileArc(p((self.e, self.f)), self.r, p(b1), p(s0)))
        if math.dist(s0, s1) > _EPS:
            segs.append(ProfileLine(p(s0), p(s1)))
        return tuple(segs)


@dataclass(frozen=True)
class AptCutter(MillingTool):
    """A cutter given by its APT 7 parameters; ``diameter`` must equal ``apt_parameters.d``."""

    apt_parameters: AptParameters = field(default=None)  # type: ignore[assignment]
    kind: str = field(default="apt", init=False)

    def __post_init__(self) -> None:
        if self.apt_parameters is None:
            raise ToolDefinitionError("APT cutter needs its 7 parameters")
        if abs(self.apt_parameters.d - self.diameter) > 1e-9:
            raise ToolDefinitionError(f"APT cutter: diameter {self.diameter} != d {self.apt_parameters.d}")
        super().__post_init__()

    def apt(self) -> AptParameters:
        a = self.apt_parameters
        return AptParameters(a.d, a.r, a.e, a.f, a.alpha, a.beta, self.flute_length)


@dataclass(frozen=True)
class FlatEndMill(MillingTool):
    kind: str = field(default="flat", init=False)

    def apt(self) -> AptParameters:
        return AptParameters(self.diameter, 0.0, self.radius, 0.0, 0.0, 0.0, self.flute_length)


@dataclass(frozen=True)
class BallEndMill(MillingTool):
    kind: str = field(default="ball", init=False)

    def apt(self) -> AptParameters:
        if self.flute_length < self.radius:
            raise ToolDefinitionError(f"tool {self.label}: ball end mill flute length below its radius")
        r = self.radius
        return AptParameters(self.diameter, r, 0.0, r, 0.0, 0.0, self.flute_length)


@dataclass(frozen=True)
class BullNoseEndMill(MillingTool):
    """Flat end mill with a corner radius ``corner_radius`` (mm), 0 < corner_radius < diameter/2."""

    corner_radius: float = 0.0
    kind: str = field(default="bullnose", init=False)

    def apt(self) -> AptParameters:
        rc = self.corner_radius
        if not (0 < rc < self.radius):
            raise ToolDefinitionError(
                f"tool {self.label}: corner radius must be in (0, {self.radius}), got {rc}"
            )
        return AptParameters(self.diameter, rc, self.radius - rc, rc, 0.0, 0.0, self.flute_length)


@dataclass(frozen=True)
class TaperedEndMill(MillingTool):
    """Flat-bottomed tapered mill: ``tip_diameter`` at the tip, side at ``taper_angle`` (degrees,
    from the axis, > 0 widens upward). ``diameter`` is the tip diameter here (the APT ``d``)."""

    taper_angle: float = 0.0
    kind: str = field(default="tapered", init=False)

    def apt(self) -> AptParameters:
        if not (0 <= self.taper_angle < 90):
            raise ToolDefinitionError(f"tool {self.label}: taper angle must be in [0, 90) degrees")
        return AptParameters(self.diameter, 0.0, self.radius, 0.0, 0.0, self.taper_angle, self.flute_length)


@dataclass(frozen=True)
class ChamferMill(MillingTool):
    """Chamfer / spot / V-bit: a cone from ``tip_diameter`` (0 for a point) at ``taper_angle`` from the
    axis (half the included angle) up to ``diameter``, cylindrical above that up to the flute length."""

    tip_diameter: float = 0.0
    taper_angle: float = 45.0
    kind: str = field(default="chamfer", init=False)

    def apt(self) -> AptParameters:
        if not (0 < self.taper_angle < 90):
            raise ToolDefinitionError(f"tool {self.label}: chamfer half-angle must be in (0, 90) degrees")
        if not (0 <= self.tip_diameter < self.diameter):
            raise ToolDefinitionError(f"tool {self.label}: tip diameter must be in [0, diameter)")
        if self.cone_height > self.flute_length + _EPS:
            raise ToolDefinitionError(f"tool {self.label}: cone ({self.cone_height:.4g} mm) longer than the flutes")
        if self.tip_diameter > 0:
            raise ToolDefinitionError(f"tool {self.label}: a flat-tipped chamfer mill has no APT form")
        # A pointed cone is the APT cutter whose bottom line rises at alpha = 90 - half-angle.
        alpha = 90.0 - self.taper_angle
        return AptParameters(self.diameter, 0.0, self.radius, self.cone_height, alpha, 0.0, self.flute_length)

    @property
    def cone_height(self) -> float:
        return (self.radius - self.tip_diameter / 2) / math.tan(math.radians(self.taper_angle))

    def cutting_profile(self) -> tuple[ProfileSegment, ...]:
        if self.tip_diameter == 0:
            return self.apt().cutting_profile()
        rt, h0 = self.tip_diameter / 2, self.cone_height
        segs: list[ProfileSegment] = [ProfileLine((0.0, 0.0), (rt, 0.0)), ProfileLine((rt, 0.0), (self.radius, h0))]
        if self.flute_length > h0 + _EPS:
            segs.append(ProfileLine((self.radius, h0), (self.radius, self.flute_length)))
        return tuple(segs)

    def __post_init__(self) -> None:
        if self.tip_diameter > 0:
            if not (0 < self.taper_angle < 90) or not (self.tip_diameter < self.diameter):
                raise ToolDefinitionError(f"tool {self.label}: need 0 < half-angle < 90 and tip < diameter")
            if self.cone_height > self.flute_length + _EPS:
                raise ToolDefinitionError(f"tool {self.label}: cone longer than the flutes")
            object.__setattr__(self, "_skip_apt", True)
        MillingTool.__post_init__(self)


@dataclass(frozen=True)
class Drill(MillingTool):
    """A twist drill: a pointed cone of ``point_angle`` (degrees, the *included* angle of the point,
    118 typical) from the tip up to ``diameter``, cylindrical above that up to the flute length.

    In APT terms the bottom line rises at ``alpha = 90 - point_angle/2`` above the horizontal from
    the axis to the corner at radius ``d/2``, height ``(d/2) / tan(point_angle/2)`` (the cone height),
    the same cutter as a pointed :class:`ChamferMill` of half-angle ``point_angle/2``.
    """

    point_angle: float = 118.0
    kind: str = field(default="drill", init=False)

    def apt(self) -> AptParameters:
        if not (0 < self.point_angle < 180):
            raise ToolDefinitionError(f"tool {self.label}: drill point angle must be in (0, 180) degrees, "
                                      f"got {self.point_angle:g}")
        if self.cone_height > self.flute_length + _EPS:
            raise ToolDefinitionError(f"tool {self.label}: drill point ({self.cone_height:.4g} mm) longer than "
                                      "the flutes")
        alpha = 90.0 - self.point_angle / 2
        return AptParameters(self.diameter, 0.0, self.radius, self.cone_height, alpha, 0.0, self.flute_length)

    @property
    def cone_height(self) -> float:
        """Height of the point above the tip, mm: ``r / tan(point_angle / 2)``."""
        return self.radius / math.tan(math.radians(self.point_angle / 2))


TOOL_KINDS: dict[str, type[MillingTool]] = {
    cls.kind: cls  # type: ignore[misc]
    for cls in (FlatEndMill, BallEndMill, BullNoseEndMill, TaperedEndMill, ChamferMill, Drill, AptCutter)
}


def describe(tool: MillingTool) -> str:
    """A tool's cutting geometry in a few words (mm, degrees), for messages: ``flat D=3.175``."""
    parts = [f"{tool.kind} D={tool.diameter:.6g}"]
    for attr, word in (("corner_radius", "CR"), ("taper_angle", "taper"), ("tip_diameter", "tip"),
                       ("point_angle", "point")):
        value = getattr(tool, attr, None)
        if value:
            parts.append(f"{word}={value:.6g}")
    return " ".join(parts)


def cutting_shape_difference(a: MillingTool, b: MillingTool, tolerance: float = 5e-4) -> float:
    """The largest difference (mm) between the radii of two tools' cutting parts, over the height
    both have flutes (0 when they agree: the families may differ, e.g. a 118 degree drill and a
    pointed chamfer mill of half-angle 59). Sampled at every profile vertex and at 256 even steps;
    ``tolerance`` (mm) is what a post's rounding of the sizes (3 decimals) may account for, and
    differences below it are reported as 0."""
    h = min(a.flute_length, b.flute_length)
    zs = {h * k / 256 for k in range(257)}
    for tool in (a, b):
        for s in tool.cutting_profile():
            zs.update(z for z in (s.start[1], s.end[1]) if 0 <= z <= h)
    pa, pb = a.profile(), b.profile()
    worst = max(abs(pa.radius_at(z) - pb.radius_at(z)) for z in zs)
    return worst if worst > tolerance else 0.0
