"""Stock from the job (specs, solids, CAMotics) and inferred from the toolpath."""
from __future__ import annotations

import math

import pytest

from fusioncut.errors import InputError
from fusioncut.io.apt import read_apt
from fusioncut.io.stock import FACING_ALLOWANCE, infer_stock, parse_stock, solid_stock, stock_top
from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Toolpath
from fusioncut.model.stock import BoxStock, CylinderStock, SolidStock
from fusioncut.model.tools import BallEndMill, FlatEndMill, TaperedEndMill

from shared_data import DATA


def feed(a, b, tool=1):
    return LinearMove(start=a, end=b, feed=500.0, tool=tool)


def rapid(a, b, tool=1):
    return LinearMove(start=a, end=b, rapid=True, tool=tool)


FLAT6 = {1: FlatEndMill(diameter=6.0, flute_length=20.0, number=1)}


def test_program_cutting_below_zero_has_its_top_at_zero():
    # a personal-use style program: rapids posted as feeds at z = 5 far away from the part
    moves = (
        rapid((0, 0, 15), (10, 10, 15)),
        feed((10, 10, 15), (10, 10, 5)),
        feed((10, 10, 5), (10, 10, -3)),
        feed((10, 10, -3), (40, 10, -3)),
        feed((40, 10, -3), (40, 10, 5)),
        feed((40, 10, 5), (200, 150, 5)),  # feed "rapid" above the stock: not part of the stock
    )
    tp = Toolpath(moves, FLAT6)
    top, rule = stock_top(tp)
    assert top == 0.0 and "below z = 0" in rule
    stock = infer_stock(tp, margin=2.0)
    assert stock.inferred
    assert stock.minimum == pytest.approx((10 - 3 - 2, 10 - 3 - 2, -3 - 2))
    assert stock.maximum == pytest.approx((40 + 3 + 2, 10 + 3 + 2, 0.0))


def test_arc_bulge_and_tool_radius_bound_the_stock():
    arc = ArcMove(start=(0, -5, -1), end=(0, 5, -1), center=(0, 0, -1), plane=ArcPlane.XY, clockwise=False,
                  feed=300.0, tool=2)
    tp = Toolpath((feed((0, -5, 3), (0, -5, -1), tool=2), arc), {2: BallEndMill(diameter=4.0, flute_length=10.0)})
    stock = infer_stock(tp, margin=0.5)
    # counter-clockwise from 6 o'clock to 12 o'clock bulges to x = +5, never to x < 0
    assert stock.maximum[0] == pytest.approx(5 + 2 + 0.5)
    assert stock.minimum[0] == pytest.approx(0 - 2 - 0.5)
    assert stock.minimum[1] == pytest.approx(-5 - 2 - 0.5) and stock.maximum[1] == pytest.approx(5 + 2 + 0.5)


def test_tapered_tool_counts_with_its_widest_cutting_radius():
    tool = TaperedEndMill(diameter=2.0, flute_length=10.0, taper_angle=10.0)
    tp = Toolpath((feed((0, 0, 5), (0, 0, -2)), feed((0, 0, -2), (10, 0, -2))), {1: tool})
    widest = 1.0 + 10.0 * math.tan(math.radians(10.0))
    assert infer_stock(tp, margin=0.0).maximum[0] == pytest.approx(10 + widest)


def test_origin_on_the_table_uses_the_highest_sideways_level():
    moves = (
        feed((0, 0, 30), (0, 0, 25)),  # entry plunge through air
        feed((0, 0, 25), (0, 0, 20)),
        feed((0, 0, 20), (50, 0, 20)),  # first level: the stock top
        feed((50, 0, 20), (50, 0, 15)),
        feed((50, 0, 15), (0, 0, 15)),
        feed((0, 0, 15), (0, 0, 30)),
    )
    tp = Toolpath(moves, FLAT6)
    top, rule = stock_top(tp)
    assert top == 20.0 and "sideways" in rule
    stock = infer_stock(tp, margin=1.0)
    assert stock.maximum[2] == 20.0 and stock.minimum[2] == pytest.approx(14.0)


def test_single_level_facing_assumes_an_allowance_and_says_so():
    moves = (feed((0, 0, 5), (0, 0, 0)), feed((0, 0, 0), (100, 0, 0)), feed((100, 0, 0), (100, 30, 0)))
    tp = Toolpath(moves, FLAT6, source="face.nc")
    top, rule = stock_top(tp)
    assert top == FACING_ALLOWANCE == 1.0
    assert "facing pass" in rule and "--stock-top" in rule
    assert infer_stock(tp).maximum[2] == 1.0
    stock = infer_stock(tp, top=1.0)
    assert stock.maximum[2] == 1.0 and stock.minimum[2] == pytest.approx(-1.0)
    assert stock.maximum[1] == pytest.approx(30 + 3 + 1.0)


def test_rapids_only_and_bad_arguments():
    with pytest.raises(InputError, match="no feed moves"):
        infer_stock(Toolpath((rapid((0, 0, 0), (1, 1, 1)),), FLAT6))
    tp = Toolpath((feed((0, 0, 5), (0, 0, -1)),), FLAT6)
    with pytest.raises(InputError, match="margin"):
        infer_stock(tp, margin=-1.0)
    with pytest.raises(InputError, match="no feed move goes below the stock top"):
        infer_stock(tp, top=-5.0)


def test_unknown_tool_falls_back_to_the_largest_known_radius():
    tp = Toolpath((feed((0, 0, 1), (0, 0, -1), tool=7),), {1: FlatEndMill(diameter=10.0, flute_length=20.0)})
    assert infer_stock(tp, margin=0.0).maximum[0] == pytest.approx(5.0)


def test_inferred_from_an_apt_program(tmp_path):
    p = tmp_path / "p.apt"
    p.write_text(
        "UNITS/MM\nCUTTER/8\nLOADTL/1\nRAPID\nGOTO/0,0,10\nFEDRAT/500\nGOTO/0,0,-4\nGOTO/30,0,-4\n"
        "MOVARC/30,10,-4,0,0,1,10,ANGLE,180\nGOTO/30,20,-4\nGOTO/0,20,-4\nGOTO/0,20,10\n"
    )
    stock = infer_stock(read_apt(p), margin=1.0)
    assert stock.minimum == pytest.approx((-5.0, -5.0, -5.0))
    assert stock.maximum == pytest.approx((30 + 10 + 5.0, 25.0, 0.0))


# ---------------------------------------------------------------------------------------------------


def test_parse_box_and_cylinder():
    assert parse_stock("box:0,0,-20,80,80,0") == BoxStock((0, 0, -20), (80, 80, 0))
    assert parse_stock(" cylinder: 0,0,-30, 25, 30 ") == CylinderStock((0, 0, -30), 25, 30)
    for bad, msg in [("box:0,0,0,1,1", "box needs"), ("box:0,0,0,1,1,x", "numbers"), ("cyl:0,0,0,-1,5", "radius"),
                     ("box:0,0,0,1,1,nan", "finite"), ("sphere:1", "expected box"), ("box:0,0,0,0,1,1", "maximum")]:
        with pytest.raises(InputError, match=msg):
            parse_stock(bad)


def test_solid_stock_checks_the_file(tmp_path):
    step = tmp_path / "blank.step"
    step.write_text("ISO-10303-21;\nEND-ISO-10303-21;\n")
    assert solid_stock(step) == SolidStock(step)
    assert parse_stock("blank.step", base_dir=tmp_path) == SolidStock(step)
    with pytest.raises(InputError, match="not found"):
        solid_stock(tmp_path / "missing.brep")
    with pytest.raises(InputError, match="STEP or BREP"):
        solid_stock(tmp_path / "blank.stl")


@pytest.mark.skipif(not DATA.is_dir(), reason="shared test data (../shared/data) not present")
def test_stock_from_camotics_project():
    stock = parse_stock(str(DATA / "camotics-examples" / "bear" / "bear.camotics"))
    assert stock == BoxStock((0, 0, -20), (80, 80, 0))
