"""The analytic engine in a run (``engine="analytic"``): the CLI, resume, the job hash, refusals."""
from __future__ import annotations

import json
import logging
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_runner import stop_after
from typer.testing import CliRunner

from fusioncut.cli import app
from fusioncut.engines.analytic.engine import AnalyticEngine, CheckpointMismatch, UnsupportedStock
from fusioncut.engines.analytic.profile import UnsupportedTool
from fusioncut.engines.base import EngineOptions
from fusioncut.io.job import Job, Options, StockSpec, ToolSpec, job_hash, load_job
from fusioncut.io.mesh import mesh_volume, read_stl
from fusioncut.io.results import load_results
from fusioncut.model import BoxStock
from fusioncut.runner import prepare_job, run_job

# A flat end mill slot 2 mm deep (entering from outside the stock) and a ball-end ramp (1:2, swept along its path).
PROGRAM = """\
G21 G90 G17
(Slot)
T1 M6
S10000 M3
G0 X-5 Y5 Z5
G1 Z-2 F300
G1 X12 F600
G0 Z5
(Ramp)
T2 M6
G0 X5 Y15 Z5
G1 Z0.5 F300
G1 X9 Z-2 F600
G0 Z5
M30
"""
STOCK = {"kind": "box", "min": [0, 0, -10], "max": [30, 20, 0]}
TOOLS = [{"number": 1, "kind": "flat", "diameter": 6, "flute_length": 15},
         {"number": 2, "kind": "ball", "diameter": 6, "flute_length": 15}]
# the slot's removed volume (mm³): 2 mm deep, 6 mm wide from the stock's edge at x = 0 to x = 12, and
# the half disc of the tool's end
SLOT_VOLUME = 2 * (6 * 12 + math.pi * 3 ** 2 / 2)


def job_file(tmp_path: Path, **options) -> Path:
    (tmp_path / "prog.nc").write_text(PROGRAM)
    job = {"name": "analytic", "stock": STOCK, "tools": TOOLS, "toolpaths": ["prog.nc"],
           "options": {"max_segment_length": 3.0, "engine": "analytic", **options}}
    path = tmp_path / "job.json"
    path.write_text(json.dumps(job))
    return path


def refuse_the_ball(monkeypatch) -> None:
    """Make the analytic engine refuse tool T2 (the ball) as it refuses a non-convex lower profile,
    which no tool family of a job makes today."""
    from fusioncut.engines.analytic import engine as analytic

    real = analytic.lower_profile

    def refuse_ball(tool):
        if tool.number == 2:
            raise UnsupportedTool(f"tool {tool.label}: its lower profile is not convex")
        return real(tool)

    monkeypatch.setattr(analytic, "lower_profile", refuse_ball)


def tables(out: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    r = load_results(out)
    return r.cl.drop(columns=["time_ms"]), r.slices


def test_cli_run_with_the_analytic_engine_gives_the_engines_maps(tmp_path):
    job = job_file(tmp_path, checkpoint_every=5)
    job.write_text(job.read_text().replace('"engine": "analytic", ', ""))  # the flag chooses it
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["run", str(job), "--out", str(out), "--engine", "analytic"])
    assert res.exit_code == 0, res.output
    found = re.search(r"relative\s+error\s+([0-9.e+-]+)", res.output)
    assert found, res.output
    error = float(found.group(1))
    assert error < 1e-9
    # the IPW as the mesh of the exact height map: closed, its volume the run's to within the mesh's
    # linear walls (the slot's two 2 mm walls and the ramp's, a grid step of 3/8 mm)
    assert not (out / "ipw.step").exists()
    assert "the IPW is written as STL only" in (out / "fusioncut.log").read_text()
    ipw = read_stl(out / "ipw.stl")
    final = 30 * 20 * 10 - load_results(out).cl["removed_volume_mm3"].sum()
    assert abs(mesh_volume(ipw) - final) < 0.5 * 0.375 * 2 * (2 * 12 + 2 * 6), (mesh_volume(ipw), final)
    assert json.loads((out / "metadata.json").read_text())["engine_options"]["engine"] == "analytic"

    cl = load_results(out).cl
    loaded, base = load_job(job)
    p = prepare_job(loaded.model_copy(update={"options": Options(**{**loaded.options.model_dump(),
                                                                      "engine": "analytic"})}), base)
    maps = list(AnalyticEngine(p.options).run(p.toolpath, p.stock, p.default_tool))
    assert list(cl["cl"]) == [m.cl_index for m in maps] and len(maps) > 10
    assert list(cl["status"].astype(str)) == [m.status.value for m in maps]
    assert set(cl["engine"]) == {"analytic"} and {m.engine for m in maps} == {"analytic"}
    for column, values in (("removed_volume_mm3", [m.removed_volume for m in maps]),
                           ("ae_mm", [m.ae for m in maps]), ("ap_mm", [m.ap for m in maps])):
        assert list(cl[column]) == pytest.approx(values, abs=1e-12, rel=1e-12), column
    slot = cl[cl["operation"] == "Slot"]["removed_volume_mm3"].sum()
    assert slot == pytest.approx(SLOT_VOLUME, rel=1e-7)
    assert cl[cl["operation"] == "Ramp"]["removed_volume_mm3"].sum() > 1.0


def test_an_interrupted_analytic_run_resumes_to_identical_results(tmp_path):
    job, base = load_job(job_file(tmp_path, checkpoint_every=4))
    ref = run_job(job, base, tmp_path / "ref")
    assert not ref.interrupted and ref.conservation_error < 1e-9

    out = tmp_path / "out"
    assert run_job(job, base, out, on_cl=stop_after(9)).interrupted
    assert json.loads((out / "checkpoint" / "state.json").read_text())["next_cl"] == 9
    again = run_job(job, base, out)
    assert not again.interrupted and again.resumed_from == 9
    (cl_a, sl_a), (cl_b, sl_b) = tables(tmp_path / "ref"), tables(out)
    pd.testing.assert_frame_equal(cl_a, cl_b, check_exact=True)
    pd.testing.assert_frame_equal(sl_a, sl_b, check_exact=True)
    assert again.removed_volume == ref.removed_volume and again.final_volume == ref.final_volume


def test_a_job_that_does_not_name_the_engine_keeps_its_hash(tmp_path):
    """The hash below was computed before the engine and kernel budget options existed, for this very job."""
    (tmp_path / "p.nc").write_text("G21 G90\nT1 M6\nG0 X0 Y0 Z5\nG1 Z-1 F100\nG1 X10\nM30\n")
    job = Job(name="h", stock=StockSpec(kind="box", min=(0, 0, -10), max=(30, 20, 0)),
              tools=[ToolSpec(number=1, kind="flat", diameter=6, flute_length=15)], toolpaths=["p.nc"],
              options=Options(max_segment_length=3.0))
    assert job_hash(job, tmp_path) == "fe98d63b5b0a2285"
    brep = job.model_copy(update={"options": Options(max_segment_length=3.0, engine="brep")})
    analytic = job.model_copy(update={"options": Options(max_segment_length=3.0, engine="analytic")})
    assert job_hash(brep, tmp_path) == "fe98d63b5b0a2285"
    assert job_hash(analytic, tmp_path) != "fe98d63b5b0a2285"
    budget = job.model_copy(update={"options": Options(max_segment_length=3.0, kernel_budget_s=5.0)})
    assert job_hash(budget, tmp_path) == "fe98d63b5b0a2285"  # the kernel's budget changes no computed CL


def test_an_unknown_engine_is_refused_naming_the_flag(tmp_path):
    res = CliRunner().invoke(app, ["run", str(job_file(tmp_path)), "--out", str(tmp_path / "out"),
                                   "--engine", "parallel-brep"])
    assert res.exit_code != 0 and "engine" in res.output and "Traceback" not in res.output
    with pytest.raises(Exception, match="options.engine"):
        EngineOptions(engine="parallel-brep")


def test_a_solid_stock_is_refused_before_anything_is_written(tmp_path):
    path = job_file(tmp_path)
    (tmp_path / "blank.step").write_text("")  # refused by kind: the file is never read
    data = json.loads(path.read_text())
    data["stock"] = {"kind": "file", "path": "blank.step"}
    path.write_text(json.dumps(data))
    job, base = load_job(path)
    out = tmp_path / "out"
    with pytest.raises(UnsupportedStock, match="box stock or a round bar, got SolidStock"):
        run_job(job, base, out)
    assert not (out / "cl.parquet").exists()
    res = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "cli")])
    assert res.exit_code != 0 and "round bar" in res.output and "Traceback" not in res.output


def test_a_round_bar_runs_on_the_analytic_engine_and_adds_up(tmp_path, caplog):
    """engine 'auto' with a cylinder stock: the analytic engine runs it, the bar's volume less the
    removed total is the workpiece's, and 2 workers give the same tables bit for bit (they start from
    the bar, not its box)."""
    job, base = auto_job(tmp_path, stock={"kind": "cylinder", "base_center": [15, 10, -10], "radius": 18,
                                          "height": 10})
    with caplog.at_level(logging.INFO, logger="fusioncut.run"):
        r = run_job(job, base, tmp_path / "out", export_ipw=False)
    assert "engine auto: the analytic engine runs this job" in caplog.text
    res = load_results(tmp_path / "out")
    assert set(res.cl["engine"]) == {"analytic"} and (res.cl["status"] == "engaged").any()
    assert r.conservation_error < 1e-9
    parallel = job.model_copy(update={"options": job.options.model_copy(update={"workers": 2})})
    par = run_job(parallel, base, tmp_path / "par", export_ipw=False)
    assert par.removed_volume == r.removed_volume
    (cl_a, sl_a), (cl_b, sl_b) = tables(tmp_path / "out"), tables(tmp_path / "par")
    pd.testing.assert_frame_equal(cl_a, cl_b, check_exact=True)
    pd.testing.assert_frame_equal(sl_a, sl_b, check_exact=True)


def test_a_parallel_analytic_run_equals_one_process_and_resumes_across_them(tmp_path, caplog):
    """workers=2 (chunks of CLs on an embedded Dask cluster): the same tables, bit for bit, as one
    process; stopped after 9 CLs, the parallel run's checkpoint resumes in one process to them too."""
    job, base = load_job(job_file(tmp_path, checkpoint_every=4))
    ref = run_job(job, base, tmp_path / "ref")
    parallel_job = job.model_copy(update={"options": job.options.model_copy(update={"workers": 2})})
    with caplog.at_level(logging.INFO, logger="fusioncut.parallel"):
        par = run_job(parallel_job, base, tmp_path / "par")
    assert not par.interrupted and par.removed_volume == ref.removed_volume
    assert re.search(r"analytic engine on 2 workers: \d+ CLs .* serial fraction", caplog.text)
    (cl_a, sl_a), (cl_b, sl_b) = tables(tmp_path / "ref"), tables(tmp_path / "par")
    pd.testing.assert_frame_equal(cl_a, cl_b, check_exact=True)
    pd.testing.assert_frame_equal(sl_a, sl_b, check_exact=True)
    assert (tmp_path / "par" / "ipw.stl").read_bytes() == (tmp_path / "ref" / "ipw.stl").read_bytes()

    out = tmp_path / "out"
    assert run_job(parallel_job, base, out, on_cl=stop_after(9)).interrupted
    again = run_job(job, base, out)
    assert not again.interrupted and again.resumed_from == 9
    cl_c, sl_c = tables(out)
    pd.testing.assert_frame_equal(cl_a, cl_c, check_exact=True)
    pd.testing.assert_frame_equal(sl_a, sl_c, check_exact=True)


def test_an_unsupported_tool_is_refused_before_anything_is_written(tmp_path, monkeypatch):
    """The runner asks the engine about every tool first; the profile's refusal (a non-convex lower
    profile, which no tool family of a job makes today) is stood in for here."""
    refuse_the_ball(monkeypatch)
    job, base = load_job(job_file(tmp_path))
    out = tmp_path / "out"
    with pytest.raises(UnsupportedTool, match="not convex"):
        run_job(job, base, out)
    assert not (out / "cl.parquet").exists() and not (out / "checkpoint").exists()


def test_a_checkpoint_of_another_toolpath_is_refused(tmp_path):
    slot = PROGRAM.split("(Ramp)")[0] + "M30\n"
    engines, paths = [], []
    for name, program in (("a", slot), ("b", slot.replace("Y5 Z5", "Y6 Z5"))):
        (tmp_path / name).mkdir()
        (tmp_path / name / "prog.nc").write_text(program)
        job = Job(name=name, stock=StockSpec(**STOCK), tools=[ToolSpec(**TOOLS[0])], toolpaths=["prog.nc"],
                  options=Options(max_segment_length=3.0, engine="analytic"))
        paths.append(prepare_job(job, tmp_path / name))
        engines.append(AnalyticEngine(paths[-1].options))
    a, b = engines
    maps = a.run(paths[0].toolpath, paths[0].stock, paths[0].default_tool)
    for _ in range(9):
        next(maps)
    a.save_checkpoint(tmp_path / "ck", 9)
    assert b.load_checkpoint(tmp_path / "ck") == 9
    with pytest.raises(CheckpointMismatch, match="not this toolpath's"):
        next(b.process(paths[1].toolpath, paths[1].default_tool, start_at=9))
    assert a.load_checkpoint(tmp_path / "ck") == 9  # its own toolpath resumes
    assert next(a.process(paths[0].toolpath, paths[0].default_tool, start_at=9)).cl_index == 9


def auto_job(tmp_path: Path, **changes) -> tuple[Job, Path]:
    """The module's job without an engine named (engine 'auto', the default)."""
    path = job_file(tmp_path)
    data = json.loads(path.read_text())
    del data["options"]["engine"]
    data.update(changes)
    path.write_text(json.dumps(data))
    return load_job(path)


def test_auto_is_the_default_and_runs_the_analytic_engine_where_it_applies(tmp_path, caplog):
    job, base = auto_job(tmp_path)
    assert job.options.engine == "auto" and EngineOptions().engine == "auto"
    with caplog.at_level(logging.INFO, logger="fusioncut.run"):
        r = run_job(job, base, tmp_path / "out", export_ipw=False)
    assert "engine auto: the analytic engine runs this job" in caplog.text
    assert json.loads((tmp_path / "out" / "metadata.json").read_text())["engine_options"]["engine"] == "analytic"
    assert set(load_results(tmp_path / "out").cl["engine"]) == {"analytic"} and r.conservation_error < 1e-9
    assert json.loads((tmp_path / "out" / "checkpoint" / "run.json").read_text())["engine"] == "analytic"
    analytic = job.model_copy(update={"options": job.options.model_copy(update={"engine": "analytic"})})
    run_job(analytic, base, tmp_path / "named", export_ipw=False)
    (cl_a, sl_a), (cl_b, sl_b) = tables(tmp_path / "out"), tables(tmp_path / "named")
    pd.testing.assert_frame_equal(cl_a, cl_b, check_exact=True)
    pd.testing.assert_frame_equal(sl_a, sl_b, check_exact=True)


@pytest.mark.parametrize("case, why", [
    ("export", "an IPW export or snapshot is asked"),
    ("solid", "needs a box stock or a round bar and the stock is a SolidStock"),
    ("sampled", "sweep 'sampled' is asked"),
    ("tool", "cannot sweep a tool: tool T2: its lower profile is not convex"),
    ("2.5D", "every cut is a level or vertical move of a flat end mill"),
])
def test_auto_runs_the_brep_engine_where_the_analytic_one_does_not_apply_and_says_why(tmp_path, caplog, monkeypatch,
                                                                                      case, why):
    changes: dict = {}
    if case == "solid":
        from fusioncut.engines.brep.occ import write_step
        from fusioncut.engines.brep.stock import stock_solid

        write_step(stock_solid(BoxStock((0, -5, -10), (30, 25, 0))), str(tmp_path / "blank.step"))
        changes["stock"] = {"kind": "file", "path": "blank.step"}
    job, base = auto_job(tmp_path, **changes)
    if case == "sampled":
        job = job.model_copy(update={"options": job.options.model_copy(update={"sweep": "sampled"})})
    if case == "2.5D":  # the slot alone: a plunge and a level cut of the flat end mill
        (base / "prog.nc").write_text(PROGRAM.split("(Ramp)")[0] + "M30\n")
    if case == "tool":
        refuse_the_ball(monkeypatch)
    with caplog.at_level(logging.INFO, logger="fusioncut.run"):
        run_job(job, base, tmp_path / "out", export_ipw=case == "export", resume=False)
    assert "engine auto: the B-Rep engine runs this job, as" in caplog.text and why in caplog.text
    assert json.loads((tmp_path / "out" / "metadata.json").read_text())["engine_options"]["engine"] == "brep"
    assert set(load_results(tmp_path / "out").cl["engine"]) == {"brep"}
    assert (tmp_path / "out" / "ipw.step").exists() == (case == "export")


def test_a_checkpoint_of_the_engine_auto_did_not_resolve_to_is_not_resumed(tmp_path, caplog):
    job, base = auto_job(tmp_path)
    out = tmp_path / "out"
    assert run_job(job, base, out, on_cl=stop_after(9), export_ipw=False).interrupted  # analytic
    with caplog.at_level(logging.WARNING, logger="fusioncut.run"):
        again = run_job(job, base, out)  # the IPW export asked: brep
    assert again.resumed_from == 0 and "is of the analytic engine and this run's is the brep engine" in caplog.text
    assert set(load_results(out).cl["engine"]) == {"brep"} and (out / "ipw.step").exists()


def fail_analytic_at(monkeypatch, k: int) -> None:
    """Make the analytic step's volume stage raise on CL ``k`` (it runs once per CL, in order)."""
    real, calls = AnalyticEngine._removed, iter(range(10 ** 6))

    def removed(self, *args):
        if next(calls) == k:
            raise RuntimeError("a stand-in for a numerical failure")
        return real(self, *args)

    monkeypatch.setattr(AnalyticEngine, "_removed", removed)


ANGLES = ["entry_min_deg", "entry_max_deg", "exit_min_deg", "exit_max_deg"]


@pytest.mark.parametrize("operation", ["Slot", "Ramp"])
def test_a_cl_the_analytic_engine_cannot_compute_is_computed_by_the_brep_engine(tmp_path, monkeypatch, operation):
    """The volume stage raises on one CL (the slot's last, or a piece of the ramp, swept by the B-Rep
    engine as a level step): its row comes from the B-Rep engine on a local workpiece and agrees
    with an all-B-Rep run to 1e-6 mm³ and 0.001°; every other row is the all-analytic run's."""
    job, base = load_job(job_file(tmp_path))
    run_job(job, base, tmp_path / "ana", export_ipw=False)
    brep_job = job.model_copy(update={"options": job.options.model_copy(update={"engine": "brep"})})
    run_job(brep_job, base, tmp_path / "brep", export_ipw=False)
    ana, brep = load_results(tmp_path / "ana"), load_results(tmp_path / "brep")
    cut = ana.cl[(ana.cl["operation"] == operation) & (ana.cl["status"] == "engaged")]["cl"]
    k = int(cut.iloc[-1] if operation == "Slot" else cut.iloc[len(cut) // 2])
    fail_analytic_at(monkeypatch, k)
    r = run_job(job, base, tmp_path / "out", export_ipw=False)
    out = load_results(tmp_path / "out")
    row, want = out.row(k), brep.row(k)
    assert row["engine"] == "brep" and row["status"] == "engaged" and "RuntimeError" in row["warnings"]
    assert row["removed_volume_mm3"] == pytest.approx(want["removed_volume_mm3"], abs=1e-6)
    for column in ANGLES:
        assert row[column] == pytest.approx(want[column], abs=1e-3), column
    assert row["ap_mm"] == pytest.approx(want["ap_mm"], abs=1e-6) and row["ae_mm"] == pytest.approx(want["ae_mm"], abs=1e-6)
    s, w = out.slices_of(k), brep.slices_of(k)
    assert len(s) == len(w) and np.allclose(s[["entry_deg", "exit_deg"]], w[["entry_deg", "exit_deg"]], atol=1e-3)
    others, ref = out.cl[out.cl["cl"] != k], ana.cl[ana.cl["cl"] != k]
    pd.testing.assert_frame_equal(others.drop(columns=["time_ms"]).reset_index(drop=True),
                                  ref.drop(columns=["time_ms"]).reset_index(drop=True), check_exact=True)
    assert set(others["engine"]) == {"analytic"}
    assert r.removed_volume == pytest.approx(ana.cl["removed_volume_mm3"].sum() - ana.row(k)["removed_volume_mm3"]
                                             + want["removed_volume_mm3"], abs=1e-6)


def test_a_cl_neither_engine_computes_fails_alone(tmp_path, monkeypatch):
    """Where the B-Rep engine fails the CL too, its row is FAILED naming both errors; the run goes on
    and the later CLs are the all-analytic run's (the failed CL's sweep counts as cut)."""
    from fusioncut.engines.brep.engine import BRepEngine

    job, base = load_job(job_file(tmp_path))
    run_job(job, base, tmp_path / "ana", export_ipw=False)
    ana = load_results(tmp_path / "ana")
    k = int(ana.cl[(ana.cl["operation"] == "Slot") & (ana.cl["status"] == "engaged")]["cl"].iloc[1])
    fail_analytic_at(monkeypatch, k)

    def kernel_trouble(self, *cl):
        raise RuntimeError("a stand-in for a kernel failure")

    monkeypatch.setattr(BRepEngine, "step", kernel_trouble)
    run_job(job, base, tmp_path / "out", export_ipw=False)
    out = load_results(tmp_path / "out")
    row = out.row(k)
    assert row["status"] == "failed" and row["engine"] == "brep"
    assert "analytic engine: RuntimeError: a stand-in for a numerical failure" in row["reason"]
    assert "B-Rep engine: RuntimeError: a stand-in for a kernel failure" in row["reason"]
    later = out.cl[out.cl["cl"] > k].drop(columns=["time_ms"]).reset_index(drop=True)
    pd.testing.assert_frame_equal(later, ana.cl[ana.cl["cl"] > k].drop(columns=["time_ms"]).reset_index(drop=True),
                                  check_exact=True)


def test_an_analytic_runs_snapshots_are_meshes_of_the_workpiece_then(tmp_path):
    """``snapshot_cls`` with the analytic engine: ipw_cl<N>.stl, the workpiece after CL N (its volume
    the stock's less the CLs up to N, within the mesh's sloped walls), no STEP."""
    job, base = load_job(job_file(tmp_path))
    job = job.model_copy(update={"options": job.options.model_copy(update={"snapshot_cls": [4, 9]})})
    out = tmp_path / "out"
    r = run_job(job, base, out, export_ipw=False)
    assert sorted(p.name for p in r.exported) == ["ipw_cl000004.stl", "ipw_cl000009.stl"]
    assert not list(out.glob("*.step"))
    cl = load_results(out).cl
    for n in (4, 9):
        final = 30 * 20 * 10 - cl[cl["cl"] <= n]["removed_volume_mm3"].sum()
        assert abs(mesh_volume(read_stl(out / f"ipw_cl{n:06d}.stl")) - final) < 0.5 * 0.375 * 2 * (2 * 12 + 2 * 6)
    assert mesh_volume(read_stl(out / "ipw_cl000004.stl")) > mesh_volume(read_stl(out / "ipw_cl000009.stl"))
