"""Tool-tip dynamics for chatter stability: modal parameters, measured FRFs and their modal fit.

The structure at the tool tip is described per machine direction ``x`` and ``y`` (the machine's X and Y
axes, seen in the plane normal to the tool axis) by independent single-degree-of-freedom modes, summed
(no cross terms: the FRF from a force along x to a displacement along y is taken as zero). A mode has
natural frequency ``fn_hz`` (Hz), damping ratio ``zeta`` (-) and modal stiffness ``k_n_per_m`` (N/m);
its receptance (displacement over force, m/N) at the angular frequency ``w`` (rad/s) is

    Phi(i w) = 1 / (k (1 - r**2 + 2 i zeta r)),      r = w / wn,  wn = 2 pi fn_hz

(the convention ``x(t) = Re(X e^{+i w t})``, in which the imaginary part is negative at resonance).
Its mass is ``k / wn**2`` (kg) and its viscous damping ``2 zeta sqrt(k m)`` (N s/m).

Two inputs:

* a modes JSON file ``{"x": [{"fn_hz": 600, "zeta": 0.035, "k_n_per_m": 5.6e6}, ...], "y": [...]}``
  (:func:`read_modes_json`; a direction with an empty list is rigid);
* a measured FRF as CSV (:func:`read_frf_csv`), columns ``frequency_hz`` and, per measured direction,
  ``x_real``, ``x_imag`` / ``y_real``, ``y_imag`` (m/N), fitted to modes by :func:`fit_modes`: peaks of
  ``-Im Phi`` give the starting modes (``fn`` at the peak, ``zeta`` from the half-height width
  ``2 zeta wn``, ``k = 1 / (2 zeta |Im Phi|)`` at the peak), then a Levenberg-Marquardt least-squares
  refinement of every ``fn, zeta, k`` on the complex FRF. The fit's error is the relative RMS of the
  complex residual, ``sqrt(sum |Phi_fit - Phi|**2 / sum |Phi|**2)``.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from fusioncut.errors import InputError, SourceLocation
from fusioncut.io.json_input import read_json

DIRECTIONS = ("x", "y")
MODE_KEYS = ("fn_hz", "zeta", "k_n_per_m")


@dataclass(frozen=True)
class Mode:
    """One single-degree-of-freedom mode: ``fn_hz`` (Hz), ``zeta`` (-), ``k_n_per_m`` (N/m)."""

    fn_hz: float
    zeta: float
    k_n_per_m: float

    def __post_init__(self) -> None:
        for key in MODE_KEYS:
            v = getattr(self, key)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) or v <= 0:
                raise InputError(f"mode {key} must be a finite number > 0, got {v!r}")
        if self.zeta >= 1:
            raise InputError(f"mode zeta must be < 1 (an underdamped mode), got {self.zeta!r}")

    @property
    def wn(self) -> float:
        """Natural angular frequency (rad/s)."""
        return 2.0 * math.pi * self.fn_hz

    @property
    def mass_kg(self) -> float:
        return self.k_n_per_m / self.wn ** 2

    @property
    def damping_n_s_per_m(self) -> float:
        return 2.0 * self.zeta * math.sqrt(self.k_n_per_m * self.mass_kg)

    def receptance(self, w: np.ndarray) -> np.ndarray:
        """``Phi(i w)`` (m/N) at angular frequencies ``w`` (rad/s)."""
        r = np.asarray(w, dtype=float) / self.wn
        return 1.0 / (self.k_n_per_m * (1.0 - r * r + 2j * self.zeta * r))


@dataclass(frozen=True)
class ToolDynamics:
    """Modes of the tool tip along the machine's x and y (either may be empty: rigid)."""

    x: tuple[Mode, ...] = ()
    y: tuple[Mode, ...] = ()
    source: str = ""

    def __post_init__(self) -> None:
        if not self.x and not self.y:
            raise InputError("the tool-tip dynamics need at least one mode (x or y)", self.source or None)

    def modes(self, direction: str) -> tuple[Mode, ...]:
        return self.x if direction == "x" else self.y

    def receptance(self, direction: str, w: np.ndarray) -> np.ndarray:
        """Summed receptance (m/N) of one direction at angular frequencies ``w`` (rad/s)."""
        w = np.asarray(w, dtype=float)
        out = np.zeros(w.shape, dtype=complex)
        for m in self.modes(direction):
            out += m.receptance(w)
        return out

    @property
    def all_modes(self) -> tuple[tuple[str, Mode], ...]:
        return tuple(("x", m) for m in self.x) + tuple(("y", m) for m in self.y)

    def frequency_band_hz(self) -> tuple[float, float]:
        """Lowest and highest natural frequency (Hz)."""
        f = [m.fn_hz for _, m in self.all_modes]
        return min(f), max(f)

    def as_dict(self) -> dict[str, list[dict[str, float]]]:
        return {d: [{k: float(getattr(m, k)) for k in MODE_KEYS} for m in self.modes(d)] for d in DIRECTIONS}


def read_modes_json(path: str | Path) -> ToolDynamics:
    """Modes from a JSON file (module docstring); errors name the file (and line for bad JSON) and the
    entry, e.g. ``modes.json: x[1].zeta must be < 1``."""
    path = Path(path)
    data = read_json(path)
    if not isinstance(data, dict):
        raise InputError('expected an object {"x": [modes], "y": [modes]}', path)
    unknown = sorted(set(data) - set(DIRECTIONS))
    if unknown:
        raise InputError(f"unknown key(s) {', '.join(map(repr, unknown))}; expected 'x' and/or 'y'", path)
    modes: dict[str, tuple[Mode, ...]] = {}
    for d in DIRECTIONS:
        entries = data.get(d, [])
        if not isinstance(entries, list):
            raise InputError(f"{d!r} must be a list of modes", path)
        out = []
        for i, e in enumerate(entries):
            if not isinstance(e, dict) or sorted(e) != sorted(MODE_KEYS):
                raise InputError(f"{d}[{i}] must be an object with exactly the keys {', '.join(MODE_KEYS)}", path)
            try:
                out.append(Mode(*(e[k] for k in MODE_KEYS)))
            except InputError as exc:
                raise InputError(f"{d}[{i}]: {exc.reason}", path) from None
        modes[d] = tuple(out)
    if not modes["x"] and not modes["y"]:
        raise InputError("no mode in 'x' nor 'y'", path)
    return ToolDynamics(modes["x"], modes["y"], str(path))


# --------------------------------------------------------------------------------------------------
# measured FRFs


@dataclass(frozen=True)
class MeasuredFRF:
    """A measured receptance: ``frequency_hz`` (F,) and per measured direction a complex array (m/N)."""

    frequency_hz: np.ndarray
    frf: dict[str, np.ndarray]
    source: str = ""


def read_frf_csv(path: str | Path) -> MeasuredFRF:
    """Read an FRF CSV: a header naming ``frequency_hz`` and ``x_real, x_imag`` and/or ``y_real, y_imag``
    (m/N; any order, case ignored, extra columns ignored; blank lines and ``#`` lines skipped). Frequencies
    must be finite, > 0 and strictly increasing. Errors name the file, line and column."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"not a UTF-8 text file ({exc.reason} at byte {exc.start})", path) from None
    reader = csv.reader(text.splitlines())
    rows: list[tuple[int, list[str]]] = []
    for fields in reader:
        if not fields or all(not f.strip() for f in fields) or fields[0].lstrip().startswith("#"):
            continue
        rows.append((reader.line_num, fields))
    if not rows:
        raise InputError("no header; expected frequency_hz, x_real, x_imag, y_real, y_imag",
                         SourceLocation(str(path), 1))
    head_line, header = rows[0]
    names = [h.strip().lower() for h in header]
    where = SourceLocation(str(path), head_line)
    if "frequency_hz" not in names:
        raise InputError(f"header lacks column 'frequency_hz' (found: {', '.join(names)})", where)
    dirs = []
    for d in DIRECTIONS:
        have = [f"{d}_real" in names, f"{d}_imag" in names]
        if any(have) and not all(have):
            raise InputError(f"header has only one of {d}_real, {d}_imag", where)
        if all(have):
            dirs.append(d)
    if not dirs:
        raise InputError("header names neither x_real, x_imag nor y_real, y_imag", where)
    cols = ["frequency_hz"] + [f"{d}_{p}" for d in dirs for p in ("real", "imag")]
    index = {c: names.index(c) for c in cols}
    values: dict[str, list[float]] = {c: [] for c in cols}
    for line, fields in rows[1:]:
        for c in cols:
            k = index[c]
            if k >= len(fields):
                raise InputError(f"{len(fields)} field(s), column {c!r} is field {k + 1}",
                                 SourceLocation(str(path), line))
            try:
                v = float(fields[k].strip())
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise InputError(f"{c}: {fields[k].strip()!r} is not a finite number",
                                 SourceLocation(str(path), line, k + 1))
            values[c].append(v)
    f = np.array(values["frequency_hz"])
    if len(f) < 8:
        raise InputError(f"{len(f)} frequency row(s); a modal fit needs at least 8", path)
    bad = np.flatnonzero((f <= 0) | np.r_[False, np.diff(f) <= 0])
    if len(bad):
        line = rows[1 + int(bad[0])][0]
        raise InputError("frequencies must be > 0 Hz and strictly increasing", SourceLocation(str(path), line))
    frf = {d: np.array(values[f"{d}_real"]) + 1j * np.array(values[f"{d}_imag"]) for d in dirs}
    return MeasuredFRF(f, frf, str(path))


@dataclass(frozen=True)
class ModalFit:
    """Modes fitted to one direction's FRF and the fit's relative RMS error (see the module docstring)."""

    modes: tuple[Mode, ...]
    relative_rms_error: float


def _model(params: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Summed receptance of modes with log-parameters ``(ln wn, ln zeta, ln k)`` per row."""
    wn, zeta, k = np.exp(params[:, 0:1]), np.exp(params[:, 1:2]), np.exp(params[:, 2:3])
    r = w[None, :] / wn
    return (1.0 / (k * (1.0 - r * r + 2j * zeta * r))).sum(axis=0)


def _peaks(f: np.ndarray, frf: np.ndarray, n_modes: int | None, where: str) -> list[tuple[float, float, float]]:
    """Starting ``(fn, zeta, k)`` from the peaks of ``-Im Phi`` (see the module docstring)."""
    g = -frf.imag
    top = float(g.max())
    if top <= 0:
        raise InputError("the imaginary part is never negative: not a receptance in the convention "
                         "x = Re(X e^{+iwt}) (conjugate it) or no resonance in the band", where)
    inner = np.flatnonzero((g[1:-1] > g[:-2]) & (g[1:-1] >= g[2:])) + 1
    # a peak is the highest point within +-5 % of its frequency (measurement noise makes local maxima)
    inner = [i for i in inner if g[i] >= g[(f >= 0.95 * f[i]) & (f <= 1.05 * f[i])].max()]
    cand = sorted(inner, key=lambda i: -g[i])
    if n_modes is None:  # every peak at least 10 % of the highest
        cand = [i for i in cand if g[i] >= 0.1 * top]
    cand = cand[: (n_modes or 6)]
    if n_modes is not None and len(cand) < n_modes:
        raise InputError(f"found {len(cand)} resonance peak(s), {n_modes} asked for", where)
    out = []
    for i in sorted(cand):
        half = 0.5 * g[i]
        lo = i
        while lo > 0 and g[lo] > half:
            lo -= 1
        hi = i
        while hi < len(g) - 1 and g[hi] > half:
            hi += 1
        width = max(f[hi] - f[lo], f[min(i + 1, len(f) - 1)] - f[max(i - 1, 0)])
        zeta = min(max(width / (2.0 * f[i]), 1e-4), 0.5)
        out.append((float(f[i]), zeta, 1.0 / (2.0 * zeta * g[i])))
    return out


def fit_modes(frequency_hz: Sequence[float], frf: Sequence[complex], n_modes: int | None = None,
              where: str = "") -> ModalFit:
    """Fit summed modes to one direction's measured receptance (m/N at ``frequency_hz``).

    ``n_modes``: how many modes (the highest peaks); by default every peak of ``-Im Phi`` at least 10 % of
    the highest that is the highest point within +-5 % of its frequency (at most 6). Starting values by
    peak picking, then Levenberg-Marquardt on the complex residual relative to the largest ``|Phi|``
    (parameters ``ln wn, ln zeta, ln k``, which keeps them > 0).
    """
    f = np.asarray(frequency_hz, dtype=float)
    h = np.asarray(frf, dtype=complex)
    start = _peaks(f, h, n_modes, where)
    w = 2.0 * math.pi * f
    scale = float(np.abs(h).max())
    p = np.log(np.array([[2.0 * math.pi * fn, z, k] for fn, z, k in start]))

    def residual(q: np.ndarray) -> np.ndarray:
        d = (_model(q.reshape(-1, 3), w) - h) / scale
        return np.concatenate((d.real, d.imag))

    x = p.ravel()
    r = residual(x)
    lam = 1e-3
    for _ in range(200):
        jac = np.empty((len(r), len(x)))
        for j in range(len(x)):
            dx = np.zeros_like(x)
            dx[j] = 1e-7
            jac[:, j] = (residual(x + dx) - r) / 1e-7
        jtj, jtr = jac.T @ jac, jac.T @ r
        improved = False
        for _ in range(20):
            step = np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-12), -jtr)
            cand = x + step
            rc = residual(cand)
            if np.isfinite(rc).all() and rc @ rc < r @ r:
                improved = True
                small = np.abs(step).max() < 1e-10 or (r @ r - rc @ rc) < 1e-14 * max(r @ r, 1e-300)
                x, r, lam = cand, rc, max(lam / 5.0, 1e-12)
                break
            lam *= 10.0
        if not improved or small:
            break
    q = np.exp(x.reshape(-1, 3))
    try:
        modes = tuple(sorted((Mode(float(wn / (2 * math.pi)), float(z), float(k)) for wn, z, k in q),
                             key=lambda m: m.fn_hz))
    except InputError as exc:
        raise InputError(f"the modal fit did not converge to a physical mode ({exc.reason})", where) from None
    err = float(np.sqrt(np.sum(np.abs(_model(x.reshape(-1, 3), w) - h) ** 2) / np.sum(np.abs(h) ** 2)))
    return ModalFit(modes, err)


def dynamics_from_frf(measured: MeasuredFRF, n_modes: int | None = None) -> tuple[ToolDynamics, dict[str, ModalFit]]:
    """Fit every measured direction of ``measured``; an unmeasured direction is rigid."""
    fits = {d: fit_modes(measured.frequency_hz, h, n_modes, f"{measured.source} ({d})")
            for d, h in measured.frf.items()}
    dyn = ToolDynamics(fits["x"].modes if "x" in fits else (), fits["y"].modes if "y" in fits else (), measured.source)
    return dyn, fits


def read_dynamics(path: str | Path, n_modes: int | None = None) -> tuple[ToolDynamics, dict[str, ModalFit]]:
    """Modes from ``path``: a ``.json`` modes file (no fits) or a ``.csv`` FRF (fitted)."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        return read_modes_json(path), {}
    if path.suffix.lower() == ".csv":
        return dynamics_from_frf(read_frf_csv(path), n_modes)
    raise InputError(f"unknown dynamics file type {path.suffix!r}: give modes (.json) or an FRF (.csv)", path)
