"""Tool-tip dynamics: modes files, FRF CSV files and the modal fit (exact recovery from a closed-form
FRF written with 4 significant digits, recovery under measurement noise, errors naming file:line)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fusioncut.analysis.dynamics import (Mode, ToolDynamics, dynamics_from_frf, fit_modes, read_dynamics,
                                         read_frf_csv, read_modes_json)
from fusioncut.errors import InputError

DOCS = Path(__file__).parents[2] / "docs"
TRUE = ToolDynamics((Mode(600.0, 0.035, 5.6e6), Mode(1450.0, 0.02, 1.4e7)), (Mode(660.0, 0.03, 5.7e6),))


def test_receptance_closed_form() -> None:
    m = Mode(922.0, 0.011, 1.34e6)
    # at resonance Phi = 1 / (2 i zeta k); statically 1 / k; far above, -1 / (k r^2)
    assert m.receptance(np.array([m.wn]))[0] == pytest.approx(-1j / (2 * m.zeta * m.k_n_per_m), rel=1e-12)
    assert m.receptance(np.array([0.0]))[0] == pytest.approx(1 / m.k_n_per_m, rel=1e-12)
    assert m.mass_kg * m.wn ** 2 == pytest.approx(m.k_n_per_m, rel=1e-12)
    assert m.damping_n_s_per_m == pytest.approx(2 * m.zeta * m.mass_kg * m.wn, rel=1e-12)


def test_modes_json_example_and_errors(tmp_path: Path) -> None:
    dyn = read_modes_json(DOCS / "stability_modes_example.json")
    assert dyn.x == TRUE.x and dyn.y == TRUE.y
    cases = {
        '{"x": [{"fn_hz": 600, "zeta": 1.2, "k_n_per_m": 5e6}]}': "x[0]: mode zeta must be < 1",
        '{"x": [{"fn_hz": -1, "zeta": 0.1, "k_n_per_m": 5e6}]}': "x[0]: mode fn_hz must be a finite number > 0",
        '{"y": [{"fn_hz": 600, "zeta": 0.1}]}': "y[0] must be an object with exactly the keys",
        '{"z": []}': "unknown key(s) 'z'",
        '{"x": []}': "no mode",
        '{"x": [\n  {"fn_hz": 600,}]}': ":2:",
    }
    for text, msg in cases.items():
        p = tmp_path / "m.json"
        p.write_text(text)
        with pytest.raises(InputError) as exc:
            read_modes_json(p)
        assert str(exc.value).startswith(str(p)) and msg in str(exc.value), str(exc.value)


def test_fit_recovers_modes_from_the_example_csv() -> None:
    """The example FRF holds the example modes' receptance with 4 significant digits."""
    dyn, fits = read_dynamics(DOCS / "stability_frf_example.csv")
    for got, want in ((dyn.x, TRUE.x), (dyn.y, TRUE.y)):
        assert len(got) == len(want)
        for g, w in zip(got, want):
            assert g.fn_hz == pytest.approx(w.fn_hz, rel=1e-4)
            assert g.zeta == pytest.approx(w.zeta, rel=2e-3)
            assert g.k_n_per_m == pytest.approx(w.k_n_per_m, rel=2e-3)
    assert 0 < fits["x"].relative_rms_error < 1e-3 and 0 < fits["y"].relative_rms_error < 1e-3


def test_fit_under_noise_reports_its_error() -> None:
    f = np.linspace(100.0, 3000.0, 600)
    h = TRUE.receptance("x", 2 * math.pi * f)
    rng = np.random.default_rng(7)
    noise = 0.01 * np.abs(h).max() * (rng.standard_normal(len(f)) + 1j * rng.standard_normal(len(f)))
    fit = fit_modes(f, h + noise)
    assert [round(m.fn_hz) for m in fit.modes] == [600, 1450]
    for g, w in zip(fit.modes, TRUE.x):
        assert g.fn_hz == pytest.approx(w.fn_hz, rel=2e-3)
        assert g.zeta == pytest.approx(w.zeta, rel=0.05)
        assert g.k_n_per_m == pytest.approx(w.k_n_per_m, rel=0.05)
    # the reported error is the noise's own size relative to the FRF
    expected = float(np.sqrt(np.sum(np.abs(noise) ** 2) / np.sum(np.abs(h + noise) ** 2)))
    assert fit.relative_rms_error == pytest.approx(expected, rel=0.1)
    one = fit_modes(f, h + noise, n_modes=1)
    assert len(one.modes) == 1 and one.relative_rms_error > fit.relative_rms_error


def test_frf_csv_errors(tmp_path: Path) -> None:
    f = np.arange(400.0, 800.0, 10.0)
    h = TRUE.receptance("x", 2 * math.pi * f)
    good = [f"{a:g},{b:.6g},{c:.6g}" for a, b, c in zip(f, h.real, h.imag)]

    def write(lines: list[str]) -> Path:
        p = tmp_path / "frf.csv"
        p.write_text("\n".join(lines) + "\n")
        return p

    assert dynamics_from_frf(read_frf_csv(write(["frequency_hz,x_real,x_imag", *good])))[0].y == ()
    cases = [
        (["frequency_hz,x_real", *good], ":1: header has only one of x_real, x_imag"),
        (["f,x_real,x_imag", *good], ":1: header lacks column 'frequency_hz'"),
        (["frequency_hz,x_real,x_imag", *good[:3], "410,1e-7,oops", *good[3:]], ":5:3: x_imag"),
        (["frequency_hz,x_real,x_imag", *good[:3], good[1], *good[3:]], ":5: frequencies must be > 0 Hz and "
                                                                         "strictly increasing"),
        (["frequency_hz,x_real,x_imag", *good[:4]], "4 frequency row(s)"),
    ]
    for lines, msg in cases:
        p = write(lines)
        with pytest.raises(InputError) as exc:
            read_frf_csv(p)
        assert str(exc.value).startswith(str(p)) and msg in str(exc.value), str(exc.value)
    # the other sign convention (imaginary part positive at resonance) is refused, not fitted
    conj = [f"{a:g},{b:.6g},{-c:.6g}" for a, b, c in zip(f, h.real, h.imag)]
    p = write(["frequency_hz,x_real,x_imag", *conj])
    with pytest.raises(InputError, match="never negative"):
        dynamics_from_frf(read_frf_csv(p))
    with pytest.raises(InputError, match="unknown dynamics file type"):
        read_dynamics(tmp_path / "modes.txt")
