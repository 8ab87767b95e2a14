"""Where a G-code program stopped being read, and what it left unread.

A program ends at M2/M30, at a ``%`` line that closes it (LinuxCNC: the first non-blank line is a
lone ``%`` and a later lone ``%`` ends the program), or at the end of the text. Lines after the end
are not executed, as in LinuxCNC; because a stray end can silently drop most of a program, the
interpreter warns whenever lines with words remain unread, naming the line where reading stopped
and how many lines were left (and how many of those have axis words, i.e. would probably move).
"""
from __future__ import annotations

import re

__all__ = ["no_moves_warning", "stop_warning", "unread_lines"]

# comments and the rest of a line after ";"
_COMMENTS = re.compile(r"\([^)]*\)?|;.*")
# an axis word: the letter, then a number, a parameter or an expression
_AXIS_WORD = re.compile(r"[xyzabcXYZABC]\s*[-+.0-9#\[]")


def unread_lines(lines: list[str], after: int) -> tuple[int, int]:
    """(lines with words, those with axis words) among ``lines[after:]``; blank and comment-only
    lines, block-deleted (``/``) lines and lone ``%`` lines are not counted."""
    words = axes = 0
    for raw in lines[after:]:
        s = raw.strip()
        if not s or s == "%" or s[0] == "/":
            continue
        body = _COMMENTS.sub("", s).strip()
        if not body:
            continue
        words += 1
        if _AXIS_WORD.search(body):
            axes += 1
    return words, axes


def stop_warning(where: str, reason: str, lines: list[str], after: int, furthest_line: int) -> str | None:
    """The warning for a program that ``reason`` ended at ``where`` (``file:line``), when lines with
    words follow ``after`` (0-based index of the first line not read); ``None`` when none do.
    ``furthest_line`` (1-based) is the last line executed, when it lies beyond the stopping line (an
    M2 in a subroutine)."""
    words, axes = unread_lines(lines, after)
    if not words:
        return None
    beyond = f" after line {furthest_line}" if furthest_line else ""
    return (f"{where}: {reason} ends the program here: {words:,} line{'s' if words != 1 else ''} with words"
            f"{beyond} {'are' if words != 1 else 'is'} not read ({axes:,} with axis words)")


def no_moves_warning(source: str, stop: tuple[int, str] | None, zero_length_only: bool, lines: list[str]) -> str:
    """Why a program yields no moves: ``stop`` is the (line, what) that ended it, when something did."""
    if stop is not None:
        line, what = stop
        return f"{source}: no moves: {what} at line {line} ends the program before any move"
    if zero_length_only:
        return f"{source}: no moves: every move has zero length"
    if not any(raw.strip() for raw in lines):
        return f"{source}: no moves: the file is empty"
    return f"{source}: no moves: no block of the program moves the tool"
