"""Rewrite the feed rates of a G-code program, changing nothing but ``F`` words.

:func:`rewrite_feeds` takes the program text and, per 1-based source line, the feed (mm/min) the
feed moves of that line should run at (e.g. :meth:`fusioncut.analysis.feed.FeedAdvice.line_feeds`),
and returns a program in which only ``F`` words differ: an ``F`` word's number is replaced, or an
``F`` word is added at the end of a line's code (before its comment). Every other character - other
words, their order and spelling, comments, white space, line numbers, line endings - is kept.

How the feeds are written
-------------------------
* **Modal F.** ``F`` is modal: a line without one runs at the last ``F``. The rewriter follows the
  program as the interpreter runs it (:class:`~fusioncut.io.gcode.interpreter.GCodeInterpreter`: subroutines,
  loops and canned cycles included) and gives a line an explicit ``F`` exactly when the feed in effect
  in the *new* program differs from the one that line needs: its advised feed, or else its original
  feed. So after a changed line, the first following line that relied on the original modal ``F``
  gets that ``F`` back, and no line gets a redundant one.
* **Units.** Advised feeds are mm/min; they are written in the units in force at the line: G21
  mm/min, G20 inch/min (``/ 25.4``), G95 per revolution (``/ S``, per rev in program units), G93
  inverse time (``F`` scaled by advised / programmed feed, i.e. ``1 / minutes`` for the move).
* **Number format** follows the post: as many decimals as the program's longest ``F`` number (one
  if it has none), trailing zeros trimmed when the post trims them (``F1000``, ``F333.3``) and kept
  when it pads (``F1000.0``), a trailing point when it writes ``F1000.``. Advised numbers are rounded
  **down** to that resolution, so a feed chosen to respect a force limit never exceeds it; restored
  original feeds are written with the program's own text, so they read back to the same number.
* **Case and spacing** follow the line (``F`` after upper-case words, ``f`` after lower-case ones; a
  space before the inserted word when the line separates its words by spaces).
* **Tapping** (G84, G74) keeps its programmed feed: the feed of a tapping cycle must match the
  thread pitch times the spindle speed, so advice for such a line is ignored and reported.
* **Expressions.** An ``F[...]`` or ``F#<...>`` value that has to change is replaced by a number.
* **Lines that run several times** (subroutines, loops) can carry only one ``F``: when they would
  need different ones (e.g. G93 moves of different lengths, or advice that differs from the feed the
  line had on another pass), :class:`~fusioncut.errors.InputError` names the line.

Afterwards the new program is interpreted again and checked: same blocks executed, moves identical
except for their feed, each feed the one asked for. Anything else raises
:class:`~fusioncut.errors.InputError` naming ``file:line`` instead of writing a wrong program.
"""
from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

from fusioncut.errors import InputError, SourceLocation
from fusioncut.io.gcode.files import decode_gcode
from fusioncut.io.gcode.interpreter import ArcCenters, GCodeInterpreter
from fusioncut.io.gcode.lexer import Block, parse_line
from fusioncut.model.moves import Move
from fusioncut.model.tools import MillingTool
from fusioncut.model.units import length_scale

__all__ = ["RewriteResult", "rewrite_feeds", "rewrite_gcode_file"]

# motion codes (G code * 10) whose feed is tied to the thread pitch
_TAPPING = {840, 740}
# rounding down to the post's resolution tolerates this much float noise (in units of the last digit)
_FLOOR_SLACK = 1e-6


@dataclass(frozen=True)
class RewriteResult:
    """What :func:`rewrite_feeds` did.

    ``text`` is the new program. ``replaced`` and ``inserted`` are the 1-based lines whose ``F``
    number was replaced or that got a new ``F`` word (each line is in at most one of them);
    ``notes`` explain advice that was not applied (``file:line: ...``).
    """

    text: str
    replaced: tuple[int, ...]
    inserted: tuple[int, ...]
    notes: tuple[str, ...] = ()

    @property
    def changed_lines(self) -> tuple[int, ...]:
        return tuple(sorted(self.replaced + self.inserted))


# --------------------------------------------------------------------------------------------------
# tracing a program


@dataclass
class _Exec:
    """One executed block: its line, the F number in effect after it (program units, as the
    interpreter keeps it), the feed mode and units, spindle speed, motion code, whether the feed
    mode changed in it (which resets F), and the feed moves it made."""

    line: int
    feed: float | None
    mode: str
    inch: bool
    rpm: float | None
    motion: int | None
    reset: bool
    moves: list[Move]


def _trace(text: str, source: str, tools: Mapping[int, MillingTool] | None,
           arc_centers: ArcCenters) -> tuple[list[_Exec], list[Move]]:
    interp = GCodeInterpreter(text, source=source, tools=tools, strict=False, arc_centers=arc_centers)
    m = interp.machine
    execs: list[_Exec] = []
    last_of_line: dict[int, _Exec] = {}
    mode = m.feed_mode
    prev_line = None
    for line, moves in interp:
        # the step that releases moves held by cutter compensation at the end of the text is not
        # a block of its own: it repeats the last line number and ends the program
        finish = interp.ended and line == prev_line
        if not finish:
            e = _Exec(line, m.feed, m.feed_mode, m.inch, m.rpm, m.motion, m.feed_mode != mode, [])
            execs.append(e)
            last_of_line[line] = e
        mode = m.feed_mode
        prev_line = line
        # with cutter compensation a move can come out one block late: it belongs to the latest
        # execution of the line it was programmed on
        for mv in moves:
            owner = last_of_line.get(mv.source.line)
            if owner is not None and not mv.is_rapid:
                owner.moves.append(mv)
    return execs, interp.moves


# --------------------------------------------------------------------------------------------------
# F words in the text


@dataclass(frozen=True)
class _FWord:
    """An F word of a line: the value's character span ``[start, end)`` in the line (0-based) and
    its text; ``literal`` when it is a plain number."""

    start: int
    end: int
    text: str
    literal: bool


def _code_end(body: str) -> int:
    """Index just past the last character of code (not comment, not white space) in ``body``."""
    end = 0
    in_paren = False
    for i, ch in enumerate(body):
        if in_paren:
            if ch == ")":
                in_paren = False
            continue
        if ch == "(":
            in_paren = True
        elif ch == ";":
            break
        elif not ch.isspace():
            end = i + 1
    return end


def _word_columns(block: Block) -> list[int]:
    cols = [c for _, c in block.g] + [c for _, c in block.m] + [c for _, c in block.words.values()]
    cols += [c for _, _, c in block.assignments]
    return sorted(cols)


def _f_word(block: Block, body: str) -> _FWord | None:
    if "f" not in block.words:
        return None
    col = block.words["f"][1]
    start = col  # 0-based index just after the letter
    nxt = [c - 1 for c in _word_columns(block) if c > col]
    stop = min(nxt) if nxt else len(body)
    for mark in "(;":
        k = body.find(mark, start, stop)
        if k >= 0:
            stop = k
    value = body[start:stop]
    lead = len(value) - len(value.lstrip())
    value = value.strip()
    start += lead
    literal = value.replace(" ", "").replace("\t", "").lstrip("+-").replace(".", "", 1).isdigit()
    return _FWord(start, start + len(value), value, literal)


@dataclass(frozen=True)
class _Style:
    decimals: int
    trim: bool  # trailing zeros after the point dropped
    trailing_dot: bool  # whole numbers written "1000."
    spaced: bool  # words separated by spaces
    upper: bool


def _detect_style(texts: list[str], bodies: list[str]) -> _Style:
    # a program without any F number gets one decimal, trimmed: the common post style
    decimals, trim, dot = (0, True, False) if texts else (1, True, False)
    for t in texts:
        t = t.replace(" ", "").replace("\t", "").lstrip("+-")
        if "." in t:
            frac = t.split(".", 1)[1]
            if not frac:
                dot = True
                continue
            decimals = max(decimals, len(frac))
            if frac.endswith("0"):
                trim = False
    spaced_votes = compact_votes = upper_votes = lower_votes = 0
    for b in bodies[:2000]:
        code = b[:_code_end(b)]
        if "(" in code:
            continue
        letters = [c for c in code if c.isalpha()]
        if len(letters) >= 2:
            if " " in code.strip() or "\t" in code.strip():
                spaced_votes += 1
            else:
                compact_votes += 1
        upper_votes += sum(c.isupper() for c in letters)
        lower_votes += sum(c.islower() for c in letters)
    return _Style(min(decimals, 6), trim, dot, spaced_votes >= compact_votes, upper_votes >= lower_votes)


def _format(value: float, style: _Style) -> str:
    d = style.decimals
    s = f"{value:.{d}f}"
    if d and style.trim:
        s = s.rstrip("0").rstrip(".")
    if "." not in s and style.trailing_dot:
        s += "."
    return s


def _format_down(value: float, style: _Style) -> str:
    """``value`` rounded down to the style's resolution (never up: feeds chosen to stay under a limit)."""
    scale = 10 ** style.decimals
    return _format(math.floor(value * scale + _FLOOR_SLACK) / scale, style)


def _format_exact(value: float, style: _Style, known: Mapping[float, str]) -> str:
    """A text that reads back as exactly ``value``: the program's own spelling when it has one."""
    if value in known:
        return known[value]
    for d in range(style.decimals, 16):
        s = _format(value, replace(style, decimals=d))
        if float(s.rstrip(".")) == value:
            return s
    return repr(value)


# --------------------------------------------------------------------------------------------------
# the rewriter


def _same_motion(a: Move, b: Move) -> bool:
    # columns may shift on a line whose F number got longer or shorter: compare file and line only
    def norm(m: Move) -> Move:
        return replace(m, feed=None, source=SourceLocation(m.source.file, m.source.line, 0))

    return norm(a) == norm(b)


def rewrite_feeds(
    text: str,
    feeds: Mapping[int, float],
    *,
    source: str = "<memory>",
    tools: Mapping[int, MillingTool] | None = None,
    arc_centers: ArcCenters = "auto",
) -> RewriteResult:
    """The program ``text`` with the feed moves of each line in ``feeds`` (1-based line -> mm/min)
    running at that feed, and every other feed move at its original feed; only ``F`` words change.

    See the module docstring for the rules. ``source`` names the program in messages; ``tools`` and
    ``arc_centers`` are passed to the interpreter as :func:`fusioncut.io.gcode.read_gcode` takes them.
    Lines of ``feeds`` that make no feed move are left alone and reported in ``notes``.
    """
    for line, v in feeds.items():
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError(f"advised feed must be a finite number > 0 mm/min, got {v!r}",
                             SourceLocation(source, int(line)))
    lines = text.splitlines(keepends=True)
    bodies = [ln.splitlines()[0] if ln.splitlines() else "" for ln in lines]
    # splitlines() of the interpreter and ours must agree on line numbers
    if len(bodies) != len(text.splitlines()):  # pragma: no cover - the same function on the same text
        raise InputError("line structure of the program is ambiguous", source)

    execs, old_moves = _trace(text, source, tools, arc_centers)

    fwords: dict[int, _FWord] = {}
    for e in execs:
        if e.line not in fwords and 1 <= e.line <= len(bodies):
            block = parse_line(bodies[e.line - 1], e.line, source)
            fw = _f_word(block, bodies[e.line - 1])
            if fw is not None:
                fwords[e.line] = fw
    literal_texts = [fw.text for fw in fwords.values() if fw.literal]
    style = _detect_style(literal_texts, bodies)
    known: dict[float, str] = {}
    for t in literal_texts:
        known.setdefault(float(t.replace(" ", "").replace("\t", "")), t)

    notes: list[str] = []
    used_lines: set[int] = set()

    # what F number each execution with feed moves needs, as (text, value)
    required: list[tuple[str, float] | None] = []
    for e in execs:
        if not e.moves:
            required.append(None)
            continue
        want = feeds.get(e.line)
        where = SourceLocation(source, e.line)
        if want is not None:
            used_lines.add(e.line)
        if want is not None and e.motion in _TAPPING:
            notes.append(f"{where}: tapping cycle: feed kept (it must match the thread pitch)")
            want = None
        if want is None:
            required.append(None if e.feed is None else (_format_exact(e.feed, style, known), e.feed))
            continue
        scale = length_scale(e.inch)
        if e.mode == "units_per_minute":
            number = want / scale
        elif e.mode == "units_per_revolution":
            if not e.rpm:
                raise InputError("feed per revolution (G95) with zero spindle speed: cannot convert the "
                                 "advised feed", where)
            number = want / (scale * e.rpm)
        else:  # inverse time: F is 1/minutes of the move, feed = F * length
            moving = [m for m in e.moves if m.feed]
            if not moving or not e.feed:
                raise InputError("inverse time (G93) move without a feed: cannot scale it", where)
            number = min(e.feed * want / m.feed for m in moving)  # type: ignore[operator]
        s = _format_down(number, style)
        if float(s.rstrip(".")) <= 0:
            raise InputError(f"advised feed {want:g} mm/min is below the program's F resolution", where)
        required.append((s, float(s.rstrip("."))))
    for line in sorted(set(feeds) - used_lines):
        notes.append(f"{SourceLocation(source, int(line))}: no feed move on this line; advice ignored")

    # Walk the executions in order with the feed in effect in the new program, giving a line an F
    # where that feed is not the one the line needs. A line gets at most one F text: when a line that
    # already ran gets one, earlier decisions may be stale, so the walk starts again (edits are only
    # ever added, so this ends).
    edits: dict[int, str] = {}

    def walk() -> bool:
        modal: float | None = None
        seen: set[int] = set()
        for e, req in zip(execs, required):
            if e.reset:
                modal = None
            if e.line in edits:
                modal = float(edits[e.line].rstrip("."))
            elif e.line in fwords:
                modal = e.feed
            if req is not None and modal != req[1]:
                if e.line in edits:
                    raise InputError(
                        f"this line runs more than once (subroutine or loop) and would need F{edits[e.line]} "
                        f"on one pass and F{req[0]} on another; it cannot carry both", SourceLocation(source, e.line))
                edits[e.line] = req[0]
                modal = req[1]
                if e.line in seen:
                    return False
            seen.add(e.line)
        return True

    while not walk():
        pass

    # edit the text
    replaced: list[int] = []
    inserted: list[int] = []
    new_lines = list(lines)
    for line, number in sorted(edits.items()):
        body = bodies[line - 1]
        ending = lines[line - 1][len(body):]
        fw = fwords.get(line)
        if fw is not None:
            if fw.literal and float(fw.text.replace(" ", "").replace("\t", "").rstrip(".")) == float(number.rstrip(".")):
                continue  # already the right number
            body = body[: fw.start] + number + body[fw.end:]
            replaced.append(line)
        else:
            p = _code_end(body)
            code = body[:p]
            letters = [c for c in code if c.isalpha()]
            upper = any(c.isupper() for c in letters) or (not any(c.islower() for c in letters) and style.upper)
            words = sum(1 for c in letters)
            stripped = code.strip()
            spaced = (" " in stripped or "\t" in stripped) if words >= 2 else style.spaced
            word = ("F" if upper else "f") + number
            body = body[:p] + (" " if spaced and p > 0 else "") + word + body[p:]
            inserted.append(line)
        new_lines[line - 1] = body + ending
    new_text = "".join(new_lines)

    _verify(old_moves, new_text, execs, required, source, tools, arc_centers)
    return RewriteResult(new_text, tuple(replaced), tuple(inserted), tuple(notes))


def _verify(old_moves: list[Move], new_text: str, execs: list[_Exec], required: list[tuple[str, float] | None],
            source: str, tools: Mapping[int, MillingTool] | None, arc_centers: ArcCenters) -> None:
    """Interpret the new program and check it does what the old one did, at the feeds asked for."""
    try:
        new_execs, new_moves = _trace(new_text, source, tools, arc_centers)
    except InputError as exc:  # pragma: no cover - would be a bug of the rewriter
        raise InputError(f"the rewritten program does not read back: {exc.reason}", exc.where) from None
    if [e.line for e in new_execs] != [e.line for e in execs] or len(new_moves) != len(old_moves):
        raise InputError("rewriting the feeds changed which blocks run (does the program read #<_feed>?)", source)
    for a, b in zip(old_moves, new_moves):
        if not _same_motion(a, b):
            raise InputError("rewriting the feed changed the motion of this line", a.source)
    for old, new, req in zip(execs, new_execs, required):
        where = SourceLocation(source, old.line)
        if req is not None and new.feed != req[1]:
            raise InputError(f"rewriting the feeds left F{new.feed} here instead of F{req[0]}", where)


def rewrite_gcode_file(
    path: str | os.PathLike[str],
    feeds: Mapping[int, float],
    out: str | os.PathLike[str],
    *,
    tools: Mapping[int, MillingTool] | None = None,
    arc_centers: ArcCenters = "auto",
) -> RewriteResult:
    """:func:`rewrite_feeds` on the file ``path``, writing the new program to ``out`` (same encoding
    and line endings; ``out`` must not be ``path``)."""
    p, o = Path(path), Path(out)
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise InputError(f"cannot read G-code file: {e.strerror}", p) from None
    if o.exists() and o.resolve() == p.resolve():
        raise InputError("the rewritten program must not overwrite the original", o)
    text, encoding = decode_gcode(raw)
    result = rewrite_feeds(text, feeds, source=str(path), tools=tools, arc_centers=arc_centers)
    o.parent.mkdir(parents=True, exist_ok=True)
    o.write_bytes(result.text.encode(encoding))
    return result
