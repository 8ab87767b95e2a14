"""``fusioncut demo``, ``fusioncut run JOB.json | PROGRAM`` and ``fusioncut schema``.

``run`` takes a job file or a toolpath file (G-code, APT/CLSF, Fusion JSON, CAMotics project); a
toolpath file runs as the job :func:`fusioncut.io.job.program_job` makes of it (``--stock``,
``--stock-top``, ``--tools``), written as ``job.json`` into the results folder so that
``fusioncut run OUT/job.json`` repeats it. One flag per job engine option (``--slice-height``,
``--sweep``, ...) is generated from :class:`~fusioncut.engines.base.EngineOptions` and overrides the
job's value.

Both runs show one progress bar per operation (CLs done, CL/s, time left) and one for the whole
program, write a log (``--log-file``, default ``<out>/fusioncut.log``; ``--log-level debug`` records
every CL with its source ``file:line``, status, sweep method and timings) and, unless
``--no-ipw-export``, the final workpiece as ``ipw.step`` and ``ipw.stl`` in the results folder.
``run`` resumes from the checkpoint of an interrupted run of the same job unless ``--fresh``;
``--workers N`` / ``--scheduler ADDRESS`` run it on Dask workers (same results, see
:mod:`fusioncut.engines.brep.parallel`), and its checkpoint resumes with or without them.
"""
from __future__ import annotations

import inspect
import json
import logging
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from enum import Enum
from pathlib import Path
from typing import Literal, Optional, get_args, get_origin

import typer
from rich import box
from rich.console import Console
from rich.logging import RichHandler
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn
from rich.table import Table

from fusioncut.cli._errors import friendly_errors
from fusioncut.demo import DEMO_OPTIONS
from fusioncut.engines.sizing import Budget
from fusioncut.extras import require
from fusioncut.io.job import OptionField, engine_option_fields
from fusioncut.model import EngagementMap

console = Console()

EXIT_INTERRUPTED = 130  # the shell's code for "stopped by Ctrl-C": the results are incomplete


class LogLevel(str, Enum):
    debug = "debug"
    info = "info"
    warning = "warning"
    error = "error"


@contextmanager
def _logging(log_file: Path, level: LogLevel, append: bool) -> Iterator[None]:
    """Log FusionCut's records at ``level`` into ``log_file`` and warnings to the terminal, for the
    duration of one command (handlers are removed again, so repeated runs in one process, as in the
    tests, do not pile them up)."""
    log_file.parent.mkdir(parents=True, exist_ok=True)
    lvl = getattr(logging, level.value.upper())
    file_handler = logging.FileHandler(log_file, mode="a" if append else "w", encoding="utf-8")
    file_handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    file_handler.setLevel(lvl)
    term_handler = RichHandler(console=Console(stderr=True), level=logging.WARNING, show_path=False)
    pkg = logging.getLogger("fusioncut")
    old_level = pkg.level
    # the terminal shows warnings whatever the file's level is
    pkg.setLevel(min(lvl, logging.WARNING))
    root = logging.getLogger()
    root.addHandler(file_handler)
    root.addHandler(term_handler)
    try:
        yield
    finally:
        root.removeHandler(file_handler)
        root.removeHandler(term_handler)
        file_handler.close()
        pkg.setLevel(old_level)


def _clock(seconds: float | None) -> str:
    if seconds is None or seconds != seconds or seconds == float("inf"):
        return "-:--:--"
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


class _ProgressReporter:
    """One bar per operation plus one for the program. CL/s counts the CLs computed by this run
    since the bar's first CL began; the time left is the CLs still to do at that rate."""

    def __init__(self, bar: Progress) -> None:
        self.bar = bar
        self.tasks: dict[str, int] = {}
        self.overall: int | None = None
        self.started: dict[int, tuple[float, int]] = {}  # task -> (start time, CLs computed since)
        self.last = time.monotonic()

    def on_start(self, plan) -> None:  # plan: fusioncut.runner.RunPlan
        self.overall = self.bar.add_task("all operations", total=plan.total, completed=plan.start_at,
                                         rate="", eta="")
        for op, n in plan.expected.items():
            self.tasks[op] = self.bar.add_task(f"  {escape(op) or '(no operation)'}", total=n,
                                               completed=plan.done.get(op, 0), rate="", eta="")
        self.last = time.monotonic()

    def on_cl(self, m: EngagementMap, total: int) -> None:
        now = time.monotonic()
        for task in (self.tasks.get(m.operation), self.overall):
            if task is None:
                continue
            # a bar's clock starts when its first CL started, i.e. when the previous CL ended
            start, n = self.started.get(task, (self.last, 0))
            n += 1
            self.started[task] = (start, n)
            t = self.bar.tasks[self._index(task)]
            rate = n / max(now - start, 1e-9)
            left = max((t.total or 0) - t.completed - 1, 0)
            self.bar.update(task, advance=1, rate=f"{rate:.1f} CL/s", eta=_clock(left / rate))
        self.last = now

    def _index(self, task_id: int) -> int:
        return next(i for i, t in enumerate(self.bar.tasks) if t.id == task_id)


def _run_with_progress(start: Callable[..., object]):
    """Call ``start(on_cl=..., on_start=...)`` with a live progress display."""
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TextColumn("{task.fields[rate]}"), TextColumn("{task.fields[eta]}"), console=console,
                  transient=True) as bar:
        reporter = _ProgressReporter(bar)
        return start(on_cl=reporter.on_cl, on_start=reporter.on_start)


def _print_summary(result) -> None:
    # fits 80 columns: two-line headers, one space between columns, only the operation's name wraps
    table = Table(title=f"FusionCut results in {escape(str(result.out_dir))}", box=box.SIMPLE_HEAD,
                  show_edge=False, pad_edge=False, collapse_padding=True)
    for col in ("operation", "CLs", "engaged", "air", "rapid", "failed", "removed\nmm³", "max ae\nmm",
                "max ap\nmm", "median\nms/CL"):
        named = col == "operation"
        table.add_column(col, justify="left" if named else "right", no_wrap=not named, min_width=11 if named else None,
                         ratio=1 if named else None)
    for op in result.operations.values():
        table.add_row(escape(op.operation) or "-", str(op.cls), str(op.engaged), str(op.air), str(op.rapid),
                      f"[red]{op.failed}[/]" if op.failed else "0",
                      f"{op.removed:.0f}" if op.removed >= 1000 else f"{op.removed:.1f}", f"{op.max_ae:.4g}",
                      f"{op.max_ap:.4g}", f"{op.median_ms:.1f}")
    console.print(table)
    console.print(f"stock {result.stock_volume:.1f} mm³ − final {result.final_volume:.1f} mm³ = "
                  f"Σ removed {result.removed_volume:.1f} mm³ (relative error {result.conservation_error:.1e}); "
                  f"{result.seconds:.1f} s")
    if result.resumed_from:
        console.print(f"resumed from the checkpoint at CL {result.resumed_from}")
    if result.exported:
        console.print("workpiece written to " + escape(", ".join(p.name for p in result.exported)), highlight=False)
    if result.interrupted:
        console.print("[yellow]interrupted: the results of every finished CL and a checkpoint were kept; "
                      "run the same command again to resume[/]")
        raise typer.Exit(EXIT_INTERRUPTED)


LOG_FILE_HELP = "log file (default: <out>/fusioncut.log)"
LOG_LEVEL_HELP = "log file level; debug records every CL (source file:line, status, sweep method, timings)"
IPW_HELP = "write the final workpiece as ipw.step and ipw.stl into the results folder"
WORKERS_HELP = ("run on an embedded Dask cluster of N worker processes, each owning a share of the workpiece's "
                "cells (20 mm cells if the job sets cell_size to null); overrides the job's options.workers")
MAX_CLS_HELP = ("refuse a job that makes more CL segments than this (counted from its moves before anything "
                "is expanded)")
MAX_SLICES_HELP = "refuse a job that evaluates more slices (per CL: flute length / slice_height) than this"
SOURCE_HELP = ("job JSON (see `fusioncut schema`), or a toolpath file: G-code (.nc .ngc .tap ...), APT/CLSF "
               "(.apt .cls), Fusion JSON post (.json), CAMotics project (.camotics)")
TOOLS_HELP = "tool library (.json, .tools, .tbl) in place of the job's; a program's own tools fill the gaps"
STOCK_HELP = ("stock in place of the job's: box:x0,y0,z0,x1,y1,z1 or cylinder:cx,cy,cz,radius,height (mm), a "
              ".step/.stp/.brep file, a .camotics project's workpiece, or infer (the default for a program)")
STOCK_TOP_HELP = ("the top of the inferred stock (mm, machine z): give it when the program does not show it "
                  "(a program cutting at one level only gets 1 mm of stock above that level)")
SCHEDULER_HELP = ("run on every worker of a running Dask scheduler (e.g. tcp://host:8786); wins over "
                  "--workers; overrides the job's options.scheduler")


def _flag_value(option: OptionField, value: object) -> object:
    """A generated option flag's value as the job's validation takes it (``none``/``null``: ``None``,
    for an option that takes it)."""
    if option.takes_none and isinstance(value, str) and value.strip().lower() in ("none", "null"):
        return None
    return value


def _with_engine_flags(command: Callable[..., None]) -> None:
    """Give ``command`` (whose ``**engine_options`` takes them) one flag per job engine option,
    generated from :class:`~fusioncut.engines.base.EngineOptions` (help and default from its fields):
    ``--slice-height 0.5``, ``--sweep sampled``, ``--cell-size none``. A flag not given keeps the
    job's value; the job's validation refuses a bad one naming the flag."""
    signature = inspect.signature(command)
    params = [p for p in signature.parameters.values() if p.kind is not inspect.Parameter.VAR_KEYWORD]
    annotations = {p.name: p.annotation for p in params}
    for f in engine_option_fields():
        flag = "--" + f.name.replace("_", "-")
        choices = get_args(f.type) if get_origin(f.type) is Literal else ()
        if f.type is bool:
            option, annotation = typer.Option(None, f"{flag}/--no-{flag[2:]}", help=f.description), Optional[bool]
        else:
            metavar = "|".join(choices) if choices else ("NUMBER|none" if f.takes_none else "NUMBER")
            option, annotation = typer.Option(None, flag, metavar=metavar, help=f.description), Optional[str]
        params.append(inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=option,
                                        annotation=annotation))
        annotations[f.name] = annotation
    command.__signature__ = signature.replace(parameters=params)  # type: ignore[attr-defined]
    command.__annotations__ = {**annotations, "return": None}


def register(app: typer.Typer) -> None:
    @app.command()
    @friendly_errors
    def demo(out: Path = typer.Option(Path("fusioncut-out/demo"), help="results folder"),
             slice_height: Optional[float] = typer.Option(None, help="axial slice spacing, mm (default: the demo's, "
                                                                      f"{DEMO_OPTIONS['slice_height']:g})"),
             sweep: Optional[str] = typer.Option(None, help="exact (the default), or sampled (tool copies, the "
                                                            "published method)"),
             log_file: Optional[Path] = typer.Option(None, help=LOG_FILE_HELP),
             log_level: LogLevel = typer.Option(LogLevel.info, case_sensitive=False, help=LOG_LEVEL_HELP),
             ipw_export: bool = typer.Option(True, "--ipw-export/--no-ipw-export", help=IPW_HELP)) -> None:
        """Mill the built-in demo block (face, slot, trochoidal, contour, ball finish) and summarise.

        The demo is the service's demo job (:func:`fusioncut.demo.demo_job`): its G-code is written
        into the results folder as ``demo.ngc`` and run as a job, so both make the same CLs."""
        from fusioncut.demo import DEMO_FILE, demo_gcode, demo_job
        from fusioncut.io.job import Job, with_options
        from fusioncut.runner import run_job

        job = with_options(Job.model_validate(demo_job()), {"slice_height": slice_height, "sweep": sweep}, flags=True)
        out.mkdir(parents=True, exist_ok=True)
        (out / DEMO_FILE).write_text(demo_gcode(), encoding="utf-8")
        with _logging(log_file or out / "fusioncut.log", log_level, append=False):
            result = _run_with_progress(lambda **cb: run_job(job, out, out, resume=False, export_ipw=ipw_export,
                                                             **cb))
        _print_summary(result)

    def run(source: Path = typer.Argument(..., metavar="JOB_OR_PROGRAM", help=SOURCE_HELP),
            out: Path = typer.Option(None, help="results folder (default: fusioncut-out/<job name>)"),
            fresh: bool = typer.Option(False, "--fresh",
                                       help="start over, ignoring a checkpoint of an interrupted run"),
            tools: Optional[Path] = typer.Option(None, "--tools", metavar="LIBRARY", help=TOOLS_HELP),
            stock: Optional[str] = typer.Option(None, "--stock", metavar="SPEC", help=STOCK_HELP),
            stock_top: Optional[float] = typer.Option(None, "--stock-top", metavar="Z", help=STOCK_TOP_HELP),
            log_file: Optional[Path] = typer.Option(None, help=LOG_FILE_HELP),
            log_level: LogLevel = typer.Option(LogLevel.info, case_sensitive=False, help=LOG_LEVEL_HELP),
            ipw_export: bool = typer.Option(True, "--ipw-export/--no-ipw-export", help=IPW_HELP),
            # a string: the job's validation refuses a bad count in one line, as in a job file
            workers: Optional[str] = typer.Option(None, "--workers", metavar="N", help=WORKERS_HELP),
            scheduler: Optional[str] = typer.Option(None, "--scheduler", metavar="ADDRESS",
                                                    help=SCHEDULER_HELP),
            max_cls: int = typer.Option(Budget.max_cls, "--max-cls", min=1, metavar="N", help=MAX_CLS_HELP),
            max_slices: int = typer.Option(Budget.max_slices, "--max-slices", min=1, metavar="N",
                                           help=MAX_SLICES_HELP),
            **engine_options: Optional[str]) -> None:
        """Run a job file, or a toolpath file without one; an interrupted run of the same job
        continues from its checkpoint.

        A toolpath file (G-code, APT/CLSF, Fusion JSON, CAMotics project) is run as a job of its own
        (stock inferred unless --stock, the program's tools unless --tools), written as job.json into
        the results folder: `fusioncut run OUT/job.json` runs it again."""
        from fusioncut.api import JOB_FILE
        from fusioncut.io.job import (
            load_job,
            program_job,
            with_inputs,
            with_run_options,
        )
        from fusioncut.io.readers import is_job_file
        from fusioncut.runner import run_job

        if stock_top is not None:
            if stock not in (None, "infer"):
                raise typer.BadParameter("--stock-top states the top of an inferred stock, not of --stock " + stock)
            stock = {"kind": "infer", "top": stock_top}  # type: ignore[assignment]
        fields = {f.name: f for f in engine_option_fields()}
        given = {name: _flag_value(fields[name], value) for name, value in engine_options.items() if value is not None}
        if is_job_file(source):
            job, base = load_job(source)
            job = with_inputs(job, stock=stock, tools=tools, options=given, flags=True)
            write_job = False
        else:
            job = with_inputs(program_job(source, stock=stock, tools=tools), options=given, flags=True)
            base, write_job = Path.cwd(), True
        # run options: they change neither the job hash nor the results, so a resume still matches
        job = with_run_options(job, workers=workers, scheduler=scheduler)
        if job.options.workers > 1 or job.options.scheduler:
            require("parallel", "running on Dask workers (--workers, --scheduler or the job's options)")
        out = out or Path("fusioncut-out") / job.name
        if write_job:
            out.mkdir(parents=True, exist_ok=True)
            (out / JOB_FILE).write_text(job.model_dump_json(indent=2), encoding="utf-8")
        # a resumed run appends to the log of the run it continues
        with _logging(log_file or out / "fusioncut.log", log_level, append=not fresh):
            budget = Budget(max_cls=max_cls, max_slices=max_slices)
            result = _run_with_progress(lambda **cb: run_job(job, base, out, resume=not fresh,
                                                             export_ipw=ipw_export, budget=budget, **cb))
        _print_summary(result)

    _with_engine_flags(run)
    app.command()(friendly_errors(run))

    @app.command()
    def schema() -> None:
        """Print the JSON Schema of job files."""
        from fusioncut.io.job import Job

        console.print_json(json.dumps(Job.model_json_schema()))
