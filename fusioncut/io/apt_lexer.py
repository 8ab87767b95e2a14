"""Lexing of APT / CLSF text (ISO 4343): ``$$`` comments, ``$`` continuation lines, and records
``MAJOR/arg, arg, ...`` or a bare ``MAJOR`` word, with the line each starts on (1-based)."""
from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass

__all__ = ["NUMBER", "Record", "parse_record", "records"]


@dataclass(frozen=True)
class Record:
    line: int  # first physical line of the logical record
    major: str  # upper case, inner blanks collapsed: "GOTO", "TOOL PATH"
    args: tuple[str, ...]
    rest: str  # raw text after the slash (for PPRINT and messages)


def _strip_comment(line: str) -> str:
    """The line without its ``$$`` comment (a ``$$`` inside quotes is text)."""
    quoted = False
    i = 0
    while i < len(line):
        ch = line[i]
        if ch == "'":
            quoted = not quoted
        elif ch == "$" and not quoted and line.startswith("$$", i):
            return line[:i]
        i += 1
    return line


def _split_args(rest: str) -> tuple[str, ...]:
    out, cur, quoted = [], [], False
    for ch in rest:
        if ch == "'":
            quoted = not quoted
        if ch == "," and not quoted:
            out.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
    out.append("".join(cur).strip())
    return tuple(out)


def records(text: str) -> Iterator[Record]:
    pending: list[str] = []
    first_line = 0
    for lineno, raw in enumerate(text.splitlines(), start=1):
        body = _strip_comment(raw).rstrip()
        if not pending:
            first_line = lineno
        if body.endswith("$"):  # continuation: the record goes on on the next line
            pending.append(body[:-1])
            continue
        pending.append(body)
        logical = " ".join(p.strip() for p in pending).strip()
        pending = []
        if logical:
            yield parse_record(logical, first_line)
    if pending:
        logical = " ".join(p.strip() for p in pending).strip()
        if logical:
            yield parse_record(logical, first_line)


def parse_record(text: str, line: int) -> Record:
    if "/" in text:
        major, rest = text.split("/", 1)
        args = _split_args(rest)
    else:
        major, rest, args = text, "", ()
    major = " ".join(major.split()).upper()
    return Record(line, major, args, rest)


NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eEdD][+-]?\d+)?")
