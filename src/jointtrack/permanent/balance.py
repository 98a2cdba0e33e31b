"""Sinkhorn scaling: to a doubly stochastic matrix (Schaub eq. 38) and to powers of two.

Per(D1 A D2) = Π d1 · Π d2 · Per(A) (Schaub eq. 39), so diagonal scaling moves
the permanent by a known factor. Two uses:

* :func:`sinkhorn` is the public factorisation ``B = diag(d1) A diag(d2)`` with B
  doubly stochastic, itself a cheap approximation of the assignment marginals.
* :func:`balance_pow2` rounds the scaling exponents to integers, so that applying
  it is *exact* in floating point; every exact method runs on the balanced matrix,
  which bounds intermediate values (no overflow/underflow) and, for Glynn/Ryser,
  keeps the terms of the alternating sum within a few decades of the result.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.permanent._validate import check_problem


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


def balance_pow2(A, row_counts=None, col_counts=None, iters: int = 12):
    """Power-of-two exponents (er, ec) with ``ldexp(A, er[:,None] + ec[None,:])`` near-balanced.

    For a rectangular (n < m) matrix only the rows are scaled (ec = 0).

    The exponents come from a few Sinkhorn sweeps in log space, rounded to
    integers, so applying them changes no mantissa bit. Zero rows/columns get
    exponent 0. Returned as int64 arrays.
    """
    n, m = A.shape
    rows = np.ones(n) if row_counts is None else np.asarray(row_counts, float)
    cols = np.ones(m) if col_counts is None else np.asarray(col_counts, float)
    if n == 0 or m == 0:
        return np.zeros(n, np.int64), np.zeros(m, np.int64)
    logA = _log(A)
    live_rows = np.isfinite(logA).any(axis=1)
    if not live_rows.all():
        return np.zeros(n, np.int64), np.zeros(m, np.int64)
    if rows.sum() < cols.sum():
        # Per(D1 A D2) = Π d1 Π d2 Per(A) holds only for square matrices: an n×m
        # assignment uses n of the m columns, so only rows may be scaled freely.
        u = -_lse_rows(logA, np.log(cols))
        er = np.rint(u / np.log(2.0)).astype(np.int64)
        return er, np.zeros(m, np.int64)
    target = float(np.log(rows.sum() / cols.sum()))
    for sweeps in (iters, 10 * iters):
        u, v, _ = _log_scaling(logA, np.log(rows), np.log(cols), target, sweeps, 0.0)
        er = np.rint(u / np.log(2.0)).astype(np.int64)
        ec = np.rint(v / np.log(2.0)).astype(np.int64)
        if _well_balanced(logA, er, ec, rows, cols):
            return er, ec
    return _dual_exponents(logA, rows, cols)


def _well_balanced(logA, er, ec, rows, cols) -> bool:
    """Row and column sums of the scaled (expanded) matrix all within a factor 4 of 1.

    Then every DP state is at most 4^k while Per ≥ e^{-n}·16^{-n} (van der
    Waerden's bound for doubly stochastic matrices, loosened by the factor 4),
    so states that underflow cannot matter.
    """
    ln2 = np.log(2.0)
    r = _lse_rows(logA, ln2 * ec + np.log(cols)) + ln2 * er
    c = _lse_rows(np.ascontiguousarray(logA.T), ln2 * er + np.log(rows)) + ln2 * ec
    return bool(np.all(np.abs(r) <= 2 * ln2) and np.all(np.abs(c) <= 2 * ln2))


def _dual_exponents(logA, rows, cols):
    """Scaling from the optimal-transport duals of max Σ x_ij log a_ij (HiGHS).

    Complementary slackness gives log a_ij ≤ u_i + v_j with equality on the
    support of an optimal (integral) assignment, so after scaling every entry
    is ≤ 2 and some assignment has all entries ≥ 1/2 (after rounding to powers
    of two): Per(B) ≥ 2^{-n} while DP states stay below 2^k·k!. This is the
    fallback for matrices Sinkhorn balances only slowly (nearly decomposable
    supports, e.g. rank-one scalings spanning hundreds of decades).
    """
    from scipy.optimize import linprog
    from scipy.sparse import coo_array, vstack

    n, m = logA.shape
    qi, jj = np.nonzero(np.isfinite(logA))
    k = len(qi)
    A_eq = vstack(
        [
            coo_array((np.ones(k), (qi, np.arange(k))), shape=(n, k)),
            coo_array((np.ones(k), (jj, np.arange(k))), shape=(m, k)),
        ]
    ).tocsr()
    b_eq = np.concatenate([rows, cols]).astype(float)
    res = linprog(-logA[qi, jj], A_eq=A_eq, b_eq=b_eq, bounds=(0, None), method="highs")
    if res.status != 0:  # cannot happen for a feasible square problem; keep Sinkhorn's
        return np.zeros(n, np.int64), np.zeros(m, np.int64)
    y = res.eqlin.marginals
    er = np.rint(y[:n] / np.log(2.0)).astype(np.int64)
    ec = np.rint(y[n:] / np.log(2.0)).astype(np.int64)
    return er, ec


def apply_pow2(A, er, ec) -> np.ndarray:
    """``A * 2**(er_i + ec_j)``, exact (no rounding) unless it leaves the float range."""
    return np.ldexp(A, (er[:, None] + ec[None, :]).astype(np.int32))


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
    A, rows, cols = check_problem(A, row_counts, col_counts)
    n, m = A.shape
    if n == 0:
        return np.ones(0), A.copy(), np.ones(m)
    from jointtrack.permanent.structure import has_feasible_assignment

    if not has_feasible_assignment(A > 0, rows, cols):
        raise InfeasibleAssignmentError(
            "A has no assignment with positive weight (its permanent is 0): "
            "no Sinkhorn scaling exists"
        )
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a positive finite number, got {tol}")
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
