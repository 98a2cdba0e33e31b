r"""Bethe approximation of the permanent by belief propagation.

Definition
----------
For a non-negative n×m matrix A (n ≤ m) let P(A) be the set of n×m matrices γ ≥ 0
with supp γ ⊆ supp A, every row sum equal to 1 and every column sum at most 1;
write s_j = 1 − Σ_i γ_ij for the probability that column j is left free. The
Bethe permanent is

.. math::

    \log \operatorname{per}_B(A) = \max_{\gamma \in P(A)}
        \sum_{ij} \gamma_{ij} \log\frac{a_{ij}}{\gamma_{ij}}
      + \sum_{ij} (1-\gamma_{ij}) \log(1-\gamma_{ij})
      - \sum_j s_j \log s_j ,

the negative minimum of the Bethe free energy of the factor graph with one
"exactly one" factor per row (weights a_ij), one "at most one" factor per
column and one binary variable per entry. For square A every column is
saturated (s_j = 0), P(A) is the Birkhoff polytope restricted to supp A and this
is Vontobel's Bethe permanent [V13, Def. 21]; the maximiser γ (the Bethe
beliefs) is returned as :attr:`BethePermanent.marginals` and approximates the
assignment marginals P_ij = a_ij Per(A_{−i,−j}) / Per(A).

Rectangular matrices
--------------------
A common reduction pads A with m − n rows of ones, Per(A) = Per([A; 1]) / (m−n)!.
Its Bethe analogue, per_B([A; 1]) / (m−n)!, is *not* what is computed here: the
padded rows are interchangeable, and the Bethe entropy of m − n separate copies
does not reduce to the −Σ s_j log s_j of one merged "free" state. For a single
row [a_1 … a_m] the padded analogue is max_j a_j, while the column-slack
definition above gives Σ_j a_j = Per exactly (the factor graph is a tree). On
random rectangular matrices the tests check, with hypothesis, that
per_B([A;1])/(m−n)! ≤ per_B(A) ≤ Per(A) (observed, not a proven theorem for
n < m; for square A the lower bound is Gurvits' theorem).

Algorithm
---------
0. *Scaling.* A is first multiplied by the exact powers of two 2^(er_i + ec_j) of
   the assignment dual (:func:`jointtrack.assignment.scaling.group_exponents`),
   so every entry is ≤ ~1 and the best assignment ≈ 1; everything after works
   with logarithms. Row factors pass through the Bethe objective exactly; a
   column factor 2^ec_j does too once column j's "free" state gets the weight
   δ_j = 2^ec_j (G gains Σ_i γ_ij ec_j ln 2 + s_j ec_j ln 2 = ec_j ln 2). Without
   this BP and the projection below start 10^±150 away from the optimum on
   wide-range input and stall (a 4×5 rank-one matrix with columns 1 … 10^200 had
   column sums 2 and a "lower bound" above the permanent).
1. *Support.* Entries that lie in no row-saturating matching are 0 in every
   γ ∈ P(A); they are found from one maximum matching and a strongly-connected
   component computation [DM58] and stay 0 in the result. The remaining
   ("allowed") bipartite graph splits into connected components, each handled
   on its own (log per_B is a sum over them). A component with as many rows as
   columns is *tight* (its columns are never free); a 1×1 component is a forced
   entry (γ = 1, contributes log a_ij).
2. *Vertex optima.* In a tight component a boundary point of P can only be
   optimal if it is a vertex: moving mass ε onto an entry at 0 gains −ε log ε,
   which only an entry leaving 1 can cancel. At the vertex of a maximum-weight
   assignment σ the ε log ε terms cancel and the one-sided derivative along
   γ = σ + ε·(flow t_i π_ik from row i to the column σ(k)) is
   Σ_i t_i Σ_k π_ik log(M_ik / π_ik) with M_ik = a_{iσ(k)} / a_{iσ(i)} (k ≠ i);
   by the variational formula for the Perron root its maximum has the sign of
   log ρ(M). Since G is concave on P [V13], σ is the optimum iff ρ(M) ≤ 1; then
   per_B = Π a_{iσ(i)} exactly and γ is that permutation. Every 2×2 block is
   such a case (per_B = max(a11 a22, a12 a21)); BP would only approach it
   asymptotically. Components with more columns than rows have interior
   optima (freeing a column gains another −ε log ε that nothing cancels).
3. *Belief propagation* on the other components (interior optima), in the log
   domain. With q_ij the message ratio from entry (i,j) to row i and p_ij the
   one to column j,

   .. math::

       p_{ij} = \frac{a_{ij}}{\sum_{l \ne j} q_{il}}, \qquad
       q_{ij} = \frac{a_{ij}}{\delta_j + \sum_{k \ne i} p_{kj}},

   δ_j = 0 for tight columns ("exactly one"), 1 otherwise ("at most one"). The
   exclusive sums are prefix/suffix log-sum-exps (no subtraction, hence no
   cancellation): O(nm) per sweep. The update of log q is damped,
   log q ← damping·log q + (1 − damping)·log q_new, and accelerated by Anderson
   mixing (memory ``anderson``; least squares weighted by γ(1−γ), i.e. in the
   scale of the beliefs; restarted whenever an extrapolated step doubles the
   residual). The fixed points are the stationary points
   γ_ij(1−γ_ij) = a_ij x_i y_j of G [V13, HJ09]. The row beliefs are
   γ_ij = q_ij / Σ_l q_il, the column beliefs p_ij / (δ_j + Σ_k p_kj); the run
   stops when they agree to ``tol`` (max abs difference, zero exactly at a
   fixed point), or, with Anderson mixing, when that residual has not halved in
   100 sweeps (``converged=False``).
4. *Value.* The row beliefs are projected onto P in log space (square blocks
   by Sinkhorn–Newton, blocks with free columns by alternating Bregman
   projections) and G is evaluated there, so ``log_value`` is the
   Bethe objective at a feasible γ: a lower bound on log per_B even when BP did
   not converge (up to the projection's accuracy). If a component ends below
   its best vertex (which an extrapolation towards a wrong face could cause)
   the BP part is rerun without acceleration and the better point is kept.
   A component whose projected beliefs are not feasible to 1e-12 (or whose
   value is below its best vertex) is replaced by that vertex, which is
   feasible and exact in value (``converged=False`` in the first case); so the
   beliefs always have row sums 1 and column sums ≤ 1 + 1e-12.

Bounds and measured accuracy
----------------------------
For square A, per_B(A) ≤ Per(A) ≤ 2^{n/2} per_B(A) ([G11] lower bound, via
Schrijver's inequality; [AR19] upper bound); both are asserted by the tests
with hypothesis against brute force. per_B is exact when the allowed support is
a forest (diagonal / permutation supports, a single row, random bipartite
forests in the tests). Row and column scaling pass through exactly:
log per_B(D1 A D2) = log per_B(A) + Σ log d1 + Σ log d2 (square A; for n < m
only row scaling does, as for the permanent itself).

Measured by ``tests/test_permanent_approx.py::test_bethe_measured_accuracy_uniform_8_to_12``
(5 matrices for each n = 8, …, 12, entries iid uniform(0, 1), exact values and
marginals by a subset DP): log Per − log per_B ranged over [1.41, 1.64]
(asserted: within [1.2, 1.8]; for the all-ones matrix the gap is 1.45–1.65 at
these n, ≈ ½ log(2πn/e)), and max_ij |γ_ij − P_ij| over [0.0015, 0.013]
(asserted: ≤ 0.02). BP needed 13–18 sweeps there, 7–8 sweeps (≈ 20 ms) for
uniform 100×100 matrices, and 10–350 sweeps (< 1 s) for 100×100 Gaussian
likelihood matrices of a tracking scene. Rare ill-conditioned fixed points (a
belief ≈ ½ inside a nearly decoupled block) stall at a residual ≈ 1e-7; they
are returned with ``converged=False`` and in the cases examined the value was
within 1e-6 of long plain-BP runs.

References
----------
[V13]  P. O. Vontobel, "The Bethe permanent of a nonnegative matrix", IEEE
       Trans. Inf. Theory 59(3):1866–1901, 2013.
[HJ09] B. Huang, T. Jebara, "Approximating the permanent with belief
       propagation", arXiv:0908.1769, 2009.
[CY13] M. Chertkov, A. B. Yedidia, "Approximating the permanent with fractional
       belief propagation", JMLR 14:2029–2066, 2013.
[G11]  L. Gurvits, "Unleashing the power of Schrijver's permanental inequality
       with the help of the Bethe approximation", arXiv:1106.2844, 2011.
[AR19] N. Anari, A. Rezaei, "A tight analysis of Bethe approximation for
       permanent", FOCS 2019.
[DM58] A. L. Dulmage, N. S. Mendelsohn, "Coverings of bipartite graphs",
       Canad. J. Math. 10:517–534, 1958.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, maximum_bipartite_matching
from scipy.special import expit, logsumexp

from jointtrack.assignment._checks import as_float, as_int
from jointtrack.assignment._sinkhorn import scale_log
from jointtrack.assignment.lsap import linear_assignment
from jointtrack.assignment.scaling import group_exponents
from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.permanent._validate import check_matrix

_LN2 = math.log(2.0)

__all__ = ["BethePermanent", "bethe_permanent"]


@dataclass(frozen=True, eq=False)
class BethePermanent:
    """Result of :func:`bethe_permanent`.

    Attributes
    ----------
    log_value : float
        log per_B(A), always finite for a feasible A. Prefer it to `value`.
    value : float
        exp(log_value). It underflows to 0.0 when log_value < −745 and
        overflows to ``inf`` when log_value > 709; `log_value` is exact then.
    marginals : ndarray, shape (n, m)
        Bethe beliefs γ: rows sum to 1, columns sum to 1 for square A and to at
        most 1 otherwise; 0 wherever A is 0 (or the entry lies in no matching).
        Read-only.
    iterations : int
        BP sweeps performed (0 when nothing was left to iterate on).
    converged : bool
        whether the BP fixed-point residual fell below `tol`. When False,
        `log_value` is still the Bethe objective at a feasible γ (the last
        iterate projected onto the constraints), i.e. a lower bound on
        log per_B up to the projection's accuracy.
    """

    log_value: float
    value: float
    marginals: np.ndarray
    iterations: int
    converged: bool


def _safe_exp(x: float) -> float:
    try:
        return math.exp(x)
    except OverflowError:
        return math.inf


def _check_feasible(support: np.ndarray) -> np.ndarray:
    """Return a row-saturating matching (row -> column) or raise."""
    n, m = support.shape
    graph = csr_matrix(support.astype(np.int8))
    match = maximum_bipartite_matching(graph, perm_type="column")
    if np.any(match < 0):
        unmatched = int(np.flatnonzero(match < 0)[0])
        raise InfeasibleAssignmentError(
            f"no assignment of all {n} rows to distinct columns uses only positive entries "
            f"(row {unmatched} cannot be matched in a maximum matching); the permanent is 0"
        )
    return match


def _allowed_support(support: np.ndarray, match: np.ndarray | None = None) -> np.ndarray:
    """Entries of `support` that lie in at least one row-saturating matching.

    Given a maximum matching M, direct unmatched edges row → column and matched
    edges column → row, and add a node z with edges (free column → z) and
    (z → every row). An unmatched edge (i, j) is in some row-saturating
    matching iff j reaches i (alternating cycle) or j reaches a free column
    (alternating path), i.e. iff i and j share a strongly connected component
    of this graph. Raises InfeasibleAssignmentError when no such matching exists.
    """
    n, m = support.shape
    if match is None:
        match = _check_feasible(support)
    rows, cols = np.nonzero(support)
    is_matched = match[rows] == cols
    free_cols = np.setdiff1d(np.arange(m), match, assume_unique=False)
    z = n + m
    # node ids: rows 0..n-1, columns n..n+m-1, z = n+m
    src = np.concatenate(
        [
            rows[~is_matched],  # row -> col (unmatched)
            n + cols[is_matched],  # col -> row (matched)
            n + free_cols,  # free col -> z
            np.full(n, z),  # z -> row
        ]
    )
    dst = np.concatenate(
        [
            n + cols[~is_matched],
            rows[is_matched],
            np.full(free_cols.size, z),
            np.arange(n),
        ]
    )
    g = csr_matrix((np.ones(src.size, dtype=np.int8), (src, dst)), shape=(z + 1, z + 1))
    _, label = connected_components(g, directed=True, connection="strong")
    ok = is_matched | (label[rows] == label[n + cols])
    allowed = np.zeros_like(support)
    allowed[rows[ok], cols[ok]] = True
    return allowed


def _excl_lse_last(X: np.ndarray) -> np.ndarray:
    """out[..., k] = log Σ_{l≠k} exp(X[..., l]) via prefix/suffix sums (−inf allowed)."""
    out = np.full_like(X, -np.inf)
    if X.shape[-1] < 2:
        return out
    pre = np.logaddexp.accumulate(X, axis=-1)
    suf = np.logaddexp.accumulate(X[..., ::-1], axis=-1)[..., ::-1]
    out[..., 1:] = pre[..., :-1]
    out[..., :-1] = np.logaddexp(out[..., :-1], suf[..., 1:])
    return out


def _xlogx(x: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(x > 0, x * np.log(np.where(x > 0, x, 1.0)), 0.0)


def _project(lg, ii, jj, shape, col_free, max_sweeps: int = 5000):
    """Alternating Bregman projections of γ onto the constraint set, in log space.

    ``lg`` holds log γ on the support entries (ii, jj). Columns flagged in
    `col_free` are scaled down only when their sum exceeds 1 (projection onto
    {Σ_i γ_ij ≤ 1}); the others are scaled to sum 1. Ends with a row
    normalisation, so rows sum to 1 to rounding. Returns (log γ, largest
    remaining log column correction).
    """
    r, c = shape
    work = np.full(shape, -np.inf)
    work[ii, jj] = lg
    work -= logsumexp(work, axis=1)[:, None]
    tight_c = ~col_free
    if tight_c.any():
        # square blocks: doubly stochastic scaling by Sinkhorn–Newton (alternating
        # projections stall on nearly decomposable blocks, e.g. one dominant entry)
        tight_r = np.isfinite(work[:, tight_c]).any(axis=1)
        block = work[np.ix_(tight_r, tight_c)]
        u, v, _ = scale_log(block, np.ones(block.shape[0]), np.ones(block.shape[1]), 1e-15, 100)
        work[np.ix_(tight_r, tight_c)] = block + u[:, None] + v[None, :]
        work -= logsumexp(work, axis=1)[:, None]
    violation = np.inf
    for _ in range(max_sweeps):
        lc = logsumexp(work, axis=0)
        fac = np.where(col_free, np.minimum(0.0, -lc), -lc)
        violation = float(np.max(np.abs(fac)))
        if violation < 1e-15:
            break
        work += fac[None, :]
        work -= logsumexp(work, axis=1)[:, None]
    return np.minimum(work[ii, jj], 0.0), violation


def _check_options(tol, max_iter, damping) -> tuple[float, int, float]:
    tol = as_float(tol, "tol", minimum=0.0, open_min=True)
    max_iter = as_int(max_iter, "max_iter", 1)
    damping = as_float(damping, "damping", minimum=0.0, maximum=1.0, open_max=True)
    return tol, max_iter, damping


def _run_bp(L_sub, ii, jj, shape, ld, tol, max_iter, damping, anderson, patience=100):
    """Damped log-domain sum-product BP with optional Anderson acceleration.

    Works on the log message ratios log q_ij of the support entries (ii, jj);
    `ld` holds log δ_j per entry (0 for "at most one" columns, −inf for "exactly
    one"). Returns (d, sweeps, converged) where d is the logit of the row beliefs.
    With Anderson acceleration the run also stops, unconverged, when the best
    residual has not halved within `patience` sweeps (stagnation at the
    floating-point floor of an ill-conditioned fixed point).
    """
    work = np.full(shape, -np.inf)

    def sweep(x):
        work[ii, jj] = x
        excl_q = _excl_lse_last(work)[ii, jj]
        d = x - excl_q  # logit of the row belief γ_ij = q_ij / Σ_l q_il
        lp = L_sub - excl_q  # log p_ij
        work[ii, jj] = lp
        excl_p = _excl_lse_last(work.T).T[ii, jj]
        log_col = np.logaddexp(ld, excl_p)
        # column belief p_ij / (δ_j + Σ_k p_kj) = expit(lp − log_col)
        residual = float(np.max(np.abs(expit(d) - expit(lp - log_col))))
        new = L_sub - log_col
        if damping > 0:
            new = damping * x + (1.0 - damping) * new
        return new, residual, d

    x = L_sub.copy()
    gx, res, d = sweep(x)
    sweeps = 1
    converged = res < tol
    best, best_mark, mark_sweep = res, res, 1
    hist_dx: list[np.ndarray] = []  # Anderson history: differences of g(x)
    hist_df: list[np.ndarray] = []  # and of the residual g(x) − x
    f = gx - x
    while not converged and sweeps < max_iter:
        x_new = gx
        if anderson > 0 and hist_df:
            # least squares in the belief scale: weight γ(1−γ) = dγ/d(logit)
            wt = expit(d) * expit(-d)
            dF = np.stack(hist_df, axis=1) * wt[:, None]
            coef = np.linalg.lstsq(dF, f * wt, rcond=1e-12)[0]
            x_new = gx - np.stack(hist_dx, axis=1) @ coef
        gx_new, res_new, d_new = sweep(x_new)
        sweeps += 1
        if hist_df and not (np.all(np.isfinite(gx_new)) and res_new <= 2.0 * best):
            # safeguard: the extrapolated point is worse; restart from a plain sweep
            hist_dx.clear()
            hist_df.clear()
            x_new = gx
            gx_new, res_new, d_new = sweep(x_new)
            sweeps += 1
        elif anderson > 0:
            hist_dx.append(gx_new - gx)
            hist_df.append((gx_new - x_new) - f)
            if len(hist_df) > anderson:
                hist_dx.pop(0)
                hist_df.pop(0)
        x, gx, res, d = x_new, gx_new, res_new, d_new
        f = gx - x
        best = min(best, res)
        converged = res < tol
        if best <= 0.5 * best_mark:
            best_mark, mark_sweep = best, sweeps
        elif anderson > 0 and sweeps - mark_sweep > patience:
            break
    return d, sweeps, converged


def _vertex_is_optimal(L: np.ndarray, sigma: np.ndarray) -> bool:
    """Is the permutation vertex σ the Bethe optimum of a tight component?

    Expanding the Bethe objective G at the vertex along γ = I_σ + ε d, the
    ε log ε terms cancel and the one-sided derivative is
    Σ_i t_i [Σ_k π_ik log(M_ik / π_ik)] with M_ik = a_{iσ(k)} / a_{iσ(i)} (k ≠ i),
    maximised over stationary flows (t_i π_ik): by the variational principle of
    the Perron root it is ≤ 0 for every feasible direction iff ρ(M) ≤ 1. As G is
    concave on the polytope [V13], that is the optimality condition. M is first
    brought to entries ≤ 1 by a diagonal similarity (shortest-path potentials of
    −log M, which has no negative cycle because σ is a maximum assignment).
    """
    k = L.shape[0]
    logM = L[:, sigma] - L[np.arange(k), sigma][:, None]
    np.fill_diagonal(logM, -np.inf)
    cost = -logM
    dist = np.zeros(k)
    for _ in range(k):
        new = np.minimum(dist, np.min(dist[:, None] + cost, axis=0))
        if np.array_equal(new, dist):
            break
        dist = new
    E = np.exp(logM - dist[:, None] + dist[None, :])
    rho = float(np.max(np.abs(np.linalg.eigvals(E))))
    return rho <= 1.0 + 1e-9


def bethe_permanent(
    A,
    *,
    tol: float = 1e-10,
    max_iter: int = 10_000,
    damping: float = 0.5,
    anderson: int = 5,
) -> BethePermanent:
    r"""Bethe approximation per_B(A) of the permanent of a non-negative n×m matrix.

    log per_B(A) = max over γ ∈ P(A) of Σ γ_ij log(a_ij/γ_ij)
    + Σ (1−γ_ij) log(1−γ_ij) − Σ_j s_j log s_j (s_j = 1 − Σ_i γ_ij; 0 for square A)
    — Vontobel's Bethe permanent for square A, its column-slack form for n < m.
    See the module docstring for the algorithm (vertex test, then
    Anderson-accelerated log-domain BP), bounds and measured accuracy: for
    square A, per_B(A) ≤ Per(A) ≤ 2^{n/2} per_B(A), and for uniform random
    8×8 … 12×12 matrices log Per − log per_B was observed in [1.41, 1.64].

    Parameters
    ----------
    A : array_like, shape (n, m), n ≤ m
        non-negative finite entries.
    tol : float
        stop when max_ij |γ^row_ij − γ^col_ij| < tol (beliefs of entry (i, j)
        seen from its row and from its column factor; 0 at a BP fixed point).
    max_iter : int
        maximum number of BP sweeps.
    damping : float in [0, 1)
        weight of the old message in the log-domain update (0 = undamped).
    anderson : int
        Anderson acceleration memory (0 = plain damped BP).

    Returns
    -------
    BethePermanent
        ``log_value``, ``value``, ``marginals`` (Bethe beliefs γ),
        ``iterations`` (BP sweeps), ``converged``.

    Raises
    ------
    ValueError
        bad `A` (not 2-D, n > m, negative / non-finite entries) or options.
    InfeasibleAssignmentError
        if no assignment of the rows to distinct columns has positive weight.
    """
    A = _matrix(A)
    tol, max_iter, damping = _check_options(tol, max_iter, damping)
    anderson = as_int(anderson, "anderson", 0)
    n, m = A.shape
    gamma = np.zeros((n, m))
    if n == 0:
        gamma.setflags(write=False)
        return BethePermanent(0.0, 1.0, gamma, 0, True)

    allowed = _allowed_support(A > 0)
    # exact power-of-two scaling from the assignment dual: entries ≤ ~1, the best
    # assignment ≈ 1. A column factor 2^ec_j is compensated by giving column j's
    # "free" state the weight δ_j = 2^ec_j (see the module docstring), so
    # log per_B(A) = G_scaled − Σ er ln2 − Σ ec ln2 exactly.
    er, ec = _scaling_exponents(A)
    with np.errstate(divide="ignore"):
        # in log space: a scaled entry may be below the float64 range
        logA = np.where(allowed, np.log(np.where(allowed, A, 1.0)), -np.inf)
    logA += (er[:, None] + ec[None, :]) * _LN2
    log_delta_all = ec * _LN2

    # connected components of the allowed bipartite graph (rows 0..n-1, columns n..)
    ai, aj = np.nonzero(allowed)
    graph = csr_matrix((np.ones(ai.size, dtype=np.int8), (ai, n + aj)), shape=(n + m, n + m))
    ncomp, label = connected_components(graph, directed=False)
    nrow = np.bincount(label[:n], minlength=ncomp)
    ncol = np.bincount(label[n:], minlength=ncomp)
    # columns outside every component stay free (s_j = 1): their δ_j cancels the shift
    used_col = nrow[label[n:]] > 0
    shift = float(er.sum() + ec[used_col].sum()) * _LN2

    log_value = 0.0
    bp_comp = np.zeros(ncomp, dtype=bool)
    for comp in np.flatnonzero(nrow > 0):
        rows = np.flatnonzero(label[:n] == comp)
        cols = np.flatnonzero(label[n:] == comp)
        if nrow[comp] == ncol[comp]:
            Lc = logA[np.ix_(rows, cols)]
            if rows.size == 1:
                sigma = np.zeros(1, dtype=np.intp)
            else:
                sigma = _best_assignment(Lc)[1]
                if not _vertex_is_optimal(Lc, sigma):
                    bp_comp[comp] = True
                    continue
            gamma[rows, cols[sigma]] = 1.0
            log_value += float(np.sum(Lc[np.arange(rows.size), sigma]))
        else:
            bp_comp[comp] = True

    rows = np.flatnonzero(bp_comp[label[:n]])
    if rows.size == 0:
        return _result(log_value - shift, gamma, 0, True)
    cols = np.flatnonzero(bp_comp[label[n:]] & allowed[rows].any(axis=0))
    sub = allowed[np.ix_(rows, cols)]
    L = logA[np.ix_(rows, cols)]
    col_free = (nrow < ncol)[label[n + cols]]  # "at most one" columns
    log_delta = np.where(col_free, log_delta_all[cols], -np.inf)

    ii, jj = np.nonzero(sub)
    L_sub = L[ii, jj]
    ld = log_delta[jj]
    comp_entry = label[rows[ii]]  # component of every BP entry
    comp_col = label[n + cols]
    ld_free = np.where(col_free, log_delta, 0.0)

    # lower bound per component: the Bethe objective at the best vertex (matching)
    vertex_value = np.full(ncomp, -np.inf)
    vertex = np.zeros(ii.size)
    pos = {(int(i), int(j)): k for k, (i, j) in enumerate(zip(ii, jj, strict=True))}
    row_index = {int(r): k for k, r in enumerate(rows)}
    col_index = {int(c): k for k, c in enumerate(cols)}
    for comp in np.flatnonzero(bp_comp & (nrow > 0)):
        r_c = np.flatnonzero(label[:n] == comp)
        c_c = np.flatnonzero(label[n:] == comp)
        Lc = logA[np.ix_(r_c, c_c)]
        r_idx, c_idx = _best_assignment(Lc)
        unused = np.setdiff1d(np.arange(c_c.size), c_idx)
        vertex_value[comp] = float(np.sum(Lc[r_idx, c_idx]) + np.sum(log_delta_all[c_c[unused]]))
        for a, b in zip(r_c[r_idx], c_c[c_idx], strict=True):
            vertex[pos[(row_index[int(a)], col_index[int(b)])]] = 1.0

    def solve(aa: int):
        d, sweeps, conv = _run_bp(L_sub, ii, jj, sub.shape, ld, tol, max_iter, damping, aa)
        # Project the row beliefs onto P (rows = 1, columns = 1 or ≤ 1), then evaluate
        # the Bethe objective there: G at a feasible γ is ≤ log per_B even when BP
        # did not converge.
        lg, violation = _project(-np.logaddexp(0.0, -d), ii, jj, sub.shape, col_free)
        g = np.exp(lg)
        per_comp = _objective(g, lg, L_sub, jj, comp_entry, comp_col, col_free, ld_free, ncomp)
        return g, per_comp, sweeps, conv, violation

    g_vals, per_comp, sweeps, converged, violation = solve(anderson)
    below = bp_comp & (per_comp < vertex_value - 1e-9 * (1.0 + np.abs(vertex_value)))
    if anderson > 0 and np.any(below):
        # Anderson extrapolation ended below a vertex, i.e. not at the optimum of a
        # component: redo with plain damped BP and keep the better feasible point.
        g2, per_comp2, sweeps2, conv2, violation2 = solve(0)
        sweeps += sweeps2
        better = float(np.sum(per_comp2[bp_comp])) >= float(np.sum(per_comp[bp_comp]))
        if better and violation2 < 1e-9:
            g_vals, per_comp, converged = g2, per_comp2, conv2
        else:
            converged = False
    # Feasibility to rounding, per component; else (or if below the vertex) the best
    # vertex, which is feasible and exact in value.
    rsum = np.bincount(ii, weights=g_vals, minlength=rows.size)
    csum = np.bincount(jj, weights=g_vals, minlength=cols.size)
    bad_col = np.where(col_free, csum > 1.0 + 1e-13, np.abs(csum - 1.0) > 1e-12)
    bad = np.zeros(ncomp, dtype=bool)
    bad[comp_col[bad_col]] = True
    bad[label[rows[np.abs(rsum - 1.0) > 1e-13]]] = True
    bad |= ~np.isfinite(per_comp)
    fallback = bp_comp & (bad | (per_comp < vertex_value))
    if np.any(fallback & bad):
        converged = False
    if np.any(fallback):
        at = fallback[comp_entry]
        g_vals = np.where(at, vertex, g_vals)
        per_comp = np.where(fallback, vertex_value, per_comp)
    log_value += float(np.sum(per_comp[bp_comp]))
    g_sub = np.zeros(sub.shape)
    g_sub[ii, jj] = g_vals
    if not np.isfinite(log_value):  # pragma: no cover - defensive
        raise FloatingPointError(
            "bethe_permanent produced a non-finite log value; please report this input"
        )
    gamma[np.ix_(rows, cols)] = g_sub
    return _result(log_value - shift, gamma, sweeps, converged)


def _result(log_value: float, gamma: np.ndarray, sweeps: int, converged: bool):
    gamma.setflags(write=False)
    return BethePermanent(log_value, _safe_exp(log_value), gamma, sweeps, converged)


def _matrix(A) -> np.ndarray:
    try:
        return check_matrix(A)
    except OverflowError:
        raise ValueError("A holds an integer too large for a float64") from None


def _scaling_exponents(A: np.ndarray):
    """Power-of-two exponents (er, ec) of the assignment-dual scaling (zeros if too large)."""
    n, m = A.shape
    try:
        er, ec, ok = group_exponents(A, np.zeros(n), np.ones(n, np.int64), np.ones(m, np.int64))
    except ValueError:  # too large for one assignment solve: scale the rows by their maxima
        ok = False
    if not ok:
        with np.errstate(divide="ignore"):
            er = -np.frexp(A.max(axis=1))[1].astype(np.int64)
        return er, np.zeros(m, np.int64)
    return er, ec


def _best_assignment(L: np.ndarray):
    """(rows, cols) of a maximum-weight assignment of the log weights L (−inf = forbidden)."""
    res = linear_assignment(np.where(np.isfinite(L), -L, np.inf))
    return res.rows, res.cols


def _objective(g, lg, L_sub, jj, comp_entry, comp_col, col_free, ld_free, ncomp):
    """Bethe objective per component at γ (given with its log): finite, NaN-free."""
    with np.errstate(invalid="ignore"):
        one_minus = -np.expm1(lg)
        ent = np.where(g > 0, g * (L_sub - lg), 0.0)
        ent += np.where(one_minus > 0, one_minus * np.log(np.where(one_minus > 0, one_minus, 1)), 0)
    col_sum = np.bincount(jj, weights=g, minlength=col_free.size)
    slack = np.where(col_free, np.clip(1.0 - col_sum, 0.0, 1.0), 0.0)
    per_comp = np.bincount(comp_entry, weights=ent, minlength=ncomp)
    per_comp += np.bincount(comp_col, weights=slack * ld_free - _xlogx(slack), minlength=ncomp)
    return per_comp
