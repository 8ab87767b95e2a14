"""``fusioncut view`` (3D scene of one CL as GLB + HTML) and ``fusioncut export-ipw`` (the workpiece after a CL)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.markup import escape

from fusioncut.cli._errors import friendly_errors
from fusioncut.extras import require

console = Console()

def load_inputs(source: str, slice_height: float | None = None):
    """``(toolpath, stock, options, default_tool, name)`` of a job file, of a toolpath file (run as
    ``fusioncut run PROGRAM`` runs it: its own tools, stock inferred), or of the demo for ``"demo"``
    (the job ``fusioncut demo`` and the service run, so CL numbers match their results)."""
    if source == "demo":
        import tempfile

        from fusioncut.demo import DEMO_FILE, demo_gcode, demo_job
        from fusioncut.io.job import Job
        from fusioncut.runner import prepare_job

        with tempfile.TemporaryDirectory() as folder:
            (Path(folder) / DEMO_FILE).write_text(demo_gcode(), encoding="utf-8")
            job = Job.model_validate(demo_job(**({"slice_height": slice_height} if slice_height else {})))
            p = prepare_job(job, Path(folder))
        return p.toolpath, p.stock, p.options, p.default_tool, "demo"
    from fusioncut.io.job import load_job, program_job
    from fusioncut.io.readers import is_job_file
    from fusioncut.runner import prepare_job

    program = Path(source).is_file() and not is_job_file(source)
    job, base = (program_job(source), Path.cwd()) if program else load_job(source)
    p = prepare_job(job, base)
    options = replace(p.options, slice_height=slice_height) if slice_height else p.options
    return p.toolpath, p.stock, options, p.default_tool, job.name


def _load(source: str, cl: int, slice_height: float | None):
    """The inputs, checked (CL index included) before anything long runs."""
    from fusioncut.engines.brep.export import check_cl_index

    inputs = load_inputs(source, slice_height)
    check_cl_index(inputs[0], cl, inputs[2])
    return inputs


def _replay(inputs, cl: int):
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from fusioncut.engines.brep.export import replay

    toolpath, stock, options, default_tool, name = inputs
    with Progress(TextColumn("[bold]replaying {task.fields[name]} to CL"), BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=console, transient=True) as bar:
        task = bar.add_task("replay", total=cl + 1, name=name)
        state = replay(toolpath, stock, cl, options, default_tool,
                       on_cl=lambda m, total: bar.update(task, completed=m.cl_index + 1, total=total))
    return state, options


def _size(path: Path) -> str:
    n = path.stat().st_size
    return f"{n / 1e6:.1f} MB" if n >= 1e5 else f"{n / 1e3:.0f} kB"


def register(app: typer.Typer) -> None:
    @app.command("view")
    @friendly_errors
    def view(
        source: str = typer.Argument(..., help="Job JSON file, toolpath file, or 'demo' for the built-in demo."),
        cl: int = typer.Option(..., "--cl", min=0, help="CL index to show (as in the run's results)."),
        out: Path = typer.Option(..., "--out", "-o", help="HTML page to write (self-contained, opens from disk)."),
        glb: Optional[Path] = typer.Option(None, "--glb", help="Also write the scene as glTF binary (.glb)."),
        deflection: float = typer.Option(0.0, "--deflection", min=0.0,
                                         help="Mesh deflection in mm (0: from the tool size)."),
        slice_height: Optional[float] = typer.Option(
            None, "--slice-height", min=1e-4, help="Axial slice spacing in mm (default: the job's, 1 for demo)."),
        title: Optional[str] = typer.Option(None, "--title", help="Page title."),
    ) -> None:
        """3D view of one CL: workpiece, tool, contact faces, entry/exit lines (HTML page, optional GLB)."""
        require("viz", "fusioncut view")
        from fusioncut.engines.brep.export import cl_scene
        from fusioncut.viz.scene import scene_glb, three_dir, write_view_html

        if out.suffix.lower() not in (".html", ".htm"):
            raise ValueError(f"{out}: the page is written as .html")
        if glb is not None and glb.suffix.lower() != ".glb":
            raise ValueError(f"{glb}: the scene is written as .glb")
        for p in (out, glb):
            if p is not None and not p.parent.is_dir():
                raise ValueError(f"{p.parent}: the output folder does not exist")
        inputs = _load(source, cl, slice_height)
        three_dir()  # fail before a long replay when the page could not be written anyway
        state, options = _replay(inputs, cl)
        scene = cl_scene(state.engine.ipw, state.tool, state.map, slice_height=options.slice_height,
                         deflection=deflection or None)
        data = scene_glb(scene)
        if glb is not None:
            glb.write_bytes(data)
            console.print(f"wrote {escape(str(glb))} ({_size(glb)})", highlight=False)
        write_view_html(data, out, title)
        m = state.map
        console.print(f"wrote {escape(str(out))} ({_size(out)}): CL {cl} of {state.cl_count}, {m.status.value}, "
                      f"{len(m.engaged_slices)} engaged slices", highlight=False)

    @app.command("export-ipw")
    @friendly_errors
    def export_ipw(
        source: str = typer.Argument(..., help="Job JSON file, toolpath file, or 'demo' for the built-in demo."),
        cl: int = typer.Option(..., "--cl", min=0, help="The workpiece after this CL index."),
        out: Path = typer.Option(..., "--out", "-o", help="Output file: .step/.stp (exact), .stl (meshed), .brep."),
        deflection: float = typer.Option(0.01, "--deflection", min=1e-5, help="STL facet deflection, mm."),
        engine: str = typer.Option("brep", "--engine", help="brep: replay the B-Rep engine to the CL (STEP, STL, "
                                   "BREP); analytic: the mesh of the exact height map after the CL (STL only, "
                                   "no replay: seconds for any program; box stocks, tools of revolution)."),
        grid: Optional[float] = typer.Option(None, "--grid", min=1e-3, help="With --engine analytic: the height "
                                             "map's grid step, mm (default: an eighth of the smallest tool radius)."),
    ) -> None:
        """Write the in-process workpiece after CL N as STEP, STL or BREP."""
        from fusioncut.engines.brep.export import IPW_SUFFIXES, export_ipw as write_ipw

        if engine not in ("brep", "analytic"):
            raise ValueError(f"--engine {engine!r}: use brep or analytic")
        if out.suffix.lower() not in (IPW_SUFFIXES if engine == "brep" else {".stl": "STL"}):
            raise ValueError(f"{out}: unsupported workpiece format {out.suffix!r} (use .step, .stp, .stl or .brep; "
                             "with --engine analytic, .stl)")
        if not out.parent.is_dir():
            raise ValueError(f"{out.parent}: the output folder does not exist")
        if engine == "analytic":
            _export_height_map(_load(source, cl, None), cl, out, grid)
            return
        from fusioncut.runner import export_budget_s

        state, options = _replay(_load(source, cl, None), cl)
        kind = write_ipw(state.engine.ipw, out, deflection, budget_s=export_budget_s(options))  # as a run's export
        extra = f", deflection {deflection} mm" if kind == "STL" else ""
        console.print(f"wrote {escape(str(out))} ({kind}{extra}, {_size(out)}): the workpiece after CL {cl} of {state.cl_count}, "
                      f"{state.engine.ipw_volume:.3f} mm³", highlight=False)


def _export_height_map(inputs, cl: int, out: Path, grid: float | None) -> None:
    """The analytic engine's workpiece after CL ``cl`` as an STL (:meth:`AnalyticEngine.ipw_mesh`):
    the CLs up to it are only indexed (their sweeps), nothing is cut, so it takes seconds."""
    from fusioncut.engines.analytic.engine import AnalyticEngine
    from fusioncut.io.mesh import mesh_volume, write_stl

    toolpath, stock, options, default_tool, _ = inputs
    engine = AnalyticEngine(options)
    engine.check_tools(toolpath, default_tool)
    engine.start(stock)
    total = 0
    for c in engine.cl_sequence(toolpath, default_tool):
        if c.index <= cl:
            engine.index_only(c)
        total = c.index + 1
    triangles = engine.ipw_mesh(grid)
    write_stl(out, triangles, f"FusionCut IPW after CL {cl}, analytic height map")
    console.print(f"wrote {escape(str(out))} (STL of the analytic engine's height map, {len(triangles):,} triangles, "
                  f"{_size(out)}): the workpiece after CL {cl} of {total}, the mesh enclosing "
                  f"{mesh_volume(triangles):.3f} mm³", highlight=False)
