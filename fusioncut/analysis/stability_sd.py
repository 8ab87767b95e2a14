"""Numerical parts of the semi-discretization of :mod:`fusioncut.analysis.stability`: the exact interval
integrals of the piecewise-constant system and the spectral radius of the monodromy matrix.

Spectral radius (:func:`spectral_radius`): exact reductions, then a Krylov method where that is cheaper.

* A delayed state that no interval reads (the teeth are out of the cut there, so its input matrices are
  exactly zero) is an exactly zero column of the monodromy matrix ``Z``. With those columns (and their
  rows) last, ``Z = [[A, 0], [C, 0]]`` is block triangular: its eigenvalues are those of the principal
  submatrix ``A`` and zeros. At low radial immersion most delayed states are unread (a/D 0.1 on two
  flutes: 4 of 5), and ``A`` is that much smaller.
* The largest multipliers of ``A`` by Arnoldi's method (``krylov`` steps from a fixed start vector, the
  Gram-Schmidt orthogonalisation done twice): a Ritz value ``theta`` with residual ``r = |h_{k+1,k}| |s_k|``
  is an eigenvalue of ``A + E`` with ``||E||_2 = r``. It is accepted as the spectral radius when the
  Ritz value of largest modulus has ``r <= rel_tol |theta|``; otherwise (and for matrices of at most
  ``2 krylov`` rows, where LAPACK is as cheap) the eigenvalues come from ``numpy.linalg.eigvals``. The
  monodromy matrix of a delay equation has few multipliers away from the origin (its spectrum
  accumulates at 0), and those are what a Krylov space of a generic vector resolves first.
  ``tests/analysis/test_stability_fast.py`` compares the radius with LAPACK's on both benchmark systems.
"""
from __future__ import annotations

import math

import numpy as np

_START = np.random.default_rng(20260527).standard_normal(4096)  # fixed: a generic start vector, reproducible


def interval_integrals(a: np.ndarray, dt: np.ndarray, scale: np.ndarray | None = None,
                       degree: int = 12) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For a stack of system matrices ``a`` (..., d, d) and steps ``dt`` (s, broadcast against the
    leading axes): ``E = exp(A dt)``, ``F1 = int_0^dt e^{A(dt-s)} ds`` and ``F2 = int_0^dt e^{A(dt-s)} s ds``.

    With ``scale`` (d,) the series runs on ``S A S^-1`` (``S = diag(scale)``) and the results are turned
    back (``f(S A S^-1) = S f(A) S^-1``): with displacements and velocities in one state, ``scale = (1,
    .., 1/w, ..)`` for a frequency ``w`` of the modes makes the matrix's norm about ``w dt`` instead of
    ``w^2 dt`` and saves most doublings. Taylor series on ``X = A h``, ``h = dt / 2^q`` with the 1-norm of
    ``X`` at most 1/2 (truncation below 1e-14 relative at ``degree`` 12): ``E = P0``, ``F1 = h P1``, ``F2 =
    h^2 P2`` with ``Pj = sum X^k / (k + j)!``, evaluated as ``P2`` by Horner, ``P1 = I + X P2``, ``P0 = I +
    X P1``; then ``q`` doublings of the interval: ``E <- E E``, ``F1 <- F1 + E F1``, ``F2 <- E F2 + h F1 +
    F2`` (split at ``h``), ``h <- 2 h``.
    """
    if scale is not None:
        ratio = scale[:, None] / scale[None, :]
        e, f1, f2 = interval_integrals(a * ratio, dt, None, degree)
        return e / ratio, f1 / ratio, f2 / ratio
    d = a.shape[-1]
    h = np.broadcast_to(np.asarray(dt, dtype=float), a.shape[:-2])[..., None, None]
    norm = float((np.abs(a).sum(axis=-2).max(axis=-1) * h[..., 0, 0]).max()) if a.size else 0.0
    q = max(0, int(math.ceil(math.log2(norm / 0.5)))) if norm > 0.5 else 0
    h = h / 2.0 ** q
    x = a * h
    eye = np.eye(d)
    p2 = eye / math.factorial(degree + 2) + 0.0 * x
    for k in range(degree - 1, -1, -1):
        p2 = eye / math.factorial(k + 2) + x @ p2
    p1 = eye + x @ p2
    e = eye + x @ p1
    f1, f2 = h * p1, h * h * p2
    for _ in range(q):
        f2 = e @ f2 + h * f1 + f2
        f1 = f1 + e @ f1
        e = e @ e
        h = 2.0 * h
    return e, f1, f2


def read_states(z: np.ndarray) -> np.ndarray:
    """Indices of the columns of ``z`` (..., D, D) that are nonzero in some matrix of the stack: the
    states whose values the next period reads (the eigenvalues of ``z`` are those of the principal
    submatrices on them, and zeros)."""
    return np.flatnonzero(np.any(z != 0, axis=tuple(range(z.ndim - 1))))


def spectral_radius(z: np.ndarray, krylov: int = 20, rel_tol: float = 1e-10, chunk: int = 256) -> np.ndarray:
    """Spectral radius of each matrix of the stack ``z`` (P, D, D) (module docstring)."""
    keep = read_states(z)
    if len(keep) < z.shape[-1]:
        z = z[:, keep][:, :, keep]
    p, d = z.shape[0], z.shape[-1]
    if d <= 2 * krylov:
        return np.abs(np.linalg.eigvals(z)).max(axis=1) if d else np.zeros(p)
    out = np.empty(p)
    for s in range(0, p, chunk):
        out[s:s + chunk] = _arnoldi_radius(z[s:s + chunk], krylov, rel_tol)
    return out


def _arnoldi_radius(z: np.ndarray, k: int, rel_tol: float) -> np.ndarray:
    p, d = z.shape[0], z.shape[-1]
    v = np.zeros((p, k + 1, d))
    h = np.zeros((p, k + 1, k))
    start = np.resize(_START, d)
    v[:, 0] = start / np.linalg.norm(start)
    for j in range(k):
        w = np.matmul(z, v[:, j, :, None])[..., 0]
        basis = v[:, :j + 1]
        for _ in range(2):  # classical Gram-Schmidt, twice: orthogonal to rounding
            c = np.matmul(basis, w[..., None])[..., 0]
            w -= np.matmul(c[:, None, :], basis)[:, 0]
            h[:, :j + 1, j] += c
        beta = np.linalg.norm(w, axis=1)
        h[:, j + 1, j] = beta
        v[:, j + 1] = w / np.where(beta > 0, beta, 1.0)[:, None]
    theta, vec = np.linalg.eig(h[:, :k, :k])
    top = np.argmax(np.abs(theta), axis=1)
    rows = np.arange(p)
    radius = np.abs(theta[rows, top])
    residual = np.abs(h[:, k, k - 1]) * np.abs(vec[rows, k - 1, top])
    bad = np.flatnonzero(~(residual <= rel_tol * radius))
    if len(bad):
        radius[bad] = np.abs(np.linalg.eigvals(z[bad])).max(axis=1)
    return radius
