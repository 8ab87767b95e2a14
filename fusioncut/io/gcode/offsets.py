"""Offsets on the :class:`~.machine.Machine`: G10 (work origins, tool table), G92 and its cancels,
G28/G30 (go home, store home), tool length offsets (G43, G43.1, G49) and the numbered parameters
5161-5426 through which programs read and write them.

Values given in the program are in program units and become mm (degrees for A, B, C). The machine
frame is the program frame shifted by the active G54-G59.3 origin plus the G92 offset when applied.
A tool length offset does not move the controlled point (the tip): when it changes without a move,
the same physical spot gets a new Z, and targets in machine coordinates (G53, G28, G30) put the tip
``length`` below the programmed spindle position.
"""
from __future__ import annotations

import math

from fusioncut.errors import InputError
from fusioncut.io.gcode.machine import Machine, Words
from fusioncut.io.gcode.modal import AXES, gname
from fusioncut.io.gcode.motion import target

__all__ = ["g10", "g92", "home", "non_modal", "set_system_param", "system_param", "tool_length"]


def non_modal(m: Machine, w: Words, code: int, col: int) -> bool:
    """Group 0 codes that set offsets or move home (G10, G28, G28.1, G30, G30.1, G92, G92.1-G92.3);
    ``True`` for G53, which changes how the block's own motion reads its axis words."""
    if code == 100:
        g10(m, w, col)
    elif code in (280, 300):
        home(m, w, code, col)
    elif code in (281, 301):
        stored = m.g28 if code == 281 else m.g30
        for k in range(6):
            stored[k] = m.pos[k] + (m.tlo if k == 2 else 0.0)
    elif code == 920:
        g92(m, w, col)
    elif code == 921:
        m.g92 = [0.0] * 6
        m.g92_applied = False
    elif code == 922:
        m.g92_applied = False
    elif code == 923:
        m.g92_applied = True
    return code == 530


def tool_length(m: Machine, group: tuple[int, int], w: Words) -> None:
    """G43 H (tool table length), G43.1 Z (given length), G49 (none)."""
    code, col = group
    if m.comp is not None:
        raise InputError("cannot change the tool length offset with cutter compensation on", m.where(col))
    old = m.tlo
    if code == 490:
        m.tlo_number = None
        m.tlo = 0.0
    elif code == 430:
        h = w.get("h")
        n = int(h) if h is not None else (m.tool or 0)
        if h is not None and (h < 0 or h != math.floor(h)):
            raise InputError(f"bad H word H{h:g}", m.where(w.col("h")))
        m.tlo_number = n
        m.tlo = m.tool_lengths.get(n, 0.0) if n else 0.0
    elif code == 431:
        z = w.get("z")
        m.tlo_number = None
        m.tlo = (z or 0.0) * m.scale()
        for letter in "xyabc":
            w.get(letter)
    # Like LinuxCNC, the position is that of the controlled point: when the offset changes
    # without a move, the same physical spot gets a new Z (no-op when lengths are unknown, 0).
    m.pos[2] += old - m.tlo


def g10(m: Machine, w: Words, col: int) -> None:
    """G10 L2/L20 (work origins, given or from the current point) and L1/L10/L11 (tool table)."""
    l_val = w.get("l")
    p = w.get("p")
    if l_val is None:
        raise InputError("G10 needs an L word", m.where(col))
    lv = int(l_val)
    s = m.scale()
    if lv in (2, 20):
        if p is None or p != math.floor(p) or not 0 <= p <= 9:
            raise InputError("G10 L2/L20 needs P0..P9", m.where(col))
        n = int(p) or m.cs
        r = w.get("r")
        if r:
            m.unsupported("G10 coordinate system rotation R not supported", w.col("r"))
        for k, a in enumerate(AXES):
            v = w.get(a)
            if v is None:
                continue
            vm = v * s if k < 3 else v
            if lv == 2:
                m.g5x[n][k] = vm
            else:
                # L20: choose the origin so the current point has coordinate v in system n
                shift = m.g92[k] if m.g92_applied else 0.0
                m.g5x[n][k] = m.pos[k] - shift - vm
    elif lv in (1, 10, 11):
        if p is None or p != math.floor(p) or p < 0:
            raise InputError("G10 L1/L10/L11 needs a tool number P", m.where(col))
        n = int(p)
        z = w.get("z")
        r = w.get("r")
        for letter in "xyabcijq":
            w.get(letter)
        if z is not None:
            if lv == 1:
                m.tool_lengths[n] = z * s
            else:
                # L10/L11: length such that the current point is at Z (tip relative to the
                # spindle gauge point); as we do not move the tip with G43 this only
                # matters for machine-coordinate targets
                m.tool_lengths[n] = (m.pos[2] + m.tlo) - (z * s + m.offset()[2])
        if r is not None:
            m.tool_radii[n] = abs(r) * s
    else:
        raise InputError(f"G10 L{l_val:g} not supported", m.where(col))


def g92(m: Machine, w: Words, col: int) -> None:
    """G92: shift the program frame so the current point has the given coordinates."""
    if m.comp is not None:
        raise InputError("cannot change G92 offsets with cutter compensation on", m.where(col))
    if not any(a in w for a in AXES):
        raise InputError("G92 needs at least one axis word", m.where(col))
    s = m.scale()
    new = list(m.g92) if m.g92_applied else [0.0] * 6
    for k, a in enumerate(AXES):
        v = w.get(a)
        if v is None:
            continue
        vm = v * s if k < 3 else v
        new[k] = m.pos[k] - m.g5x[m.cs][k] - vm
    m.g92 = new
    m.g92_applied = True


def home(m: Machine, w: Words, code: int, col: int) -> None:
    """G28 / G30: rapid to the intermediate point (the axis words), then to the stored point."""
    stored = m.g28 if code == 280 else m.g30
    if m.comp is not None:
        raise InputError(f"{gname(code)} with cutter compensation on", m.where(col))
    mid = target(m, w, False)
    loc = m.where(col)
    m.linear(mid, True, loc)
    given = [a in w.vals for a in AXES]
    end = list(mid)
    for k in range(6):
        if given[k] or not any(given):
            end[k] = stored[k] - (m.tlo if k == 2 else 0.0)
    m.linear(end, True, loc)


def system_param(m: Machine, n: int) -> float | None:
    """The value of numbered parameter ``n`` that mirrors machine state (program units), if it is one."""
    s = m.scale()

    def unit(axis: int, v: float) -> float:
        return v / s if axis < 3 else v

    if 5161 <= n <= 5166:
        return unit(n - 5161, m.g28[n - 5161])
    if 5181 <= n <= 5186:
        return unit(n - 5181, m.g30[n - 5181])
    if n == 5210:
        return 1.0 if m.g92_applied else 0.0
    if 5211 <= n <= 5216:
        return unit(n - 5211, m.g92[n - 5211])
    if n == 5220:
        return float(m.cs)
    if 5221 <= n <= 5399:
        k, r = divmod(n - 5221, 20)
        if k < 9 and r < 6:
            return unit(r, m.g5x[k + 1][r])
        return None
    if n == 5400:
        return float(m.tool or 0)
    if n == 5403:
        return m.tlo / s
    if n == 5410:
        radius = m.tool_radii.get(m.tool or 0)
        return 2 * radius / s if radius is not None else 0.0
    if 5420 <= n <= 5425:
        return unit(n - 5420, m.program_pos(n - 5420))
    return None


def set_system_param(m: Machine, n: int, v: float) -> bool:
    """Write ``v`` (program units) to the offset that parameter ``n`` mirrors; ``False`` if none."""
    s = m.scale()

    def mm(axis: int) -> float:
        return v * s if axis < 3 else v

    if 5161 <= n <= 5166:
        m.g28[n - 5161] = mm(n - 5161)
    elif 5181 <= n <= 5186:
        m.g30[n - 5181] = mm(n - 5181)
    elif 5211 <= n <= 5216:
        m.g92[n - 5211] = mm(n - 5211)
    elif 5221 <= n <= 5399 and (n - 5221) // 20 < 9 and (n - 5221) % 20 < 6:
        k, r = divmod(n - 5221, 20)
        m.g5x[k + 1][r] = mm(r)
    else:
        return False
    return True
