"""Numerical parts of the semi-discretization of :mod:`fusioncut.analysis.stability`: the exact interval
integrals of the piecewise-constant system and the spectral radius of the monodromy matrix.

Spectral radius (:func:`spectral_radius`): exact reductions, then a Krylov method where that is cheaper.

* A delayed state that no interval reads (the teeth are out of the cut there, so its input matrices are
  exactly zero) is an exactly zero column of the monodromy matrix ``Z``. With those columns (and their
  rows) last, ``Z = [[A, 0], [C, 0]]`` is block triangular: its eigenvalues are those of the principal
  submatrix ``A`` and zeros. At low radial immersion most delayed states are unread (a/D 0.1 on two
  flutes: 4 of 5), and ``A`` is that much smaller.
* Where ``A`` has more than ``2 krylov`` rows, the largest multipliers by Arnoldi's method (``krylov``
  steps from a fixed start vector, the Gram-Schmidt orthogonalisation done twice), each product with the
  monodromy matrix computed by running the period's steps on the vector, so that the matrix is never
  formed: a Ritz value ``theta`` with residual ``r = |h_{k+1,k}| |s_k|`` is an eigenvalue of ``Z + E``
  with ``||E||_2 = r``. It is accepted as the spectral radius when the Ritz value of largest modulus has
  ``r <= rel_tol |theta|``; otherwise (and for smaller ``A``, where LAPACK is as cheap) the eigenvalues of
  ``A`` come from ``numpy.linalg.eigvals``. The monodromy matrix of a delay equation has few multipliers
  away from the origin (its spectrum accumulates at 0), and those are what a Krylov space of a generic
  vector resolves first.
  ``tests/analysis/test_stability_fast.py`` compares the radius with LAPACK's on both benchmark systems.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

_START = np.random.default_rng(20260527).standard_normal(4096)  # fixed: a generic start vector, reproducible


def interval_integrals(a: np.ndarray, dt: np.ndarray, scale: np.ndarray | None = None,
                       degree: int = 12) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For a stack of system matrices ``a`` (..., d, d) and steps ``dt`` (s, broadcast against the
    leading axes): ``E = exp(A dt)``, ``F1 = int_0^dt e^{A(dt-s)} ds`` and ``F2 = int_0^dt e^{A(dt-s)} s ds``.

    With ``scale`` (d,) the series runs on ``S A S^-1`` (``S = diag(scale)``) and the results are turned
    back (``f(S A S^-1) = S f(A) S^-1``): with displacements and velocities in one state, ``scale = (1,
    .., 1/w, ..)`` for a frequency ``w`` of the modes makes the matrix's norm about ``w dt`` instead of
    ``w^2 dt`` and saves most doublings. Taylor series on ``X = A h``, ``h = dt / 2^q`` with the 1-norm of
    ``X`` at most 1/2 over the stack (truncation below 1e-14 relative at ``degree`` 12): ``E = P0``, ``F1 =
    h P1``, ``F2 = h^2 P2`` with ``Pj = sum X^k / (k + j)!``, evaluated as ``P2`` by Horner, ``P1 = I + X
    P2``, ``P0 = I + X P1``; then ``q`` doublings of the interval: ``E <- E E``, ``F1 <- F1 + E F1``, ``F2
    <- E F2 + h F1 + F2`` (split at ``h``), ``h <- 2 h``.
    """
    if scale is not None:
        ratio = scale[:, None] / scale[None, :]
        e, f1, f2 = interval_integrals(a * ratio, dt, None, degree)
        return e / ratio, f1 / ratio, f2 / ratio
    d = a.shape[-1]
    h = np.broadcast_to(np.asarray(dt, dtype=float), a.shape[:-2])[..., None, None]
    norm = float((np.abs(a).sum(axis=-2).max(axis=-1) * h[..., 0, 0]).max()) if a.size else 0.0
    q = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
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


def monodromy(phi0: np.ndarray, c_old: np.ndarray, c_new: np.ndarray, red: np.ndarray) -> np.ndarray:
    """The monodromy matrices (pairs, D, D), ``D = d2 + m r``, of the SD steps: per pair and interval ``i``
    of the ``m``, ``y_{i+1} = phi0_i y_i + c_old_i R q_{i-m} + c_new_i R q_{i-m+1}`` on the state ``y``
    (``d2`` = 2 n: modal displacements, then velocities), ``R`` (r, n) summing the modal displacements of
    each direction. The state of the map is ``y`` and the delayed displacements ``R q_{-1} .. R q_{-m}``."""
    nb, m, d2 = phi0.shape[:3]
    r, n = red.shape
    # rows of the monodromy matrix, propagated step by step: y (the state) and the delayed displacements
    # R q_{i-1} .. R q_{i-m} (a list: shifting it moves references, not rows)
    dim = d2 + m * r
    eye = np.broadcast_to(np.eye(dim), (nb, dim, dim))
    y = eye[:, :d2].copy()
    delayed = [eye[:, d2 + j * r: d2 + (j + 1) * r] for j in range(m)]
    for i in range(m):
        now = red @ y[:, :n]
        newer = delayed[-2] if m > 1 else now  # R q_{i-m+1}
        top = phi0[:, i] @ y + c_old[:, i] @ delayed[-1] + c_new[:, i] @ newer
        delayed = [now] + delayed[:-1]
        y = top
    return np.concatenate([y, *delayed], axis=1)


def read_slots(c_old: np.ndarray, c_new: np.ndarray) -> np.ndarray:
    """Which delayed displacements ``R q_{-1-j}`` (j = 0 .. m-1) some interval of some pair reads: slot ``j``
    enters step ``m-1-j`` through ``c_old`` and step ``m-2-j`` through ``c_new``. An unread slot is an
    exactly zero column of the monodromy matrix."""
    m = c_old.shape[1]
    old = np.any(c_old != 0, axis=(0, 2, 3))[::-1]  # slot j <- step m-1-j
    new = np.zeros(m, dtype=bool)
    new[:m - 1] = np.any(c_new != 0, axis=(0, 2, 3))[:m - 1][::-1]  # slot j <- step m-2-j
    return old | new


def read_states(z: np.ndarray) -> np.ndarray:
    """Indices of the columns of ``z`` (..., D, D) that are nonzero in some matrix of the stack: the
    states whose values the next period reads (the eigenvalues of ``z`` are those of the principal
    submatrices on them, and zeros)."""
    return np.flatnonzero(np.any(z != 0, axis=tuple(range(z.ndim - 1))))


def radius_of(z: np.ndarray) -> np.ndarray:
    """Spectral radius of each matrix of the stack ``z`` (P, D, D) by LAPACK, the unread states left out."""
    keep = read_states(z)
    if len(keep) < z.shape[-1]:
        z = z[:, keep][:, :, keep]
    return np.abs(np.linalg.eigvals(z)).max(axis=1) if z.shape[-1] else np.zeros(z.shape[0])


def spectral_radius(phi0: np.ndarray, c_old: np.ndarray, c_new: np.ndarray, red: np.ndarray, krylov: int = 16,
                    rel_tol: float = 1e-10) -> np.ndarray:
    """Spectral radius of the monodromy matrix of the SD steps of each pair (:func:`monodromy`; module
    docstring): LAPACK on the read states where they are at most ``2 krylov`` with ``y``, else Arnoldi
    on the matrix-free map (:func:`_arnoldi`), LAPACK where its top Ritz value is not verified."""
    d2, r = phi0.shape[2], red.shape[0]
    if d2 + r * int(read_slots(c_old, c_new).sum()) <= 2 * krylov:
        return radius_of(monodromy(phi0, c_old, c_new, red))
    dim = d2 + phi0.shape[1] * r
    start = np.resize(_START, dim)
    h = _arnoldi(np.ascontiguousarray(phi0), np.ascontiguousarray(c_old), np.ascontiguousarray(c_new),
                 np.ascontiguousarray(red, dtype=float), krylov, start / np.linalg.norm(start))
    theta, vec = np.linalg.eig(h[:, :krylov, :krylov])
    rows = np.arange(len(h))
    top = np.argmax(np.abs(theta), axis=1)
    radius = np.abs(theta[rows, top])
    residual = np.abs(h[:, krylov, krylov - 1]) * np.abs(vec[rows, krylov - 1, top])
    bad = np.flatnonzero(~(residual <= rel_tol * radius))
    if len(bad):
        radius[bad] = radius_of(monodromy(phi0[bad], c_old[bad], c_new[bad], red))
    return radius


@njit(cache=True)
def _arnoldi(phi0, c_old, c_new, red, k, start):  # pragma: no cover - compiled
    """Arnoldi's Hessenberg matrices (pairs, k + 1, k) of the monodromy maps of :func:`monodromy`, each
    product with the monodromy matrix computed by running the ``m`` steps on the vector (the delayed
    displacements in a ring buffer), the new vector orthogonalised twice by classical Gram-Schmidt."""
    npairs, m, d2 = phi0.shape[0], phi0.shape[1], phi0.shape[2]
    r, n = red.shape
    dim = d2 + m * r
    h = np.zeros((npairs, k + 1, k))
    v = np.zeros((k + 1, dim))
    w = np.zeros(dim)
    y = np.zeros(d2)
    ynew = np.zeros(d2)
    buf = np.zeros((m, r))
    now = np.zeros(r)
    for q in range(npairs):
        v[:] = 0.0
        v[0] = start
        for j in range(k):
            y[:] = v[j, :d2]
            for s in range(m):
                buf[s] = v[j, d2 + s * r: d2 + (s + 1) * r]
            head = 0  # delayed[i] = buf[(head + i) % m], delayed[0] the most recent
            for i in range(m):
                for a in range(r):
                    acc = 0.0
                    for b in range(n):
                        acc += red[a, b] * y[b]
                    now[a] = acc
                last = buf[(head + m - 1) % m]
                newer = buf[(head + m - 2) % m] if m > 1 else now
                for a in range(d2):
                    acc = 0.0
                    for b in range(d2):
                        acc += phi0[q, i, a, b] * y[b]
                    for b in range(r):
                        acc += c_old[q, i, a, b] * last[b] + c_new[q, i, a, b] * newer[b]
                    ynew[a] = acc
                head = (head + m - 1) % m
                buf[head] = now
                y[:] = ynew
            w[:d2] = y
            for s in range(m):
                w[d2 + s * r: d2 + (s + 1) * r] = buf[(head + s) % m]
            for _ in range(2):
                for i in range(j + 1):
                    c = 0.0
                    for b in range(dim):
                        c += v[i, b] * w[b]
                    h[q, i, j] += c
                    for b in range(dim):
                        w[b] -= c * v[i, b]
            beta = np.sqrt(np.sum(w * w))
            h[q, j + 1, j] = beta
            if beta > 0:
                v[j + 1] = w / beta
            else:
                v[j + 1] = 0.0
    return h
