"""Sinkhorn scaling: to a doubly stochastic matrix (Schaub eq. 38) and to powers of two.

Per(D1 A D2) = Π d1 · Π d2 · Per(A) (Schaub eq. 39), so diagonal scaling moves
the permanent by a known factor. Two uses:

* :func:`sinkhorn` is the public factorisation ``B = diag(d1) A diag(d2)`` with B
  doubly stochastic, itself a cheap approximation of the assignment marginals.
* :func:`balance_exponents` rounds a few sweeps' exponents to integers, so that
  applying them is *exact* in floating point; Glynn/Ryser run on the dual-scaled
  (:mod:`jointtrack.assignment.scaling`) and then balanced matrix, which keeps
  the terms of their alternating sums within a few decades of the result.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from jointtrack.assignment._checks import as_counts, as_float, as_int, as_weights
from jointtrack.assignment.feasibility import is_feasible
from jointtrack.errors import InfeasibleAssignmentError


@nb.njit(cache=True)
def _lse_rows(logA, add_cols):
    """log Σ_j exp(logA[i, j] + add_cols[j]) for every row i (stable; -inf rows stay -inf)."""
    n, m = logA.shape
    out = np.empty(n)
    for i in range(n):
        mx = -np.inf
        for j in range(m):
            v = logA[i, j] + add_cols[j]
            if v > mx:
                mx = v
        if mx == -np.inf:
            out[i] = -np.inf
            continue
        s = 0.0
        for j in range(m):
            s += np.exp(logA[i, j] + add_cols[j] - mx)
        out[i] = mx + np.log(s)
    return out


@nb.njit(cache=True)
def _log_scaling(logA, log_rows, log_cols, col_target, iters, tol):
    """Alternate row/column normalisation in log space (weighted by group counts).

    Rows of the expanded matrix are normalised to sum 1 and columns to
    exp(col_target) (= n/m). Returns (u, v, err) with err the final max
    relative row-sum error when ``tol > 0`` (else inf).
    """
    n, m = logA.shape
    logAT = np.ascontiguousarray(logA.T)
    u = np.zeros(n)
    v = np.zeros(m)
    err = np.inf
    for _ in range(iters):
        u = -_lse_rows(logA, v + log_cols)
        s = _lse_rows(logAT, u + log_rows)
        for j in range(m):
            v[j] = col_target - s[j] if np.isfinite(s[j]) else 0.0
        if tol > 0.0:
            r = _lse_rows(logA, v + log_cols)
            err = 0.0
            for i in range(n):
                e = abs(np.expm1(r[i] + u[i]))
                if e > err:
                    err = e
            if err <= tol:
                break
    return u, v, err


def _log(A: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return np.log(A)


def balance_exponents(B, iters: int = 12):
    """Integer exponents (er, ec) from a few Sinkhorn sweeps on a square matrix.

    Used after the dual scaling of :mod:`jointtrack.assignment.scaling` to bring
    a dense square matrix close to doubly stochastic before Glynn's or Ryser's
    formula, whose rounding error grows with ‖terms‖/|Per|. Rounded to integers,
    so applying them changes no mantissa bit; zero rows/columns get 0.
    """
    n, m = B.shape
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(m, np.int64)
    logA = _log(B)
    ones = np.zeros(n)
    u, v, _ = _log_scaling(logA, ones, np.zeros(m), 0.0, iters, 0.0)
    er = np.rint(u / np.log(2.0)).astype(np.int64)
    ec = np.rint(v / np.log(2.0)).astype(np.int64)
    er[~np.isfinite(u)] = 0
    ec[~np.isfinite(v)] = 0
    return er, ec


def sinkhorn(A, *, tol: float = 1e-12, max_iter: int = 10_000, row_counts=None, col_counts=None):
    """Sinkhorn factorisation ``B = diag(d1) · A · diag(d2)`` (Schaub eq. 38).

    For square A, B is doubly stochastic (unit row and column sums) and, by
    eq. (39), ``Per(A) = Per(B) / (Π d1 · Π d2)``. For an n×m matrix with
    n < m, rows sum to 1 and columns to n/m; eq. (39) does not hold then (an
    assignment uses only n of the m column factors), only the row factors
    scale the permanent exactly. With ``row_counts``/``col_counts`` the
    scaling is that of the expanded matrix (groups of identical rows/columns get
    identical factors) expressed on the compressed one.

    Iterates in log space (Sinkhorn 1964; Marshall & Olkin 1968) until the
    largest relative row-sum error is below `tol`.

    Returns
    -------
    d1 : (n,) ndarray
    B : (n, m) ndarray
    d2 : (m,) ndarray

    Raises
    ------
    InfeasibleAssignmentError
        if A has no positive assignment (no scaling can exist).
    ValueError
        bad input, or if the iteration does not reach `tol`: then A's support
        lacks total support and no exact doubly stochastic scaling exists
        (some entries of the limit are 0 that are positive in A).
    """
    A = as_weights(A, "A")
    n, m = A.shape
    rows = as_counts(row_counts, n, "row_counts")
    cols = as_counts(col_counts, m, "col_counts")
    if rows.sum() > cols.sum():
        raise ValueError(
            f"A expands to more rows than columns ({rows.sum()} > {cols.sum()}); transpose it"
        )
    tol = as_float(tol, "tol", minimum=0.0, open_min=True)
    max_iter = as_int(max_iter, "max_iter", 1)
    if n == 0:
        return np.ones(0), A.copy(), np.ones(m)
    if not is_feasible(A, None, rows, cols):
        raise InfeasibleAssignmentError(
            "A has no assignment with positive weight (its permanent is 0): "
            "no Sinkhorn scaling exists"
        )
    logA = _log(A)
    target = float(np.log(rows.sum() / cols.sum()))
    u, v, err = _log_scaling(logA, np.log(rows), np.log(cols), target, max_iter, float(tol))
    if not err <= tol:
        raise ValueError(
            f"Sinkhorn scaling did not converge to tol={tol} in {max_iter} iterations "
            f"(row-sum error {err:.3g}): A's support probably lacks total support, "
            "so no exact doubly stochastic scaling exists"
        )
    d1, d2 = np.exp(u), np.exp(v)
    B = np.exp(logA + u[:, None] + v[None, :])
    return d1, B, d2
