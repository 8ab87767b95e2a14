"""Reader for APT cutter-location (CL) data: ISO 4343 as written by Autodesk Fusion's "Common ISO 4343
APT" post, and the Siemens NX CLSF dialect.

All output is in millimetres and mm/min, in the frame the CL data are written in (Fusion: the WCS;
NX: the MCS named by ``MSYS``, which is not applied). A CL point is the tool tip on the tool axis.

Lexical rules (ISO 4343): ``$$`` starts a comment running to the end of the line; a line whose text
ends in a single ``$`` continues on the next line; a record is ``MAJOR/arg, arg, ...`` or a bare
``MAJOR`` word. Words are case-insensitive; ``PPRINT`` text is kept verbatim.

Statements read (anything else is reported once in the warnings and otherwise ignored; statements
that would move the tool in ways we do not evaluate are refused, see below):

* ``UNITS/MM | INCHES`` - inch programs are scaled by 25.4 (coordinates, cutter, ``FEDRAT`` without
  an explicit unit). Without ``UNITS`` millimetres are assumed, and a warning says so.
* ``FEDRAT/f[, MMPM|IPM|MMPR|IPR]`` (Fusion) and ``FEDRAT/MMPM|IPM|..., f`` (NX). Per-revolution
  feeds are converted with the spindle speed in effect.
* ``RAPID`` - one-shot (ISO 4343 5.42): only the next ``GOTO`` is a rapid.
* ``GOTO/x, y, z[, i, j, k]`` (also ``GOTO/x, y`` keeping z), ``FROM/x, y, z`` (sets the position),
  ``GODLTA/dx, dy, dz`` (relative move), ``GOHOME/x, y, z`` (rapid), ``TLAXIS/i, j, k``.
  Tool axes are read and checked: anything other than (0, 0, 1) is an :class:`InputError`
  "5-axis not supported yet" naming ``file:line``. How many axes were read is reported in the
  warnings (the model has no per-move tool axis yet).
* ``MOVARC/cx, cy, cz, i, j, k, r, ANGLE, a`` followed by the ``GOTO`` of the arc's end (Fusion; also
  the keyword form ``MOVARC/CENTER, cx, cy, cz, AXIS, i, j, k, RADIUS, r[, ANGLE, a]``): the arc
  turns counter-clockwise about (i, j, k) (right-hand rule) by ``a`` degrees (Autodesk's post negates
  the plane normal for clockwise arcs). Revisions of the Autodesk post before 2021 wrote the plane
  normal for both senses; when the end point only fits the stated angle in the opposite sense, that
  sense is used and a warning says so.
* NX ``CIRCLE/cx, cy, cz, i, j, k, r[, t, f, d, e][, TIMES, n]`` followed by its ``GOTO``: NX states
  the axis for *clockwise* motion, so the arc turns clockwise about (i, j, k); ``TIMES, n`` adds n
  full turns (see :mod:`fusioncut.io.apt_arcs`). The convention belongs to the record, not the file:
  Fusion's post never writes ``CIRCLE``. The file is recognised as an NX CLSF by NX's own records
  (``TOOL PATH``, ``TLDATA``, ``MSYS``, ``END-OF-PATH``, ``PAINT`` at the start of a line); a ``CIRCLE``
  in a file without any of them is read the NX way all the same and a warning says so. When most
  ``CIRCLE`` arcs that join a feed line tangentially start straight back against it, a warning says
  the file seems to state its axes the other way round.
  Helices (end off the arc plane) are kept; the axis must be +-x, +-y or +-z.
* ``CUTTER/d[, r[, e, f, alpha[, beta, h]]]`` and NX ``TLDATA/MILL, d, r, l, beta, alpha[, e, f
  [, r2, e2, f2]]`` - see :func:`cutter_from_parameters` for how the parameters become a tool.
* ``LOADTL/n, ...``, NX ``LOAD/TOOL, n[, ADJUST, m]`` and ``SELECT/TOOL, n`` - tool numbers.
* ``SPINDL/rpm[, RPM][, CLW|CCLW]``, ``SPINDL/RPM, rpm, CLW``, ``SPINDL/ON|OFF|CLW|CCLW``. ``OFF`` keeps
  the last speed: Autodesk's APT post writes ``SPINDL/OFF`` for *start spindle* (and ``ON`` for stop).
* ``CYCLE/type, depth, [INCR, i,] MMPM|IPM, f, clearance[, RAPTO, r][, DWELL, q]`` ... ``CYCLE/OFF``
  as Fusion writes them: each ``GOTO`` inside the cycle is the hole *bottom*, ``clearance`` the
  absolute clearance height, ``RAPTO`` the distance from there down to the retract plane. Each hole is
  expanded to rapid to clearance, rapid to the retract plane, feed to the bottom, rapid back up; pecks,
  dwells and spindle reversals are not modelled (warning). NX cycles (``FEDTO`` ...) are refused.
* ``TOOL PATH/operation, TOOL, tool-name`` and ``END-OF-PATH`` (NX operation boundaries); in
  Fusion files the operation name is the first ``PPRINT`` after the previous motion and before the
  next ``CUTTER``/``LOADTL`` (the post writes the operation comment there).
* ``FINI`` ends the program; later text is ignored.

Refused with an :class:`InputError`: NX ``NURBS`` (and ``KNOT``) spline motion, which is not
evaluated (a program that lost it would cut a different part), APT part-program source (``name=GEOM/...`` definitions, ``GOFWD``,
``GOLFT``, ``INDIRV``...), CL transformations (``ORIGIN``, ``TRANS``, ``COPY``, ``TRACUT``, ``REFSYS``),
``RETRCT``, ``MODE/TURN``, and any malformed record. Zero-length motions are dropped. The first
motion of a program has no known start: it only sets the position (a warning is given when it is a feed).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

from fusioncut.errors import (
    FusionCutError,
    InputError,
    SourceLocation,
    ToolDefinitionError,
)
from fusioncut.io.apt_arcs import (
    MAX_EXTRA_TURNS,
    TangentCheck,
    nx_circle_axis,
    nx_marker_line,
    solve_arc,
)
from fusioncut.io.apt_lexer import NUMBER, Record, records
from fusioncut.io.cutters import (
    ToolRegistry,
    check_tool_axis,
    cutter_from_parameters,
    finite,
)
from fusioncut.io.text import read_source_text
from fusioncut.model.moves import ArcMove, LinearMove, Move, Point, Toolpath
from fusioncut.model.tools import (
    ASSUMED_FLUTE_LENGTH_DIAMETERS,
    ChamferMill,
    MillingTool,
    SpindleDirection,
    TaperedEndMill,
)
from fusioncut.model.units import MM_PER_INCH

__all__ = ["read_apt", "cutter_from_parameters"]

_DIM_TOL = 1e-6  # mm; dimensions closer than this are equal


# --------------------------------------------------------------------------------------------------
# the reader

_IGNORED = {
    "PARTNO", "MACHIN", "PPRINT", "COOLNT", "DELAY", "DWELL", "STOP", "OPSTOP", "END", "PAINT", "MSYS",
    "MULTAX", "CLRSRF", "PLABEL", "SEQNO", "OPSKIP", "AUTOPS", "OFSTNO", "TLON", "HEAD", "POSTN",
    "PITCH", "MCS", "TURRET", "LINTOL", "INTOL", "OUTTOL", "CUTTOL", "OPERATION TYPE", "PREFUN", "AUXFUN",
    "DISPLY", "DRAFT", "NOPOST", "LEADER", "CLAMP", "UNCLMP",
}
_REFUSED = {
    "GOFWD": "APT part-program source", "GOLFT": "APT part-program source", "GORGT": "APT part-program source",
    "GOBACK": "APT part-program source", "GOUP": "APT part-program source", "GODOWN": "APT part-program source",
    "GO": "APT part-program source", "INDIRV": "APT part-program source", "INDIRP": "APT part-program source",
    "PSIS": "APT part-program source", "TLLFT": "APT part-program source", "TLRGT": "APT part-program source",
    "ORIGIN": "a CL transformation", "TRANS": "a CL transformation", "COPY": "a CL transformation",
    "TRACUT": "a CL transformation", "REFSYS": "a CL transformation", "INDEX": "a CL transformation",
    "RETRCT": "a retract to an undefined clearance plane",
}
# motion statements that may not come between an arc statement and the GOTO of its end
_BREAKS_ARC = {"RAPID", "GODLTA", "GOHOME", "FROM", "MOVARC", "CIRCLE", "CYCLE"}
_FEED_UNITS = {"MMPM": (1.0, False), "IPM": (MM_PER_INCH, False), "MMPR": (1.0, True), "IPR": (MM_PER_INCH, True)}


@dataclass
class _PendingArc:
    rec: Record
    center: Point
    axis: tuple[float, float, float]
    radius: float | None
    sweep_deg: float | None
    extra_turns: int = 0  # NX ``TIMES, n``


@dataclass
class _Cycle:
    rec: Record
    feed: float  # mm/min or mm/rev as stated (scaled)
    per_rev: bool
    clearance: float  # mm, absolute
    rapto: float  # mm below the clearance height


@dataclass
class _Cutter:
    tool: MillingTool
    where: SourceLocation
    token: int


@dataclass
class _State:
    scale: float = 1.0
    units_seen: bool = False
    pos: Point | None = None
    feed: float | None = None  # as stated, scaled to mm
    feed_per_rev: bool = False
    rpm: float | None = None
    spindle: SpindleDirection = SpindleDirection.CW
    rapid_next: bool = False
    arc: _PendingArc | None = None
    cycle: _Cycle | None = None
    cutter: _Cutter | None = None
    tool_number: int | None = None
    tool_name: str = ""
    operation: str = ""
    pprints: list[str] = field(default_factory=list)
    axes_read: int = 0
    flipped_arcs: list[SourceLocation] = field(default_factory=list)
    circle_joints: TangentCheck = field(default_factory=TangentCheck)


class _AptReader:
    def __init__(self, path: str | Path):
        self.file = str(path)
        self.s = _State()
        self.moves: list[Move] = []
        self.warnings: list[str] = []
        self.registry = ToolRegistry(self.warnings.append)
        self._warned: set[str] = set()
        self._tokens = 0
        self._unknown_tool_warned: set[int | None] = set()
        self._tool_cache: dict[tuple, int] = {}
        self.nx_marker: int | None = None  # line of the first NX-only record (see apt_arcs.nx_marker_line)

    # -- small utilities ---------------------------------------------------------------------------
    def where(self, rec: Record) -> SourceLocation:
        return SourceLocation(self.file, rec.line)

    def warn_once(self, key: str, message: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(message)

    def num(self, rec: Record, token: str, what: str) -> float:
        t = token.strip()
        if not NUMBER.fullmatch(t):
            raise InputError(f"{rec.major}: expected a number for {what}, got {token.strip()!r}", self.where(rec))
        return finite(float(t.replace("D", "E").replace("d", "e")), what, self.where(rec))

    def fields(self, rec: Record) -> list[str]:
        """The record's comma-separated fields; a trailing empty one is tolerated, inner ones are not."""
        args = list(rec.args)
        if args and args[-1] == "":
            args.pop()
        if "" in args:
            raise InputError(f"{rec.major}: empty field in {rec.rest.strip()!r}", self.where(rec))
        return args

    def nums(self, rec: Record, tokens: tuple[str, ...] | list[str], what: str) -> list[float]:
        return [self.num(rec, t, what) for t in tokens]

    @staticmethod
    def is_number(token: str) -> bool:
        return bool(NUMBER.fullmatch(token.strip()))

    def length(self, value: float) -> float:
        return value * self.s.scale

    # -- driver ------------------------------------------------------------------------------------
    def run(self, text: str) -> Toolpath:
        handlers: dict[str, Callable[[Record], None]] = {
            "UNITS": self.on_units, "FEDRAT": self.on_fedrat, "RAPID": self.on_rapid, "GOTO": self.on_goto,
            "FROM": self.on_from, "GODLTA": self.on_godlta, "GOHOME": self.on_gohome, "TLAXIS": self.on_tlaxis,
            "MOVARC": self.on_movarc, "CIRCLE": self.on_circle, "CUTTER": self.on_cutter, "TLDATA": self.on_tldata,
            "LOADTL": self.on_loadtl, "LOAD": self.on_load, "SELECT": self.on_load, "SPINDL": self.on_spindl,
            "CYCLE": self.on_cycle, "TOOL PATH": self.on_tool_path, "END-OF-PATH": self.on_end_of_path,
            "PPRINT": self.on_pprint, "MODE": self.on_mode, "CUTCOM": self.on_cutcom, "INSERT": self.on_insert,
            "NURBS": self.on_nurbs, "KNOT": self.on_nurbs,
        }
        self.nx_marker = nx_marker_line(text)
        for rec in records(text):
            if "=" in rec.major or "(" in rec.major:
                raise InputError(
                    f"{rec.major!r} looks like APT part-program source (a definition), not CL data", self.where(rec)
                )
            if rec.major == "FINI":
                break
            if rec.major in _REFUSED:
                raise InputError(f"{rec.major} is {_REFUSED[rec.major]}; not supported in CL data", self.where(rec))
            if self.s.arc is not None and rec.major in _BREAKS_ARC:
                raise InputError(f"arc at line {self.s.arc.rec.line} is not followed by the GOTO of its end point",
                                 self.where(rec))
            handler = handlers.get(rec.major)
            try:
                if handler is not None:
                    handler(rec)
                elif rec.major not in _IGNORED:
                    self.warn_once(f"unknown:{rec.major}", f"{self.where(rec)}: {rec.major} statements are ignored")
            except FusionCutError:
                raise
            except (ValueError, ArithmeticError) as e:  # defensive: never leak a bare Python error
                raise InputError(f"cannot interpret {rec.major}: {e}", self.where(rec)) from e
        if self.s.arc is not None:
            raise InputError("arc is not followed by the GOTO of its end point", self.where(self.s.arc.rec))
        return self.finish()

    def finish(self) -> Toolpath:
        if not self.moves:
            raise InputError("no tool motion found (no GOTO records): is this APT CL data?", SourceLocation(self.file))
        if not self.s.units_seen:
            self.warnings.insert(0, f"{self.file}: no UNITS statement; millimetres assumed")
        if self.s.axes_read:
            self.warnings.append(f"{self.file}: tool axis read on {self.s.axes_read} records, all (0, 0, 1)")
        if self.s.flipped_arcs:
            self.warnings.append(
                f"{self.s.flipped_arcs[0]}: {len(self.s.flipped_arcs)} arc(s) turn against their stated axis; "
                "their sense was taken from the end point (older Autodesk APT posts write the plane normal)"
            )
        reversed_circles = self.s.circle_joints.warning()
        if reversed_circles:
            self.warnings.append(reversed_circles)
        return Toolpath(tuple(self.moves), dict(self.registry.tools), tuple(self.warnings), self.file)

    # -- motion ------------------------------------------------------------------------------------
    def current_tool(self, rec: Record) -> int | None:
        s = self.s
        if s.cutter is None:
            if s.tool_number is not None and s.tool_number not in self._unknown_tool_warned:
                self._unknown_tool_warned.add(s.tool_number)
                self.warnings.append(f"{self.where(rec)}: T{s.tool_number} has no CUTTER/TLDATA geometry")
            return s.tool_number
        # building a tool validates its geometry: do it once per (definition, number, name, spindle)
        key = (s.tool_number, s.cutter.token, s.tool_name, s.spindle)
        if key not in self._tool_cache:
            tool = s.cutter.tool
            tool = replace(tool, name=tool.name or s.tool_name, spindle=s.spindle)
            self._tool_cache[key] = self.registry.register(s.tool_number, tool, s.cutter.where)
        return self._tool_cache[key]

    def feed_now(self, rec: Record) -> float:
        s = self.s
        if s.feed is None:
            raise InputError("feed move before any FEDRAT", self.where(rec))
        if s.feed_per_rev:
            if not s.rpm:
                raise InputError("feed per revolution without a spindle speed", self.where(rec))
            return s.feed * s.rpm
        return s.feed

    def emit_linear(self, end: Point, rec: Record, rapid: bool, feed: float | None = None) -> None:
        s = self.s
        if s.pos is None:
            s.pos = end
            if not rapid:
                self.warnings.append(
                    f"{self.where(rec)}: the first motion is a feed move from an unknown position; "
                    "it only sets the position"
                )
            return
        if end == s.pos:
            return
        if not rapid and feed is None:
            feed = self.feed_now(rec)
        move = LinearMove(
            start=s.pos, end=end, feed=None if rapid else feed, spindle_rpm=s.rpm, tool=self.current_tool(rec),
            operation=s.operation, source=self.where(rec), rapid=rapid,
        )
        self.moves.append(move)
        s.pos = end
        s.pprints.clear()

    def point(self, rec: Record, what: str = "GOTO") -> tuple[Point, tuple[float, float, float] | None]:
        """(x, y, z) in mm and the tool axis if given, from a GOTO-like record."""
        args = self.fields(rec)
        if len(args) == 2:
            if self.s.pos is None:
                raise InputError(f"{what}/x, y without a known z", self.where(rec))
            x, y = (finite(self.length(v), "coordinate", self.where(rec)) for v in self.nums(rec, args, "coordinate"))
            return (x, y, self.s.pos[2]), None
        if len(args) not in (3, 6):
            raise InputError(f"{what} needs x, y, z or x, y, z, i, j, k; got {len(args)} values", self.where(rec))
        vals = self.nums(rec, args, "a coordinate")
        p = (self.length(vals[0]), self.length(vals[1]), self.length(vals[2]))
        for v in p:
            finite(v, "coordinate", self.where(rec))
        axis = None
        if len(vals) == 6:
            axis = (vals[3], vals[4], vals[5])
            check_tool_axis(axis, self.where(rec))
            self.s.axes_read += 1
        return p, axis

    def on_goto(self, rec: Record) -> None:
        s = self.s
        end, _ = self.point(rec)
        if s.arc is not None:
            self.emit_arc(end)
            return
        if s.cycle is not None:
            self.emit_cycle_point(end, rec)
            return
        rapid, s.rapid_next = s.rapid_next, False
        self.emit_linear(end, rec, rapid)

    def on_rapid(self, rec: Record) -> None:
        self.s.rapid_next = True

    def on_from(self, rec: Record) -> None:
        self.s.pos, _ = self.point(rec, "FROM")

    def on_gohome(self, rec: Record) -> None:
        end, _ = self.point(rec, "GOHOME")
        self.s.rapid_next = False
        self.emit_linear(end, rec, rapid=True)

    def on_godlta(self, rec: Record) -> None:
        if self.s.pos is None:
            raise InputError("GODLTA from an unknown position", self.where(rec))
        args = self.fields(rec)
        if len(args) == 1:  # GODLTA/dz moves along the tool axis, which is +z here
            d = (0.0, 0.0, self.num(rec, args[0], "a distance"))
        elif len(args) == 3:
            v = self.nums(rec, args, "a distance")
            d = (v[0], v[1], v[2])
        else:
            raise InputError(f"GODLTA needs dz or dx, dy, dz; got {len(args)} values", self.where(rec))
        p = self.s.pos
        end = tuple(finite(p[i] + self.length(d[i]), "coordinate", self.where(rec)) for i in range(3))
        rapid, self.s.rapid_next = self.s.rapid_next, False
        self.emit_linear((end[0], end[1], end[2]), rec, rapid)

    def on_tlaxis(self, rec: Record) -> None:
        args = self.fields(rec)
        if len(args) < 3 or not all(self.is_number(a) for a in args[:3]):
            raise InputError("TLAXIS needs i, j, k", self.where(rec))
        v = self.nums(rec, args[:3], "an axis component")
        check_tool_axis((v[0], v[1], v[2]), self.where(rec))
        self.s.axes_read += 1

    # -- arcs --------------------------------------------------------------------------------------
    def on_movarc(self, rec: Record) -> None:
        args = [a.upper() for a in self.fields(rec)]
        center = axis = None
        radius = sweep = None
        if args and not self.is_number(args[0]):  # keyword form
            i = 0
            while i < len(args):
                word = args[i]
                take = {"CENTER": 3, "AXIS": 3, "RADIUS": 1, "ANGLE": 1}.get(word)
                if take is None:
                    raise InputError(f"MOVARC: unexpected {word!r}", self.where(rec))
                if i + take > len(args) - 1:
                    raise InputError(f"MOVARC: {word} needs {take} value(s)", self.where(rec))
                vals = self.nums(rec, args[i + 1 : i + 1 + take], word.lower())
                if word == "CENTER":
                    center = (vals[0], vals[1], vals[2])
                elif word == "AXIS":
                    axis = (vals[0], vals[1], vals[2])
                elif word == "RADIUS":
                    radius = vals[0]
                else:
                    sweep = vals[0]
                i += 1 + take
        else:
            if len(args) < 7:
                raise InputError(f"MOVARC needs cx, cy, cz, i, j, k, r; got {len(args)} values", self.where(rec))
            v = self.nums(rec, args[:7], "an arc parameter")
            center, axis, radius = (v[0], v[1], v[2]), (v[3], v[4], v[5]), v[6]
            rest = args[7:]
            if rest:
                if len(rest) != 2 or rest[0] != "ANGLE":
                    raise InputError("MOVARC: expected ', ANGLE, a' after the radius", self.where(rec))
                sweep = self.num(rec, rest[1], "the arc angle")
        if center is None or axis is None:
            raise InputError("MOVARC needs CENTER and AXIS", self.where(rec))
        self.start_arc(rec, center, axis, radius, sweep)

    def on_circle(self, rec: Record) -> None:
        """NX ``CIRCLE/x, y, z, i, j, k, r[, t, f, d, e][, TIMES, n]``: the axis assumes clockwise motion."""
        args = self.fields(rec)
        if len(args) < 7:
            raise InputError(f"CIRCLE needs cx, cy, cz, i, j, k, r; got {len(args)} values", self.where(rec))
        v = self.nums(rec, args[:7], "an arc parameter")
        extra_turns = 0
        rest = [a.upper() for a in args[7:]]
        i = 0
        while i < len(rest):
            if rest[i] == "TIMES":
                if i + 1 >= len(rest):
                    raise InputError("CIRCLE: TIMES needs the number of full turns", self.where(rec))
                n = self.num(rec, rest[i + 1], "the number of turns")
                if n != int(n) or not 1 <= n <= MAX_EXTRA_TURNS:
                    raise InputError(
                        f"CIRCLE: TIMES must be a whole number from 1 to {MAX_EXTRA_TURNS}, got {rest[i + 1]!r}",
                        self.where(rec),
                    )
                extra_turns = int(n)
                i += 2
            elif self.is_number(rest[i]):  # tolerance, its ratio, tool diameter and corner radius
                self.num(rec, rest[i], "a CIRCLE parameter")
                i += 1
            else:
                raise InputError(f"CIRCLE: unexpected {args[7 + i]!r}", self.where(rec))
        if self.nx_marker is None:
            self.warn_once(
                "circle-dialect",
                f"{self.where(rec)}: CIRCLE read as Siemens NX writes it (clockwise about the stated axis), "
                "although the file has none of NX's TOOL PATH, TLDATA, MSYS, END-OF-PATH or PAINT records",
            )
        axis = nx_circle_axis((v[3], v[4], v[5]))
        self.start_arc(rec, (v[0], v[1], v[2]), axis, v[6], None, extra_turns)

    def on_nurbs(self, rec: Record) -> None:
        raise InputError(
            f"{rec.major} record: spline (NURBS) motion is not supported, and the program cannot run without "
            "it; output the operation as lines and arcs (NX: the operation's Motion Output Type)",
            self.where(rec),
        )

    def start_arc(self, rec: Record, center: Point, axis: tuple[float, float, float], radius: float | None,
                  sweep: float | None, extra_turns: int = 0) -> None:
        """Remember an arc statement (program units, ``axis`` counter-clockwise) until the GOTO of its end."""
        if self.s.cycle is not None:
            raise InputError("arc inside a drilling cycle", self.where(rec))
        c = (self.length(center[0]), self.length(center[1]), self.length(center[2]))
        self.s.arc = _PendingArc(rec, c, axis, None if radius is None else self.length(radius), sweep, extra_turns)

    def emit_arc(self, end: Point) -> None:
        s = self.s
        arc = s.arc
        assert arc is not None
        s.arc = None
        where = self.where(arc.rec)
        if s.rapid_next:
            raise InputError("RAPID before an arc: rapid arcs are not defined", where)
        if s.pos is None:
            raise InputError("arc from an unknown position (no motion before it)", where)
        sol = solve_arc(s.pos, end, arc.center, arc.axis, where, radius=arc.radius, sweep_deg=arc.sweep_deg)
        if sol.sense_from_end_point:
            s.flipped_arcs.append(where)
        move = ArcMove(
            start=s.pos, end=end, feed=self.feed_now(arc.rec), spindle_rpm=s.rpm, tool=self.current_tool(arc.rec),
            operation=s.operation, source=where, center=sol.center, plane=sol.plane, clockwise=sol.clockwise,
            turns=sol.turns + arc.extra_turns,
        )
        if arc.rec.major == "CIRCLE":
            s.circle_joints.add(self.moves[-1] if self.moves else None, move)
        self.moves.append(move)
        s.pos = end
        s.pprints.clear()

    # -- cycles ------------------------------------------------------------------------------------
    def on_cycle(self, rec: Record) -> None:
        args = [a.upper() for a in self.fields(rec)]
        if not args:
            raise InputError("CYCLE needs a type", self.where(rec))
        kind = args[0]
        if kind == "OFF":
            self.s.cycle = None
            return
        if kind in {"ON", "AVOID", "NOMORE"}:
            self.warn_once(f"cycle:{kind}", f"{self.where(rec)}: CYCLE/{kind} ignored")
            return
        words = args[1:]
        if "FEDTO" in words or "RTRCTO" in words:
            raise InputError("NX-style CYCLE (FEDTO/RTRCTO) not supported yet", self.where(rec))
        feed = clearance = None
        per_rev = False
        rapto = 0.0
        i = 0
        seen_depth = False
        while i < len(words):
            w = words[i]
            if w in _FEED_UNITS:
                unit, per_rev = _FEED_UNITS[w]
                if i + 2 > len(words) - 1:
                    raise InputError("CYCLE: feed unit must be followed by feed and clearance", self.where(rec))
                feed = self.num(rec, words[i + 1], "the cycle feed") * unit
                clearance = self.length(self.num(rec, words[i + 2], "the cycle clearance"))
                i += 3
            elif w in {"RAPTO", "DWELL", "INCR", "ORIENT", "DEPTH", "STEP"}:
                if i + 1 >= len(words):
                    raise InputError(f"CYCLE: {w} needs a value", self.where(rec))
                v = self.num(rec, words[i + 1], w.lower())
                if w == "RAPTO":
                    rapto = self.length(v)
                i += 2
            elif self.is_number(w) and not seen_depth:
                self.num(rec, w, "the cycle depth")
                seen_depth = True
                i += 1
            elif self.is_number(w):  # e.g. the fine-boring shift; it does not change the geometry
                self.num(rec, w, "a cycle parameter")
                i += 1
            else:
                raise InputError(f"CYCLE/{kind}: unexpected {w!r}", self.where(rec))
        if feed is None or clearance is None:
            raise InputError(
                f"CYCLE/{kind}: expected the Autodesk form 'type, depth, MMPM|IPM, feed, clearance[, RAPTO, r]'",
                self.where(rec),
            )
        if feed <= 0:
            raise InputError("CYCLE: feed must be > 0", self.where(rec))
        self.s.cycle = _Cycle(rec, feed, per_rev, clearance, rapto)
        self.warn_once(
            "cycle", f"{self.where(rec)}: canned cycles are expanded as single plunges "
            "(pecks, dwells and spindle reversal are not modelled)"
        )

    def emit_cycle_point(self, bottom: Point, rec: Record) -> None:
        cyc = self.s.cycle
        assert cyc is not None
        x, y, zb = bottom
        retract = cyc.clearance - cyc.rapto
        if retract < zb - _DIM_TOL:
            raise InputError(
                f"hole bottom z={zb:.6g} lies above the retract plane z={retract:.6g}", self.where(rec)
            )
        self.s.rapid_next = False
        feed = cyc.feed
        if cyc.per_rev:
            if not self.s.rpm:
                raise InputError("cycle feed per revolution without a spindle speed", self.where(rec))
            feed *= self.s.rpm
        self.emit_linear((x, y, cyc.clearance), rec, rapid=True)
        self.emit_linear((x, y, retract), rec, rapid=True)
        self.emit_linear((x, y, zb), rec, rapid=False, feed=feed)
        self.emit_linear((x, y, cyc.clearance), rec, rapid=True)

    # -- tools -------------------------------------------------------------------------------------
    def new_cutter(self, rec: Record, tool: MillingTool) -> None:
        self._tokens += 1
        self.s.cutter = _Cutter(tool, self.where(rec), self._tokens)
        self.take_operation_name()

    def take_operation_name(self) -> None:
        if self.s.pprints:
            self.s.operation = self.s.pprints[0]
            self.s.pprints.clear()

    def on_cutter(self, rec: Record) -> None:
        args = self.fields(rec)
        if not args or not all(self.is_number(a) for a in args):
            raise InputError("CUTTER needs numeric parameters d[, r[, e, f, alpha[, beta, h]]]", self.where(rec))
        v = self.nums(rec, args, "a cutter parameter")
        if len(v) not in (1, 2, 5, 6, 7):
            raise InputError(f"CUTTER takes 1, 2, 5 or 7 parameters, got {len(v)}", self.where(rec))
        d = self.length(v[0])
        r = self.length(v[1]) if len(v) > 1 else 0.0
        e = self.length(v[2]) if len(v) > 2 else None
        f = self.length(v[3]) if len(v) > 3 else None
        alpha = v[4] if len(v) > 4 else 0.0
        beta = v[5] if len(v) > 5 else 0.0
        if len(v) == 7 and v[6] > 0:
            h = self.length(v[6])
        else:
            h = ASSUMED_FLUTE_LENGTH_DIAMETERS * max(d, 2 * r)
            self.warnings.append(
                f"{self.where(rec)}: CUTTER gives no flute length; assumed "
                f"{ASSUMED_FLUTE_LENGTH_DIAMETERS:g} x diameter = {h:.4g} mm"
            )
        if d <= _DIM_TOL and r <= _DIM_TOL and beta > 0:
            self.warnings.append(
                f"{self.where(rec)}: CUTTER with zero diameter read as a pointed cone of half-angle {beta:g} deg "
                "(Fusion writes drills this way too; a drill would be modelled wrongly)"
            )
        tool = cutter_from_parameters(d, r, alpha, beta, h, self.where(rec), e=e, f=f)
        if beta > 0 and isinstance(tool, (TaperedEndMill, ChamferMill)):
            self.warnings.append(
                f"{self.where(rec)}: CUTTER gives no largest diameter; the {beta:g} deg taper is assumed to run "
                f"up the whole flute length ({h:.4g} mm)"
            )
        self.new_cutter(rec, tool)

    def on_tldata(self, rec: Record) -> None:
        args = self.fields(rec)
        kind = args[0].upper() if args else ""
        if kind != "MILL":
            raise ToolDefinitionError(
                f"TLDATA/{kind or '?'} tools are not modelled (milling tools only)", self.where(rec)
            )
        vals = args[1:]
        if len(vals) < 3 or not all(self.is_number(a) for a in vals):
            raise InputError("TLDATA/MILL needs d, r, l[, taper, tip angle[, ...]]", self.where(rec))
        v = self.nums(rec, vals, "a tool parameter")
        d, r, length = self.length(v[0]), self.length(v[1]), self.length(v[2])
        beta = v[3] if len(v) > 3 else 0.0
        alpha = v[4] if len(v) > 4 else 0.0
        e = self.length(v[5]) if len(v) > 6 else None
        f = self.length(v[6]) if len(v) > 6 else None
        if len(v) > 7 and v[7] > _DIM_TOL:
            raise ToolDefinitionError(
                "TLDATA/MILL with an upper radius (barrel/lollipop form) is not modelled", self.where(rec)
            )
        if len(v) > 6 and abs(alpha) < 1e-9 and abs(beta) < 1e-9:
            e = f = None  # the named families need no corner centre
        # NX gives only the tool length: the whole of it is taken as fluted
        self.new_cutter(rec, cutter_from_parameters(d, r, alpha, beta, length, self.where(rec), e=e, f=f))

    def tool_number_from(self, rec: Record, token: str) -> int:
        v = self.num(rec, token, "the tool number")
        if v != int(v) or v < 0:
            raise InputError(f"tool number must be a whole number >= 0, got {token.strip()!r}", self.where(rec))
        return int(v)

    def on_loadtl(self, rec: Record) -> None:
        args = self.fields(rec)
        if not args:
            raise InputError("LOADTL needs a tool number", self.where(rec))
        self.s.tool_number = self.tool_number_from(rec, args[0])
        self.take_operation_name()

    def on_load(self, rec: Record) -> None:
        args = self.fields(rec)
        if len(args) < 2 or args[0].upper() != "TOOL":
            self.warn_once(f"load:{rec.rest}", f"{self.where(rec)}: {rec.major}/{rec.rest.strip()} ignored")
            return
        self.s.tool_number = self.tool_number_from(rec, args[1])
        self.take_operation_name()

    def on_spindl(self, rec: Record) -> None:
        s = self.s
        words = [a.upper() for a in self.fields(rec)]
        if any(w in {"SFM", "SMM"} for w in words):
            self.warn_once("css", f"{self.where(rec)}: constant surface speed ignored; spindle speed unknown")
            return
        speed_seen = False
        for w in words:
            if w == "CLW":
                s.spindle = SpindleDirection.CW
            elif w == "CCLW":
                s.spindle = SpindleDirection.CCW
            elif w in {"ON", "OFF", "RPM", "RANGE", "LOW", "HIGH", "MEDIUM", "MAXRPM", "ORIENT", "LOCK"}:
                pass
            elif self.is_number(w):
                value = self.num(rec, w, "the spindle speed")
                if speed_seen:
                    continue  # further numbers are gear ranges and the like
                if value < 0:
                    raise InputError(f"spindle speed must be >= 0, got {value:g}", self.where(rec))
                s.rpm, speed_seen = value, True
            else:
                raise InputError(f"SPINDL: unexpected {w!r}", self.where(rec))

    # -- feeds, units, bookkeeping -----------------------------------------------------------------
    def on_units(self, rec: Record) -> None:
        word = rec.args[0].upper() if rec.args else ""
        if word in {"MM", "MILLIMETERS", "MILLIMETRES", "METRIC"}:
            self.s.scale = 1.0
        elif word in {"INCHES", "INCH", "IN"}:
            self.s.scale = MM_PER_INCH
        else:
            raise InputError(f"UNITS/{word or '?'}: expected MM or INCHES", self.where(rec))
        self.s.units_seen = True
        self.s.pprints.clear()  # header comments are not operation names

    def on_fedrat(self, rec: Record) -> None:
        args = [a.upper() for a in self.fields(rec)]
        value = None
        unit, per_rev = self.s.scale, False
        for w in args:
            if w in _FEED_UNITS:
                unit, per_rev = _FEED_UNITS[w]
            elif w in {"PERMIN"}:
                unit, per_rev = self.s.scale, False
            elif w in {"PERREV"}:
                unit, per_rev = self.s.scale, True
            elif self.is_number(w) and value is None:
                value = self.num(rec, w, "the feed")
            else:
                raise InputError(f"FEDRAT: unexpected {w!r}", self.where(rec))
        if value is None:
            raise InputError("FEDRAT needs a feed value", self.where(rec))
        if value <= 0:
            raise InputError(f"feed must be > 0, got {value:g}", self.where(rec))
        self.s.feed = value * unit
        self.s.feed_per_rev = per_rev

    def on_tool_path(self, rec: Record) -> None:
        args = list(rec.args)
        self.s.operation = args[0] if args else ""
        self.s.tool_name = ""
        if len(args) >= 3 and args[1].upper() == "TOOL":
            self.s.tool_name = args[2]
        self.s.pprints.clear()

    def on_end_of_path(self, rec: Record) -> None:
        self.s.operation = ""

    def on_pprint(self, rec: Record) -> None:
        text = rec.rest.strip()
        if len(text) >= 2 and text[0] == text[-1] == "'":
            text = text[1:-1]
        if text:
            self.s.pprints.append(text.strip())

    def on_mode(self, rec: Record) -> None:
        word = rec.args[0].upper() if rec.args else ""
        if word and word != "MILL":
            raise InputError(f"MODE/{word}: only milling programs are supported", self.where(rec))

    def on_cutcom(self, rec: Record) -> None:
        words = {a.upper() for a in rec.args}
        if words & {"LEFT", "RIGHT"}:
            self.warn_once(
                "cutcom", f"{self.where(rec)}: cutter compensation requested; CL points are read as tool-tip positions"
            )

    def on_insert(self, rec: Record) -> None:
        self.warn_once("insert", f"{self.where(rec)}: INSERT (raw controller code) ignored")


def read_apt(path: str | Path) -> Toolpath:
    """Read an APT CL file (Fusion APT post or NX CLSF) into a :class:`Toolpath` in mm and mm/min.

    Raises :class:`InputError` (or its subclass :class:`ToolDefinitionError`) naming ``file:line``
    for anything malformed or unsupported, including tool axes other than +z.
    """
    reader = _AptReader(path)
    return reader.run(read_source_text(path))
