"""The job file: one JSON naming stock, tools, toolpath files and options (mm, degrees).

``fusioncut run job.json`` is reproducible: the same file gives the same results, and the job hash
(SHA-256 of the normalised job and the bytes of every input file) is written into the results.
The JSON Schema is ``Job.model_json_schema()`` (``fusioncut schema`` prints it).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from fusioncut.errors import InputError
from fusioncut.model.stock import BoxStock, CylinderStock, SolidStock, Stock
from fusioncut.model.tools import (AptCutter, AptParameters, BallEndMill, BullNoseEndMill, ChamferMill, FlatEndMill,
                                   MillingTool, SpindleDirection, TaperedEndMill)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class StockSpec(_Strict):
    """``box`` (min, max corners), ``cylinder`` (base_center, radius, height), ``file`` (STEP/BREP path)
    or ``infer`` (the feed moves' extents plus ``margin``)."""

    kind: Literal["box", "cylinder", "file", "infer"]
    min: tuple[float, float, float] | None = None
    max: tuple[float, float, float] | None = None
    base_center: tuple[float, float, float] | None = None
    radius: float | None = None
    height: float | None = None
    path: str | None = None
    margin: float = 2.0

    @model_validator(mode="after")
    def _complete(self) -> StockSpec:
        need = {"box": ("min", "max"), "cylinder": ("base_center", "radius", "height"), "file": ("path",), "infer": ()}
        missing = [k for k in need[self.kind] if getattr(self, k) is None]
        if missing:
            raise ValueError(f"{self.kind} stock needs {', '.join(missing)}")
        return self


class ToolSpec(_Strict):
    """One tool. ``kind``: flat, ball, bullnose, tapered, chamfer, apt. Lengths mm, angles degrees."""

    number: int
    kind: Literal["flat", "ball", "bullnose", "tapered", "chamfer", "apt"]
    diameter: float = Field(gt=0)
    flute_length: float = Field(gt=0)
    corner_radius: float = 0.0
    taper_angle: float = 0.0
    tip_diameter: float = 0.0
    apt: tuple[float, float, float, float, float, float, float] | None = None  # d, r, e, f, alpha, beta, h
    flutes: int = 2
    helix_angle: float = 30.0
    spindle: Literal["cw", "ccw"] = "cw"
    shank_diameter: float | None = None
    overall_length: float | None = None
    name: str = ""

    def build(self) -> MillingTool:
        common = dict(diameter=self.diameter, flute_length=self.flute_length, flutes=self.flutes,
                      helix_angle=self.helix_angle, spindle=SpindleDirection(self.spindle),
                      shank_diameter=self.shank_diameter, overall_length=self.overall_length,
                      number=self.number, name=self.name)
        if self.kind == "flat":
            return FlatEndMill(**common)
        if self.kind == "ball":
            return BallEndMill(**common)
        if self.kind == "bullnose":
            return BullNoseEndMill(**common, corner_radius=self.corner_radius)
        if self.kind == "tapered":
            return TaperedEndMill(**common, taper_angle=self.taper_angle)
        if self.kind == "chamfer":
            return ChamferMill(**common, tip_diameter=self.tip_diameter, taper_angle=self.taper_angle)
        if self.apt is None:
            raise InputError(f"tool T{self.number}: kind 'apt' needs the 7 parameters in 'apt'")
        return AptCutter(**common, apt_parameters=AptParameters(*self.apt))


class Options(_Strict):
    """Engine options, see :class:`fusioncut.engines.base.EngineOptions`."""

    slice_height: float = Field(1.0, gt=0)
    max_segment_length: float | None = Field(None, gt=0)
    chord_tolerance: float = Field(1e-3, gt=0)
    sweep: Literal["exact", "sampled"] = "exact"


class Job(_Strict):
    """A FusionCut job. Relative paths are relative to the job file."""

    name: str = "job"
    stock: StockSpec
    tools: list[ToolSpec] = []
    tool_library: str | None = None
    toolpaths: list[str] = Field(min_length=1)
    strict: bool = False
    options: Options = Options()


def load_job(path: str | Path) -> tuple[Job, Path]:
    """Read and validate a job file; errors name the file and the JSON path of the bad field."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("job file not found", path) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        where = f"{path}:{getattr(exc, 'lineno', 0)}:{getattr(exc, 'colno', 0)}"
        raise InputError(f"not valid JSON: {getattr(exc, 'msg', exc)}", where) from None
    try:
        return Job.model_validate(data), path.parent
    except ValidationError as exc:
        first = exc.errors()[0]
        loc = ".".join(str(p) for p in first["loc"]) or "<root>"
        raise InputError(f"{loc}: {first['msg']} ({exc.error_count()} problem(s) in all)", path) from None


def build_stock(spec: StockSpec, base: Path) -> Stock | None:
    """The stock of the job; ``None`` for ``infer`` (the caller infers it from the toolpath)."""
    if spec.kind == "box":
        return BoxStock(spec.min, spec.max)  # type: ignore[arg-type]
    if spec.kind == "cylinder":
        return CylinderStock(spec.base_center, spec.radius, spec.height)  # type: ignore[arg-type]
    if spec.kind == "file":
        return SolidStock(base / spec.path)  # type: ignore[operator]
    return None


def job_hash(job: Job, base: Path) -> str:
    h = hashlib.sha256(job.model_dump_json().encode())
    for p in [*job.toolpaths, *([job.tool_library] if job.tool_library else [])]:
        f = base / p
        if f.is_file():
            h.update(f.read_bytes())
    return h.hexdigest()[:16]
