"""Tool records: every tool family survives JSON exactly, and an incomplete record is refused."""
from __future__ import annotations

import dataclasses
import json

import pytest

from fusioncut.errors import ToolDefinitionError
from fusioncut.io.tool_records import FIELD_UNITS, PLAIN_FIELDS, tool_from_record, tool_record
from fusioncut.model.tools import (
    TOOL_KINDS, AptCutter, AptParameters, BallEndMill, BullNoseEndMill, ChamferMill, Drill, FlatEndMill,
    SpindleDirection, TaperedEndMill,
)

# every common field away from its default, sizes without a short decimal form
COMMON = dict(flutes=3, helix_angle=100 / 3, spindle=SpindleDirection.CCW, shank_diameter=6.1, overall_length=71 / 3,
              number=7, name="T7 [neck]", neck_diameter=5.5, shoulder_length=22.0 + 1e-9, source="lib.json:12")
TOOLS = [
    FlatEndMill(20 / 3, 19.05, **COMMON),
    BallEndMill(6.0, 12.5, **COMMON),
    BullNoseEndMill(6.0, 12.5, corner_radius=0.7, **COMMON),
    TaperedEndMill(3.0, 12.0, taper_angle=2.5, **{**COMMON, "neck_diameter": None, "shoulder_length": None}),
    ChamferMill(6.0, 12.0, tip_diameter=0.0, taper_angle=45.0, **COMMON),
    ChamferMill(6.0, 12.0, tip_diameter=1.0, taper_angle=30.0, **COMMON),
    Drill(5.0, 12.0, point_angle=135.0, **COMMON),
    AptCutter(10.0, 15.0, apt_parameters=AptParameters(10.0, 1.0, 4.0, 1.0, 0.0, 0.0, 15.0), **COMMON),
    FlatEndMill(3.175, 12.0),  # all defaults: None stays None
]


def test_every_family_is_covered():
    assert {t.kind for t in TOOLS} == set(TOOL_KINDS)
    known = set(FIELD_UNITS) | set(PLAIN_FIELDS) | {"apt_parameters"}
    for cls in TOOL_KINDS.values():
        fields = {f.name for f in dataclasses.fields(cls) if f.init}
        assert fields <= known, f"{cls.__name__}: {fields - known} have no unit in tool_records"


@pytest.mark.parametrize("tool", TOOLS, ids=lambda t: f"{t.kind}-{t.name or 'default'}")
def test_round_trip_through_json(tool):
    record = json.loads(json.dumps(tool_record(tool)))
    back = tool_from_record(record, "T7")
    assert back == tool and type(back) is type(tool)
    assert back.source == tool.source  # not part of ==, kept all the same
    assert back.profile() == tool.profile()
    assert record["kind"] == tool.kind and record["diameter_mm"] == tool.diameter
    assert record["helix_angle_deg"] == tool.helix_angle and record["spindle"] == tool.spindle.value


def test_record_keys_carry_units():
    record = tool_record(TOOLS[0])
    assert record["flute_length_mm"] == 19.05 and record["neck_diameter_mm"] == 5.5 and record["flutes"] == 3
    assert tool_record(TOOLS[7])["apt_parameters"] == {"d_mm": 10.0, "r_mm": 1.0, "e_mm": 4.0, "f_mm": 1.0,
                                                       "alpha_deg": 0.0, "beta_deg": 0.0, "h_mm": 15.0}


def test_incomplete_or_foreign_records_are_refused_naming_the_tool():
    good = tool_record(TOOLS[0])
    old = {"kind": "flat", "diameter_mm": 10.0, "flute_length_mm": 20.0}  # what results held before
    with pytest.raises(ToolDefinitionError, match=r"^tool T1: the record lacks flutes, helix_angle_deg"):
        tool_from_record(old, "T1")
    with pytest.raises(ToolDefinitionError, match="unknown field.*colour"):
        tool_from_record({**good, "colour": "red"}, "T1")
    with pytest.raises(ToolDefinitionError, match="unknown kind 'laser'"):
        tool_from_record({**good, "kind": "laser"}, "T1")
    with pytest.raises(ToolDefinitionError, match="field flutes: an integer"):
        tool_from_record({**good, "flutes": 2.5}, "T1")
    with pytest.raises(ToolDefinitionError, match="field diameter_mm: a number"):
        tool_from_record({**good, "diameter_mm": "6"}, "T1")
    with pytest.raises(ToolDefinitionError, match="field spindle"):
        tool_from_record({**good, "spindle": "both"}, "T1")
    with pytest.raises(ToolDefinitionError, match="diameter must be > 0"):  # the model's own checks still run
        tool_from_record({**good, "diameter_mm": -1.0}, "T1")
