"""Names that come from files (operations, paths) reach rich consoles escaped: rich would read
"[d2.4mm]" as a style tag and drop it."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from rich.console import Console

from fusioncut.cli import run as run_cli


def test_run_summary_shows_bracketed_names_literally(monkeypatch, tmp_path: Path) -> None:
    console = Console(width=250, record=True, color_system=None)
    monkeypatch.setattr(run_cli, "console", console)
    op = SimpleNamespace(operation="Contour [d2.4mm]", cls=3, engaged=2, air=1, rapid=0, failed=0, removed=1.5,
                         max_ae=0.5, max_ap=1.0, median_ms=2.0)
    result = SimpleNamespace(out_dir=tmp_path / "out[v2]", operations={"c": op}, stock_volume=10.0,
                             final_volume=8.5, removed_volume=1.5, conservation_error=0.0, seconds=1.0,
                             resumed_from=None, exported=[tmp_path / "ipw[v2].step"], interrupted=False)
    run_cli._print_summary(result)
    text = console.export_text()
    assert "Contour [d2.4mm]" in text
    assert "out[v2]" in text and "ipw[v2].step" in text


def _results(out: Path) -> None:
    """A results folder of two engaged CLs (a 2 mm slot and a half-immersion cut) with a 10 mm flat mill."""
    from fusioncut.errors import SourceLocation
    from fusioncut.io.results import ResultWriter
    from fusioncut.model import AngleInterval, CLStatus, EngagementMap, SliceEngagement, SpindleDirection

    def cl(i: int, entry: float) -> EngagementMap:
        sl = tuple(SliceEngagement(0.25 + 0.5 * k, -1.75 + 0.5 * k, 5.0, (AngleInterval(entry, 180.0),))
                   for k in range(4))
        return EngagementMap(i, (i + 1.0, 0, -2.0), (float(i), 0, -2.0), "T1", SpindleDirection.CW, 0.0,
                             CLStatus.ENGAGED, source=SourceLocation("prog.nc", 10 + i), feed=600.0,
                             operation="op", slices=sl, axial_range=(0.0, 2.0))

    with ResultWriter(out, tools={"T1": {"kind": "flat", "diameter_mm": 10.0, "flute_length_mm": 20.0}}) as w:
        for m in (cl(0, 0.0), cl(1, 90.0)):
            w.add(m, length_mm=1.0)


def test_forces_and_stability_print_bracketed_folders_literally(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from fusioncut.cli import app

    res = tmp_path / "res[v2]"
    _results(res)
    r = CliRunner().invoke(app, ["forces", str(res), "--rpm", "9000", "--slice-height", "0.5", "--no-plot"],
                           env={"COLUMNS": "400"})
    assert r.exit_code == 0, r.output
    assert f"in {res}" in r.output.replace("\n", "")
    modes = Path(__file__).parents[2] / "docs" / "stability_modes_example.json"
    out = tmp_path / "stab[v2]"
    r = CliRunner().invoke(app, ["stability", str(res), "--modes", str(modes), "--rpm", "9000", "--flutes", "4",
                                 "--helix", "30", "--slice-height", "0.5", "--out", str(out), "--no-plot"],
                           env={"COLUMNS": "400"})
    assert r.exit_code == 0, r.output
    assert f"in {out}" in r.output.replace("\n", "")


def test_run_progress_bars_show_bracketed_operation_names_literally() -> None:
    from rich.progress import Progress, TextColumn

    console = Console(width=120, record=True, color_system=None)
    bar = Progress(TextColumn("{task.description}"), console=console)
    reporter = run_cli._ProgressReporter(bar)
    reporter.on_start(SimpleNamespace(total=3, start_at=0, expected={"Contour [d2.4mm]": 2, "": 1}, done={}))
    console.print(bar.get_renderable())
    text = console.export_text()
    assert "  Contour [d2.4mm]" in text and "(no operation)" in text
