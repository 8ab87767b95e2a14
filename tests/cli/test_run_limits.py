"""``fusioncut run`` sizes a job before expanding it: over its budget, a clear error and exit code 2."""
from __future__ import annotations

import json
import time
import tracemalloc

from typer.testing import CliRunner

import fusioncut.engines.brep.engine  # noqa: F401 - imported before measuring, as in any run
import fusioncut.io.gcode  # noqa: F401
import fusioncut.runner  # noqa: F401
from fusioncut.cli import app

runner = CliRunner()

PROGRAM = """\
G21 G90 G17
T1 M6
S10000 M3
G0 X-5 Y5 Z5
G1 Z-2 F300
G1 X12 F600
G0 Z5
M30
"""


def _job(tmp_path, **options) -> str:
    (tmp_path / "prog.nc").write_text(PROGRAM)
    job = {"name": "small", "stock": {"kind": "box", "min": [0, 0, -10], "max": [30, 20, 0]},
           "tools": [{"number": 1, "kind": "flat", "diameter": 6, "flute_length": 15}],
           "toolpaths": ["prog.nc"], "options": options}
    (tmp_path / "job.json").write_text(json.dumps(job))
    return str(tmp_path / "job.json")


def _invoke(args):
    """The result, the CPU seconds and the peak MB of a second run of ``args`` (the first one pays for
    the imports and the kernels' loading, once per process)."""
    runner.invoke(app, args)
    tracemalloc.start()
    t0 = time.process_time()
    try:
        res = runner.invoke(app, args)
        return res, time.process_time() - t0, tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def test_a_job_over_max_cls_is_refused_before_anything_is_written(tmp_path):
    out = tmp_path / "out"
    # 1 µm segments: the rapid from the origin makes 8,660, the plunge on line 5 passes 10,000
    res, cpu, mb = _invoke(["run", _job(tmp_path, max_segment_length=1e-3), "--out", str(out), "--max-cls", "10000"])
    assert res.exit_code == 2, res.output
    text = res.output.replace("\n", "")
    assert "prog.nc:5" in text and "more than 10,000 CL segments" in text and "--max-cls" in text
    assert "Traceback" not in res.output
    assert not (out / "cl.csv").exists() and not (out / "cl.parquet").exists()
    assert cpu < 1.0 and mb < 50


def test_max_cls_raises_the_limit(tmp_path):
    out = tmp_path / "out"
    res = runner.invoke(app, ["run", _job(tmp_path, max_segment_length=4.0), "--out", str(out), "--max-cls", "3",
                              "--no-ipw-export"])
    assert res.exit_code == 2 and "more than 3 CL segments" in res.output.replace("\n", "")
    res = runner.invoke(app, ["run", _job(tmp_path, max_segment_length=4.0), "--out", str(out), "--max-cls", "100",
                              "--no-ipw-export"])
    assert res.exit_code == 0, res.output


def test_max_slices_and_lower_bounds(tmp_path):
    res, cpu, mb = _invoke(["run", _job(tmp_path, slice_height=1e-3), "--out", str(tmp_path / "o"),
                            "--max-slices", "20000"])
    assert res.exit_code == 2 and "15,000 a CL" in res.output.replace("\n", "") and cpu < 1.0 and mb < 50
    res, cpu, mb = _invoke(["run", _job(tmp_path, max_segment_length=1e-5), "--out", str(tmp_path / "o")])
    text = res.output.replace("\n", "")
    assert res.exit_code == 2 and "options.max_segment_length" in text and "lower bound" in text
    assert cpu < 1.0 and mb < 50
