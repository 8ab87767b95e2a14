"""Domain values: tools, moves, stock and engagement results (immutable; mm, mm/min, degrees)."""
from fusioncut.model.engagement import AngleInterval, CLStatus, EngagementMap, SliceEngagement
from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Move, Toolpath
from fusioncut.model.stock import BoxStock, CylinderStock, SolidStock, Stock
from fusioncut.model.tools import (
    TOOL_KINDS,
    AptCutter,
    AptParameters,
    BallEndMill,
    BullNoseEndMill,
    ChamferMill,
    Drill,
    FlatEndMill,
    MillingTool,
    SpindleDirection,
    TaperedEndMill,
    ToolProfile,
)

__all__ = [
    "AngleInterval", "CLStatus", "EngagementMap", "SliceEngagement", "ArcMove", "ArcPlane", "LinearMove",
    "Move", "Toolpath", "BoxStock", "CylinderStock", "SolidStock", "Stock", "TOOL_KINDS", "AptCutter", "AptParameters",
    "BallEndMill", "BullNoseEndMill", "ChamferMill", "Drill", "FlatEndMill", "MillingTool", "SpindleDirection",
    "TaperedEndMill", "ToolProfile",
]
