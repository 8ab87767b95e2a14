"""Plots of engagement results, drawn from loaded result tables (:func:`fusioncut.io.results.load_results`).

Every function takes a :class:`~fusioncut.io.results.Results`, returns a matplotlib
:class:`~matplotlib.figure.Figure` and, given ``out``, saves it (PNG or SVG, chosen by the suffix).
Figures are created without pyplot on an Agg canvas: no display is needed, nothing is kept in
pyplot's global figure registry (so plotting many CLs does not leak memory), and the image has exactly
``figsize * dpi`` pixels (constrained layout fits the labels inside the figure instead of cropping it).

Angle conventions (see :mod:`fusioncut.model.angles`): the engagement map, program view and heat map
use **immersion** angles (feed frame, from +y in the sense the teeth turn); the polar top view uses
**machine** angles (counter-clockwise from +X, seen from +Z). Lengths are mm.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from matplotlib.transforms import blended_transform_factory

from fusioncut.io.results import Results
from fusioncut.model.angles import machine_from_immersion
from fusioncut.model.tools import SpindleDirection

SUFFIX_FORMATS = {".png": "png", ".svg": "svg"}

ENTRY_COLOR = "#1a9850"  # green: the tooth enters the material
EXIT_COLOR = "#d73027"  # red: the tooth leaves it
ARC_COLOR = "#2c7fb8"
POLAR_SPAN_MAX_DEG = 180.0  # the polar plot's colour scale of engaged arcs: 0 .. a full slot


# --------------------------------------------------------------------------------------------------
# figure plumbing


def new_figure(figsize: tuple[float, float] = (8.0, 5.0), dpi: float = 100.0) -> Figure:
    """An Agg-backed figure of ``figsize`` inches at ``dpi`` with constrained layout."""
    fig = Figure(figsize=figsize, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, out: str | os.PathLike[str]) -> Path:
    """Save ``fig`` to ``out`` as PNG or SVG by its suffix, at the figure's own size and dpi."""
    path = Path(out)
    fmt = SUFFIX_FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise ValueError(f"{path}: unsupported plot format {path.suffix!r} (use .png or .svg)")
    path.parent.mkdir(parents=True, exist_ok=True)
    # no bbox_inches="tight": it would crop the image to a size other than the one asked for
    fig.savefig(path, format=fmt, dpi=fig.dpi)
    return path


def _finish(fig: Figure, out: str | os.PathLike[str] | None) -> Figure:
    if out is not None:
        save_figure(fig, out)
    return fig


def _cl_title(row: pd.Series) -> str:
    where = f"{row['file']}:{row['line']}" if int(row["line"]) else str(row["file"])
    parts = [f"CL {int(row['cl'])}", where]
    if row["operation"]:
        parts.append(str(row["operation"]))
    parts.append(f"tool {row['tool']}")
    return " — ".join(parts)


def _cl_facts(row: pd.Series) -> str:
    """One line of the key numbers of a CL, for a subtitle."""
    facts = [f"status {row['status']}", f"ae {row['ae_mm']:.3g} mm", f"ap {row['ap_mm']:.3g} mm"]
    if not math.isnan(row["feed_mm_min"]):
        facts.append(f"feed {row['feed_mm_min']:.4g} mm/min")
    if row["removed_volume_mm3"]:
        facts.append(f"removed {row['removed_volume_mm3']:.4g} mm³")
    if row["reason"]:
        facts.append(f"reason: {row['reason']}")
    return ", ".join(facts)


def _extents(sl: pd.DataFrame, col: str) -> tuple[np.ndarray, np.ndarray]:
    """Drawn extent ``(lo, hi)`` (mm) of each slice row along ``col``. Heights (``z_tool_mm``) span the
    slice's recorded band ``[z_lo_mm, z_hi_mm]``; radii, and heights of folders that do not record the
    bands, get a thin mark centred on the value (4 % of the largest value, at least 0.05 mm), which
    shows where the slice is without claiming how far it reaches."""
    v = sl[col].to_numpy(dtype=float)
    half = 0.5 * max(0.05, 0.04 * float(np.abs(v).max(initial=0.0)))
    lo, hi = v - half, v + half
    if col == "z_tool_mm":
        known = sl["z_lo_mm"].notna().to_numpy() & sl["z_hi_mm"].notna().to_numpy()
        lo = np.where(known, sl["z_lo_mm"].to_numpy(dtype=float), lo)
        hi = np.where(known, sl["z_hi_mm"].to_numpy(dtype=float), hi)
    return lo, hi


def _wrapped(entry: float, exit_: float) -> list[tuple[float, float]]:
    """Pieces ``(start, width)`` of an arc within [0, 360): arcs may run past 360 (exit <= entry + 360)."""
    if exit_ <= 360.0:
        return [(entry, exit_ - entry)]
    return [(entry, 360.0 - entry), (0.0, exit_ - 360.0)]


def _operation_colors(ops: list[str]) -> dict[str, tuple]:
    cmap = colormaps["tab10"] if len(ops) <= 10 else colormaps["tab20"]
    return {op: cmap(k % cmap.N) for k, op in enumerate(ops)}


def _no_data(ax, text: str, y: float = 0.5) -> None:  # type: ignore[no-untyped-def]
    ax.text(0.5, y, text, transform=ax.transAxes, ha="center", va="center", color="0.35", fontsize=11,
            bbox=dict(boxstyle="round,pad=0.3", fc="white", ec="0.8"), zorder=10)


# --------------------------------------------------------------------------------------------------
# engagement map of one CL


def plot_engagement_map(
    results: Results,
    cl: int,
    *,
    out: str | os.PathLike[str] | None = None,
    figsize: tuple[float, float] = (8.0, 5.0),
    dpi: float = 100.0,
) -> Figure:
    """Engaged immersion intervals of CL ``cl`` as horizontal bars: immersion angle (deg) vs height
    above the tool tip (mm). Arcs that run past 360° are drawn wrapped into [0, 360)."""
    row = results.row(cl)
    sl = results.slices_of(cl)
    fig = new_figure(figsize, dpi)
    ax = fig.add_subplot()

    # Immersion 180..360 is the half of the tool behind the feed direction: contact there means
    # back-cutting (or a plunge/ramp), worth seeing at a glance.
    ax.axvspan(180, 360, color="0.94", zorder=0)
    ax.text(270, 0.99, "rear half (φ > 180°)", transform=blended_transform_factory(ax.transData, ax.transAxes),
            ha="center", va="top", fontsize=8, color="0.45")

    if len(sl):
        lo, hi = _extents(sl, "z_tool_mm")
        for z0, z1, entry, exit_ in zip(lo, hi, sl["entry_deg"], sl["exit_deg"]):
            ax.broken_barh(_wrapped(float(entry), float(exit_)), (z0, z1 - z0),
                           facecolors=ARC_COLOR, edgecolors="none", alpha=0.85)
        margin = 0.5 * float(np.max(hi - lo))
        ax.set_ylim(max(0.0, float(lo.min()) - margin), float(hi.max()) + margin)
    else:
        _no_data(ax, f"no contact (status: {row['status']})")
        ax.set_ylim(0, 1)

    ax.set_xlim(0, 360)
    ax.set_xticks(np.arange(0, 361, 30))
    ax.set_xlabel("immersion angle φ (deg; 0 = +y of the feed frame, in the sense the teeth turn)")
    ax.set_ylabel("height above tool tip z (mm)")
    ax.grid(True, color="0.85", lw=0.6)
    ax.set_axisbelow(True)
    ax.set_title(f"{_cl_title(row)}\n{_cl_facts(row)}", fontsize=10)
    return _finish(fig, out)


# --------------------------------------------------------------------------------------------------
# polar top view of one CL


def plot_polar(
    results: Results,
    cl: int,
    *,
    radial: str = "z",
    out: str | os.PathLike[str] | None = None,
    figsize: tuple[float, float] = (7.0, 7.0),
    dpi: float = 100.0,
) -> Figure:
    """Top view (seen from +Z) of CL ``cl`` in the machine frame: the engaged arc of every slice,
    the tooth entry (green) and exit (red) lines and the feed direction (arrow).

    ``radial="z"`` puts each slice on its own ring at its height above the tip (mm), so slices of
    a cylindrical tool do not hide each other; ``radial="radius"`` draws them at the tool radius
    (true top view, useful for ball and tapered tools).
    """
    if radial not in ("z", "radius"):
        raise ValueError(f"radial must be 'z' or 'radius', got {radial!r}")
    row = results.row(cl)
    sl = results.slices_of(cl)
    fig = new_figure(figsize, dpi)
    ax = fig.add_subplot(projection="polar")
    ax.set_theta_zero_location("E")  # machine +X to the right
    ax.set_theta_direction(1)  # counter-clockwise, as seen from +Z

    spindle = SpindleDirection(str(row["spindle"]))
    feed_angle = float(row["feed_angle_machine_deg"])
    rcol = "z_tool_mm" if radial == "z" else "radius_mm"
    r_max = 1.0
    if len(sl):
        lo, hi = _extents(sl, rcol)
        r_max = float(hi.max()) + 0.5 * float(np.max(hi - lo))
        # colour: the arc's engaged angle in degrees, on a fixed 0-180 scale (a plunge's 360 at the
        # top); the radius already tells the height, and a fixed scale never degenerates
        norm = Normalize(0.0, POLAR_SPAN_MAX_DEG, clip=True)
        cmap = colormaps["viridis"]
        for (_, s), r0, r1 in zip(sl.iterrows(), lo, hi):
            span = float(s["exit_machine_deg"] - s["entry_machine_deg"])
            ax.bar(math.radians(float(s["entry_machine_deg"]) + span / 2), r1 - r0, width=math.radians(span),
                   bottom=r0, color=cmap(norm(span)), edgecolor="none", alpha=0.9)
            # where the tooth really enters/leaves depends on the spindle sense: go through the
            # immersion angles rather than guessing from the counter-clockwise machine bounds
            for phi, color in ((s["entry_deg"], ENTRY_COLOR), (s["exit_deg"], EXIT_COLOR)):
                a = math.radians(machine_from_immersion(float(phi), feed_angle, spindle))
                ax.plot([a, a], [r0, r1], color=color, lw=1.6)
        cb = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.7, pad=0.1, extend="max")
        cb.set_ticks(np.arange(0.0, POLAR_SPAN_MAX_DEG + 1, 45.0))
        cb.set_ticklabels([f"{d:.0f}°" for d in np.arange(0.0, POLAR_SPAN_MAX_DEG + 1, 45.0)])
        cb.set_label("engaged arc of the slice (°)")
    else:
        _no_data(ax, f"no contact (status: {row['status']})", y=0.3)  # below the feed arrow

    r_lim = r_max * 1.18
    ax.set_rlim(0, r_lim)
    ax.yaxis.set_major_locator(MaxNLocator(4))  # a few radial labels, apart from each other
    fa = math.radians(feed_angle)
    ax.annotate("", xy=(fa, r_lim * 0.98), xytext=(0, 0),
                arrowprops=dict(arrowstyle="-|>", color="black", lw=1.8, mutation_scale=18), zorder=5)
    # label beside the shaft rather than past the tip, where it would sit on the angle tick labels
    ax.text(fa + math.radians(7), r_lim * 0.8, "feed", ha="center", va="center", fontsize=10,
            fontweight="bold", bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.8))
    if radial == "radius" and len(sl):
        t = np.linspace(0, 2 * math.pi, 361)
        ax.plot(t, np.full_like(t, float(sl["radius_mm"].max())), color="0.5", lw=0.8, ls="--")

    ax.set_xticks(np.radians(np.arange(0, 360, 45)))
    ax.set_xticklabels([f"{d}°" for d in range(0, 360, 45)])
    # radial tick labels behind the tool (opposite the feed), where there is usually no contact
    ax.set_rlabel_position((feed_angle + 200.0) % 360.0)
    sense = "CW (M3)" if spindle == SpindleDirection.CW else "CCW (M4)"
    handles = [Line2D([], [], color=ENTRY_COLOR, lw=2, label="tooth entry"),
               Line2D([], [], color=EXIT_COLOR, lw=2, label="tooth exit"),
               Line2D([], [], color="black", lw=2, label=f"feed {feed_angle:.1f}° (machine)")]
    ax.legend(handles=handles, loc="lower left", bbox_to_anchor=(-0.12, -0.12), fontsize=8, frameon=False)
    rname = "slice height z (mm)" if radial == "z" else "tool radius (mm)"
    fig.suptitle(f"{_cl_title(row)}\n{_cl_facts(row)}\nmachine frame seen from +Z, angles CCW from +X; "
                 f"radius = {rname}; spindle {sense}", fontsize=9)
    return _finish(fig, out)


# --------------------------------------------------------------------------------------------------
# the whole program


def plot_program(
    results: Results,
    *,
    out: str | os.PathLike[str] | None = None,
    figsize: tuple[float, float] = (11.0, 6.0),
    dpi: float = 100.0,
) -> Figure:
    """Engagement along the program vs CL index, coloured per operation.

    Top: the immersion range [smallest entry, largest exit] of every CL in contact (deg), failed CLs
    marked with a cross. Bottom: ae (solid) and ap (dashed), mm.
    """
    cl = results.cl.sort_values("cl", kind="stable")
    fig = new_figure(figsize, dpi)
    ax1, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    ops = list(dict.fromkeys(cl["operation"]))
    colors = _operation_colors(ops)

    for op in ops:
        g = cl[cl["operation"] == op]
        c = colors[op]
        x = g["cl"].to_numpy()
        lo, hi = g["entry_min_deg"].to_numpy(), g["exit_max_deg"].to_numpy()
        hit = ~np.isnan(lo)
        # a band per run of CLs in contact: each CL covers [cl - 0.5, cl + 0.5], air CLs break it
        ax1.fill_between(x, np.where(hit, lo, 0), np.where(hit, hi, 0), where=hit, step="mid",
                         color=c, alpha=0.55, lw=0)
        ax1.step(x, np.where(hit, lo, np.nan), where="mid", color=c, lw=0.9)
        ax1.step(x, np.where(hit, hi, np.nan), where="mid", color=c, lw=0.9)
        ax2.plot(x, g["ae_mm"], color=c, lw=1.3, drawstyle="steps-mid")
        ax2.plot(x, g["ap_mm"], color=c, lw=1.3, ls="--", drawstyle="steps-mid")

    failed = cl[cl["status"] == "failed"]
    top = max(360.0, float(np.nanmax(cl["exit_max_deg"].to_numpy(dtype=float), initial=0.0)))
    if len(failed):
        ax1.plot(failed["cl"], np.full(len(failed), top * 0.98), "x", color=EXIT_COLOR, ms=7, mew=1.5)
    if cl["entry_min_deg"].isna().all():
        _no_data(ax1, "no contact in the results")

    ax1.set_ylim(0, top)
    ax1.set_yticks(np.arange(0, top + 1, 90))
    ax1.set_ylabel("immersion range\n[min entry, max exit] (deg)")
    ax1.grid(True, color="0.88", lw=0.6)
    ax1.set_axisbelow(True)
    ax2.set_ylabel("depth of cut (mm)")
    ax2.set_xlabel("CL index")
    ax2.grid(True, color="0.88", lw=0.6)
    ax2.set_ylim(bottom=0)

    op_handles = [Patch(color=colors[op], label=op or "(no operation)") for op in ops]
    if len(failed):
        op_handles.append(Line2D([], [], ls="", marker="x", color=EXIT_COLOR, label="failed CL"))
    # legends outside the axes: the data reaches every corner of these panels
    ax1.legend(handles=op_handles, title="operation", loc="upper left", bbox_to_anchor=(1.01, 1.0),
               fontsize=8, title_fontsize=8, frameon=False)
    ax2.legend(handles=[Line2D([], [], color="0.2", label="ae (radial)"),
                        Line2D([], [], color="0.2", ls="--", label="ap (axial)")],
               loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    files = list(dict.fromkeys(cl["file"]))
    src = files[0] if len(files) == 1 else f"{len(files)} files"
    fig.suptitle(f"Engagement over the program — {src} ({len(cl)} CLs)", fontsize=11)
    return _finish(fig, out)


# --------------------------------------------------------------------------------------------------
# heat map CL x height


def engaged_span_grid(
    results: Results, *, max_columns: int = 2000, max_rows: int = 200
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Engaged span (deg, summed over the arcs of a slice) on a CL x height grid.

    Returns ``(cl_edges, z_edges, span)`` with ``span[row, col]`` (rows: heights above the tip in mm,
    columns: CL index); cells without contact are 0. Every CL gets its own column unless there are
    more than ``max_columns``; then neighbouring CLs share one and a cell holds the largest span.

    A slice fills the rows whose centres lie in its recorded band ``[z_lo_mm, z_hi_mm]``, and at
    least the row holding its height; rows are as tall as the thinnest band (at most ``max_rows``
    rows). Slices of folders that do not record the bands fill only the row holding their height.
    """
    cls = results.cl["cl"].to_numpy()
    sl = results.slices
    if not len(cls):
        return np.array([-0.5, 0.5]), np.array([0.0, 1.0]), np.zeros((1, 1))
    lo, hi = int(cls.min()), int(cls.max())
    n_x = max(1, min(hi - lo + 1, max_columns))
    x_edges = np.linspace(lo - 0.5, hi + 0.5, n_x + 1)
    if not len(sl):
        return x_edges, np.array([0.0, 1.0]), np.zeros((1, n_x))

    ps = (sl.assign(span=sl["exit_deg"] - sl["entry_deg"])
          .groupby(["cl", "z_tool_mm"], as_index=False)
          .agg(span=("span", "sum"), z_lo=("z_lo_mm", "first"), z_hi=("z_hi_mm", "first")))
    z = ps["z_tool_mm"].to_numpy(dtype=float)
    z_lo, z_hi = ps["z_lo"].fillna(ps["z_tool_mm"]).to_numpy(), ps["z_hi"].fillna(ps["z_tool_mm"]).to_numpy()

    bottom, top = float(z_lo.min()), float(z_hi.max())
    if top - bottom < 1e-9:
        bottom, top = bottom - 0.5, top + 0.5
    thick = z_hi - z_lo
    finest = float(thick[thick > 1e-9].min()) if (thick > 1e-9).any() else (top - bottom) / max_rows
    n_rows = int(min(max_rows, max(1, math.ceil((top - bottom) / finest - 1e-9))))
    z_edges = np.linspace(bottom, top, n_rows + 1)
    dz = (top - bottom) / n_rows
    # rows whose centre lies in the band; at least the row holding z itself, so that a band
    # thinner than a row (binned heights) still shows
    centre0 = bottom + 0.5 * dz
    r_lo = np.ceil((z_lo - centre0) / dz - 1e-9).astype(int)
    r_hi = np.floor((z_hi - centre0) / dz - 1e-9).astype(int) + 1
    r_z = np.clip(((z - bottom) / dz).astype(int), 0, n_rows - 1)
    r_lo = np.clip(np.minimum(r_lo, r_z), 0, n_rows - 1)
    r_hi = np.clip(np.maximum(r_hi, r_z + 1), 1, n_rows)
    col = np.clip(np.searchsorted(x_edges, ps["cl"].to_numpy(), side="right") - 1, 0, n_x - 1)

    counts = r_hi - r_lo
    idx = np.repeat(np.arange(len(z)), counts)
    # row numbers r_lo[i], r_lo[i]+1, ... for each slice i, without a Python loop
    rows = r_lo[idx] + (np.arange(len(idx)) - np.repeat(np.cumsum(counts) - counts, counts))
    grid = np.zeros((n_rows, n_x))
    np.maximum.at(grid, (rows, col[idx]), ps["span"].to_numpy()[idx])
    return x_edges, z_edges, grid


def plot_heatmap(
    results: Results,
    *,
    out: str | os.PathLike[str] | None = None,
    figsize: tuple[float, float] = (11.0, 5.0),
    dpi: float = 100.0,
    max_columns: int = 2000,
    max_rows: int = 200,
) -> Figure:
    """Heat map of the engaged span (immersion deg) per CL (x) and height above the tool tip (y, mm).

    Cells without contact are left blank (grey background); operation boundaries are dashed lines.
    """
    x_edges, z_edges, grid = engaged_span_grid(results, max_columns=max_columns, max_rows=max_rows)
    fig = new_figure(figsize, dpi)
    ax = fig.add_subplot()
    ax.set_facecolor("0.93")
    masked = np.ma.masked_less_equal(grid, 0.0)
    if masked.count():
        vmax = max(180.0, float(masked.max()))
        mesh = ax.pcolormesh(x_edges, z_edges, masked, cmap="magma_r", vmin=0, vmax=vmax, shading="flat")
        cb = fig.colorbar(mesh, ax=ax, pad=0.01)
        cb.set_label("engaged span (deg, immersion)")
    else:
        _no_data(ax, "no contact in the results")
    ax.set_xlim(x_edges[0], x_edges[-1])
    ax.set_ylim(z_edges[0], z_edges[-1])

    # operation boundaries: where the operation changes along the program
    cl = results.cl.sort_values("cl", kind="stable")
    ops = cl["operation"].to_numpy()
    starts = [0] + [k for k in range(1, len(ops)) if ops[k] != ops[k - 1]]
    trans = blended_transform_factory(ax.transData, ax.transAxes)
    width = x_edges[-1] - x_edges[0]
    for k, nxt in zip(starts, starts[1:] + [len(ops)]):
        x = float(cl["cl"].iloc[k]) - 0.5
        if k:
            ax.axvline(x, color="0.3", ls="--", lw=0.8)
        x_end = float(cl["cl"].iloc[nxt - 1]) + 0.5
        # name an operation only where it has room, so short ones do not print over each other
        if ops[k] and (x_end - x) >= 0.06 * width:
            ax.text(x, 1.01, f" {ops[k]}", transform=trans, ha="left", va="bottom", fontsize=8, color="0.25")
    ax.set_xlabel("CL index")
    ax.set_ylabel("height above tool tip z (mm)")
    n_cl = int(cl["cl"].max() - cl["cl"].min() + 1) if len(cl) else 0
    binned = f" ({n_cl} CLs in {len(x_edges) - 1} columns, max per cell)" if len(x_edges) - 1 < n_cl else ""
    ax.set_title(f"Engaged span per slice{binned}", fontsize=11, pad=14)
    return _finish(fig, out)


PLOTS = {"map": plot_engagement_map, "polar": plot_polar, "program": plot_program, "heatmap": plot_heatmap}

__all__ = [
    "PLOTS", "engaged_span_grid", "new_figure", "plot_engagement_map", "plot_heatmap", "plot_polar",
    "plot_program", "save_figure",
]


# --------------------------------------------------------------------------------------------------
# cutting forces and feed advice along the program (tables of fusioncut.analysis)


def _table_of(data: object) -> pd.DataFrame:
    """The per-CL DataFrame of a forces table, a feed advice table, or an object holding one (``.table``)."""
    table = getattr(data, "table", data)
    if not isinstance(table, pd.DataFrame):
        raise TypeError(f"expected a DataFrame or an object with a .table DataFrame, got {type(data).__name__}")
    return table.sort_values("cl", kind="stable")


def plot_forces(
    table: object,
    *,
    frame: str = "feed",
    out: str | os.PathLike[str] | None = None,
    figsize: tuple[float, float] = (11.0, 6.5),
    dpi: float = 100.0,
) -> Figure:
    """Cutting forces along the program vs CL index, from a forces table
    (:func:`fusioncut.analysis.forces.forces_table`, or ``forces.csv`` written by ``fusioncut forces``).

    Top: peak (solid) and mean (dashed) resultant ``|F|`` and the peak ``|Fx|, |Fy|, |Fz|`` (N) in the
    ``feed`` frame (x along the feed) or the ``machine`` frame. Bottom: peak and mean spindle cutting
    power (W). CLs whose forces are unknown (rapids, failed CLs) are gaps; failed CLs are marked.
    """
    if frame not in ("feed", "machine"):
        raise ValueError(f"frame must be 'feed' or 'machine', got {frame!r}")
    t = _table_of(table)
    suffix = "" if frame == "feed" else "_machine"
    x = t["cl"].to_numpy()
    fig = new_figure(figsize, dpi)
    ax1, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    ax1.plot(x, t["resultant_peak_N"], color="black", lw=1.4, drawstyle="steps-mid", label="|F| peak", gid="resultant_peak")
    ax1.plot(x, t["resultant_mean_N"], color="black", lw=1.0, ls="--", drawstyle="steps-mid", label="|F| mean",
             gid="resultant_mean")
    for axis, color in zip("xyz", ("#1b9e77", "#d95f02", "#7570b3")):
        col = f"f{axis}{suffix}_peak_N"
        ax1.plot(x, t[col], color=color, lw=0.9, drawstyle="steps-mid", label=f"|F{axis}| peak", gid=col)
    ax2.plot(x, t["power_peak_W"], color=ARC_COLOR, lw=1.2, drawstyle="steps-mid", label="peak", gid="power_peak")
    ax2.plot(x, t["power_mean_W"], color=ARC_COLOR, lw=1.0, ls="--", drawstyle="steps-mid", label="mean",
             gid="power_mean")
    failed = t[t["status"].astype("string") == "failed"]
    if len(failed):
        ax1.plot(failed["cl"], np.zeros(len(failed)), "x", color=EXIT_COLOR, ms=7, mew=1.5, label="failed CL (unknown)")
    if not np.isfinite(t["resultant_peak_N"].to_numpy(dtype=float)).any():
        _no_data(ax1, "no forces known (no engaged CL with a feed and a spindle speed)")
    ax1.set_ylabel("force on the tool (N)")
    ax1.set_ylim(bottom=0)
    ax2.set_ylabel("spindle cutting power (W)")
    ax2.set_ylim(bottom=0)
    ax2.set_xlabel("CL index")
    for ax in (ax1, ax2):
        ax.grid(True, color="0.88", lw=0.6)
        ax.set_axisbelow(True)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    where = "feed frame: x along the feed, z up the tool" if frame == "feed" else "machine frame"
    fig.suptitle(f"Cutting forces along the program ({len(t)} CLs; {where})", fontsize=11)
    return _finish(fig, out)


_QUANTITY_LABELS = {
    "force": ("force_peak", "N", "peak resultant force |F| (N)"),
    "chip": ("chip_peak", "mm", "peak chip thickness (mm)"),
    "power": ("power_peak", "W", "peak cutting power (W)"),
    "mrr": ("mrr", "mm3_min", "material removal rate (mm³/min)"),
}


def plot_feed_advice(
    advice: object,
    *,
    quantity: str | None = None,
    limit: float | None = None,
    out: str | os.PathLike[str] | None = None,
    figsize: tuple[float, float] = (11.0, 6.5),
    dpi: float = 100.0,
) -> Figure:
    """Programmed vs advised feed along the program vs CL index, from a
    :class:`~fusioncut.analysis.feed.FeedAdvice` (or its ``table``).

    Top: programmed (grey) and advised (blue) feed (mm/min); CLs whose advice comes from a limit
    that cannot be met (note ``unreachable``) are marked. Bottom: ``quantity`` (``force``, ``chip``,
    ``power`` or ``mrr``; default: the advice's first limit) at the programmed and at the advised
    feed, with the limit as a red line (``limit`` defaults to the advice's). Rapids are gaps.
    """
    t = _table_of(advice)
    lim_obj = getattr(advice, "limit", None)
    if quantity is None:
        active = getattr(lim_obj, "active", ()) or ("force",)
        quantity = active[0]
    if quantity not in _QUANTITY_LABELS:
        raise ValueError(f"quantity must be one of {', '.join(_QUANTITY_LABELS)}, got {quantity!r}")
    if limit is None and lim_obj is not None:
        limit = lim_obj.value(quantity)
    stem, unit, label = _QUANTITY_LABELS[quantity]
    x = t["cl"].to_numpy()
    fig = new_figure(figsize, dpi)
    ax1, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    ax1.plot(x, t["programmed_feed_mm_min"], color="0.45", lw=1.6, drawstyle="steps-mid", label="programmed",
             gid="programmed_feed")
    ax1.plot(x, t["advised_feed_mm_min"], color=ARC_COLOR, lw=1.3, drawstyle="steps-mid", label="advised",
             gid="advised_feed")
    bad = t[t["note"].astype("string").str.contains("unreachable", regex=False).fillna(False)]
    if len(bad):
        ax1.plot(bad["cl"], bad["advised_feed_mm_min"], "v", color=EXIT_COLOR, ms=5, label="limit unreachable",
                 gid="unreachable")
    ax2.plot(x, t[f"{stem}_programmed_{unit}"], color="0.45", lw=1.2, drawstyle="steps-mid", label="at programmed feed",
             gid=f"{quantity}_programmed")
    ax2.plot(x, t[f"{stem}_advised_{unit}"], color=ARC_COLOR, lw=1.2, drawstyle="steps-mid", label="at advised feed",
             gid=f"{quantity}_advised")
    if limit is not None:
        ax2.axhline(limit, color=EXIT_COLOR, lw=1.2, ls="--", label=f"limit {limit:g}", gid="limit")
    ax1.set_ylabel("feed (mm/min)")
    ax1.set_ylim(bottom=0)
    ax2.set_ylabel(label)
    ax2.set_ylim(bottom=0)
    ax2.set_xlabel("CL index")
    for ax in (ax1, ax2):
        ax.grid(True, color="0.88", lw=0.6)
        ax.set_axisbelow(True)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    feeds = t[["length_mm", "programmed_feed_mm_min", "advised_feed_mm_min"]].to_numpy(dtype=float)
    ok = np.isfinite(feeds).all(axis=1) & (feeds[:, 1] > 0) & (feeds[:, 2] > 0)
    t_prog = float(np.sum(feeds[ok, 0] / feeds[ok, 1])) * 60.0
    t_adv = float(np.sum(feeds[ok, 0] / feeds[ok, 2])) * 60.0
    fig.suptitle(f"Feed advice along the program ({len(t)} CLs) — feed time {t_prog:.1f} s programmed, "
                 f"{t_adv:.1f} s advised", fontsize=11)
    return _finish(fig, out)


PLOTS_ANALYSIS = {"forces": plot_forces, "feed": plot_feed_advice}

__all__ += ["PLOTS_ANALYSIS", "plot_feed_advice", "plot_forces"]
