"""Calibrated coefficients end to end (issue 27 item 4): dynamometer records of slot cuts, built from
known coefficients by the force model with noise, are averaged and calibrated by ``fusioncut
calibrate``; the coefficients file it writes drives ``forces`` and ``stability``; its checks (signs,
plausibility, units, --material with --coefficients) name the file."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import typer
from typer.testing import CliRunner

from fusioncut.analysis.calibrate import read_coefficients_json
from fusioncut.analysis.forces import compute_cl_forces, forces_table
from fusioncut.analysis.materials import AL7075_T6_CARBIDE as TRUE
from fusioncut.errors import InputError, SourceLocation
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement, SpindleDirection

KEYS = ("ktc", "krc", "kac", "kte", "kre", "kae")
FEEDS = np.array([0.03, 0.05, 0.07, 0.09, 0.11, 0.13, 0.15])
TEST_TOOL = FlatEndMill(diameter=12.0, flute_length=30.0, flutes=3, helix_angle=30.0)
DEPTH = 3.0
MODES = Path(__file__).parents[2] / "docs" / "stability_modes_example.json"


def app() -> typer.Typer:
    from fusioncut.cli.forces import register as forces_commands
    from fusioncut.cli.stability import register as stability_command

    a = typer.Typer()
    forces_commands(a)
    stability_command(a)
    return a


def invoke(*args: str):
    return CliRunner().invoke(app(), list(args), env={"COLUMNS": "300", "NO_COLOR": "1"})


def slot_map(depth: float, slices: int) -> EngagementMap:
    sl = tuple(SliceEngagement((i + 0.5) * depth / slices, (i + 0.5) * depth / slices, 6.0,
                               (AngleInterval(0.0, 180.0),)) for i in range(slices))
    return EngagementMap(0, (1, 0, 0), (0, 0, 0), "T1", SpindleDirection.CW, 0.0, CLStatus.ENGAGED, feed=1.0,
                         slices=sl, axial_range=(0.0, depth))


def dynamometer_csv(path: Path, rng: np.random.Generator, negate: bool = True, noise_n: float = 8.0) -> Path:
    """Per feed: 20 revolutions of a table dynamometer's record (the reaction on the workpiece, 360
    samples a revolution, white noise of ``noise_n`` N and a drift-free offset removed by the zero), its
    mean over whole revolutions, negated into the force on the tool unless ``negate`` is False."""
    emap = slot_map(DEPTH, 30)
    rows = ["c_mm,fx_N,fy_N,fz_N"]
    for c in FEEDS:
        f = compute_cl_forces(emap, TEST_TOOL, TRUE, rpm=8000.0, feed_per_tooth=float(c)).feed_frame  # (360, 3)
        record = -np.tile(f, (20, 1)) + rng.normal(0.0, noise_n, (20 * len(f), 3))
        mean = record.mean(axis=0) * (-1 if negate else 1)
        rows.append(f"{c:g},{mean[0]:.4f},{mean[1]:.4f},{mean[2]:.4f}")
    path.write_text("\n".join(rows) + "\n")
    return path


def results_dir(out: Path) -> list[EngagementMap]:
    """A slot and a half-immersion (down-milling) CL, 2 mm deep in 0.5 mm slices, with a 12 mm flat mill."""
    from fusioncut.io.results import ResultWriter

    def cl(i: int, arc: tuple[float, float]) -> EngagementMap:
        sl = tuple(SliceEngagement(0.25 + 0.5 * k, -2.0 + 0.25 + 0.5 * k, 6.0, (AngleInterval(*arc),))
                   for k in range(4))
        return EngagementMap(i, (i + 1.0, 0, -2.0), (float(i), 0, -2.0), "T1", SpindleDirection.CW, 0.0,
                             CLStatus.ENGAGED, source=SourceLocation("prog.nc", 10 + i), feed=900.0, operation="op",
                             slices=sl, axial_range=(0.0, 2.0))

    maps = [cl(0, (0.0, 180.0)), cl(1, (90.0, 180.0))]
    with ResultWriter(out, tools={"T1": {"kind": "flat", "diameter_mm": 12.0, "flute_length_mm": 30.0}}) as w:
        for m in maps:
            w.add(m, length_mm=1.0)
    return maps


def test_calibrated_file_drives_forces_and_stability(tmp_path: Path) -> None:
    rng = np.random.default_rng(27)
    data = dynamometer_csv(tmp_path / "slots.csv", rng)
    k_file = tmp_path / "k.json"
    r = invoke("calibrate", str(data), "--axial-depth", str(DEPTH), "--flutes", "3", "--out", str(k_file))
    assert r.exit_code == 0, r.output
    assert "warning" not in r.output
    doc = json.loads(k_file.read_text(encoding="utf-8"))
    assert doc["units"] == {"ktc": "N/mm²", "krc": "N/mm²", "kac": "N/mm²", "kte": "N/mm", "kre": "N/mm",
                            "kae": "N/mm"}
    assert doc["fit"]["data"] == str(data) and doc["fit"]["tests"] == len(FEEDS) and doc["fit"]["flutes"] == 3
    assert all(0.99 < doc["fit"]["r_squared"][a] <= 1.0 for a in ("x", "y", "z"))
    assert "slots.csv" in doc["source"] and "warnings" not in doc
    # every coefficient within 4 of its stated standard errors of the truth (and the errors are small)
    got = read_coefficients_json(k_file)
    for key in KEYS:
        se = doc["fit"]["stderr"][key]
        assert abs(getattr(got, key) - getattr(TRUE, key)) < 4 * se, (key, getattr(got, key), se)
        assert se < 0.05 * max(abs(getattr(TRUE, key)), 20.0), (key, se)

    maps = results_dir(tmp_path / "res")
    common = ["--rpm", "9000", "--flutes", "4", "--helix", "30", "--slice-height", "0.5"]
    r = invoke("forces", str(tmp_path / "res"), "--coefficients", str(k_file), "--no-plot", *common)
    assert r.exit_code == 0, r.output
    table = pd.read_csv(tmp_path / "res" / "forces.csv")
    tool = FlatEndMill(diameter=12.0, flute_length=30.0, flutes=4, helix_angle=30.0)
    direct = forces_table(maps, tool, got, [9000.0, 9000.0], dz=0.5)
    for col in ("fy_mean_N", "resultant_peak_N", "torque_peak_Nm"):
        np.testing.assert_allclose(table[col], direct[col], rtol=1e-9)
    truth = forces_table(maps, tool, TRUE, [9000.0, 9000.0], dz=0.5)
    np.testing.assert_allclose(table["resultant_peak_N"], truth["resultant_peak_N"], rtol=0.03)

    out = tmp_path / "stab"
    r = invoke("stability", str(tmp_path / "res"), "--modes", str(MODES), "--coefficients", str(k_file),
               "--no-sd", "--no-plot", "--out", str(out), *common)
    assert r.exit_code == 0, r.output
    from fusioncut.analysis.dynamics import read_modes_json
    from fusioncut.analysis.stability_table import stability_table

    stab = pd.read_csv(out / "stability.csv")
    want = stability_table(maps, tool, got, read_modes_json(MODES), [9000.0, 9000.0], dz=0.5, sd=False)
    np.testing.assert_allclose(stab["a_lim_zoa_mm"], want["a_lim_zoa_mm"], rtol=1e-12)
    assert np.all(np.isfinite(stab["a_lim_zoa_mm"]))
    # --material and --coefficients together are refused, naming both
    for cmd in (["forces", str(tmp_path / "res")], ["stability", str(tmp_path / "res"), "--modes", str(MODES),
                                                     "--out", str(out)]):
        r = invoke(*cmd, "--material", "al7075-t6", "--coefficients", str(k_file), *common)
        assert r.exit_code == 2 and "give --material or --coefficients, not both" in r.output, r.output


def test_calibrate_refuses_broken_sign_conventions_naming_the_file(tmp_path: Path) -> None:
    """The table dynamometer's readings not negated: Ktc < 0, refused naming the CSV; no file written."""
    data = dynamometer_csv(tmp_path / "raw.csv", np.random.default_rng(1), negate=False)
    r = invoke("calibrate", str(data), "--axial-depth", str(DEPTH), "--flutes", "3")
    assert r.exit_code == 2, r.output
    text = " ".join(r.output.split())
    assert f"{data}: Ktc" in text and "negate" in text and "Traceback" not in text
    assert not (tmp_path / "raw_coefficients.json").exists()


def test_implausible_values_are_warned_and_recorded(tmp_path: Path) -> None:
    """Forces written in daN (a tenth of the newtons): Ktc 80 N/mm² is below every published set; the
    command warns naming the file, and the warning is kept in the coefficients file and repeated by
    every command that reads it."""
    data = dynamometer_csv(tmp_path / "slots.csv", np.random.default_rng(2), noise_n=0.0)
    tenth = pd.read_csv(data)
    tenth[["fx_N", "fy_N", "fz_N"]] /= 10.0
    tenth.to_csv(data, index=False)
    r = invoke("calibrate", str(data), "--axial-depth", str(DEPTH), "--flutes", "3")
    assert r.exit_code == 0, r.output
    text = " ".join(r.output.split())
    assert f"warning: {data}: Ktc" in text and "outside 150..6000" in text
    k_file = tmp_path / "slots_coefficients.json"
    doc = json.loads(k_file.read_text(encoding="utf-8"))
    assert doc["ktc"] == pytest.approx(TRUE.ktc / 10, rel=1e-3) and any("Ktc" in w for w in doc["warnings"])
    results_dir(tmp_path / "res")
    r = invoke("forces", str(tmp_path / "res"), "--coefficients", str(k_file), "--no-plot", "--rpm", "9000",
               "--flutes", "4", "--slice-height", "0.5")
    assert r.exit_code == 0 and f"warning: {k_file}: Ktc" in " ".join(r.output.split()), r.output


def test_scattered_tests_warn_about_the_fit(tmp_path: Path) -> None:
    """Noise as large as the feed's effect: R² of Fx and Fy under 0.95 is reported as a warning."""
    data = dynamometer_csv(tmp_path / "slots.csv", np.random.default_rng(3), noise_n=3000.0)
    r = invoke("calibrate", str(data), "--axial-depth", str(DEPTH), "--flutes", "3")
    assert r.exit_code == 0, r.output
    assert "not linear in the feed per tooth: R²" in " ".join(r.output.split())


@pytest.mark.parametrize("change, message", [
    ({"units": {"ktc": "MPa"}}, "'units' must be"),
    ({"ktc": -800.0}, "Ktc = -800 N/mm² is not > 0"),
    ({"krc": 0.0}, "Krc = 0 N/mm² is not > 0"),
    ({"ktc": "800"}, "must be numbers"),
    ({"colour": 1}, "unknown key(s) ['colour']"),
])
def test_coefficients_file_errors_name_the_file(tmp_path: Path, change: dict, message: str) -> None:
    doc = dict(TRUE.as_dict(), name="al", source="book")
    doc.update(change)
    p = tmp_path / "k.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(InputError) as e:
        read_coefficients_json(p)
    assert str(e.value).startswith(f"{p}: ") and message in str(e.value)


def test_library_coefficients_are_plausible() -> None:
    from fusioncut.analysis.calibrate import plausibility_warnings
    from fusioncut.analysis.materials import MATERIALS

    for name, k in MATERIALS.items():
        assert plausibility_warnings(k) == [], name
    # each check can fire
    bad = [plausibility_warnings(TRUE.__class__(**dict(TRUE.as_dict(), **c))) for c in
           ({"ktc": 9000.0, "krc": 3000.0}, {"krc": 2000.0}, {"kac": -900.0}, {"kte": -1.0}, {"kre": 500.0})]
    assert all(len(w) == 1 for w in bad), bad
