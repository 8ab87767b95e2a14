"""NX CLSF arcs and splines: ``CIRCLE`` states its axis for clockwise motion, ``TIMES, n`` adds turns,
``NURBS`` is refused naming its line; Fusion's ``MOVARC`` keeps the right-hand rule.

The programs are built here the way the posts write them: coordinates rounded to 4 decimals.
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusioncut.errors import InputError
from fusioncut.io.apt import read_apt
from fusioncut.io.apt_arcs import nx_marker_line
from fusioncut.model.moves import ArcMove, ArcPlane

NX_HEADER = """\
TOOL PATH/CONTOUR,TOOL,D10
TLDATA/MILL,10.0000,0.0000,75.0000,0.0000,0.0000
MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000
$$ centerline data
PAINT/PATH
LOAD/TOOL,1
FEDRAT/MMPM,1000.0000
"""
FUSION_HEADER = """\
UNITS/MM
CUTTER/10.000000, 0.000000, 10.000000, 0.000000, 0.000000, 0.000000, 30.000000
LOADTL/1
FEDRAT/1000.000000, MMPM
"""


def _f(v: float) -> str:
    return f"{v:.4f}"


def _point(p) -> str:
    return ",".join(_f(c) for c in p)


def _write(tmp_path: Path, text: str, name: str = "prog.cls") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _arc_record(dialect: str, center, normal_index: int, ccw: bool, radius: float, sweep_deg: float) -> str:
    """One arc statement: ``ccw`` is the sense about the positive plane normal (axis ``normal_index``)."""
    axis = [0.0, 0.0, 0.0]
    if dialect == "fusion":  # right-hand rule: the axis about which the tool turns counter-clockwise
        axis[normal_index] = 1.0 if ccw else -1.0
        return f"MOVARC/{_point(center)},{_point(axis)},{_f(radius)},ANGLE,{_f(sweep_deg)}"
    axis[normal_index] = -1.0 if ccw else 1.0  # NX: the axis about which the tool turns clockwise
    return f"CIRCLE/{_point(center)},{_point(axis)},{_f(radius)},0.0600,0.5000,10.0000,0.0000"


_PLANES = {ArcPlane.XY: (0, 1, 2), ArcPlane.ZX: (2, 0, 1), ArcPlane.YZ: (1, 2, 0)}


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    dialect=st.sampled_from(["fusion", "nx"]),
    plane=st.sampled_from(list(_PLANES)),
    heading=st.floats(0.0, 2 * math.pi),
    radius=st.floats(0.5, 50.0),
    sweep_deg=st.floats(10.0, 350.0),
    ccw=st.booleans(),
    origin=st.tuples(*[st.floats(-200.0, 200.0)] * 3),
)
def test_arc_after_a_tangent_line_starts_along_it(tmp_path, dialect, plane, heading, radius, sweep_deg, ccw, origin):
    a, b, n = _PLANES[plane]
    d = (math.cos(heading), math.sin(heading))  # the line's direction in the plane's (a, b) coordinates
    left = (-d[1], d[0])
    side = 1.0 if ccw else -1.0  # the centre lies on the side the arc turns to

    def lift(u: float, v: float) -> list[float]:
        p = list(origin)
        p[a] += u
        p[b] += v
        return p

    start2 = (-20.0 * d[0], -20.0 * d[1])
    c2 = (side * radius * left[0], side * radius * left[1])
    phi = side * math.radians(sweep_deg)
    rx, ry = -c2[0], -c2[1]  # from the centre to the arc's start (the line's end, the origin)
    end2 = (c2[0] + rx * math.cos(phi) - ry * math.sin(phi), c2[1] + rx * math.sin(phi) + ry * math.cos(phi))
    header = NX_HEADER if dialect == "nx" else FUSION_HEADER
    text = (
        header
        + f"GOTO/{_point(lift(*start2))}\n"
        + f"GOTO/{_point(lift(0.0, 0.0))}\n"
        + _arc_record(dialect, lift(*c2), n, ccw, radius, sweep_deg) + "\n"
        + f"GOTO/{_point(lift(*end2))}\n"
    )
    tp = read_apt(_write(tmp_path, text))
    line, arc = tp.moves[-2], tp.moves[-1]
    assert isinstance(arc, ArcMove) and arc.plane is plane and arc.clockwise is (not ccw)
    t_line, t_arc = line.tangent_at(1.0), arc.tangent_at(0.0)
    # rounding to 4 decimals turns the directions by at most ~1e-4 rad at r >= 0.5 mm
    assert sum(p * q for p, q in zip(t_line, t_arc)) > math.cos(1e-3)
    assert math.isclose(abs(arc.sweep), math.radians(sweep_deg), abs_tol=1e-3)
    assert not any("against their stated axis" in w or "start back against" in w for w in tp.warnings)


def _rounded_rectangle(dialect: str, ccw: bool, x0: float, y0: float, w: float, h: float, r: float) -> str:
    """A closed contour of four lines and four corner arcs (z = -2), the way a contour operation
    writes it: start in the middle of the bottom side, run round it ``ccw`` or clockwise."""
    z = -2.0
    # corner centres counter-clockwise from the bottom right, with the tangent points either side
    corners = [
        ((x0 + w - r, y0 + r), (x0 + w - r, y0), (x0 + w, y0 + r)),
        ((x0 + w - r, y0 + h - r), (x0 + w, y0 + h - r), (x0 + w - r, y0 + h)),
        ((x0 + r, y0 + h - r), (x0 + r, y0 + h), (x0, y0 + h - r)),
        ((x0 + r, y0 + r), (x0, y0 + r), (x0 + r, y0)),
    ]
    if not ccw:  # the same corners the other way round
        corners = [(c, q, p) for c, p, q in reversed(corners)]
    start = (x0 + w / 2, y0, z)
    lines = [f"GOTO/{_point(start)}"]
    for c, p, q in corners:
        lines.append(f"GOTO/{_point((p[0], p[1], z))}")
        lines.append(_arc_record(dialect, (c[0], c[1], z), 2, ccw, r, 90.0))
        lines.append(f"GOTO/{_point((q[0], q[1], z))}")
    lines.append(f"GOTO/{_point(start)}")
    header = NX_HEADER if dialect == "nx" else FUSION_HEADER
    return header + "\n".join(lines) + "\n"


@pytest.mark.parametrize("dialect", ["nx", "fusion"])
@pytest.mark.parametrize("ccw", [True, False])
def test_contour_with_corner_arcs_has_its_closed_form_length(tmp_path, dialect, ccw):
    w, h, r = 60.0, 40.0, 5.0
    text = _rounded_rectangle(dialect, ccw, 12.34567, -7.65432, w, h, r)
    tp = read_apt(_write(tmp_path, text))
    arcs = [m for m in tp.moves if isinstance(m, ArcMove)]
    assert len(arcs) == 4 and all(a.clockwise is (not ccw) for a in arcs)
    exact = 2 * (w - 2 * r) + 2 * (h - 2 * r) + 2 * math.pi * r
    total = sum(m.length for m in tp.moves)
    assert abs(total - exact) < 1e-3, (total, exact)  # a corner read the wrong way round is 270 degrees
    for m0, m1 in zip(tp.moves, tp.moves[1:]):  # the contour turns smoothly everywhere
        assert sum(p * q for p, q in zip(m0.tangent_at(1.0), m1.tangent_at(0.0))) > math.cos(1e-3)
    assert not any("start back against" in w for w in tp.warnings)


def test_circles_that_reverse_at_tangent_lines_are_reported(tmp_path):
    # the same contour with its CIRCLE axes written by the right-hand rule, as NX does not
    text = _rounded_rectangle("nx", True, 0.0, 0.0, 60.0, 40.0, 5.0)
    flipped = text.replace("0.0000,0.0000,-1.0000,5.0000", "0.0000,0.0000,1.0000,5.0000")
    assert flipped.count("CIRCLE/") == 4 and flipped != text
    tp = read_apt(_write(tmp_path, flipped))
    found = [w for w in tp.warnings if "start back against" in w]
    assert len(found) == 1 and "4 of 4 CIRCLE arcs" in found[0] and ":10:" in found[0]


def test_circle_times_adds_full_turns(tmp_path):
    # a helical ramp: a quarter plus two full turns about (0, 0), dropping 2 mm
    text = NX_HEADER + """\
GOTO/3.0000,0.0000,0.0000
CIRCLE/0.0000,0.0000,-2.0000,0.0000000,0.0000000,-1.0000000,3.0000,0.0600,0.5000,10.0000,0.0000,TIMES,2
GOTO/0.0000,3.0000,-2.0000
CIRCLE/0.0000,0.0000,-3.0000,0.0000000,0.0000000,-1.0000000,3.0000,0.0600,0.5000,10.0000,0.0000,TIMES,1
GOTO/0.0000,3.0000,-3.0000
"""
    tp = read_apt(_write(tmp_path, text))
    ramp, full = tp.moves
    assert ramp.turns == 2 and not ramp.clockwise
    assert math.isclose(ramp.sweep, math.pi / 2 + 4 * math.pi)
    assert math.isclose(ramp.length, math.hypot(3.0 * (math.pi / 2 + 4 * math.pi), 2.0))
    # ends that coincide in the plane: the full circle a CIRCLE without TIMES is, plus one turn
    assert full.turns == 1 and math.isclose(full.sweep, 4 * math.pi)
    assert full.point_at(0.125) == pytest.approx((-3.0, 0.0, -2.125))


@pytest.mark.parametrize(
    "tail, message",
    [
        ("TIMES,0", "TIMES must be a whole number"),
        ("TIMES,1.5", "TIMES must be a whole number"),
        ("TIMES,99999", "TIMES must be a whole number"),
        ("TIMES", "TIMES needs the number"),
        ("CLW", "unexpected 'CLW'"),
    ],
)
def test_malformed_circle_names_its_line(tmp_path, tail, message):
    text = NX_HEADER + f"""\
GOTO/3.0000,0.0000,0.0000
CIRCLE/0.0000,0.0000,0.0000,0.0000000,0.0000000,-1.0000000,3.0000,0.0600,0.5000,10.0000,0.0000,{tail}
GOTO/0.0000,3.0000,0.0000
"""
    path = _write(tmp_path, text)
    with pytest.raises(InputError, match=message) as err:
        read_apt(path)
    assert err.value.where.line == 9 and f"{path}:9" in str(err.value)


def test_nurbs_motion_is_refused_naming_its_line(tmp_path):
    text = NX_HEADER + """\
GOTO/0.0000,0.0000,0.0000
NURBS/
KNOT/0.0000000,0.0000000,0.0000000,1.0000000,1.0000000,1.0000000
GOTO/10.0000,0.0000,0.0000
GOTO/10.0000,10.0000,0.0000
"""
    path = _write(tmp_path, text)
    with pytest.raises(InputError, match="NURBS") as err:
        read_apt(path)
    assert err.value.where.line == 9 and f"{path}:9" in str(err.value)


def test_circle_in_a_file_without_nx_records_is_read_the_nx_way_with_a_warning(tmp_path):
    text = """\
UNITS/MM
CUTTER/6
FEDRAT/100
GOTO/0, 0, 0
GOTO/10, 0, 0
CIRCLE/10, 5, 0, 0, 0, -1, 5
GOTO/10, 10, 0
"""
    tp = read_apt(_write(tmp_path, text, "prog.apt"))
    arc = tp.moves[-1]
    assert not arc.clockwise and arc.point_at(0.5) == pytest.approx((15.0, 5.0, 0.0))
    assert any(":6: CIRCLE read as Siemens NX writes it" in w for w in tp.warnings)


def test_nx_marker_line():
    assert nx_marker_line("UNITS/MM\n$$ TOOL PATH/X\nGOTO/1,2,3\n") is None  # a comment does not count
    assert nx_marker_line("$$ header\nRAPID\n  tool   path/OP1,TOOL,T\n") == 3
    assert nx_marker_line("GOTO/1,2,3\nEND-OF-PATH\n") == 2
    assert nx_marker_line("PAINTED/1\nMSYSX/2\n") is None
