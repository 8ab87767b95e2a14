"""Result tables: values, dtypes and units round-trip; CSV == Parquet; interrupted writers stay loadable.

Engagement maps are built by hand (no geometry engine) with intervals whose derived numbers (ae,
machine angles, MRR) are known in closed form.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import re

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from fusioncut import __version__
from fusioncut.engines.base import EngineOptions
from fusioncut.errors import FusionCutError, SourceLocation
from fusioncut.io import results as res
from fusioncut.io.results import CL_COLUMNS, SLICE_COLUMNS, SUMMARY_COLUMNS, ResultWriter, load_results
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement, SpindleDirection

R = 5.0  # tool radius, mm


def slices(intervals: list[tuple[float, float]], n: int = 3, dz: float = 0.5, z_tip: float = -2.0,
           radius: float = R) -> tuple[SliceEngagement, ...]:
    """``n`` slices ``dz`` apart from the tip, all with the same intervals (immersion deg)."""
    return tuple(
        SliceEngagement(z=dz * k, z_machine=z_tip + dz * k, radius=radius,
                        intervals=tuple(AngleInterval(a, b) for a, b in intervals))
        for k in range(n)
    )


def make_em(i: int, status: CLStatus = CLStatus.ENGAGED, intervals=((0.0, 60.0),), *, op: str = "rough",
            feed: float | None = 600.0, spindle=SpindleDirection.CW, feed_angle: float = 0.0,
            step: float = 2.0, removed: float = 1.5, **kw) -> EngagementMap:
    """CL ``i`` moving ``step`` mm along +X at z = -2, ending at x = i * step."""
    sl = slices(list(intervals)) if intervals else ()
    return EngagementMap(
        cl_index=i, position=(step * i, 1.0, -2.0), start=(step * (i - 1), 1.0, -2.0), tool=kw.pop("tool", "T1"),
        spindle=spindle, feed_angle=feed_angle, status=status,
        source=kw.pop("source", SourceLocation("prog.nc", 10 + i, 3)), feed=feed, operation=op, slices=sl,
        removed_volume=removed if intervals else 0.0, axial_range=(0.0, 1.0) if intervals else (0.0, 0.0),
        timings_ms=(("sweep", 2.0), ("boolean", 0.5 + i)), sweep_method="exact" if intervals else "", **kw,
    )


def program() -> list[EngagementMap]:
    """A small program exercising every status, both spindles, wrap-around arcs and awkward text."""
    return [
        make_em(0, CLStatus.RAPID, None, op="", feed=None, warnings=("rapid move hits the stock",)),
        make_em(1),  # up-milling (0, 60): ae = R (1 - cos 60) = 2.5
        make_em(2, intervals=((1.0 / 3.0, 0.1 + 0.2 + 90.0), (170.0, 180.0))),
        make_em(3, CLStatus.AIR, None, removed=0.0),
        make_em(4, intervals=((330.0, 370.0),), spindle=SpindleDirection.CCW, feed_angle=90.0, op="finish",
                source=SourceLocation("dir, with comma/ü \"q\".nc", 7, 1)),
        make_em(5, CLStatus.FAILED, None, op="finish", reason='boolean failed, "tangent" faces\nsecond line'),
        make_em(6, intervals=((0.0, 180.0),), op="finish", feed=1e-12, tool="T2 ball"),
    ]


def write(path, ems, **kw) -> None:
    with ResultWriter(path, **kw) as w:
        for em in ems:
            w.add(em)


@pytest.fixture
def written(tmp_path):
    ems = program()
    write(tmp_path, ems, job_hash="abc123", batch_size=3, max_io_fraction=None,
          expected_cls={"": 1, "rough": 4, "finish": 3, "drill": 10},
          tools={"T1": {"kind": "flat", "diameter_mm": 10.0}})
    return tmp_path, ems


# ---------------------------------------------------------------------------------------------------


def test_cl_values_round_trip(written):
    path, ems = written
    cl = load_results(path).cl
    assert list(cl["cl"]) == [em.cl_index for em in ems]
    for em, (_, row) in zip(ems, cl.iterrows()):
        assert (row["x"], row["y"], row["z"]) == em.position
        assert (row["x0"], row["y0"], row["z0"]) == em.start
        assert row["file"] == em.source.file and row["line"] == em.source.line
        assert row["operation"] == em.operation and row["tool"] == em.tool
        assert row["status"] == em.status.value and row["reason"] == em.reason
        assert row["spindle"] == em.spindle.value
        assert row["feed_angle_machine_deg"] == em.feed_angle
        assert row["length_mm"] == 2.0  # chord of a straight 2 mm step
        assert row["time_ms"] == 2.0 + 0.5 + em.cl_index
        assert row["removed_volume_mm3"] == em.removed_volume
        assert row["ap_mm"] == em.ap

    by = cl.set_index("cl")
    # closed forms: up-milling (0, 60) on R = 5 has ae = R (1 - cos 60) = 2.5 mm
    assert by.loc[1, "ae_mm"] == pytest.approx(2.5, rel=1e-12)
    assert by.loc[6, "ae_mm"] == pytest.approx(2 * R, rel=1e-12)  # slot
    assert by.loc[2, ["entry_min_deg", "entry_max_deg", "exit_min_deg", "exit_max_deg"]].tolist() == [
        1.0 / 3.0, 170.0, 0.1 + 0.2 + 90.0, 180.0]
    assert by.loc[4, "exit_max_deg"] == 370.0
    # MRR = V * feed / length; NaN where it means nothing
    assert by.loc[1, "mrr_mm3_min"] == 1.5 * 600.0 / 2.0
    assert by.loc[6, "mrr_mm3_min"] == 1.5 * 1e-12 / 2.0
    assert math.isnan(by.loc[0, "mrr_mm3_min"])  # rapid
    assert math.isnan(by.loc[5, "mrr_mm3_min"])  # failed
    assert by.loc[3, "mrr_mm3_min"] == 0.0  # air: a real zero
    assert math.isnan(by.loc[0, "feed_mm_min"])
    for c in ("entry_min_deg", "entry_max_deg", "exit_min_deg", "exit_max_deg"):
        assert by.loc[[0, 3, 5], c].isna().all()
    assert by.loc[0, "warnings"] == "rapid move hits the stock"
    assert by.loc[5, "reason"].endswith("second line")


def test_slice_values_and_machine_angles(written):
    path, ems = written
    sl = load_results(path).slices
    assert len(sl) == sum(len(s.intervals) for em in ems for s in em.slices)
    cl1 = sl[sl["cl"] == 1]
    assert cl1["z_tool_mm"].tolist() == [0.0, 0.5, 1.0]
    assert cl1["z_machine_mm"].tolist() == [-2.0, -1.5, -1.0]
    assert (cl1["radius_mm"] == R).all() and (cl1["interval"] == 0).all()
    assert (cl1["entry_deg"] == 0.0).all() and (cl1["exit_deg"] == 60.0).all()
    # CW spindle, feed +X: immersion phi sits at machine 90 - phi, so (0, 60) covers machine 30..90
    assert (cl1["entry_machine_deg"] == 30.0).all() and (cl1["exit_machine_deg"] == 90.0).all()
    # CCW spindle, feed +Y: machine = phi, counter-clockwise; the wrapped arc stays one interval
    cl4 = sl[sl["cl"] == 4]
    assert (cl4["entry_machine_deg"] == 330.0).all() and (cl4["exit_machine_deg"] == 370.0).all()
    cl2 = sl[(sl["cl"] == 2) & (sl["z_tool_mm"] == 0.5)]
    assert cl2["interval"].tolist() == [0, 1]
    assert cl2["entry_deg"].tolist() == [1.0 / 3.0, 170.0]
    assert set(sl["cl"]) == {1, 2, 4, 6}  # CLs without contact have no slice rows


def test_dtypes_units_and_metadata(written):
    path, _ = written
    r = load_results(path)
    for df, cols in ((r.cl, CL_COLUMNS), (r.slices, SLICE_COLUMNS), (r.summary, SUMMARY_COLUMNS)):
        assert list(df.columns) == [c.name for c in cols]
        for c in cols:
            want = "category" if c.dtype == "category" else c.dtype
            assert str(df[c.name].dtype) == want, c.name
    assert list(r.cl["status"].cat.categories) == [s.value for s in CLStatus]

    for name, cols in (("cl", CL_COLUMNS), ("slices", SLICE_COLUMNS)):
        schema = pq.read_schema(path / f"{name}.parquet")
        for c in cols:
            meta = schema.field(c.name).metadata
            assert meta[b"unit"].decode() == c.unit
            if c.unit == "deg":  # every angle says which convention it is in
                assert meta[b"angle"].decode() == ("machine" if "machine" in c.name else "immersion")
        meta = json.loads(schema.metadata[b"fusioncut"])
        assert meta["job_hash"] == "abc123" and meta["fusioncut_version"] == __version__
        assert meta["tools"] == {"T1": {"kind": "flat", "diameter_mm": 10.0}, "T2 ball": {}}
        assert "immersion" in meta["angle_convention"] and "machine" in meta["angle_convention"]
        assert meta["units"]["cl"]["mrr_mm3_min"] == "mm^3/min"
    assert r.metadata["job_hash"] == "abc123"
    # CSV readers get the same metadata from metadata.json
    assert load_results(path, prefer="csv").metadata == r.metadata


def test_csv_and_parquet_agree(written):
    path, _ = written
    p, c = load_results(path), load_results(path, prefer="csv")
    assert (p.source, c.source) == ("parquet", "csv")
    pd.testing.assert_frame_equal(p.cl, c.cl, check_exact=True)
    pd.testing.assert_frame_equal(p.slices, c.slices, check_exact=True)


def test_csv_floats_are_exact(tmp_path):
    # values with no short decimal form must survive the text format bit for bit
    rng = np.random.default_rng(7)
    ems = [make_em(i, intervals=((float(a), float(a + b)),), removed=float(v))
           for i, (a, b, v) in enumerate(zip(rng.uniform(0, 359, 40), rng.uniform(1e-9, 300, 40),
                                             rng.lognormal(0, 8, 40)))]
    write(tmp_path, ems, batch_size=7, max_io_fraction=None)
    p, c = load_results(tmp_path), load_results(tmp_path, prefer="csv")
    pd.testing.assert_frame_equal(p.cl, c.cl, check_exact=True)
    pd.testing.assert_frame_equal(p.slices, c.slices, check_exact=True)
    assert c.cl["removed_volume_mm3"].tolist() == [em.removed_volume for em in ems]


def test_summary(written):
    path, _ = written
    s = load_results(path).summary.set_index("operation")
    assert list(s.index) == ["", "rough", "finish", "drill"]  # first appearance, then expected-only
    assert s.loc["rough", ["cls", "processed", "engaged", "air", "rapid", "failed"]].tolist() == [4, 3, 2, 1, 0, 0]
    assert s.loc["finish", ["cls", "processed", "engaged", "failed"]].tolist() == [3, 3, 2, 1]
    assert s.loc["", "rapid"] == 1
    assert s.loc["drill", ["cls", "processed"]].tolist() == [10, 0]  # not started: visible as missing
    assert s.loc["rough", "volume_removed_mm3"] == 3.0
    assert s.loc["rough", "time_s"] == pytest.approx((2.5 + 1 + 2.5 + 2 + 2.5 + 3) / 1000.0)
    # CL 2 spans immersion 1/3 .. 180 deg: ae = R (cos(1/3 deg) - cos(180 deg))
    assert s.loc["rough", "max_ae_mm"] == pytest.approx(R * (math.cos(math.radians(1 / 3)) + 1), rel=1e-12)
    assert s.loc["finish", "max_ap_mm"] == 1.0


def test_writer_flushes_in_batches(tmp_path):
    ems = program()
    w = ResultWriter(tmp_path, batch_size=2, max_io_fraction=None)
    assert len(load_results(tmp_path).cl) == 0  # loadable (and empty) before the first CL
    seen = []
    for em in ems:
        w.add(em)
        seen.append(len(load_results(tmp_path).cl))
    assert seen == [0, 2, 2, 4, 4, 6, 6]
    assert (w.written, w.pending) == (6, 1)
    w.close()
    assert len(load_results(tmp_path).cl) == 7
    with pytest.raises(ValueError):
        w.add(ems[0])


def test_a_load_reads_one_whole_file_while_a_writer_replaces_it(tmp_path, monkeypatch):
    """A running job's tables are replaced at every flush (os.replace) while the service reads them:
    a load reads the file it opened to the end, even when it is replaced mid-read (pyarrow given the
    path opened it again for the pages and met the new file: "Page was smaller than expected")."""
    ems = program()
    w = ResultWriter(tmp_path, batch_size=2, max_io_fraction=None)
    for em in ems[:2]:
        w.add(em)
    later = tmp_path / "later"
    with ResultWriter(later, max_io_fraction=None) as w2:
        for em in ems:
            w2.add(em)
    real = res.pq.read_table

    def replaced_mid_read(source, *a, **k):
        for name in ("cl.parquet", "slices.parquet"):
            if (later / name).exists():
                os.replace(later / name, tmp_path / name)  # the writer's next flush lands now
        return real(source, *a, **k)

    monkeypatch.setattr(res.pq, "read_table", replaced_mid_read)
    assert load_results(tmp_path).cl["cl"].tolist() == [0, 1]  # the file as it was opened


def test_unclosed_writer_leaves_consistent_files(tmp_path):
    # the process "dies" without close(): every completed batch is on disk, CSV and Parquet agree,
    # and every CL in the cl table has its slices
    ems = program()
    w = ResultWriter(tmp_path, batch_size=3, max_io_fraction=None)
    for em in ems:
        w.add(em)
    p, c = load_results(tmp_path), load_results(tmp_path, prefer="csv")
    assert p.cl["cl"].tolist() == [0, 1, 2, 3, 4, 5]
    pd.testing.assert_frame_equal(p.cl, c.cl, check_exact=True)
    pd.testing.assert_frame_equal(p.slices, c.slices, check_exact=True)
    assert set(p.slices["cl"]) == {1, 2, 4}
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".tmp")]
    del w


@pytest.mark.parametrize("exc", [RuntimeError, KeyboardInterrupt])
def test_exception_mid_run_flushes_everything_added(tmp_path, exc):
    ems = program()
    with pytest.raises(exc):
        with ResultWriter(tmp_path, batch_size=100) as w:
            for em in ems[:5]:
                w.add(em)
            raise exc("interrupted")
    r = load_results(tmp_path)
    assert r.cl["cl"].tolist() == [0, 1, 2, 3, 4]
    assert set(r.slices["cl"]) == {1, 2, 4}
    pd.testing.assert_frame_equal(r.cl, load_results(tmp_path, prefer="csv").cl, check_exact=True)


def test_crash_while_writing_keeps_previous_files(tmp_path, monkeypatch):
    ems = program()
    w = ResultWriter(tmp_path, batch_size=2, max_io_fraction=None)
    for em in ems[:2]:
        w.add(em)
    before = {f: (tmp_path / f).read_bytes() for f in ("cl.csv", "cl.parquet", "slices.csv", "slices.parquet")}

    real = pq.write_table

    def dies_half_way(table, where, **kw):  # writes some bytes, then the "power goes"
        where.write(b"PAR1 partial garbage")
        raise OSError("disk vanished")

    monkeypatch.setattr(res.pq, "write_table", dies_half_way)
    w.add(ems[2])
    with pytest.raises(OSError):
        w.add(ems[3])
    # the Parquet files are untouched and still hold the first batch; no temporary file is left
    assert (tmp_path / "cl.parquet").read_bytes() == before["cl.parquet"]
    assert (tmp_path / "slices.parquet").read_bytes() == before["slices.parquet"]
    assert load_results(tmp_path).cl["cl"].tolist() == [0, 1]
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".tmp")]

    # the pending CLs were kept: once the disk is back, a flush writes them and nothing twice
    monkeypatch.setattr(res.pq, "write_table", real)
    w.close()
    p, c = load_results(tmp_path), load_results(tmp_path, prefer="csv")
    assert p.cl["cl"].tolist() == [0, 1, 2, 3]
    # the CSV of the failed flush was already replaced before the Parquet write died; the retry must
    # not append its rows a second time
    assert c.cl["cl"].tolist() == [0, 1, 2, 3]
    pd.testing.assert_frame_equal(p.slices, c.slices, check_exact=True)


def test_io_throttle_postpones_but_never_loses(tmp_path, monkeypatch):
    class Clock:  # every reading advances one second: each flush "takes" one second
        t = 0.0

        def monotonic(self) -> float:
            self.t += 1.0
            return self.t

    monkeypatch.setattr(res, "time", Clock())
    w = ResultWriter(tmp_path, batch_size=2, max_io_fraction=0.25)
    written = []
    for i in range(12):
        w.add(make_em(i))
        written.append(w.written)
    assert written[1] == 2  # the first batch always goes out
    assert written[3] == 2  # due, but only 1 s after a 1 s flush: postponed (25 % I/O at most)
    steps = np.diff([0] + written)
    assert steps.max() > 2  # a later flush carries the postponed batch along with its own
    assert w.written + w.pending == 12
    w.close()
    assert load_results(tmp_path).cl["cl"].tolist() == list(range(12))


def test_new_writer_replaces_old_results(tmp_path):
    write(tmp_path, program())
    ResultWriter(tmp_path)  # a new job in the same directory, nothing added yet
    r = load_results(tmp_path)
    assert len(r.cl) == 0 and len(r.slices) == 0 and len(r.summary) == 0


def test_explicit_path_length_for_arcs(tmp_path):
    with ResultWriter(tmp_path) as w:
        w.add(make_em(1), length_mm=math.pi)  # e.g. a half circle of radius 1 between the points
    row = load_results(tmp_path).cl.iloc[0]
    assert row["length_mm"] == math.pi
    assert row["mrr_mm3_min"] == 1.5 * 600.0 / math.pi


def test_csv_only_directory_loads(tmp_path, written):
    path, _ = written
    for f in ("cl.parquet", "slices.parquet"):
        (path / f).unlink()
    r = load_results(path)
    assert r.source == "csv" and len(r.cl) == 7


@pytest.mark.parametrize("prefer", ["parquet", "csv"])
def test_results_written_before_a_column_was_added_still_load(written, prefer):
    """Folders written before ``rubbing_slices`` existed load with 0 there; any other missing column
    is still an error naming the file."""
    import pyarrow.parquet as pq

    path, _ = written
    table = pq.read_table(path / "cl.parquet")
    pq.write_table(table.drop(["rubbing_slices"]).replace_schema_metadata(table.schema.metadata), path / "cl.parquet")
    csv = pd.read_csv(path / "cl.csv", dtype=str, keep_default_na=False)
    csv.drop(columns=["rubbing_slices"]).to_csv(path / "cl.csv", index=False)
    r = load_results(path, prefer=prefer)
    assert len(r.cl) == 7 and (r.cl["rubbing_slices"] == 0).all() and r.cl["rubbing_slices"].dtype == "int64"
    csv.drop(columns=["rubbing_slices", "ae_mm"]).to_csv(path / "cl.csv", index=False)
    (path / "cl.parquet").unlink()
    with pytest.raises(FusionCutError, match=r"cl\.csv: missing columns ae_mm$"):
        load_results(path, prefer=prefer)


def test_load_errors_are_fusioncut_errors(tmp_path):
    with pytest.raises(FusionCutError, match="not found"):
        load_results(tmp_path / "missing")
    with pytest.raises(FusionCutError, match="no cl.parquet or cl.csv"):
        load_results(tmp_path)
    with pytest.raises(ValueError):
        ResultWriter(tmp_path, batch_size=0)


def test_row_lookup(written):
    path, _ = written
    r = load_results(path)
    assert r.row(4)["operation"] == "finish"
    assert r.slices_of(2)["z_tool_mm"].is_monotonic_increasing
    with pytest.raises(FusionCutError, match="CL 99 is not in the results"):
        r.row(99)


# -- what the engine knew: options, slice height, tools, spindle speed, slice bands -----------------

DZ = 0.5


def engine_em(i: int, axial=(0.2, 1.3), zs=(0.35, 0.75, 1.15), **kw) -> EngagementMap:
    """A map as the engine makes it with slice height DZ: each slice in the middle of its band
    [k, k+1) * DZ clipped to the contact ``axial`` (0.2 .. 0.5, 0.5 .. 1.0, 1.0 .. 1.3 mm)."""
    sl = tuple(SliceEngagement(z=z, z_machine=z - 2.0, radius=R, intervals=(AngleInterval(0.0, 90.0),)) for z in zs)
    return dataclasses.replace(make_em(i, **kw), slices=sl, axial_range=axial)


def test_metadata_keeps_options_and_tools(tmp_path):
    tool = FlatEndMill(20 / 3, 19.05, flutes=3, helix_angle=100 / 3, spindle=SpindleDirection.CCW, number=1,
                       neck_diameter=6.0, shoulder_length=25.0)
    opts = EngineOptions(slice_height=DZ, failure_dir=tmp_path / "failures", fuzzy=1e-6, cell_size=None)
    with ResultWriter(tmp_path, tools={"T1": tool}, options=opts) as w:
        w.add(engine_em(1))
    meta = json.loads((tmp_path / "metadata.json").read_text())
    assert meta["slice_height_mm"] == DZ and meta["engine_options"]["fuzzy_retries"] == list(opts.fuzzy_retries)
    for prefer in ("parquet", "csv"):
        r = load_results(tmp_path, prefer=prefer)
        assert r.slice_height == DZ and r.require_slice_height() == DZ
        assert r.tools == {"T1": tool} and r.tool("T1").flutes == 3
        # every EngineOptions field, as JSON: paths as text, tuples as lists
        assert set(r.options) == {f.name for f in dataclasses.fields(EngineOptions)}
        assert r.options["failure_dir"] == str(tmp_path / "failures") and r.options["cell_size"] is None
        rebuilt = EngineOptions(**{k: tuple(v) if isinstance(v, list) else v for k, v in r.options.items()})
        assert dataclasses.replace(rebuilt, failure_dir=opts.failure_dir) == opts
        assert r.missing == {}


def test_spindle_speed_and_slice_bands_per_row(tmp_path):
    with ResultWriter(tmp_path, options=EngineOptions(slice_height=DZ)) as w:
        w.add(engine_em(1), spindle_rpm=12000.0)
        w.add(engine_em(2))  # no S programmed
        w.add(engine_em(3, axial=(0.0, 0.0)))  # slices off the engine's rule: band unknown
    for prefer in ("parquet", "csv"):
        r = load_results(tmp_path, prefer=prefer)
        assert r.cl["spindle_rpm"].iloc[0] == 12000.0 and r.cl["spindle_rpm"].iloc[1:].isna().all()
        s1 = r.slices_of(1)
        assert s1["z_lo_mm"].tolist() == [0.2, 0.5, 1.0] and s1["z_hi_mm"].tolist() == [0.5, 1.0, 1.3]
        assert np.allclose(0.5 * (s1["z_lo_mm"] + s1["z_hi_mm"]), s1["z_tool_mm"], rtol=0, atol=1e-12)
        assert r.slices_of(3)[["z_lo_mm", "z_hi_mm"]].isna().all().all()
    # without the options the writer does not know the bands
    with ResultWriter(tmp_path / "bare") as w:
        w.add(engine_em(1))
    assert load_results(tmp_path / "bare").slices[["z_lo_mm", "z_hi_mm"]].isna().all().all()


@pytest.mark.parametrize("prefer", ["parquet", "csv"])
def test_older_folders_load_with_what_they_lack_named(tmp_path, prefer):
    """A folder written before the metadata kept options, tools, speeds and bands: it loads, the
    columns are NaN, and ``missing`` names each thing; asking for the slice height or a tool is a
    clear error naming the folder."""
    with ResultWriter(tmp_path, tools={"T1": FlatEndMill(10.0, 20.0)}, options=EngineOptions(slice_height=DZ)) as w:
        w.add(engine_em(1), spindle_rpm=8000.0)
    meta = json.loads((tmp_path / "metadata.json").read_text())
    for key in ("engine_options", "slice_height_mm"):
        del meta[key]
    meta["tools"] = {"T1": {"kind": "flat", "diameter_mm": 10.0, "flute_length_mm": 20.0}}
    (tmp_path / "metadata.json").write_text(json.dumps(meta))
    for name, drop in (("cl", ["spindle_rpm"]), ("slices", ["z_lo_mm", "z_hi_mm"])):
        table = pq.read_table(tmp_path / f"{name}.parquet")
        old = table.drop(drop).replace_schema_metadata({b"fusioncut": json.dumps(meta).encode()})
        pq.write_table(old, tmp_path / f"{name}.parquet")
        csv = pd.read_csv(tmp_path / f"{name}.csv", dtype=str, keep_default_na=False)
        csv.drop(columns=drop).to_csv(tmp_path / f"{name}.csv", index=False)
    r = load_results(tmp_path, prefer=prefer)
    assert set(r.missing) == {"engine_options", "slice_height", "spindle_rpm", "slice_bands", "tool T1"}
    assert r.cl["spindle_rpm"].isna().all() and r.slices[["z_lo_mm", "z_hi_mm"]].isna().all().all()
    assert r.options is None and r.slice_height is None and r.tools == {}
    with pytest.raises(FusionCutError, match=rf"^{tmp_path}: the slice height is not recorded .*--slice-height"):
        r.require_slice_height()
    with pytest.raises(FusionCutError, match=r"tool T1: metadata.json has no full record of it .*lacks flutes"):
        r.tool("T1")


@pytest.mark.parametrize("name, columns", [("cl", CL_COLUMNS), ("slices", SLICE_COLUMNS),
                                           ("summary", SUMMARY_COLUMNS)])
def test_column_tables_render_every_column(name, columns):
    md = res.column_table(name).splitlines()
    assert md[0] == "| column | dtype | unit | meaning |" and len(md) == len(columns) + 2
    for line, c in zip(md[2:], columns):
        cells = [x.strip() for x in re.split(r"(?<!\\)\|", line)[1:-1]]  # an escaped pipe is text
        assert cells == [f"`{c.name}`", c.dtype, c.unit or "-", c.description.replace("|", "\\|")]
    assert f"``{columns[-1].name}``" in res.column_table(name, "rst") and f"``{name}`` table" in res.__doc__


def test_a_run_records_its_options_tools_and_speeds(tmp_path):
    """Through the runner: the folder of a real (tiny) run rebuilds its tool, knows its slice height
    and options, and carries the program's spindle speed on each CL and a band on each slice."""
    from fusioncut.model import BoxStock, LinearMove, Toolpath
    from fusioncut.runner import run_toolpath

    tool = FlatEndMill(6.0, 15.0, flutes=4, helix_angle=45.0, number=1)
    pts = [(-5.0, 5.0, -1.3), (12.0, 5.0, -1.3), (12.0, 9.0, -1.3)]
    moves = tuple(LinearMove(a, b, feed=600.0, spindle_rpm=s, tool=1) for a, b, s in zip(pts, pts[1:], (9000.0, None)))
    opts = EngineOptions(slice_height=DZ, cell_size=None)
    run_toolpath(Toolpath(moves, {1: tool}), BoxStock((0.0, 0.0, -10.0), (30.0, 20.0, 0.0)), tmp_path, opts,
                 export_ipw=False)
    r = load_results(tmp_path)
    assert r.tools == {"T1": tool} and r.slice_height == DZ and r.options["cell_size"] is None
    assert r.missing == {}
    assert r.cl["spindle_rpm"].iloc[0] == 9000.0 and math.isnan(r.cl["spindle_rpm"].iloc[1])
    assert len(r.slices) and r.slices[["z_lo_mm", "z_hi_mm"]].notna().all().all()
    assert r.cl["ap_mm"].max() == pytest.approx(1.3, abs=1e-9)
    top = r.slices.groupby("cl")["z_hi_mm"].max() - r.slices.groupby("cl")["z_lo_mm"].min()
    np.testing.assert_allclose(top.to_numpy(), r.cl.set_index("cl").loc[top.index, "ap_mm"].to_numpy(), atol=1e-9)


@pytest.mark.parametrize("prefer", ["parquet", "csv"])
def test_each_row_says_which_engine_computed_it_and_older_folders_take_their_options_engine(tmp_path, prefer):
    """``engine`` per CL row (format 3): what the map says. A folder written before the column took
    the engine its options name (one engine ran every CL then); without options it is unknown."""
    with ResultWriter(tmp_path, options=EngineOptions(slice_height=DZ)) as w:
        w.add(dataclasses.replace(engine_em(1), engine="analytic"))
        w.add(dataclasses.replace(engine_em(2), engine="brep"))
    meta = json.loads((tmp_path / "metadata.json").read_text())
    assert meta["format_version"] == 3
    r = load_results(tmp_path, prefer=prefer)
    assert r.cl["engine"].tolist() == ["analytic", "brep"] and "engine" not in r.missing
    for options, ran, missing in (({"engine": "analytic"}, "analytic", False), ({}, "brep", False), (None, "", True)):
        old_meta = {**meta, "format_version": 2, "engine_options": options}
        (tmp_path / "metadata.json").write_text(json.dumps(old_meta))
        table = pq.read_table(tmp_path / "cl.parquet")
        pq.write_table(table.drop(["engine"]).replace_schema_metadata({b"fusioncut": json.dumps(old_meta).encode()}),
                       tmp_path / "old.parquet")
        old = tmp_path / "old"
        old.mkdir(exist_ok=True)
        (tmp_path / "old.parquet").replace(old / "cl.parquet")
        for name in ("slices.parquet", "slices.csv", "metadata.json"):
            (old / name).write_bytes((tmp_path / name).read_bytes())
        csv = pd.read_csv(tmp_path / "cl.csv", dtype=str, keep_default_na=False)
        csv.drop(columns=["engine"]).to_csv(old / "cl.csv", index=False)
        r = load_results(old, prefer=prefer)
        assert r.cl["engine"].tolist() == [ran, ran] and ("engine" in r.missing) == missing, options
