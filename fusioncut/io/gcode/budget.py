"""The G-code interpreter's work budget: how many moves a program may expand to.

A few bytes of G-code can ask for unbounded work: ``o100 repeat [1000000]`` around two moves, or an
arc of ``P100000`` turns that everything downstream (CL segments, the engine) works through turn by
turn. The interpreter refuses such programs with a :class:`~fusioncut.errors.JobTooLarge` naming
``file:line`` and the count, before the work is done where the count is known in advance:

* the moves a block expands to (canned cycle repeats and pecks, spline chords, an arc's turns) are
  checked before the block emits any;
* a ``repeat`` loop is checked once its first pass has run: that pass's moves and blocks times the
  passes still to come must fit (unless the body can leave the loop early: ``break``, ``return``,
  M2/M30, which only the running count can judge);
* every emitted move and executed block is counted, so ``while`` loops, whose pass count is unknown,
  stop at the limit itself.

Units: one emitted move counts 1 and each extra turn of an arc (``P`` - 1) counts 1 more. A program
may execute ``BLOCKS_PER_MOVE`` blocks per move of its budget plus ``MIN_BLOCKS`` (O-word loops and
subroutines execute blocks that move nothing; a block costs about what a move costs to read, so both
limits bound the reading time alike). ``max_moves=None`` (or 0) lifts both limits.
"""
from __future__ import annotations

from typing import Iterable

from fusioncut.errors import JobTooLarge, SourceLocation
from fusioncut.io.gcode.lexer import Block

__all__ = ["BLOCKS_PER_MOVE", "DEFAULT_MAX_MOVES", "MAX_ARC_TURNS", "MIN_BLOCKS", "MoveBudget", "may_leave_early"]

DEFAULT_MAX_MOVES = 1_000_000
# blocks executed per move of the budget, plus a floor for small budgets: 2.1 million blocks at the
# default. Posted programs execute about 1 block per move; LinuxCNC's recursive flowsnake example
# executes 15 per move, 2,938 blocks in all, which the floor admits under any budget
BLOCKS_PER_MOVE = 2
MIN_BLOCKS = 100_000
# turns of one G2/G3 (its P word): downstream a turn is flattened into many short pieces (a 5 mm
# radius within 0.001 mm takes 157 chords), so a turn costs what a hundred short moves cost
MAX_ARC_TURNS = 1000


class MoveBudget:
    """The limits of one interpreter run and the arc turns spent of them so far.

    The interpreter holds the count of moves it emitted and of blocks it executed; the expanded size
    is those moves plus ``extra_turns``. It asks :meth:`room` before emitting moves and compares the
    blocks with ``max_blocks``.
    """

    __slots__ = ("max_moves", "max_blocks", "extra_turns")

    def __init__(self, max_moves: int | None):
        if max_moves is not None and (not isinstance(max_moves, int) or max_moves < 0):
            raise ValueError(f"max_moves must be a whole number >= 0 or None, not {max_moves!r}")
        self.max_moves = max_moves or None
        self.max_blocks = self.max_moves * BLOCKS_PER_MOVE + MIN_BLOCKS if self.max_moves else None
        self.extra_turns = 0

    def room(self, moves: int) -> int:
        """How many moves the program may still emit after ``moves`` emitted ones (huge if unlimited)."""
        if self.max_moves is None:
            return 1 << 62
        return self.max_moves - self.extra_turns - moves

    def refuse(self, what: str, where: SourceLocation) -> JobTooLarge:
        return JobTooLarge(f"the program expands to more than {self.max_moves:,} moves ({what}); "
                          "raise max_moves to allow it", where)

    def check(self, moves: int, n: int, what: str, where: SourceLocation) -> None:
        """Refuse a block about to add ``n`` to the ``moves`` spent so far if that passes the limit."""
        if n > self.room(moves):
            raise self.refuse(what, where)

    def check_blocks(self, executed: int, where: SourceLocation) -> None:
        if self.max_blocks is not None and executed > self.max_blocks:
            raise JobTooLarge(f"the program executes more than {self.max_blocks:,} blocks (an endless "
                             "O-word loop?); raise max_moves to allow it", where)

    def check_repeat(self, spent: tuple[int, int], first_pass: tuple[int, int], passes_left: int,
                     passes: int, where: SourceLocation) -> None:
        """A ``repeat`` loop of ``passes`` whose first pass made ``first_pass`` (moves, blocks), with
        ``spent`` (moves, blocks) so far: refuse it if the passes left would pass a limit."""
        if self.max_moves is None:
            return
        moves, blocks = first_pass
        if moves * passes_left > self.room(spent[0]):
            raise self.refuse(f"a repeat loop of {passes:,} × {moves:,}", where)
        assert self.max_blocks is not None
        if spent[1] + blocks * passes_left > self.max_blocks:
            raise JobTooLarge(f"the program executes more than {self.max_blocks:,} blocks (a repeat loop "
                             f"of {passes:,} × {blocks:,}); raise max_moves to allow it", where)


def may_leave_early(body: Iterable[Block]) -> bool:
    """True when a loop body's blocks hold a way out before its passes are done: ``break`` or
    ``return``, or an M code that is (or may evaluate to) M2/M30."""
    for b in body:
        if b.oword is not None and b.oword.keyword in ("break", "return"):
            return True
        if any(not isinstance(v, float) or v in (2.0, 30.0) for v, _ in b.m):
            return True
    return False
