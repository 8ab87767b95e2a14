"""Forces and feed advice from a B-Rep engagement run of a real program.

The Fusion-posted 2D adaptive ``1055_utab_265bit.nc`` (2.65 mm flat end mill, S5000, F1000/F333.3) is
run through the engine for its first CLs (rapids, an air move, a plunge, a ramp into a full slot,
air, adaptive passes), the results written and read back, and then:

* forces rebuilt from the saved tables equal the forces of the engine's own maps (so nothing the
  force model needs is lost on disk), and the mean forces of the full-slot CLs equal Altintas's
  closed-form slot averages;
* ``fusioncut forces`` writes the per-CL table (CSV and Parquet agreeing, units in the Parquet
  fields) and a plot;
* ``fusioncut advise`` writes a program that differs only in F words, reads back to the same moves,
  and whose feeds keep every advised CL at or under the force limit.
"""
from __future__ import annotations

import json
import math
import os
import pickle
import re
import shutil
import time
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
import typer
from typer.testing import CliRunner

from fusioncut.analysis.feed import FeedLimit, advise_feeds
from fusioncut.analysis.forces import compute_cl_forces, forces_from_results, forces_table
from fusioncut.analysis.result_maps import engagement_maps_from_results
from fusioncut.analysis.materials import AL7075_T6_CARBIDE as K
from fusioncut.cli import forces as forces_cli
from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.segments import cl_segments
from fusioncut.errors import InputError
from fusioncut.io.gcode import read_gcode
from fusioncut.io.results import ResultWriter, load_results
from fusioncut.io.stock import infer_stock
from fusioncut.model import CLStatus, Toolpath
from shared_data import DATA

PROGRAM = DATA / "fusion-posted" / "1055_utab_265bit.nc"
N_MOVES = 100
RPM = 5000.0
SLICE = 1.0
LIMIT_N = 150.0

pytestmark = pytest.mark.skipif(not PROGRAM.exists(), reason="shared test data not available")


def _run(moves: int | None, out: Path):
    full = read_gcode(PROGRAM)
    stock = infer_stock(full)  # the stock of the whole program, as a run of it would have
    tp = full if moves is None else Toolpath(full.moves[:moves], full.tools, (), full.source)
    opts = EngineOptions(slice_height=SLICE)
    segments = cl_segments(tp.moves, opts.max_segment_length, opts.chord_tolerance)
    maps = []
    with ResultWriter(out, tools={t.label: t for t in tp.tools.values()}, options=opts) as w:
        for m, seg in zip(BRepEngine(opts).run(tp, stock), segments):
            w.add(m, length_mm=seg.length, spindle_rpm=seg.spindle_rpm)
            maps.append(m)
    return full, maps


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The engine run, once per test session: pytest-xdist workers share one run through the
    common parent of their temporary directories (the first to claim it computes, the others wait)."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent
    shared = root / "utab-first-cls"
    done, failed = shared / "maps.pkl", shared / "failed"
    try:
        shared.mkdir()
        mine = True
    except FileExistsError:
        mine = False
    if mine:
        try:
            full, maps = _run(N_MOVES, shared / "results")
        except BaseException:
            failed.touch()
            raise
        tmp = shared / "maps.tmp"
        tmp.write_bytes(pickle.dumps(maps))
        tmp.replace(done)
        return full, maps, shared / "results"
    deadline = time.monotonic() + 600
    while not done.exists():
        if failed.exists() or time.monotonic() > deadline:
            pytest.fail("the shared engine run failed in another worker")
        time.sleep(0.2)
    return read_gcode(PROGRAM), pickle.loads(done.read_bytes()), shared / "results"


def _copy(results: Path, tmp_path: Path) -> Path:
    """A private copy of the shared results, for commands that write next to them."""
    out = tmp_path / "results"
    shutil.copytree(results, out)
    return out


@pytest.fixture(scope="module")
def cli_app():
    app = typer.Typer()
    app.callback()(lambda: None)
    forces_cli.register(app)
    return app


def test_run_covers_the_interesting_cases(run):
    _, maps, _ = run
    statuses = {m.status for m in maps}
    assert {CLStatus.RAPID, CLStatus.AIR, CLStatus.ENGAGED} <= statuses
    assert not any(m.status == CLStatus.FAILED for m in maps)
    slots = [m for m in maps if _is_slot(m)]
    assert len(slots) > 20  # the first pass is a full slot at 2 mm depth


def _is_slot(m) -> bool:
    s = m.engaged_slices
    return (m.status == CLStatus.ENGAGED and len(s) == 2 and abs(m.ap - 2.0) < 1e-9
            and all(len(x.intervals) == 1 and abs(x.intervals[0].entry) < 1e-9
                    and abs(x.intervals[0].exit - 180.0) < 1e-9 for x in s))


def test_forces_from_saved_tables_equal_forces_from_engine_maps(run):
    full, maps, out = run
    tool = full.tools[1]
    results = load_results(out)
    assert results.slice_height == SLICE and results.missing == {}
    rebuilt = engagement_maps_from_results(results)
    assert len(rebuilt) == len(maps)
    compared = 0
    for a, b in zip(maps, rebuilt):
        assert (a.cl_index, a.status, a.source.line) == (b.cl_index, b.status, b.source.line)
        if a.status != CLStatus.ENGAGED or not a.engaged_slices:
            continue
        np.testing.assert_allclose(b.axial_range, a.axial_range, atol=1e-9)
        fa = compute_cl_forces(a, tool, K, rpm=RPM, dz=SLICE)
        fb = compute_cl_forces(b, tool, K, rpm=RPM, dz=SLICE)
        np.testing.assert_allclose(fb.feed_frame, fa.feed_frame, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(fb.mean_machine_frame, fa.mean_machine_frame, rtol=1e-9, atol=1e-9)
        compared += 1
    assert compared > 50


def test_forces_of_a_results_folder_need_no_program(run):
    """Differential: the forces of the results folder alone (tools, spindle speeds, slice height and
    bands from the folder) equal the forces of the engine's own maps with the program's tool and S
    words, CL by CL, to the last bits the tables' float round trip allows."""
    full, maps, out = run
    results = load_results(out)
    sl = results.slices
    assert sl[["z_lo_mm", "z_hi_mm"]].notna().all().all()  # the engine's slices all sit on its rule
    np.testing.assert_allclose(0.5 * (sl["z_lo_mm"] + sl["z_hi_mm"]), sl["z_tool_mm"], rtol=0, atol=1e-12)
    alone = forces_from_results(results, K)
    rpm_at = {m.source.line: m.spindle_rpm for m in full.moves}
    live = forces_table(maps, full.tools[1], K, [rpm_at[m.source.line] for m in maps], dz=SLICE)
    assert (alone["rpm"].dropna() == RPM).all() and alone["resultant_peak_N"].notna().sum() > 50
    pd.testing.assert_frame_equal(alone.reset_index(drop=True), live, rtol=1e-12, atol=1e-9)


def _as_older_folder(results: Path, tmp_path: Path) -> Path:
    """A copy of ``results`` as FusionCut wrote it before it kept the slice height, the engine options,
    full tool records, spindle speeds and slice bands."""
    out = _copy(results, tmp_path)
    meta = json.loads((out / "metadata.json").read_text())
    del meta["engine_options"], meta["slice_height_mm"]
    meta["tools"] = {label: {k: t[k] for k in ("kind", "diameter_mm", "flute_length_mm")}
                     for label, t in meta["tools"].items()}
    (out / "metadata.json").write_text(json.dumps(meta))
    for name, drop in (("cl", ["spindle_rpm"]), ("slices", ["z_lo_mm", "z_hi_mm"])):
        table = pq.read_table(out / f"{name}.parquet").drop(drop)
        pq.write_table(table.replace_schema_metadata({b"fusioncut": json.dumps(meta).encode()}), out / f"{name}.parquet")
        pd.read_csv(out / f"{name}.csv", dtype=str, keep_default_na=False).drop(columns=drop).to_csv(
            out / f"{name}.csv", index=False)
    return out


def test_forces_of_an_older_folder_need_what_it_lacks(run, tmp_path):
    """An older folder names what it lacks (spindle speeds, the tool) instead of guessing; given them
    and the slice height, its bands rebuilt by the slice rule give the same forces as a new folder's."""
    full, _, out = run
    old = load_results(_as_older_folder(out, tmp_path))
    with pytest.raises(InputError, match=r"spindle speeds are not recorded.*--rpm"):
        forces_from_results(old, K)
    with pytest.raises(InputError, match=r"tool T1: metadata.json has no full record of it"):
        forces_from_results(old, K, rpm=RPM, dz=SLICE)
    with pytest.raises(InputError, match=r"--slice-height"):  # never guessed from the slices
        forces_from_results(old, K, rpm=RPM, tools={"T1": full.tools[1]})
    got = forces_from_results(old, K, rpm=RPM, tools={"T1": full.tools[1]}, dz=SLICE)
    want = forces_from_results(load_results(out), K, rpm=RPM)
    pd.testing.assert_frame_equal(got, want, rtol=1e-12, atol=1e-9)
    with pytest.raises(InputError, match="computed with slice height 1 mm, not 0.5 mm"):
        forces_from_results(load_results(out), K, dz=0.5)


def textbook_slot_mean(n: int, a: float, c: float) -> np.ndarray:
    """Altintas's mean Fx, Fy, Fz (N) of a flat end mill in a full slot (immersion 0..pi), any helix."""
    def prim(p: float) -> np.ndarray:
        fx = (n * a * c / (8 * math.pi)) * (K.ktc * math.cos(2 * p) - K.krc * (2 * p - math.sin(2 * p))) + (
            n * a / (2 * math.pi)) * (-K.kte * math.sin(p) + K.kre * math.cos(p))
        fy = (n * a * c / (8 * math.pi)) * (K.ktc * (2 * p - math.sin(2 * p)) + K.krc * math.cos(2 * p)) - (
            n * a / (2 * math.pi)) * (K.kte * math.cos(p) + K.kre * math.sin(p))
        fz = (n * a / (2 * math.pi)) * (-K.kac * c * math.cos(p) + K.kae * p)
        return np.array([fx, fy, fz])

    return prim(math.pi) - prim(0.0)


def test_cli_forces_table_and_plot(run, cli_app, tmp_path):
    full, maps, shared = run
    out = _copy(shared, tmp_path)
    r = CliRunner().invoke(cli_app, ["forces", str(out), "--program", str(PROGRAM), "--material", "Al7075-T6"])
    assert r.exit_code == 0, r.output
    csv = pd.read_csv(out / "forces.csv")
    par = pq.read_table(out / "forces.parquet")
    assert len(csv) == len(maps) == par.num_rows
    assert par.schema.field("resultant_peak_N").metadata[b"unit"] == b"N"
    assert par.schema.field("power_mean_W").metadata[b"unit"] == b"W"
    np.testing.assert_allclose(par.column("resultant_peak_N").to_numpy(zero_copy_only=False),
                               csv["resultant_peak_N"].to_numpy(), rtol=1e-12, equal_nan=True)
    # rapids: unknown, not zero; air: zero
    by_status = {s: csv[csv["status"] == s] for s in ("rapid", "air", "engaged")}
    assert by_status["rapid"]["resultant_peak_N"].isna().all()
    assert (by_status["air"]["resultant_peak_N"] == 0).all()
    assert (csv["rpm"].dropna() == RPM).all()
    # full slots: mean forces in closed form, c = F / (rpm N) = 1000 / (5000 * 2) = 0.1 mm
    slots = [m.cl_index for m in maps if _is_slot(m) and m.position[2] == m.start[2]]
    want = textbook_slot_mean(2, 2.0, 0.1)
    for cl in slots:
        row = csv[csv["cl"] == cl].iloc[0]
        assert row["feed_per_tooth_mm"] == pytest.approx(0.1)
        got = [row["fx_mean_N"], row["fy_mean_N"], row["fz_mean_N"]]
        np.testing.assert_allclose(got, want, rtol=1e-9)
        # torque and power of a slot: N a r / (2 pi) * (2 Ktc c + pi Kte), P = T * omega
        t = 2 * 2.0 * 1.325 / (2 * math.pi) * (2 * K.ktc * 0.1 + math.pi * K.kte) * 1e-3
        assert row["torque_mean_Nm"] == pytest.approx(t, rel=1e-9)
        assert row["power_mean_W"] == pytest.approx(t * RPM * 2 * math.pi / 60, rel=1e-9)
        assert row["chip_peak_mm"] == pytest.approx(0.1)
    img = mpimg.imread(out / "forces.png")
    assert img.shape[0] > 100 and img[..., :3].std() > 0.05


def _strip_f(line: str) -> str:
    code, paren, comment = line.partition("(")
    return re.sub(r"[Ff]\s*[-+]?[0-9.]+", "", code).rstrip() + paren + comment


def test_cli_advise_keeps_forces_under_the_limit(run, cli_app, tmp_path):
    full, maps, shared = run
    out = _copy(shared, tmp_path)
    new = tmp_path / "utab_advised.nc"
    r = CliRunner().invoke(cli_app, ["advise", str(out), "--program", str(PROGRAM), "--max-force", str(LIMIT_N),
                                     "--out", str(new)])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "utab_advised_feed.png").stat().st_size > 0
    table = pd.read_csv(tmp_path / "utab_advised_advice.csv")
    assert len(table) == len(maps)

    # only F words differ, line by line
    old_lines = PROGRAM.read_text().splitlines()
    new_lines = new.read_text().splitlines()
    assert len(old_lines) == len(new_lines)
    changed = [k for k, (a, b) in enumerate(zip(old_lines, new_lines)) if a != b]
    assert changed
    assert all(_strip_f(old_lines[k]) == _strip_f(new_lines[k]) for k in changed)

    # the same motion, at the advised feeds
    old_tp, new_tp = full, read_gcode(new)
    assert len(old_tp.moves) == len(new_tp.moves)
    new_feed = {}
    for a, b in zip(old_tp.moves, new_tp.moves):
        assert (type(a), a.start, a.end, a.source.line) == (type(b), b.start, b.end, b.source.line)
        new_feed[b.source.line] = b.feed
    tool = full.tools[1]
    checked = 0
    for m, row in zip(maps, table.itertuples()):
        if m.status != CLStatus.ENGAGED or "unreachable" in str(row.note):
            continue
        feed = new_feed[m.source.line]
        # what the program now feeds is the advice, rounded down to the post's 0.1 mm/min
        assert row.advised_feed_mm_min - 0.1 < feed <= row.advised_feed_mm_min + 1e-9
        if m.engaged_slices:
            f = compute_cl_forces(m, tool, K, rpm=RPM, dz=SLICE,
                                  feed_per_tooth=feed / (RPM * tool.flutes) * _horizontal(m))
            if row.reason in ("force", "smoothing", "min_feed"):
                assert f.resultant_peak <= LIMIT_N * (1 + 1e-9)
                checked += 1
            # a raised feed is never over the limit either
            if feed > m.feed:
                assert f.resultant_peak <= LIMIT_N * (1 + 1e-9)
    assert checked > 50
    # the slot is slowed: 230 N at F1000 -> the limit binds, 5 % steps of 1000 mm/min
    slot_rows = table[table["cl"].isin([m.cl_index for m in maps if _is_slot(m) and m.position[2] == m.start[2]])]
    assert (slot_rows["advised_feed_mm_min"] == 450.0).all()
    assert (slot_rows["limit_feed_mm_min"] < 500.0).all()
    assert "feed time" in r.output


def _horizontal(m) -> float:
    d = np.subtract(m.position, m.start)
    n = float(np.linalg.norm(d))
    return 1.0 if n < 1e-9 else float(math.hypot(d[0], d[1])) / n


def test_advise_from_results_matches_advise_from_maps(run):
    full, maps, out = run
    tool = full.tools[1]
    lim = FeedLimit(max_force=LIMIT_N, max_chip_thickness=0.08)
    a = advise_feeds(load_results(out), tool, K, lim, rpm=RPM)
    lengths = load_results(out).cl["length_mm"].to_numpy()
    b = advise_feeds(maps, tool, K, lim, rpm=RPM, dz=SLICE, lengths=lengths)
    pd.testing.assert_series_equal(a.table["advised_feed_mm_min"], b.table["advised_feed_mm_min"], rtol=1e-9)
    assert set(a.table["limiting_quantity"].dropna()) <= {"force", "chip", ""}


@pytest.mark.slow
def test_whole_program_forces_and_advice(tmp_path, cli_app):
    """The whole program (6519 moves; many minutes): every CL processed, advice rewritten and read back."""
    full, maps = _run(None, tmp_path / "res")
    assert not any(m.status == CLStatus.FAILED for m in maps)
    r = CliRunner().invoke(cli_app, ["forces", str(tmp_path / "res"), "--program", str(PROGRAM)])
    assert r.exit_code == 0, r.output
    new = tmp_path / "all.nc"
    r = CliRunner().invoke(cli_app, ["advise", str(tmp_path / "res"), "--program", str(PROGRAM), "--max-force",
                                     str(LIMIT_N), "--out", str(new), "--max-feed", "1500"])
    assert r.exit_code == 0, r.output
    new_tp = read_gcode(new)
    assert [(m.start, m.end) for m in new_tp.moves] == [(m.start, m.end) for m in full.moves]


def test_cli_forces_need_no_program(run, cli_app, tmp_path):
    """``fusioncut forces RESULTS`` alone takes the recorded speeds, tools and slice height: the table
    is the one ``--program`` gives; an older folder asks for the slice height, then the speeds (exit 2, no
    traceback); ``--flutes`` overrides the recorded tool."""
    _, maps, shared = run
    out = _copy(shared, tmp_path)
    r = CliRunner().invoke(cli_app, ["forces", str(out), "--no-plot"])
    assert r.exit_code == 0, r.output
    alone = pd.read_csv(out / "forces.csv")
    r = CliRunner().invoke(cli_app, ["forces", str(out), "--program", str(PROGRAM), "--no-plot"])
    assert r.exit_code == 0, r.output
    with_program = pd.read_csv(out / "forces.csv")
    assert alone["resultant_peak_N"].notna().sum() > 50
    pd.testing.assert_frame_equal(alone, with_program, check_exact=True)
    old = _as_older_folder(shared, tmp_path / "old")
    r = CliRunner().invoke(cli_app, ["forces", str(old), "--no-plot"])
    assert r.exit_code == 2 and "--slice-height" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(cli_app, ["forces", str(old), "--slice-height", str(SLICE), "--no-plot"])
    assert r.exit_code == 2 and "--rpm" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(cli_app, ["forces", str(out), "--rpm", str(RPM), "--no-plot"])
    assert r.exit_code == 0, r.output
    plain = pd.read_csv(out / "forces.csv")
    np.testing.assert_allclose(plain["resultant_peak_N"], alone["resultant_peak_N"], equal_nan=True)
    r = CliRunner().invoke(cli_app, ["forces", str(out), "--rpm", str(RPM), "--flutes", "4", "--no-plot"])
    assert r.exit_code == 0, r.output
    four = pd.read_csv(out / "forces.csv")
    slot = [m.cl_index for m in maps if _is_slot(m) and m.position[2] == m.start[2]][0]
    # four flutes at the same feed: half the chip, twice the teeth in the cut
    assert four.loc[slot, "feed_per_tooth_mm"] == pytest.approx(plain.loc[slot, "feed_per_tooth_mm"] / 2)


def test_cli_advise_refuses_results_of_another_program(run, cli_app, tmp_path):
    _, _, shared = run
    out = _copy(shared, tmp_path)
    lines = PROGRAM.read_text().splitlines(keepends=True)
    lines[16] = lines[16].replace("F1000", "F900")  # line 17: "G1 Z5 F1000"
    other = tmp_path / PROGRAM.name
    other.write_text("".join(lines))
    r = CliRunner().invoke(cli_app, ["advise", str(out), "--program", str(other), "--max-force", "150",
                                     "--out", str(tmp_path / "x.nc")])
    assert r.exit_code == 2, r.output
    assert f"{PROGRAM.name}:17" in r.output.replace("\n", "") and "this program" in r.output
    assert not (tmp_path / "x.nc").exists()
    r = CliRunner().invoke(cli_app, ["advise", str(out), "--program", str(PROGRAM), "--out", str(tmp_path / "y.nc")])
    assert r.exit_code == 2 and "at least one limit" in r.output
