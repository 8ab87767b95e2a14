"""What every engagement engine offers, whatever its kernel."""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, Protocol

from fusioncut.errors import JobTooLarge
from fusioncut.model.engagement import EngagementMap
from fusioncut.model.stock import Stock
from fusioncut.model.tools import MillingTool
from fusioncut.model.moves import Toolpath


@dataclass(frozen=True)
class EngineOptions:
    """Knobs of a run (mm unless stated).

    ``slice_height``: axial slice spacing; slice k covers [k, k+1)*slice_height above the tip and is
    evaluated in the middle of its part that touches material. ``max_segment_length``: longer moves
    are split into CL segments of at most this length (None: as programmed). ``chord_tolerance``:
    ZX / YZ arcs become chords within this distance of the path. ``ramp_step``: ramps and helices
    up to a 1:5 slope are swept as level steps whose tool positions stay within this distance of
    the path (:mod:`fusioncut.engines.segments` says why not the oblique sweep, and why not finer).
    ``sweep``: "exact" or "sampled" (tool copies every R/4, the published method). ``failure_dir``:
    where the shapes of a failed Boolean are saved as .brep. ``merge_growth``: merge same-surface
    faces of a workpiece cell when its face count grew by this fraction since the last merge.

    ``cell_size``: the workpiece is kept as square columns of this size (mm), 20 by default, so that
    each Boolean touches a bounded piece; ``None`` keeps it whole. Cells give the whole workpiece's
    results on lines, arcs, trochoids and helical entries (tested to 0.001° and 1e-6, and a helical
    entry centred on a cell corner conserves volume to 1e-9). On the quick Titan-like benchmark 20 mm
    cells took 156 s against 275 s for the whole workpiece, and the adaptive median 48 against 85 ms.
    A cell that a level flat-end-mill cut leaves solid is split into quarter squares, down to a
    quarter of ``cell_size`` (``fusioncut.engines.brep.engine.BRepEngine._quarter`` says why that far).

    ``fuzzy``: the Booleans' fuzzy value (mm). ``None`` means 1e-6 with cells and 0 (exact) without:
    cells need it (with 0, OCCT returned an empty Common where a sweep face lay on a cell wall), the
    whole workpiece does better without (1e-6 leaked 1.3e-6 of the stock volume over 540 CLs of a
    real program). ``fuzzy_retries``: the values a failed Boolean is retried with.

    ``kernel_threads``: let the kernel run each Boolean on its own threads. Alone on 2 cores this
    took the quick benchmark's adaptive median from 68 to 59–65 ms; with two runs sharing the cores it
    cost 6–13% (1055_utab, first 300 CLs), so the parallel engine's workers turn it off where they
    have a core each, and keep it where their host has a core to spare (a lone worker on 2 cores).

    ``ceiling_pixel``: pixel size (mm) of the material's height bounds
    (:class:`fusioncut.engines.ceiling.MaterialCeiling`), with which a cell whose material the sweep
    provably misses skips its Booleans; ``None`` runs every Boolean. Used with exact sweeps only; it
    changes no result, only the time.

    ``layers``: keep cells that only cylindrical tools (flat end mills with the flute's diameter up
    the shank) have cut horizontally or vertically as stacks of 2.5D layers, cut by 2D Booleans
    (:mod:`fusioncut.engines.brep.layers`); the first other cut turns a cell into a solid for good.
    Same material, same contact faces, fewer and cheaper kernel operations. Exact sweeps only.
    ``max_layers``: a layered cell with more layers than this goes on as a solid. A cut costs a 2D
    difference per layer it takes material from (0.1-0.6 ms in closed form; 1.5 ms with OCCT's
    General Fuse, when this was 6), and a helical entry's steps leave a ledge each on the bore (44 a
    turn on the Titan-like benchmark): its first helix and the trochoids after it (CLs 997-1596)
    took 14.2 s with 6 (the bore's cells solid), 10.2 s with 30 and 3.0 s with 100 (all layered),
    with the same maps CL by CL.

    ``min_chip_thickness`` (mm, default 1 µm, 0 turns it off): a slice band whose removed material
    is thinner than this across the path (removed volume / contact height / horizontal travel of the
    CL) only rubs, as the µm skins a post's rounded coordinates leave on an earlier pass's walls: its
    arcs are no engagement and do not count in ap (:mod:`fusioncut.engines.chip`). Known only where
    the CL's cells that lost material were all layered; elsewhere no slice is called rubbing.

    Lower bounds (:data:`LOWER_BOUNDS`, checked when the options are made, before any move is
    expanded): 1e-3 mm for ``max_segment_length``, ``ramp_step`` and ``slice_height``, 1e-5 mm for
    ``chord_tolerance``. Below them a value buys no accuracy and only multiplies the work: 1 µm is
    the kernel's own working precision scale (the Booleans' fuzzy values are 1e-6 to 1e-4 mm) and
    posts write coordinates to 1 µm (3 decimals) or 0.1 µm, so CLs, steps or slices closer than that
    are closer than the program itself says where the tool is; a chord's sagitta of 1e-5 mm is a
    hundredth of the default and ten times the Booleans' default fuzzy value (a 5 mm arc then takes
    1,571 chords a turn). ``max_segment_length: 1e-5`` on a 5-line job once took 57 s and 1.8 GB
    before it was refused; how much work a job makes within the bounds is sized by
    :mod:`fusioncut.engines.sizing`.
    """

    slice_height: float = 1.0
    max_segment_length: float | None = None
    chord_tolerance: float = 1e-3
    ramp_step: float = 5e-2
    sweep: Literal["exact", "sampled"] = "exact"
    failure_dir: Path | None = None
    merge_growth: float = 0.5
    fuzzy: float | None = None
    fuzzy_retries: tuple[float, ...] = (1e-6, 1e-5, 1e-4)
    cell_size: float | None = 20.0
    kernel_threads: bool = True
    ceiling_pixel: float | None = 0.1
    layers: bool = True
    max_layers: int = 128
    min_chip_thickness: float = 1e-3

    def __post_init__(self) -> None:
        for name, low in LOWER_BOUNDS.items():
            value = getattr(self, name)
            if value is not None and not value >= low:
                raise JobTooLarge(f"options.{name}: {value:g} mm is below its lower bound of {low:g} mm "
                                  "(finer buys no accuracy, only work; see EngineOptions)")


# mm; EngineOptions' docstring says why these values
LOWER_BOUNDS = {"max_segment_length": 1e-3, "ramp_step": 1e-3, "slice_height": 1e-3, "chord_tolerance": 1e-5}


class EngagementEngine(Protocol):
    def run(self, toolpath: Toolpath, stock: Stock, default_tool: MillingTool | None = None) -> Iterator[EngagementMap]:
        """Yield one EngagementMap per CL segment, in order; never skip one."""
        ...
