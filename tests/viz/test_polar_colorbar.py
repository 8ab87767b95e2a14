"""The polar plot's colour bar reads in degrees (the engaged arc of each slice), also for a CL with a
single slice, where a scale of slice heights collapsed to one value (its labels read
"1e−13+2.5e−1")."""
from __future__ import annotations

import math

import pytest
from matplotlib import colormaps
from matplotlib.colors import to_rgba

from fusioncut.errors import SourceLocation
from fusioncut.io.results import ResultWriter, load_results
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, SliceEngagement, SpindleDirection
from fusioncut.viz.plots import POLAR_SPAN_MAX_DEG, plot_polar


def _map(i: int, intervals: list[tuple[float, float]], zs: list[float]) -> EngagementMap:
    # heights as posts write coordinates (3 decimals)
    sl = tuple(SliceEngagement(z=z, z_machine=-2.0 + z, radius=3.0,
                               intervals=tuple(AngleInterval(a, b) for a, b in intervals)) for z in zs)
    return EngagementMap(
        cl_index=i, position=(10.125, 4.0, -2.0), start=(9.125, 4.0, -2.0), tool="T1",
        spindle=SpindleDirection.CW, feed_angle=0.0, status=CLStatus.ENGAGED,
        source=SourceLocation("part.nc", 10 + i, 1), feed=600.0, operation="slot", slices=sl,
        removed_volume=1.0, axial_range=(0.0, max(zs) + 0.25))


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    d = tmp_path_factory.mktemp("polar")
    with ResultWriter(d) as w:
        w.add(_map(0, [(0.0, 60.0)], [0.25]))  # one slice: the case that read 1e-13+2.5e-1
        w.add(_map(1, [(0.0, 180.0)], [0.25, 0.75, 1.25]))
    return load_results(d)


def _colorbar(fig):
    return fig.axes[1]


@pytest.mark.parametrize("cl", [0, 1])
def test_colour_bar_reads_degrees(results, cl):
    fig = plot_polar(results, cl)
    fig.canvas.draw()
    cb = _colorbar(fig)
    labels = [t.get_text() for t in cb.get_yticklabels() if t.get_text()]
    assert labels == ["0°", "45°", "90°", "135°", "180°"]
    assert cb.yaxis.get_offset_text().get_text() == ""
    assert "(°)" in cb.get_ylabel()


def test_arc_colour_is_its_span(results):
    ax = plot_polar(results, 0).axes[0]
    bars = [p for p in ax.patches if p.get_width() > 0]
    assert len(bars) == 1 and math.isclose(bars[0].get_width(), math.radians(60.0))
    want = colormaps["viridis"](60.0 / POLAR_SPAN_MAX_DEG)
    assert bars[0].get_facecolor()[:3] == pytest.approx(to_rgba(want)[:3], abs=1e-6)


def test_radial_labels_are_few(results):
    fig = plot_polar(results, 1)
    fig.canvas.draw()
    shown = [t for t in fig.axes[0].get_yticklabels() if t.get_text()]
    assert 2 <= len(shown) <= 5
