"""The machine state an RS274/NGC program drives, and the moves it emits.

:class:`Machine` is the one object the parts of the interpreter share: the block executor
(:mod:`.interpreter`), offsets (:mod:`.offsets`), motion (:mod:`.motion`), canned cycles
(:mod:`.cycles`) and cutter compensation (:mod:`.comp`) are functions of it. It holds the modal state
in internal units (mm, mm/min, degrees; ``feed`` is the ``F`` number as programmed), the work
offsets, the position of the tool tip in the machine frame, and the moves, warnings and budget of the
run. Every move leaves through :meth:`Machine.push`, which checks the move budget and updates the
position.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

from fusioncut.errors import InputError, SourceLocation
from fusioncut.io.gcode.budget import MoveBudget
from fusioncut.io.gcode.lexer import Block
from fusioncut.io.gcode.modal import COORD_SYSTEMS, ModalState, gname
from fusioncut.io.gcode.tool_comments import ToolComment
from fusioncut.model.moves import ArcPlane, LinearMove, Move
from fusioncut.model.tools import MillingTool
from fusioncut.model.units import MM_PER_INCH

__all__ = ["CompState", "HeldMove", "Machine", "Words"]

# safety limit against runaway programs (an L or P word of 1e9); the program's total of moves and
# blocks is bounded by its MoveBudget (budget.py)
MAX_MOVES_PER_BLOCK = 100_000


class Words:
    """The evaluated words of one block, remembering which ones a command used (the rest are
    reported as unused)."""

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

    def first_axis_col(self) -> int:
        cols = [self.col(a) for a in "xyzabc" if a in self.vals]
        return min(cols) if cols else 0


@dataclass
class HeldMove:
    """A compensated move held back until the next move is known (plane coordinates a, b)."""

    kind: str  # "rapid", "feed", "arc"
    end: list[float]  # 6 coordinates, machine frame
    feed: float | None
    loc: SourceLocation
    direction: tuple[float, float] = (0.0, 0.0)  # programmed in-plane direction of a straight move
    center: tuple[float, float] = (0.0, 0.0)
    turn: int = 0  # LinuxCNC's turn: +-(1 + extra turns), sign = counter-clockwise
    original_turns: float = 0.0  # programmed sweep (rad) of an arc, to detect gouges
    rpm: float | None = None
    tool: int | None = None
    operation: str = ""


@dataclass
class CompState:
    """Cutter radius compensation while it is on (see :mod:`.comp`): the side, the radius (mm, >= 0),
    the plane, and the moves held for one move of lookahead."""

    side: str  # "left" or "right"
    radius: float
    plane: ArcPlane
    first: bool = True  # no move made since compensation was turned on
    queue: list[HeldMove] = field(default_factory=list)
    endpoint: tuple[float, float] | None = None  # where the first held move starts
    cur: list[float] = field(default_factory=list)  # end of the last held move (compensated)
    prog: list[float] = field(default_factory=list)  # last programmed point

    @property
    def left(self) -> bool:
        return self.side == "left"

    def hold(self, move: HeldMove, programmed: list[float]) -> None:
        """Hold ``move`` (the compensated form of a move programmed to end at ``programmed``)."""
        self.queue.append(move)
        self.first = False
        self.cur = list(move.end)  # a copy: a concave corner later moves the held move's end
        self.prog = list(programmed)


class Machine:
    """Modal state, offsets, position and output of one interpreter run (see the module doc).

    Offsets are per axis X Y Z A B C: ``g5x[1..9]`` the G54-G59.3 origins (``cs`` the active one),
    ``g92`` the G92 shift (when ``g92_applied``), ``g28``/``g30`` the stored home points, all mm or
    degrees in the machine frame. ``tlo`` is the tool length in use (mm): the tip lies that far below
    the spindle gauge point.
    """

    def __init__(self, *, source: str, strict: bool, arc_centers: str, allow_rotary: bool,
                 tools: Mapping[int, MillingTool] | None, tool_lengths: Mapping[int, float] | None,
                 max_moves: int | None):
        self.source = source
        self.strict = strict
        self.arc_centers = arc_centers
        self.allow_rotary = allow_rotary
        self.user_tools = dict(tools) if tools is not None else None
        # --- output
        self.moves: list[Move] = []
        self.rotary_ends: list[tuple[float, float, float]] = []
        self.warnings: list[str] = []
        self.step_moves: list[Move] = []  # the moves of the block being executed
        self.budget = MoveBudget(max_moves)
        self.move_room = self.budget.room(0)  # emitting a move with this many emitted passes the budget
        self.line = 0  # source line of the block being executed
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
        self.seen_m6 = False
        self.tlo_number: int | None = None
        self.tlo = 0.0
        self.tool_lengths: dict[int, float] = dict(tool_lengths or {})
        self.tool_radii: dict[int, float] = {n: t.radius for n, t in (tools or {}).items()}
        self.tool_comments: dict[int, ToolComment] = {}
        self.first_units: str | None = None  # "mm" or "inch": the program's first G20/G21
        self.spindle = "off"
        self.rpm: float | None = None
        self.feed: float | None = None
        self.coolant: set[str] = set()
        self.retract_old_z = True
        self.operation = ""
        self.pending_operation: str | None = None  # a standalone comment's name for the next move
        self._warned_once: set[str] = set()
        # canned cycle memory (LinuxCNC's cycle_r, cycle_cc, cycle_p, ...) in mm
        self.cycle: dict[str, float] = {}
        self.cycle_initial: float | None = None  # initial level of a run of cycles
        self.g5_last: tuple[float, float] | None = None  # a G5's next I/J, for a G5 without them
        # cutter compensation
        self.comp: CompState | None = None
        self.base: list[float] | None = None  # where G91 / missing axis words start from, if not pos
        self.arc_not_allowed = False  # the move after G40 must be straight

    # ------------------------------------------------------------------ state and reports
    @property
    def comp_side(self) -> str:
        return self.comp.side if self.comp is not None else "off"

    def state(self) -> ModalState:
        g = self.g5x[self.cs]
        return ModalState(
            units="inch" if self.inch else "mm",
            distance_mode="absolute" if self.absolute else "incremental",
            arc_distance_mode="absolute" if self.arc_absolute else "incremental",
            plane=self.plane,
            feed_mode=self.feed_mode,  # type: ignore[arg-type]
            motion_mode=gname(self.motion) if self.motion is not None else None,
            coordinate_system=COORD_SYSTEMS[self.cs - 1],
            work_offset=(g[0], g[1], g[2]),
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
            line=self.line,
        )

    def where(self, col: int) -> SourceLocation:
        return SourceLocation(self.source, self.line, col)

    def unsupported(self, message: str, col: int) -> None:
        """Strict: raise; lenient: warn and go on without the offending word or code."""
        where = self.where(col)
        if self.strict:
            raise InputError(message, where)
        self.warnings.append(f"{where}: {message} (ignored)")

    def warn_once(self, key: str, message: str, col: int = 0) -> None:
        if key in self._warned_once:
            return
        self._warned_once.add(key)
        self.warnings.append(f"{self.where(col)}: {message}")

    # ------------------------------------------------------------------ coordinates
    def scale(self) -> float:
        """Millimetres per program unit of length."""
        return MM_PER_INCH if self.inch else 1.0

    def offset(self) -> list[float]:
        """Program-to-machine offset per axis: the active G5x origin plus G92 when applied (mm/deg)."""
        g = self.g5x[self.cs]
        if self.g92_applied:
            return [g[k] + self.g92[k] for k in range(6)]
        return list(g)

    def program_pos(self, axis: int) -> float:
        """Current position of an axis in program coordinates (mm / deg)."""
        off = self.g5x[self.cs][axis] + (self.g92[axis] if self.g92_applied else 0.0)
        return self.pos[axis] - off

    # ------------------------------------------------------------------ feeds
    def feed_rate(self, length: float, loc: SourceLocation, w: Words | None, rotary_length: float = 0.0) -> float:
        """mm/min for a feed move of ``length`` mm (see the package doc for the feed modes)."""
        mode = self.feed_mode
        if mode == "units_per_minute":
            f = self.feed
            if not f:
                self.feed_missing(loc)
                return 0.0
            return f * self.scale()
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
            self.feed_missing(loc)
            return 0.0
        if not self.rpm:
            if self.strict:
                raise InputError("feed per revolution (G95) with zero spindle speed", loc)
            self.warn_once("g95rpm", "feed per revolution (G95) with zero spindle speed: feed 0", loc.column)
            return 0.0
        return f * self.scale() * self.rpm

    def feed_missing(self, loc: SourceLocation) -> None:
        if self.strict:
            raise InputError("feed move with zero feed rate (no F word in effect)", loc)
        self.warn_once("nofeed", "feed move with zero feed rate (no F word in effect): feed 0", loc.column)

    # ------------------------------------------------------------------ emitting moves
    def check_rotary(self, end: list[float], loc: SourceLocation) -> None:
        p = self.pos
        if (end[3] != p[3] or end[4] != p[4] or end[5] != p[5]) and not self.allow_rotary:
            raise InputError("5-axis / rotary motion not supported yet", loc)

    def check_block(self, n: int, loc: SourceLocation) -> None:
        """Refuse a block about to make ``n`` moves when one block may not, or the program may not."""
        if n > MAX_MOVES_PER_BLOCK:
            raise InputError(f"one block would make {n} moves (more than {MAX_MOVES_PER_BLOCK})", loc)
        self.budget.check(len(self.moves), n, f"this block makes {n:,}", loc)

    def spend_turns(self, turns: int, loc: SourceLocation) -> None:
        """An arc's ``turns`` extra turns each count as a move of the budget (see budget.py)."""
        self.budget.check(len(self.moves), turns + 1, f"an arc of {turns + 1:,} turns", loc)
        self.budget.extra_turns += turns
        self.move_room = self.budget.room(0)

    def take_operation(self) -> str:
        """The operation name of the next move: a pending standalone comment's, else the current one."""
        if self.pending_operation is not None:
            self.operation = self.pending_operation
            self.pending_operation = None
        return self.operation

    def push(self, mv: Move, end: list[float]) -> None:
        """Emit ``mv``, which ends at ``end`` (6 coordinates); the tool is then there."""
        if len(self.moves) >= self.move_room:
            raise self.budget.refuse("at this block", mv.source)
        self.moves.append(mv)
        self.step_moves.append(mv)
        self.rotary_ends.append((end[3], end[4], end[5]))
        self.pos = list(end)

    def linear(self, end: list[float], rapid: bool, loc: SourceLocation, w: Words | None = None) -> LinearMove:
        """A straight rapid or feed from the current position to ``end``."""
        p = self.pos
        self.check_rotary(end, loc)
        start = (p[0], p[1], p[2])
        e = (end[0], end[1], end[2])
        feed = None
        if not rapid:
            length = math.dist(start, e)
            rot = 0.0
            if length == 0.0 and self.feed_mode == "inverse_time":
                rot = math.dist(p[3:], end[3:])
            feed = self.feed_rate(length, loc, w, rot)
        mv = LinearMove(start=start, end=e, feed=feed, spindle_rpm=self.rpm, tool=self.tool,
                        operation=self.take_operation(), source=loc, rapid=rapid)
        self.push(mv, end)
        return mv

    def end_program(self) -> None:
        """M2/M30: LinuxCNC resets part of the modal state (the rest of the file is not executed)."""
        self.comp = None
        self.plane = ArcPlane.XY
        self.absolute = True
        self.feed_mode = "units_per_minute"
        self.spindle = "off"
        self.coolant.clear()
        self.motion = 10
        self.cs = 1
