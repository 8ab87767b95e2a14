"""Reader for the toolpath JSON written by Autodesk's "JSON JavaScript Object Notation" post
(``json.cps``, FORKID 6F22B39A; the format follows its revision 43569 of 2021).

The document (the post writes it on one line)::

    {"type": "hsm", "version": 1, "unit": "mm" | "in", "name"?: str, "comment"?: str,
     "toolpath": [entry, ...]}

Every entry is an object with a single key, in program order:

==================  ========================================================================
``section``         a new operation: ``type`` ("milling"), ``feedMode`` ("per min" | "per rev"),
                    ``spindle`` {``speed`` rpm, ``direction`` "cw" | "ccw"}, ``tool`` {``type``
                    ("flat mill", "ball mill", "bullnose mill", "chamfer mill", "face mill",
                    "tapered mill", "drill", ...), ``number``, ``diameter``, ``cornerRadius``,
                    ``tipDiameter``, ``taperAngle`` (degrees, omitted when 0), ``fluteLength``,
                    ``bodyLength``, ...}, ``work`` / ``wcs`` / ``fcs`` frames {``right``, ``up``,
                    ``forward``, ``origin``}
``p``               a parameter {``name``, ``value``}; ``operation-comment`` names the operation
``f``               feed (unit/min, or unit/rev in "per rev" sections); ``"fast"`` means rapid
``l``               linear feed move to [x, y, z]
``lf``              rapid move to [x, y, z] (Fusion's ``onRapid``)
``m`` / ``mf``      5-axis feed / rapid move {``e``: end, ``z``: tool axis}
``c``               arc {``e``: end, ``c``: centre, ``n``: rotation axis (counter-clockwise about
                    it; the post negates the plane normal for clockwise arcs), ``a``: sweep, degrees}
``cycle``           canned cycle {``type``, ``clearance``, ``retract`` (absolute heights),
                    ``feedrate``, ``points``: [{``p``: [x, y, z hole bottom]}], ...}
``rpm``, ``spindle``, ``coolant``, ``comment``, ``command``, ``dwell``, ``power``,
``cutterCompensation``, ``passThrough``: read or ignored, no motion
==================  ========================================================================

Coordinates are taken as written (they are in the section's work-plane frame; a warning says when
that frame is rotated about z or offset). A section whose work plane or a move whose tool axis is not
+z raises :class:`InputError` "5-axis not supported yet". Cycles are expanded to rapid to clearance,
rapid to retract, feed to the bottom, rapid to clearance (pecks and dwells not modelled); probing
cycles are skipped. Unknown entry keys are reported once and ignored. Everything is converted to mm
and mm/min. Errors name the file, the JSON path (``toolpath[12].c.n``) and the line:column of the
entry; moves carry that line:column as their source.
"""
from __future__ import annotations

import bisect
import json
import re
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import AllowInfNan, BaseModel, ConfigDict, Strict, TypeAdapter, ValidationError

from fusioncut.errors import FusionCutError, InputError, SourceLocation, ToolDefinitionError
from fusioncut.io.apt_arcs import solve_arc
from fusioncut.io.cutters import ToolRegistry, check_tool_axis, finite
from fusioncut.io.text import read_utf8_text
from fusioncut.io.tool_library import fusion_tool, pydantic_message
from fusioncut.model.moves import ArcMove, LinearMove, Move, Point, Toolpath
from fusioncut.model.tools import MillingTool, SpindleDirection
from fusioncut.model.units import MM_PER_INCH

__all__ = ["read_fusion_json"]

Num = Annotated[float, Strict(), AllowInfNan(False)]
Vec = tuple[Num, Num, Num]


class _Model(BaseModel):
    model_config = ConfigDict(extra="ignore")


class _Header(_Model):
    type: Literal["hsm"]
    version: Annotated[int, Strict()]
    unit: Literal["mm", "in"]
    name: str | None = None
    comment: str | None = None


class _Tool(_Model):
    type: str
    number: Annotated[int, Strict()] | None = None
    diameter: Num
    cornerRadius: Num = 0.0
    tipDiameter: Num | None = None
    taperAngle: Num = 0.0
    fluteLength: Num | None = None
    bodyLength: Num | None = None


class _Spindle(_Model):
    speed: Num | None = None
    direction: Literal["cw", "ccw"] | None = None


class _Frame(_Model):
    right: Vec = (1.0, 0.0, 0.0)
    up: Vec = (0.0, 1.0, 0.0)
    forward: Vec = (0.0, 0.0, 1.0)
    origin: Vec = (0.0, 0.0, 0.0)


class _Section(_Model):
    type: str = "milling"
    feedMode: Literal["per min", "per rev"] = "per min"
    spindle: _Spindle | Annotated[int, Strict()] | None = None
    tool: _Tool
    work: _Frame | None = None
    toolOrientation: Num | None = None


class _Arc(_Model):
    e: Vec
    c: Vec
    n: Vec
    a: Num


class _Move5(_Model):
    e: Vec
    z: Vec


class _CyclePoint(_Model):
    p: Vec


class _Cycle(_Model):
    type: str
    clearance: Num
    retract: Num
    feedrate: Num | None = None
    points: list[_CyclePoint] = []


class _Param(_Model):
    name: str
    value: Any = None


class _SpindleCmd(_Model):
    direction: Literal["cw", "ccw"] | None = None
    power: Literal["on", "off"] | None = None


_ENTRY_MODELS: dict[str, Any] = {
    "section": _Section, "c": _Arc, "m": _Move5, "mf": _Move5, "cycle": _Cycle, "p": _Param,
    "spindle": _SpindleCmd,
}
_SCALARS: dict[str, Any] = {
    "l": Vec, "lf": Vec, "f": Num | Literal["fast"], "rpm": Num,
}
_SCALAR_ADAPTERS = {key: TypeAdapter(t) for key, t in _SCALARS.items()}
_NO_MOTION = {"comment", "command", "coolant", "dwell", "power", "cutterCompensation", "passThrough"}
_WS = re.compile(r"[ \t\r\n]*")


# --------------------------------------------------------------------------------------------------
# locating toolpath entries in the text (the post writes one long line, so line:column is what helps)


class _Text:
    def __init__(self, text: str, file: str):
        self.text = text
        self.file = file
        self._newlines = [i for i, ch in enumerate(text) if ch == "\n"]
        self.decoder = json.JSONDecoder(parse_constant=self._reject_constant)

    @staticmethod
    def _reject_constant(token: str) -> Any:
        raise ValueError(f"{token} is not a number")

    def where(self, offset: int) -> SourceLocation:
        line = bisect.bisect_left(self._newlines, offset)
        col = offset - (self._newlines[line - 1] + 1 if line else 0)
        return SourceLocation(self.file, line + 1, col + 1)

    def skip_ws(self, i: int) -> int:
        return _WS.match(self.text, i).end()  # type: ignore[union-attr]

    def expect(self, i: int, ch: str, what: str) -> int:
        i = self.skip_ws(i)
        if i >= len(self.text) or self.text[i] != ch:
            raise InputError(f"not valid JSON: expected {what}", self.where(i))
        return i + 1

    def value(self, i: int) -> tuple[Any, int]:
        i = self.skip_ws(i)
        try:
            return self.decoder.raw_decode(self.text, i)
        except json.JSONDecodeError as e:
            raise InputError(f"not valid JSON: {e.msg}", self.where(e.pos)) from e
        except (ValueError, RecursionError) as e:
            raise InputError(f"not valid JSON: {e}", self.where(i)) from e

    def document(self) -> tuple[dict[str, Any], list[tuple[Any, int]] | None]:
        """The top-level object without its toolpath, and the toolpath entries with their offsets."""
        i = self.expect(0, "{", "a JSON object")
        head: dict[str, Any] = {}
        entries: list[tuple[Any, int]] | None = None
        i = self.skip_ws(i)
        if i < len(self.text) and self.text[i] == "}":
            return head, None
        while True:
            key, i = self.value(i)
            if not isinstance(key, str):
                raise InputError("not valid JSON: object keys must be strings", self.where(i))
            i = self.expect(i, ":", "':'")
            j = self.skip_ws(i)
            if key == "toolpath" and j < len(self.text) and self.text[j] == "[":
                entries, i = self.array(j)
            else:
                head[key], i = self.value(i)
            i = self.skip_ws(i)
            if i < len(self.text) and self.text[i] == ",":
                i += 1
                continue
            i = self.expect(i, "}", "',' or '}'")
            break
        if self.skip_ws(i) != len(self.text):
            raise InputError("not valid JSON: text after the document", self.where(self.skip_ws(i)))
        return head, entries

    def array(self, i: int) -> tuple[list[tuple[Any, int]], int]:
        i += 1  # '['
        out: list[tuple[Any, int]] = []
        i = self.skip_ws(i)
        if i < len(self.text) and self.text[i] == "]":
            return out, i + 1
        while True:
            start = self.skip_ws(i)
            v, i = self.value(start)
            out.append((v, start))
            i = self.skip_ws(i)
            if i < len(self.text) and self.text[i] == ",":
                i += 1
                continue
            return out, self.expect(i, "]", "',' or ']'")


# --------------------------------------------------------------------------------------------------


class _JsonReader:
    def __init__(self, file: str, skip_unsupported_tools: bool):
        self.file = file
        self.skip_unsupported = skip_unsupported_tools
        self.moves: list[Move] = []
        self.warnings: list[str] = []
        self.registry = ToolRegistry(self.warnings.append)
        self._warned: set[str] = set()
        self.scale = 1.0
        self.pos: Point | None = None
        self.feed: float | None = None
        self.fast = False
        self.per_rev = False
        self.rpm: float | None = None
        self.spindle = SpindleDirection.CW
        self.tool: MillingTool | None = None
        self.tool_number: int | None = None
        self.tool_key: int | None = None
        self.tool_where: SourceLocation | None = None
        self.operation = ""
        self.skipping = False  # inside a section whose tool we skip
        self.flipped: list[SourceLocation] = []

    def warn_once(self, key: str, message: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(message)

    def L(self, v: tuple[float, float, float], where: SourceLocation, path: str) -> Point:
        return tuple(finite(c * self.scale, f"{path}: coordinate", where) for c in v)  # type: ignore[return-value]

    # -- tools ---------------------------------------------------------------------------------------
    def current_tool(self) -> int | None:
        if self.tool is None:
            return self.tool_number
        if self.tool_key is None:
            tool = self.tool if self.tool.spindle == self.spindle else _with_spindle(self.tool, self.spindle)
            assert self.tool_where is not None
            self.tool_key = self.registry.register(self.tool_number, tool, self.tool_where)
        return self.tool_key

    def on_section(self, sec: _Section, where: SourceLocation, path: str) -> None:
        self.skipping = False
        if sec.type != "milling":
            raise InputError(f"{path}.type: {sec.type!r} sections are not supported (milling only)", where)
        if sec.toolOrientation:
            raise InputError(f"{path}.toolOrientation: a B-axis tool orientation is not supported", where)
        if sec.work is not None:
            try:
                check_tool_axis(sec.work.forward, where)
            except InputError as e:
                raise InputError(f"{path}.work.forward: {e.reason} (tilted work plane)", where) from e
            w = sec.work
            if _differs(w.right, (1, 0, 0)) or _differs(w.up, (0, 1, 0)) or _differs(w.origin, (0, 0, 0)):
                self.warn_once(
                    "frame", f"{where}: {path}.work: the work plane is rotated about z or offset; "
                    "coordinates are taken as written (work-plane frame)"
                )
        self.per_rev = sec.feedMode == "per rev"
        self.feed = None
        self.fast = False
        if isinstance(sec.spindle, _Spindle):
            if sec.spindle.speed is not None:
                if sec.spindle.speed < 0:
                    raise InputError(f"{path}.spindle.speed: must be >= 0", where)
                self.rpm = sec.spindle.speed
            if sec.spindle.direction is not None:
                self.spindle = SpindleDirection(sec.spindle.direction)
        t = sec.tool
        k = self.scale

        def mm(v: float | None) -> float | None:
            return None if v is None else v * k

        kind = " ".join(t.type.lower().split())
        if kind in {"probe", "holder"}:
            self.warn_once(f"skip:{kind}", f"{where}: {path}: {kind} sections do not cut; skipped")
            self.skipping = True
            self.tool = None
            return
        try:
            self.tool = fusion_tool(
                t.type, where, self.warnings, json_path=f"{path}.tool", diameter=t.diameter * k,
                flute_length=mm(t.fluteLength), corner_radius=t.cornerRadius * k, tip_diameter=mm(t.tipDiameter),
                # a drill's or spot drill's taperAngle is its point's included angle (posts print it as
                # TAPER=118deg), a chamfer mill's the half-angle from the axis
                taper_angle=t.taperAngle, point_angle=t.taperAngle if kind in {"spot drill", "drill"} else None,
                number=t.number, spindle=self.spindle, overall_length=mm(t.bodyLength), source=str(where),
            )
        except ToolDefinitionError as e:
            if not self.skip_unsupported:
                raise
            self.warnings.append(f"{e} - section skipped")
            self.skipping = True
            self.tool = None
            return
        self.tool_number = t.number
        self.tool_key = None
        self.tool_where = where

    # -- motion --------------------------------------------------------------------------------------
    def feed_now(self, where: SourceLocation, path: str) -> float:
        if self.feed is None:
            raise InputError(f"{path}: feed move before any feed ('f') in this section", where)
        if self.per_rev:
            if not self.rpm:
                raise InputError(f"{path}: feed per revolution without a spindle speed", where)
            return self.feed * self.rpm
        return self.feed

    def linear(self, end: Point, where: SourceLocation, path: str, rapid: bool, feed: float | None = None) -> None:
        if self.pos is None:
            self.pos = end
            if not rapid:
                self.warnings.append(f"{where}: {path}: the first motion is a feed move from an unknown position; "
                                     "it only sets the position")
            return
        if end == self.pos:
            return
        if self.skipping:
            self.pos = end
            return
        if not rapid and feed is None:
            feed = self.feed_now(where, path)
        self.moves.append(LinearMove(
            start=self.pos, end=end, feed=None if rapid else feed, spindle_rpm=self.rpm, tool=self.current_tool(),
            operation=self.operation, source=where, rapid=rapid,
        ))
        self.pos = end

    def arc(self, arc: _Arc, where: SourceLocation, path: str) -> None:
        end = self.L(arc.e, where, f"{path}.e")
        if self.pos is None:
            raise InputError(f"{path}: arc from an unknown position (no motion before it)", where)
        if self.skipping:
            self.pos = end
            return
        if self.fast:
            raise InputError(f"{path}: arc at rapid feed ('f': \"fast\") is not defined", where)
        center = self.L(arc.c, where, f"{path}.c")
        try:
            sol = solve_arc(self.pos, end, center, arc.n, where, sweep_deg=arc.a)
        except InputError as e:
            raise InputError(f"{path}: {e.reason}", where) from e
        if sol.sense_from_end_point:
            self.flipped.append(where)
        self.moves.append(ArcMove(
            start=self.pos, end=end, feed=self.feed_now(where, path), spindle_rpm=self.rpm, tool=self.current_tool(),
            operation=self.operation, source=where, center=sol.center, plane=sol.plane, clockwise=sol.clockwise,
            turns=sol.turns,
        ))
        self.pos = end

    def cycle(self, cyc: _Cycle, where: SourceLocation, path: str) -> None:
        kind = cyc.type.lower()
        if kind.startswith("probing"):
            self.warn_once("probing", f"{where}: {path}: probing cycles do not cut; skipped")
            return
        if kind == "back-boring":
            raise InputError(f"{path}.type: back-boring cycles are not supported", where)
        if cyc.feedrate is None or cyc.feedrate <= 0:
            raise InputError(f"{path}.feedrate: a cycle needs a feed > 0", where)
        self.warn_once("cycle", f"{where}: {path}: canned cycles are expanded as single plunges "
                                "(pecks, dwells and spindle reversal are not modelled)")
        feed = cyc.feedrate * self.scale
        if self.per_rev:
            if not self.rpm:
                raise InputError(f"{path}: cycle feed per revolution without a spindle speed", where)
            feed *= self.rpm
        clear = finite(cyc.clearance * self.scale, f"{path}.clearance", where)
        retract = finite(cyc.retract * self.scale, f"{path}.retract", where)
        if retract > clear + 1e-9:
            raise InputError(f"{path}: retract height {retract:g} above the clearance height {clear:g}", where)
        for k, pt in enumerate(cyc.points):
            x, y, zb = self.L(pt.p, where, f"{path}.points[{k}].p")
            if zb > retract + 1e-9:
                raise InputError(
                    f"{path}.points[{k}]: hole bottom z={zb:g} above the retract height {retract:g}", where
                )
            self.linear((x, y, clear), where, path, rapid=True)
            self.linear((x, y, retract), where, path, rapid=True)
            self.linear((x, y, zb), where, path, rapid=False, feed=feed)
            self.linear((x, y, clear), where, path, rapid=True)

    # -- driver --------------------------------------------------------------------------------------
    def entry(self, raw: Any, where: SourceLocation, path: str) -> None:
        if not isinstance(raw, dict) or not raw:
            raise InputError(f"{path}: expected an object with one key", where)
        if len(raw) != 1:
            raise InputError(f"{path}: expected one key per entry, got {', '.join(map(str, raw))}", where)
        (key, value), = raw.items()
        path = f"{path}.{key}"
        try:
            if key in _ENTRY_MODELS:
                parsed = _ENTRY_MODELS[key].model_validate(value)
            elif key in _SCALARS:
                parsed = _SCALAR_ADAPTERS[key].validate_python(value)
            else:
                parsed = value
        except ValidationError as e:
            raise InputError(pydantic_message(e, path), where) from e
        if key == "section":
            self.on_section(parsed, where, path)
        elif key == "p":
            if parsed.name == "operation-comment" and isinstance(parsed.value, str):
                self.operation = parsed.value
        elif key == "f":
            if parsed == "fast":
                self.fast = True
            else:
                if parsed <= 0:
                    raise InputError(f"{path}: feed must be > 0, got {parsed:g}", where)
                self.fast = False
                self.feed = parsed * self.scale
        elif key == "rpm":
            if parsed < 0:
                raise InputError(f"{path}: spindle speed must be >= 0", where)
            self.rpm = parsed
        elif key == "spindle":
            if parsed.direction is not None and SpindleDirection(parsed.direction) != self.spindle:
                self.spindle = SpindleDirection(parsed.direction)
                self.tool_key = None
        elif key == "l":
            self.linear(self.L(parsed, where, path), where, path, rapid=self.fast)
        elif key == "lf":
            self.linear(self.L(parsed, where, path), where, path, rapid=True)
        elif key in ("m", "mf"):
            try:
                check_tool_axis(parsed.z, where)
            except InputError as e:
                raise InputError(f"{path}.z: {e.reason}", where) from e
            self.linear(self.L(parsed.e, where, f"{path}.e"), where, path, rapid=(key == "mf" or self.fast))
        elif key == "c":
            self.arc(parsed, where, path)
        elif key == "cycle":
            self.cycle(parsed, where, path)
        elif key in _NO_MOTION:
            if key == "passThrough":
                self.warn_once("pass", f"{where}: {path}: pass-through controller code ignored")
            elif key == "cutterCompensation" and isinstance(value, dict) and value.get("mode") in ("left", "right"):
                self.warn_once(
                    "comp", f"{where}: {path}: cutter compensation requested; points read as tool-tip positions"
                )
        else:
            self.warn_once(f"unknown:{key}", f"{where}: {path}: unknown entry ignored")

    def run(self, text: str) -> Toolpath:
        doc = _Text(text, self.file)
        head, entries = doc.document()
        try:
            header = _Header.model_validate(head)
        except ValidationError as e:
            raise InputError(pydantic_message(e, ""), SourceLocation(self.file)) from e
        if header.version != 1:
            self.warnings.append(f"{self.file}: format version {header.version}; read as version 1")
        if entries is None:
            what = "not an array" if "toolpath" in head else "missing"
            raise InputError(f"toolpath: {what} (expected an array of entries)", SourceLocation(self.file))
        self.scale = MM_PER_INCH if header.unit == "in" else 1.0
        for i, (raw, offset) in enumerate(entries):
            where = doc.where(offset)
            try:
                self.entry(raw, where, f"toolpath[{i}]")
            except FusionCutError:
                raise
            except (ValueError, ArithmeticError) as e:  # defensive: never leak a bare Python error
                raise InputError(f"toolpath[{i}]: cannot interpret the entry: {e}", where) from e
        if not self.moves:
            raise InputError("no tool motion in the toolpath", SourceLocation(self.file))
        if self.flipped:
            self.warnings.append(
                f"{self.flipped[0]}: {len(self.flipped)} arc(s) turn against their stated axis; "
                "their sense was taken from the end point"
            )
        return Toolpath(tuple(self.moves), dict(self.registry.tools), tuple(self.warnings), self.file)


def _differs(a: tuple[float, float, float], b: tuple[float, float, float]) -> bool:
    return any(abs(x - y) > 1e-6 for x, y in zip(a, b))


def _with_spindle(tool: MillingTool, spindle: SpindleDirection) -> MillingTool:
    return replace(tool, spindle=spindle)


def read_fusion_json(path: str | Path, *, skip_unsupported_tools: bool = False) -> Toolpath:
    """Read a Fusion JSON-post toolpath into a :class:`Toolpath` (mm, mm/min).

    Sections whose tool cannot be modelled raise :class:`ToolDefinitionError`; with
    ``skip_unsupported_tools`` they are skipped instead (their motion still moves the position) and
    a warning names them. Every malformed input raises :class:`InputError` naming the file, the
    entry's line:column and its JSON path.
    """
    return _JsonReader(str(path), skip_unsupported_tools).run(read_utf8_text(path))
