"""The settings a block makes before it moves, in LinuxCNC's order of execution: feed mode, F, S, T,
tool change, spindle, coolant, then dwell, plane, units, cutter compensation, tool length offset,
coordinate system, path control, distance modes and retract mode.

Tools: ``T`` prepares, ``M6`` loads. Until the program's first ``M6``, a ``T`` word loads the tool
directly, because posts for machines without a tool changer (Fusion's hobby posts) never write M6;
after the first M6, a ``T`` only prepares the next tool (Fanuc-style pre-staging). Changing the feed
mode resets the feed rate, as in LinuxCNC.
"""
from __future__ import annotations

import math

from fusioncut.errors import InputError
from fusioncut.io.gcode.comp import set_mode as set_compensation
from fusioncut.io.gcode.machine import Machine, Words
from fusioncut.io.gcode.modal import COORD_SYSTEM_CODES, FEED_MODES, PLANE_CODES, BlockCodes
from fusioncut.io.gcode.offsets import tool_length

__all__ = ["machine_settings", "modal_settings"]


def machine_settings(m: Machine, codes: BlockCodes, w: Words) -> None:
    """Feed mode, F, S, T, M6/M61, spindle (M3/M4/M5), coolant (M7/M8/M9), and the I/O M codes' words."""
    groups, mcodes = codes.g, codes.m
    if 5 in groups:
        mode = FEED_MODES[groups[5][0]]
        if mode != m.feed_mode:
            m.feed = None  # LinuxCNC resets the feed rate when the feed mode changes
        m.feed_mode = mode
    f = w.get("f")
    if f is not None:
        if f < 0:
            raise InputError(f"negative feed rate F{f:g}", m.where(w.col("f")))
        m.feed = f
    s = w.get("s")
    if s is not None:
        if s < 0:
            raise InputError(f"negative spindle speed S{s:g}", m.where(w.col("s")))
        m.rpm = s
    t = w.get("t")
    if t is not None:
        if t < 0 or t != math.floor(t):
            raise InputError(f"tool number must be a whole number >= 0, got T{t:g}", m.where(w.col("t")))
        m.prepared_tool = int(t)
        if not m.seen_m6:
            m.tool = int(t)  # before any M6, T loads the tool (see the module doc)
    m6 = mcodes.get(6)
    if m6 is not None:
        if m6[0] == 6:
            m.seen_m6 = True
            if m.prepared_tool is not None:
                m.tool = m.prepared_tool
            if m.comp is not None:
                raise InputError("tool change with cutter compensation on", m.where(m6[1]))
        else:  # M61 Q: set the loaded tool number without a change
            q = w.get("q")
            if q is None or q < 0 or q != math.floor(q):
                raise InputError("M61 needs a Q word with a tool number", m.where(m6[1]))
            m.tool = int(q)
    m7 = mcodes.get(7)
    if m7 is not None:
        code = m7[0]
        if code == 3:
            m.spindle = "cw"
        elif code == 4:
            m.spindle = "ccw"
            m.warn_once("m4", "M4 (counter-clockwise spindle) is kept in the modal state only; "
                        "moves do not carry the spindle direction yet", m7[1])
        elif code == 5:
            m.spindle = "off"
    for code in codes.coolant:
        if code == 7:
            m.coolant.add("mist")
        elif code == 8:
            m.coolant.add("flood")
        else:
            m.coolant.clear()
    if 5 in mcodes:
        for letter in "pelq":
            w.get(letter)


def modal_settings(m: Machine, codes: BlockCodes, w: Words) -> None:
    """G4 dwell, plane, units, cutter compensation, tool length offset, coordinate system, G64 words,
    distance modes (G90/G91, G90.1/G91.1) and retract mode (G98/G99)."""
    groups = codes.g
    g0 = groups.get(0)
    if g0 and g0[0] == 40:
        p = w.get("p")
        if p is None or p < 0:
            raise InputError("G4 dwell needs a P word >= 0", m.where(g0[1]))
    if 2 in groups:
        if m.comp is not None:
            raise InputError("cannot change the plane with cutter compensation on", m.where(groups[2][1]))
        m.plane = PLANE_CODES[groups[2][0]]
    if 6 in groups:
        m.inch = groups[6][0] == 200
        if m.first_units is None:
            m.first_units = "inch" if m.inch else "mm"
    if 7 in groups:
        set_compensation(m, groups[7], w)
    if 8 in groups:
        tool_length(m, groups[8], w)
    if 12 in groups:
        if m.comp is not None:
            raise InputError("cannot change coordinate system with cutter compensation on", m.where(groups[12][1]))
        m.cs = COORD_SYSTEM_CODES.index(groups[12][0]) + 1
    if 13 in groups and groups[13][0] == 640:
        w.get("p")
        w.get("q")
    if 3 in groups:
        m.absolute = groups[3][0] == 900
    if 4 in groups:
        m.arc_absolute = groups[4][0] == 901
    if 10 in groups:
        m.retract_old_z = groups[10][0] == 980
