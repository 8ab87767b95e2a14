"""The benchmark runs end to end on its smoke-test size (the timings themselves are not asserted)."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))


@pytest.mark.slow
def test_benchmark_tiny_runs_and_reports(tmp_path):
    import run_benchmark

    report = run_benchmark.main(["--tiny", "--slicing", "1,0.5", "--workers", "1", "--out", str(tmp_path)])
    assert (tmp_path / "benchmark.json").is_file()
    assert set(report["operations"]) >= {"Face", "Adaptive", "Contour", "Finish"}
    assert all(v <= 1e-6 for v in report["conservation"].values())
    for row in report["operations"].values():
        assert row["slice_1"]["processed"] <= row["cls"]
        # every operation gets baseline CLs, the windows run on through links in the air
        assert row["baseline_median_ms"] > 0 and row["sum_ratio"] > 0
    assert report["parallel_seconds"][1] > 0
    # a worker holds the kernel and the cells: more than an empty Python process, less than the machine
    assert 100 < report["worker_peak_rss_mb"][1] < 24 * 1024


@pytest.mark.slow
def test_quick_program_workpiece_stays_small_past_the_helix_where_a_merge_left_a_hole(tmp_path):
    """On the quick program, the face merge at CL 2078 (a helix step at Z-6.45) leaves a hole; while
    such merges were refused whole, the workpiece grew to 4,382 faces by CL 2199 and the Boolean
    median rose from 55–85 ms to 254 ms. Now the faces around the hole stay and the rest is merged."""
    from run_benchmark import WHOLE
    from titan_program import STOCK_MAX, STOCK_MIN, ProgramSize, titan_program

    from fusioncut.engines.base import EngineOptions
    from fusioncut.engines.brep.engine import BRepEngine
    from fusioncut.engines.cl_maps import cl_sequence
    from fusioncut.engines.brep.occ import count_faces
    from fusioncut.io.gcode import read_gcode
    from fusioncut.model import BoxStock, CLStatus

    program = tmp_path / "quick.nc"
    # the quick size when this was found (its second depth level holds that helix step)
    program.write_text(titan_program(ProgramSize(slot_length=16.0, slots=2, depths=(-4.0, -8.0), finish_rows=4, contours=1)))
    # the hole was found on the whole workpiece, a solid by then: with up to 6 layers, as it was (with
    # more, the helix's ledges stay layers and the merge this guards is never reached)
    engine = BRepEngine(EngineOptions(**WHOLE, max_layers=6))
    engine.start(BoxStock(STOCK_MIN, STOCK_MAX))
    most_faces = 0
    for index, move, tool, feed_angle in cl_sequence(read_gcode(program), engine.options):
        assert engine.step(index, move, tool, feed_angle).status != CLStatus.FAILED, index
        if index >= 2070:
            most_faces = max(most_faces, count_faces(engine.ipw))
        if index == 2200:
            break
    assert most_faces < 1000
    assert abs(engine.stock_volume - engine.ipw_volume - engine.removed_total) <= 1e-6 * engine.stock_volume


@pytest.mark.slow
def test_real_programs_benchmark_runs_both_engines_on_the_same_cls(tmp_path):
    """The real-program benchmark on bear's first CLs: both engines run the same CLs without a
    failure and remove the same volume (the B-Rep engine's steps differ from the exact ramps only
    within its step tolerance: 1.3e-6 relative measured over 20 CLs)."""
    import json

    import real_programs
    from shared_data import DATA

    if not (DATA / "camotics-examples" / "bear" / "bear.nc").is_file():
        pytest.skip("shared data missing")
    out = tmp_path / "real.json"
    assert real_programs.main(["--programs", "bear", "--cls", "6", "--windows", "1", "--out", str(out)]) == 0
    (res,) = json.loads(out.read_text())
    ana, brep = res["windows"]
    assert (ana["engine"], brep["engine"]) == ("analytic", "brep")
    assert ana["cls"] == brep["cls"] == 6 and ana["failed"] == brep["failed"] == 0
    assert ana["removed_mm3"] > 1000  # the plunge and the first full-depth raster line
    assert abs(res["removed_relative_difference"]) < 1e-5


@pytest.mark.parametrize("name,start,cls,removed", [("bear", 8801, 3, 10.0), ("titan", 36100, 5, 1.0)])
def test_a_real_program_window_conserves_its_volume(name, start, cls, removed):
    """The real-program benchmark's conservation on a window of bear's ball finishing (CLs 8801-8803, 3D
    segments) and of the Titan-like program's ball-end raster (CLs 36100-36104, level lines along x whose
    cells are integrated across each line in closed form, .sections): the box around the window's
    footprints loses what its CLs removed, both integrals of the material taken from the sweeps alone, to
    the integrals' tolerance (``volume_rel`` of each)."""
    import real_programs
    from shared_data import DATA

    from fusioncut.engines.analytic.engine import AnalyticEngine
    from fusioncut.engines.base import EngineOptions

    if name == "bear" and not (DATA / "camotics-examples" / "bear" / "bear.nc").is_file():
        pytest.skip("shared data missing")
    toolpath, stock, default = real_programs.load(next(p for p in real_programs.PROGRAMS if p.name == name))
    options = EngineOptions(slice_height=1.0)
    engine = AnalyticEngine(options)
    engine.start(stock)
    row = real_programs.timed(engine.process(toolpath, default, start_at=start), cls)
    assert row["cut"] == cls and row["removed_mm3"] > removed
    assert real_programs.window_conservation(toolpath, stock, default, options, start, row) \
        <= 3 * AnalyticEngine.volume_rel


def test_the_generated_round_bar_program_removes_its_closed_form():
    """``gen_round_bar_flat`` on the analytic engine: no CL fails and the total is the closed form of
    its module docstring to 1e-9 (the B-Rep engine's total agrees, docs/benchmark.md)."""
    import math

    from finishing_programs import load

    from fusioncut.engines.analytic.engine import AnalyticEngine
    from fusioncut.engines.base import EngineOptions

    toolpath, stock, _ = load("gen_round_bar_flat")
    engine = AnalyticEngine(EngineOptions(slice_height=1.0))
    maps = list(engine.run(toolpath, stock))
    assert maps and all(m.status.value != "failed" and m.engine == "analytic" for m in maps)

    def strip(y):
        return y * math.sqrt(400.0 - y * y) + 400.0 * math.asin(y / 20.0)

    want = math.pi * 625.0 + math.pi * (625.0 - 400.0) * 7.0 + 3.0 * (strip(7.0) - strip(-3.0))
    assert sum(m.removed_volume for m in maps) == pytest.approx(want, rel=1e-9)
    assert engine.ipw_volume == pytest.approx(math.pi * 625.0 * 30.0 - want, rel=1e-9)
