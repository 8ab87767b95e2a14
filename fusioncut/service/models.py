"""Response models of the HTTP API (they are what the OpenAPI document shows)."""
from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import BaseModel, Field

JobState = Literal["queued", "running", "done", "failed", "cancelled"]


class Problem(BaseModel):
    """Every 4xx/5xx answer: one line saying what is wrong and, for input, where."""

    detail: str = Field(examples=["tiny.nc:7:4: unknown G code G7.5"])


class ProgressInfo(BaseModel):
    done: int = Field(description="CL segments finished")
    total: int = Field(description="CL segments of the job")
    fraction: float = Field(description="done / total, 0..1")
    eta_s: float | None = Field(None, description="estimated seconds left (running jobs)")
    rate_cl_s: float | None = Field(None, description="CLs per second of the current run")
    operation: str = Field("", description="operation being computed")


class JobStatus(BaseModel):
    id: str
    name: str
    state: JobState
    created_at: float = Field(description="Unix time")
    started_at: float | None = None
    finished_at: float | None = None
    message: str = Field("", description="outcome, or why it failed")
    progress: ProgressInfo
    links: dict[str, str] = Field(default_factory=dict, description="related API addresses")


class JobList(BaseModel):
    jobs: list[JobStatus]


class FileInfo(BaseModel):
    name: str
    size: int = Field(description="bytes")
    media_type: str
    url: str


class FileList(BaseModel):
    files: list[FileInfo]


class SummaryTable(BaseModel):
    """Rows of ``summary.csv`` (one per operation); columns as documented in fusioncut.io.results."""

    rows: list[dict[str, Any]]


class Scene(BaseModel):
    """What the 3D view draws: the stock (or the IPW file), the tools and the CL points."""

    stock: dict[str, Any] | None = Field(None, description="box {min,max} or cylinder {base_center,radius,height}")
    ipw: str | None = Field(None, description="name of the IPW mesh in the job's files (ipw.stl), if written")
    tools: dict[str, Any] = Field(default_factory=dict, description="tool label -> kind, diameter_mm, flute_length_mm")
    cls: dict[str, list[Any]] = Field(description="columns cl, x, y, z, tool, status, operation (one entry per CL)")


class ClDetail(BaseModel):
    cl: dict[str, Any] = Field(description="the CL's row of the cl table")
    slices: list[dict[str, Any]] = Field(description="its engaged arcs (rows of the slices table)")


class ServiceInfo(BaseModel):
    version: str
    scheduler: str = Field(description="Dask scheduler address")
    embedded_cluster: bool
    max_upload_bytes: int
    max_cls: int = Field(description="largest job accepted, in CL segments")
    max_slices: int = Field(0, description=
        "largest job accepted, in slice evaluations (flute length / slice_height per CL)")


def json_safe(value: Any) -> Any:
    """JSON-safe values: NaN and infinities become null, numpy scalars plain numbers."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if hasattr(value, "item") and not isinstance(value, (list, dict, str)):
        return json_safe(value.item())
    return value
