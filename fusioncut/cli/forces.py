"""Cutting-force commands.

* ``fusioncut calibrate CSV``: linear edge-force coefficients from slot tests, written to a coefficients
  file (JSON: :func:`fusioncut.analysis.calibrate.coefficients_document`) that ``forces``, ``advise``
  and ``stability`` take with ``--coefficients`` instead of ``--material``.
* ``fusioncut forces RESULTS_DIR``: per-CL forces of a run (``forces.csv``, ``forces.parquet`` and
  ``forces.png`` in the results directory).
* ``fusioncut advise RESULTS_DIR --program FILE --max-force N --out NEW``: feed advice, the program
  rewritten with only its F words changed, the advice table and a plot of programmed vs advised feed.

A results folder records each CL's spindle speed, the tools (full records) and the engine's slice
height (:func:`_setup`); ``--rpm``, ``--flutes`` and ``--helix`` override them. Folders written before
those were recorded take them from ``--program`` (S words, tool comments) or the options, and the slice
height from ``--slice-height`` (else inferred from the slices).
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from fusioncut.cli._errors import friendly_errors
from fusioncut.cli._process import (_COEFFICIENTS_HELP, _MATERIAL_HELP, _coefficients, _rpm_range, _setup, _Setup,
                                   _tool_dynamics, _tool_info, _write_table)

console = Console(soft_wrap=True)  # messages name paths: the terminal wraps them, rich does not break them


def _fmt(value: float, digits: int = 4) -> str:
    return "n/a" if math.isnan(value) else f"{value:.{digits}g}"


@friendly_errors
def calibrate(
    csv_file: Path = typer.Argument(..., metavar="CSV", help="Slot tests: columns c_mm, fx_N, fy_N, fz_N."),
    axial_depth: float = typer.Option(..., "--axial-depth", help="Axial depth of the slots (mm)."),
    flutes: int = typer.Option(..., "--flutes", help="Number of flutes of the test tool."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Coefficients file to write (JSON; default: "
                                                                 "CSV's name + _coefficients.json beside it)."),
    name: Optional[str] = typer.Option(None, "--name", help="Name of the coefficient set (default: from CSV)."),
) -> None:
    """Fit the linear edge-force coefficients to mean forces of full-slot cuts and write them to a
    coefficients file that forces, advise and stability take with --coefficients.

    Each CSV row is one slot cut at feed per tooth c_mm with the mean force on the tool over whole
    revolutions (fx_N along the feed, fy_N 90 deg counter-clockwise from it, fz_N up the axis; M3
    spindle). A table dynamometer measures the reaction: negate its readings. Ktc or Krc not > 0 is
    refused (a sign convention broken); implausible values and a poor fit (R²) are warned about and
    recorded in the file.
    """
    from fusioncut.analysis.calibrate import (COEFFICIENT_UNITS, calibrate_from_slot_tests, check_signs,
                                              plausibility_warnings, read_slot_tests_csv, write_coefficients_json)

    tests = read_slot_tests_csv(csv_file)
    coeffs, fit = calibrate_from_slot_tests(tests.c, tests.fx, tests.fy, tests.fz, axial_depth, flutes,
                                            name=name or f"calibrated from {csv_file.name}")
    coeffs = dataclasses.replace(coeffs, source=f"{coeffs.source}; data {csv_file}")
    check_signs(coeffs, csv_file)
    warnings = plausibility_warnings(coeffs, fit)

    table = Table(title=f"Cutting coefficients from {fit.tests} slot tests ({escape(csv_file.name)}, "
                  f"a = {axial_depth:g} mm, {flutes} flutes)")
    table.add_column("coefficient")
    table.add_column("value", justify="right")
    table.add_column("std. error", justify="right")
    table.add_column("unit")
    for key, value in coeffs.as_dict().items():
        table.add_row(key.capitalize(), _fmt(value, 5), _fmt(fit.stderr[key], 3), COEFFICIENT_UNITS[key])
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
    for w in warnings:
        console.print(f"[yellow]warning:[/] {escape(str(csv_file))}: {escape(w)}", highlight=False)
    out = out or csv_file.with_name(csv_file.stem + "_coefficients.json")
    write_coefficients_json(out, coeffs, fit, str(csv_file), warnings)
    console.print(escape(f"wrote {out}"), highlight=False)


# --------------------------------------------------------------------------------------------------
# shared set-up of forces and advise



@friendly_errors
def forces(
    results_dir: Path = typer.Argument(..., help="Results directory of a run."),
    program: Optional[Path] = typer.Option(None, "--program", help="The program the results came from: spindle "
                                                                    "speeds and tools the results do not record."),
    material: Optional[str] = typer.Option(None, "--material", help=_MATERIAL_HELP),
    coefficients: Optional[Path] = typer.Option(None, "--coefficients", help=_COEFFICIENTS_HELP),
    rpm: Optional[float] = typer.Option(None, "--rpm", help="Spindle speed (rev/min) for every CL."),
    flutes: Optional[int] = typer.Option(None, "--flutes", min=1, help="Flute count (overrides the tool's)."),
    helix: Optional[float] = typer.Option(None, "--helix", help="Helix angle, deg (overrides the tool's)."),
    slice_height: Optional[float] = typer.Option(None, "--slice-height", help="Engine slice height, mm, for "
                                                                              "results that do not record it."),
    samples: int = typer.Option(360, "--samples", min=1, help="Spindle angles per revolution."),
    plot: bool = typer.Option(True, "--plot/--no-plot", help="Also draw forces.png."),
) -> None:
    """Per-CL cutting forces of a run: forces.csv / forces.parquet (+ forces.png) in RESULTS_DIR.

    Columns (forces on the tool): peak and mean Fx Fy Fz in the feed frame (x along the feed, y 90 deg
    counter-clockwise from it, z up the tool axis) and in the machine frame (N), peak and mean
    resultant |F| (N), torque (N*m), spindle power (W), peak chip thickness (mm); feed (mm/min), rpm,
    feed per tooth (mm). Rapids and failed CLs have empty cells.
    """
    import pandas as pd

    from fusioncut.analysis.forces import FORCE_COLUMNS, forces_table

    s = _setup(results_dir, program, _coefficients(material, coefficients), rpm, flutes, helix, slice_height)
    parts = []
    for label, idx in s.groups.items():
        part = forces_table([s.maps[i] for i in idx], s.tools[label], s.coefficients, [s.rpms[i] for i in idx],
                            dz=s.dz, samples=samples)
        part.index = idx
        parts.append(part)
    table = pd.concat(parts).sort_index()
    _write_table(table, results_dir / "forces", {c: (u, d) for c, u, d in FORCE_COLUMNS},
                 {"coefficients_name": s.coefficients.name, "coefficients": s.coefficients.as_dict(),
                  "coefficients_source": s.coefficients.source, "slice_height_mm": s.dz,
                  "tools": {k: _tool_info(t) for k, t in s.tools.items()}})
    wrote = ["forces.csv", "forces.parquet"]
    if plot:
        from fusioncut.viz.plots import plot_forces

        plot_forces(table, out=results_dir / "forces.png")
        wrote.append("forces.png")
    known = table[table["resultant_peak_N"].notna()]
    summary = Table(title=f"Cutting forces ({escape(s.coefficients.name)}; slice height {s.dz:g} mm)")
    for col in ("CLs with forces", "max |F| peak N", "mean |F| mean N", "max torque N*m", "max power W",
                "max chip mm"):
        summary.add_column(col, justify="right")
    summary.add_row(str(len(known)), _fmt(known["resultant_peak_N"].max()), _fmt(known["resultant_mean_N"].mean()),
                    _fmt(known["torque_peak_Nm"].max()), _fmt(known["power_peak_W"].max()),
                    _fmt(known["chip_peak_mm"].max()))
    console.print(summary)
    unknown = int(((table["status"] != "rapid") & table["resultant_peak_N"].isna()).sum())
    if unknown:
        console.print(f"[yellow]note:[/] {unknown} feed CL(s) without forces (failed, or no feed / spindle speed)")
    console.print(f"wrote {', '.join(wrote)} in {escape(str(results_dir))}", highlight=False)



@friendly_errors
def advise(
    results_dir: Path = typer.Argument(..., help="Results directory of a run of PROGRAM."),
    program: Path = typer.Option(..., "--program", help="The G-code program the results came from."),
    out: Path = typer.Option(..., "--out", "-o", help="The rewritten program (only F words change)."),
    max_force: Optional[float] = typer.Option(None, "--max-force", help="Peak resultant force limit (N)."),
    max_chip: Optional[float] = typer.Option(None, "--max-chip", help="Peak chip thickness limit (mm)."),
    max_power: Optional[float] = typer.Option(None, "--max-power", help="Peak spindle power limit (W)."),
    max_mrr: Optional[float] = typer.Option(None, "--max-mrr", help="Removal rate limit (mm³/min)."),
    min_feed: Optional[float] = typer.Option(None, "--min-feed", help="Lowest feed (mm/min; default 10 % of "
                                                                      "the smallest programmed cutting feed)."),
    max_feed: Optional[float] = typer.Option(None, "--max-feed", help="Highest feed (mm/min; default the largest "
                                                                      "programmed cutting feed)."),
    air_feed: bool = typer.Option(False, "--air-feed", help="Feed air cuts at --max-feed."),
    raise_ramps: bool = typer.Option(False, "--raise-ramps", help="Let moves going down be fed faster than "
                                                                  "programmed."),
    quantum: float = typer.Option(0.05, "--quantum", help="Feed step, fraction of the programmed feed."),
    min_run: Optional[float] = typer.Option(None, "--min-run", help="Shortest stretch (mm) a raised feed must "
                                                                    "last (default: tool diameter)."),
    material: Optional[str] = typer.Option(None, "--material", help=_MATERIAL_HELP),
    coefficients: Optional[Path] = typer.Option(None, "--coefficients", help=_COEFFICIENTS_HELP),
    rpm: Optional[float] = typer.Option(None, "--rpm", help="Spindle speed (rev/min) for every CL (default: the "
                                                            "recorded ones, else the program's S)."),
    flutes: Optional[int] = typer.Option(None, "--flutes", min=1, help="Flute count (overrides the tool's)."),
    helix: Optional[float] = typer.Option(None, "--helix", help="Helix angle, deg (overrides the tool's)."),
    slice_height: Optional[float] = typer.Option(None, "--slice-height", help="Engine slice height, mm, for "
                                                                              "results that do not record it."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Feed plot (.png/.svg; default OUT's name + "
                                                             "_feed.png)."),
    modes: Optional[list[str]] = typer.Option(None, "--modes", help="Tool-tip dynamics (as for fusioncut "
                                                                    "stability): adds the spindle speed advice."),
    max_margin: float = typer.Option(0.8, "--max-margin", help="With --modes: the largest chatter margin ap / "
                                                               "a_lim to hold per operation."),
    rpm_min: Optional[float] = typer.Option(None, "--rpm-min", help="With --modes: lowest speed searched "
                                                                    "(default: half the programmed)."),
    rpm_max: Optional[float] = typer.Option(None, "--rpm-max", help="With --modes: highest speed searched "
                                                                    "(default: 1.5 times the programmed)."),
) -> None:
    """Advise feeds that keep the load at a limit, and rewrite PROGRAM with them (only F words change).

    Writes OUT, OUT's name + _advice.csv (per CL: programmed and advised feed mm/min, what limited it,
    loads at both feeds) and the plot. Feeds are mm/min here; the program gets them in its own units.
    With --modes also OUT's name + _speeds.csv: per operation the largest chatter margin (ZOA) at the
    programmed speed and the nearest speed where every CL keeps --max-margin; the program's S words are
    not changed (the feed cannot remove chatter: the ZOA limit does not depend on it).
    """
    import pandas as pd

    from fusioncut.analysis.feed import FEED_COLUMNS, FeedAdvice, FeedLimit, same_source_file, advise_feeds
    from fusioncut.errors import InputError
    from fusioncut.io.gcode import rewrite_gcode_file
    from fusioncut.viz.plots import SUFFIX_FORMATS, plot_feed_advice

    plot = plot or out.with_name(out.stem + "_feed.png")
    if plot.suffix.lower() not in SUFFIX_FORMATS:
        raise ValueError(f"{plot}: unsupported plot format {plot.suffix!r} (use .png or .svg)")
    limit = FeedLimit(max_force=max_force, max_chip_thickness=max_chip, max_power=max_power, max_mrr=max_mrr,
                      min_feed=min_feed, max_feed=max_feed, air_feed=air_feed, raise_ramps=raise_ramps)
    rpm_range = _rpm_range(rpm_min, rpm_max)
    if rpm_range is not None and not modes:
        raise InputError("--rpm-min and --rpm-max search a spindle speed: give --modes too")
    s = _setup(results_dir, program, _coefficients(material, coefficients), rpm, flutes, helix, slice_height)
    mine = [i for i, m in enumerate(s.maps) if same_source_file(str(m.source.file), str(program))]
    if not mine:
        raise InputError(f"no CL of the results comes from {program.name}", results_dir)
    _check_same_program(s, mine, program)

    # one feed range for every tool of the program (defaults from all its engaged CLs)
    cutting = [s.maps[i].feed for i in mine if s.maps[i].status.value == "engaged" and s.maps[i].feed]
    if limit.min_feed is None or limit.max_feed is None:
        if not cutting:
            raise InputError("no engaged CL with a programmed feed: give --min-feed and --max-feed", results_dir)
        limit = dataclasses.replace(limit, min_feed=limit.min_feed if limit.min_feed is not None else 0.1 * min(cutting),
                                    max_feed=limit.max_feed if limit.max_feed is not None else max(cutting))
        if limit.min_feed > limit.max_feed:  # type: ignore[operator]
            raise InputError(f"--min-feed {limit.min_feed:g} is above --max-feed {limit.max_feed:g} mm/min")
    parts, advices = [], []
    lengths = s.results.cl["length_mm"].to_numpy(dtype=float)
    wanted = set(mine)
    for label, idx in s.groups.items():
        idx = [i for i in idx if i in wanted]
        if not idx:
            continue
        adv = advise_feeds([s.maps[i] for i in idx], s.tools[label], s.coefficients, limit,
                           rpm=[s.rpms[i] for i in idx], dz=s.dz, lengths=lengths[idx], quantum=quantum,
                           min_run_length=min_run)
        adv.table.index = idx
        parts.append(adv.table)
        advices.append(adv)
    table = pd.concat(parts).sort_index()
    advice = FeedAdvice(table=table.reset_index(drop=True), limit=limit, quantum=quantum,
                        min_run_length=advices[0].min_run_length, slice_height=s.dz)
    result = rewrite_gcode_file(program, advice.line_feeds(), out)
    _write_table(table, out.with_name(out.stem + "_advice"), {c: (u, d) for c, u, d in FEED_COLUMNS},
                 {"program": str(program), "limit": dataclasses.asdict(advice.limit), "quantum": quantum,
                  "min_run_length_mm": advice.min_run_length, "coefficients_name": s.coefficients.name,
                  "coefficients": s.coefficients.as_dict()})
    plot_feed_advice(advice, out=plot)

    t = advice.table
    prog, adv_f = t["programmed_feed_mm_min"], t["advised_feed_mm_min"]
    unreachable = int(t["note"].str.contains("unreachable", regex=False).sum())
    console.print(f"feed advice for {escape(program.name)}: {len(t)} CLs; "
                  f"feed time {advice.cycle_time_s('programmed'):.1f} s programmed -> {advice.cycle_time_s():.1f} s "
                  f"advised; {int((adv_f < prog).sum())} CLs slower, "
                  f"{int((adv_f > prog).sum())} faster; {advice.feed_changes()} feed changes; "
                  f"{len(result.changed_lines)} lines changed", highlight=False)
    counts = t["reason"].value_counts()
    console.print("advice set by: " + ", ".join(f"{k} {v}" for k, v in counts.items()), highlight=False)
    if unreachable:
        console.print(f"[yellow]note:[/] {unreachable} CL(s) exceed the limit at every feed down to --min-feed "
                      f"({advice.limit.min_feed:g} mm/min): note 'unreachable' in the advice table", highlight=False)
    for note in result.notes[:10]:
        console.print(f"[yellow]note:[/] {escape(note)}", highlight=False)
    wrote = f"wrote {out}, {out.stem}_advice.csv/.parquet, {plot.name}"
    if modes:
        _advise_speeds(s, mine, modes, max_margin, rpm_range, out.with_name(out.stem + "_speeds"))
        wrote += f", {out.stem}_speeds.csv/.parquet"
    console.print(escape(wrote), highlight=False)



def _advise_speeds(s: _Setup, rows: list[int], modes: list[str], max_margin: float,
                   rpm_range: Optional[tuple[float, float]], stem: Path) -> None:
    """The spindle speed advice of the CLs ``rows`` per tool and operation: ``stem``.csv/.parquet and a table."""
    import pandas as pd

    from fusioncut.analysis.speed_advice import SPEED_COLUMNS, advise_speeds

    dynamics = _tool_dynamics(modes, s.tools, None)
    wanted = set(rows)
    parts = []
    for label, idx in s.groups.items():
        idx = [i for i in idx if i in wanted]
        if idx:
            parts.append(advise_speeds([s.maps[i] for i in idx], s.tools[label], s.coefficients, dynamics[label],
                                       [s.rpms[i] for i in idx], max_margin=max_margin, dz=s.dz, rpm_range=rpm_range))
    table = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=[c[0] for c in SPEED_COLUMNS])
    _write_table(table, stem, {c: (u, d) for c, u, d in SPEED_COLUMNS},
                 {"max_margin": max_margin, "rpm_range": list(rpm_range) if rpm_range else None,
                  "modes": {k: d.as_dict() for k, d in dynamics.items()}})
    view = Table(title=f"Spindle speed per operation (chatter margin ap / a_lim, ZOA; hold <= {max_margin:g})")
    for col in ("operation", "tool", "rpm", "CLs", "margin", "worst CL", "suggested rpm", "margin there"):
        view.add_column(col, justify="left" if col in ("operation", "tool") else "right")
    for r in table.itertuples():
        view.add_row(escape(str(r.operation) or "-"), escape(str(r.tool)), f"{r.spindle_rpm:g}", str(r.engaged_cls),
                     _fmt(r.margin_max, 3), str(r.worst_cl), _fmt(r.suggested_rpm, 6),
                     _fmt(r.margin_max_suggested, 3))
    console.print(view)
    if not len(table):
        console.print("[yellow]note:[/] no engaged CL with a spindle speed: no speed advice", highlight=False)


def _check_same_program(s: _Setup, rows: list[int], program: Path) -> None:
    """The results must come from this very program: their feeds per line must be the program's."""
    from fusioncut.errors import InputError, SourceLocation

    feeds: dict[int, set[float]] = {}
    for m in s.program.moves:
        if m.feed is not None:
            feeds.setdefault(m.source.line, set()).add(round(m.feed, 6))
    for i in rows:
        m = s.maps[i]
        if m.feed is None:
            continue
        have = feeds.get(m.source.line)
        if not have or round(m.feed, 6) not in have:
            got = ", ".join(f"{f:g}" for f in sorted(have)) if have else "no feed move"
            raise InputError(f"the results say CL {m.cl_index} feeds at {m.feed:g} mm/min here, the program has "
                             f"{got}: were the results computed from this program?",
                             SourceLocation(str(program), m.source.line))


def register(app: typer.Typer) -> None:
    app.command("calibrate")(calibrate)
    app.command("forces")(forces)
    app.command("advise")(advise)
