"""Plots drawn from saved results: files, pixel sizes, SVG validity, and that what is drawn is right."""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import matplotlib.image as mpimg
import numpy as np
import pytest
import typer
from matplotlib.colors import to_rgba
from typer.testing import CliRunner

from fusioncut.cli import plot as plot_cli
from fusioncut.engines.base import EngineOptions
from fusioncut.errors import FusionCutError, SourceLocation
from fusioncut.io.results import ResultWriter, load_results
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, SliceEngagement, SpindleDirection
from fusioncut.viz import plots
from fusioncut.viz.plots import (
    ENTRY_COLOR,
    EXIT_COLOR,
    engaged_span_grid,
    plot_engagement_map,
    plot_heatmap,
    plot_polar,
    plot_program,
)


DZ = 0.5  # the run's slice height, mm


def em(i: int, intervals, *, op: str, top: float = 2.0, status=CLStatus.ENGAGED,
       spindle=SpindleDirection.CW, feed_angle: float = 0.0) -> EngagementMap:
    """A map as the engine slices it: contact 0 .. ``top`` mm, a slice in the middle of each band
    [k, k+1) * DZ clipped to the contact (``top`` 1.8: the last band is 1.5 .. 1.8, its slice at 1.65)."""
    bands = [(k * DZ, min((k + 1) * DZ, top)) for k in range(math.ceil(top / DZ - 1e-9))]
    sl = tuple(SliceEngagement(z=0.5 * (lo + hi), z_machine=-5 + 0.5 * (lo + hi), radius=4.0,
                               intervals=tuple(AngleInterval(a, b) for a, b in intervals or ())) for lo, hi in bands)
    return EngagementMap(
        cl_index=i, position=(float(i), 0.0, -5.0), start=(i - 1.0, 0.0, -5.0), tool="T3", spindle=spindle,
        feed_angle=feed_angle, status=status, source=SourceLocation("job/part.nc", 40 + i, 1), feed=500.0,
        operation=op, slices=sl if intervals else (), removed_volume=0.5 if intervals else 0.0,
        axial_range=(0.0, top) if intervals else (0.0, 0.0),
    )


@pytest.fixture(scope="module")
def results_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("results")
    ems = [em(0, None, op="rough", status=CLStatus.RAPID)]
    ems += [em(i, [(0.0, 60.0)], op="rough") for i in range(1, 6)]  # up-milling, 4 slices 0.5 mm apart
    ems += [em(6, None, op="rough", status=CLStatus.FAILED)]
    ems += [em(i, [(330.0, 370.0)], op="finish", top=1.8, spindle=SpindleDirection.CCW, feed_angle=90.0)
            for i in range(7, 10)]
    with ResultWriter(d, batch_size=4, options=EngineOptions(slice_height=DZ)) as w:
        for e in ems:
            w.add(e)
    return d


@pytest.fixture(scope="module")
def results(results_dir):
    return load_results(results_dir)


ALL = [
    ("map", lambda r, **kw: plot_engagement_map(r, 2, **kw)),
    ("polar", lambda r, **kw: plot_polar(r, 8, **kw)),
    ("program", plot_program),
    ("heatmap", plot_heatmap),
]


@pytest.mark.parametrize("kind,fn", ALL, ids=[k for k, _ in ALL])
def test_png_has_requested_size(tmp_path, results, kind, fn):
    # an awkward size: figsize * dpi must come out exactly, without a tight-bbox crop
    out = tmp_path / f"{kind}.png"
    fig = fn(results, out=out, figsize=(6.43, 4.17), dpi=100)
    assert out.stat().st_size > 0
    img = mpimg.imread(out)
    assert img.shape[:2] == (417, 643)
    assert img[..., :3].std() > 0.05  # not a blank canvas
    assert fig.get_size_inches().tolist() == [6.43, 4.17]


@pytest.mark.parametrize("kind,fn", ALL, ids=[k for k, _ in ALL])
def test_svg_is_xml(tmp_path, results, kind, fn):
    out = tmp_path / f"{kind}.svg"
    fn(results, out=out, figsize=(5, 4), dpi=72)
    root = ET.parse(out).getroot()
    assert root.tag == "{http://www.w3.org/2000/svg}svg"
    assert root.get("width") == "360pt" and root.get("height") == "288pt"


def test_titles_name_cl_and_source(results):
    fig = plot_engagement_map(results, 2)
    title = fig.axes[0].get_title()
    assert "CL 2" in title and "job/part.nc:42" in title and "rough" in title and "T3" in title
    fig = plot_polar(results, 8)
    assert "CL 8" in fig.get_suptitle() and "job/part.nc:48" in fig.get_suptitle()
    assert "spindle CCW" in fig.get_suptitle()
    assert "(°)" in fig.axes[1].get_ylabel()  # colour bar of the engaged arcs, in degrees
    fig = plot_program(results)
    assert "(deg)" in fig.axes[0].get_ylabel() and "(mm)" in fig.axes[1].get_ylabel()
    assert fig.axes[1].get_xlabel() == "CL index"


def _lines_of_color(ax, color) -> list[np.ndarray]:
    want = to_rgba(color)
    return [np.asarray(ln.get_xdata(), dtype=float) for ln in ax.get_lines() if to_rgba(ln.get_color()) == want]


def test_polar_entry_exit_in_machine_frame(results):
    # CW spindle, feed +X, immersion (0, 60): the tooth enters at machine 90 deg and leaves at 30 deg
    ax = plot_polar(results, 2).axes[0]
    entries, exits = _lines_of_color(ax, ENTRY_COLOR), _lines_of_color(ax, EXIT_COLOR)
    assert len(entries) == len(exits) == 4  # one per slice
    assert all(np.allclose(x, math.radians(90.0)) for x in entries)
    assert all(np.allclose(x, math.radians(30.0)) for x in exits)
    # CCW spindle, feed +Y: machine = immersion, so (330, 370) enters at 330 and leaves at 10
    ax = plot_polar(results, 8).axes[0]
    assert all(np.allclose(x, math.radians(330.0)) for x in _lines_of_color(ax, ENTRY_COLOR))
    assert all(np.allclose(x, math.radians(10.0)) for x in _lines_of_color(ax, EXIT_COLOR))
    # the engaged arcs: 4 slices, each a 40 deg bar centred on machine 350 deg, a ring over its band
    bars = [p for p in ax.patches if p.get_width() > 0]
    assert len(bars) == 4
    assert all(math.isclose(p.get_width(), math.radians(40.0)) for p in bars)
    rings = sorted((round(p.get_y(), 12), round(p.get_y() + p.get_height(), 12)) for p in bars)
    assert rings == [(0.0, 0.5), (0.5, 1.0), (1.0, 1.5), (1.5, 1.8)]


def test_polar_true_radius_view(results):
    ax = plot_polar(results, 2, radial="radius").axes[0]
    bars = [p for p in ax.patches if p.get_width() > 0]
    assert all(math.isclose(p.get_y() + p.get_height() / 2, 4.0) for p in bars)  # drawn at the tool radius
    with pytest.raises(ValueError):
        plot_polar(results, 2, radial="diameter")


def test_engagement_map_wraps_arcs_past_360(results):
    ax = plot_engagement_map(results, 8).axes[0]
    pieces = sorted(tuple(map(float, seg)) for coll in ax.collections for seg in _barh_segments(coll))
    # (330, 370) is drawn as 330..360 and 0..10 on each of the 4 slices
    assert pieces.count((0.0, 10.0)) == 4 and pieces.count((330.0, 30.0)) == 4
    assert ax.get_xlim() == (0.0, 360.0)
    # each bar covers its slice's band: the clipped top band 1.5 .. 1.8 mm too
    heights = sorted({(round(float(p.vertices[:, 1].min()), 12), round(float(p.vertices[:, 1].max()), 12))
                      for coll in ax.collections for p in coll.get_paths()})
    assert heights == [(0.0, 0.5), (0.5, 1.0), (1.0, 1.5), (1.5, 1.8)]


def _barh_segments(coll):
    for path in coll.get_paths():
        v = path.vertices
        yield (v[:, 0].min(), v[:, 0].max() - v[:, 0].min())


def test_heatmap_grid_values(results):
    x_edges, z_edges, grid = engaged_span_grid(results)
    assert len(x_edges) - 1 == 10  # one column per CL 0..9
    col = lambda cl: int(np.searchsorted(x_edges, cl) - 1)  # noqa: E731
    assert grid[:, col(0)].max() == 0 and grid[:, col(6)].max() == 0  # rapid and failed: no contact
    assert grid[:, col(3)].max() == 60.0 and grid[:, col(8)].max() == 40.0
    # CL 3 is engaged over its 4 bands (z 0..2), CL 8 over 0..1.8 (its top band clipped to 1.5..1.8)
    centres = 0.5 * (z_edges[1:] + z_edges[:-1])
    assert z_edges[0] == pytest.approx(0.0) and z_edges[-1] == pytest.approx(2.0)
    assert len(centres) >= 2.0 / 0.3  # rows as fine as the thinnest band
    assert (grid[:, col(3)] == 60.0).all()
    np.testing.assert_array_equal(grid[:, col(8)], np.where(centres < 1.8, 40.0, 0.0))
    # binned: 10 CLs into 3 columns keep the largest span of each
    x3, _, g3 = engaged_span_grid(results, max_columns=3)
    assert len(x3) == 4 and g3.max() == 60.0 and g3.shape[1] == 3


def test_plots_work_from_csv(tmp_path, results_dir):
    r = load_results(results_dir, prefer="csv")
    plot_heatmap(r, out=tmp_path / "h.png", figsize=(4, 3), dpi=50)
    plot_polar(r, 3, out=tmp_path / "p.png", figsize=(4, 4), dpi=50)
    assert mpimg.imread(tmp_path / "p.png").shape[:2] == (200, 200)


def test_no_contact_cl_and_bad_inputs(tmp_path, results):
    for fn in (plot_engagement_map, plot_polar):
        texts = " ".join(t.get_text() for t in fn(results, 0).axes[0].texts)
        assert "no contact (status: rapid)" in texts
    with pytest.raises(FusionCutError, match="CL 42"):
        plot_engagement_map(results, 42)
    with pytest.raises(ValueError, match="unsupported plot format"):
        plot_program(results, out=tmp_path / "x.jpg")


@pytest.fixture(scope="module")
def cli_app():
    # only this command, so other modules of the CLI being edited do not affect these tests
    app = typer.Typer()
    app.callback()(lambda: None)  # keep "plot" a sub-command
    plot_cli.register(app)
    return app


def test_cli_plot(tmp_path, results_dir, cli_app):
    runner = CliRunner()
    out = tmp_path / "m.png"
    r = runner.invoke(cli_app, ["plot", str(results_dir), "--kind", "map", "--cl", "3", "--out", str(out),
                                "--width", "640", "--height", "400"])
    assert r.exit_code == 0, r.output
    assert mpimg.imread(out).shape[:2] == (400, 640)
    out = tmp_path / "h.svg"
    r = runner.invoke(cli_app, ["plot", str(results_dir), "--kind", "heatmap", "--out", str(out)])
    assert r.exit_code == 0, r.output
    ET.parse(out)


@pytest.mark.parametrize("name,args,message", [
    ("x.png", ["--kind", "polar"], "--cl"),
    ("x.png", ["--kind", "map", "--cl", "77"], "CL 77 is not in the results"),
    ("x.pdf", ["--kind", "program"], "unsupported plot format"),
])
def test_cli_plot_errors(tmp_path, results_dir, cli_app, name, args, message):
    # one clear line and exit code 2, no traceback and no file
    r = CliRunner().invoke(cli_app, ["plot", str(results_dir), "--out", str(tmp_path / name), *args])
    assert r.exit_code == 2
    assert message in r.output and "Traceback" not in r.output
    assert not (tmp_path / name).exists()


def test_cli_missing_results(tmp_path, cli_app):
    r = CliRunner().invoke(cli_app, ["plot", str(tmp_path / "nope"), "--kind", "program", "--out",
                                     str(tmp_path / "x.png")])
    assert r.exit_code == 2 and "not found" in r.output


def test_plot_registry_matches_cli_kinds():
    assert set(plots.PLOTS) == {k.value for k in plot_cli.PlotKind}


# --------------------------------------------------------------------------------------------------
# forces and feed advice along the program (tables of fusioncut.analysis)


@pytest.fixture(scope="module")
def force_maps():
    from fusioncut.model import FlatEndMill

    tool = FlatEndMill(diameter=8.0, flute_length=20.0, flutes=3, helix_angle=30.0)
    ems = [em(0, None, op="rough", status=CLStatus.RAPID)]
    ems += [em(i, [(0.0, 60.0 + 20 * i)], op="rough") for i in range(1, 6)]
    ems += [em(6, None, op="rough", status=CLStatus.FAILED)]
    ems += [em(i, [(0.0, 180.0)], op="finish") for i in range(7, 10)]
    return tool, ems


def _line(ax, gid):
    (ln,) = [ln for ln in ax.get_lines() if ln.get_gid() == gid]
    return ln


def test_plot_forces_draws_the_table(tmp_path, force_maps):
    from fusioncut.analysis.forces import forces_table
    from fusioncut.analysis.materials import AL7075_T6_CARBIDE

    tool, ems = force_maps
    table = forces_table(ems, tool, AL7075_T6_CARBIDE, 8000.0, dz=0.5)
    out = tmp_path / "f.png"
    fig = plots.plot_forces(table, out=out, figsize=(6.4, 4.0), dpi=100)
    assert mpimg.imread(out).shape[:2] == (400, 640)
    ax1, ax2 = fig.axes[:2]
    np.testing.assert_array_equal(_line(ax1, "resultant_peak").get_ydata(), table["resultant_peak_N"])
    np.testing.assert_array_equal(_line(ax1, "fy_peak_N").get_ydata(), table["fy_peak_N"])
    np.testing.assert_array_equal(_line(ax2, "power_mean").get_ydata(), table["power_mean_W"])
    assert np.isnan(_line(ax1, "resultant_peak").get_ydata()[[0, 6]]).all()  # rapid, failed: unknown
    assert "(N)" in ax1.get_ylabel() and "(W)" in ax2.get_ylabel()
    # the machine frame uses the machine columns
    fig = plots.plot_forces(table, frame="machine")
    np.testing.assert_array_equal(_line(fig.axes[0], "fx_machine_peak_N").get_ydata(), table["fx_machine_peak_N"])
    with pytest.raises(ValueError, match="frame"):
        plots.plot_forces(table, frame="tool")


def test_plot_feed_advice_draws_feeds_and_the_limit(tmp_path, force_maps):
    from fusioncut.analysis.feed import FeedLimit, advise_feeds
    from fusioncut.analysis.materials import AL7075_T6_CARBIDE

    tool, ems = force_maps
    advice = advise_feeds(ems, tool, AL7075_T6_CARBIDE, FeedLimit(max_force=120.0, max_feed=900.0), rpm=8000.0,
                          dz=0.5)
    out = tmp_path / "a.svg"
    fig = plots.plot_feed_advice(advice, out=out, figsize=(5, 4), dpi=72)
    ET.parse(out)
    ax1, ax2 = fig.axes[:2]
    t = advice.table
    np.testing.assert_array_equal(_line(ax1, "advised_feed").get_ydata(), t["advised_feed_mm_min"])
    np.testing.assert_array_equal(_line(ax1, "programmed_feed").get_ydata(), t["programmed_feed_mm_min"])
    np.testing.assert_array_equal(_line(ax2, "force_advised").get_ydata(), t["force_peak_advised_N"])
    assert list(_line(ax2, "limit").get_ydata()) == [120.0, 120.0]
    assert "feed time" in fig.get_suptitle()
    # another quantity, from the bare table with an explicit limit
    fig = plots.plot_feed_advice(t, quantity="chip", limit=0.05)
    assert list(_line(fig.axes[1], "limit").get_ydata()) == [0.05, 0.05]
    with pytest.raises(ValueError, match="quantity"):
        plots.plot_feed_advice(t, quantity="torque")
    with pytest.raises(TypeError):
        plots.plot_feed_advice([1, 2, 3])


def test_folders_without_bands_mark_slices_without_claiming_their_reach(tmp_path):
    """Results written without the slice height (older folders) have no bands: each slice is a thin
    mark at its height and fills one heat map row, instead of a band guessed from its neighbours."""
    with ResultWriter(tmp_path) as w:
        w.add(em(3, [(0.0, 60.0)], op="rough"))
    r = load_results(tmp_path)
    assert r.slices["z_lo_mm"].isna().all()
    _, z_edges, grid = engaged_span_grid(r)
    rows = np.flatnonzero(grid[:, 0])
    assert len(rows) == 4  # one row per slice, at its height
    assert all(z_edges[k] <= z <= z_edges[k + 1] for k, z in zip(rows, [0.25, 0.75, 1.25, 1.75]))
    ax = plot_engagement_map(r, 3).axes[0]
    spans = [float(np.ptp(p.vertices[:, 1])) for coll in ax.collections for p in coll.get_paths()]
    assert len(spans) == 4 and max(spans) == pytest.approx(0.04 * 1.75)
