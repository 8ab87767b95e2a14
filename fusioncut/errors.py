"""The project's own error types.

Every error a user can provoke with bad input is a :class:`FusionCutError`; the CLI prints its message
(which names the file, line and column, or the CL) instead of a traceback.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


class FusionCutError(Exception):
    """Base of every error FusionCut raises on purpose."""


@dataclass(frozen=True)
class SourceLocation:
    """Where something came from: a file, a 1-based line and column (0 when unknown)."""

    file: str = "<memory>"
    line: int = 0
    column: int = 0

    def __str__(self) -> str:
        parts = [str(self.file)]
        if self.line:
            parts.append(str(self.line))
            if self.column:
                parts.append(str(self.column))
        return ":".join(parts)


class InputError(FusionCutError):
    """Malformed or unsupported input; the message starts with ``file:line:column``."""

    def __init__(self, message: str, where: SourceLocation | str | Path | None = None):
        if where is not None and not isinstance(where, SourceLocation):
            where = SourceLocation(str(where))
        self.where = where
        self.reason = message
        super().__init__(f"{where}: {message}" if where is not None else message)


class JobTooLarge(InputError):
    """A job that would make more work than its budget allows (:class:`fusioncut.engines.sizing.Budget`,
    or a G-code program beyond its reader's ``max_moves``, :mod:`fusioncut.io.gcode_budget`), or an
    option below its lower bound: refused before anything is expanded."""


class ToolDefinitionError(InputError):
    """A tool whose geometry we cannot model (unknown type, impossible dimensions)."""


class GeometryError(FusionCutError):
    """A geometric operation failed (e.g. a Boolean); carries the CL index when known."""

    def __init__(self, message: str, cl_index: int | None = None):
        self.cl_index = cl_index
        self.reason = message
        super().__init__(f"CL {cl_index}: {message}" if cl_index is not None else message)


class BooleanFailure(GeometryError):
    """A 3D Boolean of the workpiece and a sweep failed, or gave a shape that fails its volume checks,
    with every fuzzy value and retry tried (the engine reports the CL FAILED and goes on)."""


class RegionCutFailure(GeometryError):
    """A 2D Boolean of a layered cell failed with every fuzzy value (the engine reports the CL FAILED)."""


class Degenerate(GeometryError):
    """The closed-form planar difference cannot decide a piece's side within its tolerance; the
    caller falls back to the kernel's General Fuse."""


class KernelFailure(GeometryError, RuntimeError):
    """The geometry kernel could not build a shape (a wire that does not close, a fuse or split that
    reports errors). A ``RuntimeError`` too, so callers that retry on kernel trouble catch it."""


class EngineStateError(FusionCutError, RuntimeError):
    """An engine was asked for a state it does not hold: a checkpoint at another CL than its state,
    a workpiece whose workers are closed, a batch out of order. A bug, not bad input."""
