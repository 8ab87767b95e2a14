"""Downloads of a job's result files name its files as the user did, and change nothing else: the
table's other cells (quoted ones too), the Parquet types and metadata, the JSON values; a listing's
size is the download's size. No service process: the rewriting of :mod:`fusioncut.service.portable`."""
from __future__ import annotations

import io
import json

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from fusioncut.service.portable import portable_download, portable_size, portable_text


@pytest.fixture
def job(tmp_path):
    """A job folder whose results name its input and its results folder by server path."""
    job_dir = tmp_path / "data, \"odd\" name" / "jobs" / "0123abcd"  # a comma and quotes: CSV quoting
    (job_dir / "input").mkdir(parents=True)
    (job_dir / "results").mkdir()
    return job_dir


def _download(path, job_dir) -> bytes:
    body, size = portable_download(path, job_dir)
    data = b"".join(body)
    assert size is None or size == len(data)
    assert portable_size(path, job_dir) == len(data)
    return data


def test_a_csv_table_keeps_every_cell_but_the_server_paths(job):
    src = str(job / "input" / "Fräse (1).nc")
    frame = pd.DataFrame({"cl": [0, 1, 2], "file": [src] * 3, "x": [0.1, 1e-17, float("nan")],
                          "reason": ["", f"{src}:7: arc radius, mismatch \"R\"", ""],
                          "warnings": ["", "", f"a, b | {job / 'results' / 'failures'}"]})
    path = job / "results" / "cl.csv"
    frame.to_csv(path, index=False, lineterminator="\n")
    assert b'data, ""odd"" name/jobs/0123abcd/input' in path.read_bytes()  # quoted, its quotes doubled
    data = _download(path, job)
    assert b"0123abcd" not in data
    got = pd.read_csv(io.BytesIO(data), keep_default_na=False, na_values=[""])
    want = pd.read_csv(path, keep_default_na=False, na_values=[""])
    assert got["file"].tolist() == ["Fräse (1).nc"] * 3
    assert got["reason"][1] == 'Fräse (1).nc:7: arc radius, mismatch "R"'
    assert got["warnings"][2] == "a, b | results/failures"
    for col in ("file", "reason", "warnings"):
        want[col] = want[col].fillna("").map(lambda s: portable_text(s, job / "input", job)).replace("", float("nan"))
    pd.testing.assert_frame_equal(got, want)


def test_parquet_keeps_its_types_and_metadata_but_the_server_paths(job):
    meta = {"engine_options": {"failure_dir": str(job / "results" / "failures"), "slice_height": 0.5},
            "tools": {"T1": {"kind": "flat", "diameter_mm": 6.0}}}
    schema = pa.schema([pa.field("cl", pa.int64(), nullable=False, metadata={"unit": ""}),
                        pa.field("file", pa.string(), metadata={"description": "source file"}),
                        pa.field("z", pa.float64(), metadata={"unit": "mm"})],
                       metadata={"fusioncut": json.dumps(meta, sort_keys=True).encode()})
    table = pa.table({"cl": [0, 1], "file": [str(job / "input" / "a.nc")] * 2, "z": [-1.0, None]}, schema=schema)
    path = job / "results" / "cl.parquet"
    pq.write_table(table, path)
    got = pq.read_table(io.BytesIO(_download(path, job)))
    assert got.column("file").to_pylist() == ["a.nc", "a.nc"]
    assert got.select(["cl", "z"]).equals(table.select(["cl", "z"]))
    assert [(f.name, f.type, f.nullable, f.metadata) for f in got.schema] == \
           [(f.name, f.type, f.nullable, f.metadata) for f in table.schema]
    got_meta = json.loads(got.schema.metadata[b"fusioncut"])
    assert got_meta["engine_options"] == {"failure_dir": "results/failures", "slice_height": 0.5}
    assert got_meta["tools"] == meta["tools"]


def test_json_and_other_files(job):
    path = job / "results" / "metadata.json"
    data = {"engine_options": {"failure_dir": str(job / "results" / "failures"), "fuzzy": [0.0, 1e-6]},
            "job_hash": "abc", "name": "Bohrung_ü"}
    path.write_text(json.dumps(data, indent=2, sort_keys=True))
    got = json.loads(_download(path, job))
    assert got == {**data, "engine_options": {"failure_dir": "results/failures", "fuzzy": [0.0, 1e-6]}}
    png = job / "results" / "program.png"
    png.write_bytes(b"\x89PNG" + str(job).encode())  # images are served as they are
    assert _download(png, job) == png.read_bytes()
