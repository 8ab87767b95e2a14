"""``fusioncut stability RESULTS --modes FILE --out DIR``: chatter stability per CL of a run.

Writes ``stability.csv`` / ``stability.parquet`` (columns
:data:`fusioncut.analysis.stability_table.STABILITY_COLUMNS`), ``lobes.png`` (ZOA and SD limit against the
spindle speed for one CL, with every CL's (speed, ap) point of the same tool over it) and
``margin.png`` (ap / a_lim along the program); with ``--stick-out`` also the static deflection columns
(:data:`fusioncut.analysis.deflection.DEFLECTION_COLUMNS`) and ``deflection.png``. The spindle speeds,
tools and slice height come from the results as for ``fusioncut forces`` (``--rpm``/``--flutes``/
``--helix`` override; ``--program`` and ``--slice-height`` for older folders); the cutting coefficients
from ``--material`` or a coefficients file (``--coefficients``, JSON, see
:func:`fusioncut.analysis.calibrate.read_coefficients_json`).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Optional

import typer
from rich.console import Console
from rich.markup import escape

from fusioncut.cli._errors import friendly_errors
from fusioncut.cli._process import (_COEFFICIENTS_HELP, _MATERIAL_HELP, _coefficients, _rpm_range, _setup, _tool_dynamics,
                                   _tool_info, _write_table)

console = Console(soft_wrap=True)  # messages name paths: the terminal wraps them, rich does not break them


@friendly_errors
def stability(
    results_dir: Path = typer.Argument(..., metavar="RESULTS", help="Results directory of a run."),
    modes: list[str] = typer.Option(..., "--modes", help="Tool-tip dynamics, modes (.json) or a measured FRF (.csv): "
                                                        "FILE for every tool, TOOL=FILE for one (its label or T "
                                                        "number); repeatable."),
    out: Path = typer.Option(..., "--out", "-o", help="Directory for stability.csv/.parquet and the plots."),
    material: Optional[str] = typer.Option(None, "--material", help=_MATERIAL_HELP),
    coefficients: Optional[Path] = typer.Option(None, "--coefficients", help=_COEFFICIENTS_HELP),
    program: Optional[Path] = typer.Option(None, "--program", help="The program the results came from: spindle "
                                                                    "speeds and tools the results do not record."),
    rpm: Optional[float] = typer.Option(None, "--rpm", help="Spindle speed (rev/min) for every CL."),
    flutes: Optional[int] = typer.Option(None, "--flutes", min=1, help="Flute count (overrides the tool's)."),
    helix: Optional[float] = typer.Option(None, "--helix", help="Helix angle, deg (overrides the tool's)."),
    slice_height: Optional[float] = typer.Option(None, "--slice-height", help="Engine slice height, mm, for "
                                                                              "results that do not record it."),
    sd: bool = typer.Option(True, "--sd/--no-sd", help="Also the semi-discretization limit (slower)."),
    sd_steps: int = typer.Option(30, "--sd-steps", min=4, help="Least SD steps per tooth period."),
    sd_max_steps: int = typer.Option(120, "--sd-max-steps", min=4, help="Most SD steps per tooth period; "
                                                                        "slower speeds get no SD limit."),
    rpm_min: Optional[float] = typer.Option(None, "--rpm-min", help="Lowest speed searched for a stable one "
                                                                    "(default: half the CL's)."),
    rpm_max: Optional[float] = typer.Option(None, "--rpm-max", help="Highest speed searched (default: 1.5 times "
                                                                    "the CL's)."),
    n_modes: Optional[int] = typer.Option(None, "--fit-modes", min=1, help="Modes per direction fitted to an FRF "
                                                                           "(default: one per clear peak)."),
    lobes_cl: Optional[int] = typer.Option(None, "--lobes-cl", help="CL whose lobes are drawn (default: the "
                                                                     "largest margin)."),
    plot: bool = typer.Option(True, "--plot/--no-plot", help="Draw lobes.png and margin.png."),
    stick_out: Optional[float] = typer.Option(None, "--stick-out", help="Tool stick-out from the holder (mm): "
                                                                        "adds the static deflection columns."),
    flute_factor: float = typer.Option(0.8, "--flute-factor", help="Effective diameter of the flutes for "
                                                                   "bending, fraction of the diameter."),
    youngs_gpa: float = typer.Option(600.0, "--youngs-gpa", help="Young's modulus of the tool (GPa; carbide "
                                                                 "about 600)."),
) -> None:
    """Chatter stability per CL: limiting depth by ZOA and SD, margin ap / a_lim, nearest stable speed;
    with --stick-out also the static tool deflection and the wall's surface location error."""
    import pandas as pd

    from fusioncut.analysis.deflection import DEFLECTION_COLUMNS, SteppedCantilever, deflection_table
    from fusioncut.analysis.stability_table import STABILITY_COLUMNS, stability_table

    rpm_range = _rpm_range(rpm_min, rpm_max)
    s = _setup(results_dir, program, _coefficients(material, coefficients), rpm, flutes, helix, slice_height)
    dynamics = _tool_dynamics(modes, s.tools, n_modes)
    parts = []
    for label, idx in s.groups.items():
        part = stability_table([s.maps[i] for i in idx], s.tools[label], s.coefficients, dynamics[label],
                               [s.rpms[i] for i in idx], dz=s.dz, sd=sd, sd_steps=sd_steps,
                               sd_max_steps=sd_max_steps, rpm_range=rpm_range)
        if stick_out is not None:
            beam = SteppedCantilever.for_tool(s.tools[label], stick_out, flute_factor, youngs_gpa * 1e3)
            extra = deflection_table([s.maps[i] for i in idx], s.tools[label], s.coefficients, beam,
                                     [s.rpms[i] for i in idx], dz=s.dz)
            part = pd.concat([part.reset_index(drop=True), extra], axis=1)
        part.index = idx
        parts.append(part)
    table = pd.concat(parts).sort_index()
    out.mkdir(parents=True, exist_ok=True)
    _write_table(table, out / "stability", {c: (u, d) for c, u, d in STABILITY_COLUMNS + DEFLECTION_COLUMNS},
                 {"modes": {k: d.as_dict() for k, d in dynamics.items()}, "coefficients": s.coefficients.as_dict(),
                  "coefficients_name": s.coefficients.name, "slice_height_mm": s.dz, "sd": sd,
                  "tools": {k: _tool_info(t) for k, t in s.tools.items()}})
    wrote = ["stability.csv", "stability.parquet"]
    known = table[table["margin"].notna()]
    if plot and len(known):
        chosen = _chosen_row(table, lobes_cl)
        _plot_lobes(s, table, chosen, dynamics, sd, sd_steps, sd_max_steps, out / "lobes.png")
        _plot_margin(table, out / "margin.png")
        wrote += ["lobes.png", "margin.png"]
        if stick_out is not None:
            _plot_deflection(table, out / "deflection.png")
            wrote.append("deflection.png")
    chatter = known[known["margin"] >= 1.0]
    console.print(f"stability of {len(known)} CL(s) ({escape(s.coefficients.name)}, Ktc "
                  f"{s.coefficients.ktc:g} N/mm²): {len(chatter)} with margin >= 1 (chatter predicted), largest "
                  f"margin {known['margin'].max() if len(known) else math.nan:.3g}", highlight=False)
    no_speed = int(((table["status"] == "engaged") & table["spindle_rpm"].isna()).sum())
    if no_speed:
        console.print(f"[yellow]note:[/] {no_speed} engaged CL(s) without a spindle speed have no limit (the "
                      "program sets none there): give --rpm, or --program for a folder that does not record "
                      "the speeds", highlight=False)
    no_sd = int((known["a_lim_sd_mm"].isna() & (known["status"] == "engaged")).sum()) if sd else 0
    if no_sd:
        console.print(f"[yellow]note:[/] {no_sd} engaged CL(s) without an SD limit: at their speed a tooth period "
                      f"needs more than --sd-max-steps {sd_max_steps} steps (their margin is ZOA's)", highlight=False)
    console.print(f"wrote {', '.join(wrote)} in {escape(str(out))}", highlight=False)



def _chosen_row(table: Any, cl: Optional[int]) -> Any:
    from fusioncut.errors import InputError

    known = table[table["margin"].notna() & (table["status"] == "engaged")]
    if cl is None:
        if not len(known):
            known = table[table["margin"].notna()]
        return known.loc[known["margin"].idxmax()]
    rows = table[table["cl"] == cl]
    if not len(rows) or not rows["margin"].notna().any():
        raise InputError(f"--lobes-cl {cl}: no such CL with a stability limit (engaged, with a spindle speed)")
    return rows[rows["margin"].notna()].iloc[-1]


def _plot_lobes(s: Any, table: Any, row: Any, dynamics: dict[str, Any], sd: bool, sd_steps: int,
                sd_max_steps: int, path: Path) -> None:
    """ZOA (and SD at 40 speeds) lobes of the chosen CL between 0.3 and 2 times its speed, with the
    (speed, ap) points of the CLs of the same tool (red: margin >= 1)."""
    import numpy as np

    from fusioncut.analysis.stability import ModalSystem, chatter_grid, cl_directional, sd_a_lim, zoa_lobes
    from fusioncut.viz.plots import new_figure, save_figure

    i = int(row.name)
    emap = s.maps[i]
    tool = s.tools[emap.tool]
    dyn = dynamics[emap.tool]
    cd = cl_directional(emap, tool, s.coefficients, s.dz)
    n = float(row["spindle_rpm"])
    grid = chatter_grid(dyn)
    speeds, zoa = zoa_lobes(cd.alpha0, grid, s.coefficients.ktc, cd.flutes, 0.3 * n, 2.0 * n, 400)
    fig = new_figure((9.0, 5.5))
    ax = fig.subplots()
    ax.plot(speeds, zoa, color="black", lw=1.2, label="ZOA a_lim", gid="zoa")
    if sd:
        few = np.linspace(0.3 * n, 2.0 * n, 40)
        ref = np.interp(few, speeds, np.where(np.isfinite(zoa), zoa, cd.ap))
        lim = sd_a_lim(cd, ModalSystem.from_dynamics(dyn), s.coefficients.ktc, few, ref, steps=sd_steps,
                       max_steps=sd_max_steps)
        ax.plot(few, lim, "o-", color="#2c7fb8", ms=3, lw=1.0, label="SD a_lim", gid="sd")
    same = table[(table["margin"].notna()) & (table.index.isin(s.groups[emap.tool]))]
    bad = same["margin"] >= 1.0
    ax.scatter(same.loc[~bad, "spindle_rpm"], same.loc[~bad, "ap_mm"], s=10, color="#1a9850",
               label="CLs, margin < 1", gid="stable")
    ax.scatter(same.loc[bad, "spindle_rpm"], same.loc[bad, "ap_mm"], s=10, color="#d73027",
               label="CLs, margin >= 1", gid="chatter")
    ax.scatter([n], [row["ap_mm"]], s=60, marker="*", color="black", label=f"CL {int(row['cl'])}", gid="chosen")
    top = np.nanmax(np.concatenate([zoa[np.isfinite(zoa)], same["ap_mm"].to_numpy(dtype=float), [1e-3]]))
    ax.set_ylim(0, min(top, 4 * max(float(np.nanmin(zoa)), float(row["ap_mm"]))) * 1.1)
    ax.set_xlabel("spindle speed (rev/min)")
    ax.set_ylabel("axial depth (mm)")
    ax.set_title(f"Stability lobes of CL {int(row['cl'])} ({row['operation'] or 'no operation'}, tool {emap.tool}); "
                 "points: every CL of the tool", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    save_figure(fig, path)


def _plot_margin(table: Any, path: Path) -> None:
    from fusioncut.viz.plots import new_figure, save_figure

    fig = new_figure((11.0, 4.0))
    ax = fig.subplots()
    ax.plot(table["cl"], table["margin"], color="black", lw=1.0, drawstyle="steps-mid", gid="margin")
    ax.axhline(1.0, color="#d73027", lw=1.0, ls="--", label="stability limit")
    ax.set_xlabel("CL")
    ax.set_ylabel("margin ap / a_lim")
    ax.set_title("Chatter margin along the program (>= 1: chatter predicted)", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    save_figure(fig, path)


def _plot_deflection(table: Any, path: Path) -> None:
    from fusioncut.viz.plots import new_figure, save_figure

    fig = new_figure((11.0, 4.0))
    ax = fig.subplots()
    ax.plot(table["cl"], table["tip_deflection_peak_um"], color="black", lw=1.0, drawstyle="steps-mid",
            label="tip deflection, peak", gid="tip")
    ax.fill_between(table["cl"], table["sle_min_um"], table["sle_max_um"], step="mid", color="#2c7fb8", alpha=0.5,
                    label="wall surface location error (+ material left)", gid="sle")
    ax.axhline(0.0, color="grey", lw=0.6)
    ax.set_xlabel("CL")
    ax.set_ylabel("µm")
    ax.set_title("Static tool deflection along the program", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    save_figure(fig, path)


def register(app: typer.Typer) -> None:
    app.command("stability")(stability)
