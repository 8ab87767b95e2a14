"""The runner: inputs checked before anything is written, tool resolution, checkpoints and resume,
IPW export, and the Fusion-posted program end to end."""
from __future__ import annotations

import json
import logging
import shutil
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from fusioncut.engines.segments import segments_for
from fusioncut.errors import FusionCutError, InputError, ToolDefinitionError
from fusioncut.io.job import Job, Options, StockSpec, ToolSpec
from fusioncut.io.results import load_results
from fusioncut.model import BoxStock, FlatEndMill
from fusioncut.runner import RunPlan, prepare_job, run_job, run_toolpath

from shared_data import DATA
FUSION = DATA / "fusion-posted" / "1055_utab_265bit.nc"
TBL = DATA / "linuxcnc-tool-tables" / "configs_sim_axis_sim_mm.tbl"
needs_data = pytest.mark.skipif(not FUSION.exists(), reason="shared data not available")

# A slot and a pocket pass with an arc: about 30 CL segments with max_segment_length 3 mm.
PROGRAM = """\
G21 G90 G17
(Slot)
T1 M6
S10000 M3
G0 X-5 Y5 Z5
G1 Z-2 F300
G1 X12 F600
G1 Y9
G1 X-5
(Pocket)
G1 Y12 Z-3
G1 X20
G2 X26 Y12 I3 J0
G1 Y4
G0 Z5
M30
"""
RESULT_FILES = ("cl.parquet", "cl.csv", "slices.parquet", "slices.csv", "summary.csv", "metadata.json")
TIME_COLUMNS = ["time_ms"]


def small_job(tmp_path: Path, program: str = PROGRAM, **options) -> tuple[Job, Path]:
    """The small job, run by the B-Rep engine unless ``engine`` is given: these runner tests read
    its checkpoints, cells and failure shapes (the analytic engine's runs: test_runner_analytic)."""
    options = {"engine": "brep", **options}
    base = tmp_path / "job"
    base.mkdir(exist_ok=True)
    (base / "prog.nc").write_text(program)
    job = Job(name="small", stock=StockSpec(kind="box", min=(0, 0, -10), max=(30, 20, 0)),
              tools=[ToolSpec(number=1, kind="flat", diameter=6, flute_length=15)], toolpaths=["prog.nc"],
              options=Options(max_segment_length=3.0, **options))
    return job, base


def stop_after(n: int):
    """An ``on_cl`` that stops the run (as Ctrl-C does) once ``n`` CLs are done."""
    seen: list[int] = []

    def on_cl(m, total):
        seen.append(m.cl_index)
        if len(seen) == n:
            raise KeyboardInterrupt

    return on_cl


def tables(out: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    r = load_results(out)
    return r.cl.drop(columns=TIME_COLUMNS), r.slices


def assert_same_results(a: Path, b: Path) -> None:
    (cl_a, sl_a), (cl_b, sl_b) = tables(a), tables(b)
    pd.testing.assert_frame_equal(cl_a, cl_b, check_exact=True)
    pd.testing.assert_frame_equal(sl_a, sl_b, check_exact=True)
    sa = pd.read_csv(a / "summary.csv").drop(columns=["time_s"])
    sb = pd.read_csv(b / "summary.csv").drop(columns=["time_s"])
    pd.testing.assert_frame_equal(sa, sb, check_exact=True)


def result_files(out: Path) -> list[str]:
    return sorted(p.name for p in out.glob("*") if p.name in RESULT_FILES) if out.exists() else []


# --------------------------------------------------------------------------------------------------
# checkpoints and resume


def test_checkpoints_follow_the_rows_on_disk(tmp_path):
    """Every checkpoint_every CLs the rows are on disk first, then the checkpoint names the next CL."""
    job, base = small_job(tmp_path, checkpoint_every=4)
    out = tmp_path / "out"
    seen = []

    def check(m, total):
        if (m.cl_index + 1) % 4 == 0 and m.cl_index + 1 < total:
            state = json.loads((out / "checkpoint" / "state.json").read_text())
            on_disk = list(load_results(out).cl["cl"])
            seen.append((state["next_cl"], on_disk))

    result = run_job(job, base, out, on_cl=check, export_ipw=False)
    assert len(seen) >= 5
    for next_cl, on_disk in seen:
        assert on_disk == list(range(next_cl))
    total = sum(op.cls for op in result.operations.values())
    assert json.loads((out / "checkpoint" / "state.json").read_text())["next_cl"] == total


def test_interrupted_run_resumes_to_identical_results(tmp_path):
    job, base = small_job(tmp_path, checkpoint_every=4)
    ref = run_job(job, base, tmp_path / "ref", export_ipw=False)
    assert not ref.interrupted and ref.resumed_from == 0

    out = tmp_path / "out"
    r1 = run_job(job, base, out, on_cl=stop_after(7), export_ipw=False)
    assert r1.interrupted
    assert json.loads((out / "checkpoint" / "state.json").read_text())["next_cl"] == 7
    assert list(load_results(out).cl["cl"]) == list(range(7))

    plans: list[RunPlan] = []
    second_seen: list[int] = []
    r2 = run_job(job, base, out, on_cl=lambda m, t: second_seen.append(m.cl_index), on_start=plans.append,
                 export_ipw=False)
    assert not r2.interrupted and r2.resumed_from == 7
    assert second_seen[0] == 7 and plans[0].start_at == 7 and sum(plans[0].done.values()) == 7
    assert_same_results(tmp_path / "ref", out)
    assert r2.removed_volume == ref.removed_volume
    assert sum(op.removed for op in r2.operations.values()) == pytest.approx(ref.removed_volume, abs=1e-9)
    assert {k: v.cls for k, v in r2.operations.items()} == {k: v.cls for k, v in ref.operations.items()}
    assert r2.final_volume == pytest.approx(ref.final_volume, rel=1e-12)
    assert r2.conservation_error < 1e-6


def test_a_checkpoint_that_cannot_be_written_never_ends_the_run(tmp_path, caplog, monkeypatch):
    """The kernel refused to rebuild a layered cell's faces while a checkpoint was written
    (StdFail_NotDone, on Fusion programs with R-format helical entries): the run ended in a traceback.
    Now the failure is logged naming the CL, the run finishes with every CL, and a resume starts
    from the last checkpoint written."""
    from fusioncut.engines.brep.engine import BRepEngine

    job, base = small_job(tmp_path, checkpoint_every=4)
    ref = run_job(job, base, tmp_path / "ref", export_ipw=False)
    save = BRepEngine.save_checkpoint

    def flaky(self, folder, next_cl):
        if next_cl >= 8:
            raise RuntimeError("StdFail_NotDone: BRep_API: command not done")
        save(self, folder, next_cl)

    monkeypatch.setattr(BRepEngine, "save_checkpoint", flaky)
    out = tmp_path / "out"
    with caplog.at_level(logging.ERROR, logger="fusioncut.run"):
        result = run_job(job, base, out, export_ipw=False)
    assert not result.interrupted
    assert_same_results(tmp_path / "ref", out)
    assert result.removed_volume == ref.removed_volume
    assert "the checkpoint before CL 8 could not be written (RuntimeError: StdFail_NotDone" in caplog.text
    assert json.loads((out / "checkpoint" / "state.json").read_text())["next_cl"] == 4


def test_rows_past_the_checkpoint_are_dropped_on_resume(tmp_path):
    """A run killed after flushing rows beyond its last checkpoint: those rows are computed again,
    never listed twice."""
    job, base = small_job(tmp_path, checkpoint_every=4)
    run_job(job, base, tmp_path / "ref", export_ipw=False)
    out = tmp_path / "out"
    saved = tmp_path / "checkpoint-at-8"

    def kill_late(m, total):
        if m.cl_index == 9:  # the checkpoint of CL 8 is on disk: keep a copy of it
            shutil.copytree(out / "checkpoint", saved)
        if m.cl_index == 13:
            raise KeyboardInterrupt

    run_job(job, base, out, on_cl=kill_late, export_ipw=False)
    assert list(load_results(out).cl["cl"]) == list(range(14))
    # as if the process had died before writing the checkpoint at CL 14
    shutil.rmtree(out / "checkpoint")
    shutil.copytree(saved, out / "checkpoint")
    r = run_job(job, base, out, export_ipw=False)
    assert r.resumed_from == 8
    assert_same_results(tmp_path / "ref", out)


def test_finished_run_called_again_keeps_its_results(tmp_path):
    job, base = small_job(tmp_path)
    out = tmp_path / "out"
    first = run_job(job, base, out, export_ipw=False)
    again = run_job(job, base, out, on_cl=lambda m, t: pytest.fail("nothing is left to compute"),
                    export_ipw=False)
    total = sum(op.cls for op in first.operations.values())
    assert again.resumed_from == total
    assert again.removed_volume == first.removed_volume
    assert list(load_results(out).cl["cl"]) == list(range(total))


def test_another_job_or_fresh_starts_over(tmp_path):
    job, base = small_job(tmp_path, checkpoint_every=3)
    out = tmp_path / "out"

    def stop(m, total):
        if m.cl_index == 5:
            raise KeyboardInterrupt

    run_job(job, base, out, on_cl=stop, export_ipw=False)
    changed = job.model_copy(update={"options": Options(max_segment_length=3.0, slice_height=0.5)})
    seen: list[int] = []
    r = run_job(changed, base, out, on_cl=lambda m, t: seen.append(m.cl_index), export_ipw=False)
    assert r.resumed_from == 0 and seen[0] == 0
    assert list(load_results(out).cl["cl"]) == list(range(len(seen)))

    # the same job but resume=False: computed again from CL 0
    seen.clear()
    r = run_job(changed, base, out, on_cl=lambda m, t: seen.append(m.cl_index), resume=False, export_ipw=False)
    assert r.resumed_from == 0 and seen[0] == 0


def test_run_options_do_not_break_a_resume(tmp_path):
    """checkpoint_every and snapshot_cls steer the run, not its results: changing them still resumes."""
    job, base = small_job(tmp_path, checkpoint_every=4)
    out = tmp_path / "out"

    def stop(m, total):
        if m.cl_index == 5:
            raise KeyboardInterrupt

    run_job(job, base, out, on_cl=stop, export_ipw=False)
    other = job.model_copy(update={"options": Options(max_segment_length=3.0, checkpoint_every=50, engine="brep")})
    assert run_job(other, base, out, export_ipw=False).resumed_from == 6


# --------------------------------------------------------------------------------------------------
# IPW export, snapshots, per-CL log


def test_ipw_export_and_snapshots(tmp_path):
    from fusioncut.engines.brep.occ import volume
    from fusioncut.engines.brep.stock import stock_solid
    from fusioncut.model import SolidStock

    job, base = small_job(tmp_path, snapshot_cls=[8])
    out = tmp_path / "out"
    r = run_job(job, base, out)
    assert {p.name for p in r.exported} == {"ipw.step", "ipw.stl", "ipw_cl000008.step"}
    assert volume(stock_solid(SolidStock(out / "ipw.step"))) == pytest.approx(r.final_volume, rel=1e-6)
    assert set(load_results(out).cl["engine"]) == {"brep"}  # the B-Rep engine's rows say so
    removed_0_to_8 = load_results(out).cl.query("cl <= 8")["removed_volume_mm3"].sum()
    assert removed_0_to_8 > 0
    snap = volume(stock_solid(SolidStock(out / "ipw_cl000008.step")))
    assert snap == pytest.approx(r.stock_volume - removed_0_to_8, rel=1e-6)
    stl = (out / "ipw.stl").read_bytes()
    triangles = int.from_bytes(stl[80:84], "little")
    assert triangles > 12 and len(stl) == 84 + 50 * triangles  # binary STL, complete

    r2 = run_job(job, base, tmp_path / "no-export", export_ipw=False)
    assert not (tmp_path / "no-export" / "ipw.step").exists() and not (tmp_path / "no-export" / "ipw.stl").exists()
    assert {p.name for p in r2.exported} == {"ipw_cl000008.step"}


def test_debug_log_traces_every_cl(tmp_path, caplog):
    job, base = small_job(tmp_path)
    with caplog.at_level(logging.DEBUG, logger="fusioncut"):
        r = run_job(job, base, tmp_path / "out", export_ipw=False)
    lines = [rec.getMessage() for rec in caplog.records if rec.levelno == logging.DEBUG
             and rec.getMessage().startswith("CL ")]
    total = sum(op.cls for op in r.operations.values())
    assert len(lines) == total
    cl = load_results(tmp_path / "out").cl
    for line, (_, row) in zip(lines, cl.iterrows()):
        assert line.startswith(f"CL {row['cl']} {row['file']}:{row['line']} {row['status']} ")
        assert f"sweep_method={row['sweep_method']}" in line
        assert "sweep=" in line and "total=" in line
    engaged = [ln for ln in lines if " engaged " in ln]
    assert engaged and all("boolean=" in ln and "boolean=-" not in ln for ln in engaged)


# --------------------------------------------------------------------------------------------------
# tools and stock


def test_only_tool_is_used_for_moves_without_t_word(tmp_path, caplog):
    job, base = small_job(tmp_path, program=PROGRAM.replace("T1 M6\n", ""))
    with caplog.at_level(logging.WARNING, logger="fusioncut"):
        p = prepare_job(job, base)
    assert p.default_tool is not None and p.default_tool.diameter == 6
    # without the T line the first move is on line 4
    assert any("without a T word" in r.getMessage() and "prog.nc:4" in r.getMessage() for r in caplog.records)


def test_no_t_word_and_two_tools_names_the_first_move(tmp_path):
    job, base = small_job(tmp_path, program=PROGRAM.replace("T1 M6\n", ""))
    job = job.model_copy(update={"tools": [*job.tools, ToolSpec(number=2, kind="ball", diameter=4,
                                                                 flute_length=10)]})
    with pytest.raises(InputError, match=r"prog\.nc:4:.*no tool.*2 tools"):
        prepare_job(job, base)
    assert not (tmp_path / "out").exists()


def test_undefined_tool_names_its_first_move(tmp_path):
    job, base = small_job(tmp_path, program=PROGRAM.replace("(Pocket)\n", "(Pocket)\nT7 M6\n"))
    with pytest.raises(InputError, match=r"prog\.nc:12:.*T7"):
        prepare_job(job, base)


def test_tool_library_resolves_tools_and_logs_its_warnings(tmp_path, caplog):
    if not TBL.exists():
        pytest.skip("shared data not available")
    job, base = small_job(tmp_path, program=PROGRAM.replace("T1 M6", "T2 M6"))
    shutil.copy(TBL, base / "tools.tbl")
    job = job.model_copy(update={"tools": [], "tool_library": "tools.tbl"})
    with caplog.at_level(logging.WARNING, logger="fusioncut"):
        p = prepare_job(job, base)
    assert p.toolpath.tools[2].diameter == 1.5  # T2 P4 Z0.1 D1.5 ;1.5mm end mill
    messages = " ".join(r.getMessage() for r in caplog.records)
    assert "state no units" in messages and "T3 left out" in messages and "tap drill" in messages
    # T3 is a tap drill: refused by the library, so a program using it fails with that reason
    refused = job.model_copy(update={"toolpaths": ["drill.nc"]})
    (base / "drill.nc").write_text(PROGRAM.replace("T1 M6", "T3 M6"))
    with pytest.raises(ToolDefinitionError, match=r"drill\.nc:5:.*T3.*not a milling cutter"):
        prepare_job(refused, base)


def test_stock_top_is_passed_to_the_inference(tmp_path):
    job, base = small_job(tmp_path)
    job = job.model_copy(update={"stock": StockSpec(kind="infer", top=1.5, margin=1.0)})
    p = prepare_job(job, base)
    assert isinstance(p.stock, BoxStock) and p.stock.inferred
    assert p.stock.maximum[2] == 1.5
    assert p.stock.minimum[2] == pytest.approx(-3 - 1.0)  # deepest feed -3 mm, margin 1 mm
    guessed = prepare_job(job.model_copy(update={"stock": StockSpec(kind="infer")}), base)
    assert guessed.stock.maximum[2] == 0.0  # cuts below z = 0: the work origin is on the top


# --------------------------------------------------------------------------------------------------
# bad input: nothing written


def test_bad_program_fails_before_writing(tmp_path):
    job, base = small_job(tmp_path, program=PROGRAM.replace("G1 X12 F600", "G1 X[12 +"))
    out = tmp_path / "out"
    with pytest.raises(InputError, match=r"prog\.nc:7"):
        run_job(job, base, out)
    assert result_files(out) == []


FUZZ_BASE = PROGRAM.splitlines()
GCODE_CHARS = "GMTXYZIJKFSPRLQNOD0123456789.-+ []#<>()=;%/*\t"


@st.composite
def mutated_programs(draw) -> str:
    lines = list(FUZZ_BASE)
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(lines) - 1))
        kind = draw(st.sampled_from(["insert", "delete", "replace", "new_line", "truncate"]))
        line = lines[i]
        if kind == "insert":
            pos = draw(st.integers(0, len(line)))
            lines[i] = line[:pos] + draw(st.text(GCODE_CHARS, min_size=1, max_size=6)) + line[pos:]
        elif kind == "delete" and line:
            pos = draw(st.integers(0, len(line) - 1))
            lines[i] = line[:pos] + line[pos + draw(st.integers(1, 4)):]
        elif kind == "replace":
            lines[i] = draw(st.text(GCODE_CHARS, max_size=20))
        elif kind == "new_line":
            lines.insert(i, draw(st.text(GCODE_CHARS, max_size=20)))
        else:
            lines = lines[:i + 1]
    return "\n".join(lines) + "\n"


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(program=mutated_programs(), strict=st.booleans(), infer=st.booleans())
def test_any_failing_read_raises_our_error_and_writes_nothing(tmp_path_factory, program, strict, infer):
    tmp = tmp_path_factory.mktemp("fuzz")
    job, base = small_job(tmp, program=program)
    job = job.model_copy(update={"strict": strict, **({"stock": StockSpec(kind="infer")} if infer else {})})
    try:
        prepare_job(job, base)
    except FusionCutError:
        event("input refused")
    except Exception as exc:  # noqa: BLE001
        pytest.fail(f"{type(exc).__name__} instead of a FusionCutError for:\n{program}\n{exc}")
    else:
        event("input accepted")
        return  # valid input: running the engine is tested elsewhere
    out = tmp / "out"
    with pytest.raises(FusionCutError):
        run_job(job, base, out)
    assert result_files(out) == []
    assert not (out / "checkpoint").exists()


# --------------------------------------------------------------------------------------------------
# the Fusion-posted program


def fusion_job() -> tuple[Job, Path]:
    return Job(name="utab", stock=StockSpec(kind="infer"), toolpaths=[FUSION.name]), FUSION.parent


def check_complete_run(out: Path, n: int, result) -> pd.DataFrame:
    cl = load_results(out).cl
    assert list(cl["cl"]) == list(range(n))  # every CL reported, in order
    assert (cl["status"] == "failed").sum() == 0, cl[cl["status"] == "failed"][["cl", "reason"]]
    assert result.conservation_error < 1e-6
    assert (cl["line"].diff().dropna() >= 0).all()  # program order: source lines never go back
    return cl


@needs_data
def test_fusion_program_tool_comes_from_the_post_comment():
    p = prepare_job(*fusion_job())
    tool = p.toolpath.tools[1]
    assert isinstance(tool, FlatEndMill) and tool.diameter == 2.65 and tool.flute_length == 12.55
    assert p.default_tool is None and p.stock.maximum[2] == 0.0


@needs_data
def test_fusion_program_first_cls_end_to_end(tmp_path):
    p = prepare_job(*fusion_job())
    moves = p.toolpath.moves[:150]
    n = len(segments_for(moves, p.options))
    assert n >= 150
    tp = replace(p.toolpath, moves=moves)
    r = run_toolpath(tp, p.stock, tmp_path / "out", p.options, default_tool=p.default_tool, job_id=p.job_id,
                     export_ipw=False)
    cl = check_complete_run(tmp_path / "out", n, r)
    assert (cl["status"] == "engaged").sum() > 100
    assert set(cl["operation"]) == {"2D Adaptive2"} and set(cl["tool"]) == {"T1"}
    assert r.removed_volume == pytest.approx(cl["removed_volume_mm3"].sum(), rel=1e-9)


@pytest.mark.slow
@needs_data
def test_fusion_program_whole_run(tmp_path):
    job, base = fusion_job()
    out = tmp_path / "out"
    r = run_job(job, base, out)
    p = prepare_job(job, base)
    n = len(segments_for(p.toolpath.moves, p.options))
    cl = check_complete_run(out, n, r)
    assert set(cl["operation"]) == {"2D Adaptive2", "2D Contour2", "2D Contour3"}
    assert (out / "ipw.step").stat().st_size > 0 and (out / "ipw.stl").stat().st_size > 84
