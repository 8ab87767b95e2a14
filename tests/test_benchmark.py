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
        assert row["baseline_median_ms"] is None or row["baseline_median_ms"] > 0
    assert report["parallel_seconds"][1] > 0
