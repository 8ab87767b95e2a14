"""Running a whole job: read inputs, run the engine CL by CL, write results as they come.

Shared by the CLI and the service so there is one implementation of a run:

1. :func:`prepare_job` reads and checks *every* input (tool library, tools, toolpaths, stock) and
   writes nothing, so bad input fails with an :class:`~fusioncut.errors.InputError` naming
   ``file:line`` before the results folder is touched.
2. :func:`run_toolpath` runs the CLs, writing rows as they come (:class:`ResultWriter`). Every
   ``checkpoint_every`` CLs, when the run ends and when it is interrupted, the rows are flushed
   and *then* the engine state is saved in ``<out>/checkpoint`` (a checkpoint never runs ahead of
   the rows on disk).
3. Calling :func:`run_job` again on the same folder resumes: if the checkpoint belongs to the same
   job hash (and FusionCut version) the IPW is loaded, rows of CLs at or after the checkpoint are
   dropped, and the run continues there, ending with the results an uninterrupted run gives. A
   different job starts over and clears the folder's results.

Ctrl-C stops cleanly after the CL in progress (a second Ctrl-C stops at once): rows are flushed,
a checkpoint is written and the result says ``interrupted``. Per CL, the log records at DEBUG level
the index, source ``file:line``, status, sweep method and timings (ms).

The run options ``workers`` and ``scheduler`` run the CLs on Dask workers
(:mod:`fusioncut.engines.brep.parallel`) with the same rows, checkpoints, snapshots and exports; a
checkpoint of a parallel run resumes single-process and the other way round. The workers compute
CLs in batches, so there Ctrl-C stops once the batch in progress is done.

The engine option ``engine="analytic"`` runs :class:`~fusioncut.engines.analytic.engine.AnalyticEngine`
(exact sweeps, no Booleans) instead: box stocks, round bars and tools of revolution only, checked
before anything is written; with ``workers`` or ``scheduler`` its CLs are computed in chunks on Dask workers
(:mod:`fusioncut.engines.analytic.parallel`, the same rows); it keeps no B-Rep workpiece, so the
IPW export and snapshots are STL only, a mesh of its exact height map (one warning says so; no
STEP). ``engine="auto"`` (the default) is resolved before anything is written
(:func:`resolve_engine`): the analytic engine where it applies to the whole run and no IPW export
or snapshot is asked, else the B-Rep engine, with one log line saying why. ``metadata.json``'s
``engine_options.engine`` and the checkpoint's ``run.json`` record the engine that ran (a checkpoint
of the other engine is not resumed), and each ``cl`` row its ``engine``.
"""
from __future__ import annotations

import json
import logging
import os
import signal
import statistics
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from fusioncut._version import __version__
from fusioncut.engines.analytic.engine import AnalyticEngine
from fusioncut.engines.base import Engine, EngineKind, EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.segments import segments_for
from fusioncut.engines.sizing import Budget, size_toolpath
from fusioncut.errors import FusionCutError, InputError
from fusioncut.io import tool_sources
from fusioncut.io.job import RUN_OPTIONS, Job, build_stock, job_hash, read_toolpath
from fusioncut.io.mesh import write_stl
from fusioncut.io.results import ResultWriter, load_results
from fusioncut.model import (ArcMove, ArcPlane, BoxStock, CLStatus, CylinderStock, EngagementMap, MillingTool, Move,
                             Stock, Toolpath)

log = logging.getLogger("fusioncut.run")

CHECKPOINT_DIR = "checkpoint"
RUN_STATE = "run.json"  # in the checkpoint folder: which job (hash, version) the engine state is of,
# and the cell size its workpiece was cut into
DEFAULT_CHECKPOINT_EVERY = 200
EXPORT_BUDGETS = 10  # an IPW export (joining every cell, then writing) may take this many CL kernel budgets
PARALLEL_CELL_SIZE = EngineOptions().cell_size  # mm: the cells of a parallel run whose job asks for none

__all__ = [
    "OperationSummary", "PreparedJob", "RunPlan", "RunResult", "export_budget_s", "prepare_job", "read_toolpath",
    "resolve_engine", "run_job", "run_toolpath",
]


@dataclass
class OperationSummary:
    """Per-operation counts and totals of a run (volumes mm³, depths mm, times ms)."""

    operation: str
    cls: int = 0
    engaged: int = 0
    air: int = 0
    rapid: int = 0
    failed: int = 0
    removed: float = 0.0
    max_ae: float = 0.0
    max_ap: float = 0.0
    times_ms: list[float] = field(default_factory=list)

    def add(self, m: EngagementMap) -> None:
        total = dict(m.timings_ms).get("total")
        self._count(m.status.value, m.removed_volume, m.ae, m.ap, total)

    def add_row(self, row: dict[str, Any]) -> None:
        """Count a CL from its ``cl`` table row (the CLs a resumed run kept)."""
        t = row["time_ms"]
        self._count(str(row["status"]), row["removed_volume_mm3"], row["ae_mm"], row["ap_mm"],
                    t if t > 0 else None)

    def _count(self, status: str, removed: float, ae: float, ap: float, total_ms: float | None) -> None:
        self.cls += 1
        setattr(self, status, getattr(self, status) + 1)
        self.removed += removed
        self.max_ae = max(self.max_ae, ae)
        self.max_ap = max(self.max_ap, ap)
        if total_ms is not None:
            self.times_ms.append(total_ms)

    @property
    def median_ms(self) -> float:
        return statistics.median(self.times_ms) if self.times_ms else 0.0


@dataclass
class RunResult:
    """Outcome of a run. Volumes in mm³, ``seconds`` the wall time of this call. ``resumed_from`` is
    the first CL computed by this call (0 unless a checkpoint was resumed); ``exported`` lists the
    IPW files written (``ipw.step``, ``ipw.stl``, snapshots). ``final_volume`` is the IPW's; the
    analytic engine's is integrated from its sweeps, independently of the CLs' volumes
    (:func:`_final_volume`), unless the run was interrupted."""

    operations: dict[str, OperationSummary]
    stock_volume: float
    final_volume: float
    removed_volume: float
    seconds: float
    out_dir: Path
    interrupted: bool = False
    resumed_from: int = 0
    exported: list[Path] = field(default_factory=list)

    @property
    def conservation_error(self) -> float:
        """|stock - final - Σ removed| / stock volume."""
        return abs(self.stock_volume - self.final_volume - self.removed_volume) / self.stock_volume


@dataclass(frozen=True)
class RunPlan:
    """What a run is about to do, given to ``on_start`` before the first CL: CLs per operation in
    program order (``expected``), how many of them are already done (``done``, from a checkpoint),
    the total CL count and the first CL index computed now."""

    expected: dict[str, int]
    done: dict[str, int]
    total: int
    start_at: int = 0


@dataclass(frozen=True)
class PreparedJob:
    """Everything a job needs, read and checked: the toolpath with exactly the tools it uses, the
    stock, engine options, the tool for moves without a T word, the job hash and run options."""

    toolpath: Toolpath
    stock: Stock
    options: EngineOptions
    default_tool: MillingTool | None
    job_id: str
    checkpoint_every: int = DEFAULT_CHECKPOINT_EVERY
    snapshot_cls: tuple[int, ...] = ()
    workers: int = 1
    scheduler: str | None = None


# --------------------------------------------------------------------------------------------------
# reading and checking the inputs


def prepare_job(job: Job, base: Path) -> PreparedJob:
    """Read and check every input of ``job`` (paths relative to ``base``); writes nothing.

    Tools are resolved per T number (:func:`fusioncut.io.tool_sources.resolve_tools`): the job's
    ``tools`` first, then the tool library (a tool the library could not model fails with its
    reason) and the tools the toolpath file describes itself (Fusion tool comments, APT ``CUTTER``),
    in the order the job's ``tool_source`` says; sources that disagree on a tool are warned about.
    Moves without a T word use the only tool defined when there is exactly one. Anything
    unresolved is an :class:`InputError` naming the ``file:line`` of the first move concerned.
    """
    library = None
    if job.tool_library:
        from fusioncut.io.tool_library import read_tool_library

        library = read_tool_library(base / job.tool_library)
        for w in library.warnings:
            log.warning("%s", w)
        for number, err in sorted(library.refused.items()):
            log.warning("tool library: T%d left out: %s", number, err)
    job_tools = tool_sources.job_tools(job.tools, library, base)
    given: dict[int, MillingTool] = {**(library or {}), **job_tools}

    moves: list[Move] = []
    warnings: list[str] = []
    file_tools: dict[int, MillingTool] = {}
    for name in job.toolpaths:
        tp = read_toolpath(base / name, given, job.strict)
        again = tool_sources.program_first_tools(tp, given, job_tools, job.tool_source)
        if again is not None:  # compensate with the program's tool radii, not the library's
            tp = read_toolpath(base / name, again, job.strict)
        for n, t in (tp.program_tools if tp.program_tools is not None else tp.tools).items():
            file_tools.setdefault(n, t)
        moves.extend(tp.moves)
        warnings.extend(tp.warnings)
    for w in warnings:
        log.warning("%s", w)
    if not moves:
        raise InputError("the toolpath has no moves", base / job.toolpaths[0])

    tools, default_tool, tool_warnings = tool_sources.resolve_tools(moves, job_tools, library, file_tools,
                                                                    job.tool_source)
    for w in tool_warnings:
        log.warning("%s", w)
    warnings.extend(tool_warnings)
    toolpath = Toolpath(tuple(moves), tools, tuple(warnings), source=",".join(job.toolpaths))
    stock = build_stock(job.stock, base)
    if stock is None:
        from fusioncut.io.stock import infer_stock, stock_top

        top, rule = (job.stock.top, "the top given") if job.stock.top is not None else stock_top(toolpath)
        stock = infer_stock(toolpath, margin=job.stock.margin, top=top)
        log.warning("stock inferred from the toolpath extents: %s .. %s (top: %s)", stock.minimum, stock.maximum, rule)
    engine_opts = job.options.model_dump(exclude=set(RUN_OPTIONS))
    return PreparedJob(toolpath, stock, EngineOptions(**engine_opts), default_tool, job_hash(job, base),
                       job.options.checkpoint_every, tuple(job.options.snapshot_cls), job.options.workers,
                       job.options.scheduler)


# --------------------------------------------------------------------------------------------------
# running


def run_job(job: Job, base: Path, out_dir: Path, on_cl: Callable[[EngagementMap, int], None] | None = None,
            resume: bool = True, *, export_ipw: bool = True,
            on_start: Callable[[RunPlan], None] | None = None, budget: Budget | None = None) -> RunResult:
    """Run ``job`` (paths relative to ``base``) into ``out_dir``; see the module docstring.

    ``resume``: continue from a checkpoint of the same job in ``out_dir`` (``False``: start over).
    ``on_cl(map, total)`` is called after each CL, once its row and any due checkpoint are written;
    ``on_start(plan)`` once before the first. ``export_ipw`` writes the final workpiece as
    ``ipw.step`` and ``ipw.stl``. Input errors are raised before anything is written. The job's
    ``workers`` / ``scheduler`` options run it in parallel (see :func:`run_toolpath`).

    To stop a run from outside (a service cancelling a job), raise ``KeyboardInterrupt`` in
    ``on_cl``: the run returns with ``interrupted=True`` and a checkpoint after that CL. Any other
    exception from ``on_cl`` also leaves a checkpoint and is then raised. ``budget``: see
    :func:`run_toolpath`.
    """
    p = prepare_job(job, base)
    options = replace(p.options, failure_dir=Path(out_dir) / "failures")
    return run_toolpath(p.toolpath, p.stock, out_dir, options, default_tool=p.default_tool, job_id=p.job_id,
                        on_cl=on_cl, resume=resume, checkpoint_every=p.checkpoint_every,
                        snapshot_cls=p.snapshot_cls, export_ipw=export_ipw, on_start=on_start, workers=p.workers,
                        scheduler=p.scheduler, budget=budget)


def run_toolpath(toolpath: Toolpath, stock: Stock, out_dir: Path, options: EngineOptions | None = None,
                 default_tool: MillingTool | None = None, job_id: str = "",
                 on_cl: Callable[[EngagementMap, int], None] | None = None, *, resume: bool = False,
                 checkpoint_every: int = DEFAULT_CHECKPOINT_EVERY, snapshot_cls: Iterable[int] = (),
                 export_ipw: bool = True, on_start: Callable[[RunPlan], None] | None = None,
                 workers: int = 1, scheduler: str | None = None, budget: Budget | None = None) -> RunResult:
    """Run every CL of ``toolpath`` on ``stock``, writing results into ``out_dir`` as they come.

    ``on_cl(map, total)`` is called after each CL (progress reporting). ``resume`` continues from a
    checkpoint in ``out_dir`` whose job hash is ``job_id``. ``checkpoint_every`` (CLs; 0: only at the
    end and on interruption), ``snapshot_cls`` (CL indices after which the IPW is written as
    ``ipw_cl<N>.step``) and ``export_ipw`` (``ipw.step`` and ``ipw.stl`` at the end).

    ``workers`` > 1 runs the CLs on an embedded Dask cluster of that many worker processes,
    ``scheduler`` on the workers of a running Dask scheduler (see
    :mod:`fusioncut.engines.brep.parallel`); the cluster is closed when the run ends, however it ends.
    ``budget`` (default :class:`~fusioncut.engines.sizing.Budget`): the job is sized from its moves
    first and refused (:class:`~fusioncut.errors.JobTooLarge`) before anything is expanded or written
    when it would make more work than that.
    """
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    options = options or EngineOptions()
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    options = resolve_engine(options, toolpath, stock, default_tool, export_ipw or bool(tuple(snapshot_cls)))
    with _CtrlC() as ctrl_c:  # also over the cluster's start and close: Ctrl-C there only asks to stop
        engine = _engine(options, workers, scheduler)
        try:
            result = _run(engine, ctrl_c, toolpath, stock, out_dir, default_tool, job_id, on_cl, resume,
                          checkpoint_every, snapshot_cls, export_ipw, on_start, budget)
        finally:
            engine.close()
    result.seconds = time.perf_counter() - t0
    return result


def resolve_engine(options: EngineOptions, toolpath: Toolpath, stock: Stock, default_tool: MillingTool | None = None,
                   wants_ipw: bool = False) -> EngineOptions:
    """``options`` with ``engine="auto"`` resolved, before anything is written: ``analytic`` when the
    analytic engine applies to the whole run (a box stock or a round bar, every tool passing
    :meth:`AnalyticEngine.check_tools`, exact sweeps, and no B-Rep workpiece wanted: ``wants_ipw``,
    an IPW export or snapshot asked), else ``brep``; one INFO line of the log says which and why
    (naming the tool or the stock). Options asking for an engine by name are returned as given."""
    if options.engine != EngineKind.AUTO:
        return options
    why = _why_not_analytic(options, toolpath, stock, default_tool, wants_ipw)
    if why:
        log.info("engine auto: the B-Rep engine runs this job, as %s", why)
        return replace(options, engine=EngineKind.BREP)
    log.info("engine auto: the analytic engine runs this job (a box or round bar stock, tools of revolution "
             "without undercut, exact sweeps, no IPW export or snapshot asked)")
    return replace(options, engine=EngineKind.ANALYTIC)


def _why_not_analytic(options: EngineOptions, toolpath: Toolpath, stock: Stock, default_tool: MillingTool | None,
                      wants_ipw: bool) -> str:
    """Why the analytic engine does not apply to a run ('' when it does)."""
    if not isinstance(stock, (BoxStock, CylinderStock)):
        return f"the analytic engine needs a box stock or a round bar and the stock is a {type(stock).__name__}"
    if not options.exact:
        return f"sweep {options.sweep.value!r} is asked (the analytic engine sweeps exactly)"
    try:
        AnalyticEngine(options).check_tools(toolpath, default_tool)
    except FusionCutError as exc:
        return f"the analytic engine cannot sweep a tool: {exc}"
    if wants_ipw:
        return ("an IPW export or snapshot is asked, which the B-Rep engine writes as STEP and STL (the analytic "
                "engine writes an STL of its height map only; without the export, e.g. --no-ipw-export, or with "
                "engine 'analytic', the analytic engine runs it)")
    if _flat_level_cuts(toolpath, default_tool):
        return ("every cut is a level or vertical move of a flat end mill, where the B-Rep engine's 2.5D layers are "
                "exact as well and far faster (docs/decisions/engine-auto.md)")
    return ""


def _flat_level_cuts(toolpath: Toolpath, default_tool: MillingTool | None) -> bool:
    """Whether every feed move is level (a line or an XY arc at one height) or vertical (a plunge or a
    retract) and made with a flat end mill: the program the B-Rep engine cuts as 2.5D layers, exactly
    (a ramp, a helix, a 3D move or another tool shape it sweeps in steps or as solids)."""
    for move in toolpath.moves:
        if move.is_rapid:
            continue
        tool = toolpath.tools.get(move.tool, default_tool) if move.tool is not None else default_tool
        if tool is None or tool.kind != "flat":
            return False
        (x0, y0, z0), (x1, y1, z1) = move.start, move.end
        if isinstance(move, ArcMove) and move.plane != ArcPlane.XY:
            return False
        if z0 != z1 and (isinstance(move, ArcMove) or (x0, y0) != (x1, y1)):
            return False
    return True


def _engine(options: EngineOptions, workers: int, scheduler: str | None) -> Engine:
    """The engine for these run options: :class:`AnalyticEngine` when the options ask for it, else
    :class:`BRepEngine`; with ``workers`` > 1 or a ``scheduler``, their parallel kinds with the Dask
    client open (an unreachable scheduler fails here, before anything is written)."""
    analytic = options.engine == EngineKind.ANALYTIC
    if workers <= 1 and not scheduler:
        return AnalyticEngine(options) if analytic else BRepEngine(options)
    if _inside_dask_worker():
        # a LocalCluster's worker processes cannot be started from a (daemonic) Dask worker, and a
        # job the service runs already has its own worker: it stays single-process there
        log.warning("running inside a Dask worker: the job runs single-process here (workers and scheduler "
                    "ignored)")
        return AnalyticEngine(options) if analytic else BRepEngine(options)
    if analytic:
        from fusioncut.engines.analytic.parallel import ParallelAnalyticEngine

        analytic_engine = ParallelAnalyticEngine(options, workers=workers, scheduler=scheduler)
        analytic_engine.open()
        return analytic_engine
    # imported here: distributed costs a second of start-up that a single-process run saves
    from fusioncut.engines.brep.parallel import ParallelBRepEngine

    if scheduler and workers > 1:
        log.info("the cells are split among every worker of the scheduler at %s; workers=%d is ignored",
                 scheduler, workers)
    engine = ParallelBRepEngine(options, workers=workers, scheduler=scheduler)
    engine.open()
    return engine


def _inside_dask_worker() -> bool:
    try:
        from distributed import get_worker
    except ImportError:
        return False
    try:
        get_worker()
    except ValueError:
        return False
    return True


def _run(engine: Engine, ctrl_c: _CtrlC, toolpath: Toolpath, stock: Stock, out_dir: Path,
         default_tool: MillingTool | None, job_id: str, on_cl: Callable[[EngagementMap, int], None] | None,
         resume: bool, checkpoint_every: int, snapshot_cls: Iterable[int], export_ipw: bool,
         on_start: Callable[[RunPlan], None] | None, budget: Budget | None = None) -> RunResult:
    options = engine.options
    size_toolpath(toolpath, options, default_tool, checkpoint_every, snapshot_cls, budget, stock)
    segments = segments_for(toolpath.moves, options)
    total = len(segments)
    expected: dict[str, int] = {}
    for s in segments:
        expected[s.operation] = expected.get(s.operation, 0) + 1
    ck_dir = out_dir / CHECKPOINT_DIR
    if engine.kind == EngineKind.ANALYTIC:
        engine.check_tools(toolpath, default_tool)  # type: ignore[attr-defined]  # before anything is written

    ran = _engine_name(engine)
    start_at, kept_rows = (_resume_point(engine, out_dir, job_id, total) if resume else (0, []))
    if start_at == 0:
        if engine.shares_cells and options.cell_size is None:
            engine.options = replace(options, cell_size=PARALLEL_CELL_SIZE)
            log.info("parallel run: the workpiece is kept as %g mm cells (the job asks for none)",
                     PARALLEL_CELL_SIZE)
        engine.start(stock)  # reads and checks a stock solid: still before anything is written
        _clear_previous_run(out_dir)
        _write_run_state(ck_dir, job_id, engine.options.cell_size, ran)
    else:
        log.warning("resuming from the checkpoint in %s at CL %d of %d", ck_dir, start_at, total)
        _continue_with_checkpoint_cells(engine, ck_dir)
    ops: dict[str, OperationSummary] = {}
    for row in kept_rows:
        ops.setdefault(row["operation"], OperationSummary(row["operation"])).add_row(row)
    if on_start:
        done: dict[str, int] = {}
        for s in segments[:start_at]:
            done[s.operation] = done.get(s.operation, 0) + 1
        on_start(RunPlan(dict(expected), done, total, start_at))

    tools = {t.label: t for t in toolpath.tools.values()}
    if default_tool is not None:
        tools.setdefault(default_tool.label, default_tool)
    snapshots = set(snapshot_cls)
    snapshot_suffix = ".step"
    if engine.kind == EngineKind.ANALYTIC and (export_ipw or snapshots):
        log.warning("the analytic engine keeps no B-Rep workpiece: the IPW is written as STL only, a mesh of its "
                    "exact height map (no STEP: the B-Rep engine writes that)")
        snapshot_suffix = ".stl"
    exported: list[Path] = []
    interrupted = False
    writer = ResultWriter(out_dir, job_hash=job_id, tools=tools, options=engine.options, expected_cls=expected,
                          keep_below=start_at)
    # engine_state: index of the last CL the engine state includes; recorded: the last CL whose row
    # the writer holds. A checkpoint is only consistent when they agree and no step is half done.
    engine_state = recorded = start_at - 1
    in_engine = False
    checkpointed = start_at

    def checkpoint() -> None:
        nonlocal checkpointed
        writer.flush()  # rows first: the checkpoint never runs ahead of the results on disk
        if _save_checkpoint(engine, ck_dir, recorded + 1):
            checkpointed = recorded + 1

    with writer:
        try:
            maps = engine.process(toolpath, default_tool, start_at=start_at)
            while True:
                in_engine = True
                m = next(maps, None)
                in_engine = False
                if m is None:
                    break
                engine_state = m.cl_index
                writer.add(m, length_mm=segments[m.cl_index].length, spindle_rpm=segments[m.cl_index].spindle_rpm)
                recorded = m.cl_index
                ops.setdefault(m.operation, OperationSummary(m.operation)).add(m)
                _log_cl(m)
                if m.cl_index in snapshots:
                    exported += _export(engine, [out_dir / f"ipw_cl{m.cl_index:06d}{snapshot_suffix}"])
                if checkpoint_every and (m.cl_index + 1) % checkpoint_every == 0 and m.cl_index + 1 < total:
                    checkpoint()
                if on_cl:
                    on_cl(m, total)
                if ctrl_c.requested:
                    raise KeyboardInterrupt
        except BaseException as exc:
            interrupted = isinstance(exc, KeyboardInterrupt)
            if not in_engine and engine_state == recorded:
                try:
                    checkpoint()
                except Exception:  # noqa: BLE001 - keep the original error; the rows are flushed on exit
                    log.exception("could not write a checkpoint")
            if not interrupted:
                raise
            log.warning("interrupted after CL %d: results kept in %s; the checkpoint is at CL %d, run again "
                        "to resume", recorded, out_dir, checkpointed)
    if not interrupted:
        _save_checkpoint(engine, ck_dir, total)  # the writer is closed: every row is on disk
        if export_ipw:
            exported += _export(engine, [out_dir / "ipw.step", out_dir / "ipw.stl"])
    final = engine.ipw_volume if interrupted else _final_volume(engine)
    return RunResult(ops, engine.stock_volume, final, engine.removed_total, 0.0, out_dir, interrupted, start_at,
                     exported)


def _final_volume(engine: Engine) -> float:
    """The workpiece's volume (mm³) at the end of a run. The analytic engine keeps no workpiece, and its
    ``ipw_volume`` is the stock's less the CLs' volumes, which would make the conservation check
    empty: its workpiece is integrated from the sweeps instead (``material_volume``), so that the
    result's conservation error compares that with the CLs' volumes. A failure there is logged and
    the check is left empty, as the results are complete without it."""
    integrate = getattr(engine, "material_volume", None)
    if integrate is None:
        return engine.ipw_volume
    t0 = time.perf_counter()
    try:
        final = integrate()
    except Exception as e:  # noqa: BLE001 - a check of complete results: reported, not raised
        log.error("could not integrate the final workpiece to check the volumes: %s", e)
        return engine.ipw_volume
    log.info("final workpiece integrated from the sweeps in %.1f s: %.6f mm³", time.perf_counter() - t0, final)
    return final


def _save_checkpoint(engine: Engine, ck_dir: Path, next_cl: int) -> bool:
    """Write the engine's checkpoint before CL ``next_cl``; a failure (the kernel refusing to rebuild a
    cell's faces, a full disk) is logged naming the CL and the run goes on: the results stay right,
    only a resume starts from the last checkpoint that was written (each is written whole or not at all)."""
    try:
        engine.save_checkpoint(ck_dir, next_cl)
    except Exception as exc:  # noqa: BLE001 - a checkpoint is a convenience: it never ends the run
        log.error("the checkpoint before CL %d could not be written (%s: %s); the run goes on, and a resume "
                  "starts from the last checkpoint written", next_cl, type(exc).__name__, exc)
        return False
    return True


def _log_cl(m: EngagementMap) -> None:
    """The per-CL trace line (DEBUG): index, source, status, sweep method, timings in ms."""
    if m.status == CLStatus.FAILED:
        log.error("CL %d (%s): %s", m.cl_index, m.source, m.reason)
    if log.isEnabledFor(logging.DEBUG):
        t = dict(m.timings_ms)
        times = " ".join(f"{k}={t[k]:.2f}" if k in t else f"{k}=-"
                         for k in ("sweep", "boolean", "contact", "slicing", "total"))
        log.debug("CL %d %s:%d %s sweep_method=%s ms: %s", m.cl_index, m.source.file, m.source.line,
                  m.status.value, m.sweep_method or "-", times)


def _export(engine: Engine, paths: list[Path]) -> list[Path]:
    """Write the current IPW to each path (.step or .stl; the analytic engine's to the .stl ones
    only, :func:`_export_mesh`); a failure is logged, not raised, because the results are complete
    without it."""
    from fusioncut.engines.brep.export import export_ipw

    if engine.kind == EngineKind.ANALYTIC:
        return _export_mesh(engine, [p for p in paths if p.suffix.lower() == ".stl"])
    written = []
    try:
        ipw = engine.ipw  # once for all paths: a parallel engine fetches it from its workers
    except Exception as e:  # noqa: BLE001 - as below: the results are complete without the files
        log.error("could not get the workpiece to write %s: %s", ", ".join(p.name for p in paths), e)
        return written
    if ipw is None:
        log.warning("the %s engine keeps no workpiece to write %s", engine.kind.value,
                    ", ".join(p.name for p in paths))
        return written
    for p in paths:
        try:
            # joins the cells into one solid and keeps OCCT's output quiet, in the kernel's killable child
            export_ipw(ipw, p, budget_s=export_budget_s(engine.options))
            written.append(p)
        except KeyboardInterrupt:  # the run is done and its rows written: only the file is given up
            log.warning("interrupted while writing %s: not written", p)
            break
        except Exception as e:  # noqa: BLE001 - OCP raises its own types; the run itself succeeded
            log.error("could not write %s: %s", p, e)
    return written


def export_budget_s(options: EngineOptions) -> float | None:
    """The wall time (s) an IPW export may take: :data:`EXPORT_BUDGETS` of a CL's kernel budget
    (None: no budget, as the CLs have none)."""
    budget = options.kernel_budget_s
    return None if budget is None else EXPORT_BUDGETS * budget


def _export_mesh(engine: Engine, paths: list[Path]) -> list[Path]:
    """Write the analytic engine's workpiece as a mesh of its exact height map
    (:meth:`AnalyticEngine.ipw_mesh`) to each path (binary STL); a failure is logged, not raised."""
    written = []
    try:
        triangles = engine.ipw_mesh()  # type: ignore[attr-defined]
    except Exception as e:  # noqa: BLE001 - the results are complete without the files
        log.error("could not mesh the workpiece to write %s: %s", ", ".join(p.name for p in paths), e)
        return written
    for p in paths:
        try:
            written.append(write_stl(p, triangles, "FusionCut IPW, analytic engine's height map"))
        except OSError as e:
            log.error("could not write %s: %s", p, e)
    return written


# --------------------------------------------------------------------------------------------------
# checkpoints


def _engine_name(engine: Engine) -> str:
    """What the rows and the checkpoint call the engine: ``analytic`` or ``brep`` (either B-Rep kind:
    their checkpoints resume in each other)."""
    return EngineKind.ANALYTIC.value if engine.kind == EngineKind.ANALYTIC else EngineKind.BREP.value


def _write_run_state(ck_dir: Path, job_id: str, cell_size: float | None, engine: str) -> None:
    ck_dir.mkdir(parents=True, exist_ok=True)
    tmp = ck_dir / (RUN_STATE + ".tmp")
    tmp.write_text(json.dumps({"job_hash": job_id, "fusioncut_version": __version__, "cell_size": cell_size,
                               "engine": engine}))
    os.replace(tmp, ck_dir / RUN_STATE)


def _continue_with_checkpoint_cells(engine: Engine, ck_dir: Path) -> None:
    """Give the engine the cell size of the run that wrote the checkpoint.

    Its cells are what was loaded, whatever this run's options say: a parallel run without a job
    ``cell_size`` cuts 20 mm cells, and a single-process run resuming it must treat them as cells
    (the Booleans' fuzzy value depends on it); a parallel run resuming a whole workpiece has one cell.
    """
    try:
        state = json.loads((ck_dir / RUN_STATE).read_text())
    except (OSError, ValueError):
        return
    if "cell_size" not in state:
        return
    cell_size = state["cell_size"]
    if cell_size is None and engine.shares_cells:
        log.warning("the checkpoint in %s keeps the workpiece whole, so one worker does all the work; --fresh "
                    "starts over with cells shared out among the workers", ck_dir)
    elif cell_size != engine.options.cell_size:
        log.info("the checkpoint keeps the workpiece as %s; the run goes on with them",
                 "one piece" if cell_size is None else f"{cell_size:g} mm cells")
    engine.options = replace(engine.options, cell_size=cell_size)


def _resume_point(engine: Engine, out_dir: Path, job_id: str, total: int) -> tuple[int, list[dict[str, Any]]]:
    """(first CL to compute, kept ``cl`` rows) from a checkpoint in ``out_dir``; (0, []) to start over.

    Loads the engine state on success. The checkpoint must be of the same job hash and FusionCut
    version, and the results on disk must hold exactly the CLs before it (later rows are dropped)."""
    ck_dir = out_dir / CHECKPOINT_DIR
    try:
        state = json.loads((ck_dir / RUN_STATE).read_text())
    except (OSError, ValueError):
        return 0, []
    if state.get("job_hash") != job_id or state.get("fusioncut_version") != __version__:
        log.warning("the checkpoint in %s is of another job or FusionCut version; starting over", ck_dir)
        return 0, []
    if state.get("engine", _engine_name(engine)) != _engine_name(engine):  # engine 'auto' resolved otherwise
        log.warning("the checkpoint in %s is of the %s engine and this run's is the %s engine; starting over",
                    ck_dir, state["engine"], _engine_name(engine))
        return 0, []
    next_cl = engine.load_checkpoint(ck_dir)
    if not next_cl:
        return 0, []
    if next_cl > total:
        log.warning("the checkpoint in %s is past the end of the toolpath; starting over", ck_dir)
        return 0, []
    try:
        cl = load_results(out_dir).cl
    except (FusionCutError, OSError, ValueError) as e:
        log.warning("cannot read the results to resume (%s); starting over", e)
        return 0, []
    kept = cl[cl["cl"] < next_cl]
    if list(kept["cl"]) != list(range(next_cl)):
        log.warning("the results in %s do not hold CLs 0..%d of the checkpoint; starting over", out_dir, next_cl - 1)
        return 0, []
    return next_cl, kept[["operation", "status", "removed_volume_mm3", "ae_mm", "ap_mm", "time_ms"]].to_dict("records")


def _clear_previous_run(out_dir: Path) -> None:
    """Remove what an earlier run wrote besides the tables (the writer replaces those): checkpoint,
    IPW exports and snapshots, failure shapes. Only FusionCut's own file names are touched."""
    ck_dir = out_dir / CHECKPOINT_DIR
    # the engine state goes first, so a half-cleared folder can never be resumed
    for name in ("state.json", RUN_STATE):
        (ck_dir / name).unlink(missing_ok=True)
    for pattern in ("ipw-*", "*.tmp"):  # the engine's IPW files, whatever BRep flavour it writes
        for p in ck_dir.glob(pattern):
            p.unlink(missing_ok=True)
    for pattern in ("ipw.step", "ipw.stl", "ipw_cl*.step"):
        for p in out_dir.glob(pattern):
            p.unlink(missing_ok=True)
    for pattern in ("cl*_ipw.brep", "cl*_sweep.brep"):
        for p in (out_dir / "failures").glob(pattern):
            p.unlink(missing_ok=True)


class _CtrlC:
    """While active (main thread, default SIGINT handler only), the first Ctrl-C only sets
    ``requested`` so the run stops after the CL in progress with a consistent checkpoint; a second
    one raises KeyboardInterrupt at once. Elsewhere (service threads) nothing is changed."""

    def __init__(self) -> None:
        self.requested = False
        self._previous: Any = None

    def __enter__(self) -> _CtrlC:
        if threading.current_thread() is threading.main_thread() \
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            self._previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum: int, frame: Any) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        log.warning("Ctrl-C: stopping after the CL in progress (press again to stop at once)")

    def __exit__(self, *exc: object) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)

