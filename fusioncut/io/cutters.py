"""Cutters as CL-data readers state them, and the checks those readers share.

:func:`cutter_from_parameters` turns an APT/CLSF ``CUTTER`` statement (or a Fusion JSON tool) into one
of the model's tools, naming the family when the parameters match one and an
:class:`~fusioncut.model.tools.AptCutter` otherwise; :func:`make_tool` is the one place a reader builds
a :class:`~fusioncut.model.tools.MillingTool`, turning a refused geometry into a
:class:`~fusioncut.errors.ToolDefinitionError` naming the source line. :class:`ToolRegistry` keeps the
tools a program defines by number. All lengths in mm.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

from fusioncut.errors import InputError, SourceLocation, ToolDefinitionError
from fusioncut.model.tools import (
    AptCutter,
    AptParameters,
    BallEndMill,
    BullNoseEndMill,
    ChamferMill,
    FlatEndMill,
    MillingTool,
    SpindleDirection,
    TaperedEndMill,
)

__all__ = ["MAX_ABS_VALUE", "ToolRegistry", "check_tool_axis", "cutter_from_parameters", "finite", "make_tool"]

# Coordinates beyond a kilometre are garbage, not a machine; refusing them early keeps the arithmetic
# (squares, trigonometry) away from overflow.
MAX_ABS_VALUE = 1e6
_AXIS_TOL = 1e-6  # tolerance on unit tool-axis components
_DIM_TOL = 1e-6  # mm; dimensions closer than this are equal


def finite(value: float, what: str, where: SourceLocation) -> float:
    """``value`` if it is finite and within :data:`MAX_ABS_VALUE`, else an :class:`InputError`."""
    if not math.isfinite(value) or abs(value) > MAX_ABS_VALUE:
        raise InputError(f"{what} {value!r} is out of range", where)
    return value


def check_tool_axis(axis: tuple[float, float, float], where: SourceLocation) -> None:
    """Refuse any tool axis but +z: the engines model 3-axis milling only."""
    n = math.sqrt(sum(c * c for c in axis))
    if n < 1e-9:
        raise InputError(f"tool axis {axis} has zero length", where)
    u = tuple(c / n for c in axis)
    if abs(u[0]) > _AXIS_TOL or abs(u[1]) > _AXIS_TOL or u[2] < 1 - _AXIS_TOL:
        raise InputError(
            f"5-axis not supported yet: tool axis ({u[0]:.6g}, {u[1]:.6g}, {u[2]:.6g}) is not (0, 0, 1)", where
        )


def _same_geometry(a: MillingTool, b: MillingTool) -> bool:
    return replace(a, number=None, name="", spindle=SpindleDirection.CW) == replace(
        b, number=None, name="", spindle=SpindleDirection.CW
    )


class ToolRegistry:
    """Collects the tools a program uses, keyed by tool number.

    Programs that give no number, or reuse a number for a different cutter (NX numbers every tool 0
    unless told otherwise), get the next free number and a warning, so that one number never stands
    for two geometries.
    """

    def __init__(self, warn: Callable[[str], None]):
        self.tools: dict[int, MillingTool] = {}
        self._warn = warn
        self._spindle_warned: set[int] = set()

    def _free_number(self) -> int:
        n = 1
        while n in self.tools:
            n += 1
        return n

    def register(self, number: int | None, tool: MillingTool, defined_at: SourceLocation) -> int:
        """The number under which ``tool`` (defined at ``defined_at``, programmed as ``number``) is kept."""
        if number is None:
            n = self._free_number()
            self._warn(f"{defined_at}: the cutter has no tool number; numbered T{n}")
        elif number in self.tools and not _same_geometry(self.tools[number], tool):
            n = self._free_number()
            self._warn(f"{defined_at}: tool number {number} is reused for a different cutter; numbered T{n}")
        else:
            n = number
        if n not in self.tools:
            self.tools[n] = replace(tool, number=n)
        elif self.tools[n].spindle != tool.spindle and n not in self._spindle_warned:
            self._spindle_warned.add(n)
            self._warn(f"{defined_at}: T{n} runs in both spindle directions; modelled as {self.tools[n].spindle.value}")
        return n


def make_tool(cls: type[MillingTool], where: SourceLocation, context: str = "", **kwargs) -> MillingTool:
    """Build a model tool, re-raising its geometry errors at ``where`` (``context``, e.g. a JSON path,
    is put in front of the message)."""
    try:
        return cls(**kwargs)
    except ToolDefinitionError as e:
        raise ToolDefinitionError(f"{context}: {e.reason}" if context else e.reason, where) from e


def cutter_from_parameters(
    d: float,
    r: float,
    alpha: float,
    beta: float,
    h: float,
    where: SourceLocation,
    *,
    e: float | None = None,
    f: float | None = None,
    name: str = "",
) -> MillingTool:
    """The tool an APT-style parameter set describes (mm, degrees; see :mod:`fusioncut.model.tools`).

    The named families are recognised from ``(d, r, alpha, beta)`` alone, so ISO 4343 cutters and
    Fusion's APT post (which writes the *tip diameter* in the ``e`` slot) read the same:

    * alpha = beta = 0: flat (r = 0), ball (r = d/2) or bull-nose end mill;
    * r = alpha = 0, beta > 0: tapered end mill with tip diameter d, or, for d = 0, a pointed cone
      (V-bit) of half-angle beta reaching diameter ``2 h tan(beta)`` at the top of the flutes;
    * r = beta = 0, alpha > 0: pointed cone of half-angle ``90 - alpha`` up to diameter d;
    * anything else: an :class:`AptCutter`, whose ``(e, f)`` must be given and consistent, or - when
      they are not given (NX 5-parameter form) - follow from tangency of the corner with the bottom
      line through the tip and with the side line reaching diameter d at the corner.
    """
    if not (d >= 0 and r >= 0 and h > 0):
        raise ToolDefinitionError(f"cutter needs d >= 0, r >= 0 and a flute length > 0 (d={d}, r={r}, h={h})", where)
    common = {"flute_length": h, "name": name}
    if abs(alpha) < 1e-9 and abs(beta) < 1e-9:
        if d <= _DIM_TOL:
            raise ToolDefinitionError(f"cutter diameter must be > 0, got {d}", where)
        if r <= _DIM_TOL:
            return make_tool(FlatEndMill, where, diameter=d, **common)
        if abs(r - d / 2) <= _DIM_TOL * max(1.0, d):
            return make_tool(BallEndMill, where, diameter=d, **common)
        return make_tool(BullNoseEndMill, where, diameter=d, corner_radius=r, **common)
    if r <= _DIM_TOL and abs(alpha) < 1e-9 and 0 < beta < 90:
        if d > _DIM_TOL:
            return make_tool(TaperedEndMill, where, diameter=d, taper_angle=beta, **common)
        top = 2 * h * math.tan(math.radians(beta))
        return make_tool(ChamferMill, where, diameter=top, taper_angle=beta, **common)
    if r <= _DIM_TOL and abs(beta) < 1e-9 and 0 < alpha < 90:
        if d <= _DIM_TOL:
            raise ToolDefinitionError(f"cutter diameter must be > 0, got {d}", where)
        return make_tool(ChamferMill, where, diameter=d, taper_angle=90.0 - alpha, **common)
    if e is None or f is None:
        cb = math.cos(math.radians(beta))
        e = d / 2 - r * cb
        ca = math.cos(math.radians(alpha))
        if ca <= 0:
            raise ToolDefinitionError(f"cutter bottom angle {alpha} must be below 90 degrees", where)
        f = (r + e * math.sin(math.radians(alpha))) / ca
    try:
        params = AptParameters(d, r, e, f, alpha, beta, h)
    except ToolDefinitionError as err:
        raise ToolDefinitionError(
            f"{err.reason} (neither an ISO 4343 cutter nor one of the named families)", where
        ) from err
    return make_tool(AptCutter, where, diameter=d, apt_parameters=params, **common)
