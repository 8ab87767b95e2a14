"""Motion of a block on the :class:`~.machine.Machine`: end points from axis words, G2/G3 arcs with
LinuxCNC's centre rules and checks, and G5/G5.1 splines flattened into feeds.

All coordinates are machine-frame mm (degrees for A, B, C). Arc centres come from ``R`` (LinuxCNC's
``arc_data_r``: a negative R takes the long way round) or from I/J/K, incremental from the start
(G91.1) or absolute (G90.1); ``arc_centers="auto"`` switches to absolute centres for the rest of the
program when incremental ones fail the radius check and absolute ones pass it (see the package doc).
"""
from __future__ import annotations

import math
from dataclasses import replace

from fusioncut.errors import InputError, JobTooLarge, SourceLocation
from fusioncut.io.gcode.budget import MAX_ARC_TURNS
from fusioncut.io.gcode.machine import Machine, Words
from fusioncut.io.gcode.modal import AXES, PLANE_GCODE, PLANE_OFFSET_WORDS, ROTARY, gname
from fusioncut.model.moves import ArcMove, ArcPlane
from fusioncut.model.units import MM_PER_INCH

__all__ = ["arc", "arc_center", "arc_target", "spline", "target"]

# LinuxCNC's arc checks (interp_internal.hh): a centre-format arc may "spiral" by this much between
# its start and end radius, or by up to 100 times as much if also within this relative amount ...
SPIRAL_ABS_TOL_MM = 2 * 0.01 * math.sqrt(2)
SPIRAL_ABS_TOL_INCH = 2 * 0.001 * math.sqrt(2)
SPIRAL_REL_TOL = 0.001
# ... a radius below this is a zero-radius arc; R-format arcs may miss the end by this much
RADIUS_TOL_INCH = 0.00005
# chord tolerance when flattening G5/G5.1 splines, mm
SPLINE_TOLERANCE_MM = 0.001
MAX_COORDINATE = 1e12  # mm or degrees; beyond this a program is broken, and floats lose their meaning


def target(m: Machine, w: Words, g53: bool) -> list[float]:
    """End point (machine frame, mm/deg) from the block's axis words; missing words and G91 increments
    start from the programmed point (which differs from the tool's with cutter compensation on)."""
    comp = m.comp
    if m.base is not None:
        base = m.base
        if comp is None:
            m.base = None  # only the first move after G40 starts from the programmed point
    elif comp is not None and not comp.first and comp.radius > 0:
        base = comp.prog
    else:
        base = m.pos
    end = list(base)
    s = m.scale()
    vals = w.vals
    if g53:
        if comp is not None:
            raise InputError("G53 with cutter radius compensation on", m.where(0))
        if not m.absolute:
            raise InputError("G53 in incremental distance mode (G91)", m.where(0))
        for k, a in enumerate(AXES):
            if a in vals:
                w.used.add(a)
                v = vals[a] * s if k < 3 else vals[a]
                end[k] = v - (m.tlo if k == 2 else 0.0)
        return end
    if m.absolute:
        off = None
        for k, a in enumerate(AXES):
            if a in vals:
                w.used.add(a)
                if off is None:
                    off = m.offset()
                end[k] = (vals[a] * s if k < 3 else vals[a]) + off[k]
    else:
        for k, a in enumerate(AXES):
            if a in vals:
                w.used.add(a)
                end[k] = base[k] + (vals[a] * s if k < 3 else vals[a])
    for k in range(6):
        if not abs(end[k]) <= MAX_COORDINATE:
            raise InputError(f"{AXES[k].upper()} coordinate {end[k]:.6g} out of range", m.where(w.col(AXES[k])))
    return end


def arc_target(m: Machine, w: Words, loc: SourceLocation) -> tuple[list[float], int]:
    """End point and extra turns (``P`` - 1, charged to the budget) of a G2/G3 block."""
    ia, ib, _ = m.plane.axes
    wa, wb = AXES[ia], AXES[ib]
    if m.arc_not_allowed:
        raise InputError("the move just after ending cutter compensation (G40) must be straight", loc)
    if wa not in w.vals and wb not in w.vals:
        raise InputError(f"arc in {PLANE_GCODE[m.plane]} needs {wa.upper()} or {wb.upper()}", loc)
    end = target(m, w, False)
    p_turns = w.get("p")
    turns = 0
    if p_turns is not None:
        if p_turns < 1 or p_turns != math.floor(p_turns):
            raise InputError(f"arc P (turns) must be a whole number >= 1, got P{p_turns:g}", loc)
        if p_turns > MAX_ARC_TURNS:
            raise JobTooLarge(f"arc P{p_turns:g}: more than {MAX_ARC_TURNS:,} turns in one block", loc)
        turns = int(p_turns) - 1
        if turns:
            m.spend_turns(turns, loc)
    return end, turns


def arc_center(m: Machine, end: list[float], cw: bool, w: Words, loc: SourceLocation,
               start: list[float]) -> tuple[float, float]:
    """In-plane centre (a, b) of a G2/G3 from ``start`` to ``end``, from R or I/J/K, with LinuxCNC's checks."""
    plane = m.plane
    ia, ib, _ = plane.axes
    oa, ob, _ = PLANE_OFFSET_WORDS[plane]
    s = m.scale()
    sa, sb = start[ia], start[ib]
    ea, eb = end[ia], end[ib]
    rad_tol = RADIUS_TOL_INCH * MM_PER_INCH
    r = w.get("r")
    if r is not None:
        if oa in w.vals or ob in w.vals:
            raise InputError("arc with both R and I/J/K", loc)
        return _center_from_radius(sa, sb, ea, eb, r * s, cw, rad_tol, loc)
    if oa not in w.vals and ob not in w.vals:
        raise InputError(f"arc needs R or {oa.upper()}/{ob.upper()} centre words", loc)
    if m.arc_absolute and (oa not in w.vals or ob not in w.vals):
        missing = oa if oa not in w.vals else ob
        raise InputError(f"{missing.upper()} word missing in an absolute-centre (G90.1) arc", loc)
    i_v = (w.get(oa) or 0.0) * s
    j_v = (w.get(ob) or 0.0) * s
    spiral = SPIRAL_ABS_TOL_INCH * MM_PER_INCH if m.inch else SPIRAL_ABS_TOL_MM
    off = m.offset()
    absolute_center = (i_v + off[ia], j_v + off[ib])
    center = absolute_center if m.arc_absolute else (sa + i_v, sb + j_v)
    err = _radius_error(sa, sb, ea, eb, center, rad_tol, spiral)
    if err is None:
        return center
    fits_absolute = not m.arc_absolute and _radius_error(sa, sb, ea, eb, absolute_center, rad_tol, spiral) is None
    if fits_absolute and m.arc_centers == "auto":
        m.arc_absolute = True
        m.warnings.append(
            f"{loc}: arc centre words read as incremental give start and end radii "
            f"{err[1]:.4f} and {err[2]:.4f} mm; as absolute centres (G90.1) they fit, so this "
            f"program is taken to use absolute I/J/K from here on"
        )
        return absolute_center
    hint = " (the centre fits as an absolute G90.1 centre: try arc_centers='auto' or 'absolute')" if fits_absolute else ""
    raise InputError(err[0] + hint, loc)


def arc(m: Machine, end: list[float], center: tuple[float, float], cw: bool, turns: int,
        loc: SourceLocation, w: Words | None) -> ArcMove:
    """Emit an arc from the current position to ``end`` about the in-plane ``center``."""
    m.check_rotary(end, loc)
    p = m.pos
    ia, ib, n = m.plane.axes
    c = [0.0, 0.0, 0.0]
    c[ia], c[ib], c[n] = center[0], center[1], p[n]
    mv = ArcMove(start=(p[0], p[1], p[2]), end=(end[0], end[1], end[2]), feed=None, spindle_rpm=m.rpm,
                 tool=m.tool, operation=m.take_operation(), source=loc, center=(c[0], c[1], c[2]),
                 plane=m.plane, clockwise=cw, turns=turns)
    # the feed of inverse time and the check need the arc's length, which the move computes
    mv = replace(mv, feed=m.feed_rate(mv.length, loc, w))
    m.push(mv, end)
    return mv


def spline(m: Machine, code: int, w: Words, loc: SourceLocation) -> None:
    """G5 cubic / G5.1 quadratic spline in G17, flattened into feeds within SPLINE_TOLERANCE_MM."""
    if m.plane is not ArcPlane.XY:
        raise InputError(f"{gname(code)} splines need the XY plane (G17)", loc)
    if m.comp is not None:
        raise InputError(f"{gname(code)} with cutter compensation on", loc)
    s = m.scale()
    if "z" in w.vals or any(a in w.vals for a in ROTARY):
        raise InputError(f"{gname(code)} moves only X and Y", loc)
    end = target(m, w, False)
    p0 = (m.pos[0], m.pos[1])
    p3 = (end[0], end[1])
    if code == 51:
        i_v, j_v = w.get("i"), w.get("j")
        if i_v is None and j_v is None:
            raise InputError("G5.1 needs I and J (control point offset from the start)", loc)
        c1 = (p0[0] + (i_v or 0.0) * s, p0[1] + (j_v or 0.0) * s)

        def point(t: float) -> tuple[float, float]:
            u = 1 - t
            return (u * u * p0[0] + 2 * u * t * c1[0] + t * t * p3[0],
                    u * u * p0[1] + 2 * u * t * c1[1] + t * t * p3[1])

        d2 = math.hypot(p0[0] - 2 * c1[0] + p3[0], p0[1] - 2 * c1[1] + p3[1]) * 2
    else:
        i_v, j_v, p_v, q_v = w.get("i"), w.get("j"), w.get("p"), w.get("q")
        if p_v is None or q_v is None:
            raise InputError("G5 needs P and Q (second control point offset from the end)", loc)
        if i_v is None and j_v is None:
            if m.g5_last is None:
                raise InputError("G5 without I/J must follow another G5", loc)
            i_v, j_v = m.g5_last
        c1 = (p0[0] + (i_v or 0.0) * s, p0[1] + (j_v or 0.0) * s)
        c2 = (p3[0] + p_v * s, p3[1] + q_v * s)
        m.g5_last = (-p_v, -q_v)

        def point(t: float) -> tuple[float, float]:
            u = 1 - t
            return (u ** 3 * p0[0] + 3 * u * u * t * c1[0] + 3 * u * t * t * c2[0] + t ** 3 * p3[0],
                    u ** 3 * p0[1] + 3 * u * u * t * c1[1] + 3 * u * t * t * c2[1] + t ** 3 * p3[1])

        # bound on |B''| of a cubic: 6 * max of its two second differences
        d2 = 6 * max(math.hypot(p0[0] - 2 * c1[0] + c2[0], p0[1] - 2 * c1[1] + c2[1]),
                     math.hypot(c1[0] - 2 * c2[0] + p3[0], c1[1] - 2 * c2[1] + p3[1]))
    # chord error of a segment of parameter length h is at most |B''| h^2 / 8
    nseg = max(1, math.ceil(math.sqrt(d2 / (8 * SPLINE_TOLERANCE_MM)))) if d2 > 0 else 1
    m.check_block(nseg, loc)
    for k in range(1, nseg + 1):
        x, y = p3 if k == nseg else point(k / nseg)
        e = list(m.pos)
        e[0], e[1] = x, y
        e[2] = end[2]
        m.linear(e, False, loc, w)


def _radius_error(sa: float, sb: float, ea: float, eb: float, center: tuple[float, float],
                  rad_tol: float, spiral_abs: float) -> tuple[str, float, float] | None:
    """LinuxCNC 2.9's centre-format arc check; ``None`` when the arc is acceptable.

    The end radius may differ from the start radius by ``spiral_abs`` (0.0283 mm in G21, 0.00283 in
    in G20) whatever the radius, and by up to 100 times that when the relative difference stays
    within 0.1 %."""
    r1 = math.hypot(center[0] - sa, center[1] - sb)
    r2 = math.hypot(center[0] - ea, center[1] - eb)
    if r1 < rad_tol or r2 < rad_tol:
        return (f"zero-radius arc (r1={r1:.4g}, r2={r2:.4g} mm)", r1, r2)
    abs_err = abs(r1 - r2)
    rel_err = abs_err / max(r1, r2)
    if abs_err > 100 * spiral_abs or (rel_err > SPIRAL_REL_TOL and abs_err > spiral_abs):
        return (
            f"radius to end of arc differs from radius to start: start=({sa:.4f}, {sb:.4f}) "
            f"centre=({center[0]:.4f}, {center[1]:.4f}) end=({ea:.4f}, {eb:.4f}) mm, r1={r1:.4f} r2={r2:.4f} "
            f"(abs_err={abs_err:.4g} mm, rel_err={100 * rel_err:.4f}%)",
            r1,
            r2,
        )
    return None


def _center_from_radius(sa: float, sb: float, ea: float, eb: float, radius: float, cw: bool,
                        tol: float, loc: SourceLocation) -> tuple[float, float]:
    """Centre of an R-format arc (LinuxCNC's arc_data_r): negative R takes the long way round."""
    if ea == sa and eb == sb:
        raise InputError("R-format arc cannot end where it starts (use I/J/K for a full circle)", loc)
    if radius == 0:
        raise InputError("arc radius R0", loc)
    abs_r = abs(radius)
    ma, mb = (sa + ea) / 2, (sb + eb) / 2
    half = math.hypot(ma - ea, mb - eb)
    if half - abs_r > tol:
        raise InputError(f"arc radius {abs_r:.4f} mm too small to reach the end point ({half:.4f} mm away)", loc)
    if half / abs_r > 1 - 1e-12:
        half = abs_r  # a small excess is a semicircle
    if (cw and radius > 0) or (not cw and radius < 0):
        theta = math.atan2(eb - sb, ea - sa) - math.pi / 2
    else:
        theta = math.atan2(eb - sb, ea - sa) + math.pi / 2
    offset = abs_r * math.cos(math.asin(half / abs_r))
    return (ma + offset * math.cos(theta), mb + offset * math.sin(theta))
