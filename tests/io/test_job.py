"""Job files: validation, stock specs, the job hash and toolpath dispatch."""
from __future__ import annotations

import json
from dataclasses import replace

import pytest

from fusioncut.errors import InputError
from fusioncut.io.job import Job, Options, StockSpec, build_stock, job_hash, load_job, read_toolpath
from fusioncut.model import ArcMove, LinearMove


def write_job(tmp_path, **fields) -> object:
    doc = {"stock": {"kind": "infer"}, "toolpaths": ["p.nc"], **fields}
    path = tmp_path / "job.json"
    path.write_text(json.dumps(doc))
    return path


def test_stock_top_only_for_inferred_stock(tmp_path):
    assert StockSpec(kind="infer", top=2.5).top == 2.5
    with pytest.raises(InputError, match="stock: .*'top' applies to inferred stock only"):
        load_job(write_job(tmp_path, stock={"kind": "box", "min": [0, 0, 0], "max": [1, 1, 1], "top": 1}))
    with pytest.raises(InputError, match="margin"):
        load_job(write_job(tmp_path, stock={"kind": "infer", "margin": -1}))


def test_run_options_are_validated(tmp_path):
    job, _ = load_job(write_job(tmp_path, options={"checkpoint_every": 10, "snapshot_cls": [0, 5]}))
    assert job.options.checkpoint_every == 10 and job.options.snapshot_cls == [0, 5]
    assert Options().checkpoint_every == 200
    with pytest.raises(InputError, match="snapshot_cls"):
        load_job(write_job(tmp_path, options={"snapshot_cls": [-1]}))
    with pytest.raises(InputError, match="checkpoint_every"):
        load_job(write_job(tmp_path, options={"checkpoint_every": -5}))


def test_job_hash_follows_results_not_run_options(tmp_path):
    (tmp_path / "p.nc").write_text("G0 X1\n")
    job = Job(stock=StockSpec(kind="infer"), toolpaths=["p.nc"])
    h = job_hash(job, tmp_path)
    assert len(h) == 16
    steering = job.model_copy(update={"options": Options(checkpoint_every=7, snapshot_cls=[3])})
    assert job_hash(steering, tmp_path) == h
    assert job_hash(job.model_copy(update={"options": Options(slice_height=0.5)}), tmp_path) != h
    assert job_hash(job.model_copy(update={"stock": StockSpec(kind="infer", top=1.0)}), tmp_path) != h
    (tmp_path / "p.nc").write_text("G0 X2\n")  # same job, other program bytes
    assert job_hash(job, tmp_path) != h


def test_stock_file_must_exist_and_its_bytes_count(tmp_path):
    spec = StockSpec(kind="file", path="blank.step")
    with pytest.raises(InputError, match="blank.step.*not found"):
        build_stock(spec, tmp_path)
    (tmp_path / "blank.step").write_text("ISO-10303-21;\n")
    assert build_stock(spec, tmp_path).path == tmp_path / "blank.step"
    job = Job(stock=spec, toolpaths=["p.nc"])
    h = job_hash(job, tmp_path)
    (tmp_path / "blank.step").write_text("ISO-10303-21; changed\n")
    assert job_hash(job, tmp_path) != h


def test_read_toolpath_dispatches_on_the_suffix(tmp_path):
    (tmp_path / "a.ngc").write_text("G21\nG1 X10 F100\nG2 X20 I5 J0\n")
    tp = read_toolpath(tmp_path / "a.ngc")
    assert [type(m) for m in tp.moves] == [LinearMove, ArcMove]
    (tmp_path / "a.apt").write_text("UNITS/MM\nCUTTER/6\nFEDRAT/100\nGOTO/0,0,0\nGOTO/5,0,0\n")
    assert read_toolpath(tmp_path / "a.apt").moves[-1].end == (5.0, 0.0, 0.0)
    (tmp_path / "a.json").write_text("{not json")
    with pytest.raises(InputError, match=r"a\.json:1"):
        read_toolpath(tmp_path / "a.json")
    with pytest.raises(InputError, match="missing.nc"):
        read_toolpath(tmp_path / "missing.nc")


@pytest.mark.parametrize("text", ["[" * 100_000, '{"a":' * 100_000, "{\"name\": NaN}"])
def test_a_job_file_that_breaks_the_parser_is_refused_naming_it(tmp_path, text):
    """100,000 levels of nesting raised RecursionError out of the CLI (a traceback); NaN is no JSON number."""
    path = tmp_path / "deep.json"
    path.write_text(text)
    with pytest.raises(InputError, match=r"deep\.json.*(nests too deeply|not a number)"):
        load_job(path)


def test_a_bad_job_file_names_its_line_and_column(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text('{\n  "name": "x",\n  "stock": }\n')
    with pytest.raises(InputError, match=r"bad\.json:3:12: not valid JSON"):
        load_job(path)


# --------------------------------------------------------------------------------------------------
# the options generated from EngineOptions, and jobs made from programs


def test_the_jobs_engine_options_are_engine_options_fields_with_their_defaults_and_help():
    import dataclasses

    from fusioncut.engines.base import EngineOptions
    from fusioncut.io.job import ENGINE_ONLY, RUN_OPTIONS

    engine = {f.name: f for f in dataclasses.fields(EngineOptions)}
    job_fields = set(Options.model_fields) - RUN_OPTIONS
    assert job_fields == set(engine) - ENGINE_ONLY and ENGINE_ONLY <= set(engine)
    for name in job_fields:
        field = Options.model_fields[name]
        assert field.default == getattr(engine[name].default, "value", engine[name].default), name
        assert field.description == engine[name].metadata["help"], name
    # a job's engine options make the EngineOptions they say, every field included
    values = {"slice_height": 0.5, "max_segment_length": 2.0, "chord_tolerance": 2e-3, "ramp_step": 0.1,
              "sweep": "sampled", "cell_size": None, "min_chip_thickness": 0.0, "engine": "analytic",
              "kernel_budget_s": 30.0}
    assert set(values) == job_fields
    made = EngineOptions(**Options(**values).model_dump(exclude=set(RUN_OPTIONS)))
    assert {k: getattr(made, k) for k in values} == values


@pytest.mark.parametrize("options, message", [
    ({"slice_height": 0}, "options.slice_height"), ({"cell_size": -1}, "options.cell_size"),
    ({"min_chip_thickness": -1e-3}, "options.min_chip_thickness"), ({"sweep": "step"}, "options.sweep"),
    ({"layers": False}, "options.layers"),  # an engine-only option is not a job option
    ({"kernel_budget_s": 0}, "options.kernel_budget_s"),
])
def test_bad_engine_options_name_the_field(tmp_path, options, message):
    with pytest.raises(InputError, match=message):
        load_job(write_job(tmp_path, options=options))


def test_tool_spec_of_a_model_tool_builds_it_back():
    from fusioncut.io.job import ToolSpec
    from fusioncut.model import (AptCutter, AptParameters, BallEndMill, BullNoseEndMill, ChamferMill, Drill,
                                 FlatEndMill, SpindleDirection, TaperedEndMill)

    tools = [FlatEndMill(10, 25, flutes=3, helix_angle=35, spindle=SpindleDirection.CCW, shank_diameter=12,
                         neck_diameter=9, shoulder_length=30, overall_length=80, name="flat"),
             BallEndMill(6, 15), BullNoseEndMill(8, 20, corner_radius=1.5), TaperedEndMill(6, 20, taper_angle=3),
             ChamferMill(12, 8, tip_diameter=2, taper_angle=45), Drill(5, 30, point_angle=135),
             AptCutter(6, 10, apt_parameters=AptParameters(6, 0, 3, 0, 0, 0, 10))]
    for n, tool in enumerate(tools, 1):
        spec = ToolSpec.of(tool, n)
        assert spec.number == n and spec.kind == tool.kind
        assert spec.build() == replace(tool, number=n), tool.kind
    with pytest.raises(InputError, match="T number"):
        ToolSpec.of(FlatEndMill(6, 10))


def test_a_program_job_states_its_inputs_absolutely(tmp_path, monkeypatch):
    from fusioncut.io.job import program_job
    from fusioncut.model import BoxStock, FlatEndMill

    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.nc").write_text("G0 X1\n")
    (tmp_path / "blank.step").write_text("ISO-10303-21;\n")
    job = program_job("p.nc")
    assert job.name == "p" and job.toolpaths == [str(tmp_path / "p.nc")] and job.stock.kind == "infer"
    assert program_job("p.nc", stock="blank.step").stock.path == str(tmp_path / "blank.step")
    assert program_job("p.nc", stock=BoxStock((0, 0, -1), (1, 2, 0))).stock.max == (1.0, 2.0, 0.0)
    assert program_job("p.nc", stock={"kind": "infer", "top": 2}).stock.top == 2.0
    tooled = program_job("p.nc", tools={3: FlatEndMill(6, 10)}, options={"slice_height": 0.25})
    assert [t.number for t in tooled.tools] == [3] and tooled.options.slice_height == 0.25
    with pytest.raises(InputError, match="tool library not found"):
        program_job("p.nc", tools="lib.tbl")
    with pytest.raises(InputError, match="stock.margin: .*greater than or equal to 0"):
        program_job("p.nc", stock={"kind": "infer", "margin": -1})
