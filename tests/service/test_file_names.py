"""File names with letters of any script (``résumé.nc``) are accepted, in their NFC form, and still
never name anything outside the job folder."""
from __future__ import annotations

import io
import json
import unicodedata

import pandas as pd
import pyarrow.parquet as pq
import pytest
from service_helpers import TINY_GCODE, TINY_JOB, wait_for

from fusioncut.errors import InputError
from fusioncut.service.files import check_name

NFC = "résumé.nc"
NFD = unicodedata.normalize("NFD", NFC)  # e + combining acute accent, as macOS names files


@pytest.mark.parametrize("name", [NFC, "Fräse T1 (v2).nc", "деталь-3.ngc", "部品.nc", "Ωmega_2.tap"])
def test_letters_of_any_script_are_accepted(name):
    assert check_name(name) == name


def test_names_are_kept_in_nfc():
    assert NFD != NFC and check_name(NFD) == NFC


@pytest.mark.parametrize("name", [
    "..", "../résumé.nc", "a/résumé.nc", "a\\b.nc", ".résumé.nc", "_job.json", " résumé.nc",
    "\u202egnp.nc",  # right-to-left override: shows as "cn.png"
    "x\x00.nc", "r\u00e9sum\u00e9\n.nc",
    "ｒésumé／x.nc",  # fullwidth solidus: NFKC would make it "/"
    "\u0301e.nc",  # starts with a combining accent
    "部" * 90 + ".nc",  # 90 letters, 270 UTF-8 bytes: over the file system's 255
])
def test_unsafe_names_are_refused(name):
    with pytest.raises(InputError):
        check_name(name)


def test_an_upload_named_resume_runs(client):
    job = {k: v for k, v in TINY_JOB.items() if k not in ("toolpaths", "name")}
    r = client.post("/api/jobs", files=[("toolpath", (NFD, TINY_GCODE.encode(), "text/plain"))],
                    data={"job": json.dumps(job), "name": "résumé"})
    assert r.status_code == 201, r.text
    done = wait_for(client, r.json()["id"])
    assert done["state"] == "done", done
    cl = pd.read_csv(io.BytesIO(client.get(f"/api/jobs/{done['id']}/files/cl.csv").content))
    assert set(cl["file"]) == {NFC}  # the name as uploaded, not the path on the server
    row = client.get(f"/api/jobs/{done['id']}/cls/0").json()["cl"]
    assert row["file"] == NFC
    # a JSON submission with the file inline: the same name
    r = client.post("/api/jobs", json={"job": {**TINY_JOB, "toolpaths": [NFC]}, "files": {NFC: TINY_GCODE}})
    assert r.status_code == 201, r.text
    # one name given in both forms is two files named alike
    r = client.post("/api/jobs", json={"job": {**TINY_JOB, "toolpaths": [NFC]}, "files": {NFC: "", NFD: ""}})
    assert r.status_code == 422 and "two files named" in r.json()["detail"]
    # and a path is still refused, whatever its letters
    r = client.post("/api/jobs", files=[("toolpath", ("../" + NFC, TINY_GCODE.encode(), "text/plain"))],
                    data={"job": json.dumps(job)})
    assert r.status_code == 422 and "not a plain file name" in r.json()["detail"]


def test_a_job_naming_its_file_in_nfd_runs_and_downloads_show_no_server_path(client, service):
    # the job typed on macOS (NFD), the file stored under its NFC name
    r = client.post("/api/jobs", json={"job": {**TINY_JOB, "toolpaths": [NFD]}, "files": {NFC: TINY_GCODE}})
    assert r.status_code == 201, r.text
    done = wait_for(client, r.json()["id"])
    assert done["state"] == "done", done

    server = str(service.data_dir.resolve())
    on_disk = service.data_dir.resolve() / "jobs" / done["id"] / "results"
    assert server in (on_disk / "cl.csv").read_text(encoding="utf-8")  # the runner records where it read
    listing = {f["name"]: f for f in client.get(f"/api/jobs/{done['id']}/files").json()["files"]}
    got = {}
    for name, f in listing.items():
        r = client.get(f["url"])
        assert r.status_code == 200 and len(r.content) == f["size"], name
        assert server.encode() not in r.content, name
        got[name] = r.content

    for name, read in (("cl.csv", pd.read_csv), ("cl.parquet", pd.read_parquet)):
        mine, theirs = read(io.BytesIO(got[name])), read(on_disk / name)
        assert set(mine["file"]) == {NFC}, name
        pd.testing.assert_frame_equal(mine.drop(columns="file"), theirs.drop(columns="file"))
    mine, theirs = json.loads(got["metadata.json"]), json.loads((on_disk / "metadata.json").read_text())
    assert mine["engine_options"].pop("failure_dir") == "results/failures"
    theirs["engine_options"].pop("failure_dir")
    assert mine == theirs
    meta = pq.read_schema(io.BytesIO(got["slices.parquet"])).metadata
    assert meta.keys() == pq.read_schema(on_disk / "slices.parquet").metadata.keys()
