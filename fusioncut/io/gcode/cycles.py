"""Canned cycles G73, G74, G81-G89 expanded into rapids and feeds, as LinuxCNC 2.9 does.

The cycle works along the normal of the selected plane (Z in G17, Y in G18, X in G19; "up" is the
positive direction) and positions in the plane's two axes. All values here are machine-frame mm.

* ``R`` is the retract plane, the cycle-axis word (``Z`` in G17) the bottom. In G90 both are absolute;
  in G91, ``R`` is relative to the *initial level* (the cycle-axis position when this run of cycles
  began) and the bottom relative to ``R``; the in-plane words are increments applied on every repeat.
* G98 retracts to the initial level (or ``R`` if that is higher), G99 to ``R``.
* A repeat: rapid in the plane at the current level, rapid down to ``R`` (when not there), the cycle's
  own moves, then the retract. When the initial level is below ``R``, the tool first rapids up to ``R``.
* ``L`` repeats (default 1), ``P`` dwell (G82, G86, G88, G89), ``Q`` peck depth (G73, G83), ``I J K``
  (G87 back boring) are remembered from the previous block of the same cycle, like ``R`` and the
  bottom; the first block of a cycle must give the bottom and ``R``.
"""
from __future__ import annotations

import math
from fusioncut.errors import InputError, SourceLocation
from fusioncut.io.gcode.machine import MAX_MOVES_PER_BLOCK, Machine, Words
from fusioncut.io.gcode.modal import AXES, PLANE_OFFSET_WORDS, gname

__all__ = ["canned_cycle"]

PECK_CLEARANCE_MM = 0.254  # LinuxCNC's G83_RAPID_DELTA (0.010 in): G73/G83 re-approach this far above


def canned_cycle(m: Machine, code: int, w: Words, loc: SourceLocation) -> None:
    """Expand one block of cycle ``code`` (G code * 10) into moves (see the module doc)."""
    if m.comp is not None:
        raise InputError("canned cycles cannot be used with cutter compensation on", loc)
    if m.feed_mode == "inverse_time":
        raise InputError("canned cycles cannot be used in inverse time feed (G93)", loc)
    name = gname(code)
    plane = m.plane
    ia, ib, ic = plane.axes
    la, lb, lc = AXES[ia], AXES[ib], AXES[ic]
    s = m.scale()
    cyc = m.cycle
    same = m.motion == code
    if any(r in w.vals for r in "abc"):
        raise InputError("rotary axes cannot move in a canned cycle", loc)
    if not same and lc not in w.vals:
        raise InputError(f"{name} needs {lc.upper()} (the bottom) in its first block", loc)
    cc_raw = w.get(lc)
    cc_raw = cc_raw * s if cc_raw is not None else cyc["cc"]
    r_word = w.get("r")
    if r_word is not None:
        r_raw = r_word * s
    elif same:
        r_raw = cyc["r"]
    else:
        raise InputError(f"{name} needs R (the retract plane) in its first block", loc)
    l_word = w.get("l")
    repeats = 1
    if l_word is not None:
        if l_word != math.floor(l_word) or l_word < 1:
            raise InputError(f"{name} L (repeats) must be a whole number >= 1, got L{l_word:g}", loc)
        repeats = int(l_word)
    if not m.feed and m.feed_mode == "units_per_minute":
        m.feed_missing(loc)

    pos = m.pos
    if m.cycle_initial is None:
        m.cycle_initial = pos[ic]
    old_cc = m.cycle_initial
    current = pos[ic]
    off = m.offset()
    a_inc = b_inc = 0.0
    if m.absolute:
        r = r_raw + off[ic]
        cc = cc_raw + off[ic]
        av, bv = w.get(la), w.get(lb)
        aa = av * s + off[ia] if av is not None else pos[ia]
        bb = bv * s + off[ib] if bv is not None else pos[ib]
    else:
        av, bv = w.get(la), w.get(lb)
        a_inc = av * s if av is not None else 0.0
        b_inc = bv * s if bv is not None else 0.0
        r = r_raw + old_cc
        cc = r + cc_raw
        aa, bb = pos[ia], pos[ib]
    if r < cc:
        raise InputError(f"{name}: the R plane is below the bottom {lc.upper()}", loc)

    # cycle-specific words
    dwell = 0.0
    if code in (820, 860, 880, 890, 840, 740):
        p = w.get("p")
        if p is None:
            if not same and code not in (840, 740):
                raise InputError(f"{name} needs a P (dwell) word", loc)
            p = cyc.get("p", 0.0)
        dwell = p
        cyc["p"] = p
    delta = 0.0
    if code in (730, 830):
        q = w.get("q")
        if q is None:
            if not same:
                raise InputError(f"{name} needs a Q (peck depth) word", loc)
            q = cyc["q"]
        if q <= 0:
            raise InputError(f"{name} Q (peck depth) must be > 0", loc)
        cyc["q"] = q
        delta = q * s
    offsets = (0.0, 0.0, 0.0)
    if code == 870:
        oa, ob, oc = PLANE_OFFSET_WORDS[plane]
        vals = []
        for letter in (oa, ob, oc):
            v = w.get(letter)
            if v is None:
                if not same:
                    raise InputError(f"G87 needs {oa.upper()}, {ob.upper()} and {oc.upper()}", loc)
                v = cyc[letter]
            cyc[letter] = v
            vals.append(v * s)
        k = vals[2] + (cc if not m.absolute else off[ic])
        offsets = (vals[0], vals[1], k)
    if code in (840, 740):
        want = "cw" if code == 840 else "ccw"
        if m.spindle != want:
            sense = "clockwise (M3)" if want == "cw" else "counter-clockwise (M4)"
            raise InputError(f"{name} needs the spindle turning {sense}", loc)
    if code in (860, 870, 880) and m.spindle == "off":
        raise InputError(f"{name} needs the spindle turning", loc)
    del dwell  # dwells take no path; kept above to check and remember P

    pecks = (r - cc) / delta if code in (730, 830) else 0.0
    if not pecks <= MAX_MOVES_PER_BLOCK:
        raise InputError(f"{name}: peck depth Q too small for the hole ({pecks:.3g} pecks)", loc)
    m.check_block(repeats * (8 + 3 * math.ceil(pecks)), loc)

    def point(a: float, b: float, c: float) -> list[float]:
        e = list(m.pos)
        e[ia], e[ib], e[ic] = a, b, c
        return e

    def rapid(a: float, b: float, c: float) -> None:
        m.linear(point(a, b, c), True, loc)

    def feed(a: float, b: float, c: float) -> None:
        m.linear(point(a, b, c), False, loc)

    if old_cc < r:
        # below the R plane: first straight up to it
        rapid(pos[ia], pos[ib], r)
        old_cc = r
        current = r
    clear = r if not m.retract_old_z else old_cc
    for _ in range(repeats):
        aa += a_inc
        bb += b_inc
        rapid(aa, bb, current)
        if current != r:
            rapid(aa, bb, r)
        if code == 810 or code == 820:
            feed(aa, bb, cc)
            rapid(aa, bb, clear)
        elif code in (730, 830):
            depth = r - delta
            while depth > cc:
                feed(aa, bb, depth)
                if code == 830:
                    rapid(aa, bb, r)
                rapid(aa, bb, depth + PECK_CLEARANCE_MM)
                depth -= delta
            feed(aa, bb, cc)
            rapid(aa, bb, clear)
        elif code in (840, 740):
            feed(aa, bb, cc)
            feed(aa, bb, clear)  # spindle reverses and the tap feeds back out
        elif code == 850:
            feed(aa, bb, cc)
            feed(aa, bb, r)
            rapid(aa, bb, clear)
        elif code == 860:
            feed(aa, bb, cc)
            rapid(aa, bb, clear)  # spindle stopped at the bottom
        elif code == 870:
            oa_, ob_, k = offsets
            rapid(aa + oa_, bb + ob_, r)
            rapid(aa + oa_, bb + ob_, cc)
            rapid(aa, bb, cc)
            feed(aa, bb, k)
            feed(aa, bb, cc)
            rapid(aa + oa_, bb + ob_, cc)
            rapid(aa + oa_, bb + ob_, clear)
            rapid(aa, bb, clear)
        elif code == 880:
            feed(aa, bb, cc)
            # LinuxCNC stops here for the operator to retract by hand; we record that as a rapid
            rapid(aa, bb, clear)
        elif code == 890:
            feed(aa, bb, cc)
            feed(aa, bb, clear)
        current = clear
    cyc["cc"] = cc_raw
    cyc["r"] = r_raw
    m.motion = code
