"""``forces``, ``stability`` and ``advise`` take each CL's spindle speed, the tools and the slice height
from what the results folder records (no program, no --rpm/--flutes/--slice-height), and the options
override or, for older folders, supply them."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import typer
from typer.testing import CliRunner

from fusioncut.analysis.dynamics import read_modes_json
from fusioncut.analysis.forces import forces_table
from fusioncut.analysis.materials import AL7075_T6_CARBIDE as AL
from fusioncut.analysis.stability_table import stability_table
from fusioncut.engines.base import EngineOptions
from fusioncut.errors import SourceLocation
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement, SpindleDirection

MODES = Path(__file__).parents[2] / "docs" / "stability_modes_example.json"
TOOL = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=4, helix_angle=35.0)
RPM = [9000.0, 12000.0, 12000.0]


def write_results(out: Path) -> list[EngagementMap]:
    """Three 2 mm CLs in 0.5 mm slices (a slot, half and quarter immersion) at two recorded speeds, the
    tool's full record and the engine's slice height 0.5 mm."""
    def cl(i: int, arc: tuple[float, float]) -> EngagementMap:
        sl = tuple(SliceEngagement(0.25 + 0.5 * k, -1.75 + 0.5 * k, 5.0, (AngleInterval(*arc),)) for k in range(4))
        return EngagementMap(i, (i + 1.0, 0, -2.0), (float(i), 0, -2.0), "T1", SpindleDirection.CW, 0.0,
                             CLStatus.ENGAGED, source=SourceLocation("p.nc", 10 + i), feed=800.0, operation="op",
                             slices=sl, axial_range=(0.0, 2.0))

    from fusioncut.io.results import ResultWriter

    maps = [cl(0, (0.0, 180.0)), cl(1, (90.0, 180.0)), cl(2, (135.0, 180.0))]
    with ResultWriter(out, tools={"T1": TOOL}, options=EngineOptions(slice_height=0.5)) as w:
        for m, n in zip(maps, RPM):
            w.add(m, length_mm=1.0, spindle_rpm=n)
    return maps


def invoke(*args: str):
    from fusioncut.cli.forces import register as forces_commands
    from fusioncut.cli.stability import register as stability_command

    app = typer.Typer()
    forces_commands(app)
    stability_command(app)
    return CliRunner().invoke(app, list(args), env={"COLUMNS": "200", "NO_COLOR": "1"})


def test_commands_read_speeds_tools_and_slice_height_from_the_results(tmp_path: Path) -> None:
    maps = write_results(tmp_path / "res")
    r = invoke("forces", str(tmp_path / "res"), "--no-plot")
    assert r.exit_code == 0, r.output
    got = pd.read_csv(tmp_path / "res" / "forces.csv")
    want = forces_table(maps, TOOL, AL, RPM, dz=0.5)
    np.testing.assert_allclose(got["resultant_peak_N"], want["resultant_peak_N"], rtol=1e-9)
    assert list(got["rpm"]) == RPM

    r = invoke("stability", str(tmp_path / "res"), "--modes", str(MODES), "--no-sd", "--no-plot", "--out",
               str(tmp_path / "stab"))
    assert r.exit_code == 0, r.output
    got = pd.read_csv(tmp_path / "stab" / "stability.csv")
    want = stability_table(maps, TOOL, AL, read_modes_json(MODES), RPM, dz=0.5, sd=False)
    np.testing.assert_allclose(got["a_lim_zoa_mm"], want["a_lim_zoa_mm"], rtol=1e-12)
    assert list(got["spindle_rpm"]) == RPM

    # the options override: one speed and another flute count for every CL
    r = invoke("stability", str(tmp_path / "res"), "--modes", str(MODES), "--no-sd", "--no-plot", "--out",
               str(tmp_path / "stab2"), "--rpm", "10000", "--flutes", "2")
    assert r.exit_code == 0, r.output
    got = pd.read_csv(tmp_path / "stab2" / "stability.csv")
    two = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=2, helix_angle=35.0)
    want = stability_table(maps, two, AL, read_modes_json(MODES), [10000.0] * 3, dz=0.5, sd=False)
    np.testing.assert_allclose(got["a_lim_zoa_mm"], want["a_lim_zoa_mm"], rtol=1e-12)

    # a slice height that disagrees with the recorded one is refused, naming the folder
    r = invoke("forces", str(tmp_path / "res"), "--no-plot", "--slice-height", "0.25")
    assert r.exit_code == 2 and "slice height 0.5 mm, not 0.25 mm" in " ".join(r.output.split()), r.output
