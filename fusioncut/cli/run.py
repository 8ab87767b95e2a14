"""``fusioncut demo``, ``fusioncut run JOB.json`` and ``fusioncut schema``."""
from __future__ import annotations

import json
import logging
from pathlib import Path

import typer
from rich.console import Console
from rich.logging import RichHandler
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from fusioncut.cli._errors import friendly_errors
from fusioncut.engines.base import EngineOptions
from fusioncut.model import EngagementMap

console = Console()


def _setup_logging(out_dir: Path, level: str) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    file_handler = logging.FileHandler(out_dir / "fusioncut.log", mode="w")
    file_handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    logging.basicConfig(level=getattr(logging, level.upper(), logging.INFO), force=True,
                        handlers=[file_handler, RichHandler(console=Console(stderr=True), level=logging.WARNING,
                                                            show_path=False)])


def _progress():
    return Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TextColumn("{task.fields[rate]:.0f} CL/s"), TimeRemainingColumn(), console=console,
                    transient=True)


def _run_with_progress(start):
    with _progress() as bar:
        task = bar.add_task("CWE", total=None, rate=0.0)
        state = {"op": None}

        def on_cl(m: EngagementMap, total: int) -> None:
            if m.operation != state["op"]:
                state["op"] = m.operation
                bar.update(task, description=m.operation or "CWE")
            done = bar.tasks[0].completed + 1
            elapsed = bar.tasks[0].elapsed or 1e-9
            bar.update(task, total=total, completed=done, rate=done / elapsed)

        return start(on_cl)


def _print_summary(result) -> None:
    table = Table(title=f"FusionCut results in {result.out_dir}")
    for col in ("operation", "CLs", "engaged", "air", "rapid", "failed", "removed mm³", "max ae mm",
                "max ap mm", "median ms/CL"):
        table.add_column(col, justify="left" if col == "operation" else "right")
    for op in result.operations.values():
        table.add_row(op.operation or "-", str(op.cls), str(op.engaged), str(op.air), str(op.rapid),
                      f"[red]{op.failed}[/]" if op.failed else "0", f"{op.removed:.1f}", f"{op.max_ae:.3f}",
                      f"{op.max_ap:.3f}", f"{op.median_ms:.1f}")
    console.print(table)
    console.print(f"stock {result.stock_volume:.1f} mm³ − final {result.final_volume:.1f} mm³ = "
                  f"Σ removed {result.removed_volume:.1f} mm³ (relative error {result.conservation_error:.1e}); "
                  f"{result.seconds:.1f} s")
    if result.interrupted:
        console.print("[yellow]interrupted: the results of every finished CL were kept[/]")


def register(app: typer.Typer) -> None:
    @app.command()
    @friendly_errors
    def demo(out: Path = typer.Option(Path("fusioncut-out/demo"), help="results folder"),
             slice_height: float = typer.Option(1.0, help="axial slice spacing, mm"),
             sweep: str = typer.Option("exact", help="exact, or sampled (tool copies, the published method)"),
             log_level: str = typer.Option("info", help="log file level")) -> None:
        """Mill the built-in demo block (face, slot, trochoidal, contour, ball finish) and summarise."""
        from fusioncut.demo import demo_stock, demo_toolpath
        from fusioncut.runner import run_toolpath

        _setup_logging(out, log_level)
        if sweep not in ("exact", "sampled"):
            raise typer.BadParameter("--sweep is exact or sampled")
        opts = EngineOptions(slice_height=slice_height, max_segment_length=2.0, sweep=sweep,  # type: ignore[arg-type]
                             failure_dir=out / "failures")
        result = _run_with_progress(lambda cb: run_toolpath(demo_toolpath(), demo_stock(), out, opts, on_cl=cb))
        _print_summary(result)

    @app.command()
    @friendly_errors
    def run(job_file: Path = typer.Argument(..., help="job JSON (see `fusioncut schema`)"),
            out: Path = typer.Option(None, help="results folder (default: fusioncut-out/<job name>)"),
            log_level: str = typer.Option("info", help="log file level")) -> None:
        """Run a job file."""
        from fusioncut.io.job import load_job
        from fusioncut.runner import run_job

        job, base = load_job(job_file)
        out = out or Path("fusioncut-out") / job.name
        _setup_logging(out, log_level)
        result = _run_with_progress(lambda cb: run_job(job, base, out, on_cl=cb))
        _print_summary(result)

    @app.command()
    def schema() -> None:
        """Print the JSON Schema of job files."""
        from fusioncut.io.job import Job

        console.print_json(json.dumps(Job.model_json_schema()))
