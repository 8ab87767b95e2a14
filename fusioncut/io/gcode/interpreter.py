"""The RS274/NGC interpreter: runs a program block by block on a :class:`~.machine.Machine`.

A block runs in LinuxCNC's order: its values are evaluated with the parameters as they were before
the line, parameter settings take effect, codes are sorted by modal group, then comments, machine
settings (:mod:`.settings`), non-modal codes (:mod:`.offsets`), motion (:mod:`.motion`,
:mod:`.cycles`, :mod:`.comp`) and stops. O-word lines go to the program's flow control
(:mod:`.flow`). The rules are summarised in the package doc (:mod:`fusioncut.io.gcode`).
"""
from __future__ import annotations

import gc
from dataclasses import replace
from typing import Iterator, Literal, Mapping

from fusioncut.errors import InputError, SourceLocation
from fusioncut.io.gcode.budget import DEFAULT_MAX_MOVES
from fusioncut.io.gcode.comp import arc as compensated_arc
from fusioncut.io.gcode.comp import flush as release_held_moves
from fusioncut.io.gcode.comp import straight as compensated_straight
from fusioncut.io.gcode.cycles import canned_cycle
from fusioncut.io.gcode.flow import Program
from fusioncut.io.gcode.lexer import Block, evaluate, parse_line
from fusioncut.io.gcode.machine import Machine, Words
from fusioncut.io.gcode.modal import AXES, AXES_SET, CYCLES, GROUP0_AXIS_USERS, ModalState, gname, sort_codes
from fusioncut.io.gcode.motion import arc, arc_center, arc_target, spline, target
from fusioncut.io.gcode.offsets import non_modal
from fusioncut.io.gcode.params import Parameters
from fusioncut.io.gcode.program_end import no_moves_warning, stop_warning
from fusioncut.io.gcode.settings import machine_settings, modal_settings
from fusioncut.io.gcode.tool_comments import parse_tool_comment, tools_from_comments
from fusioncut.model.moves import LinearMove, Move, Toolpath
from fusioncut.model.tools import MillingTool

__all__ = ["ArcCenters", "GCodeInterpreter"]

ArcCenters = Literal["auto", "incremental", "absolute"]

# comments that are messages to the operator, not operation names
_MESSAGE_PREFIXES = ("msg,", "debug,", "print,", "log,", "logopen,", "logappend,", "logclose")


class GCodeInterpreter:
    """Runs an RS274/NGC program block by block.

    ``step()`` executes the next block and returns the moves it produced (``None`` once the program
    has ended); iterating yields ``(line, moves)`` per executed block; ``state`` is the
    :class:`ModalState` after the last block; ``execute(text)`` runs one extra line (MDI style,
    without O-word flow control); ``toolpath()`` gives the result as :func:`read_gcode` does.
    ``moves`` holds every move so far, zero-length ones included, and ``rotary_ends`` the A, B, C
    angles at the end of each move. ``tool_lengths`` (tool number -> mm) are the lengths G43 uses.
    ``machine`` is the :class:`~.machine.Machine` the program drives (modal state in internal units).
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
        self.machine = Machine(source=self.source, strict=strict, arc_centers=arc_centers,
                               allow_rotary=allow_rotary, tools=tools, tool_lengths=tool_lengths,
                               max_moves=max_moves)
        self.program = Program(text, self.source)
        self.params = Parameters(self.machine)
        self._block_limit = self.machine.budget.max_blocks or 1 << 62
        self._ended = False
        self._stop: tuple[int, str] | None = None  # (line, what) of an M2/M30/% that ended the program
        self._mdi_lines = 0

    # ------------------------------------------------------------------ public
    @property
    def state(self) -> ModalState:
        return self.machine.state()

    @property
    def moves(self) -> list[Move]:
        return self.machine.moves

    @property
    def rotary_ends(self) -> list[tuple[float, float, float]]:
        return self.machine.rotary_ends

    @property
    def warnings(self) -> list[str]:
        return self.machine.warnings

    @property
    def inch(self) -> bool:
        """True while the program's units are inches (G20)."""
        return self.machine.inch

    @property
    def ended(self) -> bool:
        return self._ended

    def step(self) -> list[Move] | None:
        """Execute the next block of the program; its moves, or ``None`` when the program has ended."""
        prog, m = self.program, self.machine
        while not self._ended:
            if prog.index >= len(prog.lines):
                return self._finish()
            i = prog.index
            block = prog.block(i)
            prog.index = i + 1
            if block.percent:
                if block.percent_text:
                    self._stray_percent(block)
                    continue
                if prog.started or prog.percent_open:
                    self._stopped(i, "the closing %")
                    return self._finish()
                prog.percent_open = True
                continue
            if block.deleted or (block.is_empty and block.comment is None):
                continue
            prog.started = True
            prog.executed += 1
            if prog.executed > self._block_limit:
                m.budget.check_blocks(prog.executed, SourceLocation(self.source, block.line, 1))
            if i > prog.furthest:
                prog.furthest = i
            m.step_moves = []
            m.line = block.line
            if block.oword is not None:
                prog.control(i, block, self.params, m)
            else:
                self._execute(block)
            return m.step_moves
        return None

    def __iter__(self) -> Iterator[tuple[int, list[Move]]]:
        while True:
            moves = self.step()
            if moves is None:
                return
            yield self.machine.line, moves

    def run(self) -> GCodeInterpreter:
        """Execute the whole program; returns ``self``."""
        # Tens of thousands of small acyclic objects (moves, points) would make the cyclic garbage
        # collector rescan the growing heap again and again; nothing here creates reference cycles,
        # so it is paused while the program runs.
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
        held until the next one is known (see :mod:`fusioncut.io.gcode.comp`)."""
        m = self.machine
        self._mdi_lines += 1
        m.line = len(self.program.lines) + self._mdi_lines
        block = parse_line(text, m.line, self.source)
        if block.oword is not None:
            raise InputError("O-word control lines need a program", SourceLocation(self.source, m.line, 1))
        m.step_moves = []
        if not block.deleted and not block.percent:
            self._execute(block)
        return m.step_moves

    def toolpath(self, *, drop_zero_length: bool = True) -> Toolpath:
        """The moves so far as a :class:`Toolpath`; zero-length moves dropped and counted in a warning."""
        m = self.machine
        moves: list[Move] = m.moves
        warnings = list(m.warnings)
        if drop_zero_length:
            kept = [mv for mv in moves if not (isinstance(mv, LinearMove) and mv.start == mv.end)]
            dropped = len(moves) - len(kept)
            if dropped:
                warnings.append(f"{self.source}: dropped {dropped} zero-length move{'s' if dropped != 1 else ''}")
            moves = kept
        if not moves:
            warnings.append(no_moves_warning(self.source, self._stop, bool(m.moves), self.program.lines))
        inch = m.first_units == "inch"
        if m.user_tools is None:
            tools, program = tools_from_comments(m.tool_comments, inch, warnings), None
        else:
            # tools given replace the comments' (unusable comments then go unreported); keep the program's own
            tools, program = m.user_tools, tools_from_comments(m.tool_comments, inch, [])
        return Toolpath(moves=tuple(moves), tools=tools, warnings=tuple(warnings), source=self.source,
                        program_tools=program)

    # ------------------------------------------------------------------ program end
    def _stopped(self, index: int, what: str) -> None:
        """The program ends at line ``index + 1`` by ``what``: warn when lines with words remain unread."""
        prog = self.program
        line = index + 1
        self._stop = (line, what)
        after = max(index, prog.furthest) + 1
        furthest = prog.furthest + 1 if prog.furthest > index else 0
        warning = stop_warning(f"{self.source}:{line}", what, prog.lines, after, furthest)
        if warning is not None:
            self.machine.warnings.append(warning)

    def _stray_percent(self, block: Block) -> None:
        """A ``%`` line with text after it: not a program delimiter (LinuxCNC refuses the line with
        "Bad character '%' used"); strict: the same refusal, lenient: ignored with a warning."""
        self.machine.line = block.line
        col = len(block.text) - len(block.text.lstrip()) + 1
        text = block.text.strip()
        shown = text if len(text) <= 40 else text[:37] + "..."
        self.machine.unsupported(f"'{shown}': a % line with text after the % is not a program start or end "
                                 "(only a lone % is)", col)

    def _finish(self) -> list[Move] | None:
        """End of the program text: release held compensated moves (returned as a last step)."""
        self._ended = True
        m = self.machine
        if m.comp is not None:
            m.step_moves = []
            release_held_moves(m)
            if m.step_moves:
                return m.step_moves
        return None

    # ------------------------------------------------------------------ block execution
    def _execute(self, block: Block) -> None:
        m = self.machine
        if (block.simple and m.comp is None and m.base is None
                and (m.motion == 0 or m.motion == 10) and m.feed_mode != "inverse_time"):
            self._execute_simple(block)
            return
        self._execute_general(block)

    def _execute_simple(self, block: Block) -> None:
        """Fast path for the bulk of posted code: ``[N..] [X..] [Y..] [Z..] [F..]`` in G0/G1 mode.

        Same result as the general path (the tests compare both on whole files)."""
        m = self.machine
        # a simple block is constant: its values are plain floats
        words: dict[str, tuple[float, int]] = block.words  # type: ignore[assignment]
        f = words.get("f")
        if f is not None:
            if f[0] < 0:
                raise InputError(f"negative feed rate F{f[0]:g}", m.where(f[1]))
            m.feed = f[0]
        pos = m.pos
        end = list(pos)
        s = m.scale()
        col = 0
        moved = False
        off = m.offset() if m.absolute else None
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
        rapid = m.motion == 0
        if rapid:
            feed = None
        elif m.feed_mode == "units_per_minute" and m.feed:
            feed = m.feed * s
        else:
            feed = m.feed_rate(0.0, loc, None)
        mv = LinearMove(start=(pos[0], pos[1], pos[2]), end=(end[0], end[1], end[2]), feed=feed,
                        spindle_rpm=m.rpm, tool=m.tool, operation=m.take_operation(), source=loc, rapid=rapid)
        m.push(mv, end)

    def _execute_general(self, block: Block) -> None:
        m = self.machine
        params = self.params
        # 1. evaluate every value with the parameters as they were before the line
        vals = {k: evaluate(v[0], params) for k, v in block.words.items()}
        gs = [(evaluate(v, params), c) for v, c in block.g]
        ms = [(evaluate(v, params), c) for v, c in block.m]
        assigns = [(r, evaluate(v, params), c) for r, v, c in block.assignments]
        for ref, value, c in assigns:
            params.assign(ref, value, SourceLocation(self.source, block.line, c))
        w = Words(block, vals)
        for letter in "uvw":
            if letter in vals:
                w.used.add(letter)
                m.unsupported(f"{letter.upper()} axis not supported", w.col(letter))
                del vals[letter]

        # 2. G and M codes by modal group
        codes = sort_codes(gs, ms, m.where, m.unsupported)
        g0 = codes.g.get(0)
        g1 = codes.g.get(1)
        has_axes = not AXES_SET.isdisjoint(vals)
        g0_axes = bool(g0 and g0[0] in GROUP0_AXIS_USERS) or codes.g.get(8, (0, 0))[0] == 431
        if g1 and has_axes and g0_axes:
            raise InputError(f"{gname(g0[0] if g0 else 431)} and {gname(g1[0])} both want the axis words of this block",
                             m.where(g1[1]))

        # 3. comment: operation names, tool descriptions
        if block.comment is not None:
            self._comment(block)

        # 4.-5. feed, speed, tool, spindle, coolant; plane, units, offsets, distance modes
        machine_settings(m, codes, w)
        modal_settings(m, codes, w)

        # 6. non-modal codes that move or set offsets
        g53 = non_modal(m, w, *g0) if g0 is not None else False

        # 7. motion
        motion: int | None = None
        motion_col = 0
        if g1 is not None:
            motion, motion_col = g1
        elif codes.skipped and has_axes:
            # an unknown or unsupported code may be the one that wanted these axis words (G33,
            # G38.2, ...): moving with the modal G0/G1 instead could invent a cut
            for a in AXES:
                w.get(a)
            m.warnings.append(f"{m.where(w.first_axis_col())}: motion of this block skipped")
        elif has_axes and not g0_axes:
            motion = m.motion
            motion_col = w.first_axis_col()
            if motion is None:
                raise InputError("axis words without a motion mode (G0, G1, ...) in effect", m.where(motion_col))
        if g53 and motion not in (0, 10):
            raise InputError("G53 needs G0 or G1", m.where(g0[1] if g0 else 0))
        if motion == 800:
            if has_axes:
                raise InputError("axis words with G80", m.where(w.first_axis_col()))
            m.motion = None
            m.cycle_initial = None
        elif motion is not None:
            self._motion(motion, m.where(motion_col), w, g53)

        # 8. stops: held compensated moves are released first
        stop = codes.m.get(4)
        if stop is not None:
            if m.comp is not None:
                release_held_moves(m)
            if stop[0] in (2, 30):
                m.end_program()
                self._ended = True
                self._stopped(block.line - 1, f"M{stop[0]}")

        if not codes.skipped:
            for letter in [k for k in vals if k not in w.used]:
                m.unsupported(f"{letter.upper()} word not used by any command in this block", w.col(letter))

    def _motion(self, code: int, loc: SourceLocation, w: Words, g53: bool) -> None:
        m = self.machine
        if code in CYCLES:
            canned_cycle(m, code, w, loc)
            return
        if code != m.motion:
            m.cycle_initial = None
        if code != 50:
            m.g5_last = None  # a G5 without I/J continues only a directly preceding G5
        m.motion = code
        if code in (0, 10):
            m.arc_not_allowed = False
            end = target(m, w, g53)
            if m.comp is not None:
                compensated_straight(m, end, code == 0, w, loc)
            else:
                m.linear(end, code == 0, loc, w)
        elif code in (20, 30):
            end, turns = arc_target(m, w, loc)
            if m.comp is not None:
                compensated_arc(m, end, code == 20, turns, w, loc)
            else:
                arc(m, end, arc_center(m, end, code == 20, w, loc, m.pos), code == 20, turns, loc, w)
        elif code in (50, 51):
            spline(m, code, w, loc)

    def _comment(self, block: Block) -> None:
        """A standalone comment names the next moves' operation, unless it is a message or describes
        a tool (:mod:`.tool_comments`)."""
        text = (block.comment or "").strip()
        if not block.standalone_comment or not text or text.lower().startswith(_MESSAGE_PREFIXES):
            return
        tool = parse_tool_comment(text)
        m = self.machine
        if tool is not None:
            where = SourceLocation(self.source, block.line, block.comment_column)
            m.tool_comments[tool.number] = replace(tool, where=where)
            return
        m.pending_operation = text
