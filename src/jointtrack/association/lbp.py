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

Split-float messages (every cluster in range, no floor): weights and messages
are kept as a float mantissa and a power-of-two exponent (as in
:mod:`jointtrack.assignment._splitfloat`), and each leave-one-out sum is taken
on the scale of its largest exponent by prefix and suffix sums
(:func:`_loo_sums`). Nothing over- or underflows and every operation rounds
about once, as in plain floating point, whatever the spread of the weights —
likelihood ratios from subnormal to 1e300 and miss weights from 5e-324 to 1 in
one cluster — and no weight is changed: the cluster is neither scaled nor
floored. (Plain float messages need the cluster put in range first. A power of
two per track cannot put two tracks whose miss weights are both far below their
likelihoods in range together; the sparse tier used to raise the factors it
left below 2^-400 to 2^-400, which moved β by up to 1 once ratios passed
~1e120 and let BP on feasible clusters with a ``miss = 0`` track overflow into
a spurious degeneration, issue 31 item 12. The dense tier's dual scaling kept
the factors that matter in range but needs an assignment solve on the
(N+M)-node expansion, which the pair tier exists to avoid; split floats need
neither, so both tiers run one kernel.) ``μ = +inf`` arises exactly where a
``miss = 0`` track has no other measurement left and makes ν = 0 for its
competitors: this propagates the constraint "track i must take j", which holds
in every feasible event, so BP on a feasible cluster never leaves a track with
no belief; infeasible clusters are refused before BP by the one feasibility
test.

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
for P gated pairs. :func:`lbp_pair_marginals` takes the pairs directly, for
clusters whose N × M matrix would not fit (the last-but-one tier of
:func:`jointtrack.association.budget.fallback_pair_marginals`);
:func:`lbp_marginals` is its face on an N × M matrix and runs the same kernel on
the same pairs, so both return the same β. :func:`lbp_marginals` refuses
clusters with N + M > :data:`DENSE_LBP_MAX` (:class:`~jointtrack.errors.ExactLimitError`):
it runs up to ``max_iter`` sweeps whatever the size, and the refusal sends such
a cluster of a budgeted caller to the pair tier, whose sweeps are capped by work.

BP is exact when the gating graph is a forest (no cycles); on loopy (dense)
clusters it is an approximation. Measured here (``tests/test_association_approx``):
on 200 random dense 5×10 clusters, ``L = 5·U[0,1]``, ``miss = 0.1``, the
largest absolute marginal error against brute-force enumeration was 0.0093
(median over clusters 0.0038); the tests assert ≤ 0.03. At 20×40 (dense) it
needs ≈ 37 sweeps for a certified tol = 1e-9 (time: ``benchmarks/RESULTS.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from jointtrack.assignment._checks import _as_real_array, as_float, as_int, as_weights
from jointtrack.assignment._splitfloat import split_normalize
from jointtrack.assignment.feasibility import is_feasible_pairs
from jointtrack.association._validate import (
    NO_FEASIBLE_EVENT,
    check_cluster,
    require_feasible_event,
)
from jointtrack.errors import ExactLimitError, InfeasibleAssignmentError

__all__ = ["DENSE_LBP_MAX", "LBPInfo", "lbp_marginals", "lbp_pair_marginals"]

#: Largest N + M that :func:`lbp_marginals` accepts (larger: :func:`lbp_pair_marginals`).
DENSE_LBP_MAX = 4000
#: Stored message mantissas are kept in [2^-32, 2^32] (renormalised outside it), so a
#: product of two is in [2^-64, 2^64] and a sum holding its largest-exponent term is ≥ 2^-64.
_MANT_LO = 2.0**-32
_MANT_HI = 2.0**32
#: A leave-one-out sum below this (on the scale of the largest exponent) has left out the
#: term that sets the scale: it is recomputed on its own scale.
_SAFE_SUM = 2.0**-500
#: Index of 2^0 in :func:`_powers_of_two` (its entries are 2^-1074 … 2^1023).
_BIAS = 1074


@dataclass(frozen=True)
class LBPInfo:
    """Diagnostics of :func:`lbp_marginals` and :func:`lbp_pair_marginals`.

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
        the contraction bound was available (all ``miss > 0`` and Williams &
        Lau's A and B finite).
    """

    iterations: int
    converged: bool
    max_change: float
    error_bound: float
    certified: bool


@numba.njit(cache=True)
def _g(x, c):
    # log(1 + c (e^x − 1)/(1 + c)); c = inf → x
    if not np.isfinite(c):
        return x
    return np.log1p(c * np.expm1(x) / (1.0 + c))


@numba.njit(cache=True)
def _powers_of_two():
    """2^k for k = −1074 … 1023 at index k + 1074, exactly (doubling and halving are exact)."""
    pow2 = np.empty(_BIAS + 1024)
    pow2[_BIAS] = 1.0
    for k in range(1, _BIAS + 1):
        pow2[_BIAS - k] = 0.5 * pow2[_BIAS - k + 1]
    for k in range(1, 1024):
        pow2[_BIAS + k] = 2.0 * pow2[_BIAS + k - 1]
    return pow2


@numba.njit(cache=True, inline="always")
def _down(x, d, pow2):
    """x·2^d for an integer-valued d ≤ 0, one rounding; 0 below 2^-1074 (negligible here)."""
    return x * pow2[np.int64(d) + _BIAS] if d >= -1074.0 else 0.0


@numba.njit(cache=True, inline="always")
def _stored(m, e):
    """A message m·2^e with its mantissa brought back into [_MANT_LO, _MANT_HI] if needed."""
    if m == 0.0 or m == np.inf or (m >= _MANT_LO and m <= _MANT_HI):
        return m, e
    f, k = split_normalize(m, 0)
    return f, e + k


@numba.njit(cache=True, inline="always")
def _sum_without(t, k, bm, be, pow2, skip):
    """``b + Σ_{r<k, r≠skip} t[r]`` as (mantissa, exponent) on its own largest exponent.

    ``t[r] = t[r, 0]·2^t[r, 1]`` (finite, or the skipped one infinite), ``b = bm·2^be``.
    """
    top = be if bm > 0.0 else -np.inf
    for r in range(k):
        if r != skip and t[r, 0] > 0.0 and t[r, 1] > top:
            top = t[r, 1]
    if top == -np.inf:
        return 0.0, 0.0
    s = _down(bm, be - top, pow2) if bm > 0.0 else 0.0
    for r in range(k):
        if r != skip and t[r, 0] > 0.0:
            s += _down(t[r, 0], t[r, 1] - top, pow2)
    return s, top


@numba.njit(cache=True, inline="always")
def _loo_sums(t, k, top, bm, be, pow2, pre, aligned, out):
    """Leave-one-out sums ``out[q] = b + Σ_{r<k, r≠q} t[r]`` of finite split floats.

    ``t[r] = t[r, 0]·2^t[r, 1]`` with mantissas in [2^-64, 2^64] or 0, ``b = bm·2^be``,
    ``top`` the largest exponent among them (b included). The terms are put on the
    scale 2^top (exact powers of two) and summed by prefix and suffix, so nothing
    cancels: a sum that holds the term of exponent ``top`` is ≥ 2^-64 and exact to
    rounding; the one that leaves it out is recomputed on its own scale where it
    fell below :data:`_SAFE_SUM`. ``pre`` and ``aligned`` are scratch of length ≥ k.
    """
    acc = _down(bm, be - top, pow2) if bm > 0.0 else 0.0
    for q in range(k):
        pre[q] = acc
        aligned[q] = _down(t[q, 0], t[q, 1] - top, pow2) if t[q, 0] > 0.0 else 0.0
        acc += aligned[q]
    suf = 0.0
    for q in range(k - 1, -1, -1):
        s = pre[q] + suf
        suf += aligned[q]
        if s >= _SAFE_SUM:
            out[q, 0] = s
            out[q, 1] = top
        else:
            out[q, 0], out[q, 1] = _sum_without(t, k, bm, be, pow2, q)


@numba.njit(cache=True)
def _lbp_pairs_kernel(indptr, w, miss, col_ptr, col_perm, A, B, tol, max_iter, certified):
    """Synchronous BP sweeps on the gated pairs: one message pair (μ, ν) per pair.

    Pairs are in row-major order (track ``i``'s pairs are ``indptr[i]:indptr[i+1]``,
    columns increasing); ``col_perm[col_ptr[j]:col_ptr[j+1]]`` lists measurement
    ``j``'s pairs by increasing track. Weights and messages are split floats
    ``x[:, 0]·2^x[:, 1]`` (mantissa, integer-valued power-of-two exponent; as in
    :mod:`jointtrack.assignment._splitfloat`), so nothing over- or underflows:
    ``w`` (P, 2) the likelihood ratios, ``miss`` (N, 2) the miss weights (mantissa
    0 for a certainly detected track). Memory O(N + M + P). Returns ``(ν (P, 2),
    sweeps, converged, d, bound)``.
    """
    n = miss.shape[0]
    n_meas = col_ptr.shape[0] - 1
    npairs = w.shape[0]
    pow2 = _powers_of_two()
    width = 1
    for i in range(n):
        width = max(width, indptr[i + 1] - indptr[i])
    for j in range(n_meas):
        width = max(width, col_ptr[j + 1] - col_ptr[j])
    t = np.empty((width, 2))
    loo = np.empty((width, 2))
    pre = np.empty(width)
    aligned = np.empty(width)
    nu = np.zeros((npairs, 2))
    nu[:, 0] = 1.0  # ν ≡ 1
    mu = np.empty((npairs, 2))
    ln2 = np.log(2.0)
    it = 0
    d = np.inf
    bound = np.inf
    converged = False
    alpha0 = 0.0
    if certified:
        alpha0 = (A / (1.0 + A)) * (B / (1.0 + B))
    while it < max_iter:
        it += 1
        # track → measurement: μ = L / (miss + Σ_{j'≠j} L ν)
        for i in range(n):
            lo = indptr[i]
            k = indptr[i + 1] - lo
            bm = miss[i, 0]
            be = miss[i, 1]
            top = be if bm > 0.0 else -np.inf
            for q in range(k):
                p = lo + q
                t[q, 0] = w[p, 0] * nu[p, 0]
                t[q, 1] = w[p, 1] + nu[p, 1]
                if t[q, 0] > 0.0 and t[q, 1] > top:
                    top = t[q, 1]
            if top == -np.inf:  # miss = 0 and every ν = 0: each sum is 0
                for q in range(k):
                    loo[q, 0] = 0.0
            else:
                _loo_sums(t, k, top, bm, be, pow2, pre, aligned, loo)
            for q in range(k):
                p = lo + q
                if loo[q, 0] == 0.0:  # a certainly detected track with nothing else left
                    mu[p, 0] = np.inf
                    mu[p, 1] = 0.0
                else:
                    mu[p, 0], mu[p, 1] = _stored(w[p, 0] / loo[q, 0], w[p, 1] - loo[q, 1])
        # measurement → track: ν = 1 / (1 + Σ_{i'≠i} μ), compared with the last ν in place;
        # the change is the largest ratio (logs only beyond 2^±900 or where ν hit 0)
        q_hi = 1.0
        q_lo = 1.0
        d_far = 0.0
        for j in range(n_meas):
            lo = col_ptr[j]
            k = col_ptr[j + 1] - lo
            top = 0.0
            n_inf = 0
            arg = -1
            for q in range(k):
                p = col_perm[lo + q]
                t[q, 0] = mu[p, 0]
                t[q, 1] = mu[p, 1]
                if t[q, 0] == np.inf:
                    n_inf += 1
                    arg = q
                elif t[q, 0] > 0.0 and t[q, 1] > top:
                    top = t[q, 1]
            if n_inf:  # μ = inf: every other sum is infinite (ν = 0)
                for q in range(k):
                    loo[q, 0] = np.inf
                if n_inf == 1:
                    loo[arg, 0], loo[arg, 1] = _sum_without(t, k, 1.0, 0.0, pow2, arg)
            else:
                _loo_sums(t, k, top, 1.0, 0.0, pow2, pre, aligned, loo)
            for q in range(k):
                p = col_perm[lo + q]
                if loo[q, 0] == np.inf:
                    bm, be = 0.0, 0.0
                else:
                    bm, be = _stored(1.0 / loo[q, 0], -loo[q, 1])
                am = nu[p, 0]
                ae = nu[p, 1]
                if am != bm or ae != be:
                    de = be - ae
                    if am == 0.0 or bm == 0.0:
                        d_far = np.inf
                    elif de > -900.0 and de < 900.0:
                        x = bm / am * pow2[np.int64(de) + _BIAS]
                        q_hi = max(q_hi, x)
                        q_lo = min(q_lo, x)
                    else:
                        d_far = max(d_far, abs(np.log(bm / am) + de * ln2))
                    nu[p, 0] = bm
                    nu[p, 1] = be
        d = max(np.log(q_hi), -np.log(q_lo), d_far)
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


@numba.njit(cache=True)
def _beliefs(indptr, w, miss, nu, beta0, pair_beta):
    """β_i0 ∝ miss_i, β_ij ∝ L_ij ν_{j→i}, normalised per track on its largest exponent.

    Writes ``beta0`` (N,) and ``pair_beta`` (P,); returns the first track whose
    beliefs are all 0 (−1 if none).
    """
    pow2 = _powers_of_two()
    for i in range(miss.shape[0]):
        lo = indptr[i]
        hi = indptr[i + 1]
        top = miss[i, 1] if miss[i, 0] > 0.0 else -np.inf
        for p in range(lo, hi):
            if nu[p, 0] > 0.0 and w[p, 1] + nu[p, 1] > top:
                top = w[p, 1] + nu[p, 1]
        if top == -np.inf:
            return i
        b0 = _down(miss[i, 0], miss[i, 1] - top, pow2) if miss[i, 0] > 0.0 else 0.0
        tot = b0
        for p in range(lo, hi):
            x = w[p, 0] * nu[p, 0]
            pair_beta[p] = _down(x, w[p, 1] + nu[p, 1] - top, pow2) if x > 0.0 else 0.0
            tot += pair_beta[p]
        beta0[i] = b0 / tot
        for p in range(lo, hi):
            pair_beta[p] /= tot
    return -1


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


def _lbp_pairs(rows, cols, values, miss, mm, tol, max_iter):
    """BP on row-major sorted gated pairs: ``(beta0 (N,), pair_beta (P,), LBPInfo)``."""
    n = miss.shape[0]
    certified = bool(np.all(miss > 0))
    A = B = np.inf
    if certified:
        with np.errstate(over="ignore", invalid="ignore"):
            A, B = _certificate(rows, cols, values / miss[rows], n, mm)
        if not (np.isfinite(A) and np.isfinite(B)):  # a ratio L/miss beyond 1.8e308
            certified = False
            A = B = np.inf
    indptr = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
    col_perm = np.argsort(cols, kind="stable").astype(np.int64)  # rows stay increasing
    col_ptr = np.zeros(mm + 1, np.int64)
    np.cumsum(np.bincount(cols, minlength=mm), out=col_ptr[1:])
    # split floats, exact: the weights as they are, whatever their magnitude
    w = np.column_stack(np.frexp(values)).astype(np.float64)
    m = np.column_stack(np.frexp(miss)).astype(np.float64)
    nu, it, conv, d, bound = _lbp_pairs_kernel(
        indptr, w, m, col_ptr, col_perm, A, B, tol, max_iter, certified
    )
    beta0 = np.empty(n)
    pair_beta = np.empty(rows.shape[0])
    if _beliefs(indptr, w, m, nu, beta0, pair_beta) >= 0:  # pragma: no cover - guarded
        # μ = inf only propagates "track i must take j", which holds in every feasible
        # event: a track losing every measurement proves the cluster infeasible
        raise InfeasibleAssignmentError(NO_FEASIBLE_EVENT)
    info = LBPInfo(int(it), bool(conv), float(d), float(bound) if certified else np.inf, certified)
    return beta0, pair_beta, info


def lbp_marginals(L, miss, *, tol: float = 1e-9, max_iter: int = 1000):
    """Approximate JPDA marginals by Williams & Lau (2014) loopy belief propagation.

    Message passing between track and measurement nodes (Williams & Lau eqs. for
    μ and ν, see the module docstring) on split-float messages (any weights in
    float64 range, none scaled or floored), with their contraction-mapping
    convergence guarantee and a certified stopping rule:
    iterate until the bound on the distance (max |Δ log ν|) from the fixed
    point is ≤ ``tol``. The same kernel as :func:`lbp_pair_marginals` on the
    gated pairs of ``L``, so both give the same β.

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
        N + M > :data:`DENSE_LBP_MAX` (use :func:`lbp_pair_marginals` on the
        gated pairs).
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
    if mm == 0 or not gated.any():
        beta[:, 0] = 1.0
        return beta, LBPInfo(0, True, 0.0, 0.0, bool(np.all(miss > 0)))
    if n + mm > DENSE_LBP_MAX:
        raise ExactLimitError(
            f"a dense cluster of {n} tracks and {mm} measurements is above the dense LBP's "
            f"limit (tracks + measurements ≤ {DENSE_LBP_MAX}: its sweeps are not capped by "
            "work); use lbp_pair_marginals on its gated pairs"
        )
    rows, cols = (a.astype(np.int64) for a in np.nonzero(gated))
    b0, bp, info = _lbp_pairs(rows, cols, L[rows, cols], miss, mm, tol, max_iter)
    beta[:, 0] = b0
    beta[rows, cols + 1] = bp
    return beta, info


def lbp_pair_marginals(
    rows, cols, L_values, miss, n_measurements: int, *, tol: float = 1e-9, max_iter: int = 1000
):
    """:func:`lbp_marginals` on the gated pairs of a cluster too large for an N × M matrix.

    The same Williams & Lau recursion on split-float messages, stopping rule
    and :class:`LBPInfo` — the same kernel, so the same β as
    :func:`lbp_marginals` — with one message pair per gated pair: memory
    O(N + M + P) and time O(sweeps · P) for P gated pairs, however large N · M.
    No weight is scaled or floored, so every cluster in float64 range is in
    range. Feasibility is checked first on the pairs (the one feasibility test,
    :func:`jointtrack.assignment.feasibility.is_feasible_pairs`).

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
        no joint event has positive weight (e.g. a ``miss = 0`` track without
        a gated pair, or more ``miss = 0`` tracks than the measurements they gate).
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
    if not is_feasible_pairs(r, c, miss, mm):
        raise InfeasibleAssignmentError(NO_FEASIBLE_EVENT)
    if r.size == 0:
        return beta0, pair_beta, LBPInfo(0, True, 0.0, 0.0, bool(np.all(miss > 0)))
    b0, bp, info = _lbp_pairs(r, c, w, miss, mm, tol, max_iter)
    beta0[:] = b0
    pair_beta[gated] = bp
    return beta0, pair_beta, info
