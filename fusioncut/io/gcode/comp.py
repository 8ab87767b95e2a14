"""Cutter radius compensation (G40, G41, G42, G41.1, G42.1) with LinuxCNC 2.9's path rules.

The compensated path keeps the tool's axis one tool radius to the left (G41) or right (G42) of the
programmed contour, seen along the direction of travel, in the XY (G17) or XZ (G18) plane. The
radius is half the ``D`` word of G41.1/G42.1 (a diameter in program units), or, for G41/G42, the
radius of tool ``D`` (default: the loaded tool) from the ``tools`` mapping given to the reader, from
``G10 L1 P.. R..``, or else from the post's tool comment ``(T1 D=...)``; an unknown radius is an
error when strict, else compensation is skipped with a warning. A negative radius swaps the side.
Radius 0 leaves the path as programmed.

How the path is built (as LinuxCNC does, so the tests can compare with ``rs274``):

* entry (the first move after G41/G42): a straight move ends one radius to the side of its programmed
  end, perpendicular to the move; an arc ends on the offset arc, through a centre recomputed so that
  it starts at the current point;
* later moves are offset by the radius; at a convex corner an arc of the tool radius about the
  programmed corner is inserted (a G0 gets a straight traverse instead); at a concave corner the
  previous move is shortened to where the two offset moves meet, which needs one move of lookahead:
  each move is held back until the next one is known (so a block's moves may appear one block late);
* G40 ends compensation: the held move is released unchanged, the next move (which must be straight)
  starts from the compensated point and ends at its programmed point;
* M0/M1/M2/M30/M60 and the end of the program release the held move as well.

Moves that would make the tool gouge (too short, or an inside corner the tool cannot reach) raise
:class:`~fusioncut.errors.InputError`, like LinuxCNC's errors of the same names.
"""
from __future__ import annotations

import math

from fusioncut.errors import InputError, SourceLocation
from fusioncut.io.gcode.machine import CompState, HeldMove, Machine, Words
from fusioncut.io.gcode.modal import gname
from fusioncut.io.gcode.motion import arc as emit_arc
from fusioncut.io.gcode.motion import arc_center
from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Move
from fusioncut.model.units import length_scale

__all__ = ["arc", "flush", "set_mode", "straight"]

SMALL = 0.05  # LinuxCNC's TOLERANCE_CONCAVE_CORNER, radians: corners closer to straight than this are not corners
HALF_PI = math.pi / 2
TWO_PI = 2 * math.pi


def _tool_inside(side_left: bool, turn: int) -> bool:
    return (side_left and turn > 0) or (not side_left and turn < 0)


def _find_turn(x1: float, y1: float, cx: float, cy: float, turn: int, x2: float, y2: float) -> float:
    """Signed sweep (rad) from point 1 to point 2 about the centre for LinuxCNC's ``turn``."""
    if turn == 0:
        return 0.0
    alpha = math.atan2(y1 - cy, x1 - cx)
    beta = math.atan2(y2 - cy, x2 - cx)
    if turn > 0:
        if beta <= alpha:
            beta += TWO_PI
        return beta - alpha + (turn - 1) * TWO_PI
    if alpha <= beta:
        alpha += TWO_PI
    return beta - alpha + (turn + 1) * TWO_PI


# --------------------------------------------------------------------------- mode changes


def set_mode(m: Machine, group: tuple[int, int], w: Words) -> None:
    """G40 (release the held move, the next move starts from the programmed point) or G41/G42/G41.1/
    G42.1 (turn compensation on with the radius the module doc describes)."""
    code, col = group
    where = m.where(col)
    if code == 400:
        comp = m.comp
        if comp is not None and comp.radius > 0 and not comp.first:
            _move_endpoint_and_flush(m, comp, comp.cur[comp.plane.axes[0]], comp.cur[comp.plane.axes[1]])
            _dequeue(m, comp)
            # the next move starts where the tool is, but its unspecified axes (and G91 increments)
            # come from the last programmed point; and it must be straight
            m.base = list(comp.prog)
            m.arc_not_allowed = True
        m.comp = None
        return
    name = gname(code)
    if m.plane not in (ArcPlane.XY, ArcPlane.ZX):
        raise InputError("cutter radius compensation only in the XY (G17) or XZ (G18) plane", where)
    if m.comp is not None:
        raise InputError("cannot turn cutter radius compensation on when it is already on", where)
    left = code in (410, 411)
    if code in (411, 421):
        d = w.get("d")
        if d is None:
            raise InputError(f"{name} with no D word (the tool diameter)", where)
        radius = d * m.scale() / 2
        orientation = w.get("l")
        if orientation is not None and orientation not in (0.0, 9.0):
            m.unsupported(f"{name} L{orientation:g} (lathe tool orientation) not supported", w.col("l"))
    else:
        d = w.get("d")
        if d is not None:
            if abs(d - round(d)) >= 1e-4 or d < 0:
                raise InputError(f"{name} requires the D word to be a tool number", where)
            number = int(round(d))
        else:
            number = m.tool or 0
        if number in m.tool_radii:
            radius = m.tool_radii[number]
        elif m.user_tools is None and number in m.tool_comments:
            # no tools given: the diameter a post wrote in its tool comment, in the program's units
            radius = m.tool_comments[number].diameter / 2 * length_scale(m.first_units == "inch")
        else:
            msg = (f"{name}: radius of tool {number} unknown (pass tools=..., or use G10 L1 or "
                   f"G41.1/G42.1 D<diameter>); compensation skipped")
            if m.strict:
                raise InputError(msg, where)
            m.warnings.append(f"{where}: {msg}")
            radius = 0.0
    if radius < 0:
        radius = -radius
        left = not left
    m.comp = CompState("left" if left else "right", radius, m.plane)


def flush(m: Machine) -> None:
    """Release held moves at their planned end points (program stops and end)."""
    comp = m.comp
    if comp is not None and comp.queue:
        a, b, _ = comp.plane.axes
        _move_endpoint_and_flush(m, comp, comp.cur[a], comp.cur[b])
        _dequeue(m, comp)


# --------------------------------------------------------------------------- queue


def _dequeue(m: Machine, comp: CompState) -> None:
    comp.endpoint = None
    queue, comp.queue = comp.queue, []
    for item in queue:
        _emit(m, comp, item)


def _emit(m: Machine, comp: CompState, item: HeldMove) -> None:
    p = m.pos
    start = (p[0], p[1], p[2])
    end = item.end
    e = (end[0], end[1], end[2])
    m.check_rotary(end, item.loc)
    mv: Move
    if item.kind == "arc":
        a, b, n = comp.plane.axes
        c = [0.0, 0.0, 0.0]
        c[a], c[b], c[n] = item.center[0], item.center[1], p[n]
        mv = ArcMove(start=start, end=e, feed=item.feed, spindle_rpm=item.rpm, tool=item.tool,
                     operation=item.operation, source=item.loc, center=(c[0], c[1], c[2]),
                     plane=comp.plane, clockwise=item.turn < 0, turns=abs(item.turn) - 1)
    else:
        mv = LinearMove(start=start, end=e, feed=item.feed, spindle_rpm=item.rpm, tool=item.tool,
                        operation=item.operation, source=item.loc, rapid=item.kind == "rapid")
    m.push(mv, end)


def _move_endpoint_and_flush(m: Machine, comp: CompState, x: float, y: float) -> None:
    """Move the in-plane end of every held move to (x, y) (a concave corner), then release them."""
    if not comp.queue:
        return
    a, b, _ = comp.plane.axes
    ep = comp.endpoint
    mismatch = 0.01 * m.scale()  # LinuxCNC's check is 0.01 in program units
    for item in comp.queue:
        loc = item.loc
        if item.kind == "arc":
            r1 = math.hypot(item.end[a] - item.center[0], item.end[b] - item.center[1])
            r2 = math.hypot(x - item.center[0], y - item.center[1])
            if abs(r1 - r2) > mismatch:
                raise InputError(f"cutter compensation made an arc with mismatched radii {r1:.4f} and {r2:.4f} mm", loc)
            if ep is not None and item.original_turns:
                l2 = _find_turn(ep[0], ep[1], item.center[0], item.center[1], item.turn, x, y)
                if abs(l2) > abs(item.original_turns) + 0.001:
                    raise InputError("arc move in concave corner cannot be reached by the tool without gouging", loc)
        elif ep is not None:
            dot = item.direction[0] * (x - ep[0]) + item.direction[1] * (y - ep[1])
            if dot < 0:
                what = "straight traverse" if item.kind == "rapid" else "straight feed"
                raise InputError(f"{what} in concave corner cannot be reached by the tool without gouging", loc)
        item.end[a] = x
        item.end[b] = y
    _dequeue(m, comp)
    comp.endpoint = (x, y)


def _held(m: Machine, kind: str, end: list[float], feed: float | None, loc: SourceLocation,
          **kw: object) -> HeldMove:
    """A compensated move ending at ``end`` (copied), with the machine's spindle, tool and operation."""
    return HeldMove(kind, list(end), feed, loc, rpm=m.rpm, tool=m.tool, operation=m.take_operation(), **kw)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- straight moves


def straight(m: Machine, end: list[float], rapid: bool, w: Words, loc: SourceLocation) -> None:
    """A G0/G1 programmed to ``end`` with compensation on: hold its offset form, adjusting the held move."""
    comp = m.comp
    assert comp is not None
    if comp.radius == 0:
        m.linear(end, rapid, loc, w)
        return
    a, b, n = comp.plane.axes
    base = m.pos if comp.first else comp.prog
    feed = None
    if not rapid:
        feed = m.feed_rate(math.dist(base[:3], end[:3]), loc, w)
    kind = "rapid" if rapid else "feed"
    r = comp.radius
    px, py = end[a], end[b]
    if comp.first:
        cx, cy = m.pos[a], m.pos[b]
        if math.hypot(px - cx, py - cy) <= r:
            raise InputError("cutter compensation entry move is not longer than the tool radius", loc)
        alpha = math.atan2(py - cy, px - cx) + (HALF_PI if comp.left else -HALF_PI)
        cur = list(end)
        cur[a] = px + r * math.cos(alpha)
        cur[b] = py + r * math.sin(alpha)
        comp.endpoint = (cx, cy)
        # LinuxCNC records the offset direction here; an entry move is long enough not to reverse
        comp.hold(_held(m, kind, cur, feed, loc, direction=(math.cos(alpha), math.sin(alpha))), end)
        return
    cx, cy = comp.cur[a], comp.cur[b]
    opx, opy = comp.prog[a], comp.prog[b]
    cur = list(end)
    if px == opx and py == opy:
        # no motion in the plane: stay at the compensated point
        cur[a], cur[b] = cx, cy
        comp.hold(_held(m, kind, cur, feed, loc, direction=(0.0, 0.0)), end)
    else:
        theta = math.atan2(cy - opy, cx - opx)
        alpha = math.atan2(py - opy, px - opx)
        if comp.left:
            if theta < alpha:
                theta += TWO_PI
            beta = theta - alpha - HALF_PI
            gamma = HALF_PI
        else:
            if alpha < theta:
                alpha += TWO_PI
            beta = alpha - theta - HALF_PI
            gamma = -HALF_PI
        ex = px + r * math.cos(alpha + gamma)
        ey = py + r * math.sin(alpha + gamma)
        mx = opx + r * math.cos(alpha + gamma)
        my = opy + r * math.sin(alpha + gamma)
        front = comp.queue[0] if comp.queue else None
        if beta < -SMALL or beta > math.pi + SMALL:
            concave = True
        elif (beta > math.pi - SMALL and front is not None and front.kind == "arc"
              and ((not comp.left and front.turn > 0) or (comp.left and front.turn < 0))):
            # an "h" shape: over a round top and down beside it; LinuxCNC stays outside the corner
            concave = True
        else:
            concave = False
        if not concave and beta > SMALL:
            # convex corner: go round it on an arc of the tool radius about the programmed corner
            _move_endpoint_and_flush(m, comp, cx, cy)
            corner = list(end)
            corner[a], corner[b], corner[n] = mx, my, comp.cur[n]
            if not rapid:
                comp.queue.append(_held(m, "arc", corner, feed, loc, center=(opx, opy),
                                        turn=-1 if comp.left else 1))
            else:
                # there is no rapid arc; a traverse at least runs parallel to the programmed one
                comp.queue.append(_held(m, "rapid", corner, None, loc))
            _dequeue(m, comp)
            comp.endpoint = (mx, my)
        elif concave:
            if front is None or front.kind != "arc":
                half_corner = (beta + math.pi) / 2
                if half_corner == 0.0:
                    raise InputError("zero degree inside corner is invalid for cutter compensation", loc)
                retreat = r / math.tan(half_corner)
                mx = cx + retreat * math.cos(theta + gamma)
                my = cy + retreat * math.sin(theta + gamma)
                _move_endpoint_and_flush(m, comp, mx, my)
            else:
                mx, my = _arc_to_line_corner(comp, front, px, py, opx, opy, loc)
                _move_endpoint_and_flush(m, comp, mx, my)
        else:
            # straight on (or tangent from an arc): nothing to adjust
            _dequeue(m, comp)
            comp.endpoint = (cx, cy)
        cur[a], cur[b] = ex, ey
        comp.hold(_held(m, kind, cur, feed, loc, direction=(px - opx, py - opy)), end)


def _arc_to_line_corner(comp: CompState, prev: HeldMove, px: float, py: float, opx: float, opy: float,
                        loc: SourceLocation) -> tuple[float, float]:
    """Where the held (compensated) arc meets the offset of the new line in a concave corner."""
    a, b, _ = comp.plane.axes
    r = comp.radius
    oldrad = math.hypot(prev.center[1] - prev.end[b], prev.center[0] - prev.end[a])
    base_dir = math.atan2(py - opy, px - opx)
    theta = base_dir + HALF_PI if prev.turn > 0 else base_dir - HALF_PI
    phi = math.atan2(prev.center[1] - opy, prev.center[0] - opx)
    inside = _tool_inside(comp.left, prev.turn)
    oldrad_uncomp = oldrad + r if inside else oldrad - r
    d = oldrad_uncomp * math.cos(theta - phi)  # old centre's distance from the new line
    d2 = d - r if inside else d + r
    ratio = d2 / oldrad
    if not -1.0 <= ratio <= 1.0:
        raise InputError(
            "arc to straight motion makes a corner the compensated tool can't fit in without gouging", loc
        )
    if inside:
        ang = (-math.acos(ratio) if prev.turn > 0 else math.acos(ratio)) + theta + math.pi
    else:
        ang = (math.acos(ratio) if prev.turn > 0 else -math.acos(ratio)) + theta + math.pi
    return prev.center[0] + oldrad * math.cos(ang), prev.center[1] + oldrad * math.sin(ang)


# --------------------------------------------------------------------------- arcs


def arc(m: Machine, end: list[float], cw: bool, turns: int, w: Words, loc: SourceLocation) -> None:
    """A G2/G3 programmed to ``end`` with compensation on: hold its offset form, adjusting the held move."""
    comp = m.comp
    assert comp is not None
    if comp.radius == 0:
        center = arc_center(m, end, cw, w, loc, m.pos)
        emit_arc(m, end, center, cw, turns, loc, w)
        return
    a, b, n = comp.plane.axes
    r = comp.radius
    turn = (-1 if cw else 1) * (turns + 1)
    px, py = end[a], end[b]
    if comp.first:
        cx, cy = m.pos[a], m.pos[b]
        if math.hypot(px - cx, py - cy) <= r:
            raise InputError("radius of cutter compensation entry arc is not greater than the tool radius", loc)
        center = arc_center(m, end, cw, w, loc, m.pos)
        arc_r = math.hypot(center[0] - cx, center[1] - cy)
        if arc_r <= r and _tool_inside(comp.left, turn):
            raise InputError("tool radius not less than arc radius with cutter compensation", loc)
        feed = m.feed_rate(_arc_length(m.pos, end, center, turn, comp.plane), loc, w)
        if _tool_inside(comp.left, turn):
            gamma = math.atan2(center[1] - py, center[0] - px)
        else:
            gamma = math.atan2(py - center[1], px - center[0])
        ex = px + r * math.cos(gamma)
        ey = py + r * math.sin(gamma)
        # the compensated arc starts here and ends at (ex, ey): find its centre on the line from
        # the end through the programmed centre
        b_len = math.hypot(cy - ey, cx - ex) / 2
        ab_ang = math.atan2(center[1] - ey, center[0] - ex)
        a_ang = math.atan2(cy - ey, cx - ex) - ab_ang
        if abs(math.cos(a_ang)) < 1e-6:
            raise InputError("tool radius not less than arc radius with cutter compensation", loc)
        c_len = b_len / math.cos(a_ang)
        ncx = ex + c_len * math.cos(ab_ang)
        ncy = ey + c_len * math.sin(ab_ang)
        cur = list(end)
        cur[a], cur[b] = ex, ey
        comp.hold(_held(m, "arc", cur, feed, loc, center=(ncx, ncy), turn=turn,
                        original_turns=_find_turn(cx, cy, ncx, ncy, turn, ex, ey)), end)
        return

    opx, opy = comp.prog[a], comp.prog[b]
    cx, cy = comp.cur[a], comp.cur[b]
    center = arc_center(m, end, cw, w, loc, comp.prog)
    ccx, ccy = center
    feed = m.feed_rate(_arc_length(comp.prog, end, center, turn, comp.plane), loc, w)
    arc_radius = math.hypot(ccx - px, ccy - py)
    theta = math.atan2(cy - opy, cx - opx)
    theta = theta - HALF_PI if comp.left else theta + HALF_PI
    delta = math.atan2(ccy - opy, ccx - opx)
    alpha = delta + HALF_PI if cw else delta - HALF_PI
    beta = theta - alpha if comp.left else alpha - theta
    if beta > 1.5 * math.pi:
        beta -= TWO_PI
    elif beta < -HALF_PI:
        beta += TWO_PI
    inside = _tool_inside(comp.left, turn)
    if inside:
        gamma = math.atan2(ccy - py, ccx - px)
        if arc_radius <= r:
            raise InputError("tool radius not less than arc radius with cutter compensation", loc)
    else:
        gamma = math.atan2(py - ccy, px - ccx)
        delta += math.pi
    ex = px + r * math.cos(gamma)
    ey = py + r * math.sin(gamma)
    cur = list(end)
    cur[a], cur[b] = ex, ey
    main_turns = _find_turn(opx, opy, ccx, ccy, turn, px, py)
    front = comp.queue[0] if comp.queue else None
    if beta < -SMALL or beta > math.pi + SMALL or (abs(beta - math.pi) < SMALL and not inside):
        # concave: cut the held move back to where it meets this offset arc
        if front is None or front.kind != "arc":
            cyv = arc_radius * math.sin(beta - HALF_PI)
            if inside:
                dist = arc_radius - r
                ratio = (cyv + r) / dist
                _fits(ratio, loc)
                ang = theta + math.asin(ratio) if turn > 0 else theta - math.asin(ratio)
            else:
                dist = arc_radius + r
                ratio = (cyv - r) / dist
                _fits(ratio, loc)
                ang = theta + math.pi - math.asin(ratio) if turn > 0 else theta + math.pi + math.asin(ratio)
            mx, my = ccx + dist * math.cos(ang), ccy + dist * math.sin(ang)
        else:
            oldrad = math.hypot(front.center[1] - front.end[b], front.center[0] - front.end[a])
            newrad = arc_radius - r if inside else arc_radius + r
            arc_cc = math.hypot(front.center[1] - ccy, front.center[0] - ccx)
            if oldrad == 0 or arc_cc == 0:
                raise InputError("arc to arc motion is invalid because the arcs have the same center", loc)
            cos_a = (oldrad ** 2 + arc_cc ** 2 - newrad ** 2) / (2 * oldrad * arc_cc)
            if not -1.0 <= cos_a <= 1.0:
                raise InputError(
                    "arc to arc motion makes a corner the compensated tool can't fit in without gouging", loc
                )
            pullback = math.acos(cos_a)
            cc_dir = math.atan2(ccy - front.center[1], ccx - front.center[0])
            if _tool_inside(comp.left, front.turn):
                direction = cc_dir + pullback if turn > 0 else cc_dir - pullback
            else:
                direction = cc_dir - pullback if turn > 0 else cc_dir + pullback
            mx = front.center[0] + oldrad * math.cos(direction)
            my = front.center[1] + oldrad * math.sin(direction)
        _move_endpoint_and_flush(m, comp, mx, my)
    elif beta > SMALL:
        # convex: an arc of the tool radius round the programmed corner, then the offset arc
        mx = opx + r * math.cos(delta)
        my = opy + r * math.sin(delta)
        _dequeue(m, comp)
        corner = list(end)
        corner[a], corner[b], corner[n] = mx, my, comp.cur[n]
        comp.queue.append(_held(m, "arc", corner, feed, loc, center=(opx, opy), turn=-1 if comp.left else 1))
        _dequeue(m, comp)
        comp.endpoint = (mx, my)
    else:
        _dequeue(m, comp)
        comp.endpoint = (cx, cy)
    comp.hold(_held(m, "arc", cur, feed, loc, center=center, turn=turn, original_turns=main_turns), end)


def _fits(ratio: float, loc: SourceLocation) -> None:
    if not -1.0 <= ratio <= 1.0:
        raise InputError("arc move in concave corner cannot be reached by the tool without gouging", loc)


def _arc_length(start: list[float], end: list[float], center: tuple[float, float], turn: int,
                plane: ArcPlane) -> float:
    """Programmed helix length (mm), which inverse time feed uses even with compensation."""
    a, b, n = plane.axes
    radius = math.hypot(center[0] - start[a], center[1] - start[b])
    sweep = _find_turn(start[a], start[b], center[0], center[1], turn, end[a], end[b])
    return math.hypot(radius * sweep, end[n] - start[n])
