"""The options of an engagement run and the names of its sweep methods and engines (model layer: the
job reader, the service and the CLI build their schemas from :class:`EngineOptions` without importing
an engine)."""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

from fusioncut.errors import InputError, JobTooLarge

__all__ = ["ENGINE_CHOICES", "LOWER_BOUNDS", "SWEEP_CHOICES", "EngineKind", "EngineOptions", "SweepMethod"]


class SweepMethod(StrEnum):
    """How a CL's swept volume is built; the value is what results and job files say.

    ``EXACT``: the tool's exact swept solid. ``SAMPLED``: the published method, a union of tool
    copies every R/4 along the move. ``STEP``: a piece of a ramp or helix swept exactly as a level
    step (:func:`fusioncut.engines.segments.step_motion`); reported, never asked for.
    """

    EXACT = "exact"
    SAMPLED = "sampled"
    STEP = "step"


# the sweep methods a job may ask for (``EngineOptions.sweep``); STEP is only ever reported
SWEEP_CHOICES = (SweepMethod.EXACT, SweepMethod.SAMPLED)


class EngineKind(StrEnum):
    """Which engine runs the CLs: the B-Rep engine in this process or over Dask workers, or the
    analytic engine (exact sweeps, no Booleans). ``AUTO`` is only asked for: the runner resolves it
    to ``ANALYTIC`` or ``BREP`` before a run starts (:func:`fusioncut.runner.resolve_engine`)."""

    AUTO = "auto"
    BREP = "brep"
    PARALLEL_BREP = "parallel-brep"
    ANALYTIC = "analytic"


# the engines a job may ask for (``EngineOptions.engine``); PARALLEL_BREP follows from the run options
ENGINE_CHOICES = (EngineKind.AUTO, EngineKind.BREP, EngineKind.ANALYTIC)


def _option(default: Any, help: str) -> Any:
    """A field of :class:`EngineOptions` with its one-paragraph help (units, what ``None`` means),
    read by the job schema, the service schema and the CLI flags (immutable defaults only)."""
    return field(default=default, metadata={"help": help})


@dataclass(frozen=True)
class EngineOptions:
    """Knobs of a run; lengths in mm. Each field's ``metadata["help"]`` documents it.

    Invariants: the lengths that drive how much work a run makes are bounded below
    (:data:`LOWER_BOUNDS`, checked here, before any move is expanded); ``sweep`` is a
    :class:`SweepMethod` one may ask for (``exact`` or ``sampled``; strings are accepted); ``engine``
    is one of :data:`ENGINE_CHOICES` (strings are accepted).

    The mechanisms behind the options are described where they act: cells, their quarters and the
    Boolean's fuzzy values in :mod:`fusioncut.engines.brep.engine`, the height map
    (``ceiling_pixel``) in :mod:`fusioncut.engines.ceiling`, layers in
    :mod:`fusioncut.engines.brep.layers`, steps and chords in :mod:`fusioncut.engines.segments`,
    rubbing (``min_chip_thickness``; known only where the CL's cells that lost material were all
    layered) in :mod:`fusioncut.engines.chip`. Why the defaults are what they are:
    ``docs/decisions/engine-options.md``.
    """

    slice_height: float = _option(1.0, (
        "Axial slice spacing (mm): slice k covers [k, k+1) * slice_height above the tool tip and is "
        "evaluated in the middle of its part that touches material."))
    max_segment_length: float | None = _option(None, (
        "Longer moves are split into CL segments of at most this length (mm); None keeps the moves "
        "as programmed."))
    chord_tolerance: float = _option(1e-3, (
        "ZX / YZ arcs and steep helices become chords within this distance (mm) of the path."))
    ramp_step: float = _option(5e-2, (
        "Ramps and helices up to a 1:5 slope are swept as level steps whose tool positions stay "
        "within this distance (mm) of the path (fusioncut.engines.segments says why)."))
    sweep: SweepMethod = _option(SweepMethod.EXACT, (
        "How a CL's swept volume is built: 'exact' (the tool's exact swept solid) or 'sampled' "
        "(tool copies every R/4, the published method)."))
    failure_dir: Path | None = _option(None, (
        "Folder where the workpiece and sweep of a failed Boolean are saved as .brep; None: "
        "./fusioncut-failures."))
    merge_growth: float = _option(0.5, (
        "Merge a workpiece cell's same-surface faces once its face count grew by this fraction "
        "since its last merge (dimensionless)."))
    fuzzy: float | None = _option(None, (
        "The Booleans' first fuzzy value (mm); None: 1e-6 with cells, 0 (exact) for a whole "
        "workpiece."))
    fuzzy_retries: tuple[float, ...] = _option((1e-6, 1e-5, 1e-4), (
        "Fuzzy values (mm) a failed Boolean is retried with, in order."))
    cell_size: float | None = _option(20.0, (
        "The workpiece is kept as square columns of this size (mm) so that each Boolean touches a "
        "bounded piece; a solid cell may be split into quarters down to a quarter of it. None keeps "
        "the workpiece whole."))
    kernel_threads: bool = _option(True, (
        "Let the kernel run each Boolean on its own threads (parallel workers turn it off where "
        "they have a core each)."))
    ceiling_pixel: float | None = _option(0.1, (
        "Pixel size (mm) of the material's height map, with which a cell the sweep provably misses "
        "skips its Booleans; None runs every Boolean. Exact sweeps only; changes no result."))
    layers: bool = _option(True, (
        "Keep cells that only cylindrical tools cut horizontally or vertically as stacks of 2.5D "
        "layers cut by 2D Booleans (same material and contact, cheaper). Exact sweeps only."))
    max_layers: int = _option(128, (
        "A layered cell with more layers than this is cut as a solid from then on."))
    min_chip_thickness: float = _option(1e-3, (
        "A slice band whose removed material is thinner than this (mm) across the path only rubs: "
        "its arcs are no engagement and do not count in ap; 0 turns the test off."))
    kernel_budget_s: float | None = _option(60.0, (
        "Wall time (s) a CL's 3D Booleans may take in the B-Rep engine: they run in a child process "
        "that is killed past it, the CL is FAILED with its shapes saved and the workpiece kept as "
        "before it; None runs them in this process, unbounded and deaf to Ctrl-C."))
    engine: EngineKind = _option(EngineKind.AUTO, (
        "Which engine computes the engagement: 'brep' (OCCT Booleans on the B-Rep IPW), 'analytic' "
        "(exact sweeps, no Booleans; box or cylinder stock and tools of revolution only; the IPW as an STL "
        "of its height map only) or 'auto': analytic where it applies to the whole run (box or cylinder "
        "stock, every tool, exact sweeps, no IPW export or snapshot asked), else brep; the log says which "
        "and why."))

    def __post_init__(self) -> None:
        self._choose("sweep", SweepMethod, SWEEP_CHOICES)
        self._choose("engine", EngineKind, ENGINE_CHOICES)
        for name, low in LOWER_BOUNDS.items():
            value = getattr(self, name)
            if value is not None and not value >= low:
                raise JobTooLarge(f"options.{name}: {value:g} mm is below its lower bound of {low:g} mm "
                                  "(finer buys no accuracy, only work; see EngineOptions)")

    def _choose(self, name: str, kind: type[StrEnum], choices: tuple[StrEnum, ...]) -> None:
        """Store field ``name`` as its enum member, or refuse a value that is not one of ``choices``."""
        value = getattr(self, name)
        try:
            member = kind(value)
        except ValueError:
            member = None
        if member not in choices:
            raise InputError(f"options.{name}: {value!r} is not one of " + ", ".join(repr(c.value) for c in choices))
        object.__setattr__(self, name, member)

    @property
    def exact(self) -> bool:
        """Whether CLs are swept exactly (the height map and the layers need it)."""
        return self.sweep == SweepMethod.EXACT


# mm. Below these a value buys no accuracy and only multiplies the work: 1 µm is the kernel's working
# precision scale (the Booleans' fuzzy values are 1e-6 to 1e-4 mm) and posts write coordinates to 1 µm
# or 0.1 µm, so CLs, steps or slices closer than that are closer than the program says where the tool
# is; a chord's sagitta of 1e-5 mm is a hundredth of the default and ten times the default fuzzy value.
# How much work a job makes within the bounds is sized by fusioncut.engines.sizing.
LOWER_BOUNDS = {"max_segment_length": 1e-3, "ramp_step": 1e-3, "slice_height": 1e-3, "chord_tolerance": 1e-5}
