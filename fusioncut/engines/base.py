"""What every engagement engine offers, whatever its kernel: the :class:`Engine` protocol the runner drives,
with the run's options and method names re-exported from :mod:`fusioncut.model.options`."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any, Protocol

from fusioncut.model.engagement import EngagementMap
from fusioncut.model.options import (ENGINE_CHOICES, LOWER_BOUNDS, SWEEP_CHOICES, EngineKind, EngineOptions,
                                     SweepMethod)
from fusioncut.model.moves import Toolpath
from fusioncut.model.stock import Stock
from fusioncut.model.tools import MillingTool

__all__ = ["ENGINE_CHOICES", "LOWER_BOUNDS", "SWEEP_CHOICES", "Engine", "EngineKind", "EngineOptions", "SweepMethod"]


class Engine(Protocol):
    """What the runner (:mod:`fusioncut.runner`) drives, declared once.

    ``start`` (or ``load_checkpoint``) sets the workpiece, ``process`` yields one map per CL segment
    from a CL index on, in order, never skipping one; after each map the engine state (``ipw``,
    ``ipw_volume``, ``removed_total``, a checkpoint) includes that CL and no later one. A checkpoint of
    one B-Rep engine kind resumes in the other; the analytic engine's only in itself (the job hash
    names the engine when it is not the default, so the runner never mixes them). ``options`` may be replaced between runs (the runner sets
    the cell size a checkpoint was cut into). Volumes are mm³.
    """

    options: EngineOptions
    stock_volume: float
    removed_total: float

    @property
    def kind(self) -> EngineKind:
        """Which engine this is (recorded with the results)."""
        ...

    @property
    def shares_cells(self) -> bool:
        """Whether the work is shared out by workpiece cells, so a run without cells gets some."""
        ...

    def start(self, stock: Stock) -> None:
        """Cut the stock into the engine's workpiece (reads and checks a stock solid)."""
        ...

    def process(self, toolpath: Toolpath, default_tool: MillingTool | None = None,
                start_at: int = 0) -> Iterator[EngagementMap]:
        """One map per CL segment from CL ``start_at`` on; the CLs before it are taken as done."""
        ...

    def save_checkpoint(self, folder: Path, next_cl: int) -> None:
        """Write the state before CL ``next_cl`` into ``folder``, atomically."""
        ...

    def load_checkpoint(self, folder: Path) -> int | None:
        """Restore a checkpoint; the next CL index, or None when there is none."""
        ...

    @property
    def ipw(self) -> Any:
        """The in-process workpiece after the last CL handed out (a kernel shape), or None for an
        engine that keeps none (the analytic engine: the runner then exports no IPW)."""
        ...

    @property
    def ipw_volume(self) -> float:
        ...

    def close(self) -> None:
        """Release what the engine holds outside this process (workers); the state goes with them."""
        ...
