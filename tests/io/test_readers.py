"""The reader registries: which reader reads a toolpath or tool library, by suffix."""
from __future__ import annotations

import json
import re

import pytest

from fusioncut.errors import InputError
from fusioncut.io.job import program_job
from fusioncut.io.readers import (DEFAULT_TOOLPATH_READER, TOOL_LIBRARY_READERS, TOOLPATH_READERS, is_job_file,
                                  read_tool_library, read_toolpath, toolpath_format)
from fusioncut.model import FlatEndMill

PROGRAM = "G21 G90\nT1 M6\nG0 X0 Y0 Z5\nG1 Z-1 F100\nG1 X10\nG2 X20 I5 J0\nM30\n"


def _project(tmp_path, files=("p.nc",), bounds=True):
    doc = {"units": "metric", "tools": {"1": {"units": "imperial", "shape": "cylindrical", "length": 1,
                                              "diameter": 0.25}},
           "files": list(files)}
    if bounds:
        doc["workpiece"] = {"automatic": False, "bounds": {"min": [-5, -5, -10], "max": [30, 10, 0]}}
    path = tmp_path / "p.camotics"
    path.write_text(json.dumps(doc))
    (tmp_path / "p.nc").write_text(PROGRAM)
    return path


@pytest.mark.parametrize("suffix, fmt", [(".nc", "G-code"), (".NGC", "G-code"), (".tap", "G-code"),
                                         (".mpf", "G-code"), (".apt", "APT"), (".cls", "APT"),
                                         (".json", "Fusion JSON"), (".camotics", "CAMotics")])
def test_the_suffix_names_the_reader(suffix, fmt):
    assert toolpath_format(f"part{suffix}").format.startswith(fmt)
    assert (suffix.lower() in TOOLPATH_READERS) or toolpath_format(f"x{suffix}") is DEFAULT_TOOLPATH_READER


def test_a_camotics_project_reads_its_programs_with_its_tools(tmp_path):
    project = _project(tmp_path)
    tp = read_toolpath(project)
    direct = read_toolpath(tmp_path / "p.nc", {1: tp.tools[1]})
    assert tp.moves == direct.moves and len(tp.moves) == 4
    assert tp.tools[1].diameter == pytest.approx(6.35) and tp.program_tools is None
    given = {1: FlatEndMill(3.0, 10.0, number=1)}
    with_given = read_toolpath(project, given)
    assert with_given.tools == given and with_given.program_tools[1].diameter == pytest.approx(6.35)


def test_a_camotics_project_without_a_readable_program_is_refused(tmp_path):
    with pytest.raises(InputError, match="p.camotics.*no G-code program"):
        read_toolpath(_project(tmp_path, files=("missing.nc",)))


def test_a_program_job_of_a_camotics_project_takes_its_workpiece(tmp_path):
    job = program_job(_project(tmp_path))
    assert (job.stock.kind, job.stock.min, job.stock.max) == ("box", (-5.0, -5.0, -10.0), (30.0, 10.0, 0.0))
    assert program_job(_project(tmp_path, bounds=False)).stock.kind == "infer"


def test_job_files_are_told_from_fusion_json_toolpaths(tmp_path):
    job = tmp_path / "job.json"
    job.write_text(json.dumps({"stock": {"kind": "infer"}, "toolpaths": ["a.nc"]}))
    post = tmp_path / "post.json"
    post.write_text(json.dumps({"type": "hsm", "version": 1, "unit": "mm", "toolpath": []}))
    broken = tmp_path / "broken.json"
    broken.write_text('{"toolpaths": [')
    assert is_job_file(job) and not is_job_file(post) and not is_job_file(broken)
    assert not is_job_file(tmp_path / "a.nc")


def test_an_unknown_tool_library_suffix_lists_the_known_ones(tmp_path):
    with pytest.raises(InputError, match=re.escape(f"'.csv' (expected {', '.join(TOOL_LIBRARY_READERS)})")):
        read_tool_library(tmp_path / "tools.csv")
