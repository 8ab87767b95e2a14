"""The removed volume's conservation over a window of CLs, checked from the sweeps alone.

Machine frame, mm. The workpiece before CL j is the stock less the sweeps of CLs 0..j-1, so the
material over any XY box follows from the path (:meth:`.engine.AnalyticEngine.material_volume`, one
integral over the box, never reading a CL's volume). Over a box holding the footprints of CLs
j..k, the material before CL j less that after CL k is what those CLs removed: the sum of their
removed volumes, to the integrals' tolerances (each ``volume_rel`` of its value). A lost sliver, a
CL counted twice or a proof of "nothing removed" that was wrong shows as a difference.
"""
from __future__ import annotations

from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.base import EngineOptions
from fusioncut.model.moves import Toolpath
from fusioncut.model.stock import Stock
from fusioncut.model.tools import MillingTool


def window_material(toolpath: Toolpath, stock: Stock, options: EngineOptions, start: int, stop: int,
                    default_tool: MillingTool | None = None) -> tuple[float, float]:
    """(the material (mm³) over the box of the footprints of CLs ``start``..``stop - 1`` before CL
    ``start``, the same after CL ``stop - 1``), each integrated from the sweeps alone; (0, 0) where
    every sweep of the window lies above the stock's top."""
    before, after = AnalyticEngine(options), AnalyticEngine(options)
    before.start(stock)
    after.start(stock)
    boxes = []
    for cl in after.cl_sequence(toolpath, default_tool):
        if cl.index >= stop:
            break
        after.index_only(cl)
        if cl.index < start:
            before.index_only(cl)
        else:  # a sweep wholly above the stock's top (a rapid over it) takes nothing: its box is left out
            boxes += [p.box for p in after.part_sweeps(cl) if p.z_low < after.stock[5]]
    if not boxes:  # nothing of the window reaches into the stock: no material changes
        return 0.0, 0.0
    box = (min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes), max(b[3] for b in boxes))
    return before.material_volume(box), after.material_volume(box)
