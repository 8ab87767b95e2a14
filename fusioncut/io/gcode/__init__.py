"""RS274/NGC G-code (LinuxCNC dialect): an interpreter producing a :class:`~fusioncut.model.moves.Toolpath`,
a feed rewriter and a writer.

Written by hand: no maintained PyPI package interprets G-code with LinuxCNC's semantics (parameters,
expressions, O-word subroutines and loops, canned cycles in all three planes, G92/G10 offsets,
G28/G30, inverse time feed). The tests compare our moves with the canonical output of LinuxCNC's own
``rs274`` interpreter, move by move, for every reference program in ``shared/data``.

Public API
----------
``read_gcode(path, *, tools=None, strict=False, arc_centers="auto", max_moves=1_000_000) -> Toolpath`` and
``parse_gcode_text(text, *, source="<memory>", ...)``; :class:`GCodeInterpreter` runs a program
block by block (``step()``, iteration, ``execute(line)`` for single MDI lines) with the modal state
inspectable after each block as a frozen :class:`ModalState`. :func:`rewrite_feeds` /
:func:`rewrite_gcode_file` change a program's ``F`` words and nothing else; :func:`write_gcode` writes
a toolpath as a program this package reads back to the same moves.

Modules, from the bottom up (each imports only those above it):

* :mod:`.lexer` reads a line into a ``Block`` (words, expressions, O-words, comments);
  :mod:`.modal` holds the modal-group tables and :class:`ModalState`; :mod:`.budget` the work budget;
  :mod:`.program_end` the warnings about where a program stopped; :mod:`.tool_comments` the tools of
  Fusion/HSM tool comments;
* :mod:`.machine` is the machine state every part works on, and emits the moves;
* :mod:`.motion` (end points, arcs, splines), :mod:`.offsets` (G10, G92, G28/G30, tool length,
  parameters 5161-5426), :mod:`.cycles` (canned cycles), :mod:`.comp` (cutter compensation),
  :mod:`.settings` (feed, speed, tool, spindle, plane, units, distance modes) are functions of it;
  :mod:`.params` holds the parameters, :mod:`.flow` the program text and O-word flow control;
* :mod:`.interpreter` runs the blocks; :mod:`.files` reads files and text; :mod:`.rewrite` rewrites
  feeds; :mod:`.writer` writes programs.

Output
------
Moves are in the machine frame after work offsets (G54-G59.3, G92), in millimetres (G20 input is
converted, 1 in = 25.4 mm); the controlled point is the tool tip. Tool length offsets (G43 H, G43.1)
are recorded in the modal state but do not shift the tip; they only matter for targets given in
machine coordinates (G53, G28, G30), where the tip ends ``length`` below the programmed spindle
position. Lengths come from ``GCodeInterpreter(tool_lengths=...)`` or G10 L1/L10 and are 0 otherwise.
Feeds are in mm/min (``None`` for rapids): G94 ``F`` is per minute in program units, G93 inverse time
``F`` becomes ``F * move length`` (LinuxCNC's rule: the XYZ length, or the rotary length for purely
rotary moves), G95 ``F`` per revolution is multiplied by the programmed ``S``. ``spindle_rpm`` is the
programmed ``S``; the spindle direction (M3/M4/M5) is in :class:`ModalState` only, and M4 draws a
warning because moves cannot carry it yet. Angles of rotary axes are degrees.

Rules worth knowing
-------------------
* Operation names: a *standalone* comment line (only a comment, maybe an ``N`` number) that is not a
  tool description or a ``(MSG,...)``-style message is remembered; the first move after one or more
  such lines takes the last of them as its ``operation``, and later moves keep it until the next
  such comment. Fusion 360 and most posts write the operation name this way, e.g. ``(2D Adaptive1)``.
* Tools: ``T`` prepares, ``M6`` loads. Until the program's first ``M6``, a ``T`` word loads the
  tool directly, because posts for machines without a tool changer (Fusion's hobby posts) never
  write M6; after the first M6, a ``T`` only prepares the next tool (Fanuc-style pre-staging).
  Tool comments as Fusion/HSM posts write them, ``(T1 D=2.65 CR=0 - ZMIN=-12.55 - flat end mill)``,
  become :class:`~fusioncut.model.tools.MillingTool` objects in ``Toolpath.tools`` (flat, ball,
  bull-nose, chamfer, drill (``TAPER`` is its point angle, 118 degrees if absent), tapered; by the
  words and ``CR``/``TAPER``), in the program's units (its first G20/G21); the flute length is not
  in the comment and is taken as ``max(3 * D, -ZMIN)`` (:mod:`fusioncut.io.gcode.tool_comments`). A
  ``tools`` mapping passed in replaces them (the program's own are then in ``Toolpath.program_tools``,
  each with its ``file:line`` as source).
* Arc centres: ``arc_centers="auto"`` starts in G91.1 (incremental I/J/K). When an I/J/K arc fails
  LinuxCNC's radius check (start and end radius differ by more than 0.0283 mm / 0.00283 in and by
  more than 0.1 %, or by more than 100 times those lengths) while reading I/J/K as absolute centres
  passes it, the program is taken to use
  absolute centres without saying G90.1 (BOTTLE.NC from easy_gcode_plot does this); we switch to
  absolute centres for the rest of the program and warn, naming file:line. ``rs274`` stops there with
  "Radius to end of arc differs from radius to start", and so does ``arc_centers="incremental"``.
  ``"absolute"`` starts in G90.1. G90.1/G91.1 in the program still switch the mode.
* Full circles: an I/J/K arc ending where it starts (in the plane) is a full turn; ``P`` adds turns.
* Canned cycles G73, G74, G81-G89 expand into the rapids and feeds LinuxCNC makes, in G17/G18/G19,
  with G98/G99, R, L repeats and G91 (R relative to the initial level, Z relative to R). G83 retracts
  to R between pecks and G73 backs off 0.254 mm (0.010 in); G84/G74 feed back out to the clearance
  level (LinuxCNC 2.9 swaps axes of G84 feeds in G18/G19, see the tests; we do not copy that). G88
  ends with the operator's manual retract, which we record as a rapid to the clearance level.
* G5 (cubic, ``I J`` and ``P Q`` control point offsets) and G5.1 (quadratic B-spline, ``I J`` control
  point offset) in G17 are flattened into feeds whose chords stay within 0.001 mm of the exact curve
  (LinuxCNC approximates them with biarcs; there is no rs274 reference for them here). G5.2/G5.3
  NURBS are unsupported codes (see Strictness).
* Cutter radius compensation G41/G42/G41.1/G42.1 follows LinuxCNC (tool radius from the ``tools``
  mapping, G10 L1 R, or the D word of G41.1/G42.1), see :mod:`fusioncut.io.gcode.comp`.
* Rotary axes A/B/C are read and tracked; a move that turns one raises
  ``InputError("5-axis / rotary motion not supported yet")`` (``GCodeInterpreter(allow_rotary=True)``
  records them instead, for comparisons with rs274).
* Zero-length moves (LinuxCNC emits e.g. ``G0`` without axes, or re-positioning moves) are kept by
  the interpreter but dropped by :func:`read_gcode`, which counts them in one warning.
* ``/`` block delete lines are skipped (the block delete switch is on). A lone ``%`` line before the
  first block opens the program and a later lone ``%`` ends it; ``M2``/``M30`` end it too. Lines
  with words after the end are not read, and a warning names the line where reading stopped and
  counts them (:mod:`fusioncut.io.gcode.program_end`). A ``%`` line with text after the ``%`` (a hobby
  post's ``% vfd enable``) neither opens nor ends the program: LinuxCNC refuses it ("Bad character
  '%' used"), and so does ``strict``; otherwise it is ignored with a warning. A program that yields
  no moves gets a warning saying why.
* Work budget: ``max_moves`` (default 1,000,000; ``None`` or 0 for no limit) bounds the moves a
  program expands to, an arc's extra ``P`` turns counting as moves, and the blocks it executes (2
  per move and 100,000 more); an arc takes at most 1,000 turns. Repeat loops and blocks that expand are checked
  before they expand (:mod:`fusioncut.io.gcode.budget`); the error names ``file:line`` and the count.
* O-word subroutines are those defined in the same file (``O<name>`` files on a search path are not
  looked up); calls nest at most 10 deep, as in LinuxCNC.
* Strictness: unknown words, words no command in the block uses, unknown or unsupported G and M codes
  (e.g. M11, G33, G38.2, G76, user M100-M199) raise :class:`InputError` naming ``file:line:column``
  when ``strict=True``; otherwise they are ignored and recorded as a ``"file:line:col: ..."`` warning,
  and a block whose unknown code may have wanted its axis words does not move. So are feed moves
  without a feed rate (feed 0 when lenient). Errors that make the path unknowable (syntax, bad
  expressions, arcs that do not close, missing cycle words, undefined subroutines or parameters)
  raise in both modes.
"""
from __future__ import annotations

from fusioncut.io.gcode.budget import DEFAULT_MAX_MOVES, MoveBudget
from fusioncut.io.gcode.files import decode_gcode, parse_gcode_text, read_gcode, read_gcode_text
from fusioncut.io.gcode.interpreter import ArcCenters, GCodeInterpreter
from fusioncut.io.gcode.modal import ModalState
from fusioncut.io.gcode.rewrite import RewriteResult, rewrite_feeds, rewrite_gcode_file
from fusioncut.io.gcode.writer import write_gcode

__all__ = [
    "DEFAULT_MAX_MOVES", "ArcCenters", "GCodeInterpreter", "ModalState", "MoveBudget", "RewriteResult",
    "decode_gcode", "parse_gcode_text", "read_gcode", "read_gcode_text", "rewrite_feeds", "rewrite_gcode_file",
    "write_gcode",
]
