"""G and M codes by modal group (LinuxCNC's numbering), the :class:`ModalState` a block leaves, and the
sorting of one block's codes into their groups.

Codes are kept as ``int(10 * code)`` (``G59.1`` is 591, ``G0`` is 0), so decimal codes compare exactly.
A block may hold at most one code of each modal group (coolant M7 and M8 together are allowed);
LinuxCNC also accepts G80 beside another motion code, which then wins. Group 0 holds the non-modal
codes. Known codes that are not interpreted (probing, threading, NURBS, ...) count as unsupported:
strict reading refuses them, lenient reading warns and ignores them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Literal

from fusioncut.errors import InputError, SourceLocation
from fusioncut.model.moves import ArcPlane, Point

__all__ = ["BlockCodes", "ModalState", "code10", "gname", "sort_codes"]

AXES = "xyzabc"
AXES_SET = frozenset(AXES)
ROTARY = "abc"
# the centre words of an arc in each plane: (first in-plane axis, second, normal)
PLANE_OFFSET_WORDS = {ArcPlane.XY: ("i", "j", "k"), ArcPlane.ZX: ("k", "i", "j"), ArcPlane.YZ: ("j", "k", "i")}
PLANE_GCODE = {ArcPlane.XY: "G17", ArcPlane.ZX: "G18", ArcPlane.YZ: "G19"}
PLANE_CODES = {170: ArcPlane.XY, 180: ArcPlane.ZX, 190: ArcPlane.YZ}
COORD_SYSTEMS = ("G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")
COORD_SYSTEM_CODES = (540, 550, 560, 570, 580, 590, 591, 592, 593)
FEED_MODES = {930: "inverse_time", 940: "units_per_minute", 950: "units_per_revolution"}

# G codes we know, as int(10 * code) -> modal group (LinuxCNC numbering; 0 = non-modal)
G_GROUP: dict[int, int] = {}
for _c in (0, 10, 20, 30, 50, 51, 52, 53, 330, 331, 382, 383, 384, 385, 730, 740, 760, 800,
           810, 820, 830, 840, 850, 860, 870, 880, 890):
    G_GROUP[_c] = 1
for _c in (170, 180, 190, 171, 181, 191):
    G_GROUP[_c] = 2
G_GROUP.update({900: 3, 910: 3, 901: 4, 911: 4, 930: 5, 940: 5, 950: 5, 200: 6, 210: 6})
for _c in (400, 410, 411, 420, 421):
    G_GROUP[_c] = 7
for _c in (430, 431, 432, 490):
    G_GROUP[_c] = 8
G_GROUP.update({980: 10, 990: 10})
for _c in COORD_SYSTEM_CODES:
    G_GROUP[_c] = 12
G_GROUP.update({610: 13, 611: 13, 640: 13, 960: 14, 970: 14, 70: 15, 80: 15})
for _c in (40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923):
    G_GROUP[_c] = 0

# Known G codes that we do not interpret: treated like unknown codes (strict: error; else warning)
G_UNSUPPORTED = {
    52: "G5.2/G5.3 NURBS", 53: "G5.2/G5.3 NURBS", 330: "G33 spindle-synchronized motion",
    331: "G33.1 rigid tapping", 382: "G38.2 probing", 383: "G38.3 probing", 384: "G38.4 probing",
    385: "G38.5 probing", 760: "G76 lathe threading cycle", 171: "G17.1 UV plane", 181: "G18.1 WU plane",
    191: "G19.1 VW plane", 70: "G7 lathe diameter mode", 80: "G8 lathe radius mode",
    432: "G43.2 additional tool length offset", 520: "G52 local offset", 960: "G96 constant surface speed",
}
CYCLES = {730, 740, 810, 820, 830, 840, 850, 860, 870, 880, 890}
GROUP0_AXIS_USERS = {100, 280, 300, 520, 920}  # group 0 codes that take the block's axis words

# M codes: value -> group (LinuxCNC numbering)
M_GROUP: dict[int, int] = {0: 4, 1: 4, 2: 4, 30: 4, 60: 4, 6: 6, 61: 6, 3: 7, 4: 7, 5: 7, 19: 7,
                           7: 8, 8: 8, 9: 8, 48: 9, 49: 9, 50: 9, 51: 9, 52: 9, 53: 9}
for _c in range(62, 69):
    M_GROUP[_c] = 5
M_UNSUPPORTED = {70: "M70 save modal state", 71: "M71 invalidate modal state",
                 72: "M72 restore modal state", 73: "M73 save and autorestore modal state",
                 98: "M98 Fanuc subprogram call", 99: "M99 Fanuc subprogram return"}


@dataclass(frozen=True)
class ModalState:
    """The interpreter's modal state after a block (what a later block inherits).

    Lengths are in millimetres except ``feed``, which is the programmed ``F`` number as written
    (program units per minute, 1/min in G93, program units per revolution in G95).
    ``position`` is the tool tip in the machine frame (mm) after the last emitted move and ``rotary``
    the A, B, C angles (deg). ``work_offset`` is the active G54-G59.3 origin and ``g92_offset`` the G92
    shift (applied when ``g92_applied``), both in mm. ``tool_length_offset`` is the H number of G43
    (``None`` after G49/G43.1) and ``tool_length`` the length in use (mm). ``operation`` is the name
    moves get now, ``line`` the source line of the last executed block.
    """

    units: Literal["mm", "inch"] = "mm"
    distance_mode: Literal["absolute", "incremental"] = "absolute"
    arc_distance_mode: Literal["absolute", "incremental"] = "incremental"
    plane: ArcPlane = ArcPlane.XY
    feed_mode: Literal["units_per_minute", "inverse_time", "units_per_revolution"] = "units_per_minute"
    motion_mode: str | None = None
    coordinate_system: str = "G54"
    work_offset: Point = (0.0, 0.0, 0.0)
    g92_offset: Point = (0.0, 0.0, 0.0)
    g92_applied: bool = False
    tool: int | None = None
    prepared_tool: int | None = None
    tool_length_offset: int | None = None
    tool_length: float = 0.0
    spindle: Literal["off", "cw", "ccw"] = "off"
    spindle_rpm: float | None = None
    feed: float | None = None
    coolant: frozenset[str] = frozenset()
    cutter_compensation: Literal["off", "left", "right"] = "off"
    retract_mode: Literal["old_z", "r_plane"] = "old_z"
    position: Point = (0.0, 0.0, 0.0)
    rotary: Point = (0.0, 0.0, 0.0)
    operation: str = ""
    line: int = 0


def gname(code10: int) -> str:
    """``G`` name of a code kept as ``int(10 * code)``: 591 -> ``G59.1``."""
    return f"G{code10 // 10}" + (f".{code10 % 10}" if code10 % 10 else "")


def code10(v: float, letter: str, where: SourceLocation) -> int:
    """``int(10 * v)`` for a G code value with at most one decimal (within 1e-4), else an error."""
    c = round(v * 10)
    if abs(v * 10 - c) > 1e-3 or c < 0:
        raise InputError(f"bad {letter} code {letter}{v:g}", where)
    return int(c)


@dataclass
class BlockCodes:
    """One block's G and M codes by modal group: ``g`` and ``m`` map a group to ``(code, column)``
    (G codes as ``int(10 * code)``), ``coolant`` lists the M7/M8/M9 codes in order. ``skipped`` is true
    when an unknown or unsupported code was ignored: it may have wanted the block's other words."""

    g: dict[int, tuple[int, int]]
    m: dict[int, tuple[int, int]]
    coolant: list[int]
    skipped: bool


def sort_codes(gs: list[tuple[float, int]], ms: list[tuple[float, int]], where: Callable[[int], SourceLocation],
               unsupported: Callable[[str, int], None]) -> BlockCodes:
    """Sort a block's evaluated G and M words (value, column) by modal group. ``where(column)`` names
    the place of an error, ``unsupported(message, column)`` reports a code that is not interpreted."""
    groups: dict[int, tuple[int, int]] = {}
    skipped = False
    for v, col in gs:
        code = code10(v, "G", where(col))
        if code not in G_GROUP:
            unsupported(f"unknown G code {gname(code)}", col)
            skipped = True
            continue
        if code in G_UNSUPPORTED:
            unsupported(f"{G_UNSUPPORTED[code]} not supported", col)
            skipped = True
            continue
        grp = G_GROUP[code]
        if grp == 1 and grp in groups and 800 in (code, groups[1][0]):
            # LinuxCNC accepts G80 next to another motion code (posts write "G0 ... G80" as a
            # safe-start line); the other code wins
            if code != 800:
                groups[1] = (code, col)
            continue
        if grp in groups:
            raise InputError(f"two G codes from the same modal group: {gname(groups[grp][0])} and {gname(code)}",
                             where(col))
        groups[grp] = (code, col)
    mcodes: dict[int, tuple[int, int]] = {}
    coolant: list[int] = []
    for v, col in ms:
        if v != math.floor(v) or v < 0:
            raise InputError(f"bad M code M{v:g}", where(col))
        code = int(v)
        if code in M_UNSUPPORTED:
            unsupported(f"{M_UNSUPPORTED[code]} not supported", col)
            continue
        if code not in M_GROUP:
            what = "user M code" if 100 <= code <= 199 else "unknown M code"
            unsupported(f"{what} M{code}", col)
            continue
        grp = M_GROUP[code]
        if grp == 8:
            coolant.append(code)
            if len(coolant) > 1 and not set(coolant) <= {7, 8}:
                raise InputError("two M codes from the same modal group", where(col))
            continue
        if grp in mcodes:
            raise InputError(f"two M codes from the same modal group: M{mcodes[grp][0]} and M{code}", where(col))
        mcodes[grp] = (code, col)
    return BlockCodes(groups, mcodes, coolant, skipped)
