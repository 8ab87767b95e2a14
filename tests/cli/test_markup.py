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
