"""Slot-test calibration: exact recovery from closed-form data, stated error bounds under noise, and
the ``fusioncut calibrate`` command (good and bad CSV files)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from fusioncut.analysis.calibrate import calibrate_from_slot_tests, read_slot_tests_csv
from fusioncut.analysis.forces import CuttingCoefficients, compute_cl_forces
from fusioncut.analysis.materials import AL7075_T6_CARBIDE
from fusioncut.cli.forces import register
from fusioncut.errors import InputError
from fusioncut.model import AngleInterval, CLStatus, EngagementMap, FlatEndMill, SliceEngagement, SpindleDirection

TRUE = AL7075_T6_CARBIDE
KEYS = ("ktc", "krc", "kac", "kte", "kre", "kae")
N, A = 4, 5.0
FEEDS = np.array([0.025, 0.05, 0.075, 0.1, 0.125, 0.15, 0.175, 0.2])


def slot_means(c: np.ndarray, n: int, a: float, k: CuttingCoefficients) -> tuple[np.ndarray, ...]:
    """Closed-form mean slot forces (Altintas 2012): each linear in the feed per tooth."""
    fx = -(n * a * k.krc / 4) * c - n * a * k.kre / math.pi
    fy = (n * a * k.ktc / 4) * c + n * a * k.kte / math.pi
    fz = (n * a * k.kac / math.pi) * c + n * a * k.kae / 2
    return fx, fy, fz


def test_exact_recovery_from_closed_form_data() -> None:
    coeffs, fit = calibrate_from_slot_tests(FEEDS, *slot_means(FEEDS, N, A, TRUE), axial_depth=A, flutes=N)
    for key in KEYS:
        assert getattr(coeffs, key) == pytest.approx(getattr(TRUE, key), rel=1e-10, abs=1e-10)
        assert fit.stderr[key] < 1e-8
    for line in (fit.x, fit.y, fit.z):
        assert line.r_squared == pytest.approx(1.0, abs=1e-12)
    assert fit.tests == len(FEEDS) and fit.flutes == N and fit.axial_depth == A


def test_round_trip_through_the_force_model() -> None:
    """Mean forces of slot maps computed by the force model (helical tool, 3 flutes) calibrate back to
    the coefficients that produced them: the two modules agree on conventions."""
    tool = FlatEndMill(diameter=10.0, flute_length=25.0, flutes=3, helix_angle=30.0)
    depth, m = 4.0, 20
    slices = tuple(
        SliceEngagement((i + 0.5) * depth / m, (i + 0.5) * depth / m, 5.0, (AngleInterval(0.0, 180.0),))
        for i in range(m)
    )
    emap = EngagementMap(0, (1, 0, 0), (0, 0, 0), "T1", SpindleDirection.CW, 0.0, CLStatus.ENGAGED, feed=1.0,
                         slices=slices, axial_range=(0.0, depth))
    means = np.array([
        compute_cl_forces(emap, tool, TRUE, rpm=10000.0, feed_per_tooth=c).mean_feed_frame for c in FEEDS
    ])
    coeffs, _ = calibrate_from_slot_tests(FEEDS, means[:, 0], means[:, 1], means[:, 2], depth, 3)
    for key in KEYS:
        assert getattr(coeffs, key) == pytest.approx(getattr(TRUE, key), rel=1e-9)


def noisy(seed: int, sigma: float, repeats: int = 2) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    c = np.repeat(FEEDS, repeats)
    return (c,) + tuple(f + rng.normal(0.0, sigma, len(c)) for f in slot_means(c, N, A, TRUE))


SIGMA = 2.0  # N, scatter of a mean force (typical of averaged dynamometer readings)


def theoretical_stderr(c: np.ndarray, sigma: float, n: int, a: float) -> dict[str, float]:
    """Standard errors of the six coefficients for independent scatter ``sigma`` (N) on every mean
    force: ordinary least squares gives se(slope) = sigma / sqrt(Sxx), se(intercept) =
    sigma * sqrt(1/m + mean(c)^2 / Sxx), scaled by the inversion factors 4/(Na), pi/(Na), 2/(Na)."""
    sxx = float(((c - c.mean()) ** 2).sum())
    s_slope = sigma / math.sqrt(sxx)
    s_int = sigma * math.sqrt(1 / len(c) + c.mean() ** 2 / sxx)
    na = n * a
    return {"ktc": 4 * s_slope / na, "krc": 4 * s_slope / na, "kac": math.pi * s_slope / na,
            "kte": math.pi * s_int / na, "kre": math.pi * s_int / na, "kae": 2 * s_int / na}


def test_noisy_data_within_stated_error() -> None:
    """sigma = 2 N on every mean force, 16 tests (8 feeds from 0.025 to 0.2 mm x 2 repeats), N = 4,
    a = 5 mm. Stated error: every coefficient within 4 theoretical standard errors, i.e. Ktc, Krc within
    +-7.0 N/mm² (0.9%, 4.1%), Kac +-5.5 N/mm² (2.5%), Kte, Kre +-0.70 N/mm, Kae +-0.45 N/mm."""
    c, fx, fy, fz = noisy(seed=20240611, sigma=SIGMA)
    coeffs, fit = calibrate_from_slot_tests(c, fx, fy, fz, A, N)
    theory = theoretical_stderr(c, SIGMA, N, A)
    stated = {"ktc": 7.0, "krc": 7.0, "kac": 5.5, "kte": 0.70, "kre": 0.70, "kae": 0.45}
    for key in KEYS:
        assert 4 * theory[key] <= stated[key] <= 4.1 * theory[key], key  # the numbers above are right
        err = abs(getattr(coeffs, key) - getattr(TRUE, key))
        assert err <= stated[key], (key, err, stated[key])
        # the reported standard error estimates the theoretical one from 14 degrees of freedom
        assert 0.5 * theory[key] < fit.stderr[key] < 1.5 * theory[key], key
    # the fit sees the noise level it was given
    for line in (fit.x, fit.y, fit.z):
        assert 0.5 * SIGMA < line.rms_residual < 1.5 * SIGMA
        assert line.r_squared > 0.99


def test_reported_standard_errors_match_the_monte_carlo_spread() -> None:
    """Over 300 seeded noise draws the spread of each estimate agrees with the reported standard error
    (within 20%: the sampling error of a standard deviation from 300 draws is about 4%)."""
    estimates = {k: [] for k in KEYS}
    reported = {k: [] for k in KEYS}
    for seed in range(300):
        coeffs, fit = calibrate_from_slot_tests(*noisy(seed, SIGMA), A, N)
        for k in KEYS:
            estimates[k].append(getattr(coeffs, k))
            reported[k].append(fit.stderr[k])
    for k in KEYS:
        spread = float(np.std(estimates[k], ddof=1))
        assert spread == pytest.approx(float(np.mean(reported[k])), rel=0.2), k
        assert float(np.mean(estimates[k])) == pytest.approx(getattr(TRUE, k), abs=4 * spread / math.sqrt(300))


def test_two_feeds_fit_exactly_without_error_estimate() -> None:
    c = np.array([0.05, 0.1])
    coeffs, fit = calibrate_from_slot_tests(c, *slot_means(c, N, A, TRUE), axial_depth=A, flutes=N)
    assert coeffs.ktc == pytest.approx(TRUE.ktc, rel=1e-10)
    assert math.isnan(fit.stderr["ktc"])


@pytest.mark.parametrize(
    "args, match",
    [
        (([0.1, 0.1, 0.1], [1, 2, 3], [1, 2, 3], [1, 2, 3], 5.0, 4), "two or more different feeds"),
        (([0.1, 0.2], [1, 2, 3], [1, 2], [1, 2], 5.0, 4), "one mean force per feed"),
        (([0.1, 0.2], [1, 2], [1, 2], [1, 2], 0.0, 4), "axial depth"),
        (([0.1, 0.2], [1, 2], [1, 2], [1, 2], 5.0, 0), "flutes"),
        (([0.1, -0.2], [1, 2], [1, 2], [1, 2], 5.0, 4), "> 0"),
        (([0.1, 0.2], [1, math.nan], [1, 2], [1, 2], 5.0, 4), "finite"),
    ],
)
def test_bad_inputs(args: tuple, match: str) -> None:
    with pytest.raises(InputError, match=match):
        calibrate_from_slot_tests(*args)


# --- CSV and command line --------------------------------------------------------------------------

def write_csv(path: Path, c: np.ndarray, fx: np.ndarray, fy: np.ndarray, fz: np.ndarray) -> Path:
    lines = ["# slot tests, a = 5 mm, 4 flutes", "c_mm, fx_N, fy_N, fz_N"]
    lines += [f"{a:.6g},{b:.10g},{d:.10g},{e:.10g}" for a, b, d, e in zip(c, fx, fy, fz)]
    path.write_text("\n".join(lines) + "\n\n")
    return path


def cli() -> typer.Typer:
    app = typer.Typer()

    @app.callback()
    def main() -> None:  # a group, so the command is called by its name as in the real CLI
        """FusionCut."""

    register(app)
    return app


def run(*args: str):
    return CliRunner().invoke(cli(), list(args), env={"COLUMNS": "300", "NO_COLOR": "1"})


def test_read_csv_columns_in_any_order(tmp_path: Path) -> None:
    p = tmp_path / "t.csv"
    p.write_text("FZ_N,c_mm,extra,fy_N,fx_N\n3,0.1,x,2,1\n6,0.2,y,4,2\n")
    t = read_slot_tests_csv(p)
    np.testing.assert_array_equal(t.c, [0.1, 0.2])
    np.testing.assert_array_equal(t.fx, [1, 2])
    np.testing.assert_array_equal(t.fz, [3, 6])


def test_cli_prints_recovered_coefficients(tmp_path: Path) -> None:
    p = write_csv(tmp_path / "slots.csv", FEEDS, *slot_means(FEEDS, N, A, TRUE))
    result = run("calibrate", str(p), "--axial-depth", "5", "--flutes", "4")
    assert result.exit_code == 0, result.output
    for key in KEYS:
        assert f"{getattr(TRUE, key):.5g}" in result.output, key
    assert "Ktc" in result.output and "N/mm²" in result.output


@pytest.mark.parametrize(
    "text, where, what",
    [
        ("c_mm,fx_N,fy_N,fz_N\n0.1,1,2,3\n0.2,abc,4,6\n", ":3:", "'fx_N'"),
        ("# comment\n\nc_mm,fx_N,fy_N\n0.1,1,2\n", ":3:", "'fz_N'"),
        ("c_mm,fx_N,fy_N,fz_N\n0.1,1,2,3\n0.2,2,4\n", ":3:", "'fz_N'"),
        ("c_mm,fx_N,fy_N,fz_N\n0.1,1,2,3\n-0.2,2,4,6\n", ":3:", "> 0"),
        ("c_mm,fx_N,fy_N,fz_N\n0.1,1,2,nan\n0.2,2,4,6\n", ":2:", "finite"),
        ("", ":1:", "no header"),
        ("c_mm,fx_N,fy_N,fz_N\n0.1,1,2,3\n", ":", "at least two"),
    ],
)
def test_cli_bad_csv_names_file_and_line(tmp_path: Path, text: str, where: str, what: str) -> None:
    p = tmp_path / "bad.csv"
    p.write_text(text)
    result = run("calibrate", str(p), "--axial-depth", "5", "--flutes", "4")
    assert result.exit_code == 2, result.output
    assert f"{p}{where}" in result.output, result.output
    assert what in result.output
    assert "Traceback" not in result.output


def test_cli_missing_file_and_bad_option(tmp_path: Path) -> None:
    result = run("calibrate", str(tmp_path / "nope.csv"), "--axial-depth", "5", "--flutes", "4")
    assert result.exit_code == 2 and "nope.csv" in result.output
    p = write_csv(tmp_path / "slots.csv", FEEDS, *slot_means(FEEDS, N, A, TRUE))
    result = run("calibrate", str(p), "--axial-depth", "-1", "--flutes", "4")
    assert result.exit_code == 2 and "axial depth" in result.output
