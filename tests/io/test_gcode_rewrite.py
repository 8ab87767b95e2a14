"""Rewriting feeds: only F words change, the program reads back to the same moves at the asked feeds.

Oracles: hand-written expected programs for the modal rules, the interpreter itself for the
read-back (moves equal but for the feed), and a line-by-line diff with the F words removed.
"""
from __future__ import annotations

import math
import re
from dataclasses import replace

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusioncut.errors import FusionCutError, InputError, SourceLocation
from fusioncut.io.gcode import parse_gcode_text
from fusioncut.io.gcode import rewrite_feeds, rewrite_gcode_file

from shared_data import DATA
FUSION = DATA / "fusion-posted/1055_utab_265bit.nc"
ARCSPIRAL = DATA / "linuxcnc-nc_files/arcspiral.ngc"
INVERSE = DATA / "linuxcnc-interp-oracle/inverse-time-with-comp/inverse.ngc"
G81 = DATA / "linuxcnc-interp-oracle/g81/g17/g98/g17-g98-g81.ngc"
needs_data = pytest.mark.skipif(not FUSION.exists(), reason="shared test data not available")

_F_WORD = re.compile(r"[Ff]\s*(?:[-+]?[0-9. ]*[0-9.]|\[[^\]]*\])")


def without_f(line: str) -> str:
    """The line with the F words of its code removed (comments kept as they are)."""
    out, i = [], 0
    for m in re.finditer(r"\([^)]*\)|;.*", line):
        out.append(_F_WORD.sub("", line[i:m.start()]).rstrip())
        out.append(m.group(0))
        i = m.end()
    out.append(_F_WORD.sub("", line[i:]).rstrip())
    return "".join(out).rstrip()


def only_f_changed(old: str, new: str) -> list[int]:
    """Asserts the two programs differ in F words only; returns the changed 1-based lines."""
    a, b = old.splitlines(keepends=True), new.splitlines(keepends=True)
    assert len(a) == len(b)
    changed = []
    for k, (x, y) in enumerate(zip(a, b), start=1):
        if x != y:
            # same line ending, same text once F words are gone
            assert x[len(x.rstrip("\r\n")):] == y[len(y.rstrip("\r\n")):]
            assert without_f(x.rstrip("\r\n")) == without_f(y.rstrip("\r\n")), (k, x, y)
            changed.append(k)
    return changed


def motion(moves):
    return [replace(m, feed=None, source=SourceLocation(m.source.file, m.source.line, 0)) for m in moves]


# --------------------------------------------------------------------------------------------------
# the modal rules, on small programs with known answers


def test_changed_line_then_modal_feed_restored():
    text = "G21 G94\nG1 X1 Y0 F600\nX10\nX20\nX30\n"
    r = rewrite_feeds(text, {3: 300.0})
    assert r.text == "G21 G94\nG1 X1 Y0 F600\nX10 F300\nX20 F600\nX30\n"
    assert r.inserted == (3, 4) and r.replaced == ()
    feeds = [m.feed for m in parse_gcode_text(r.text).moves]
    assert feeds == [600.0, 300.0, 600.0, 600.0]


def test_replaced_f_word_and_no_redundant_f():
    text = "G1 X1 F500 (first)\nX2\nX3 F700\nX4\n"
    r = rewrite_feeds(text, {1: 450.0, 2: 450.0, 4: 700.0})
    # line 2 inherits the new 450, line 4 already runs at 700: nothing to add there
    assert r.text == "G1 X1 F450 (first)\nX2\nX3 F700\nX4\n"
    assert r.replaced == (1,) and r.inserted == ()


def test_rapids_and_non_feed_lines_untouched_and_noted():
    text = "G0 X0 Y0\nG1 X5 F100\nG0 Z5\nM5\n"
    r = rewrite_feeds(text, {2: 200.0, 3: 50.0, 4: 80.0})
    assert r.text == "G0 X0 Y0\nG1 X5 F200\nG0 Z5\nM5\n"
    assert any(":3: no feed move" in n for n in r.notes) and any(":4: no feed move" in n for n in r.notes)


def test_number_format_follows_the_post():
    # padded decimals
    r = rewrite_feeds("G1 X1 F1000.00\nX2\n", {2: 1234.5678})
    assert r.text == "G1 X1 F1000.00\nX2 F1234.56\n"  # rounded down, never up
    # trailing point
    r = rewrite_feeds("G1 X1 F1000.\nX2\n", {2: 250.9})
    assert r.text == "G1 X1 F1000.\nX2 F250.\n"
    # trimmed (Fusion style)
    r = rewrite_feeds("G1 X1 F333.3\nX2 F1000\nX3\n", {3: 500.0, 1: 123.45})
    assert r.text == "G1 X1 F123.4\nX2 F1000\nX3 F500\n"


def test_inch_lowercase_compact_style():
    text = "g20g94\ng1x1y1f10\nx2\nx3\n"
    r = rewrite_feeds(text, {3: 127.0})  # 5 inch/min
    assert r.text == "g20g94\ng1x1y1f10\nx2f5\nx3f10\n"
    moves = parse_gcode_text(r.text).moves
    assert [m.feed for m in moves] == pytest.approx([254.0, 127.0, 254.0])


def test_per_revolution_and_inverse_time():
    # G95: F is per revolution in program units: 300 mm/min at S1500 is 0.2 mm/rev
    text = "G21 G95 S1500 M3\nG1 X10 F0.1\nX20\n"
    r = rewrite_feeds(text, {3: 300.0})
    assert r.text == "G21 G95 S1500 M3\nG1 X10 F0.1\nX20 F0.2\n"
    assert [m.feed for m in parse_gcode_text(r.text).moves] == pytest.approx([150.0, 300.0])
    # G93: F is 1/minutes of the move: scale it by advised / programmed feed
    text = "G21 G93\nG1 X10 F50.0\nG1 X30 F25.0\n"  # 500 mm/min, then 20 mm * 25 = 500 mm/min
    r = rewrite_feeds(text, {3: 250.0})
    assert r.text == "G21 G93\nG1 X10 F50.0\nG1 X30 F12.5\n"
    assert [m.feed for m in parse_gcode_text(r.text).moves] == pytest.approx([500.0, 250.0])
    # a G93 line run twice with moves of different lengths cannot get one F for one feed
    sub = "o1 sub\nG91 G93 G1 X#1 F10\nG94 G90\no1 endsub\no1 call [10]\no1 call [20]\nM2\n"
    assert [m.feed for m in parse_gcode_text(sub).moves] == [100.0, 200.0]
    with pytest.raises(InputError, match=r"<memory>:2: this line runs more than once.*F15.*F7 "):
        rewrite_feeds(sub, {2: 150.0})


def test_expression_feed_replaced_by_a_number_and_restored():
    text = "#<fs> = 2\nG1 X1 F[#<fs>*100]\nX2\nX3\n"
    r = rewrite_feeds(text, {2: 150.0})
    assert r.text == "#<fs> = 2\nG1 X1 F150\nX2 F200\nX3\n"
    assert [m.feed for m in parse_gcode_text(r.text).moves] == [150.0, 200.0, 200.0]


def test_loops_one_f_per_line():
    prog = "G1 X1 F500\no100 repeat [2]\nG1 X10\nG1 X0 F800\no100 endrepeat\nM2\n"
    # line 3 runs at 500 then at 800: giving it 400 on both passes is possible...
    r = rewrite_feeds(prog, {3: 400.0})
    assert r.text == prog.replace("G1 X10\n", "G1 X10 F400\n")
    assert [m.feed for m in parse_gcode_text(r.text).moves] == [500.0, 400.0, 800.0, 400.0, 800.0]
    # ... but slowing line 4 would need F500 on line 3's first pass and F800 on its second
    with pytest.raises(InputError, match=r"<memory>:3: this line runs more than once"):
        rewrite_feeds(prog, {4: 700.0})


def test_crlf_and_latin1_kept(tmp_path):
    src = tmp_path / "p.nc"
    src.write_bytes("(Fräsen)\r\nG1 X1 F100\r\nX2\r\nX3\r\n".encode("latin-1"))
    out = tmp_path / "q.nc"
    r = rewrite_gcode_file(src, {3: 50.0}, out)
    assert out.read_bytes() == "(Fräsen)\r\nG1 X1 F100\r\nX2 F50\r\nX3 F100\r\n".encode("latin-1")
    assert r.changed_lines == (3, 4)
    with pytest.raises(InputError, match="must not overwrite"):
        rewrite_gcode_file(src, {3: 50.0}, src)


@pytest.mark.parametrize("bad", [0.0, -5.0, math.nan, math.inf])
def test_bad_advice_is_an_input_error(bad):
    with pytest.raises(InputError, match=r"<memory>:2: advised feed must be"):
        rewrite_feeds("G1 X1 F100\nX2\n", {2: bad})


def test_feed_below_resolution_and_g95_without_speed():
    with pytest.raises(InputError, match="resolution"):
        rewrite_feeds("G1 X1 F100\nX2\n", {2: 0.4})
    with pytest.raises(FusionCutError, match="zero spindle speed"):
        rewrite_feeds("G95 G1 X1 F0.1\nX2\n", {2: 10.0})


# --------------------------------------------------------------------------------------------------
# real programs


@needs_data
def test_canned_cycles_and_tapping(tmp_path):
    text = G81.read_text()
    lines = text.splitlines()
    cycle = next(k for k, ln in enumerate(lines, 1) if ln.startswith("g81 x1 y2"))
    r = rewrite_feeds(text, {cycle: 127.0}, source=str(G81))  # 5 inch/min
    changed = only_f_changed(text, r.text)
    assert changed[0] == cycle and r.text.splitlines()[cycle - 1] == "g81 x1 y2 z0.5 r3 f5"
    old, new = parse_gcode_text(text).moves, parse_gcode_text(r.text).moves
    assert motion(old) == motion(new)
    for a, b in zip(old, new):
        assert b.feed == (127.0 if a.source.line == cycle and not a.is_rapid else a.feed)
    # a tapping cycle keeps its feed: it must match the pitch
    tap = "G21 G17 G98\nS500 M3\nG0 X0 Y0 Z5\nG84 X1 Y1 Z-5 R2 F500\nG80\n"
    r = rewrite_feeds(tap, {4: 250.0})
    assert r.text == tap and any("tapping" in n for n in r.notes)


@needs_data
def test_inverse_time_subroutine_called_three_times():
    text = INVERSE.read_text()
    lines = text.splitlines()
    # a G94 line relying on the modal F afterwards, in a subroutine called three times
    g94 = next(k for k, ln in enumerate(lines, 1) if ln.startswith("x1f33"))
    after = g94 + 1  # "y3", relies on F33
    r = rewrite_feeds(text, {g94: 25.4 * 20}, source="inverse.ngc")  # 20 inch/min on every call
    assert only_f_changed(text, r.text) == [g94, after]
    assert r.text.splitlines()[g94 - 1].startswith("x1f20") and r.text.splitlines()[after - 1].startswith("y3f33")
    old, new = parse_gcode_text(text).moves, parse_gcode_text(r.text).moves
    assert motion(old) == motion(new)
    # a G93 line: F scaled on every call (cutter compensation splits its moves, LinuxCNC feeds them
    # all at F times the programmed length)
    g93 = next(k for k, ln in enumerate(lines, 1) if ln.startswith("y1f20"))
    r = rewrite_feeds(text, {g93: 254.0}, source="inverse.ngc")
    assert only_f_changed(text, r.text) == [g93]
    assert r.text.splitlines()[g93 - 1].startswith("y1f10 ")
    new = parse_gcode_text(r.text).moves
    assert motion(old) == motion(new)
    assert [b.feed for b in new if b.source.line == g93] == pytest.approx([254.0] * 4)
    assert all(b.feed == a.feed for a, b in zip(old, new) if a.source.line != g93)


@needs_data
def test_arcspiral_inch_arcs():
    text = ARCSPIRAL.read_text()
    tp = parse_gcode_text(text)
    arc_lines = sorted({m.source.line for m in tp.moves if not m.is_rapid and type(m).__name__ == "ArcMove"})
    pick = arc_lines[10:400:37]
    r = rewrite_feeds(text, {k: 300.0 for k in pick})
    assert set(r.inserted) >= set(pick)
    only_f_changed(text, r.text)
    new = parse_gcode_text(r.text).moves
    assert motion(tp.moves) == motion(new)
    for a, b in zip(tp.moves, new):
        if a.source.line in pick:
            assert b.feed == pytest.approx(math.floor(300.0 / 25.4) * 25.4)  # whole inches/min, rounded down
        else:
            assert b.feed == a.feed


def _fusion_head(n: int) -> str:
    return "".join(FUSION.read_text().splitlines(keepends=True)[:n])


@needs_data
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_random_feeds_on_a_fusion_program(data):
    text = _fusion_head(1500)
    tp = parse_gcode_text(text)
    feed_lines = sorted({m.source.line for m in tp.moves if not m.is_rapid})
    chosen = data.draw(st.lists(st.sampled_from(feed_lines), unique=True, max_size=60))
    values = data.draw(st.lists(st.floats(1.0, 20000.0, allow_nan=False), min_size=len(chosen), max_size=len(chosen)))
    feeds = dict(zip(chosen, values))
    r = rewrite_feeds(text, feeds)
    step = 0.1 if re.search(r"F[0-9]+\.[0-9]", text) else 1.0  # the post's resolution, as in the text
    changed = only_f_changed(text, r.text)
    assert set(changed) == set(r.changed_lines)
    new = parse_gcode_text(r.text).moves
    assert motion(tp.moves) == motion(new)
    for a, b in zip(tp.moves, new):
        if a.is_rapid:
            assert b.feed is None
        elif a.source.line in feeds:
            want = feeds[a.source.line]
            assert want - step < b.feed <= want + 1e-9  # rounded down to the post's resolution
        else:
            assert b.feed == a.feed
    # no F word is redundant: each inserted one changes the feed in effect (the program is linear)
    prev = {}
    last = None
    for b in new:
        if not b.is_rapid:
            prev.setdefault(b.source.line, last)
            last = b.feed
    for line in r.inserted:
        assert prev[line] != next(b.feed for b in new if b.source.line == line and not b.is_rapid)


@needs_data
def test_whole_fusion_program(tmp_path):
    tp = parse_gcode_text(FUSION.read_text(), source=str(FUSION))
    feed_lines = sorted({m.source.line for m in tp.moves if not m.is_rapid})
    feeds = {k: 400.0 + 5 * (k % 150) for k in feed_lines[::7]}
    out = tmp_path / "new.nc"
    r = rewrite_gcode_file(FUSION, feeds, out)
    assert only_f_changed(FUSION.read_text(), out.read_text()) == list(r.changed_lines)
    new = parse_gcode_text(out.read_text(), source=str(FUSION)).moves
    assert motion(tp.moves) == motion(new)
    assert all(b.feed == feeds.get(a.source.line, a.feed) for a, b in zip(tp.moves, new) if not a.is_rapid)
