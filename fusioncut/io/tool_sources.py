"""Which definition of each T number a job uses, when the job, its tool library and the program
each may describe it.

Sources, by precedence: the job's ``tools`` always win; then ``tool_source`` (a job field,
``"library"`` by default, or ``"program"``); then the other one. The program's definitions are what
the readers found in the toolpath files (G-code tool comments, APT ``CUTTER``, Fusion JSON sections;
:attr:`Toolpath.program_tools` when a G-code reader was given tools that replace its comments).
A library tool the library refused (a tap, a thread mill) is an error when that source wins.

For every T number the program uses, each definition that was not chosen (but the library's when
the job's own tool overrides it, which the job does on purpose) is compared with the
chosen one by the radius of their cutting parts over their common flute length
(:func:`fusioncut.model.tools.cutting_shape_difference`, tolerance 0.0005 mm: what rounding sizes to
3 decimals accounts for); when they differ by more, a warning names both sources (``file:line`` of
the tool comment, library file and entry, the job's tools), what each says, and which is used.
Moves without a T word use the only tool defined.
"""
from __future__ import annotations

import logging
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from fusioncut.errors import InputError, ToolDefinitionError
from fusioncut.model.moves import Move, Toolpath
from fusioncut.model.tools import MillingTool, cutting_shape_difference, describe

if TYPE_CHECKING:
    from fusioncut.io.job import ToolSpec
    from fusioncut.io.tool_library import ToolLibrary

__all__ = ["ToolSource", "job_tools", "library_disagreements", "program_first_tools", "resolve_tools"]

log = logging.getLogger("fusioncut.run")

ToolSource = Literal["library", "program"]


def job_tools(specs: Iterable[ToolSpec], library: ToolLibrary | None, where: Path) -> dict[int, MillingTool]:
    """The job's own tools by number; library picks (``{"number": 2, "library": {"name": ...}}``)
    are looked up in ``library`` and renumbered. Errors are located at ``where`` (the job's folder,
    all the runner knows) and name ``tools[i]``."""
    out: dict[int, MillingTool] = {}
    for i, spec in enumerate(specs):
        if spec.number in out:
            raise InputError(f"tools: T{spec.number} is defined twice", where)
        try:
            out[spec.number] = spec.build(library)
        except ToolDefinitionError as e:
            raise ToolDefinitionError(f"tools[{i}] (T{spec.number}): {e}", where) from None
    return out


_OWNER = {"job": "the job's", "library": "the tool library's", "program": "the program's"}


def _named(kind: str, tool: MillingTool, n: int, library: ToolLibrary | None, first_use: Move) -> str:
    if kind == "job":
        return f"the job's tools ({tool.source})" if tool.source else "the job's tools"
    if kind == "library":
        entry = tool.source or (f"{library.source}: T{n}" if library is not None else f"T{n}")
        return f"the tool library ({entry})"
    return f"the program ({tool.source})" if tool.source else f"the program (first used at {first_use.source})"


def _disagreement(n: int, m: Move, chosen: tuple[str, MillingTool], other: tuple[str, MillingTool],
                  library: ToolLibrary | None, hint: str) -> list[str]:
    """The warning (a list of 0 or 1) when ``other`` describes T``n`` (first used by ``m``) with
    another cutting part than the ``chosen`` definition; each is (source kind, tool)."""
    gap = cutting_shape_difference(chosen[1], other[1])
    if gap == 0:
        return []
    return [f"{m.source}: T{n}: {_named(*chosen, n, library, m)} says {describe(chosen[1])}, "
            f"{_named(*other, n, library, m)} says {describe(other[1])} (cutting parts up to "
            f"{gap:.4g} mm apart in radius); using {_OWNER[chosen[0]]}{hint}"]


def library_disagreements(tp: Toolpath, library: ToolLibrary) -> list[str]:
    """For a toolpath read with ``library``'s tools (as ``fusioncut inspect --tools`` does): a
    warning for every T number the moves use whose library tool disagrees with the program's own."""
    program = tp.program_tools if tp.program_tools is not None else {}
    out: list[str] = []
    seen: set[int] = set()
    for m in tp.moves:
        n = m.tool
        if n is None or n in seen:
            continue
        seen.add(n)
        if n in library and n in program:
            out += _disagreement(n, m, ("library", library[n]), ("program", program[n]), library,
                                 "; a job chooses with 'tool_source' or its 'tools'")
    return out


def resolve_tools(moves: list[Move], job: dict[int, MillingTool], library: ToolLibrary | None,
                  program: dict[int, MillingTool], tool_source: ToolSource = "library",
                  ) -> tuple[dict[int, MillingTool], MillingTool | None, list[str]]:
    """The tool of every T number the moves use, the tool for moves without a T word (``None`` when
    every move has one) and the warnings about sources that disagree (see the module doc).

    Raises :class:`InputError` naming the first move that uses an undefined T number (or a move
    without a T word when not exactly one tool is defined), and the library's
    :class:`ToolDefinitionError` when a refused library tool wins.
    """
    first_use: dict[int, Move] = {}
    untooled: Move | None = None
    for m in moves:
        if m.tool is None:
            untooled = untooled or m
        elif m.tool not in first_use:
            first_use[m.tool] = m
    order = ("job", "library", "program") if tool_source == "library" else ("job", "program", "library")
    tools: dict[int, MillingTool] = {}
    warnings: list[str] = []
    for n, m in first_use.items():
        found: list[tuple[str, MillingTool]] = []
        for kind in order:
            if kind == "job" and n in job:
                found.append((kind, job[n]))
            elif kind == "program" and n in program:
                found.append((kind, program[n]))
            elif kind == "library" and library is not None and (n in library or n in library.refused):
                if n in library:
                    found.append((kind, library[n]))
                elif not found:  # the library wins with a tool it could not model: say why
                    try:
                        library.require(n)
                    except ToolDefinitionError as e:
                        raise ToolDefinitionError(f"the program uses T{n} here, but {e}", m.source) from None
        if not found:
            raise InputError(f"no tool definition for T{n} (give it in the job's 'tools' or a 'tool_library')",
                             m.source)
        (kind, chosen), others = found[0], found[1:]
        tools[n] = chosen
        for other_kind, other in others:
            if kind == "job" and other_kind == "library":
                continue  # the job overrides its own library on purpose; the program may still disagree
            warnings += _disagreement(n, m, (kind, chosen), (other_kind, other), library,
                                      "" if kind == "job" else
                                      f"; the job's tool_source {tool_source!r} chose it (set 'tool_source' or "
                                      f"give T{n} in the job's 'tools' to choose)")
    default_tool = None
    if untooled is not None:
        lower, higher = (program, library or {}) if tool_source == "library" else (library or {}, program)
        defined = {**lower, **higher, **job}
        if len(defined) != 1:
            raise InputError(
                f"this move has no tool: the program selects none (no T word) and {len(defined)} tools are "
                "defined; select one in the program or define exactly one tool in the job", untooled.source)
        default_tool = next(iter(defined.values()))
        log.warning("%s: moves without a T word use the only tool defined, %s", untooled.source, default_tool.label)
    return tools, default_tool, warnings


def program_first_tools(tp: Toolpath, given: dict[int, MillingTool], job: dict[int, MillingTool],
                        tool_source: ToolSource) -> dict[int, MillingTool] | None:
    """With ``tool_source`` ``"program"``: the tools to read a G-code file ``tp`` again with, so that
    cutter compensation and ``#5410`` use the radius of the program's own tool where the library's
    (in ``given``) has another; ``None`` when the first reading stands."""
    if tool_source != "program" or tp.program_tools is None:
        return None
    swap = {n: t for n, t in tp.program_tools.items()
            if n not in job and n in given and abs(given[n].radius - t.radius) > 5e-4}
    return {**given, **swap} if swap else None
