"""The program text and where execution stands in it: O-word subroutines, loops and branches.

:class:`Program` reads a line into a :class:`~.lexer.Block` the first time it runs and keeps it (loops
and subroutines run the same block again). The first O-word control line makes it scan the whole
text once to pair up ``sub``/``endsub``, ``do``/``while``, ``while``/``endwhile``,
``repeat``/``endrepeat`` and ``if``/``elseif``/``else``/``endif``, checking that ``break``,
``continue`` and ``return`` sit inside their construct; control lines then jump by line index.
Subroutines are those defined in the same file; calls nest at most 10 deep, as in LinuxCNC.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from fusioncut.errors import InputError, JobTooLarge, SourceLocation
from fusioncut.io.gcode.budget import may_leave_early
from fusioncut.io.gcode.lexer import Block, evaluate, parse_line
from fusioncut.io.gcode.machine import Machine
from fusioncut.io.gcode.params import Frame, Parameters

__all__ = ["Flow", "Program"]

MAX_REPEAT_COUNT = 1_000_000_000  # a repeat count of 1e15 is a broken program, not a long one

_Open = tuple[str, str, int, list[int]]  # (keyword, label, line index, if-branch indices)


@dataclass
class Flow:
    """Where O-word control lines jump to (line indices), found by scanning the program once."""

    subs: dict[str, tuple[int, int]] = field(default_factory=dict)  # label -> (sub, endsub)
    pair: dict[int, int] = field(default_factory=dict)  # matching line of a loop or next if-branch
    endif: dict[int, int] = field(default_factory=dict)  # elseif/else line -> its endif
    loops: list[tuple[int, int, str]] = field(default_factory=list)  # (first, last line, label)


class Program:
    """The lines of a program, their blocks as read so far, and the execution position: ``index``
    of the next line, ``executed`` blocks so far, ``furthest`` line index executed."""

    def __init__(self, text: str, source: str):
        self.source = source
        self.lines = text.splitlines()
        self.blocks: list[Block | None] = [None] * len(self.lines)
        self.index = 0
        self.executed = 0
        self.furthest = -1
        self.started = False  # a block with words or a comment ran
        self.percent_open = False  # a lone % opened the program
        self.flow: Flow | None = None
        self._branch_target: int | None = None  # the if-branch line a false condition jumped to

    def block(self, i: int) -> Block:
        b = self.blocks[i]
        if b is None:
            b = parse_line(self.lines[i], i + 1, self.source)
            self.blocks[i] = b
        return b

    # ------------------------------------------------------------------ scanning
    def scan(self) -> Flow:
        """Pair up the O-word lines once (see the module doc)."""
        flow = Flow()
        stack: list[_Open] = []
        started = False
        for i, raw in enumerate(self.lines):
            s = raw.lstrip()
            if not s:
                continue
            if s[0] == "%":
                if s[1:].strip():
                    continue  # not a delimiter (a % line with text after it)
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
            b = self.block(i)
            if b.oword is not None and not b.deleted:
                self._scan_line(flow, stack, i, b)
        if stack:
            kw, label, i, _ = stack[-1]
            raise InputError(f"O{label} {kw} is never closed", SourceLocation(self.source, i + 1, 1))
        return flow

    def _scan_line(self, flow: Flow, stack: list[_Open], i: int, b: Block) -> None:
        ow = b.oword
        assert ow is not None
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
            last = self.block(entry[3][-1]).oword
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

    # ------------------------------------------------------------------ executing control lines
    def control(self, i: int, block: Block, params: Parameters, machine: Machine) -> None:
        """Execute the O-word line at index ``i``: set ``index`` to where the program goes on."""
        ow = block.oword
        assert ow is not None
        kw = ow.keyword
        if kw == "":
            return  # program number (Fanuc O1234): nothing to do
        if self.flow is None:
            self.flow = self.scan()
        flow = self.flow
        where = SourceLocation(self.source, block.line, ow.column)
        arrived_by_jump = self._branch_target == i
        self._branch_target = None
        if kw in ("elseif", "else") and not arrived_by_jump:
            # the previous branch was taken and ran into this line: leave the if
            self.index = flow.endif[i] + 1
            return
        args = [evaluate(a, params) for a in ow.args]
        if kw == "sub":
            # reached in the flow of the program: skip the definition
            self.index = flow.subs[ow.label][1] + 1
        elif kw == "call":
            if ow.label not in flow.subs:
                raise InputError(f"subroutine O{ow.label} is not defined in this file", where)
            params.call(ow.label, i + 1, args, where)
            self.index = flow.subs[ow.label][0] + 1
        elif kw in ("endsub", "return"):
            if len(params.frames) == 1:
                raise InputError(f"O{ow.label} {kw} outside a subroutine call", where)
            self.index = params.leave(args)
        elif kw == "while":
            if i in flow.pair and flow.pair[i] < i:  # closing a do ... while
                if args[0]:
                    self.index = flow.pair[i] + 1
            elif not args[0]:
                self.index = flow.pair[i] + 1
        elif kw in ("endwhile", "endrepeat"):
            self.index = flow.pair[i]
        elif kw == "repeat":
            self._repeat(i, args[0], params.frames[-1], machine, where)
        elif kw in ("if", "elseif"):
            if not args[0]:
                self._branch_target = flow.pair[i]
                self.index = flow.pair[i]
        elif kw in ("break", "continue"):
            start, end = self._loop_around(i, ow.label)
            start_kw = self.block(start).oword.keyword  # type: ignore[union-attr]
            if kw == "break":
                params.frames[-1].repeats.pop(start, None)
                params.frames[-1].first_pass.pop(start, None)
                self.index = end + 1
            else:
                # continue: go to the line that tests the loop (the while of a do-while, the while
                # of a while loop, the endrepeat of a repeat)
                self.index = end if start_kw in ("do", "repeat") else start
        # "do" and "endif" need nothing

    def _repeat(self, i: int, n: float, frame: Frame, machine: Machine, where: SourceLocation) -> None:
        """A ``repeat [n]`` line: count the passes left in the frame; leave the loop after the last."""
        assert self.flow is not None
        end = self.flow.pair[i]
        reps = frame.repeats
        if i not in reps:
            if n < 0 or n != math.floor(n) or n > MAX_REPEAT_COUNT:
                raise InputError(f"repeat count must be a whole number >= 0, got {n:g}", where)
            reps[i] = int(n)
            if n > 1:
                frame.first_pass[i] = (len(machine.moves) + machine.budget.extra_turns, self.executed)
        elif i in frame.first_pass:
            self._check_repeat(i, frame, end, machine, where)
        if reps[i] <= 0:
            del reps[i]
            self.index = end + 1
        else:
            reps[i] -= 1

    def _check_repeat(self, i: int, frame: Frame, end: int, machine: Machine, where: SourceLocation) -> None:
        """The first pass of the repeat loop at line index ``i`` has run: refuse the loop if the passes
        still to come would pass the budget, unless its body can leave early (break, return, M2/M30),
        which only the running count can judge."""
        moves0, blocks0 = frame.first_pass.pop(i)
        spent = (len(machine.moves), self.executed)
        first = (len(machine.moves) + machine.budget.extra_turns - moves0, self.executed - blocks0)
        try:
            machine.budget.check_repeat(spent, first, frame.repeats[i], frame.repeats[i] + 1, where)
        except JobTooLarge:
            if not may_leave_early(self.block(j) for j in range(i + 1, end)):
                raise

    def _loop_around(self, i: int, label: str) -> tuple[int, int]:
        assert self.flow is not None
        inner = [(a, b) for a, b, lab in self.flow.loops if a < i < b and lab == label]
        if not inner:
            raise InputError(f"O{label} break/continue outside its loop", SourceLocation(self.source, i + 1, 1))
        return max(inner)


def _close(stack: list[_Open], expect: str, kw: str, label: str, where: SourceLocation) -> _Open:
    """Pop the construct an O-word closes (``endsub`` closes ``sub``, ...), checking label and kind."""
    if not stack or stack[-1][0] != expect or stack[-1][1] != label:
        raise InputError(f"O{label} {kw} without a matching O{label} {expect}", where)
    return stack.pop()
