"""Job files: validation, stock specs, the job hash and toolpath dispatch."""
from __future__ import annotations

import json

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
