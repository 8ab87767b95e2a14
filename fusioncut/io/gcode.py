"""RS274/NGC G-code interpreter (LinuxCNC dialect) producing a :class:`~fusioncut.model.moves.Toolpath`.

Written by hand: no maintained PyPI package interprets G-code with LinuxCNC's semantics (parameters,
expressions, O-word subroutines and loops, canned cycles in all three planes, G92/G10 offsets,
G28/G30, inverse time feed). The tests compare our moves with the canonical output of LinuxCNC's own
``rs274`` interpreter, move by move, for every reference program in ``shared/data``.

Public API
----------
``read_gcode(path, *, tools=None, strict=False, arc_centers="auto", max_moves=1_000_000) -> Toolpath`` and
``parse_gcode_text(text, *, source="<memory>", ...)``; :class:`GCodeInterpreter` runs a program
block by block (``step()``, iteration, ``execute(line)`` for single MDI lines) with the modal state
inspectable after each block as a frozen :class:`ModalState`.

Output
------
Moves are in the machine frame after work offsets (G54-G59.3, G92), in millimetres (G20 input is
converted, 1 in = 25.4 mm); the controlled point is the tool tip. Tool length offsets (G43 H, G43.1)
are recorded in the modal state but do not shift the tip; they only matter for targets given in
machine coordinates (G53, G28, G30), where the tip ends ``length`` below the programmed spindle
position. Lengths come from ``GCodeInterpreter(tool_lengths=...)`` or G10 L1/L10 and are 0 otherwise.
Feeds are in mm/min (``None`` for rapids): G94 ``F`` is per minute in program units, G93 inverse time
``F`` becomes ``F * move length`` (LinuxCNC's rule: the XYZ length, or the rotary length for purely
rotary moves), G95 ``F`` per revolution is multiplied by the programmed ``S``. ``spindle_rpm`` is the
programmed ``S``; the spindle direction (M3/M4/M5) is in :class:`ModalState` only, and M4 draws a
warning because moves cannot carry it yet. Angles of rotary axes are degrees.

Rules worth knowing
-------------------
* Operation names: a *standalone* comment line (only a comment, maybe an ``N`` number) that is not a
  tool description or a ``(MSG,...)``-style message is remembered; the first move after one or more
  such lines takes the last of them as its ``operation``, and later moves keep it until the next
  such comment. Fusion 360 and most posts write the operation name this way, e.g. ``(2D Adaptive1)``.
* Tools: ``T`` prepares, ``M6`` loads. Until the program's first ``M6``, a ``T`` word loads the
  tool directly, because posts for machines without a tool changer (Fusion's hobby posts) never
  write M6; after the first M6, a ``T`` only prepares the next tool (Fanuc-style pre-staging).
  Tool comments as Fusion/HSM posts write them, ``(T1 D=2.65 CR=0 - ZMIN=-12.55 - flat end mill)``,
  become :class:`~fusioncut.model.tools.MillingTool` objects in ``Toolpath.tools`` (flat, ball,
  bull-nose, chamfer, drill (``TAPER`` is its point angle, 118 degrees if absent), tapered; by the
  words and ``CR``/``TAPER``), in the program's units (its first G20/G21); the flute length is not
  in the comment and is taken as ``max(3 * D, -ZMIN)``. A ``tools`` mapping passed in replaces them
  (the program's own are then in ``Toolpath.program_tools``, each with its ``file:line`` as source).
* Arc centres: ``arc_centers="auto"`` starts in G91.1 (incremental I/J/K). When an I/J/K arc fails
  LinuxCNC's radius check (start and end radius differ by more than 0.0283 mm / 0.00283 in and by
  more than 0.1 %, or by more than 100 times those lengths) while reading I/J/K as absolute centres
  passes it, the program is taken to use
  absolute centres without saying G90.1 (BOTTLE.NC from easy_gcode_plot does this); we switch to
  absolute centres for the rest of the program and warn, naming file:line. ``rs274`` stops there with
  "Radius to end of arc differs from radius to start", and so does ``arc_centers="incremental"``.
  ``"absolute"`` starts in G90.1. G90.1/G91.1 in the program still switch the mode.
* Full circles: an I/J/K arc ending where it starts (in the plane) is a full turn; ``P`` adds turns.
* Canned cycles G73, G74, G81-G89 expand into the rapids and feeds LinuxCNC makes, in G17/G18/G19,
  with G98/G99, R, L repeats and G91 (R relative to the initial level, Z relative to R). G83 retracts
  to R between pecks and G73 backs off 0.254 mm (0.010 in); G84/G74 feed back out to the clearance
  level (LinuxCNC 2.9 swaps axes of G84 feeds in G18/G19, see the tests; we do not copy that). G88
  ends with the operator's manual retract, which we record as a rapid to the clearance level.
* G5 (cubic, ``I J`` and ``P Q`` control point offsets) and G5.1 (quadratic B-spline, ``I J`` control
  point offset) in G17 are flattened into feeds whose chords stay within 0.001 mm of the exact curve
  (LinuxCNC approximates them with biarcs; there is no rs274 reference for them here). G5.2/G5.3
  NURBS are unsupported codes (see Strictness).
* Cutter radius compensation G41/G42/G41.1/G42.1 follows LinuxCNC (tool radius from the ``tools``
  mapping, G10 L1 R, or the D word of G41.1/G42.1), see :mod:`fusioncut.io.gcode_comp`.
* Rotary axes A/B/C are read and tracked; a move that turns one raises
  ``InputError("5-axis / rotary motion not supported yet")`` (``GCodeInterpreter(allow_rotary=True)``
  records them instead, for comparisons with rs274).
* Zero-length moves (LinuxCNC emits e.g. ``G0`` without axes, or re-positioning moves) are kept by
  the interpreter but dropped by :func:`read_gcode`, which counts them in one warning.
* ``/`` block delete lines are skipped (the block delete switch is on). A lone ``%`` line before the
  first block opens the program and a later lone ``%`` ends it; ``M2``/``M30`` end it too. Lines
  with words after the end are not read, and a warning names the line where reading stopped and
  counts them (:mod:`fusioncut.io.gcode_end`). A ``%`` line with text after the ``%`` (a hobby
  post's ``% vfd enable``) neither opens nor ends the program: LinuxCNC refuses it ("Bad character
  '%' used"), and so does ``strict``; otherwise it is ignored with a warning. A program that yields
  no moves gets a warning saying why.
* Work budget: ``max_moves`` (default 1,000,000; ``None`` or 0 for no limit) bounds the moves a
  program expands to, an arc's extra ``P`` turns counting as moves, and the blocks it executes (2
  per move and 100,000 more); an arc takes at most 1,000 turns. Repeat loops and blocks that expand are checked
  before they expand (:mod:`fusioncut.io.gcode_budget`); the error names ``file:line`` and the count.
* O-word subroutines are those defined in the same file (``O<name>`` files on a search path are not
  looked up); calls nest at most 10 deep, as in LinuxCNC.
* Strictness: unknown words, words no command in the block uses, unknown or unsupported G and M codes
  (e.g. M11, G33, G38.2, G76, user M100-M199) raise :class:`InputError` naming ``file:line:column``
  when ``strict=True``; otherwise they are ignored and recorded as a ``"file:line:col: ..."`` warning,
  and a block whose unknown code may have wanted its axis words does not move. So are feed moves
  without a feed rate (feed 0 when lenient). Errors that make the path unknowable (syntax, bad
  expressions, arcs that do not close, missing cycle words, undefined subroutines or parameters)
  raise in both modes.
"""
from __future__ import annotations

import gc
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterator, Literal, Mapping

from fusioncut.errors import InputError, JobTooLarge, SourceLocation, ToolDefinitionError
from fusioncut.io import gcode_comp
from fusioncut.io.gcode_budget import DEFAULT_MAX_MOVES, MAX_ARC_TURNS, MoveBudget, may_leave_early
from fusioncut.io.gcode_comp import CompState
from fusioncut.io.gcode_end import no_moves_warning, stop_warning
from fusioncut.io.gcode_parse import Block, ParamRef, _param_index, evaluate, parse_line
from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Move, Point, Toolpath
from fusioncut.model.tools import (
    BallEndMill,
    BullNoseEndMill,
    ChamferMill,
    Drill,
    FlatEndMill,
    MillingTool,
    TaperedEndMill,
)

__all__ = ["GCodeInterpreter", "ModalState", "parse_gcode_text", "read_gcode"]

ArcCenters = Literal["auto", "incremental", "absolute"]

MM_PER_INCH = 25.4
# LinuxCNC's arc checks (interp_internal.hh): a centre-format arc may "spiral" by this much between
# its start and end radius, or by up to 100 times as much if also within this relative amount ...
SPIRAL_ABS_TOL_MM = 2 * 0.01 * math.sqrt(2)
SPIRAL_ABS_TOL_INCH = 2 * 0.001 * math.sqrt(2)
SPIRAL_REL_TOL = 0.001
# ... a radius below this is a zero-radius arc; R-format arcs may miss the end by this much
RADIUS_TOL_INCH = 0.00005
# chord tolerance when flattening G5/G5.1 splines, mm
SPLINE_TOLERANCE_MM = 0.001
# safety limits against runaway programs (an L or P word of 1e9, a repeat count of 1e15); the
# program's total of moves and blocks is bounded by its MoveBudget (gcode_budget)
MAX_MOVES_PER_BLOCK = 100_000
MAX_REPEAT_COUNT = 1_000_000_000
MAX_CALL_DEPTH = 10  # LinuxCNC's INTERP_SUB_ROUTINE_LEVELS
MAX_COORDINATE = 1e12  # mm or degrees; beyond this a program is broken, and floats lose their meaning

_AXES = "xyzabc"
_AXES_SET = frozenset(_AXES)
_ROTARY = "abc"
_PLANE_OFFSET_WORDS = {ArcPlane.XY: ("i", "j", "k"), ArcPlane.ZX: ("k", "i", "j"), ArcPlane.YZ: ("j", "k", "i")}
_PLANE_GCODE = {ArcPlane.XY: "G17", ArcPlane.ZX: "G18", ArcPlane.YZ: "G19"}
_COORD_SYSTEMS = ("G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")

# G codes we know, as int(10 * code) -> modal group (LinuxCNC numbering; 0 = non-modal)
_G_GROUP: dict[int, int] = {}
for _c in (0, 10, 20, 30, 50, 51, 52, 53, 330, 331, 382, 383, 384, 385, 730, 740, 760, 800,
           810, 820, 830, 840, 850, 860, 870, 880, 890):
    _G_GROUP[_c] = 1
for _c in (170, 180, 190, 171, 181, 191):
    _G_GROUP[_c] = 2
_G_GROUP.update({900: 3, 910: 3, 901: 4, 911: 4, 930: 5, 940: 5, 950: 5, 200: 6, 210: 6})
for _c in (400, 410, 411, 420, 421):
    _G_GROUP[_c] = 7
for _c in (430, 431, 432, 490):
    _G_GROUP[_c] = 8
_G_GROUP.update({980: 10, 990: 10})
for _c in (540, 550, 560, 570, 580, 590, 591, 592, 593):
    _G_GROUP[_c] = 12
_G_GROUP.update({610: 13, 611: 13, 640: 13, 960: 14, 970: 14, 70: 15, 80: 15})
for _c in (40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923):
    _G_GROUP[_c] = 0

# Known G codes that we do not interpret: treated like unknown codes (strict: error; else warning)
_G_UNSUPPORTED = {
    52: "G5.2/G5.3 NURBS", 53: "G5.2/G5.3 NURBS", 330: "G33 spindle-synchronized motion",
    331: "G33.1 rigid tapping", 382: "G38.2 probing", 383: "G38.3 probing", 384: "G38.4 probing",
    385: "G38.5 probing", 760: "G76 lathe threading cycle", 171: "G17.1 UV plane", 181: "G18.1 WU plane",
    191: "G19.1 VW plane", 70: "G7 lathe diameter mode", 80: "G8 lathe radius mode",
    432: "G43.2 additional tool length offset", 520: "G52 local offset", 960: "G96 constant surface speed",
}
_CYCLES = {730, 740, 810, 820, 830, 840, 850, 860, 870, 880, 890}
_GROUP0_AXIS_USERS = {100, 280, 300, 520, 920}  # group 0 codes that take the block's axis words

# M codes: value -> group (LinuxCNC numbering)
_M_GROUP: dict[int, int] = {0: 4, 1: 4, 2: 4, 30: 4, 60: 4, 6: 6, 61: 6, 3: 7, 4: 7, 5: 7, 19: 7,
                            7: 8, 8: 8, 9: 8, 48: 9, 49: 9, 50: 9, 51: 9, 52: 9, 53: 9}
for _c in range(62, 69):
    _M_GROUP[_c] = 5
_M_UNSUPPORTED = {70: "M70 save modal state", 71: "M71 invalidate modal state",
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


@dataclass
class _Frame:
    """A subroutine call (or the main program, at the bottom of the stack)."""

    label: str
    return_index: int
    saved: list[float]
    locals: dict[str, float] = field(default_factory=dict)
    repeats: dict[int, int] = field(default_factory=dict)
    # repeat line -> (moves, blocks) spent when its first pass began; checked when that pass ends
    first_pass: dict[int, tuple[int, int]] = field(default_factory=dict)


@dataclass
class _Flow:
    """Where O-word control lines jump to (line indices), found by scanning the program once."""

    subs: dict[str, tuple[int, int]] = field(default_factory=dict)  # label -> (sub, endsub)
    pair: dict[int, int] = field(default_factory=dict)  # matching line of a loop or next if-branch
    endif: dict[int, int] = field(default_factory=dict)  # elseif/else line -> its endif
    loops: list[tuple[int, int, str]] = field(default_factory=list)  # (first, last line, label)


class _Words:
    """The evaluated words of one block, remembering which ones a command used."""

    __slots__ = ("vals", "cols", "used", "block")

    def __init__(self, block: Block, vals: dict[str, float]):
        self.block = block
        self.vals = vals
        self.cols = block.words
        self.used: set[str] = {"n"}

    def __contains__(self, letter: str) -> bool:
        return letter in self.vals

    def get(self, letter: str, default: float | None = None) -> float | None:
        if letter in self.vals:
            self.used.add(letter)
            return self.vals[letter]
        return default

    def col(self, letter: str) -> int:
        return self.cols[letter][1] if letter in self.cols else 0


class GCodeInterpreter:
    """Runs an RS274/NGC program block by block.

    ``step()`` executes the next block and returns the moves it produced (``None`` once the program
    has ended); iterating yields ``(line, moves)`` per executed block; ``state`` is the
    :class:`ModalState` after the last block; ``execute(text)`` runs one extra line (MDI style,
    without O-word flow control); ``toolpath()`` gives the result as :func:`read_gcode` does.
    ``moves`` holds every move so far, zero-length ones included, and ``rotary_ends`` the A, B, C
    angles at the end of each move. ``tool_lengths`` (tool number -> mm) are the lengths G43 uses.
    """

    def __init__(
        self,
        text: str = "",
        *,
        source: str = "<memory>",
        tools: Mapping[int, MillingTool] | None = None,
        strict: bool = False,
        arc_centers: ArcCenters = "auto",
        allow_rotary: bool = False,
        tool_lengths: Mapping[int, float] | None = None,
        max_moves: int | None = DEFAULT_MAX_MOVES,
    ):
        if arc_centers not in ("auto", "incremental", "absolute"):
            raise ValueError(f"arc_centers must be 'auto', 'incremental' or 'absolute', not {arc_centers!r}")
        self.source = str(source)
        self.strict = strict
        self.arc_centers = arc_centers
        self.allow_rotary = allow_rotary
        self.user_tools = dict(tools) if tools is not None else None
        self.moves: list[Move] = []
        self.rotary_ends: list[tuple[float, float, float]] = []
        self.warnings: list[str] = []
        self._lines = text.splitlines()
        self._blocks: list[Block | None] = [None] * len(self._lines)
        self._index = 0
        self._ended = False
        self._executed = 0
        self._step_moves: list[Move] = []
        self.budget = MoveBudget(max_moves)
        self._move_room = self.budget.room(0)  # emitting a move with this many emitted passes the budget
        self._block_limit = self.budget.max_blocks or 1 << 62
        self._furthest = -1  # index of the furthest program line executed
        self._stop: tuple[int, str] | None = None  # (line, what) of an M2/M30/% that ended the program
        # --- modal state (internal units: mm, mm/min, degrees)
        self.pos = [0.0] * 6  # machine frame, tool tip
        self.inch = False
        self.absolute = True
        self.arc_absolute = arc_centers == "absolute"
        self.plane = ArcPlane.XY
        self.feed_mode = "units_per_minute"
        self.motion: int | None = None  # G code * 10, None for G80
        self.cs = 1  # 1..9 = G54..G59.3
        self.g5x = [[0.0] * 6 for _ in range(10)]  # index 1..9
        self.g92 = [0.0] * 6
        self.g92_applied = False
        self.g28 = [0.0] * 6
        self.g30 = [0.0] * 6
        self.tool: int | None = None
        self.prepared_tool: int | None = None
        self.tlo_number: int | None = None
        self.tlo = 0.0  # mm: tip lies this far below the spindle gauge point
        self.tool_lengths: dict[int, float] = dict(tool_lengths or {})
        self.tool_radii: dict[int, float] = {}
        if tools:
            for n, t in tools.items():
                self.tool_radii[n] = t.radius
        self.spindle = "off"
        self.rpm: float | None = None
        self.feed: float | None = None
        self.coolant: set[str] = set()
        self.retract_old_z = True
        self.operation = ""
        self._pending_operation: str | None = None
        self._seen_m6 = False
        self._warned_once: set[str] = set()
        self._tool_comments: dict[int, tuple[float, float, float | None, float | None, str, SourceLocation]] = {}
        self._first_units: str | None = None
        self._line = 0
        # canned cycle memory (LinuxCNC's cycle_r, cycle_cc, cycle_p, ...) in mm
        self._cycle: dict[str, float] = {}
        self._cycle_initial: float | None = None  # initial level of a run of cycles
        # parameters
        self._params = [0.0] * 5602
        self._globals: dict[str, float] = {}
        self._frames: list[_Frame] = [_Frame("", -1, [])]
        self._flow: _Flow | None = None
        self._program_started = False
        self._percent_open = False
        self._branch_target: int | None = None
        self._mdi_lines = 0
        # cutter compensation (set up lazily, see gcode_comp)
        self._comp: CompState | None = None
        self.comp_side = "off"
        self._base: list[float] | None = None  # where G91 / missing axis words start from, if not pos
        self._arc_not_allowed = False

    # ------------------------------------------------------------------ public
    @property
    def state(self) -> ModalState:
        motion = None
        if self.motion is not None:
            motion = _gname(self.motion)
        return ModalState(
            units="inch" if self.inch else "mm",
            distance_mode="absolute" if self.absolute else "incremental",
            arc_distance_mode="absolute" if self.arc_absolute else "incremental",
            plane=self.plane,
            feed_mode=self.feed_mode,  # type: ignore[arg-type]
            motion_mode=motion,
            coordinate_system=_COORD_SYSTEMS[self.cs - 1],
            work_offset=(self.g5x[self.cs][0], self.g5x[self.cs][1], self.g5x[self.cs][2]),
            g92_offset=(self.g92[0], self.g92[1], self.g92[2]),
            g92_applied=self.g92_applied,
            tool=self.tool,
            prepared_tool=self.prepared_tool,
            tool_length_offset=self.tlo_number,
            tool_length=self.tlo,
            spindle=self.spindle,  # type: ignore[arg-type]
            spindle_rpm=self.rpm,
            feed=self.feed,
            coolant=frozenset(self.coolant),
            cutter_compensation=self.comp_side,  # type: ignore[arg-type]
            retract_mode="old_z" if self.retract_old_z else "r_plane",
            position=(self.pos[0], self.pos[1], self.pos[2]),
            rotary=(self.pos[3], self.pos[4], self.pos[5]),
            operation=self.operation,
            line=self._line,
        )

    @property
    def ended(self) -> bool:
        return self._ended

    def step(self) -> list[Move] | None:
        """Execute the next block of the program; its moves, or ``None`` when the program has ended."""
        while not self._ended:
            if self._index >= len(self._lines):
                return self._finish()
            i = self._index
            block = self._block(i)
            self._index = i + 1
            if block.percent:
                if block.percent_text:
                    self._stray_percent(block)
                    continue
                if self._program_started or self._percent_open:
                    self._stopped(i, "the closing %")
                    return self._finish()
                self._percent_open = True
                continue
            if block.deleted or (block.is_empty and block.comment is None):
                continue
            self._program_started = True
            self._executed += 1
            if self._executed > self._block_limit:
                self.budget.check_blocks(self._executed, SourceLocation(self.source, block.line, 1))
            if i > self._furthest:
                self._furthest = i
            self._step_moves = []
            self._line = block.line
            if block.oword is not None:
                self._control(i, block)
            else:
                self._execute(block)
            return self._step_moves
        return None

    def __iter__(self) -> Iterator[tuple[int, list[Move]]]:
        while True:
            moves = self.step()
            if moves is None:
                return
            yield self._line, moves

    def run(self) -> GCodeInterpreter:
        """Execute the whole program; returns ``self``."""
        # Tens of thousands of small acyclic objects (moves, points) would make the cyclic garbage
        # collector rescan the growing heap again and again, doubling the run time; nothing here
        # creates reference cycles, so it is paused while the program runs.
        was_enabled = gc.isenabled()
        gc.disable()
        try:
            while self.step() is not None:
                pass
        finally:
            if was_enabled:
                gc.enable()
        return self

    def execute(self, text: str) -> list[Move]:
        """Execute one line now (MDI), whatever the program position; O-word control is refused.

        MDI lines are numbered after the program's lines. With cutter compensation on, a move is
        held until the next one is known (see :mod:`fusioncut.io.gcode_comp`)."""
        self._mdi_lines += 1
        self._line = len(self._lines) + self._mdi_lines
        block = parse_line(text, self._line, self.source)
        if block.oword is not None:
            raise InputError("O-word control lines need a program", SourceLocation(self.source, self._line, 1))
        self._step_moves = []
        if not block.deleted and not block.percent:
            self._execute(block)
        return self._step_moves

    def toolpath(self, *, drop_zero_length: bool = True) -> Toolpath:
        """The moves so far as a :class:`Toolpath`; zero-length moves dropped and counted in a warning."""
        moves: list[Move] = self.moves
        warnings = list(self.warnings)
        if drop_zero_length:
            kept = [m for m in moves if not _zero_length(m)]
            dropped = len(moves) - len(kept)
            if dropped:
                warnings.append(f"{self.source}: dropped {dropped} zero-length move{'s' if dropped != 1 else ''}")
            moves = kept
        if not moves:
            warnings.append(no_moves_warning(self.source, self._stop, bool(self.moves), self._lines))
        tools = self.user_tools if self.user_tools is not None else self._tools_from_comments(warnings)
        # tools given replace the comments' (unusable comments then go unreported); keep the program's own
        program = self._tools_from_comments([]) if self.user_tools is not None else None
        return Toolpath(moves=tuple(moves), tools=tools, warnings=tuple(warnings), source=self.source,
                        program_tools=program)

    # ------------------------------------------------------------------ program text / flow control
    def _block(self, i: int) -> Block:
        b = self._blocks[i]
        if b is None:
            b = parse_line(self._lines[i], i + 1, self.source)
            self._blocks[i] = b
        return b

    def _stopped(self, index: int, what: str) -> None:
        """The program ends at line ``index + 1`` by ``what``: warn when lines with words remain unread."""
        line = index + 1
        self._stop = (line, what)
        after = max(index, self._furthest) + 1
        furthest = self._furthest + 1 if self._furthest > index else 0
        warning = stop_warning(f"{self.source}:{line}", what, self._lines, after, furthest)
        if warning is not None:
            self.warnings.append(warning)

    def _stray_percent(self, block: Block) -> None:
        """A ``%`` line with text after it: not a program delimiter (LinuxCNC refuses the line with
        "Bad character '%' used"); strict: the same refusal, lenient: ignored with a warning."""
        self._line = block.line
        col = len(block.text) - len(block.text.lstrip()) + 1
        text = block.text.strip()
        shown = text if len(text) <= 40 else text[:37] + "..."
        self._unsupported(f"'{shown}': a % line with text after the % is not a program start or end "
                          "(only a lone % is)", col)

    def _finish(self) -> list[Move] | None:
        """End of the program text: release held compensated moves (returned as a last step)."""
        self._ended = True
        if self._comp is not None:
            self._step_moves = []
            gcode_comp.flush(self)
            if self._step_moves:
                return self._step_moves
        return None

    def _scan_flow(self) -> _Flow:
        """Pair up the O-word lines once: sub/endsub, do/while, while/endwhile, repeat/endrepeat,
        if/elseif/else/endif; check that break/continue/return sit inside their construct."""
        flow = _Flow()
        stack: list[tuple[str, str, int, list[int]]] = []  # (keyword, label, index, if-branches)
        started = False
        for i, raw in enumerate(self._lines):
            s = raw.lstrip()
            if not s:
                continue
            if s[0] == "%":
                if s[1:].strip():
                    continue  # not a delimiter (see _stray_percent)
                if started:
                    break
                started = True
                continue
            started = True
            head = s[:1].lower()
            if head not in "on":
                continue
            if head == "n":
                k = 1
                while k < len(s) and (s[k] in "0123456789 \t"):
                    k += 1
                if k >= len(s) or s[k] not in "oO":
                    continue
            b = self._block(i)
            ow = b.oword
            if ow is None or b.deleted:
                continue
            kw, label = ow.keyword, ow.label
            where = SourceLocation(self.source, b.line, ow.column)

            if kw == "sub":
                if any(f[0] == "sub" for f in stack):
                    raise InputError("subroutine definitions cannot be nested", where)
                stack.append(("sub", label, i, []))
            elif kw == "endsub":
                start = _close(stack, "sub", kw, label, where)[2]
                if label in flow.subs:
                    raise InputError(f"subroutine O{label} defined twice", where)
                flow.subs[label] = (start, i)
            elif kw in ("do", "repeat", "if"):
                stack.append((kw, label, i, [i]))
            elif kw == "while":
                if stack and stack[-1][0] == "do" and stack[-1][1] == label:
                    start = stack.pop()[2]
                    flow.pair[i] = start  # do ... while [cond]: back to the do
                    flow.loops.append((start, i, label))
                else:
                    stack.append(("while", label, i, []))
            elif kw in ("endwhile", "endrepeat"):
                start = _close(stack, "while" if kw == "endwhile" else "repeat", kw, label, where)[2]
                flow.pair[start] = i
                flow.pair[i] = start
                flow.loops.append((start, i, label))
            elif kw in ("elseif", "else"):
                entry = stack[-1] if stack else None
                if entry is None or entry[0] != "if" or entry[1] != label:
                    raise InputError(f"O{label} {kw} without a matching O{label} if", where)
                last = self._block(entry[3][-1]).oword
                if last is not None and last.keyword == "else":
                    raise InputError(f"O{label} {kw} after O{label} else", where)
                entry[3].append(i)
            elif kw == "endif":
                branches = _close(stack, "if", kw, label, where)[3] + [i]
                for a, b_ in zip(branches, branches[1:]):
                    flow.pair[a] = b_  # a false condition goes on at the next branch
                for a in branches[1:-1]:
                    flow.endif[a] = i  # falling into the next branch from a taken one: skip to endif
            elif kw in ("break", "continue"):
                if not any(f[0] in ("do", "while", "repeat") and f[1] == label for f in stack):
                    raise InputError(f"O{label} {kw} outside a loop labelled O{label}", where)
            elif kw == "return":
                if not any(f[0] == "sub" and f[1] == label for f in stack):
                    raise InputError(f"O{label} return outside subroutine O{label}", where)
        if stack:
            kw, label, i, _ = stack[-1]
            raise InputError(f"O{label} {kw} is never closed", SourceLocation(self.source, i + 1, 1))
        return flow

    def _control(self, i: int, block: Block) -> None:
        ow = block.oword
        assert ow is not None
        kw = ow.keyword
        if kw == "":
            return  # program number (Fanuc O1234): nothing to do
        if self._flow is None:
            self._flow = self._scan_flow()
        flow = self._flow
        where = SourceLocation(self.source, block.line, ow.column)
        arrived_by_jump = self._branch_target == i
        self._branch_target = None
        if kw in ("elseif", "else") and not arrived_by_jump:
            # the previous branch was taken and ran into this line: leave the if
            self._index = flow.endif[i] + 1
            return
        args = [evaluate(a, self) for a in ow.args]
        if kw == "sub":
            # reached in the flow of the program: skip the definition
            self._index = flow.subs[ow.label][1] + 1
        elif kw == "call":
            if ow.label not in flow.subs:
                raise InputError(f"subroutine O{ow.label} is not defined in this file", where)
            if len(self._frames) > MAX_CALL_DEPTH:
                raise InputError(f"subroutine calls nested deeper than {MAX_CALL_DEPTH}", where)
            if len(args) > 30:
                raise InputError("more than 30 subroutine arguments", where)
            frame = _Frame(ow.label, i + 1, self._params[1:31])
            for k in range(30):
                self._params[1 + k] = args[k] if k < len(args) else 0.0
            self._frames.append(frame)
            self._globals["_value_returned"] = 0.0
            self._index = flow.subs[ow.label][0] + 1
        elif kw in ("endsub", "return"):
            if len(self._frames) == 1:
                raise InputError(f"O{ow.label} {kw} outside a subroutine call", where)
            frame = self._frames.pop()
            self._params[1:31] = frame.saved
            if args:
                self._globals["_value"] = args[0]
                self._globals["_value_returned"] = 1.0
            self._index = frame.return_index
        elif kw == "while":
            if i in flow.pair and flow.pair[i] < i:  # closing a do ... while
                if args[0]:
                    self._index = flow.pair[i] + 1
            elif not args[0]:
                self._index = flow.pair[i] + 1
        elif kw in ("endwhile", "endrepeat"):
            self._index = flow.pair[i]
        elif kw == "repeat":
            frame = self._frames[-1]
            reps = frame.repeats
            if i not in reps:
                n = args[0]
                if n < 0 or n != math.floor(n) or n > MAX_REPEAT_COUNT:
                    raise InputError(f"repeat count must be a whole number >= 0, got {n:g}", where)
                reps[i] = int(n)
                if n > 1:
                    frame.first_pass[i] = (len(self.moves) + self.budget.extra_turns, self._executed)
            elif i in frame.first_pass:
                self._check_repeat(i, frame, flow.pair[i], where)
            if reps[i] <= 0:
                del reps[i]
                self._index = flow.pair[i] + 1
            else:
                reps[i] -= 1
        elif kw in ("if", "elseif"):
            if not args[0]:
                self._branch_target = flow.pair[i]
                self._index = flow.pair[i]
        elif kw in ("break", "continue"):
            start, end = self._loop_around(i, ow.label)
            start_kw = self._block(start).oword.keyword  # type: ignore[union-attr]
            if kw == "break":
                self._frames[-1].repeats.pop(start, None)
                self._frames[-1].first_pass.pop(start, None)
                self._index = end + 1
            else:
                # continue: go to the line that tests the loop (the while of a do-while, the while
                # of a while loop, the endrepeat of a repeat)
                self._index = end if start_kw in ("do", "repeat") else start
        # "do" and "endif" need nothing

    def _check_repeat(self, i: int, frame: _Frame, end: int, where: SourceLocation) -> None:
        """The first pass of the repeat loop at line index ``i`` has run: refuse the loop if the passes
        still to come would pass the budget, unless its body can leave early (break, return, M2/M30),
        which only the running count can judge."""
        moves0, blocks0 = frame.first_pass.pop(i)
        spent = (len(self.moves), self._executed)
        first = (len(self.moves) + self.budget.extra_turns - moves0, self._executed - blocks0)
        try:
            self.budget.check_repeat(spent, first, frame.repeats[i], frame.repeats[i] + 1, where)
        except JobTooLarge:
            if not may_leave_early(self._block(j) for j in range(i + 1, end)):
                raise

    def _loop_around(self, i: int, label: str) -> tuple[int, int]:
        assert self._flow is not None
        inner = [(a, b) for a, b, lab in self._flow.loops if a < i < b and lab == label]
        if not inner:
            raise InputError(f"O{label} break/continue outside its loop", SourceLocation(self.source, i + 1, 1))
        return max(inner)

    # ------------------------------------------------------------------ parameters
    def get_numbered(self, index: int, where: SourceLocation) -> float:
        if 5161 <= index <= 5428:
            v = self._system_param(index)
            if v is not None:
                return v
        return self._params[index]

    def get_named(self, name: str, where: SourceLocation) -> float:
        if name.startswith("_"):
            if name in self._globals:
                return self._globals[name]
            v = self._predefined(name)
            if v is not None:
                return v
        else:
            loc = self._frames[-1].locals
            if name in loc:
                return loc[name]
        raise InputError(f"named parameter #<{name}> is not defined", where)

    def has_named(self, name: str) -> bool:
        if name.startswith("_"):
            return name in self._globals or self._predefined(name) is not None
        return name in self._frames[-1].locals

    def _scale(self) -> float:
        return MM_PER_INCH if self.inch else 1.0

    def _system_param(self, n: int) -> float | None:
        s = self._scale()

        def unit(axis: int, v: float) -> float:
            return v / s if axis < 3 else v

        if 5161 <= n <= 5166:
            return unit(n - 5161, self.g28[n - 5161])
        if 5181 <= n <= 5186:
            return unit(n - 5181, self.g30[n - 5181])
        if n == 5210:
            return 1.0 if self.g92_applied else 0.0
        if 5211 <= n <= 5216:
            return unit(n - 5211, self.g92[n - 5211])
        if n == 5220:
            return float(self.cs)
        if 5221 <= n <= 5399:
            k, r = divmod(n - 5221, 20)
            if k < 9 and r < 6:
                return unit(r, self.g5x[k + 1][r])
            return None
        if n == 5400:
            return float(self.tool or 0)
        if n == 5403:
            return self.tlo / s
        if n == 5410:
            radius = self.tool_radii.get(self.tool or 0)
            return 2 * radius / s if radius is not None else 0.0
        if 5420 <= n <= 5425:
            return unit(n - 5420, self._program_pos(n - 5420))
        return None

    def _set_system_param(self, n: int, v: float) -> bool:
        s = self._scale()

        def mm(axis: int) -> float:
            return v * s if axis < 3 else v

        if 5161 <= n <= 5166:
            self.g28[n - 5161] = mm(n - 5161)
        elif 5181 <= n <= 5186:
            self.g30[n - 5181] = mm(n - 5181)
        elif 5211 <= n <= 5216:
            self.g92[n - 5211] = mm(n - 5211)
        elif 5221 <= n <= 5399 and (n - 5221) // 20 < 9 and (n - 5221) % 20 < 6:
            k, r = divmod(n - 5221, 20)
            self.g5x[k + 1][r] = mm(r)
        else:
            return False
        return True

    def _predefined(self, name: str) -> float | None:
        s = self._scale()
        if name in ("_x", "_y", "_z"):
            i = "_x _y _z".split().index(name)
            return self._program_pos(i) / s
        if name in ("_a", "_b", "_c"):
            return self._program_pos(3 + "_a _b _c".split().index(name))
        table = {
            "_metric": 0.0 if self.inch else 1.0,
            "_imperial": 1.0 if self.inch else 0.0,
            "_absolute": 1.0 if self.absolute else 0.0,
            "_incremental": 0.0 if self.absolute else 1.0,
            "_feed": self.feed or 0.0,
            "_rpm": self.rpm or 0.0,
            "_current_tool": float(self.tool or 0),
            "_selected_tool": float(self.prepared_tool if self.prepared_tool is not None else -1),
            "_line": float(self._line),
            "_coord_system": float(
                (540, 550, 560, 570, 580, 590, 591, 592, 593)[self.cs - 1]
            ),
            "_plane": float({ArcPlane.XY: 170, ArcPlane.ZX: 180, ArcPlane.YZ: 190}[self.plane]),
            "_motion_mode": float(self.motion if self.motion is not None else 800),
            "_spindle_on": 0.0 if self.spindle == "off" else 1.0,
            "_spindle_cw": 1.0 if self.spindle == "cw" else 0.0,
            "_mist": 1.0 if "mist" in self.coolant else 0.0,
            "_flood": 1.0 if "flood" in self.coolant else 0.0,
            "_call_level": float(len(self._frames) - 1),
            "_value": 0.0,
            "_value_returned": 0.0,
            "_retract_r_plane": 0.0 if self.retract_old_z else 1.0,
            "_retract_old_z": 1.0 if self.retract_old_z else 0.0,
            "_ijk_absolute_mode": 1.0 if self.arc_absolute else 0.0,
        }
        return table.get(name)

    def _assign(self, ref: ParamRef, value: float, where: SourceLocation) -> None:
        if ref.name is not None:
            name = ref.name
            if name.startswith("_"):
                if self._predefined(name) is not None and name not in ("_value", "_value_returned"):
                    raise InputError(f"#<{name}> is read-only", where)
                self._globals[name] = value
            else:
                self._frames[-1].locals[name] = value
            return
        if ref.number is not None:
            n = ref.number
        else:
            assert ref.index is not None
            n = _param_index(evaluate(ref.index, self), where)
        if 5161 <= n <= 5428 and self._set_system_param(n, value):
            return
        self._params[n] = value

    # ------------------------------------------------------------------ coordinates
    def _offset(self) -> list[float]:
        """Program-to-machine offset per axis: the active G5x origin plus G92 when applied (mm/deg)."""
        g = self.g5x[self.cs]
        if self.g92_applied:
            return [g[k] + self.g92[k] for k in range(6)]
        return list(g)

    def _program_pos(self, axis: int) -> float:
        """Current position of an axis in program coordinates (mm / deg)."""
        off = self.g5x[self.cs][axis] + (self.g92[axis] if self.g92_applied else 0.0)
        return self.pos[axis] - off

    def _where(self, col: int) -> SourceLocation:
        return SourceLocation(self.source, self._line, col)

    def _unsupported(self, message: str, col: int) -> None:
        """Strict: raise; lenient: warn and go on without the offending word or code."""
        where = self._where(col)
        if self.strict:
            raise InputError(message, where)
        self.warnings.append(f"{where}: {message} (ignored)")

    def _warn_once(self, key: str, message: str, col: int = 0) -> None:
        if key in self._warned_once:
            return
        self._warned_once.add(key)
        self.warnings.append(f"{self._where(col)}: {message}")

    # ------------------------------------------------------------------ block execution
    def _execute(self, block: Block) -> None:
        if (block.simple and self._comp is None and self._base is None
                and (self.motion == 0 or self.motion == 10) and self.feed_mode != "inverse_time"):
            self._execute_simple(block)
            return
        self._execute_general(block)

    def _execute_simple(self, block: Block) -> None:
        """Fast path for the bulk of posted code: ``[N..] [X..] [Y..] [Z..] [F..]`` in G0/G1 mode.

        Same result as the general path (the tests compare both on whole files)."""
        # a simple block is constant: its values are plain floats
        words: dict[str, tuple[float, int]] = block.words  # type: ignore[assignment]
        f = words.get("f")
        if f is not None:
            if f[0] < 0:
                raise InputError(f"negative feed rate F{f[0]:g}", self._where(f[1]))
            self.feed = f[0]
        pos = self.pos
        end = list(pos)
        s = MM_PER_INCH if self.inch else 1.0
        col = 0
        moved = False
        off = self._offset() if self.absolute else None
        for k, a in ((0, "x"), (1, "y"), (2, "z")):
            wv = words.get(a)
            if wv is not None:
                v = wv[0] * s
                end[k] = v + off[k] if off is not None else pos[k] + v
                if not moved or wv[1] < col:
                    col = wv[1]
                moved = True
        if not moved:
            return
        loc = SourceLocation(self.source, block.line, col)
        rapid = self.motion == 0
        if rapid:
            feed = None
        elif self.feed_mode == "units_per_minute" and self.feed:
            feed = self.feed * s
        else:
            feed = self._feed_rate(0.0, loc, None)
        if self._pending_operation is not None:
            self.operation = self._pending_operation
            self._pending_operation = None
        mv = LinearMove(start=(pos[0], pos[1], pos[2]), end=(end[0], end[1], end[2]), feed=feed,
                        spindle_rpm=self.rpm, tool=self.tool, operation=self.operation, source=loc, rapid=rapid)
        if len(self.moves) >= self._move_room:
            raise self.budget.refuse("at this block", loc)
        self.moves.append(mv)
        self._step_moves.append(mv)
        self.rotary_ends.append((end[3], end[4], end[5]))
        self.pos = end

    def _execute_general(self, block: Block) -> None:
        line = block.line
        # 1. evaluate every value with the parameters as they were before the line
        vals = {k: evaluate(v[0], self) for k, v in block.words.items()}
        gs = [(evaluate(v, self), c) for v, c in block.g]
        ms = [(evaluate(v, self), c) for v, c in block.m]
        assigns = [(r, evaluate(v, self), c) for r, v, c in block.assignments]
        for ref, value, c in assigns:
            self._assign(ref, value, SourceLocation(self.source, line, c))
        w = _Words(block, vals)
        for letter in "uvw":
            if letter in vals:
                w.used.add(letter)
                self._unsupported(f"{letter.upper()} axis not supported", w.col(letter))
                del vals[letter]

        # 2. G codes by modal group
        groups: dict[int, tuple[int, int]] = {}
        skip_unused_check = False
        for v, col in gs:
            code = _code10(v, "G", self._where(col))
            if code not in _G_GROUP:
                self._unsupported(f"unknown G code {_gname(code)}", col)
                skip_unused_check = True
                continue
            if code in _G_UNSUPPORTED:
                self._unsupported(f"{_G_UNSUPPORTED[code]} not supported", col)
                skip_unused_check = True
                continue
            grp = _G_GROUP[code]
            if grp == 1 and grp in groups and 800 in (code, groups[1][0]):
                # LinuxCNC accepts G80 next to another motion code (posts write "G0 ... G80" as a
                # safe-start line); the other code wins
                if code == 800:
                    continue
                groups[1] = (code, col)
                continue
            if grp in groups:
                raise InputError(
                    f"two G codes from the same modal group: {_gname(groups[grp][0])} and {_gname(code)}",
                    self._where(col),
                )
            groups[grp] = (code, col)
        mcodes: dict[int, tuple[int, int]] = {}
        coolant_codes: list[int] = []
        for v, col in ms:
            if v != math.floor(v) or v < 0:
                raise InputError(f"bad M code M{v:g}", self._where(col))
            code = int(v)
            if code in _M_UNSUPPORTED:
                self._unsupported(f"{_M_UNSUPPORTED[code]} not supported", col)
                continue
            if code not in _M_GROUP:
                what = "user M code" if 100 <= code <= 199 else "unknown M code"
                self._unsupported(f"{what} M{code}", col)
                continue
            grp = _M_GROUP[code]
            if grp == 8:
                coolant_codes.append(code)
                if len(coolant_codes) > 1 and not set(coolant_codes) <= {7, 8}:
                    raise InputError("two M codes from the same modal group", self._where(col))
                continue
            if grp in mcodes:
                raise InputError(f"two M codes from the same modal group: M{mcodes[grp][0]} and M{code}",
                                 self._where(col))
            mcodes[grp] = (code, col)

        g0 = groups.get(0)
        g1 = groups.get(1)
        has_axes = not _AXES_SET.isdisjoint(vals)
        g0_axes = bool(g0 and g0[0] in _GROUP0_AXIS_USERS) or groups.get(8, (0, 0))[0] == 431
        if g1 and has_axes and g0_axes:
            raise InputError(
                f"{_gname(g0[0] if g0 else 431)} and {_gname(g1[0])} both want the axis words of this block",
                self._where(g1[1]),
            )

        # 3. comment: operation names, tool descriptions
        if block.comment is not None:
            self._comment(block)

        # 4. feed mode, F, S, T, M6, spindle, coolant
        if 5 in groups:
            mode = {930: "inverse_time", 940: "units_per_minute", 950: "units_per_revolution"}[groups[5][0]]
            if mode != self.feed_mode:
                self.feed = None  # LinuxCNC resets the feed rate when the feed mode changes
            self.feed_mode = mode
        f = w.get("f")
        if f is not None:
            if f < 0:
                raise InputError(f"negative feed rate F{f:g}", self._where(w.col("f")))
            self.feed = f
        s = w.get("s")
        if s is not None:
            if s < 0:
                raise InputError(f"negative spindle speed S{s:g}", self._where(w.col("s")))
            self.rpm = s
        t = w.get("t")
        if t is not None:
            if t < 0 or t != math.floor(t):
                raise InputError(f"tool number must be a whole number >= 0, got T{t:g}", self._where(w.col("t")))
            self.prepared_tool = int(t)
            if not self._seen_m6:
                # before any M6, T loads the tool (posts for machines without a changer); see module doc
                self.tool = int(t)
        m6 = mcodes.get(6)
        if m6 is not None:
            if m6[0] == 6:
                self._seen_m6 = True
                if self.prepared_tool is not None:
                    self.tool = self.prepared_tool
                if self._comp is not None:
                    raise InputError("tool change with cutter compensation on", self._where(m6[1]))
            else:  # M61 Q: set the loaded tool number without a change
                q = w.get("q")
                if q is None or q < 0 or q != math.floor(q):
                    raise InputError("M61 needs a Q word with a tool number", self._where(m6[1]))
                self.tool = int(q)
        m7 = mcodes.get(7)
        if m7 is not None:
            code = m7[0]
            if code == 3:
                self.spindle = "cw"
            elif code == 4:
                self.spindle = "ccw"
                self._warn_once("m4", "M4 (counter-clockwise spindle) is kept in the modal state only; "
                                "moves do not carry the spindle direction yet", m7[1])
            elif code == 5:
                self.spindle = "off"
        for code in coolant_codes:
            if code == 7:
                self.coolant.add("mist")
            elif code == 8:
                self.coolant.add("flood")
            else:
                self.coolant.clear()
        mio = mcodes.get(5)
        if mio is not None:
            for letter in "pelq":
                w.get(letter)

        # 5. dwell, plane, units, cutter comp, tool length offset, coordinate system
        if g0 and g0[0] == 40:
            p = w.get("p")
            if p is None or p < 0:
                raise InputError("G4 dwell needs a P word >= 0", self._where(g0[1]))
        if 2 in groups:
            if self._comp is not None:
                raise InputError("cannot change the plane with cutter compensation on", self._where(groups[2][1]))
            self.plane = {170: ArcPlane.XY, 180: ArcPlane.ZX, 190: ArcPlane.YZ}[groups[2][0]]
        if 6 in groups:
            self.inch = groups[6][0] == 200
            if self._first_units is None:
                self._first_units = "inch" if self.inch else "mm"
        if 7 in groups:
            self._cutter_comp(groups[7], w)
        if 8 in groups:
            self._tool_length(groups[8], w)
        if 12 in groups:
            if self._comp is not None:
                raise InputError("cannot change coordinate system with cutter compensation on",
                                 self._where(groups[12][1]))
            self.cs = (540, 550, 560, 570, 580, 590, 591, 592, 593).index(groups[12][0]) + 1
        if 13 in groups and groups[13][0] == 640:
            w.get("p")
            w.get("q")
        if 3 in groups:
            self.absolute = groups[3][0] == 900
        if 4 in groups:
            self.arc_absolute = groups[4][0] == 901
        if 10 in groups:
            self.retract_old_z = groups[10][0] == 980

        # 6. non-modal codes that move or set offsets
        g53 = False
        if g0 is not None:
            code, col = g0
            if code == 100:
                self._g10(w, col)
            elif code in (280, 300):
                self._home(w, code, col)
            elif code in (281, 301):
                target = self.g28 if code == 281 else self.g30
                for k in range(6):
                    target[k] = self.pos[k] + (self.tlo if k == 2 else 0.0)
            elif code == 920:
                self._g92(w, col)
            elif code == 921:
                self.g92 = [0.0] * 6
                self.g92_applied = False
            elif code == 922:
                self.g92_applied = False
            elif code == 923:
                self.g92_applied = True
            elif code == 530:
                g53 = True

        # 7. motion
        motion: int | None = None
        motion_col = 0
        if g1 is not None:
            motion, motion_col = g1
        elif skip_unused_check and has_axes:
            # an unknown or unsupported code may be the one that wanted these axis words (G33,
            # G38.2, ...): moving with the modal G0/G1 instead could invent a cut
            for a in _AXES:
                w.get(a)
            self.warnings.append(f"{self._where(_first_axis_col(w))}: motion of this block skipped")
        elif has_axes and not g0_axes:
            motion = self.motion
            motion_col = _first_axis_col(w)
            if motion is None:
                raise InputError("axis words without a motion mode (G0, G1, ...) in effect",
                                 self._where(motion_col))
        if g53 and motion not in (0, 10):
            raise InputError("G53 needs G0 or G1", self._where(g0[1] if g0 else 0))
        if motion is not None:
            if motion == 800:
                if has_axes:
                    raise InputError("axis words with G80", self._where(_first_axis_col(w)))
                self.motion = None
                self._cycle_initial = None
            else:
                self._motion(motion, motion_col, w, g53)

        # 8. stops: held compensated moves are released first
        stop = mcodes.get(4)
        if stop is not None:
            if self._comp is not None:
                gcode_comp.flush(self)
            if stop[0] in (2, 30):
                self._end_program()
                self._stopped(block.line - 1, f"M{stop[0]}")

        if not skip_unused_check:
            unused = [k for k in vals if k not in w.used]
            for letter in unused:
                self._unsupported(f"{letter.upper()} word not used by any command in this block", w.col(letter))

    def _end_program(self) -> None:
        # M2/M30: LinuxCNC resets some modal state; the rest of the file is not executed
        self._comp = None
        self.comp_side = "off"
        self._ended = True
        self.plane = ArcPlane.XY
        self.absolute = True
        self.feed_mode = "units_per_minute"
        self.spindle = "off"
        self.coolant.clear()
        self.motion = 10
        self.cs = 1

    # ------------------------------------------------------------------ comments and tools
    def _comment(self, block: Block) -> None:
        text = (block.comment or "").strip()
        if not block.standalone_comment or not text:
            return
        low = text.lower()
        if low.startswith(("msg,", "debug,", "print,", "log,", "logopen,", "logappend,", "logclose")):
            return
        tool = _parse_tool_comment(text)
        if tool is not None:
            self._tool_comments[tool[0]] = (*tool[1:], SourceLocation(self.source, block.line, block.comment_column))  # type: ignore[assignment]
            return
        self._pending_operation = text

    def _tools_from_comments(self, warnings: list[str]) -> dict[int, MillingTool]:
        scale = MM_PER_INCH if self._first_units == "inch" else 1.0
        tools: dict[int, MillingTool] = {}
        for number, (d, cr, taper, zmin, kind, where) in self._tool_comments.items():  # type: ignore[misc]
            try:
                tools[number] = replace(_make_tool(number, d * scale, (cr or 0.0) * scale, taper,
                                                   None if zmin is None else zmin * scale, kind), source=str(where),
                                        name=_tool_name(kind))
            except ToolDefinitionError as e:
                warnings.append(f"{where}: tool comment not usable: {e.reason}")
        return tools

    # ------------------------------------------------------------------ modal helpers
    def _tool_length(self, group: tuple[int, int], w: _Words) -> None:
        if self._comp is not None:
            raise InputError("cannot change the tool length offset with cutter compensation on",
                             self._where(group[1]))
        old = self.tlo
        self._set_tool_length(group, w)
        # Like LinuxCNC, the position is that of the controlled point: when the offset changes
        # without a move, the same physical spot gets a new Z (no-op when lengths are unknown, 0).
        self.pos[2] += old - self.tlo

    def _set_tool_length(self, group: tuple[int, int], w: _Words) -> None:
        code, col = group
        if code == 490:
            self.tlo_number = None
            self.tlo = 0.0
        elif code == 430:
            h = w.get("h")
            n = int(h) if h is not None else (self.tool or 0)
            if h is not None and (h < 0 or h != math.floor(h)):
                raise InputError(f"bad H word H{h:g}", self._where(w.col("h")))
            self.tlo_number = n
            self.tlo = self.tool_lengths.get(n, 0.0) if n else 0.0
        elif code == 431:
            z = w.get("z")
            self.tlo_number = None
            self.tlo = (z or 0.0) * self._scale()
            for letter in "xyabc":
                w.get(letter)

    def _g10(self, w: _Words, col: int) -> None:
        l_val = w.get("l")
        p = w.get("p")
        if l_val is None:
            raise InputError("G10 needs an L word", self._where(col))
        lv = int(l_val)
        s = self._scale()
        if lv in (2, 20):
            if p is None or p != math.floor(p) or not 0 <= p <= 9:
                raise InputError("G10 L2/L20 needs P0..P9", self._where(col))
            n = int(p) or self.cs
            r = w.get("r")
            if r:
                self._unsupported("G10 coordinate system rotation R not supported", w.col("r"))
            for k, a in enumerate(_AXES):
                v = w.get(a)
                if v is None:
                    continue
                vm = v * s if k < 3 else v
                if lv == 2:
                    self.g5x[n][k] = vm
                else:
                    # L20: choose the origin so the current point has coordinate v in system n
                    g92 = self.g92[k] if self.g92_applied else 0.0
                    self.g5x[n][k] = self.pos[k] - g92 - vm
        elif lv in (1, 10, 11):
            if p is None or p != math.floor(p) or p < 0:
                raise InputError("G10 L1/L10/L11 needs a tool number P", self._where(col))
            n = int(p)
            z = w.get("z")
            r = w.get("r")
            for letter in "xyabcijq":
                w.get(letter)
            if z is not None:
                if lv == 1:
                    self.tool_lengths[n] = z * s
                else:
                    # L10/L11: length such that the current point is at Z (tip relative to the
                    # spindle gauge point); as we do not move the tip with G43 this only
                    # matters for machine-coordinate targets
                    self.tool_lengths[n] = (self.pos[2] + self.tlo) - (z * s + self._offset()[2])
            if r is not None:
                self.tool_radii[n] = abs(r) * s
        else:
            raise InputError(f"G10 L{l_val:g} not supported", self._where(col))

    def _g92(self, w: _Words, col: int) -> None:
        if self._comp is not None:
            raise InputError("cannot change G92 offsets with cutter compensation on", self._where(col))
        if not any(a in w for a in _AXES):
            raise InputError("G92 needs at least one axis word", self._where(col))
        s = self._scale()
        new = list(self.g92) if self.g92_applied else [0.0] * 6
        for k, a in enumerate(_AXES):
            v = w.get(a)
            if v is None:
                continue
            vm = v * s if k < 3 else v
            new[k] = self.pos[k] - self.g5x[self.cs][k] - vm
        self.g92 = new
        self.g92_applied = True

    def _home(self, w: _Words, code: int, col: int) -> None:
        """G28 / G30: rapid to the intermediate point (the axis words), then to the stored point."""
        stored = self.g28 if code == 280 else self.g30
        if self._comp is not None:
            raise InputError(f"{_gname(code)} with cutter compensation on", self._where(col))
        mid = self._ends(w, False)
        loc = self._where(col)
        self._linear(mid, True, loc)
        given = [a in w.vals for a in _AXES]
        end = list(mid)
        for k in range(6):
            if given[k] or not any(given):
                end[k] = stored[k] - (self.tlo if k == 2 else 0.0)
        self._linear(end, True, loc)

    def _cutter_comp(self, group: tuple[int, int], w: _Words) -> None:
        gcode_comp.set_mode(self, group, w)

    # ------------------------------------------------------------------ motion
    def _ends(self, w: _Words, g53: bool) -> list[float]:
        """End point (machine frame, mm/deg) from the block's axis words."""
        comp = self._comp
        if self._base is not None:
            base = self._base
            if comp is None:
                self._base = None  # only the first move after G40 starts from the programmed point
        elif comp is not None and not comp.first and comp.radius > 0:
            base = comp.prog
        else:
            base = self.pos
        end = list(base)
        s = self._scale()
        vals = w.vals
        if g53:
            if comp is not None:
                raise InputError("G53 with cutter radius compensation on", self._where(0))
            if not self.absolute:
                raise InputError("G53 in incremental distance mode (G91)", self._where(0))
            for k, a in enumerate(_AXES):
                if a in vals:
                    w.used.add(a)
                    v = vals[a] * s if k < 3 else vals[a]
                    end[k] = v - (self.tlo if k == 2 else 0.0)
            return end
        if self.absolute:
            off = None
            for k, a in enumerate(_AXES):
                if a in vals:
                    w.used.add(a)
                    if off is None:
                        off = self._offset()
                    end[k] = (vals[a] * s if k < 3 else vals[a]) + off[k]
        else:
            for k, a in enumerate(_AXES):
                if a in vals:
                    w.used.add(a)
                    end[k] = base[k] + (vals[a] * s if k < 3 else vals[a])
        for k in range(6):
            if not abs(end[k]) <= MAX_COORDINATE:
                raise InputError(f"{_AXES[k].upper()} coordinate {end[k]:.6g} out of range",
                                 self._where(w.col(_AXES[k])))
        return end

    def _motion(self, code: int, col: int, w: _Words, g53: bool) -> None:
        loc = self._where(col)
        if code in _CYCLES:
            from fusioncut.io.gcode_cycles import canned_cycle

            if self._comp is not None:
                raise InputError("canned cycles cannot be used with cutter compensation on", loc)
            if self.feed_mode == "inverse_time":
                raise InputError("canned cycles cannot be used in inverse time feed (G93)", loc)
            canned_cycle(self, code, w, loc)
            self.motion = code
            return
        if code != self.motion:
            self._cycle_initial = None
        if code != 50:
            self._g5_last = None  # a G5 without I/J continues only a directly preceding G5
        self.motion = code
        if code in (0, 10):
            self._arc_not_allowed = False
            end = self._ends(w, g53)
            if self._comp is not None:
                gcode_comp.straight(self, end, code == 0, w, loc)
                return
            self._linear(end, code == 0, loc, w)
        elif code in (20, 30):
            self._arc_block(code, w, loc)
        elif code in (50, 51):
            self._spline(code, w, loc)

    def _feed_rate(self, length: float, loc: SourceLocation, w: _Words | None, rotary_length: float = 0.0) -> float:
        """mm/min for a feed move of ``length`` mm (see the module doc for the feed modes)."""
        mode = self.feed_mode
        if mode == "units_per_minute":
            f = self.feed
            if not f:
                self._feed_missing(loc)
                return 0.0
            return f * self._scale()
        if mode == "inverse_time":
            if w is not None and "f" not in w.vals:
                raise InputError("F word missing for a feed move in inverse time mode (G93)", loc)
            f = self.feed or 0.0
            if f <= 0:
                raise InputError("inverse time feed needs F > 0", loc)
            # LinuxCNC: rate = F * length, the XYZ length unless only rotary axes move
            return f * (length if length > 0 or rotary_length == 0 else rotary_length)
        f = self.feed
        if not f:
            self._feed_missing(loc)
            return 0.0
        if not self.rpm:
            if self.strict:
                raise InputError("feed per revolution (G95) with zero spindle speed", loc)
            self._warn_once("g95rpm", "feed per revolution (G95) with zero spindle speed: feed 0", loc.column)
            return 0.0
        return f * self._scale() * self.rpm

    def _feed_missing(self, loc: SourceLocation) -> None:
        if self.strict:
            raise InputError("feed move with zero feed rate (no F word in effect)", loc)
        self._warn_once("nofeed", "feed move with zero feed rate (no F word in effect): feed 0", loc.column)

    def _check_rotary(self, end: list[float], loc: SourceLocation) -> None:
        p = self.pos
        if end[3] != p[3] or end[4] != p[4] or end[5] != p[5]:
            if not self.allow_rotary:
                raise InputError("5-axis / rotary motion not supported yet", loc)

    def _budget(self, n: int, loc: SourceLocation) -> None:
        """Refuse a block about to make ``n`` moves when one block may not, or the program may not."""
        if n > MAX_MOVES_PER_BLOCK:
            raise InputError(f"one block would make {n} moves (more than {MAX_MOVES_PER_BLOCK})", loc)
        self.budget.check(len(self.moves), n, f"this block makes {n:,}", loc)

    def _linear(self, end: list[float], rapid: bool, loc: SourceLocation, w: _Words | None = None) -> LinearMove:
        p = self.pos
        self._check_rotary(end, loc)
        start = (p[0], p[1], p[2])
        e = (end[0], end[1], end[2])
        feed = None
        if not rapid:
            length = math.dist(start, e)
            rot = 0.0
            if length == 0.0 and self.feed_mode == "inverse_time":
                rot = math.dist(p[3:], end[3:])
            feed = self._feed_rate(length, loc, w, rot)
        self._pending_op()
        mv = LinearMove(start=start, end=e, feed=feed, spindle_rpm=self.rpm, tool=self.tool,
                        operation=self.operation, source=loc, rapid=rapid)
        self._push(mv, end)
        return mv

    def _pending_op(self) -> None:
        if self._pending_operation is not None:
            self.operation = self._pending_operation
            self._pending_operation = None

    def _push(self, mv: Move, end: list[float]) -> None:
        if len(self.moves) >= self._move_room:
            raise self.budget.refuse("at this block", mv.source)
        self.moves.append(mv)
        self._step_moves.append(mv)
        self.rotary_ends.append((end[3], end[4], end[5]))
        self.pos = list(end)

    def _arc_block(self, code: int, w: _Words, loc: SourceLocation) -> None:
        plane = self.plane
        ia, ib, n = plane.axes
        wa, wb = _AXES[ia], _AXES[ib]
        if self._arc_not_allowed:
            raise InputError("the move just after ending cutter compensation (G40) must be straight", loc)
        if wa not in w.vals and wb not in w.vals:
            raise InputError(f"arc in {_PLANE_GCODE[plane]} needs {wa.upper()} or {wb.upper()}", loc)
        end = self._ends(w, False)
        cw = code == 20
        p_turns = w.get("p")
        turns = 0
        if p_turns is not None:
            if p_turns < 1 or p_turns != math.floor(p_turns):
                raise InputError(f"arc P (turns) must be a whole number >= 1, got P{p_turns:g}", loc)
            if p_turns > MAX_ARC_TURNS:
                raise JobTooLarge(f"arc P{p_turns:g}: more than {MAX_ARC_TURNS:,} turns in one block", loc)
            turns = int(p_turns) - 1
            if turns:
                # each extra turn counts as a move of the budget (see gcode_budget)
                self.budget.check(len(self.moves), turns + 1, f"an arc of {turns + 1:,} turns", loc)
                self.budget.extra_turns += turns
                self._move_room = self.budget.room(0)
        if self._comp is not None:
            gcode_comp.arc(self, end, cw, turns, w, loc)
            return
        center = self._arc_center(end, cw, w, loc, self.pos)
        self._arc(end, center, cw, turns, loc, w)

    def _arc_center(self, end: list[float], cw: bool, w: _Words, loc: SourceLocation,
                    start: list[float]) -> tuple[float, float]:
        """In-plane centre (a, b) of a G2/G3 from R or I/J/K, with LinuxCNC's checks."""
        plane = self.plane
        ia, ib, _ = plane.axes
        oa, ob, on = _PLANE_OFFSET_WORDS[plane]
        s = self._scale()
        sa, sb = start[ia], start[ib]
        ea, eb = end[ia], end[ib]
        r = w.get("r")
        if r is not None:
            if oa in w.vals or ob in w.vals:
                raise InputError("arc with both R and I/J/K", loc)
            return _center_from_radius(sa, sb, ea, eb, r * s, cw, RADIUS_TOL_INCH * MM_PER_INCH, loc)
        if oa not in w.vals and ob not in w.vals:
            raise InputError(f"arc needs R or {oa.upper()}/{ob.upper()} centre words", loc)
        if self.arc_absolute and (oa not in w.vals or ob not in w.vals):
            missing = oa if oa not in w.vals else ob
            raise InputError(f"{missing.upper()} word missing in an absolute-centre (G90.1) arc", loc)
        i_v = (w.get(oa) or 0.0) * s
        j_v = (w.get(ob) or 0.0) * s
        rad_tol = RADIUS_TOL_INCH * MM_PER_INCH
        spiral = SPIRAL_ABS_TOL_INCH * MM_PER_INCH if self.inch else SPIRAL_ABS_TOL_MM
        off = self._offset()
        absolute_center = (i_v + off[ia], j_v + off[ib])
        incremental_center = (sa + i_v, sb + j_v)
        if self.arc_absolute:
            center = absolute_center
        else:
            center = incremental_center
        err = _radius_error(sa, sb, ea, eb, center, rad_tol, spiral)
        if err is not None and not self.arc_absolute and self.arc_centers == "auto":
            if _radius_error(sa, sb, ea, eb, absolute_center, rad_tol, spiral) is None:
                self.arc_absolute = True
                self.warnings.append(
                    f"{loc}: arc centre words read as incremental give start and end radii "
                    f"{err[1]:.4f} and {err[2]:.4f} mm; as absolute centres (G90.1) they fit, so this "
                    f"program is taken to use absolute I/J/K from here on"
                )
                return absolute_center
        if err is not None:
            msg, r1, r2 = err
            hint = ""
            if not self.arc_absolute and _radius_error(sa, sb, ea, eb, absolute_center, rad_tol, spiral) is None:
                hint = " (the centre fits as an absolute G90.1 centre: try arc_centers='auto' or 'absolute')"
            raise InputError(msg + hint, loc)
        return center

    def _arc(self, end: list[float], center: tuple[float, float], cw: bool, turns: int,
             loc: SourceLocation, w: _Words | None) -> ArcMove:
        self._check_rotary(end, loc)
        p = self.pos
        ia, ib, n = self.plane.axes
        c = [0.0, 0.0, 0.0]
        c[ia], c[ib], c[n] = center[0], center[1], p[n]
        start = (p[0], p[1], p[2])
        e = (end[0], end[1], end[2])
        self._pending_op()
        mv = ArcMove(start=start, end=e, feed=None, spindle_rpm=self.rpm, tool=self.tool,
                     operation=self.operation, source=loc, center=(c[0], c[1], c[2]), plane=self.plane,
                     clockwise=cw, turns=turns)
        # the feed of inverse time and the check need the arc's length, which the move computes
        mv = replace(mv, feed=self._feed_rate(mv.length, loc, w))
        self._push(mv, end)
        return mv

    def _spline(self, code: int, w: _Words, loc: SourceLocation) -> None:
        """G5 cubic / G5.1 quadratic spline in G17, flattened into feeds within SPLINE_TOLERANCE_MM."""
        if self.plane is not ArcPlane.XY:
            raise InputError(f"{_gname(code)} splines need the XY plane (G17)", loc)
        if self._comp is not None:
            raise InputError(f"{_gname(code)} with cutter compensation on", loc)
        s = self._scale()
        if "z" in w.vals or any(a in w.vals for a in _ROTARY):
            raise InputError(f"{_gname(code)} moves only X and Y", loc)
        end = self._ends(w, False)
        p0 = (self.pos[0], self.pos[1])
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
                if self._g5_last is None:
                    raise InputError("G5 without I/J must follow another G5", loc)
                i_v, j_v = self._g5_last
            c1 = (p0[0] + (i_v or 0.0) * s, p0[1] + (j_v or 0.0) * s)
            c2 = (p3[0] + p_v * s, p3[1] + q_v * s)
            self._g5_last = (-p_v, -q_v)

            def point(t: float) -> tuple[float, float]:
                u = 1 - t
                return (u ** 3 * p0[0] + 3 * u * u * t * c1[0] + 3 * u * t * t * c2[0] + t ** 3 * p3[0],
                        u ** 3 * p0[1] + 3 * u * u * t * c1[1] + 3 * u * t * t * c2[1] + t ** 3 * p3[1])

            # bound on |B''| of a cubic: 6 * max of its two second differences
            d2 = 6 * max(math.hypot(p0[0] - 2 * c1[0] + c2[0], p0[1] - 2 * c1[1] + c2[1]),
                         math.hypot(c1[0] - 2 * c2[0] + p3[0], c1[1] - 2 * c2[1] + p3[1]))
        # chord error of a segment of parameter length h is at most |B''| h^2 / 8
        nseg = max(1, math.ceil(math.sqrt(d2 / (8 * SPLINE_TOLERANCE_MM)))) if d2 > 0 else 1
        self._budget(nseg, loc)
        for k in range(1, nseg + 1):
            if k == nseg:
                x, y = p3
            else:
                x, y = point(k / nseg)
            e = list(self.pos)
            e[0], e[1] = x, y
            e[2] = end[2]
            self._linear(e, False, loc, w)

    _g5_last: tuple[float, float] | None = None


# ---------------------------------------------------------------------- helpers


def _close(stack: list[tuple[str, str, int, list[int]]], expect: str, kw: str, label: str,
           where: SourceLocation) -> tuple[str, str, int, list[int]]:
    """Pop the construct an O-word closes (``endsub`` closes ``sub``, ...), checking label and kind."""
    if not stack or stack[-1][0] != expect or stack[-1][1] != label:
        raise InputError(f"O{label} {kw} without a matching O{label} {expect}", where)
    return stack.pop()


def _gname(code10: int) -> str:
    return f"G{code10 // 10}" + (f".{code10 % 10}" if code10 % 10 else "")


def _code10(v: float, letter: str, where: SourceLocation) -> int:
    c = round(v * 10)
    if abs(v * 10 - c) > 1e-3 or c < 0:
        raise InputError(f"bad {letter} code {letter}{v:g}", where)
    return int(c)


def _first_axis_col(w: _Words) -> int:
    cols = [w.col(a) for a in _AXES if a in w.vals]
    return min(cols) if cols else 0


def _zero_length(m: Move) -> bool:
    return isinstance(m, LinearMove) and m.start == m.end


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


def _parse_tool_comment(text: str) -> tuple[int, float, float | None, float | None, float | None, str] | None:
    """``T1 D=2.65 CR=0 - ZMIN=-12.55 - flat end mill`` -> (1, 2.65, 0, None, -12.55, 'flat end mill')."""
    import re

    m = _TOOL_RE.match(text)
    if not m:
        return None
    number = int(m.group(1))
    try:
        d = float(m.group(2))
        cr = float(m.group(3)) if m.group(3) else None
        taper = float(m.group(4)) if m.group(4) else None
    except ValueError:
        return None
    rest = m.group(5) or ""
    zmin = None
    zm = re.search(r"ZMIN\s*=\s*(-?\d*\.?\d+)", rest, re.I)
    if zm:
        zmin = float(zm.group(1))
    parts = [p.strip() for p in rest.split(" - ") if p.strip()]
    kind = parts[-1] if parts else ""
    if kind.upper().startswith("ZMIN"):
        kind = ""
    return number, d, cr, taper, zmin, kind


# Fusion's tool type names (getToolTypeName), longest first: hobby posts append the tool's own
# comment after them, "flat end mill 2 flute [d2.4mm]"
_FUSION_TOOL_TYPES = tuple(sorted((
    "flat end mill", "ball end mill", "bull nose end mill", "face mill", "chamfer mill", "tapered mill",
    "slot mill", "radius mill", "dovetail mill", "lollipop mill", "thread mill", "form mill", "spot drill",
    "center drill", "drill", "reamer", "boring bar", "counter bore", "counter sink", "right tap",
    "left tap", "probe"), key=len, reverse=True))


def _tool_name(kind: str) -> str:
    """A tool comment's own words, as written: what follows Fusion's type name, or all of the text
    when it starts with no type name Fusion writes."""
    text = kind.strip().lstrip("-").strip()  # a comment without ZMIN keeps the " - " before the type
    low = text.lower()
    for t in _FUSION_TOOL_TYPES:
        if low.startswith(t):
            return text[len(t):].strip()
    return text


def _compile_tool_re():
    import re

    return re.compile(
        r"^\s*T\s*(\d+)\s+D\s*=\s*(\d*\.?\d+)(?:\s+CR\s*=\s*(\d*\.?\d+))?"
        r"(?:\s+TAPER\s*=\s*(\d*\.?\d+)\s*deg)?\s*(.*)$",
        re.I,
    )


_TOOL_RE = _compile_tool_re()


def _make_tool(number: int, d: float, cr: float, taper: float | None, zmin: float | None, kind: str) -> MillingTool:
    """A model tool from a post's tool comment (mm); see the module doc for the rules."""
    flute = 3 * d
    if zmin is not None and zmin < 0:
        flute = max(flute, -zmin)
    words = kind.lower()
    if "ball" in words or (cr > 0 and abs(cr - d / 2) < 1e-9):
        return BallEndMill(diameter=d, flute_length=max(flute, d / 2), number=number)
    if "drill" in words:  # Fusion's TAPER= of a drill is its point's included angle (118 typical)
        return Drill(diameter=d, flute_length=flute, point_angle=taper or 118.0, number=number)
    if any(k in words for k in ("chamfer", "spot", "engrav", "countersink", "v-bit", "vbit")):
        return ChamferMill(diameter=d, flute_length=flute, taper_angle=taper or 45.0, number=number)
    if "taper" in words and taper:
        return TaperedEndMill(diameter=d, flute_length=flute, taper_angle=taper, number=number)
    if cr > 0:
        return BullNoseEndMill(diameter=d, flute_length=flute, corner_radius=cr, number=number)
    return FlatEndMill(diameter=d, flute_length=flute, number=number)


# ---------------------------------------------------------------------- public functions


def parse_gcode_text(
    text: str,
    *,
    source: str = "<memory>",
    tools: dict[int, MillingTool] | None = None,
    strict: bool = False,
    arc_centers: ArcCenters = "auto",
    max_moves: int | None = DEFAULT_MAX_MOVES,
) -> Toolpath:
    """Interpret G-code text into a :class:`Toolpath` (mm, machine frame, tool tip); see the module doc."""
    interp = GCodeInterpreter(text, source=source, tools=tools, strict=strict, arc_centers=arc_centers,
                              max_moves=max_moves)
    interp.run()
    return interp.toolpath()


def read_gcode(
    path: str | Path,
    *,
    tools: dict[int, MillingTool] | None = None,
    strict: bool = False,
    arc_centers: ArcCenters = "auto",
    max_moves: int | None = DEFAULT_MAX_MOVES,
) -> Toolpath:
    """Read and interpret a G-code file into a :class:`Toolpath`; errors name ``file:line:column``."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise InputError(f"cannot read G-code file: {e.strerror}", p) from None
    # G-code is ASCII; tolerate Latin-1 comments from old posts rather than failing on them
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    return parse_gcode_text(text, source=str(path), tools=tools, strict=strict, arc_centers=arc_centers,
                            max_moves=max_moves)
