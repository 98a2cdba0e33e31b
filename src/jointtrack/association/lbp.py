"""JPDA marginal association probabilities by loopy belief propagation.

J. L. Williams and R. A. Lau, "Approximate evaluation of marginal association
probabilities with belief propagation", IEEE Trans. Aerospace and Electronic
Systems 50(4):2942–2959, 2014.

The joint event weight Π_i ψ_i(a_i) (ψ_i(0) = miss_i, ψ_i(j) = L_ij; every
measurement used at most once) is a pairwise model on the bipartite gating graph
of track variables a_i and measurement variables b_j. With the track-node
weights kept unnormalised, the two BP message families of Williams & Lau
reduce to one scalar per gated edge (i, j):

    μ_{i→j} = L_ij / (miss_i + Σ_{j'≠j} L_ij' ν_{j'→i})        (track → measurement)
    ν_{j→i} = 1 / (1 + Σ_{i'≠i} μ_{i'→j})                      (measurement → track)

started from ν ≡ 1, and the beliefs are

    β_i0 ∝ miss_i,   β_ij ∝ L_ij ν_{j→i}.

(Dividing row i by miss_i gives Williams & Lau's normalisation ψ_i(0) = 1.)

Scaling (every feasible cluster in range): the cluster is first put in range by
the exact power-of-two row/column scaling of
:func:`jointtrack.assignment.scaling.scale_problem` (every factor ≤ ~1, the best
joint event ≈ 1; marginals unchanged). A column scaling turns the clutter weight
1 of measurement j into a weight v_j, so the recursions are run in their general
form with a per-measurement unused weight (the same derivation with the
measurement node's "clutter" potential v_j instead of 1):

    ν_{j→i} = 1 / (v_j + Σ_{i'≠i} μ_{i'→j}),     started from ν ≡ 1/v,

which is the unit-clutter recursion on ``L_ij / v_j`` with ν rescaled by v_j —
the same iterates, the same fixed point and the same log-metric distances, so
the convergence analysis below is unchanged (A and B are invariant under the
scaling). Positive factors that the scaling takes below 2^-400 are raised to
2^-400: only events weighing ≲ 2^-400 of the best one change, and no message
over/underflows (without scaling, ``L ~ 1e300`` against ``miss ~ 1e-300``
underflowed the miss weights to 0 and broke BP).

Convergence (Williams & Lau's contraction argument): with messages compared in the metric
d(ν, ν̃) = max_{ij} |log ν_{j→i} − log ν̃_{j→i}|, one sweep ν → ν' maps a
distance d to at most g_B(g_A(d)), g_C(x) = log(1 + C (eˣ − 1)/(1 + C)), where
A bounds the leave-one-out sums Σ_{j'≠j} L_ij'/miss_i and B the sums
Σ_{i'≠i} L_i'j/miss_i' (μ_{i→j} ≤ L_ij/miss_i, ν ≤ 1). g_B∘g_A is convex with
g(0) = 0, so α(d) = g_B(g_A(d))/d < 1 is non-decreasing and the sweep is a
contraction on any bounded set: BP converges to a unique fixed point from any
start. The certified stopping rule is the contraction-mapping bound

    d(ν_{k+1}, ν*) ≤ α(d_k) d_k / (1 − α(d_k)),   d_k = d(ν_k, ν_{k+1}),

stopped once it is ≤ ``tol``. (The rule as implemented in Stone Soup's
``JPDAwithLBP`` uses only the single factor g_A with A = W* = max_i Σ_j
L_ij/miss_i; the leave-one-out A and the measurement-side factor g_B, derived
the same way, only tighten it.) A message error ε gives
beliefs within a factor e^{±2ε} of the fixed-point beliefs.

When some ``miss_i = 0`` (a certainly detected track) A or B is infinite and no
contraction factor is available: iterations then stop when the raw message
change d_k ≤ ``tol`` and ``LBPInfo.certified`` is False. BP with such hard
constraints has no convergence guarantee and is much less accurate: measured
on 1156 random feasible clusters (N ≤ 4, M ≤ 5) with about half the tracks at
miss = 0, 3% did not converge in 1000 sweeps, the median max-marginal error
was 1e-16 (mostly trees) but the 90th percentile 0.09 and the worst 0.49 (BP
can lock onto a single event). Damping did not help. Prefer an exact method
there.

Messages live on the gated pairs (one μ and one ν per pair, the pairs in
row-major order plus a column-major permutation), so memory is O(N + M + P)
for P gated pairs: :func:`lbp_pair_marginals` takes the pairs directly, for
clusters whose N × M matrix would not fit (the last-but-one tier of
:func:`jointtrack.association.budget.fallback_pair_marginals`), and scales each
track by a power of two instead of the dense scaling, whose assignment solve is
limited to N + M ≤ 4000 (:func:`lbp_marginals` refuses larger clusters with
:class:`~jointtrack.errors.ExactLimitError`).

BP is exact when the gating graph is a forest (no cycles); on loopy (dense)
clusters it is an approximation. Measured here (``tests/test_association_approx``):
on 200 random dense 5×10 clusters, ``L = 5·U[0,1]``, ``miss = 0.1``, the
largest absolute marginal error against brute-force enumeration was 0.0093
(median over clusters 0.0038); the tests assert ≤ 0.03. At 20×40 (dense) it
needs ≈ 37 sweeps and 0.3 ms for a certified tol = 1e-9.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numba
import numpy as np

from jointtrack.assignment._checks import _as_real_array, as_float, as_int, as_weights
from jointtrack.assignment.scaling import GROUP_SCALING_MAX, scale_problem
from jointtrack.association._validate import check_cluster, require_feasible_event
from jointtrack.errors import ExactLimitError, InfeasibleAssignmentError

__all__ = ["LBPInfo", "lbp_marginals", "lbp_pair_marginals"]

#: Positive factors are kept ≥ this after scaling (events below it are negligible).
_FLOOR = 2.0**-400


@dataclass(frozen=True)
class LBPInfo:
    """Diagnostics of :func:`lbp_marginals`.

    Attributes
    ----------
    iterations : int
        message sweeps performed.
    converged : bool
        the stopping rule was met within ``max_iter`` sweeps.
    max_change : float
        d_k, the largest |Δ log ν| over gated edges in the last sweep.
    error_bound : float
        certified bound on the max |log ν − log ν*| distance of the returned
        messages to the BP fixed point (``inf`` when not certified).
    certified : bool
        the contraction bound was available (all ``miss > 0``).
    floored : int
        weights that :func:`lbp_pair_marginals`' per-track power-of-two scaling
        left below 2^-400 of their track's largest and that were raised to it
        (so the messages stay in range). 0: BP ran on the problem as given.
        Otherwise BP ran on a nearby problem and the marginals may differ from
        BP's on the given one by more than ``error_bound`` (a factor ≤ 2 on
        probabilities that small here, but O(1) where two tracks compete with
        miss weights both far below their likelihoods); the dense
        :func:`lbp_marginals`, whose dual scaling keeps every weight that
        matters near 1, does not need this.
    """

    iterations: int
    converged: bool
    max_change: float
    error_bound: float
    certified: bool
    floored: int = 0


@numba.njit(cache=True)
def _g(x, c):
    # log(1 + c (e^x − 1)/(1 + c)); c = inf → x
    if not np.isfinite(c):
        return x
    return np.log1p(c * np.expm1(x) / (1.0 + c))


@numba.njit(cache=True)
def _lbp_pairs_kernel(indptr, W, m, v, col_ptr, col_perm, cols, A, B, tol, max_iter, certified):
    """Synchronous BP sweeps on the gated pairs: one message pair (μ, ν) per pair.

    Pairs are in row-major order (track ``i``'s pairs are ``indptr[i]:indptr[i+1]``,
    columns increasing); ``col_perm[col_ptr[j]:col_ptr[j+1]]`` lists measurement
    ``j``'s pairs by increasing track. ``W`` (P,) scaled weights, ``m`` (N,) miss
    weights, ``v`` (M,) unused weights. Memory O(N + M + P): the same recursion
    and summation order as on the dense N × M matrix (ungated entries add 0.0).
    """
    n = m.shape[0]
    mm = v.shape[0]
    npairs = W.shape[0]
    nu = np.empty(npairs)
    for p in range(npairs):
        nu[p] = 1.0 / v[cols[p]]
    nu_new = np.empty(npairs)
    mu = np.zeros(npairs)
    it = 0
    d = np.inf
    bound = np.inf
    converged = False
    alpha0 = 0.0
    if certified:
        alpha0 = (A / (1.0 + A)) * (B / (1.0 + B))
    while it < max_iter:
        it += 1
        # track → measurement: leave-one-out sums by prefix/suffix (no cancellation);
        # the prefix sums are kept in nu_new, overwritten by the next pass
        for i in range(n):
            lo = indptr[i]
            hi = indptr[i + 1]
            acc = 0.0
            for p in range(lo, hi):
                nu_new[p] = acc
                acc += W[p] * nu[p]
            suf = 0.0
            for p in range(hi - 1, lo - 1, -1):
                w = W[p]
                den = m[i] + nu_new[p] + suf
                mu[p] = w / den if den > 0.0 else np.inf
                suf += w * nu[p]
        # measurement → track
        for j in range(mm):
            lo = col_ptr[j]
            hi = col_ptr[j + 1]
            acc = 0.0
            for q in range(lo, hi):
                p = col_perm[q]
                nu_new[p] = acc
                acc += mu[p]
            suf = 0.0
            for q in range(hi - 1, lo - 1, -1):
                p = col_perm[q]
                pre = nu_new[p]
                nu_new[p] = 1.0 / (v[j] + pre + suf)
                suf += mu[p]
        # change in the log metric: the largest ratio, one log per sweep
        q = 1.0
        for p in range(npairs):
            a = nu[p]
            b = nu_new[p]
            if a != b:
                if a > 0.0 and b > 0.0:
                    x = b / a if b > a else a / b
                else:
                    x = np.inf
                if x > q:
                    q = x
            nu[p] = b
        d = np.log(q)
        if certified:
            if d == 0.0:
                bound = 0.0
            elif np.isfinite(d):
                alpha = _g(_g(d, A), B) / d
                if alpha < alpha0:  # rounding for tiny d: use the limit
                    alpha = alpha0
                bound = alpha * d / (1.0 - alpha) if alpha < 1.0 else np.inf
            else:
                bound = np.inf
            if bound <= tol:
                converged = True
                break
        else:
            if d <= tol:
                converged = True
                break
    return nu, it, converged, d, bound


def _pair_layout(rows, cols, n, mm):
    """Row pointer of row-sorted pairs, and the column-major permutation with its pointer."""
    indptr = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
    col_perm = np.argsort(cols, kind="stable").astype(np.int64)  # rows stay increasing
    col_ptr = np.zeros(mm + 1, np.int64)
    np.cumsum(np.bincount(cols, minlength=mm), out=col_ptr[1:])
    return indptr, col_perm, col_ptr


def _run_pairs(rows, cols, W, m, v, A, B, tol, max_iter, certified):
    """:func:`_lbp_pairs_kernel` on row-major sorted pairs (rows, cols)."""
    indptr, col_perm, col_ptr = _pair_layout(rows, cols, m.shape[0], v.shape[0])
    return _lbp_pairs_kernel(
        indptr, W, m, v, col_ptr, col_perm, cols, A, B, tol, max_iter, certified
    )


def _lbp_kernel(W, m, v, A, B, tol, max_iter, certified):
    """Dense face of :func:`_lbp_pairs_kernel`: messages ν as an N × M array (1/v off the gate)."""
    rows, cols = np.nonzero(W > 0.0)
    nu_p, it, conv, d, bound = _run_pairs(
        rows.astype(np.int64),
        cols.astype(np.int64),
        W[rows, cols],
        m,
        v,
        A,
        B,
        tol,
        max_iter,
        certified,
    )
    nu = np.broadcast_to(1.0 / v, W.shape).copy()
    nu[rows, cols] = nu_p
    return nu, it, conv, d, bound


def _row_max(base, rows, values):
    """``max(base[i], values of row i)`` for row-sorted ``rows`` (no slow ufunc.at)."""
    top = base.copy()
    if rows.size:
        starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
        r = rows[starts]
        top[r] = np.maximum(top[r], np.maximum.reduceat(values, starts))
    return top


def _certificate(rows, cols, w, n, mm):
    """Williams & Lau's A and B: the largest leave-one-out row and column sums of ``w``."""
    out = []
    for idx, size in ((rows, n), (cols, mm)):
        tot = np.bincount(idx, w, minlength=size)
        low = np.full(size, np.inf)
        np.minimum.at(low, idx, w)
        has = np.bincount(idx, minlength=size) > 0
        out.append(float((tot - np.where(has, low, 0.0)).max()) if size else 0.0)
    return out[0], out[1]


def lbp_marginals(L, miss, *, tol: float = 1e-9, max_iter: int = 1000):
    """Approximate JPDA marginals by Williams & Lau (2014) loopy belief propagation.

    Message passing between track and measurement nodes (Williams & Lau eqs. for
    μ and ν, see the module docstring) with their contraction-mapping
    convergence guarantee and a certified stopping rule: iterate until the
    bound on the distance (max |Δ log ν|) from the fixed point is ≤ ``tol``.

    Accuracy: exact on tree-structured (cycle-free) gating graphs; on dense
    random 5×10 clusters (L = 5·U[0,1], miss = 0.1) the maximum absolute
    marginal error against exact enumeration is ≤ 0.03 (measured max 0.0093
    over 200 clusters). No accuracy guarantee when some ``miss = 0``.

    Parameters
    ----------
    L : (N, M) likelihood ratios, 0 = not gated
    miss : (N,) miss weights 1 − P_D P_G
    tol : float > 0
        bound on the log-message distance to the BP fixed point (certified when
        all ``miss > 0``; otherwise a bound on the last message change).
    max_iter : int ≥ 1
        cap on sweeps; if reached, the current beliefs are returned with
        ``converged=False``.

    Returns
    -------
    beta : (N, M+1) array, column 0 = no measurement, rows sum to 1
    info : LBPInfo

    Raises
    ------
    ValueError
        bad input (see ``check_cluster``), ``tol`` not a positive finite number,
        ``max_iter`` not a whole number ≥ 1.
    ExactLimitError
        N + M > 4000, above the dense scaling's limit (use
        :func:`lbp_pair_marginals` on the gated pairs).
    InfeasibleAssignmentError
        no joint event has positive weight.
    """
    L, miss = check_cluster(L, miss)
    tol = as_float(tol, "tol", minimum=0.0, open_min=True)
    max_iter = as_int(max_iter, "max_iter", minimum=1)
    require_feasible_event(L, miss)
    n, mm = L.shape
    beta = np.zeros((n, mm + 1))
    if n == 0:
        return beta, LBPInfo(0, True, 0.0, 0.0, True)
    gated = L > 0
    certified = bool(np.all(miss > 0))
    if mm == 0 or not gated.any():
        beta[:, 0] = 1.0
        return beta, LBPInfo(0, True, 0.0, 0.0, certified)
    if n + mm > GROUP_SCALING_MAX:
        raise ExactLimitError(
            f"a dense cluster of {n} tracks and {mm} measurements is above the dense LBP "
            f"scaling's limit (tracks + measurements ≤ {GROUP_SCALING_MAX}); use "
            "lbp_pair_marginals on its gated pairs"
        )
    W, m, v = _scaled(L, miss)
    rows, cols = (a.astype(np.int64) for a in np.nonzero(gated))
    b0, bp, info = _lbp_pairs(rows, cols, W[rows, cols], m, v, certified, tol, max_iter)
    beta[:, 0] = b0
    beta[rows, cols + 1] = bp
    return beta, info


def _lbp_pairs(rows, cols, W, m, v, certified, tol, max_iter):
    """BP on scaled row-major pairs; ``(beta0 (N,), pair beta (P,), LBPInfo)``."""
    n, mm = m.shape[0], v.shape[0]
    A = B = np.inf
    if certified:
        # A, B are invariant under the scaling: compute them on the scaled problem
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            A, B = _certificate(rows, cols, W / (m[rows] * v[cols]), n, mm)
        if not (np.isfinite(A) and np.isfinite(B)):
            certified = False
            A = B = np.inf
    nu, it, conv, d, bound = _run_pairs(rows, cols, W, m, v, A, B, tol, max_iter, certified)
    if not certified:
        bound = np.inf
    # each track's beliefs by a power of two so that the largest is in [0.5, 1)
    un = W * nu
    top = _row_max(m, rows, un)
    with np.errstate(invalid="ignore"):
        _, e = np.frexp(top)
    u0 = np.ldexp(m, -e)
    un = np.ldexp(un, -e[rows])
    tot = u0 + np.bincount(rows, un, minlength=n)
    if not (np.all(tot > 0) and np.all(np.isfinite(tot))):  # pragma: no cover - guarded
        raise InfeasibleAssignmentError(
            "belief propagation degenerated (a certainly detected track lost every "
            "measurement); use method='exact'"
        )
    info = LBPInfo(int(it), bool(conv), float(d), float(bound), certified)
    return u0 / tot, un / tot[rows], info


def lbp_pair_marginals(
    rows, cols, L_values, miss, n_measurements: int, *, tol: float = 1e-9, max_iter: int = 1000
):
    """:func:`lbp_marginals` on the gated pairs of a cluster too large for an N × M matrix.

    The same Williams & Lau recursion, stopping rule and :class:`LBPInfo`, with
    one message pair per gated pair: memory O(N + M + P) and time
    O(sweeps · P) for P gated pairs, however large N · M. Instead of the dense
    power-of-two row/column scaling of :func:`lbp_marginals` (an assignment
    solve on the (N+M)-node expansion), each track's weights are scaled by a
    power of two so that its largest one (miss or likelihood ratio) is in
    [0.5, 1) — exact, since μ and the beliefs are invariant under a scaling of
    one track's weights — and positive factors below 2^-400 of their track's
    largest are raised to 2^-400, so that messages stay in range (μ ≤ 2^400,
    every belief ≥ 2^-820 of its track's largest). Only events weighing
    ≲ 2^-400 of their track's best change. Joint feasibility is not checked
    (only that every ``miss = 0`` track has a gated pair); BP on a cluster
    without a feasible event degenerates and raises.

    Parameters
    ----------
    rows, cols : (P,) int arrays
        track (0..N−1) and measurement (0..n_measurements−1) of each gated pair,
        each pair at most once, any order.
    L_values : (P,) likelihood ratios of the pairs (pairs with 0 are not gated).
    miss : (N,) miss weights 1 − P_D P_G, in [0, 1].
    n_measurements : int
        M, the number of measurements of the cluster.
    tol, max_iter
        as :func:`lbp_marginals`.

    Returns
    -------
    beta0 : (N,) probability that each track has no measurement.
    pair_beta : (P,) probability of each pair, aligned with ``rows``/``cols``.
    info : LBPInfo

    Raises
    ------
    ValueError
        bad input, named; ``rows``/``cols`` out of range or a pair listed twice.
    InfeasibleAssignmentError
        a ``miss = 0`` track without a gated pair, or BP degenerated.
    """
    from jointtrack.association.clustering import _check_pairs

    tol = as_float(tol, "tol", minimum=0.0, open_min=True)
    max_iter = as_int(max_iter, "max_iter", minimum=1)
    miss = _as_real_array(miss, "miss")
    if miss.ndim != 1:
        raise ValueError(f"miss must be 1-D (one entry per track), got {miss.ndim} dimension(s)")
    miss = as_weights(miss.reshape(1, -1), "miss")[0]
    if np.any(miss > 1):
        i = int(np.argmax(miss > 1))
        raise ValueError(f"miss[{i}] = {miss[i]} is outside [0, 1]")
    n, mm, rows, cols = _check_pairs(miss.shape[0], n_measurements, rows, cols)
    vals = _as_real_array(L_values, "L_values")
    if vals.ndim != 1 or vals.shape[0] != rows.shape[0]:
        raise ValueError(
            f"L_values must be 1-D with one entry per pair ({rows.shape[0]}), "
            f"got shape {vals.shape}"
        )
    vals = as_weights(vals.reshape(1, -1), "L_values")[0]
    key = rows * max(mm, 1) + cols
    order = np.argsort(key, kind="stable")
    if key.size and np.any(np.diff(key[order]) == 0):
        raise ValueError("a (row, col) pair is listed twice")
    beta0 = np.ones(n)
    pair_beta = np.zeros(rows.shape[0])
    gated = order[vals[order] > 0]
    r, c, w = rows[gated], cols[gated], vals[gated]
    has = np.bincount(r, minlength=n) > 0
    if np.any((miss == 0) & ~has):
        i = int(np.argmax((miss == 0) & ~has))
        raise InfeasibleAssignmentError(
            f"track {i} has miss = 0 (certainly detected) but no gated measurement: "
            "no feasible joint association event exists"
        )
    certified = bool(np.all(miss > 0))
    if r.size == 0:
        return beta0, pair_beta, LBPInfo(0, True, 0.0, 0.0, certified)
    _, e = np.frexp(_row_max(miss, r, w))
    w = np.ldexp(w, -e[r])
    m = np.ldexp(miss, -e)
    # the floor keeps μ = w / (m + …) ≤ 2^400; without a dual scaling it can bind on
    # weights that matter, so how often it did is reported (LBPInfo.floored)
    floored = int(np.count_nonzero(w < _FLOOR) + np.count_nonzero((m > 0) & (m < _FLOOR)))
    w = np.maximum(w, _FLOOR)
    m = np.where(m > 0, np.maximum(m, _FLOOR), 0.0)
    b0, bp, info = _lbp_pairs(r, c, w, m, np.ones(mm), certified, tol, max_iter)
    if floored:
        info = replace(info, floored=floored)
    beta0[:] = b0
    pair_beta[gated] = bp
    return beta0, pair_beta, info


def _scaled(L, miss):
    """Scaled weights ``(W, miss', unused')`` with every positive factor in [2^-400, ~2]."""
    W, m, v, _shift, ok = scale_problem(L, miss)
    if not ok:  # pragma: no cover - feasibility was checked first
        W, m, v = L.copy(), miss.copy(), np.ones(L.shape[1])
    W = np.where(L > 0, np.maximum(W, _FLOOR), 0.0)
    m = np.where(miss > 0, np.maximum(m, _FLOOR), 0.0)
    v = np.maximum(v, _FLOOR)
    return np.ascontiguousarray(W), np.ascontiguousarray(m), np.ascontiguousarray(v)
