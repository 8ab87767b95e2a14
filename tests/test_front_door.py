"""The front door: ``fusioncut.simulate`` and the top-level names."""
from __future__ import annotations

import doctest
import json
import subprocess
import sys
from dataclasses import replace

import pytest

import fusioncut as fc
from fusioncut.io.results import load_results

SLOT = "G21 G90 G17\nT1 M6\nS10000 M3\nG0 X0 Y10 Z5\nG1 Z-3 F300\nG1 X50 F600\nG0 Z5\nM30\n"
STOCK = "box:10,0,-10,40,20,0"
TOOLS = {1: fc.FlatEndMill(10.0, 20.0)}
OPTIONS = fc.EngineOptions(max_segment_length=10.0)


@pytest.fixture
def slot(tmp_path):
    program = tmp_path / "slot.nc"
    program.write_text(SLOT)
    return program


def _table(res):
    return res.cl[["cl", "status", "ae_mm", "ap_mm", "removed_volume_mm3"]].to_dict("records")


def test_the_doctests_of_the_api_module_pass():
    import fusioncut.api

    failed, attempted = doctest.testmod(fusioncut.api)
    assert attempted > 5 and failed == 0


def test_import_fusioncut_loads_neither_the_kernel_nor_the_extras():
    code = ("import sys, fusioncut; fusioncut.FlatEndMill; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & "
            "{'OCP', 'dask', 'distributed', 'fastapi', 'uvicorn', 'matplotlib', 'pandas'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_every_public_name_resolves():
    for name in fc.__all__:
        assert getattr(fc, name) is not None, name
    assert fc.load_results is load_results
    import fusioncut.errors

    errors = {n for n, v in vars(fusioncut.errors).items() if isinstance(v, type) and issubclass(v, fc.FusionCutError)}
    assert errors <= set(fc.__all__)
    with pytest.raises(AttributeError):
        fc.no_such_name  # noqa: B018


def test_the_maps_of_the_iteration_are_the_rows_of_the_results(slot, tmp_path):
    run = fc.simulate(slot, stock=STOCK, tools=TOOLS, options=OPTIONS, out=tmp_path / "out")
    maps = list(run)
    res = run.results()
    assert [m.cl_index for m in maps] == list(res.cl["cl"]) == list(range(len(maps)))
    assert [m.status.value for m in maps] == list(res.cl["status"])
    assert [round(m.ap, 9) for m in maps] == [round(v, 9) for v in res.cl["ap_mm"]]
    assert abs(run.result.removed_volume - 30 * 10 * 3) < 1e-6 * 900
    assert (tmp_path / "out" / "ipw.step").is_file()
    # the job it ran, written beside the results, runs again to the same results
    job = json.loads((tmp_path / "out" / "job.json").read_text())
    assert job["toolpaths"] == [str(slot)] and job["stock"]["kind"] == "box"
    again = fc.simulate(tmp_path / "out" / "job.json", out=tmp_path / "again")
    assert _table(again.results()) == _table(res)


def test_a_run_is_iterated_once(slot):
    run = fc.simulate(slot, stock=STOCK, tools=TOOLS, options=OPTIONS)
    assert len(list(run)) > 3
    with pytest.raises(fc.RunConsumed, match="results"):
        list(run)


def test_leaving_the_iteration_early_stops_and_results_continue_the_run(slot, tmp_path):
    whole = fc.simulate(slot, stock=STOCK, tools=TOOLS, options=OPTIONS).results()
    run = fc.simulate(slot, stock=STOCK, tools=TOOLS, options=OPTIONS)
    first = []
    for m in run:
        first.append(m.cl_index)
        if len(first) == 2:
            break
    assert first == [0, 1]
    assert run.result is None  # stopped, not finished
    assert _table(run.results()) == _table(whole)


def test_the_ipw_is_the_workpiece_after_the_last_cl(slot):
    from fusioncut.engines.brep.occ import volume

    run = fc.simulate(slot, stock=STOCK, tools=TOOLS, options=replace(OPTIONS, engine="brep"))  # the B-Rep IPW
    shape = run.ipw()
    assert abs(volume(shape) - (30 * 20 * 10 - 30 * 10 * 3)) < 1e-6 * 6000
    assert abs(volume(shape) - run.result.final_volume) < 1e-9 * 6000


def test_an_analytic_run_says_it_has_no_workpiece(slot):
    run = fc.simulate(slot, stock=STOCK, tools=TOOLS, options=replace(OPTIONS, engine="analytic"))
    with pytest.raises(fc.FusionCutError, match="the analytic engine ran this job and keeps no B-Rep workpiece"):
        run.ipw()


def test_a_toolpath_in_memory_and_the_program_file_give_the_same_maps(slot):
    toolpath = fc.read_toolpath(slot, TOOLS)
    from_memory = fc.simulate(toolpath, stock=STOCK, tools=TOOLS, options=OPTIONS).results()
    from_file = fc.simulate(slot, stock=STOCK, tools=TOOLS, options=OPTIONS).results()
    assert _table(from_memory) == _table(from_file)


def test_a_job_with_options_given_as_a_dict(slot):
    job = fc.Job.model_validate({"stock": {"kind": "box", "min": [10, 0, -10], "max": [40, 20, 0]},
                                 "tools": [{"number": 1, "kind": "flat", "diameter": 10, "flute_length": 20}],
                                 "toolpaths": [str(slot)], "options": {"slice_height": 2.0}})
    run = fc.simulate(job, options={"max_segment_length": 10.0})
    assert run.options.slice_height == 2.0 and run.options.max_segment_length == 10.0
    res = run.results()
    mid_slot = res.cl[res.cl["status"] == "engaged"]["cl"].iloc[2]
    # 3 mm deep in 2 mm slices (the analytic engine finds the contact's top to 1e-10 mm)
    assert list(res.slices[res.slices["cl"] == mid_slot]["z_tool_mm"]) == pytest.approx([1.0, 2.5], abs=1e-9)


def test_the_stock_is_inferred_by_default(slot):
    run = fc.simulate(slot, tools=TOOLS, options=OPTIONS)
    assert run.stock.inferred and run.stock.maximum[2] == 0.0


@pytest.mark.parametrize("kwargs, message", [
    ({"stock": "box:1,2,3"}, "box needs"),
    ({"options": {"slice_height": -1}}, "options.slice_height"),
    ({"options": {"no_such_option": 1}}, "options.no_such_option"),
    ({"tools": "missing.tools"}, "tool library not found"),
])
def test_bad_input_is_refused_when_simulate_returns(slot, kwargs, message):
    with pytest.raises(fc.InputError, match=message):
        fc.simulate(slot, **{"tools": TOOLS, **kwargs})


def test_a_missing_program_is_named(tmp_path):
    with pytest.raises(fc.InputError, match="nothing.nc"):
        fc.simulate(tmp_path / "nothing.nc")


def test_a_toolpath_in_memory_takes_a_stock_entry_with_its_top(slot):
    toolpath = fc.read_toolpath(slot, TOOLS)
    run = fc.simulate(toolpath, stock={"kind": "infer", "top": 1.0, "margin": 0.5}, tools=TOOLS, options=OPTIONS)
    assert run.stock.maximum[2] == 1.0 and run.stock.inferred
    by_file = fc.simulate(slot, stock={"kind": "infer", "top": 1.0, "margin": 0.5}, tools=TOOLS, options=OPTIONS)
    assert by_file.stock == run.stock
