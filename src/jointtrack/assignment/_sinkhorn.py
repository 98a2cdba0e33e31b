"""Sinkhorn scaling: to a doubly stochastic matrix (Schaub eq. 38) and to powers of two.

Per(D1 A D2) = Π d1 · Π d2 · Per(A) (Schaub eq. 39), so diagonal scaling moves
the permanent by a known factor. Two uses:

* :func:`sinkhorn` is the public factorisation ``B = diag(d1) A diag(d2)`` with B
  doubly stochastic, itself a cheap approximation of the assignment marginals.
  It starts from the power-of-two dual scaling (any matrix in range), runs a
  few log-space Sinkhorn sweeps and then Sinkhorn–Newton (Newton's method with
  backtracking on the convex dual; Brauer, Clason, Lorenz & Wirth, "A
  Sinkhorn–Newton method for entropic optimal transport", 2017), which needs a
  handful of steps where plain Sinkhorn needs ~70 000 sweeps
  (``[[1e8, 1], [1, 1]]``). Existence (total support) is decided up front by a
  flow on the support.
* :func:`balance_exponents` rounds a few sweeps' exponents to integers, so that
  applying them is *exact* in floating point; Glynn/Ryser run on the dual-scaled
  (:mod:`jointtrack.assignment.scaling`) and then balanced matrix, which keeps
  the terms of their alternating sums within a few decades of the result.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from jointtrack.assignment._checks import as_counts, as_float, as_int, as_weights
from jointtrack.assignment.feasibility import is_feasible
from jointtrack.assignment.scaling import group_log_exponents
from jointtrack.errors import InfeasibleAssignmentError

_LN2 = math.log(2.0)


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


def weights_arg(A, name: str = "A") -> np.ndarray:
    """:func:`as_weights`, with an over-large Python integer reported as a ValueError."""
    try:
        return as_weights(A, name)
    except OverflowError:
        raise ValueError(f"{name} holds an integer too large for a float64") from None


# ----------------------------------------------------------------------------------------
# existence of the scaling: a flow with support exactly supp(A)
# ----------------------------------------------------------------------------------------


def _support_defect(S: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> str | None:
    """Why no scaling with row sums 1 and column sums N/M exists, or None if one does.

    A scaling exists iff some non-negative matrix with support exactly supp(A) has
    the target sums (Menon 1968; Sinkhorn & Knopp 1967 for the square case, where
    this is "total support"). In the integer form (group row i supplies
    ``rows_i·M/g``, group column j takes ``cols_j·N/g``) that is a feasible flow
    on the support in which every support edge can carry flow: an edge (i, j)
    idle in one maximum flow can carry flow in another iff j reaches i in the
    residual graph (an alternating cycle), i.e. i and j share a strongly
    connected component. Returns None also when the capacities do not fit the
    int32 flow solver (then only the iteration can tell).
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components, maximum_flow

    n, m = S.shape
    N, M = int(rows.sum()), int(cols.sum())
    g = math.gcd(N, M)
    total = N * (M // g)
    if total >= 2**31 - 1:
        return None
    ii, jj = np.nonzero(S)
    s, t = n + m, n + m + 1
    src = np.concatenate([np.full(n, s), ii, n + np.arange(m)])
    dst = np.concatenate([np.arange(n), n + jj, np.full(m, t)])
    cap = np.concatenate([rows * (M // g), np.full(ii.size, total), cols * (N // g)])
    graph = csr_matrix((cap.astype(np.int32), (src, dst)), shape=(n + m + 2, n + m + 2))
    res = maximum_flow(graph, s, t, method="dinic")
    if res.flow_value < total:
        return (
            "no matrix with A's support has unit row sums and column sums "
            f"{N}/{M} (some columns cannot all be reached from the rows): "
            "A's support lacks total support, so no such scaling exists"
        )
    flow = np.asarray(res.flow[ii, n + jj]).ravel()
    busy = flow > 0
    # residual graph on rows and columns: row -> col always, col -> row where flow > 0
    r_src = np.concatenate([ii, n + jj[busy]])
    r_dst = np.concatenate([n + jj, ii[busy]])
    resid = csr_matrix((np.ones(r_src.size, np.int8), (r_src, r_dst)), shape=(n + m, n + m))
    _, label = connected_components(resid, directed=True, connection="strong")
    idle = ~busy & (label[ii] != label[n + jj])
    if idle.any():
        k = int(np.flatnonzero(idle)[0])
        return (
            f"A's support lacks total support: the positive entry A[{ii[k]}, {jj[k]}] lies "
            "in no assignment compatible with the target sums, so it would have to vanish "
            "and no exact doubly stochastic scaling exists (the iteration cannot converge)"
        )
    return None


# ----------------------------------------------------------------------------------------
# Sinkhorn–Newton
# ----------------------------------------------------------------------------------------


# A Newton trial step may overshoot until e^{L+u+v} or its sums leave the float range;
# the resulting inf is what the line search rejects, so it must not warn.
def _sums(L, u, v, a, b):
    with np.errstate(over="ignore", invalid="ignore"):
        P = np.exp(L + u[:, None] + v[None, :])
        return P, P @ b, a @ P


def _error(r, c, tau):
    with np.errstate(over="ignore", invalid="ignore"):
        e = max(float(np.max(np.abs(r - 1.0))), float(np.max(np.abs(c / tau - 1.0))))
    return e if np.isfinite(e) else np.inf


def _newton(L, a, b, tau, u, v, tol, max_steps):
    """Newton's method with backtracking on the convex dual of the weighted scaling.

    f(u, v) = Σ_ij a_i b_j e^{L_ij + u_i + v_j} − Σ_i a_i u_i − τ Σ_j b_j v_j has
    gradient (a∘(r − 1), b∘(c − τ)) in terms of the expanded row sums r and column
    sums c; its minimiser is the scaling (Brauer, Clason, Lorenz & Wirth 2017,
    with the group counts a, b as weights). The Hessian is singular along the
    gauge (u + t, v − t); the system is Jacobi-preconditioned and solved with a
    tiny ridge, which picks the step orthogonal to the gauge. Armijo
    backtracking on f. Returns (u, v, err, steps).
    """
    n, m = L.shape

    def objective(P, uu, vv):
        with np.errstate(over="ignore", invalid="ignore"):
            val = float(a @ P @ b - a @ uu - tau * (b @ vv))
        return val if np.isfinite(val) else np.inf

    P, r, c = _sums(L, u, v, a, b)
    err = _error(r, c, tau)
    fx = objective(P, u, v)
    steps = 0
    while err > tol and steps < max_steps:
        steps += 1
        g = np.concatenate([a * (r - 1.0), b * (c - tau)])
        H = np.empty((n + m, n + m))
        H[:n, :n] = np.diag(a * r)
        H[n:, n:] = np.diag(b * c)
        H[:n, n:] = a[:, None] * P * b[None, :]
        H[n:, :n] = H[:n, n:].T
        diag = np.diag(H).copy()
        diag[~(diag > 0)] = 1.0
        s = 1.0 / np.sqrt(diag)
        Hs = H * s[:, None] * s[None, :]
        Hs[np.diag_indices_from(Hs)] += 1e-13
        try:
            Lc = np.linalg.cholesky(Hs)
            y = np.linalg.solve(Lc.T, np.linalg.solve(Lc, -g * s))
        except np.linalg.LinAlgError:
            y = np.linalg.lstsq(Hs, -g * s, rcond=1e-13)[0]
        dx = y * s
        slope = float(g @ dx)
        if not (np.all(np.isfinite(dx)) and slope < 0):
            break
        t = 1.0
        while t > 1e-12:
            un, vn = u + t * dx[:n], v + t * dx[n:]
            Pn, rn, cn = _sums(L, un, vn, a, b)
            fn = objective(Pn, un, vn)
            # Armijo; near the optimum f's decrease drowns in its rounding, then a
            # smaller residual decides
            if fn <= fx + 1e-4 * t * slope or _error(rn, cn, tau) < 0.5 * err:
                break
            t *= 0.5
        else:
            break  # no decrease: rounding floor
        u, v, P, r, c, fx = un, vn, Pn, rn, cn, fn
        err = _error(r, c, tau)
    return u, v, err, steps


def scale_log(L, a, b, tol: float, max_iter: int):
    """Log scalings (u, v, err) of ``exp(L)`` (−inf = 0) to row sums 1, column sums N/M.

    Weighted by the group counts ``a`` (rows) and ``b`` (columns): up to 20
    log-space Sinkhorn sweeps, then Sinkhorn–Newton, then plain sweeps should
    Newton stall at its rounding floor. ``err`` is the final largest relative
    row/column-sum error; at most ``max_iter`` sweeps plus Newton steps.
    """
    N, M = float(a.sum()), float(b.sum())
    tau = N / M
    warm = min(20, max_iter)
    u, v, _ = _log_scaling(L, np.log(a), np.log(b), float(np.log(tau)), warm, float(tol))
    u = np.where(np.isfinite(u), u, 0.0)
    v = np.where(np.isfinite(v), v, 0.0)
    u, v, err, steps = _newton(L, a, b, tau, u, v, tol, max_iter - warm)
    used = warm + steps
    if err > tol and used < max_iter:
        u2, v2, _ = _log_scaling(
            L + u[:, None] + v[None, :],
            np.log(a),
            np.log(b),
            float(np.log(tau)),
            max_iter - used,
            float(tol),
        )
        u, v = u + u2, v + v2
        _, r, c = _sums(L, u, v, a, b)
        err = _error(r, c, tau)
    return u, v, err


def _center_gauge(S, lr, lc):
    """Shift (lr + t, lc − t) per connected component of the support to keep e^lr, e^lc finite."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    n, m = S.shape
    ii, jj = np.nonzero(S)
    graph = csr_matrix((np.ones(ii.size, np.int8), (ii, n + jj)), shape=(n + m, n + m))
    k, label = connected_components(graph, directed=False)
    lr, lc = lr.copy(), lc.copy()
    for comp in range(k):
        R = label[:n] == comp
        C = label[n:] == comp
        if not R.any() or not C.any():
            continue
        # minimise max(|lr + t|, |lc − t|) over the block
        p = max(lr[R].max(), -lc[C].min())
        q = max(-lr[R].min(), lc[C].max())
        t = 0.5 * (q - p)
        lr[R] += t
        lc[C] -= t
    return lr, lc


def sinkhorn(A, *, tol: float = 1e-12, max_iter: int = 10_000, row_counts=None, col_counts=None):
    """Sinkhorn factorisation ``B = diag(d1) · A · diag(d2)`` (Schaub eq. 38).

    For square A, B is doubly stochastic (unit row and column sums) and, by
    eq. (39), ``Per(A) = Per(B) / (Π d1 · Π d2)``. For an n×m matrix with
    n < m, rows sum to 1 and columns to n/m; eq. (39) does not hold then (an
    assignment uses only n of the m column factors), only the row factors
    scale the permanent exactly. With ``row_counts``/``col_counts`` the
    scaling is that of the expanded matrix (groups of identical rows/columns get
    identical factors) expressed on the compressed one.

    Algorithm: the power-of-two dual scaling of
    :mod:`jointtrack.assignment.scaling` first brings any matrix in range (every
    entry ≤ ~1, the best assignment ≈ 1); then up to 20 log-space Sinkhorn
    sweeps (Sinkhorn 1964), then Newton's method with Armijo backtracking on the
    convex dual (Sinkhorn–Newton: Brauer, Clason, Lorenz & Wirth 2017), weighted
    by the group counts. Plain Sinkhorn converges linearly at a rate set by the
    second singular value of the limit — ~70 000 sweeps for ``[[1e8, 1], [1, 1]]``
    — where Newton needs a handful of steps. The existence of the scaling is
    decided combinatorially first (a flow on the support), so a support without
    total support is reported at once. The gauge ``(d1·t, d2/t)`` is fixed per
    connected block of the support to keep both factors well inside the float64
    range.

    Parameters
    ----------
    A : (n, m) array_like, non-negative finite real entries
    tol : float > 0
        stop when the largest relative row- or column-sum error is ≤ tol.
    max_iter : int ≥ 1
        maximum number of Sinkhorn sweeps plus Newton steps.
    row_counts, col_counts : array_like of positive int, optional
        group sizes of repeated rows/columns.

    Returns
    -------
    d1 : (n,) ndarray, finite and positive
    B : (n, m) ndarray
    d2 : (m,) ndarray, finite and positive

    Raises
    ------
    InfeasibleAssignmentError
        if A has no positive assignment (no scaling can exist).
    ValueError
        bad input; A's support lacks total support (no exact scaling exists:
        some entries of the limit are 0 that are positive in A); the iteration
        did not reach `tol` within `max_iter`; or the factors would not be
        representable in float64.
    """
    A = weights_arg(A, "A")
    lr, B, lc = sinkhorn_log(
        _log(A), tol=tol, max_iter=max_iter, row_counts=row_counts, col_counts=col_counts
    )
    with np.errstate(over="ignore", under="ignore"):
        d1, d2 = np.exp(lr), np.exp(lc)
    # a subnormal factor has lost bits (A = [[1e285, 0, 1e7], [5e-324, 2.3e21, 0]]
    # needs factors 1e608 apart): as unusable as one that underflowed to 0
    normal = np.finfo(float).tiny
    if not (np.all(np.isfinite(d1) & (d1 >= normal)) and np.all(np.isfinite(d2) & (d2 >= normal))):
        raise ValueError(
            "the Sinkhorn factors of A are not representable in float64 (A's entries span "
            "too wide a range); the scaling exists but d1, d2 would over- or underflow "
            "(use sinkhorn_log for the factors' logarithms)"
        )
    return d1, B, d2


def sinkhorn_log(log_A, *, tol=1e-12, max_iter=10_000, row_counts=None, col_counts=None):
    """:func:`sinkhorn` of ``A = exp(log_A)`` (−inf = 0): ``(log d1, B, log d2)``.

    For coefficients outside the float64 range (Schaub's identity coefficients
    after hundreds of updates): the support, the existence test and the scaling
    are all taken on ``log_A`` itself, so an entry far below the others is still a
    positive entry (exponentiating first flushed it to 0 and a strictly positive
    matrix then "lacked total support"). ``log_A`` must be validated (float64,
    no NaN or +inf). Raises as :func:`sinkhorn`, except that the factors need not
    be representable.
    """
    n, m = log_A.shape
    rows = as_counts(row_counts, n, "row_counts")
    cols = as_counts(col_counts, m, "col_counts")
    if rows.sum() > cols.sum():
        raise ValueError(
            f"A expands to more rows than columns ({rows.sum()} > {cols.sum()}); transpose it"
        )
    tol = as_float(tol, "tol", minimum=0.0, open_min=True)
    max_iter = as_int(max_iter, "max_iter", 1)
    if n == 0:
        return np.zeros(0), np.exp(log_A), np.zeros(m)
    S = log_A > -np.inf
    if not is_feasible(S.astype(np.float64), None, rows, cols):
        raise InfeasibleAssignmentError(
            "A has no assignment with positive weight (its permanent is 0): "
            "no Sinkhorn scaling exists"
        )
    defect = _support_defect(S, rows, cols)
    if defect is not None:
        raise ValueError(defect)
    # 1. dual scaling by powers of two: every entry ≤ ~1, best assignment ≈ 1
    try:
        er, ec, ok = group_log_exponents(log_A, np.full(n, -np.inf), rows, cols)
    except ValueError:  # expansion too large for one assignment solve
        er, ec, ok = np.zeros(n, np.int64), np.zeros(m, np.int64), False
    if not ok:
        er, ec = np.zeros(n, np.int64), np.zeros(m, np.int64)
    L = log_A + (er[:, None] + ec[None, :]) * _LN2  # log space: no underflow
    a, b = rows.astype(np.float64), cols.astype(np.float64)
    N, M = float(a.sum()), float(b.sum())
    tau = N / M
    # 2. a few Sinkhorn sweeps, 3. Sinkhorn–Newton
    u, v, err = scale_log(L, a, b, tol, max_iter)
    if not err <= tol:
        raise ValueError(
            f"Sinkhorn scaling did not converge to tol={tol} in {max_iter} iterations "
            f"(largest relative row/column-sum error {err:.3g})"
        )
    lr, lc = er * _LN2 + u, ec * _LN2 + v
    # Entries far below tol do not affect the sums, so blocks joined only by them
    # have a free relative gauge; centre each such block, keep it if the sums hold.
    with np.errstate(divide="ignore"):
        strong = L + u[:, None] + v[None, :] > math.log(tol) - 30.0
    lr, lc = _center_gauge(S, lr, lc)
    u, v = lr - er * _LN2, lc - ec * _LN2
    lr2, lc2 = _center_gauge(strong, lr, lc)
    dr, dc = lr2 - lr, lc2 - lc
    frac = 1.0
    for _ in range(12):  # largest fraction of the block shifts that keeps the sums
        _, r, c = _sums(L, u + frac * dr, v + frac * dc, a, b)
        if _error(r, c, tau) <= tol:
            lr, lc, u, v = lr + frac * dr, lc + frac * dc, u + frac * dr, v + frac * dc
            break
        frac *= 0.5
    with np.errstate(under="ignore"):
        B = np.exp(L + u[:, None] + v[None, :])
    return lr, B, lc
