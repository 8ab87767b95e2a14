"""FusionCut: exact cutter-workpiece engagement (CWE) for milling on OpenCASCADE.

The front door (see :mod:`fusioncut.api`)::

    import fusioncut as fc
    run = fc.simulate("part.nc", stock="box:0,0,-20,100,50,0", options=fc.EngineOptions(slice_height=1.0))
    for cl in run: ...            # EngagementMap per CL
    res = run.results()           # .cl, .slices, .summary DataFrames

``import fusioncut`` loads the model types and errors only; the names below are imported from their
modules when first used, so neither the kernel (OCP) nor pandas, Dask, FastAPI or matplotlib load
before they are needed.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from fusioncut.errors import (BooleanFailure, Degenerate, EngineStateError, FusionCutError, GeometryError, InputError,
                              JobTooLarge, KernelFailure, RegionCutFailure, SourceLocation, ToolDefinitionError)
from fusioncut.model import (AngleInterval, AptCutter, AptParameters, ArcMove, ArcPlane, BallEndMill, BoxStock,
                             BullNoseEndMill, ChamferMill, CLStatus, CylinderStock, Drill, EngagementMap,
                             FlatEndMill, LinearMove, MillingTool, Move, SliceEngagement, SolidStock,
                             SpindleDirection, Stock, TaperedEndMill, Toolpath, ToolProfile)
from fusioncut.model.options import EngineOptions, SweepMethod

from fusioncut._version import __version__

# name -> module that defines it, imported on first use (PEP 562)
_LAZY = {
    "simulate": "fusioncut.api", "Run": "fusioncut.api", "RunConsumed": "fusioncut.api",
    "MissingExtra": "fusioncut.extras",
    "read_toolpath": "fusioncut.io.readers", "read_tool_library": "fusioncut.io.readers",
    "load_job": "fusioncut.io.job", "Job": "fusioncut.io.job",
    "load_results": "fusioncut.io.results", "Results": "fusioncut.io.results",
}

__all__ = [
    "simulate", "Run", "RunConsumed", "read_toolpath", "read_tool_library", "load_job", "Job", "load_results",
    "Results", "EngineOptions", "SweepMethod",
    # model
    "AngleInterval", "AptCutter", "AptParameters", "ArcMove", "ArcPlane", "BallEndMill", "BoxStock", "BullNoseEndMill",
    "ChamferMill", "CLStatus", "CylinderStock", "Drill", "EngagementMap", "FlatEndMill", "LinearMove", "MillingTool",
    "Move", "SliceEngagement", "SolidStock", "SpindleDirection", "Stock", "TaperedEndMill", "Toolpath", "ToolProfile",
    # errors
    "FusionCutError", "InputError", "JobTooLarge", "ToolDefinitionError", "GeometryError", "BooleanFailure",
    "RegionCutFailure", "Degenerate", "KernelFailure", "EngineStateError", "MissingExtra", "SourceLocation",
    "__version__",
]

if TYPE_CHECKING:
    from fusioncut.api import Run, RunConsumed, simulate
    from fusioncut.engines.base import EngineOptions, SweepMethod
    from fusioncut.extras import MissingExtra
    from fusioncut.io.job import Job, load_job
    from fusioncut.io.readers import read_tool_library, read_toolpath
    from fusioncut.io.results import Results, load_results


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'fusioncut' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
