"""Stock (raw material) from the job description or, failing that, from the toolpath. All in mm.

* :func:`parse_stock` reads a stock specification: ``box:xmin,ymin,zmin,xmax,ymax,zmax``,
  ``cylinder:cx,cy,cz,radius,height`` (a bar along +z whose base centre is (cx, cy, cz)), a STEP/BREP
  path (handed to the B-Rep engine, which reads it), or a CAMotics project (its workpiece bounds).
* :func:`infer_stock` guesses a box from where the tool cut.

**How the stock is inferred.** Only the material the tool can touch matters for engagement: stock
beyond the tool's reach changes nothing. So the sides and the bottom only need to enclose every
feed move that reaches into the stock, grown by the tool's largest cutting radius and ``margin``;
the margin also keeps the box faces clear of the tool envelope (coincident faces make Boolean
operations fragile). The *top* is what decides the engagement, and it follows the machinist's
convention:

1. ``top`` when the caller gives it (always prefer the stock stated in the CAM setup);
2. otherwise, when any feed move goes below z = 0, the top is z = 0: CAM systems (Fusion's default
   setup, CAMotics' automatic workpiece) put the work origin on the top of the stock and cut
   downwards. Material left above z = 0 (a setup with a stock-top offset) is then not seen;
3. otherwise (origin on the table or the stock bottom, all cutting at z >= 0) the top is the highest
   level at which the tool feeds sideways - a facing pass or the first step-down; plunges and ramps
   above it are entries through air. Programs that post rapids as feed moves (Fusion for Personal
   Use) defeat this rule: pass ``top``.

4. if that leaves nothing below the top (every cut at one level: a facing pass), the program faces the
   part's top at that level and the depth of cut is not in the program: the top is taken
   :data:`FACING_ALLOWANCE` above it (the stock-top offset CAM setups add by default), and the rule
   says so, asking for ``top`` when the real allowance differs.
The result is marked ``inferred=True``.
"""
from __future__ import annotations

import math
from pathlib import Path

from fusioncut.errors import InputError, SourceLocation
from fusioncut.model.moves import ArcMove, Move, Toolpath
from fusioncut.model.stock import BoxStock, CylinderStock, SolidStock, Stock
from fusioncut.model.tools import MillingTool, ProfileArc

__all__ = ["infer_stock", "parse_stock", "solid_stock", "stock_top", "DEFAULT_MARGIN", "FACING_ALLOWANCE"]

DEFAULT_MARGIN = 1.0  # mm around the cut envelope (sides and bottom)
FACING_ALLOWANCE = 1.0  # mm of stock assumed above a program that cuts at one level only (rule 4)
_SOLID_SUFFIXES = {".step", ".stp", ".brep", ".brp"}
_LEVEL_TOL = 1e-6  # mm; a feed move rising less than this is level


def solid_stock(path: str | Path) -> SolidStock:
    """A STEP/BREP stock; checks only that the file exists and has a B-Rep suffix."""
    p = Path(path)
    if p.suffix.lower() not in _SOLID_SUFFIXES:
        raise InputError(f"stock solid must be a STEP or BREP file ({', '.join(sorted(_SOLID_SUFFIXES))})",
                         SourceLocation(str(p)))
    if not p.is_file():
        raise InputError("stock file not found", SourceLocation(str(p)))
    return SolidStock(p)


def parse_stock(spec: str, *, base_dir: str | Path | None = None) -> Stock:
    """The stock a specification string describes (see the module docstring); relative paths are
    taken from ``base_dir`` when given. Raises :class:`InputError` for anything else."""
    text = spec.strip()
    where = SourceLocation("<stock>")
    kind, sep, rest = text.partition(":")
    if sep and kind.strip().lower() in {"box", "cylinder", "cyl"}:
        try:
            values = [float(v) for v in rest.split(",")]
        except ValueError as e:
            raise InputError(f"stock {text!r}: {kind} needs numbers separated by commas", where) from e
        if not all(math.isfinite(v) for v in values):
            raise InputError(f"stock {text!r}: values must be finite", where)
        if kind.strip().lower() == "box":
            if len(values) != 6:
                raise InputError(f"stock {text!r}: box needs xmin,ymin,zmin,xmax,ymax,zmax", where)
            return BoxStock(tuple(values[:3]), tuple(values[3:]))  # type: ignore[arg-type]
        if len(values) != 5:
            raise InputError(f"stock {text!r}: cylinder needs cx,cy,cz,radius,height", where)
        return CylinderStock(tuple(values[:3]), values[3], values[4])  # type: ignore[arg-type]
    p = Path(text)
    if base_dir is not None and not p.is_absolute():
        p = Path(base_dir) / p
    if p.suffix.lower() == ".camotics":
        from fusioncut.io.tool_library import read_camotics_project

        project = read_camotics_project(p)
        if project.stock is None:
            raise InputError("the CAMotics project states no workpiece bounds", SourceLocation(str(p)))
        return project.stock
    if p.suffix.lower() in _SOLID_SUFFIXES:
        return solid_stock(p)
    raise InputError(
        f"stock {text!r}: expected box:..., cylinder:..., a .step/.stp/.brep file or a .camotics project", where
    )


# --------------------------------------------------------------------------------------------------


def _cutting_radius(tool: MillingTool) -> float:
    """Largest radius of the fluted part, mm (the tip diameter of a tapered mill is not it)."""
    r = 0.0
    for seg in tool.cutting_profile():
        r = max(r, seg.start[0], seg.end[0])
        # a corner arc (walked upwards, counter-clockwise) bulges furthest out at its centre's height
        if isinstance(seg, ProfileArc) and seg.start[1] <= seg.center[1] <= seg.end[1]:
            r = max(r, seg.center[0] + seg.radius)
    return r


def _extent(move: Move) -> tuple[list[float], list[float]]:
    """Exact axis-aligned bounds (lo, hi) of a move's tool-tip path."""
    lo, hi = move.bounds
    return list(lo), list(hi)


def _is_sideways_level(move: Move) -> bool:
    if isinstance(move, ArcMove):
        return not move.is_helix and move.plane.axes[2] == 2
    dz = abs(move.end[2] - move.start[2])
    dxy = math.hypot(move.end[0] - move.start[0], move.end[1] - move.start[1])
    return dz <= _LEVEL_TOL and dxy > _LEVEL_TOL


def stock_top(toolpath: Toolpath) -> tuple[float, str]:
    """The inferred top of stock (mm) and the rule that gave it (see the module docstring)."""
    feeds = [m for m in toolpath.moves if not m.is_rapid]
    if not feeds:
        raise InputError("no feed moves to infer the stock from", SourceLocation(toolpath.source))
    z_min = min(_extent(m)[0][2] for m in feeds)
    if z_min < -_LEVEL_TOL:
        return 0.0, "work origin on the stock top: the program cuts below z = 0"
    levels = [m.start[2] for m in feeds if _is_sideways_level(m)]
    if levels:
        top = max(levels)
        rule = "highest level fed sideways (no cutting below z = 0)"
    else:
        top = max(_extent(m)[1][2] for m in feeds)
        rule = "highest feed move (no sideways feed, no cutting below z = 0)"
    if top <= z_min + _LEVEL_TOL:
        return top + FACING_ALLOWANCE, (
            f"all cutting at z = {top:.6g} (a facing pass): the program does not say how deep it cuts, so "
            f"{FACING_ALLOWANCE:g} mm of stock is assumed above it; give the real top (a job's stock_top, "
            "`fusioncut run --stock-top Z`) or the whole stock (`--stock box:x0,y0,z0,x1,y1,z1`)")
    return top, rule


def infer_stock(toolpath: Toolpath, margin: float = DEFAULT_MARGIN, *, top: float | None = None) -> BoxStock:
    """A box holding every feed move that reaches below the stock top, grown by the cutting radius
    of the move's tool and by ``margin`` (mm) on the sides and below; the top follows the rule in the
    module docstring unless ``top`` is given. Returned with ``inferred=True``."""
    if not (margin >= 0 and math.isfinite(margin)):
        raise InputError(f"stock margin must be a finite length >= 0, got {margin!r}", SourceLocation(toolpath.source))
    if top is None:
        top, _ = stock_top(toolpath)
    elif not math.isfinite(top):
        raise InputError(f"stock top must be finite, got {top!r}", SourceLocation(toolpath.source))
    radii: dict[int | None, float] = {}
    fallback = max((_cutting_radius(t) for t in toolpath.tools.values()), default=0.0)
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for m in toolpath.moves:
        if m.is_rapid:
            continue
        mlo, mhi = _extent(m)
        if mlo[2] >= top - _LEVEL_TOL:
            continue  # fed through the air above the stock: it neither cuts nor bounds the stock
        if m.tool not in radii:
            tool = toolpath.tools.get(m.tool) if m.tool is not None else None
            radii[m.tool] = _cutting_radius(tool) if tool is not None else fallback
        r = radii[m.tool]
        for i in range(2):
            lo[i] = min(lo[i], mlo[i] - r)
            hi[i] = max(hi[i], mhi[i] + r)
        lo[2] = min(lo[2], mlo[2])
    if not math.isfinite(lo[2]):
        raise InputError(f"no feed move goes below the stock top z = {top:.6g}", SourceLocation(toolpath.source))
    minimum = (lo[0] - margin, lo[1] - margin, lo[2] - margin)
    maximum = (hi[0] + margin, hi[1] + margin, top)
    if margin == 0 and (hi[0] <= lo[0] or hi[1] <= lo[1]):
        raise InputError("the cut has no extent in x or y; use a margin > 0", SourceLocation(toolpath.source))
    return BoxStock(minimum, maximum, inferred=True)
