"""Cutting-force commands: ``fusioncut calibrate`` (coefficients from slot tests)."""
from __future__ import annotations

import math
from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from fusioncut.cli._errors import friendly_errors


def _fmt(value: float, digits: int = 4) -> str:
    return "n/a" if math.isnan(value) else f"{value:.{digits}g}"


@friendly_errors
def calibrate(
    csv_file: Path = typer.Argument(..., metavar="CSV", help="Slot tests: columns c_mm, fx_N, fy_N, fz_N."),
    axial_depth: float = typer.Option(..., "--axial-depth", help="Axial depth of the slots (mm)."),
    flutes: int = typer.Option(..., "--flutes", help="Number of flutes of the test tool."),
) -> None:
    """Fit the linear edge-force coefficients to mean forces of full-slot cuts.

    Each CSV row is one slot cut at feed per tooth c_mm with the mean force on the tool over whole
    revolutions (fx_N along the feed, fy_N 90 deg counter-clockwise from it, fz_N up the axis; M3
    spindle). A table dynamometer measures the reaction: negate its readings.
    """
    from fusioncut.analysis.calibrate import calibrate_from_slot_tests, read_slot_tests_csv

    tests = read_slot_tests_csv(csv_file)
    coeffs, fit = calibrate_from_slot_tests(tests.c, tests.fx, tests.fy, tests.fz, axial_depth, flutes)

    console = Console()
    table = Table(title=f"Cutting coefficients from {fit.tests} slot tests ({csv_file.name}, a = {axial_depth:g} mm, "
                  f"{flutes} flutes)")
    table.add_column("coefficient")
    table.add_column("value", justify="right")
    table.add_column("std. error", justify="right")
    table.add_column("unit")
    for key, value in coeffs.as_dict().items():
        unit = "N/mm²" if key.endswith("c") else "N/mm"
        table.add_row(key.capitalize(), _fmt(value, 5), _fmt(fit.stderr[key], 3), unit)
    console.print(table)

    lines = Table(title="Mean force = slope * c + intercept")
    for col in ("axis", "slope (N/mm)", "intercept (N)", "R²", "rms residual (N)"):
        lines.add_column(col, justify="right" if col != "axis" else "left")
    for axis, line in (("Fx", fit.x), ("Fy", fit.y), ("Fz", fit.z)):
        lines.add_row(axis, _fmt(line.slope, 5), _fmt(line.intercept, 5), _fmt(line.r_squared, 5),
                      _fmt(line.rms_residual, 3))
    console.print(lines)
    if fit.tests < 3:
        console.print("[yellow]note:[/] two tests fit the lines exactly; no error estimate is possible.")


def register(app: typer.Typer) -> None:
    app.command("calibrate")(calibrate)
