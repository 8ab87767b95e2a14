"""Identify the six linear edge-force coefficients from slot-milling tests (Altintas 2012, §2.3).

Method. Cut full slots (immersion ``[0, pi]``) with a flat end mill of ``N`` flutes at axial depth ``a``
and several feeds per tooth ``c``; record the force on the tool averaged over whole revolutions. With
the model of :mod:`fusioncut.analysis.forces` on a cylinder (``kappa = 90``) the force of one edge point
of axial length ``dz`` at immersion ``phi`` is

    Fx = -(Ktc c sin phi + Kte) cos phi - (Krc c sin phi + Kre) sin phi
    Fy = +(Ktc c sin phi + Kte) sin phi - (Krc c sin phi + Kre) cos phi
    Fz = +(Kac c sin phi + Kae)                                           (times dz)

Every one of the ``N`` teeth sweeps every height once per revolution (whatever the helix), so the mean
over a revolution is ``N a / (2 pi)`` times the integral over ``phi`` in ``[0, pi]``; with
``int sin cos = 0``, ``int sin^2 = pi/2``, ``int sin = 2``, ``int cos = 0``, ``int 1 = pi``:

    mean Fx = -(N a Krc / 4) c - N a Kre / pi
    mean Fy = +(N a Ktc / 4) c + N a Kte / pi
    mean Fz = +(N a Kac / pi) c + N a Kae / 2

Each mean force is linear in ``c``: a least-squares line ``F = slope * c + intercept`` per axis gives

    Ktc = 4 slope_y / (N a)     Kte = pi intercept_y / (N a)
    Krc = -4 slope_x / (N a)    Kre = -pi intercept_x / (N a)
    Kac = pi slope_z / (N a)    Kae = 2 intercept_z / (N a)

Sign convention of the inputs: forces on the **tool**, in the feed frame of an M3 (clockwise) spindle:
x along the feed, y 90 deg counter-clockwise from it seen from above (the up-milling side), z up the tool
axis. A table dynamometer under the workpiece measures the reaction: negate all three components.
Mean Fx then comes out negative and mean Fy positive.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from fusioncut.analysis.forces import CuttingCoefficients
from fusioncut.errors import InputError, SourceLocation
from fusioncut.io.json_input import read_json

CSV_COLUMNS = ("c_mm", "fx_N", "fy_N", "fz_N")


@dataclass(frozen=True)
class LineFit:
    """Least-squares line ``F = slope * c + intercept`` of one mean-force component.

    ``slope`` N/mm, ``intercept`` N; standard errors from the residuals (NaN with only two distinct
    feeds, where the line fits exactly and nothing is left to estimate the scatter); ``r_squared``
    (NaN if the force does not vary); ``rms_residual`` (N).
    """

    slope: float
    intercept: float
    slope_stderr: float
    intercept_stderr: float
    r_squared: float
    rms_residual: float


@dataclass(frozen=True)
class CalibrationFit:
    """Statistics of a slot-test calibration.

    ``x``, ``y``, ``z``: the line fits of mean Fx, Fy, Fz against the feed per tooth. ``stderr``: the
    standard error of each coefficient (same keys and units as :meth:`CuttingCoefficients.as_dict`),
    from the line fits' standard errors (assumes independent, equal-variance scatter per axis).
    ``tests``: number of tests; ``axial_depth`` (mm) and ``flutes`` as given.
    """

    x: LineFit
    y: LineFit
    z: LineFit
    stderr: dict[str, float]
    tests: int
    axial_depth: float
    flutes: int


def _fit_line(c: np.ndarray, f: np.ndarray) -> LineFit:
    n = len(c)
    cm = c.mean()
    sxx = float(((c - cm) ** 2).sum())
    slope = float(((c - cm) * (f - f.mean())).sum() / sxx)
    intercept = float(f.mean() - slope * cm)
    resid = f - (slope * c + intercept)
    ssr = float((resid**2).sum())
    sst = float(((f - f.mean()) ** 2).sum())
    if n > 2:
        s2 = ssr / (n - 2)
        se_slope = math.sqrt(s2 / sxx)
        se_int = math.sqrt(s2 * (1.0 / n + cm * cm / sxx))
    else:
        se_slope = se_int = math.nan
    r2 = 1.0 - ssr / sst if sst > 0 else math.nan
    return LineFit(slope, intercept, se_slope, se_int, r2, math.sqrt(ssr / n))


def _as_array(name: str, values: Sequence[float]) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    if a.ndim != 1:
        raise InputError(f"{name} must be a 1-D sequence of numbers")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name} contains a value that is not a finite number")
    return a


def calibrate_from_slot_tests(
    feeds_per_tooth: Sequence[float],
    mean_fx: Sequence[float],
    mean_fy: Sequence[float],
    mean_fz: Sequence[float],
    axial_depth: float,
    flutes: int,
    *,
    name: str = "calibrated",
) -> tuple[CuttingCoefficients, CalibrationFit]:
    """Fit the six coefficients to mean slot forces (N) measured at feeds per tooth (mm).

    ``axial_depth`` (mm) is the slot depth, ``flutes`` the tool's tooth count; the forces follow the
    sign convention of the module docstring. Needs at least two distinct feeds (three or more to get
    standard errors). Returns the coefficients (``source`` records the test count) and the fit
    statistics.
    """
    c = _as_array("feeds per tooth", feeds_per_tooth)
    fx, fy, fz = (_as_array(n, v) for n, v in (("mean Fx", mean_fx), ("mean Fy", mean_fy), ("mean Fz", mean_fz)))
    if not (len(c) == len(fx) == len(fy) == len(fz)):
        raise InputError(
            f"need one mean force per feed: got {len(c)} feeds and {len(fx)}, {len(fy)}, {len(fz)} forces"
        )
    if np.any(c <= 0):
        raise InputError("feeds per tooth must be > 0 mm")
    if len(np.unique(c)) < 2:
        raise InputError(f"need tests at two or more different feeds per tooth, got {len(np.unique(c))}")
    if not (axial_depth > 0 and math.isfinite(axial_depth)):
        raise InputError(f"axial depth must be > 0 mm, got {axial_depth}")
    if int(flutes) != flutes or flutes < 1:
        raise InputError(f"flutes must be a positive integer, got {flutes}")

    na = flutes * axial_depth
    lx, ly, lz = _fit_line(c, fx), _fit_line(c, fy), _fit_line(c, fz)
    # (coefficient, line, slope or intercept, factor) from the inversion in the module docstring
    table = {
        "ktc": (ly, "slope", 4.0 / na),
        "krc": (lx, "slope", -4.0 / na),
        "kac": (lz, "slope", math.pi / na),
        "kte": (ly, "intercept", math.pi / na),
        "kre": (lx, "intercept", -math.pi / na),
        "kae": (lz, "intercept", 2.0 / na),
    }
    values = {k: getattr(line, part) * f for k, (line, part, f) in table.items()}
    stderr = {k: abs(f) * getattr(line, f"{part}_stderr") for k, (line, part, f) in table.items()}
    coeffs = CuttingCoefficients(
        **values,
        name=name,
        source=f"slot-test calibration: {len(c)} tests, a = {axial_depth:g} mm, {flutes} flutes",
    )
    return coeffs, CalibrationFit(lx, ly, lz, stderr, len(c), float(axial_depth), int(flutes))


@dataclass(frozen=True)
class SlotTests:
    """Mean slot forces read from a file: feeds per tooth (mm), mean Fx, Fy, Fz (N)."""

    c: np.ndarray
    fx: np.ndarray
    fy: np.ndarray
    fz: np.ndarray


def read_slot_tests_csv(path: str | Path) -> SlotTests:
    """Read a CSV with a header naming the columns ``c_mm, fx_N, fy_N, fz_N`` (any order, case and
    surrounding blanks ignored, extra columns ignored). Blank lines and lines starting with ``#`` are
    skipped. Errors name the file and the 1-based line (and column for a bad value)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"not a UTF-8 text file ({exc.reason} at byte {exc.start})", path) from None
    rows: list[tuple[int, list[str]]] = []
    reader = csv.reader(text.splitlines())
    for fields in reader:
        line = reader.line_num
        if not fields or all(not f.strip() for f in fields) or fields[0].lstrip().startswith("#"):
            continue
        rows.append((line, fields))
    if not rows:
        raise InputError(f"no header; expected columns {', '.join(CSV_COLUMNS)}", SourceLocation(str(path), 1))
    header_line, header = rows[0]
    names = [h.strip().lower() for h in header]
    index: dict[str, int] = {}
    for col in CSV_COLUMNS:
        if col.lower() not in names:
            raise InputError(
                f"header lacks column {col!r} (found: {', '.join(h.strip() for h in header)}); "
                f"expected {', '.join(CSV_COLUMNS)}",
                SourceLocation(str(path), header_line),
            )
        index[col] = names.index(col.lower())
    data: dict[str, list[float]] = {col: [] for col in CSV_COLUMNS}
    for line, fields in rows[1:]:
        for col in CSV_COLUMNS:
            k = index[col]
            if k >= len(fields):
                raise InputError(
                    f"{len(fields)} field(s), column {col!r} is field {k + 1}", SourceLocation(str(path), line)
                )
            raw = fields[k].strip()
            try:
                value = float(raw)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise InputError(
                    f"column {col!r} (field {k + 1}): {raw!r} is not a finite number", SourceLocation(str(path), line)
                )
            if col == "c_mm" and value <= 0:
                raise InputError(
                    f"column 'c_mm' (field {k + 1}): feed per tooth must be > 0, got {raw}",
                    SourceLocation(str(path), line),
                )
            data[col].append(value)
    if len(data["c_mm"]) < 2:
        raise InputError(f"{len(data['c_mm'])} test row(s); need at least two feeds per tooth", path)
    return SlotTests(*(np.array(data[col]) for col in CSV_COLUMNS))


COEFFICIENT_KEYS = ("ktc", "krc", "kac", "kte", "kre", "kae")
COEFFICIENT_UNITS = {"ktc": "N/mm²", "krc": "N/mm²", "kac": "N/mm²", "kte": "N/mm", "kre": "N/mm", "kae": "N/mm"}

# plausible ranges of published linear edge-force coefficients (aluminium alloys to nickel alloys with
# carbide tools): a value outside is warned about, not refused (a calibration may be right and unusual)
KTC_RANGE = (150.0, 6000.0)     # N/mm²
KRC_KTC_RANGE = (0.05, 1.2)     # Krc / Ktc
KAC_KTC_MAX = 1.0               # |Kac| / Ktc
EDGE_KTC_MAX_MM = 0.5           # Kte / Ktc, Kre / Ktc (mm): edge force per length against a 0.5 mm chip
R_SQUARED_MIN = 0.95            # mean Fx, Fy against the feed per tooth


def plausibility_warnings(coeffs: CuttingCoefficients, fit: CalibrationFit | None = None) -> list[str]:
    """What is implausible about a coefficient set (empty: nothing): Ktc outside :data:`KTC_RANGE`,
    Krc / Ktc outside :data:`KRC_KTC_RANGE`, |Kac| above :data:`KAC_KTC_MAX` Ktc, negative or large edge
    coefficients, and with a fit an R² of Fx or Fy under :data:`R_SQUARED_MIN`. ``ktc`` and ``krc``
    must be > 0 (:func:`check_signs`)."""
    out = []
    ktc, krc = coeffs.ktc, coeffs.krc
    if not KTC_RANGE[0] <= ktc <= KTC_RANGE[1]:
        out.append(f"Ktc {ktc:.4g} N/mm² is outside {KTC_RANGE[0]:g}..{KTC_RANGE[1]:g} N/mm² (published sets, "
                   "aluminium to nickel alloys): check the axial depth, the flute count and the force units")
    if ktc > 0 and not KRC_KTC_RANGE[0] <= krc / ktc <= KRC_KTC_RANGE[1]:
        out.append(f"Krc / Ktc = {krc / ktc:.3g} is outside {KRC_KTC_RANGE[0]:g}..{KRC_KTC_RANGE[1]:g}: check "
                   "that fx_N is along the feed and fy_N across it")
    if ktc > 0 and abs(coeffs.kac) > KAC_KTC_MAX * ktc:
        out.append(f"|Kac| = {abs(coeffs.kac):.4g} N/mm² exceeds Ktc: check the sign and units of fz_N")
    for key in ("kte", "kre"):
        v = getattr(coeffs, key)
        if v < 0:
            out.append(f"{key.capitalize()} = {v:.4g} N/mm is negative (an edge force that pulls the tool into "
                       "the cut): the lines' intercepts are off, check the lowest feeds or the force offsets")
        elif ktc > 0 and v > EDGE_KTC_MAX_MM * ktc:
            out.append(f"{key.capitalize()} = {v:.4g} N/mm is more than {EDGE_KTC_MAX_MM:g} mm x Ktc: check the "
                       "zero of the dynamometer (a force offset lands in the edge coefficients)")
    if fit is not None:
        for axis, line in (("Fx", fit.x), ("Fy", fit.y)):
            if math.isfinite(line.r_squared) and line.r_squared < R_SQUARED_MIN:
                out.append(f"mean {axis} is not linear in the feed per tooth: R² {line.r_squared:.3f} < "
                           f"{R_SQUARED_MIN:g} (the linear edge-force model may not hold, or the tests scatter)")
    return out


def check_signs(coeffs: CuttingCoefficients, where: str | Path | SourceLocation | None = None) -> None:
    """Ktc and Krc must be > 0: mean Fy of a slot grows and mean Fx falls with the feed (forces on the
    tool, M3, feed frame). Otherwise the forces are most likely the workpiece's (a table dynamometer:
    negate them) or x and y are swapped; raises :class:`InputError` naming ``where``."""
    if coeffs.ktc <= 0:
        raise InputError(f"Ktc = {coeffs.ktc:.4g} N/mm² is not > 0: mean fy_N must grow with the feed (forces on "
                         "the tool, y 90 deg counter-clockwise from the feed); a table dynamometer measures the "
                         "reaction: negate its readings", where)
    if coeffs.krc <= 0:
        raise InputError(f"Krc = {coeffs.krc:.4g} N/mm² is not > 0: mean fx_N must fall with the feed (forces on "
                         "the tool, x along the feed); check the sign of fx_N and that x is the feed direction",
                         where)


def coefficients_document(coeffs: CuttingCoefficients, fit: CalibrationFit | None = None, data: str = "",
                          warnings: Sequence[str] = ()) -> dict:
    """The JSON object :func:`read_coefficients_json` reads: the six coefficients, ``units``, ``name``,
    ``source`` and, from a calibration, ``fit`` (R² and rms residual per axis, standard errors, tests,
    axial depth, flutes, the data file) and its ``warnings``."""
    doc: dict = {k: float(getattr(coeffs, k)) for k in COEFFICIENT_KEYS}
    doc.update(units=dict(COEFFICIENT_UNITS), name=coeffs.name, source=coeffs.source)
    if fit is not None:
        doc["fit"] = {
            "data": data,
            "tests": fit.tests,
            "axial_depth_mm": fit.axial_depth,
            "flutes": fit.flutes,
            "r_squared": {a: _json_number(getattr(fit, a).r_squared) for a in ("x", "y", "z")},
            "rms_residual_N": {a: _json_number(getattr(fit, a).rms_residual) for a in ("x", "y", "z")},
            "stderr": {k: _json_number(v) for k, v in fit.stderr.items()},
        }
    if warnings:
        doc["warnings"] = list(warnings)
    return doc


def _json_number(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def write_coefficients_json(path: str | Path, coeffs: CuttingCoefficients, fit: CalibrationFit | None = None,
                            data: str = "", warnings: Sequence[str] = ()) -> None:
    import json

    Path(path).write_text(json.dumps(coefficients_document(coeffs, fit, data, warnings), indent=2,
                                     ensure_ascii=False) + "\n", encoding="utf-8")


def read_coefficients_json(path: str | Path) -> CuttingCoefficients:
    """Cutting coefficients from a JSON object with the six keys of
    :meth:`CuttingCoefficients.as_dict` (``ktc, krc, kac`` N/mm², ``kte, kre, kae`` N/mm; axial sign
    convention of :mod:`fusioncut.analysis.forces`), optional ``name`` and ``source`` strings and what
    :func:`coefficients_document` adds (``units``, which must be those units, ``fit``, ``warnings``).
    Ktc and Krc must be > 0 (:func:`check_signs`). Errors name the file (and the line of bad JSON)."""
    path = Path(path)
    data = read_json(path)
    if not isinstance(data, dict):
        raise InputError(f"expected an object with the keys {', '.join(COEFFICIENT_KEYS)}", path)
    missing = [k for k in COEFFICIENT_KEYS if k not in data]
    unknown = sorted(set(data) - set(COEFFICIENT_KEYS) - {"name", "source", "units", "fit", "warnings"})
    if missing or unknown:
        raise InputError(f"missing key(s) {missing}, unknown key(s) {unknown}; expected "
                         f"{', '.join(COEFFICIENT_KEYS)} (and optional name, source, units, fit, warnings)", path)
    bad = [k for k in COEFFICIENT_KEYS if isinstance(data[k], bool) or not isinstance(data[k], (int, float))]
    if bad:
        raise InputError(f"coefficient(s) {', '.join(bad)} must be numbers", path)
    units = data.get("units", COEFFICIENT_UNITS)
    if not isinstance(units, dict) or any(units.get(k, u) != u for k, u in COEFFICIENT_UNITS.items()):
        raise InputError(f"'units' must be {COEFFICIENT_UNITS} (convert the values), got {units!r}", path)
    try:
        coeffs = CuttingCoefficients(**{k: float(data[k]) for k in COEFFICIENT_KEYS},
                                     name=str(data.get("name") or path.stem), source=str(data.get("source") or path))
    except InputError as exc:
        raise InputError(exc.reason, path) from None
    check_signs(coeffs, path)
    return coeffs
