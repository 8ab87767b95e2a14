"""RS274/NGC parameters: numbered ``#1``-``#5601``, named locals ``#<name>`` (one scope per subroutine
call) and globals ``#<_name>``, LinuxCNC's read-only predefined globals (``#<_x>``, ``#<_metric>``, ...),
and the subroutine call frames that save ``#1``-``#30``.

:class:`Parameters` is the :class:`~.lexer.ParameterStore` compiled expressions read. Values are in
program units (the units in effect now); parameters that mirror machine state (offsets 5161-5426,
the position ``#<_x>``) are read from the :class:`~.machine.Machine` when asked.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from fusioncut.errors import InputError, SourceLocation
from fusioncut.io.gcode.lexer import MAX_PARAMETER, ParamRef, param_index, evaluate
from fusioncut.io.gcode.machine import Machine
from fusioncut.io.gcode.modal import COORD_SYSTEM_CODES
from fusioncut.io.gcode.offsets import set_system_param, system_param
from fusioncut.model.moves import ArcPlane

__all__ = ["Frame", "Parameters"]

MAX_CALL_DEPTH = 10  # LinuxCNC's INTERP_SUB_ROUTINE_LEVELS
MAX_CALL_ARGUMENTS = 30
_PLANE_NUMBERS = {ArcPlane.XY: 170.0, ArcPlane.ZX: 180.0, ArcPlane.YZ: 190.0}
_AXIS_NAMES = {"_x": 0, "_y": 1, "_z": 2, "_a": 3, "_b": 4, "_c": 5}


@dataclass
class Frame:
    """A subroutine call (or the main program, at the bottom of the stack)."""

    label: str
    return_index: int
    saved: list[float]
    locals: dict[str, float] = field(default_factory=dict)
    repeats: dict[int, int] = field(default_factory=dict)
    # repeat line -> (moves, blocks) spent when its first pass began; checked when that pass ends
    first_pass: dict[int, tuple[int, int]] = field(default_factory=dict)


class Parameters:
    """The parameters of one run, over the machine whose state some of them mirror."""

    def __init__(self, machine: Machine):
        self.machine = machine
        self.numbered = [0.0] * (MAX_PARAMETER + 1)
        self.globals: dict[str, float] = {}
        self.frames: list[Frame] = [Frame("", -1, [])]

    # ------------------------------------------------------------------ ParameterStore
    def get_numbered(self, index: int, where: SourceLocation) -> float:
        if 5161 <= index <= 5428:
            v = system_param(self.machine, index)
            if v is not None:
                return v
        return self.numbered[index]

    def get_named(self, name: str, where: SourceLocation) -> float:
        if name.startswith("_"):
            if name in self.globals:
                return self.globals[name]
            v = self.predefined(name)
            if v is not None:
                return v
        else:
            loc = self.frames[-1].locals
            if name in loc:
                return loc[name]
        raise InputError(f"named parameter #<{name}> is not defined", where)

    def has_named(self, name: str) -> bool:
        if name.startswith("_"):
            return name in self.globals or self.predefined(name) is not None
        return name in self.frames[-1].locals

    # ------------------------------------------------------------------ setting
    def assign(self, ref: ParamRef, value: float, where: SourceLocation) -> None:
        """``#ref = value`` (after the whole line was evaluated)."""
        if ref.name is not None:
            name = ref.name
            if name.startswith("_"):
                if self.predefined(name) is not None and name not in ("_value", "_value_returned"):
                    raise InputError(f"#<{name}> is read-only", where)
                self.globals[name] = value
            else:
                self.frames[-1].locals[name] = value
            return
        if ref.number is not None:
            n = ref.number
        else:
            assert ref.index is not None
            n = param_index(evaluate(ref.index, self), where)
        if 5161 <= n <= 5428 and set_system_param(self.machine, n, value):
            return
        self.numbered[n] = value

    # ------------------------------------------------------------------ subroutine calls
    def call(self, label: str, return_index: int, args: list[float], where: SourceLocation) -> None:
        """Enter subroutine ``label``: ``#1``-``#30`` take the arguments (0 for missing ones)."""
        if len(self.frames) > MAX_CALL_DEPTH:
            raise InputError(f"subroutine calls nested deeper than {MAX_CALL_DEPTH}", where)
        if len(args) > MAX_CALL_ARGUMENTS:
            raise InputError(f"more than {MAX_CALL_ARGUMENTS} subroutine arguments", where)
        frame = Frame(label, return_index, self.numbered[1:31])
        for k in range(MAX_CALL_ARGUMENTS):
            self.numbered[1 + k] = args[k] if k < len(args) else 0.0
        self.frames.append(frame)
        self.globals["_value_returned"] = 0.0

    def leave(self, args: list[float]) -> int:
        """Leave the innermost subroutine (``endsub``/``return``, with an optional value); returns the
        line index to go on at."""
        frame = self.frames.pop()
        self.numbered[1:31] = frame.saved
        if args:
            self.globals["_value"] = args[0]
            self.globals["_value_returned"] = 1.0
        return frame.return_index

    # ------------------------------------------------------------------ predefined
    def predefined(self, name: str) -> float | None:
        """LinuxCNC's read-only named parameter ``name`` (program units), or ``None``."""
        m = self.machine
        axis = _AXIS_NAMES.get(name)
        if axis is not None:
            return m.program_pos(axis) / (m.scale() if axis < 3 else 1.0)
        table = {
            "_metric": 0.0 if m.inch else 1.0,
            "_imperial": 1.0 if m.inch else 0.0,
            "_absolute": 1.0 if m.absolute else 0.0,
            "_incremental": 0.0 if m.absolute else 1.0,
            "_feed": m.feed or 0.0,
            "_rpm": m.rpm or 0.0,
            "_current_tool": float(m.tool or 0),
            "_selected_tool": float(m.prepared_tool if m.prepared_tool is not None else -1),
            "_line": float(m.line),
            "_coord_system": float(COORD_SYSTEM_CODES[m.cs - 1]),
            "_plane": _PLANE_NUMBERS[m.plane],
            "_motion_mode": float(m.motion if m.motion is not None else 800),
            "_spindle_on": 0.0 if m.spindle == "off" else 1.0,
            "_spindle_cw": 1.0 if m.spindle == "cw" else 0.0,
            "_mist": 1.0 if "mist" in m.coolant else 0.0,
            "_flood": 1.0 if "flood" in m.coolant else 0.0,
            "_call_level": float(len(self.frames) - 1),
            "_value": 0.0,
            "_value_returned": 0.0,
            "_retract_r_plane": 0.0 if m.retract_old_z else 1.0,
            "_retract_old_z": 1.0 if m.retract_old_z else 0.0,
            "_ijk_absolute_mode": 1.0 if m.arc_absolute else 0.0,
        }
        return table.get(name)
