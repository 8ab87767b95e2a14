"""Spindle speed advice with a chatter margin (issue 27 item 5): per operation the largest margin at the
programmed speed, and the nearest speed where every CL of the operation keeps the margin, checked
against the ZOA limits directly; ``fusioncut advise --modes`` writes it beside the feed advice."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import typer
from typer.testing import CliRunner

from fusioncut.analysis.dynamics import read_modes_json
from fusioncut.analysis.materials import AL7075_T6_CARBIDE as AL
from fusioncut.analysis.speed_advice import advise_speeds
from fusioncut.analysis.stability import chatter_grid, cl_directional, zoa_a_lim
from fusioncut.errors import InputError, SourceLocation
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement, SpindleDirection

MODES = Path(__file__).parents[2] / "docs" / "stability_modes_example.json"
TOOL = FlatEndMill(diameter=10.0, flute_length=20.0, flutes=3, helix_angle=30.0)
PROGRAM = """%
(T1 D=10. CR=0. - ZMIN=-2. - FLAT END MILL)
G90 G94 G17
G21
(SLOT)
T1 M6
S9000 M3
G0 X0. Y0. Z5.
G1 Z-2. F300.
G1 X10. F900.
G1 X20.
(FINISH)
G1 X30. F600.
G1 X40.
M30
%
"""


def cl(i: int, arc: tuple[float, float], depth: float, line: int, feed: float, operation: str,
       file: str = "p.nc") -> EngagementMap:
    sl = tuple(SliceEngagement(0.25 * (k + 0.5), -2.0 + 0.25 * (k + 0.5), 5.0, (AngleInterval(*arc),))
               for k in range(round(depth / 0.25)))
    return EngagementMap(i, (10.0 * i + 10, 0, -2.0), (10.0 * i, 0, -2.0), "T1", SpindleDirection.CW, 0.0,
                         CLStatus.ENGAGED, source=SourceLocation(file, line), feed=feed, operation=operation,
                         slices=sl, axial_range=(0.0, depth))


def program_maps(file: str = "p.nc") -> list[EngagementMap]:
    """A 1 mm slot (SLOT: a margin above 1 at 9000 rev/min with the example modes) and a 2 mm cut of
    60 deg down-milling (FINISH: below 0.8), two CLs each, in 0.25 mm slices."""
    slot, finish = ((0.0, 180.0), 1.0, 900.0, "SLOT"), ((120.0, 180.0), 2.0, 600.0, "FINISH")
    return [cl(i, arc, depth, line, feed, op, file)
            for i, (line, (arc, depth, feed, op)) in enumerate(zip((10, 11, 13, 14), (slot, slot, finish, finish)))]


def margins(maps: list[EngagementMap], grid, rpm: np.ndarray) -> np.ndarray:
    """Largest ap / a_lim over ``maps`` at each speed, directly."""
    out = np.zeros(len(rpm))
    for m in maps:
        cd = cl_directional(m, TOOL, AL, 0.25)
        out = np.maximum(out, cd.ap / zoa_a_lim(cd.alpha0, grid, AL.ktc, 3, rpm))
    return out


def test_speed_per_operation_is_the_nearest_holding_the_margin() -> None:
    maps = program_maps()
    dyn = read_modes_json(MODES)
    grid = chatter_grid(dyn)
    t = advise_speeds(maps, TOOL, AL, dyn, [9000.0] * 4, max_margin=0.8, dz=0.25).set_index("operation")
    assert list(t.index) == ["SLOT", "FINISH"] and list(t["engaged_cls"]) == [2, 2]
    for op, rows in (("SLOT", maps[:2]), ("FINISH", maps[2:])):
        assert t.at[op, "margin_max"] == pytest.approx(margins(rows, grid, np.array([9000.0]))[0], rel=1e-12)
    # FINISH holds 0.8 at its speed: kept
    assert t.at["FINISH", "margin_max"] < 0.8 and t.at["FINISH", "suggested_rpm"] == 9000.0
    # SLOT does not; at the suggested speed it does, and at no speed nearer to 9000 on either side
    slot = maps[:2]
    n = t.at["SLOT", "suggested_rpm"]
    assert t.at["SLOT", "margin_max"] > 1.0 and 4500.0 <= n <= 13500.0 and n != 9000.0
    assert margins(slot, grid, np.array([n]))[0] <= 0.8
    assert t.at["SLOT", "margin_max_suggested"] == pytest.approx(margins(slot, grid, np.array([n]))[0], rel=1e-12)
    d = abs(n - 9000.0) * (1 - 1e-4)
    assert np.all(margins(slot, grid, np.linspace(9000.0 - d, 9000.0 + d, 2001)) > 0.8)
    # a range with no speed holding it: NaN; a bad margin is refused
    none = advise_speeds(maps[:2], TOOL, AL, dyn, [9000.0] * 2, max_margin=0.01, dz=0.25)
    assert np.isnan(none.loc[0, "suggested_rpm"]) and np.isnan(none.loc[0, "margin_max_suggested"])
    with pytest.raises(InputError, match="largest margin"):
        advise_speeds(maps, TOOL, AL, dyn, [9000.0] * 4, max_margin=0.0, dz=0.25)


def test_advise_command_writes_the_speed_advice(tmp_path: Path) -> None:
    from fusioncut.cli.forces import register
    from fusioncut.io.results import ResultWriter

    prog = tmp_path / "p.nc"
    prog.write_text(PROGRAM)
    maps = program_maps(str(prog))
    with ResultWriter(tmp_path / "res", tools={"T1": {"kind": "flat", "diameter_mm": 10.0,
                                                       "flute_length_mm": 20.0}}) as w:
        for m in maps:
            w.add(m, length_mm=10.0)
    app = typer.Typer()
    register(app)
    base = ["advise", str(tmp_path / "res"), "--program", str(prog), "--out", str(tmp_path / "new.nc"),
            "--max-force", "1e6", "--flutes", "3", "--slice-height", "0.25"]
    r = CliRunner().invoke(app, base + ["--modes", str(MODES), "--max-margin", "0.8"],
                           env={"COLUMNS": "200", "NO_COLOR": "1"})
    assert r.exit_code == 0, r.output
    got = pd.read_csv(tmp_path / "new_speeds.csv")
    want = advise_speeds(maps, TOOL, AL, read_modes_json(MODES), [9000.0] * 4, max_margin=0.8, dz=0.25)
    assert list(got["operation"]) == list(want["operation"])
    np.testing.assert_allclose(got["suggested_rpm"], want["suggested_rpm"], rtol=1e-12)
    np.testing.assert_allclose(got["margin_max"], want["margin_max"], rtol=1e-12)
    assert "Spindle speed per operation" in r.output and "SLOT" in r.output
    # the program's S words are untouched
    assert [ln for ln in (tmp_path / "new.nc").read_text().splitlines() if ln.startswith("S")] == ["S9000 M3"]
    r = CliRunner().invoke(app, base + ["--rpm-min", "5000", "--rpm-max", "12000"])
    assert r.exit_code == 2 and "give --modes too" in r.output
