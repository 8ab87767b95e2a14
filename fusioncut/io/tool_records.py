"""Tool records: a :class:`~fusioncut.model.tools.MillingTool` as plain JSON, and back, exactly.

A record names the tool's family (``kind``, a key of :data:`~fusioncut.model.tools.TOOL_KINDS`) and
holds every field the family's constructor takes, under the field's name with its unit appended
(``diameter_mm``, ``helix_angle_deg``; see :data:`FIELD_UNITS`); counts and words keep their names
(``flutes``, ``spindle`` as ``"cw"``/``"ccw"``, ``number``, ``name``, ``source``). An unset optional
field is ``null``. The APT cutter's seven parameters are a nested record
``apt_parameters: {d_mm, r_mm, e_mm, f_mm, alpha_deg, beta_deg, h_mm}``.

``tool_from_record(tool_record(t)) == t`` for every tool (floats survive JSON exactly: Python writes
the shortest repr that reads back to the same double). A record that lacks a field, has one this
version does not know, or names an unknown family is refused with a :class:`ToolDefinitionError`
naming the tool and the field: nothing is filled in with a default, so a tool rebuilt from a record
is the tool that was run, or no tool at all.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from enum import Enum
from typing import Any

from fusioncut.errors import ToolDefinitionError
from fusioncut.model.tools import TOOL_KINDS, AptParameters, MillingTool, SpindleDirection

# Unit of every dimensioned constructor field of the tool families; the record key is name_unit.
FIELD_UNITS: dict[str, str] = {
    "diameter": "mm", "flute_length": "mm", "shank_diameter": "mm", "overall_length": "mm",
    "neck_diameter": "mm", "shoulder_length": "mm", "corner_radius": "mm", "tip_diameter": "mm",
    "helix_angle": "deg", "taper_angle": "deg", "point_angle": "deg",
}
# Constructor fields without a unit, and how a record's value becomes the field's value.
PLAIN_FIELDS: dict[str, Any] = {"flutes": int, "number": int, "name": str, "source": str,
                                "spindle": SpindleDirection}
_APT_UNITS = {"d": "mm", "r": "mm", "e": "mm", "f": "mm", "alpha": "deg", "beta": "deg", "h": "mm"}


def _fields(cls: type) -> list[dataclasses.Field]:
    return [f for f in dataclasses.fields(cls) if f.init]


def _key(name: str) -> str:
    unit = FIELD_UNITS.get(name)
    return f"{name}_{unit}" if unit else name


def _plain(value: Any) -> Any:
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, AptParameters):
        return {f"{n}_{u}": float(getattr(value, n)) for n, u in _APT_UNITS.items()}
    return value


def tool_record(tool: MillingTool) -> dict[str, Any]:
    """The JSON record of ``tool`` (see the module docstring): ``kind`` and every constructor field."""
    record: dict[str, Any] = {"kind": tool.kind}
    for f in _fields(type(tool)):
        record[_key(f.name)] = _plain(getattr(tool, f.name))
    return record


def tool_from_record(record: Mapping[str, Any], label: str = "") -> MillingTool:
    """The tool a :func:`tool_record` describes; ``label`` names it in errors (the results' tool label)."""
    who = f"tool {label}" if label else "tool record"
    if not isinstance(record, Mapping):
        raise ToolDefinitionError(f"{who}: a record is a JSON object, got {type(record).__name__}")
    kind = record.get("kind")
    cls = TOOL_KINDS.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise ToolDefinitionError(f"{who}: unknown kind {kind!r} (known: {', '.join(sorted(TOOL_KINDS))})")
    fields = _fields(cls)
    keys = {_key(f.name): f.name for f in fields}
    missing = [k for k in keys if k not in record]
    if missing:
        raise ToolDefinitionError(f"{who}: the record lacks {', '.join(missing)} (a {kind} tool needs every field "
                                  "to be rebuilt as it was run)")
    unknown = sorted(k for k in record if k != "kind" and k not in keys)
    if unknown:
        raise ToolDefinitionError(f"{who}: unknown field(s) {', '.join(unknown)} for a {kind} tool")
    kwargs: dict[str, Any] = {}
    for key, name in keys.items():
        kwargs[name] = _value(name, record[key], who)
    return cls(**kwargs)


def _value(name: str, value: Any, who: str) -> Any:
    if value is None:
        return None
    try:
        if name == "apt_parameters":
            if not isinstance(value, Mapping) or set(value) != {f"{n}_{u}" for n, u in _APT_UNITS.items()}:
                raise ValueError(f"needs exactly {', '.join(f'{n}_{u}' for n, u in _APT_UNITS.items())}")
            return AptParameters(**{n: float(value[f"{n}_{u}"]) for n, u in _APT_UNITS.items()})
        if name in FIELD_UNITS:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"a number, got {value!r}")
            return float(value)
        convert = PLAIN_FIELDS[name]
        if convert is int and (isinstance(value, bool) or not isinstance(value, int)):
            raise ValueError(f"an integer, got {value!r}")
        if convert is str and not isinstance(value, str):
            raise ValueError(f"text, got {value!r}")
        return convert(value)
    except (ValueError, TypeError, KeyError) as exc:
        raise ToolDefinitionError(f"{who}: field {_key(name)}: {exc}") from None


__all__ = ["FIELD_UNITS", "PLAIN_FIELDS", "tool_from_record", "tool_record"]
