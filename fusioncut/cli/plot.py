"""``fusioncut plot``: draw a plot from a results directory written by a run."""
from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.markup import escape

from fusioncut.cli._errors import friendly_errors

console = Console(soft_wrap=True)  # messages name paths: the terminal wraps them, rich does not break them


class PlotKind(str, Enum):
    map = "map"  # engagement map of one CL: immersion angle vs height
    polar = "polar"  # top view of one CL in the machine frame
    program = "program"  # engagement range and ae/ap along the program
    heatmap = "heatmap"  # CL x height, engaged span


PER_CL = {PlotKind.map, PlotKind.polar}


def register(app: typer.Typer) -> None:
    @app.command("plot")
    @friendly_errors
    def plot(
        results_dir: Path = typer.Argument(..., help="Results directory (cl.parquet / cl.csv, slices, summary)."),
        out: Path = typer.Option(..., "--out", "-o", help="Output image; the suffix picks the format: .png or .svg."),
        kind: PlotKind = typer.Option(PlotKind.map, "--kind", "-k", help="map | polar | program | heatmap."),
        cl: Optional[int] = typer.Option(None, "--cl", help="CL index (required for --kind map and polar)."),
        width: int = typer.Option(1000, "--width", min=100, max=20000, help="Image width in pixels."),
        height: int = typer.Option(0, "--height", min=0, max=20000,
                                   help="Image height in pixels (0: a default aspect for the kind)."),
        dpi: int = typer.Option(100, "--dpi", min=20, max=1200, help="Resolution: pixels per inch (text size)."),
    ) -> None:
        """Plot engagement results: one CL (map, polar) or the whole program (program, heatmap)."""
        # matplotlib and pandas load slowly; import them only when this command actually runs, so
        # the rest of the CLI (and --help) stays fast
        from fusioncut.io.results import load_results
        from fusioncut.viz.plots import PLOTS, SUFFIX_FORMATS

        if out.suffix.lower() not in SUFFIX_FORMATS:
            raise ValueError(f"{out}: unsupported plot format {out.suffix!r} (use .png or .svg)")
        if kind in PER_CL and cl is None:
            raise ValueError(f"--kind {kind.value} draws one CL: give it with --cl N")
        aspect = {PlotKind.map: 0.625, PlotKind.polar: 1.0, PlotKind.program: 0.55, PlotKind.heatmap: 0.45}[kind]
        h_px = height or round(width * aspect)
        results = load_results(results_dir)
        fn = PLOTS[kind.value]
        kwargs = {"out": out, "figsize": (width / dpi, h_px / dpi), "dpi": dpi}
        fig = fn(results, cl, **kwargs) if kind in PER_CL else fn(results, **kwargs)
        del fig
        what = f"CL {cl}" if kind in PER_CL else f"{len(results.cl)} CLs"
        console.print(f"wrote {escape(str(out))} ({kind.value}, {what}, {width}x{h_px} px)", highlight=False)
