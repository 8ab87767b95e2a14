"""Tool definitions from tool libraries and simulator projects, as model tools in millimetres.

Formats (:func:`read_tool_library` dispatches on the suffix):

* **Fusion tool library** ``.json`` - ``{"data": [tool, ...], "version": n}``; each tool has ``type``
  ("flat end mill", "ball end mill", "bull nose end mill", "chamfer mill", "face mill",
  "tapered mill", "spot drill", "drill", ...), ``unit`` ("millimeters" | "inches"), ``description``,
  ``geometry`` (``DC`` cutting diameter, ``LCF`` flute length, ``LB`` body length (the stick-out below
  the holder, used as the tool's ``overall_length``; ``OAL`` when it is missing), ``OAL`` overall
  length, ``NOF`` flutes, ``RE`` corner radius, ``SFDM`` shank diameter, ``TA`` taper angle in degrees
  from the axis, ``SIG`` point angle in degrees (the included angle), ``tip-diameter``, ``HAND``
  right-hand cutting, ``shoulder-length`` tip to the shoulder and ``shoulder-diameter`` the neck's
  diameter below it: a reduced neck) and ``post-process.number`` (the T number). Entries of type
  "holder" are holders and are skipped. Drills become :class:`~fusioncut.model.tools.Drill` of
  their point angle (118 degrees when the entry gives none, with a warning).
* **Fusion** ``.tools`` - a zip archive holding that JSON (``tools.json``); errors name the archive
  and the member. The member is inflated in chunks up to :data:`fusioncut.io.archive.MAX_MEMBER_BYTES`
  (64 MiB), whatever its header says (:func:`fusioncut.io.archive.read_member`).
* **LinuxCNC** ``.tbl`` - lines ``T<n> P<pocket> [X..W offsets] D<diameter> [I J Q lathe data]
  ;comment``. The table carries neither units nor shapes: lengths are read in ``tbl_units``
  (millimetres unless told), every tool is a flat end mill unless its comment names another shape
  (ball, bull nose with ``R<radius>``, or a V/chamfer/spot tool with its included angle in degrees),
  and the flute length is assumed; each assumption is reported in the warnings.
* **CAMotics projects** ``.camotics`` (:func:`read_camotics_project`) - JSON with ``units``
  ("metric" | "imperial", the programs' default), ``tools`` (keyed by number: ``units``, ``shape``
  "cylindrical" | "ballnose" | "conical" | "snubnose" | "spheroid", ``length``, ``diameter``,
  ``snub_diameter``), ``workpiece`` (``automatic``, ``margin`` in percent, ``bounds.min/max`` in mm)
  and ``files`` (programs, relative to the project). CAMotics' ``length`` is the cutting length and a
  conical tool is a cone over its whole length (half-angle ``atan(d / 2 / length)``).

Tools that cannot be modelled (centre drills, taps, thread/slot/lollipop/dovetail/form mills, ...) are left
out of the returned :class:`ToolLibrary` and kept, with their :class:`ToolDefinitionError`, in
``ToolLibrary.refused``; :meth:`ToolLibrary.require` raises that error when a program asks for such a
tool, so a library holding one drill can still serve the milling operations.
"""
from __future__ import annotations

import math
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import AllowInfNan, BaseModel, ConfigDict, Field, Strict, ValidationError

from fusioncut.errors import InputError, SourceLocation, ToolDefinitionError
from fusioncut.io.archive import read_member
from fusioncut.io.cutters import make_tool
from fusioncut.io.json_input import parse_json
from fusioncut.io.text import read_source_text, read_utf8_text
from fusioncut.model.stock import BoxStock
from fusioncut.model.tools import (
    ASSUMED_FLUTE_LENGTH_DIAMETERS,
    AptCutter,
    AptParameters,
    BallEndMill,
    BullNoseEndMill,
    ChamferMill,
    Drill,
    FlatEndMill,
    MillingTool,
    SpindleDirection,
    TaperedEndMill,
)
from fusioncut.model.units import MM_PER_INCH

__all__ = ["ToolLibrary", "LibraryEntry", "CamoticsProject", "fusion_tool", "read_tool_library",
           "read_camotics_project"]

Num = Annotated[float, Strict(), AllowInfNan(False)]


@dataclass(frozen=True)
class LibraryEntry:
    """One tool entry of a library as written, numbered or not, kept or not: ``where`` (``data[3]``,
    ``line 7``), ``name`` (Fusion ``description``, the table comment), ``id`` (Fusion ``guid``),
    ``number`` (its T number, ``None`` when it has none), and the model ``tool`` or the ``error``
    that refused it."""

    where: str
    name: str
    id: str | None
    number: int | None
    tool: MillingTool | None = None
    error: ToolDefinitionError | None = None


class ToolLibrary(dict[int, MillingTool]):
    """Tools by T number (mm), plus what the reader assumed (``warnings``) and the tools it could not
    model (``refused``: T number -> the error to raise when that tool is needed). ``entries`` are all
    tool entries, duplicates and unnumbered ones included, for :meth:`pick` (default: one per tool)."""

    def __init__(self, tools: dict[int, MillingTool], *, warnings: tuple[str, ...] = (),
                 refused: dict[int, ToolDefinitionError] | None = None, source: str = "<memory>",
                 entries: tuple[LibraryEntry, ...] | None = None):
        super().__init__(tools)
        self.warnings = warnings
        self.refused = dict(refused or {})
        self.source = source
        if entries is None:
            entries = tuple(LibraryEntry(f"T{n}", t.name, None, n, tool=t) for n, t in tools.items())
            entries += tuple(LibraryEntry(f"T{n}", "", None, n, error=e) for n, e in self.refused.items())
        self.entries = entries

    def pick(self, *, name: str | None = None, id: str | None = None) -> MillingTool:
        """The tool of the one entry whose ``name`` (case and surrounding blanks ignored) or ``id`` is
        given, whatever its number; :class:`ToolDefinitionError` naming the library when none or
        several match, or when that entry was refused."""
        key, want = ("id", id.strip().lower()) if id is not None else ("name", (name or "").strip().lower())
        found = [e for e in self.entries if (getattr(e, key) or "").strip().lower() == want]
        where = SourceLocation(self.source)
        if not found:
            raise ToolDefinitionError(f"no tool with {key} {want!r} in the tool library", where)
        if len(found) > 1:
            listed = ", ".join(f"{e.where} (id {e.id})" if e.id else e.where for e in found[:6])
            raise ToolDefinitionError(f"{len(found)} tools have {key} {want!r} in the tool library: {listed}"
                                      + ("; pick one by its id" if key == "name" else ""), where)
        entry = found[0]
        if entry.tool is None:
            raise entry.error or ToolDefinitionError(f"{entry.where}: no tool", where)
        return entry.tool

    def require(self, number: int) -> MillingTool:
        """The tool numbered ``number``; :class:`ToolDefinitionError` if it was refused or is absent."""
        if number in self:
            return self[number]
        if number in self.refused:
            raise self.refused[number]
        raise ToolDefinitionError(f"T{number} is not in the tool library", SourceLocation(self.source))


# --------------------------------------------------------------------------------------------------
# Fusion tool types

def _norm_type(name: str) -> str:
    return " ".join(name.lower().replace("-", " ").replace("_", " ").split())


_FLAT = {"flat end mill", "flat mill", "face mill"}
_BALL = {"ball end mill", "ball mill"}
_BULL = {"bull nose end mill", "bullnose mill", "bull nose mill", "bullnose end mill"}
_CHAMFER = {"chamfer mill"}
_SPOT = {"spot drill"}
_TAPERED = {"tapered mill"}
_DRILL = {"drill"}
DEFAULT_POINT_ANGLE = 118.0  # degrees, a standard twist drill's point (included angle)
_REFUSED = {
    "center drill": "a centre drill", "block drill": "a block drill",
    "counterbore": "a counterbore", "counter bore": "a counterbore", "countersink": "a countersink",
    "counter sink": "a countersink", "right tap": "a tap", "left tap": "a tap", "tap right hand": "a tap",
    "tap left hand": "a tap", "tap": "a tap", "reamer": "a reamer", "boring bar": "a boring bar",
    "slot mill": "a slot mill", "radius mill": "a corner-rounding (radius) mill",
    "dovetail mill": "a dovetail mill", "lollipop mill": "a lollipop mill", "form mill": "a form mill",
    "thread mill": "a thread mill", "probe": "a probe", "holder": "a holder without a tool",
}


def fusion_tool(
    type_name: str,
    where: SourceLocation,
    warnings: list[str],
    *,
    json_path: str = "",
    diameter: float,
    flute_length: float | None,
    corner_radius: float = 0.0,
    tip_diameter: float | None = None,
    taper_angle: float = 0.0,
    point_angle: float | None = None,
    shank_diameter: float | None = None,
    overall_length: float | None = None,
    flutes: int | None = None,
    number: int | None = None,
    name: str = "",
    spindle: SpindleDirection = SpindleDirection.CW,
    tapered_type: str | None = None,
    shoulder_length: float | None = None,
    neck_diameter: float | None = None,
    source: str = "",
) -> MillingTool:
    """A Fusion tool (from a library or the JSON post) as a model tool. Lengths in mm, angles in
    degrees; ``taper_angle`` is measured from the axis, ``point_angle`` is the included angle.

    Face mills become flat end mills of their cutting diameter (a lead angle is ignored, with a
    warning); spot drills become pointed chamfer mills of half their point angle; a tapered mill with
    a corner radius is a tapered ball (an :class:`AptCutter`); drills are :class:`Drill` of
    ``point_angle`` (118 assumed, with a warning, when it is missing). ``shoulder_length`` above the
    flute length models a neck of ``neck_diameter`` (default: the cutting diameter) up to it.
    ``source`` (``file:line`` or library entry) is kept in the tool for messages. Unmodellable types raise
    :class:`ToolDefinitionError` naming the type. Errors and warnings are located at ``where`` and
    start with ``json_path`` when given.
    """
    kind = _norm_type(type_name)
    label = f"{name or type_name}" + (f" (T{number})" if number is not None else "")
    ctx = f"{json_path}: " if json_path else ""

    def refuse(message: str) -> ToolDefinitionError:
        return ToolDefinitionError(ctx + message, where)

    def note(message: str) -> None:
        warnings.append(f"{where}: {ctx}{message}")

    if kind in _REFUSED:
        raise refuse(f"tool {label} is {_REFUSED[kind]}; FusionCut models milling cutters only")
    if not (diameter > 0):
        raise refuse(f"tool {label}: diameter must be > 0, got {diameter}")
    if flute_length is None or not (flute_length > 0):
        flute_length = ASSUMED_FLUTE_LENGTH_DIAMETERS * diameter
        note(f"tool {label} has no flute length; assumed {flute_length:.4g} mm")
    common: dict[str, Any] = {"flute_length": flute_length, "number": number, "name": name, "spindle": spindle,
                              "source": source}
    if flutes is not None and flutes >= 1:
        common["flutes"] = flutes
    if shank_diameter is not None and shank_diameter > 0:
        common["shank_diameter"] = shank_diameter
    if overall_length is not None and overall_length > 0:
        if overall_length >= flute_length:
            common["overall_length"] = overall_length
        else:
            note(f"tool {label}: overall length below the flute length; ignored")
    r = corner_radius or 0.0

    def build(cls: type[MillingTool], **kw: Any) -> MillingTool:
        _neck(common, label, shoulder_length, neck_diameter, note)
        return make_tool(cls, where, json_path, **kw, **common)

    if kind in _DRILL:
        angle = point_angle if point_angle else taper_angle
        if not angle:
            angle = DEFAULT_POINT_ANGLE
            note(f"drill {label} gives no point angle; assumed {angle:g} deg")
        if not (0 < angle < 180):
            raise refuse(f"drill {label}: point angle must be in (0, 180) degrees, got {angle:g}")
        cone = diameter / 2 / math.tan(math.radians(angle / 2))
        if cone > common["flute_length"] + 1e-9:
            note(f"drill {label}: point ({cone:.4g} mm) taller than the flute length; flute length set to it")
            common["flute_length"] = cone
        return build(Drill, diameter=diameter, point_angle=angle)

    if kind in _FLAT or kind in _BALL or kind in _BULL:
        if kind == "face mill" and taper_angle:
            note(f"face mill {label}: lead angle {taper_angle:g} deg ignored (modelled flat)")
        if r <= 1e-9:
            if kind in _BALL:
                return build(BallEndMill, diameter=diameter)
            if kind in _BULL:
                note(f"bull nose {label} has no corner radius; modelled flat")
            return build(FlatEndMill, diameter=diameter)
        if abs(r - diameter / 2) <= 1e-6 * max(1.0, diameter):
            return build(BallEndMill, diameter=diameter)
        if kind in _BALL:
            raise refuse(f"ball end mill {label}: corner radius {r:g} mm is not half the diameter {diameter:g} mm")
        if kind in _FLAT and kind != "face mill":
            note(f"flat end mill {label} has a corner radius {r:g} mm; modelled as a bull nose")
        return build(BullNoseEndMill, diameter=diameter, corner_radius=r)

    if kind in _CHAMFER or kind in _SPOT:
        half = point_angle / 2 if kind in _SPOT and point_angle else taper_angle
        if not (0 < half < 90):
            raise refuse(f"tool {label}: needs a taper angle in (0, 90) degrees, got {half:g}")
        # a spot drill is pointed whatever its library entry says about a tip
        tip = 0.0 if kind in _SPOT else (tip_diameter or 0.0)
        if not (0 <= tip < diameter):
            raise refuse(f"tool {label}: tip diameter {tip:g} mm must be in [0, diameter)")
        cone = (diameter - tip) / 2 / math.tan(math.radians(half))
        if cone > common["flute_length"] + 1e-9:
            # libraries often give engravers a token flute length; the cone is what cuts
            note(f"tool {label}: cone ({cone:.4g} mm) taller than the flute length; flute length set to it")
            common["flute_length"] = cone
            if common.get("overall_length") is not None and common["overall_length"] < cone:
                del common["overall_length"]
        return build(ChamferMill, diameter=diameter, tip_diameter=tip, taper_angle=half)

    if kind in _TAPERED:
        if not (0 < taper_angle < 90):
            raise refuse(f"tapered mill {label}: taper angle must be in (0, 90) degrees, got {taper_angle:g}")
        if r <= 1e-9 and tapered_type and "ball" in tapered_type.lower() and tip_diameter:
            r = tip_diameter / 2
        if r <= 1e-9:
            if not tip_diameter or tip_diameter <= 0:
                raise refuse(f"tapered mill {label}: no tip diameter given; cannot place the taper")
            return build(TaperedEndMill, diameter=tip_diameter, taper_angle=taper_angle)
        if tip_diameter and tip_diameter > 2 * r + 1e-6:
            raise refuse(f"tapered mill {label}: tapered bull nose (tip {tip_diameter:g} mm, corner {r:g} mm) "
                         "not modelled yet")
        # tapered ball: the ball of radius r sits on the axis and the side line is tangent to it
        d = 2 * r * math.cos(math.radians(taper_angle))
        try:
            params = AptParameters(d, r, 0.0, r, 0.0, taper_angle, common["flute_length"])
        except ToolDefinitionError as e:
            raise refuse(f"tapered ball mill {label}: {e.reason}") from e
        return build(AptCutter, diameter=d, apt_parameters=params)

    raise refuse(f"tool {label}: unknown tool type {type_name!r}")


def _neck(common: dict[str, Any], label: str, shoulder: float | None, neck: float | None,
          note: Any) -> None:
    """Put a neck into the tool's keyword arguments when the shoulder lies above the flutes (Fusion
    gives a shoulder length equal to the flute length for tools without a neck)."""
    if shoulder is None or not (shoulder > common["flute_length"] + 1e-9):
        return
    top = common.get("overall_length")
    if top is not None and shoulder > top + 1e-9:
        note(f"tool {label}: shoulder length {shoulder:g} mm beyond the overall length {top:g} mm; the neck "
             "is modelled up to the overall length")
        shoulder = top
        if not (shoulder > common["flute_length"] + 1e-9):
            return
    common["shoulder_length"] = shoulder
    if neck is not None and neck > 0:
        common["neck_diameter"] = neck


# --------------------------------------------------------------------------------------------------
# Fusion library JSON

class _Geometry(BaseModel):
    model_config = ConfigDict(extra="ignore", populate_by_name=True)
    DC: Num
    LCF: Num | None = None
    LB: Num | None = None
    OAL: Num | None = None
    NOF: int | None = None
    RE: Num | None = None
    SFDM: Num | None = None
    TA: Num | None = None
    SIG: Num | None = None
    HAND: bool | None = None
    tip_diameter: Num | None = Field(default=None, alias="tip-diameter")
    shoulder_length: Num | None = Field(default=None, alias="shoulder-length")
    shoulder_diameter: Num | None = Field(default=None, alias="shoulder-diameter")


class _PostProcess(BaseModel):
    model_config = ConfigDict(extra="ignore")
    number: int | None = None


class _FusionTool(BaseModel):
    model_config = ConfigDict(extra="ignore", populate_by_name=True)
    type: str
    unit: Literal["millimeters", "inches"] = "millimeters"
    description: str = ""
    guid: str | None = None
    geometry: _Geometry | None = None
    post_process: _PostProcess | None = Field(default=None, alias="post-process")
    tapered_type: str | None = Field(default=None, alias="tapered-type")


class _FusionLibrary(BaseModel):
    model_config = ConfigDict(extra="ignore")
    data: list[Any]


def pydantic_message(err: ValidationError, prefix: str) -> str:
    """The first validation problem as ``path: message`` (``prefix`` is the path of the validated value)."""
    first = err.errors()[0]
    path = prefix
    for part in first["loc"]:
        path += f"[{part}]" if isinstance(part, int) else (f".{part}" if path else str(part))
    extra = f" ({len(err.errors()) - 1} more)" if len(err.errors()) > 1 else ""
    return f"{path or '<document>'}: {first['msg']}{extra}"


def _fusion_library_from_text(text: str, file: str) -> ToolLibrary:
    doc = parse_json(text, file)
    try:
        lib = _FusionLibrary.model_validate(doc)
    except ValidationError as e:
        raise InputError(pydantic_message(e, ""), SourceLocation(file)) from e
    warnings: list[str] = []
    entries: list[LibraryEntry] = []
    where = SourceLocation(file)
    for i, raw in enumerate(lib.data):
        path = f"data[{i}]"
        try:
            entry = _FusionTool.model_validate(raw)
        except ValidationError as e:
            raise InputError(pydantic_message(e, path), SourceLocation(file)) from e
        if _norm_type(entry.type) == "holder":
            continue
        number = entry.post_process.number if entry.post_process else None
        name = entry.description or entry.type
        tool: MillingTool | None = None
        error: ToolDefinitionError | None = None
        if entry.geometry is None:
            number_text = f" (T{number})" if number is not None else ""
            error = ToolDefinitionError(f"{path}: tool {name!r}{number_text} has no geometry", where)
        else:
            g = entry.geometry
            k = MM_PER_INCH if entry.unit == "inches" else 1.0

            def mm(v: float | None, k: float = k) -> float | None:
                return None if v is None else v * k

            try:
                tool = fusion_tool(
                    entry.type, where, warnings, json_path=path, diameter=g.DC * k, flute_length=mm(g.LCF),
                    corner_radius=mm(g.RE) or 0.0, tip_diameter=mm(g.tip_diameter), taper_angle=g.TA or 0.0,
                    point_angle=g.SIG, shank_diameter=mm(g.SFDM),
                    # the stick-out below the holder is what can touch the work; OAL includes the clamped part
                    overall_length=mm(g.LB) if g.LB else mm(g.OAL), flutes=g.NOF,
                    number=number, name=entry.description,
                    spindle=SpindleDirection.CCW if g.HAND is False else SpindleDirection.CW,
                    tapered_type=entry.tapered_type, shoulder_length=mm(g.shoulder_length),
                    neck_diameter=mm(g.shoulder_diameter), source=f"{file}: {path} {name!r}",
                )
            except ToolDefinitionError as e:
                error = e
        entries.append(LibraryEntry(path, name, entry.guid, number, tool, error))
    by_number: dict[int, list[LibraryEntry]] = {}
    for e in entries:
        if e.number is None:
            warnings.append(f"{where}: {e.where}: tool {e.name!r} has no post-process number; a job can still "
                            "pick it by name or id")
        else:
            by_number.setdefault(e.number, []).append(e)
    tools: dict[int, MillingTool] = {}
    refused: dict[int, ToolDefinitionError] = {}
    for number, same in by_number.items():
        first = same[0]
        if first.tool is not None:
            tools[number] = first.tool
        else:
            refused[number] = first.error  # type: ignore[assignment]
        if len(same) > 1:
            others = ", ".join(f"{e.where} {e.name!r}" for e in same[1:6]) + (
                f" and {len(same) - 6} more" if len(same) > 6 else "")
            warnings.append(f"{where}: T{number} is the number of {len(same)} tools; {first.where} {first.name!r} "
                            f"is kept as T{number}, not {others}; a job picks another by name or id "
                            f"(tools: {{\"number\": {number}, \"library\": {{\"name\": ...}}}})")
    if refused:
        warnings.append(
            f"{file}: {len(refused)} tool(s) cannot be modelled and were left out: "
            + ", ".join(f"T{n}" for n in sorted(refused))
        )
    return ToolLibrary(tools, warnings=tuple(warnings), refused=refused, source=file, entries=tuple(entries))


def _read_tools_archive(path: Path) -> ToolLibrary:
    file = str(path)
    try:
        with zipfile.ZipFile(path) as zf:
            names = [n for n in zf.namelist() if n.lower().endswith(".json")]
            if not names:
                raise InputError("the .tools archive holds no JSON tool library", SourceLocation(file))
            member = next((n for n in names if n.rsplit("/", 1)[-1].lower() == "tools.json"), names[0])
            data = read_member(zf, member, file)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, NotImplementedError) as e:
        raise InputError(f"not a Fusion .tools archive (zip): {e}", SourceLocation(file)) from e
    except OSError as e:
        raise InputError(f"cannot read the file: {e.strerror or e}", SourceLocation(file)) from e
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise InputError(f"{member} is not UTF-8 text", SourceLocation(file)) from e
    try:
        return _fusion_library_from_text(text, file)
    except InputError as e:  # line:column and JSON paths refer to the member: say which
        raise InputError(f"{member}: {e.reason}", e.where) from e


# --------------------------------------------------------------------------------------------------
# LinuxCNC tool tables

_TBL_WORD = re.compile(r"([A-Za-z])\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)")
_ANGLE = re.compile(r"(\d+(?:\.\d+)?)\s*(?:deg|°|grad)", re.IGNORECASE)
_RADIUS = re.compile(r"(?:\bcr\s*=?\s*|\br\s*=?\s*|radius\s*=?\s*)(\d*\.?\d+)", re.IGNORECASE)


def _tbl_tool(number: int, d: float, comment: str, scale: float, where: SourceLocation,
              warnings: list[str], assumed: list[str]) -> MillingTool:
    """The tool a table line describes; appends ``T<n>`` to ``assumed`` when its shape is a guess."""
    text = comment.lower()
    flute = ASSUMED_FLUTE_LENGTH_DIAMETERS * d
    common = {"flute_length": flute, "number": number, "name": comment.strip(), "source": str(where)}
    if re.search(r"\b(drill|tap|reamer|thread|probe|boring)", text) and "mill-drill" not in text:
        raise ToolDefinitionError(f"T{number} ({comment.strip()!r}) is not a milling cutter", where)
    angle = _ANGLE.search(text)
    if re.search(r"\bv\b|v-bit|vbit|v bit|engrav|chamfer|spot|mill-drill|countersink", text):
        if not angle:
            raise ToolDefinitionError(f"T{number} ({comment.strip()!r}): V/chamfer tool without its angle", where)
        included = float(angle.group(1))
        half = included / 2
        if not (0 < half < 90):
            raise ToolDefinitionError(f"T{number}: included angle {included:g} deg out of range", where)
        common["flute_length"] = max(flute, d / 2 / math.tan(math.radians(half)))
        return make_tool(ChamferMill, where, diameter=d, taper_angle=half, **common)
    if re.search(r"ball|kugel|sphere", text):
        return make_tool(BallEndMill, where, diameter=d, **common)
    if re.search(r"bull|torus|corner radius|toroid", text):
        m = _RADIUS.search(text)
        if m:
            r = float(m.group(1)) * scale
            if 0 < r < d / 2:
                return make_tool(BullNoseEndMill, where, diameter=d, corner_radius=r, **common)
        warnings.append(f"{where}: T{number} is named a bull nose but gives no usable corner radius; modelled flat")
        return make_tool(FlatEndMill, where, diameter=d, **common)
    if not re.search(r"end ?mill|flat|fräser|fraser|face|square|\bem\b|schaft|rough", text):
        assumed.append(f"T{number}")
    return make_tool(FlatEndMill, where, diameter=d, **common)


def _read_tbl(path: Path, units: str) -> ToolLibrary:
    file = str(path)
    scale = {"mm": 1.0, "inch": MM_PER_INCH}[units]
    text = read_source_text(path)
    tools: dict[int, MillingTool] = {}
    refused: dict[int, ToolDefinitionError] = {}
    warnings: list[str] = [f"{file}: LinuxCNC tool tables state no units; read as {units}"]
    skipped: list[str] = []
    assumed: list[str] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        body, _, comment = raw.partition(";")
        body = body.strip()
        if not body:
            continue
        words: dict[str, float] = {}
        pos = 0
        while pos < len(body):
            if body[pos].isspace():
                pos += 1
                continue
            m = _TBL_WORD.match(body, pos)
            if not m:
                raise InputError(f"cannot read {body[pos:pos + 12]!r} as a tool-table word",
                                 SourceLocation(file, lineno, pos + 1))
            letter = m.group(1).upper()
            if letter not in "TPXYZABCUVWDIJQ":
                raise InputError(f"unknown tool-table word {letter}", SourceLocation(file, lineno, pos + 1))
            value = float(m.group(2))
            if not math.isfinite(value) or abs(value) > 1e6:
                raise InputError(f"{letter} value out of range", SourceLocation(file, lineno, pos + 1))
            if letter in words:
                raise InputError(f"word {letter} given twice", SourceLocation(file, lineno, pos + 1))
            words[letter] = value
            pos = m.end()
        where = SourceLocation(file, lineno)
        if "T" not in words:
            raise InputError("tool-table line without a T word", where)
        t = words["T"]
        if t != int(t) or t < 0:
            raise InputError(f"tool number must be a whole number >= 0, got {t:g}", where)
        number = int(t)
        if number == 0 or number >= 10000:
            skipped.append(f"T{number}")  # T0 is "no tool"; T10000+ are LinuxCNC wear offsets
            continue
        if words.get("Q", 0) != 0 or words.get("I", 0) != 0 or words.get("J", 0) != 0:
            skipped.append(f"T{number} (lathe)")
            continue
        if number in tools or number in refused:
            warnings.append(f"{where}: T{number} listed again; the first entry is kept")
            continue
        d = words.get("D", 0.0) * scale
        try:
            if d <= 0:
                raise ToolDefinitionError(f"T{number} has no diameter", where)
            tools[number] = _tbl_tool(number, d, comment, scale, where, warnings, assumed)
        except ToolDefinitionError as e:
            refused[number] = e
    if tools:
        warnings.append(
            f"{file}: tool tables give no flute length; assumed {ASSUMED_FLUTE_LENGTH_DIAMETERS:g} x diameter"
        )
    if assumed:
        warnings.append(f"{file}: shape not stated in the comment, assumed flat end mill: {', '.join(assumed)}")
    if skipped:
        warnings.append(f"{file}: skipped entries that are not milling tools: {', '.join(skipped)}")
    if refused:
        warnings.append(f"{file}: left out (cannot be modelled): {', '.join(f'T{n}' for n in sorted(refused))}")
    if not tools and not refused:
        raise InputError("no milling tools in the tool table", SourceLocation(file))
    return ToolLibrary(tools, warnings=tuple(warnings), refused=refused, source=file)


def read_tool_library(path: str | Path, *, tbl_units: Literal["mm", "inch"] = "mm") -> ToolLibrary:
    """Read a tool library by suffix: Fusion ``.json`` / ``.tools``, LinuxCNC ``.tbl`` (lengths in
    ``tbl_units``). Returns a :class:`ToolLibrary` (a ``dict[int, MillingTool]`` in mm); malformed
    files raise :class:`InputError` naming the file and line or JSON path."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".json":
        return _fusion_library_from_text(read_utf8_text(p), str(p))
    if suffix == ".tools":
        return _read_tools_archive(p)
    if suffix == ".tbl":
        if tbl_units not in ("mm", "inch"):
            raise InputError(f"tbl_units must be 'mm' or 'inch', got {tbl_units!r}", SourceLocation(str(p)))
        return _read_tbl(p, tbl_units)
    raise InputError(f"unknown tool library type {p.suffix!r} (expected .json, .tools or .tbl)", SourceLocation(str(p)))


# --------------------------------------------------------------------------------------------------
# CAMotics projects

class _CamTool(BaseModel):
    model_config = ConfigDict(extra="ignore")
    number: int | None = None
    units: Literal["metric", "imperial"] | None = None
    shape: str = "cylindrical"
    length: Num
    diameter: Num
    snub_diameter: Num | None = None
    description: str = ""


class _CamBounds(BaseModel):
    min: tuple[Num, Num, Num]
    max: tuple[Num, Num, Num]


class _CamWorkpiece(BaseModel):
    model_config = ConfigDict(extra="ignore")
    automatic: bool = True
    margin: Num = 0.0
    bounds: _CamBounds | None = None


class _CamProject(BaseModel):
    model_config = ConfigDict(extra="ignore")
    units: Literal["metric", "imperial"] = "metric"
    tools: dict[str, _CamTool] = {}
    workpiece: _CamWorkpiece | None = None
    files: list[str] = []


@dataclass(frozen=True)
class CamoticsProject:
    """What a ``.camotics`` project states. ``stock`` is ``None`` when the project has no bounds and is
    marked ``inferred`` when CAMotics computed it from the toolpath ("automatic"). ``programs`` are
    resolved against the project's folder; ``units`` is the programs' default ("metric"/"imperial")."""

    tools: ToolLibrary
    stock: BoxStock | None
    programs: tuple[Path, ...]
    units: str
    warnings: tuple[str, ...]
    source: str


def _camotics_tool(number: int, t: _CamTool, default_units: str, where: SourceLocation, path: str) -> MillingTool:
    k = MM_PER_INCH if (t.units or default_units) == "imperial" else 1.0
    d, length = t.diameter * k, t.length * k
    if not (d > 0 and length > 0):
        raise ToolDefinitionError(f"{path}: T{number}: diameter and length must be > 0", where)
    shape = t.shape.lower()
    common = {"flute_length": length, "number": number, "name": t.description, "source": f"{where}: {path}"}
    if shape == "cylindrical":
        return make_tool(FlatEndMill, where, path, diameter=d, **common)
    if shape == "ballnose":
        return make_tool(BallEndMill, where, path, diameter=d, **common)
    # CAMotics sweeps conical and snub-nose tools as one cone over the whole tool length
    if shape == "conical":
        half = math.degrees(math.atan2(d / 2, length))
        return make_tool(ChamferMill, where, path, diameter=d, taper_angle=half, **common)
    if shape == "snubnose":
        snub = (t.snub_diameter or 0.0) * k
        if not (0 <= snub < d):
            raise ToolDefinitionError(f"{path}: T{number}: snub diameter must be in [0, diameter)", where)
        half = math.degrees(math.atan2((d - snub) / 2, length))
        return make_tool(ChamferMill, where, path, diameter=d, tip_diameter=snub, taper_angle=half, **common)
    raise ToolDefinitionError(f"{path}: T{number}: CAMotics shape {t.shape!r} is not modelled", where)


def read_camotics_project(path: str | Path) -> CamoticsProject:
    """Read a CAMotics ``.camotics`` project: tools (mm), the workpiece as a :class:`BoxStock` and
    the program files it names. Missing programs are reported in the warnings, not raised."""
    p = Path(path)
    file = str(p)
    text = read_utf8_text(p)
    if text.lstrip().startswith("<"):
        raise InputError("XML CAMotics projects are not supported (re-save as .camotics JSON)", SourceLocation(file))
    try:
        proj = _CamProject.model_validate(parse_json(text, file))
    except ValidationError as e:
        raise InputError(pydantic_message(e, ""), SourceLocation(file)) from e
    warnings: list[str] = []
    tools: dict[int, MillingTool] = {}
    refused: dict[int, ToolDefinitionError] = {}
    where = SourceLocation(file)
    for key, t in proj.tools.items():
        path = f"tools.{key}"
        if t.number is not None:
            number = t.number
        elif key.strip().isdigit():
            number = int(key)
        else:
            raise InputError(f"{path}: the key is not a tool number", where)
        if number in tools or number in refused:
            raise InputError(f"{path}: tool number {number} defined twice", where)
        try:
            tools[number] = _camotics_tool(number, t, proj.units, where, path)
        except ToolDefinitionError as e:
            refused[number] = e
    stock = None
    wp = proj.workpiece
    if wp is not None and wp.bounds is not None:
        try:
            stock = BoxStock(tuple(wp.bounds.min), tuple(wp.bounds.max), inferred=wp.automatic)  # type: ignore[arg-type]
        except InputError as e:
            raise InputError(f"workpiece.bounds: {e.reason}", where) from e
        if wp.automatic:
            warnings.append(f"{file}: the workpiece bounds were computed by CAMotics from the toolpath")
    programs = []
    for name in proj.files:
        prog = (p.parent / name)
        programs.append(prog)
        if not prog.exists():
            warnings.append(f"{file}: program {name!r} not found next to the project")
        elif prog.suffix.lower() == ".tpl":
            warnings.append(f"{file}: program {name!r} is a CAMotics TPL script, not G-code")
    library = ToolLibrary(tools, warnings=(), refused=refused, source=file)
    return CamoticsProject(library, stock, tuple(programs), proj.units, tuple(warnings), file)

