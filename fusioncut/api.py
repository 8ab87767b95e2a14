r"""The front door: :func:`simulate` runs a job or a toolpath and gives a :class:`Run`.

A tiny job, a 10 mm flat end mill slotting a block 3 mm deep along x (the G-code written first)::

    >>> import pathlib, tempfile
    >>> import fusioncut as fc
    >>> program = pathlib.Path(tempfile.mkdtemp()) / "slot.nc"
    >>> _ = program.write_text("G21 G90 G17\nT1 M6\nS10000 M3\nG0 X0 Y10 Z5\nG1 Z-3 F300\n"
    ...                        "G1 X50 F600\nG0 Z5\nM30\n")
    >>> run = fc.simulate(program, stock="box:10,0,-10,40,20,0", tools={1: fc.FlatEndMill(10.0, 20.0)},
    ...                   options=fc.EngineOptions(slice_height=1.0, max_segment_length=10.0))
    >>> engaged = [m for m in run if m.status == fc.CLStatus.ENGAGED]
    >>> m = engaged[2]  # x 20 -> 30, mid-slot: the tool cuts across its whole width
    >>> [(round(s.intervals[0].entry, 6), round(s.intervals[0].exit, 6)) for s in m.engaged_slices]
    [(0.0, 180.0), (0.0, 180.0), (0.0, 180.0)]
    >>> round(m.ap, 6), round(m.ae, 6)
    (3.0, 10.0)
    >>> res = run.results()  # the tables of the results folder
    >>> int((res.cl["status"] == "engaged").sum()) == len(engaged)
    True
    >>> round(run.result.removed_volume, 3)  # the slot: 30 x 10 x 3 mm
    900.0

Inputs, by ``job_or_program``: a :class:`~fusioncut.io.job.Job` (paths relative to the working
folder), a job file (``.json`` naming ``toolpaths``), a toolpath file of any suffix
:mod:`fusioncut.io.readers` reads (G-code, APT/CLSF, Fusion JSON, CAMotics project), or a
:class:`~fusioncut.model.Toolpath` in memory. Everything is read and checked when :func:`simulate`
returns, so bad input raises an :class:`~fusioncut.errors.InputError` naming ``file:line`` there;
the CLs are computed as the run is iterated (or by :meth:`Run.wait`, :meth:`Run.results`,
:meth:`Run.ipw`).
"""
from __future__ import annotations

import queue
import shutil
import tempfile
import threading
import weakref
from collections.abc import Iterator, Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fusioncut.engines.base import EngineKind, EngineOptions
from fusioncut.errors import FusionCutError, InputError
from fusioncut.extras import require
from fusioncut.io.job import (Job, StockSpec, job_options, load_job, make_options, program_job, stock_entry,
                              with_inputs)
from fusioncut.io.readers import is_job_file
from fusioncut.model import BoxStock, CylinderStock, EngagementMap, MillingTool, SolidStock, Stock, Toolpath

if TYPE_CHECKING:
    from fusioncut.io.results import Results
    from fusioncut.runner import PreparedJob, RunResult

__all__ = ["JOB_FILE", "Run", "simulate"]

JOB_FILE = "job.json"  # the job a program was run as, in its results folder: `fusioncut run OUT/job.json` repeats it
_QUEUE_SIZE = 64  # maps computed ahead of an iteration that has not taken them yet


def simulate(job_or_program: Job | Toolpath | str | Path, *,
             stock: str | Stock | StockSpec | Mapping[str, Any] | None = None,
             tools: str | Path | Mapping[int, MillingTool] | None = None,
             options: EngineOptions | Mapping[str, Any] | None = None, out: str | Path | None = None,
             workers: int = 1) -> Run:
    """Read and check a job or a toolpath; the :class:`Run` computes its CLs.

    ``stock``: a :class:`~fusioncut.model.Stock`, ``"box:x0,y0,z0,x1,y1,z1"`` (mm),
    ``"cylinder:cx,cy,cz,radius,height"``, a STEP/BREP path, a ``.camotics`` project (its workpiece),
    ``"infer"`` (:func:`fusioncut.io.stock.infer_stock`) or a job's stock entry such as
    ``{"kind": "infer", "top": 1.0}`` (:class:`~fusioncut.io.job.StockSpec`); ``None``: the job's stock, else a
    CAMotics project's workpiece, else inferred. ``tools``: a tool library file or
    ``{number: MillingTool}``, added to the job's (the program's own tools fill the gaps).
    ``options``: :class:`EngineOptions` or a dict of job options (engine and run options,
    :class:`fusioncut.io.job.Options`); a dict is merged into the job's options, an
    :class:`EngineOptions` replaces them (with its kernel fields, which a job does not state).

    ``out``: the results folder, written as the CLs come (``cl``/``slices``/``summary`` tables,
    ``metadata.json``, a checkpoint, ``ipw.step`` and ``ipw.stl`` at the end, and ``job.json`` when a
    program file was given: the job it was run as). ``None``: a temporary folder that the run
    deletes when it is garbage-collected (no IPW files written). The run starts over in ``out``: a
    checkpoint there is not resumed (``fusioncut run`` resumes).
    ``workers`` > 1: the CLs run on an embedded Dask cluster of that many processes (the
    ``[parallel]`` extra); 1 keeps a job file's own ``workers`` option.
    """
    from fusioncut.runner import prepare_job

    if workers < 1:
        raise InputError(f"workers must be at least 1, got {workers}")
    engine_options = options if isinstance(options, EngineOptions) else None
    write_job = False
    if isinstance(job_or_program, Toolpath):
        prepared = _prepare_toolpath(job_or_program, stock, tools, options)
    else:
        if isinstance(job_or_program, Job):
            job, base = job_or_program, Path.cwd()
        elif is_job_file(job_or_program):
            job, base = load_job(job_or_program)
        else:
            job, base, write_job = program_job(job_or_program), Path.cwd(), True
        job = with_inputs(job, stock=stock, tools=tools, options=options)
        prepared = prepare_job(job, base)
    if engine_options is not None:
        prepared = replace(prepared, options=engine_options)
    if workers > 1:
        prepared = replace(prepared, workers=workers)
    if prepared.workers > 1 or prepared.scheduler:
        require("parallel", "running on Dask workers")
    return Run(prepared, out, job if write_job else None)


def _prepare_toolpath(toolpath: Toolpath, stock: str | Stock | StockSpec | Mapping[str, Any] | None,
                      tools: str | Path | Mapping[int, MillingTool] | None,
                      options: EngineOptions | Mapping[str, Any] | None) -> PreparedJob:
    """A toolpath in memory made ready like a job: tools resolved per T number, stock read or inferred."""
    from fusioncut.io import tool_sources
    from fusioncut.io.job import RUN_OPTIONS, build_stock
    from fusioncut.io.readers import read_tool_library
    from fusioncut.io.stock import infer_stock
    from fusioncut.runner import PreparedJob

    if not toolpath.moves:
        raise InputError("the toolpath has no moves", toolpath.source)
    library = read_tool_library(tools) if isinstance(tools, (str, Path)) else None
    given = dict(tools) if isinstance(tools, Mapping) else {}
    resolved, default_tool, _ = tool_sources.resolve_tools(toolpath.moves, given, library, dict(toolpath.tools),
                                                           "library")
    toolpath = replace(toolpath, tools=resolved)
    if not isinstance(stock, (BoxStock, CylinderStock, SolidStock)):
        spec = stock_entry(stock)
        stock = build_stock(spec, Path.cwd()) or infer_stock(toolpath, margin=spec.margin, top=spec.top)
    run = make_options(job_options(options))
    engine = options if isinstance(options, EngineOptions) else EngineOptions(**run.model_dump(exclude=set(RUN_OPTIONS)))
    return PreparedJob(toolpath=toolpath, stock=stock, options=engine, default_tool=default_tool, job_id="",
                       checkpoint_every=run.checkpoint_every, snapshot_cls=tuple(run.snapshot_cls),
                       workers=run.workers, scheduler=run.scheduler)


class Run:
    """A run of :func:`simulate`: iterate it for the :class:`~fusioncut.model.EngagementMap` of each CL,
    in order, as the engine computes them (on a thread of this process; at most a few dozen maps
    ahead of the iteration).

    A run is computed once: iterating it again, or after :meth:`wait`, raises :class:`RunConsumed`
    (the maps are in :meth:`results`). Leaving the iteration early (``break``, an exception, Ctrl-C)
    stops the engine after the CL in progress with a checkpoint, from which :meth:`wait`,
    :meth:`results` and :meth:`ipw` continue the run to its end.

    ``out``: the results folder (a temporary one when :func:`simulate` was given none);
    ``result``: the :class:`~fusioncut.runner.RunResult` (volumes, per-operation counts) once the run
    has ended, else ``None``.
    """

    def __init__(self, prepared: PreparedJob, out: str | Path | None, job: Job | None = None) -> None:
        self._prepared = prepared
        self._export = out is not None
        if out is None:
            self.out = Path(tempfile.mkdtemp(prefix="fusioncut-run-"))
            self._cleanup = weakref.finalize(self, shutil.rmtree, self.out, ignore_errors=True)
        else:
            self.out = Path(out)
            self.out.mkdir(parents=True, exist_ok=True)
        if job is not None:
            (self.out / JOB_FILE).write_text(job.model_dump_json(indent=2), encoding="utf-8")
        self.result: RunResult | None = None
        self._iterated = False

    @property
    def options(self) -> EngineOptions:
        """The engine options the run uses."""
        return self._prepared.options

    @property
    def toolpath(self) -> Toolpath:
        """The toolpath as read, with the tools resolved per T number."""
        return self._prepared.toolpath

    @property
    def stock(self) -> Stock:
        """The stock, as given or inferred."""
        return self._prepared.stock

    def __iter__(self) -> Iterator[EngagementMap]:
        if self._iterated or self.result is not None:
            raise RunConsumed("this run was computed already: its CLs are in run.results()")
        self._iterated = True
        return self._iterate()

    def _iterate(self) -> Iterator[EngagementMap]:
        maps: queue.Queue[Any] = queue.Queue(_QUEUE_SIZE)
        stop = threading.Event()
        done = object()

        def on_cl(m: EngagementMap, total: int) -> None:
            while not stop.is_set():
                try:
                    maps.put(m, timeout=0.1)
                    return
                except queue.Full:
                    continue
            raise KeyboardInterrupt  # the runner stops after this CL, with a checkpoint

        outcome: list[Any] = []

        def work() -> None:
            try:
                outcome.append(self._compute(on_cl, resume=False))
            except BaseException as exc:  # noqa: BLE001 - handed to the iterating thread
                outcome.append(exc)
            finally:
                while True:  # the iteration may have left: never block on a full queue here
                    try:
                        maps.put(done, timeout=0.1)
                        return
                    except queue.Full:
                        if stop.is_set():
                            return

        worker = threading.Thread(target=work, name="fusioncut-run", daemon=True)
        worker.start()
        try:
            while True:
                item = maps.get()
                if item is done:
                    break
                yield item
        finally:
            stop.set()
            worker.join()
        result = outcome[0]
        if isinstance(result, BaseException):
            raise result
        self.result = result if not result.interrupted else None

    def wait(self) -> RunResult:
        """Compute every CL not computed yet (in this thread; Ctrl-C stops after the CL in progress)
        and return the :class:`~fusioncut.runner.RunResult`."""
        if self.result is None:
            resumed = self._iterated  # an iteration left early: continue from its checkpoint
            self._iterated = True
            self.result = self._compute(None, resume=resumed)
        return self.result

    def _compute(self, on_cl: Any, resume: bool) -> RunResult:
        from fusioncut.runner import run_toolpath

        p = self._prepared
        options = replace(p.options, failure_dir=self.out / "failures")
        return run_toolpath(p.toolpath, p.stock, self.out, options, default_tool=p.default_tool, job_id=p.job_id,
                            on_cl=on_cl, resume=resume, checkpoint_every=p.checkpoint_every,
                            snapshot_cls=p.snapshot_cls, export_ipw=self._export, workers=p.workers,
                            scheduler=p.scheduler)

    def results(self) -> Results:
        """The results tables (:func:`fusioncut.io.results.load_results` of :attr:`out`), once every
        CL is computed: ``cl`` (one row per CL), ``slices`` (one per engaged arc), ``summary``."""
        from fusioncut.io.results import load_results

        self.wait()
        return load_results(self.out)

    def ipw(self) -> Any:
        """The final in-process workpiece, once every CL is computed: an OCP ``TopoDS_Shape`` (a
        solid, or a compound of the workpiece cells' solids), read back exactly from the run's last
        checkpoint. Needs OpenCASCADE (OCP), as the engine does."""
        from fusioncut.engines.brep.engine import BRepEngine
        from fusioncut.runner import CHECKPOINT_DIR

        result = self.wait()
        if (self.results().options or {}).get("engine") == EngineKind.ANALYTIC.value:
            raise FusionCutError(f"{self.out}: the analytic engine ran this job and keeps no B-Rep workpiece; ask "
                                 "for engine='brep' to have one")
        engine = BRepEngine(self.options)
        if result.interrupted or engine.load_checkpoint(self.out / CHECKPOINT_DIR) is None:
            raise FusionCutError(f"{self.out}: the run left no final workpiece (see its log)")
        return engine.ipw


class RunConsumed(FusionCutError):
    """A :class:`Run` iterated a second time: its CLs are computed once."""
