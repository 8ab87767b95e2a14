"""The engine state on disk: a checkpoint a run resumes from with the results of one never stopped.

A checkpoint folder holds ``ipw-<next CL>.bbrep`` (binary BRep: doubles kept exactly) with one
compound child per cell, in cell order (an empty compound for a cell cut away, the solid, or a
layered cell's regions), and ``state.json`` with the counters, each layered cell's layer heights,
the cells' grid squares and the :class:`~fusioncut.engines.brep.cells.ClearedTool`. Layered cells
are kept as layers, not as their solid, so that the resumed run cuts the very same regions. Each
file is written to ``.tmp`` and renamed, the state last, so a checkpoint is whole or absent.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

from fusioncut.engines.brep.cells import Cell, ClearedTool, Square
from fusioncut.engines.brep.layers import layer_from_state
from fusioncut.engines.brep.occ import children, compound, read_binary_brep, write_binary_brep

__all__ = ["EngineState", "load_checkpoint", "save_checkpoint"]

STATE = "state.json"


@dataclass
class EngineState:
    """What a checkpoint holds: the first CL not yet processed, the cells, the stock's volume and the
    volume removed so far (mm³), and where the last CL's tool left no material."""

    next_cl: int
    cells: list[Cell]
    stock_volume: float
    removed_total: float
    cleared: ClearedTool | None


def save_checkpoint(folder: Path, state: EngineState) -> None:
    """Write ``state`` into ``folder`` atomically (see the module) and drop older IPW files."""
    folder.mkdir(parents=True, exist_ok=True)
    name = f"ipw-{state.next_cl:07d}.bbrep"
    cells = state.cells
    write_binary_brep(compound(compound([]) if c.empty else compound(la.region for la in c.layers) if c.layers
                               else c.shape for c in cells),
                      str(folder / (name + ".tmp")))
    os.replace(folder / (name + ".tmp"), folder / name)
    saved = {"next_cl": state.next_cl, "ipw": name, "stock_volume": state.stock_volume,
             "removed_total": state.removed_total, "faces_at_merge": [c.faces_at_merge for c in cells],
             "layers": [[la.state() for la in c.layers] if c.layers else None for c in cells],
             "squares": [c.square for c in cells], "cleared": state.cleared}
    (folder / (STATE + ".tmp")).write_text(json.dumps(saved))
    os.replace(folder / (STATE + ".tmp"), folder / STATE)
    for old in folder.glob("ipw-*.bbrep"):
        if old.name != name:
            old.unlink(missing_ok=True)


def load_checkpoint(folder: Path) -> EngineState | None:
    """The state saved by :func:`save_checkpoint` in ``folder``; None when there is none readable."""
    try:
        saved = json.loads((folder / STATE).read_text())
        ipw = read_binary_brep(str(folder / saved["ipw"]))
    except (OSError, ValueError, KeyError):
        return None
    if ipw.IsNull():
        return None
    cells = []
    heights = saved.get("layers") or [None] * len(saved["faces_at_merge"])
    squares = saved.get("squares") or [None] * len(saved["faces_at_merge"])
    for child, merged, layers, square in zip(children(ipw), saved["faces_at_merge"], heights, squares):
        square = Square(*square) if square else None
        if layers:
            cell = Cell(None, None, merged, square=square)
            cell.set_layers(tuple(layer_from_state(region, la) for region, la in zip(children(child), layers)))
        else:
            cell = Cell.of_solid(child, square, merged)
        cells.append(cell)
    cleared = ClearedTool(*saved["cleared"]) if saved.get("cleared") else None
    return EngineState(int(saved["next_cl"]), cells, saved["stock_volume"], saved["removed_total"], cleared)
