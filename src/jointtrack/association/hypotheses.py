"""Bojilov's feasible-hypothesis generation with incremental probability products.

Bojilov, Alexiev & Konstantinova, *One particular program realisation of JPDA*,
section 3. Each target is a *group* (Table 1): option 0 ("no measurement",
multiplier ``β(1 − P_D)``) and one option per measurement in its gate
(multiplier ``P_D g_ij``). A feasible joint hypothesis picks one option per
group with no measurement used twice; its probability is the product (7) of the
picked multipliers, normalised by (6); the association probability p_ij sums
the hypotheses containing (i, j).

With the DESIGN.md convention the multipliers are ``miss[i]`` and ``L[i, j]``:
Table 1's entries divided by β. That *is* (7) with its common factor removed —
``β^{N_M − N_T}`` outside the bracket and one β per target inside, i.e.
``β^{N_M}`` overall, the same in every hypothesis, so it cancels in (6).

The generator works as the paper describes: depth-first over the groups, tracks
ordered by increasing group size ``n_i`` (which minimises M'), the partial
product of the outer levels kept so that every new hypothesis costs ONE
multiplication; the count of multiplications is then exactly

    M' = n1·n2·(1 + n3·(1 + … n_{N−1}·(1 + n_N)…))

when every combination is feasible, against ``M = n1·…·nN·(N − 1)`` for the
naive variant that recomputes each hypothesis product from scratch (both are
counted, so Tables 2 and 3 can be reproduced).

Numerics (split floats): every multiplier is carried as a mantissa in
[0.5, 1) and an integer power-of-two exponent, and each group's exponents are
shifted so that the most probable hypothesis (found by one assignment solve,
:func:`~jointtrack.assignment.linear_assignment`) has every multiplier in
[0.5, 1) — a factor common to all hypotheses, cancelled by (6). A partial
product is the product of the mantissas (the one counted multiplication) with
the exponents added alongside (integer additions, not multiplications); a
mantissa product below 2^-500 is renormalised (a comparison). No multiplier or
partial product can over/underflow whatever the scale of ``L`` and ``miss``
(subnormal miss weights, likelihood ratios near the float64 limit), every
hypothesis then weighs ≤ 1 and the best ≥ 2^-N, so the sums of (6) are plain
float sums with nothing that matters lost.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numba
import numpy as np

from jointtrack.association._validate import check_cluster
from jointtrack.errors import InfeasibleAssignmentError

__all__ = [
    "DEFAULT_MAX_HYPOTHESES",
    "EnumerationResult",
    "bojilov_multiplication_counts",
    "count_hypotheses",
    "enumerate_jpda",
    "enumerate_marginals",
    "iter_hypotheses",
]

DEFAULT_MAX_HYPOTHESES = 1_000_000
_LO = 2.0**-500


@dataclass(frozen=True)
class EnumerationResult:
    """Result of :func:`enumerate_jpda`.

    Attributes
    ----------
    beta : ndarray (N, M+1)
        Association probabilities p_ij (column 0: no measurement).
    n_hypotheses : int
        Feasible joint hypotheses generated (those with non-zero probability).
    n_multiplications : int
        Multiplications spent on hypothesis products (M' for the incremental
        scheme, (N−1) per hypothesis for the naive one).
    n_additions : int
        Additions spent accumulating p_ij sums and the normaliser of (6).
    track_order : ndarray (N,)
        Order of the depth-first levels (original track indices).
    group_sizes : ndarray (N,)
        n_i of each level, in ``track_order``: options with non-zero multiplier
        (``miss > 0`` counts as one, plus the gated measurements).
    naive : bool
        True for the product-recomputed variant.
    log_normalizer : float
        Natural log of Σ_H P'(H) with the (7) weights.
    """

    beta: np.ndarray
    n_hypotheses: int
    n_multiplications: int
    n_additions: int
    track_order: np.ndarray
    group_sizes: np.ndarray
    naive: bool
    log_normalizer: float


def bojilov_multiplication_counts(group_sizes) -> tuple[int, int]:
    """Bojilov's closed forms for N groups of sizes n_1..n_N, all combinations feasible.

    Returns ``(M, M')`` with ``M = n1·…·nN·(N−1)`` (naive) and
    ``M' = n1·n2·(1 + n3·(1 + … n_{N−1}·(1 + n_N)…))`` (incremental), section 3
    of the paper, in the order given.
    """
    n = [int(x) for x in group_sizes]
    N = len(n)
    if N == 0:
        return 0, 0
    naive = math.prod(n) * (N - 1)
    if N == 1:
        return naive, 0
    inner = 1
    for k in range(N - 1, 1, -1):
        inner = 1 + n[k] * inner
    incremental = n[0] * n[1] * inner
    return naive, incremental


def count_hypotheses(L, miss) -> float:
    """Number of feasible joint hypotheses with non-zero probability (Bojilov section 2).

    Computed without enumeration, as the normaliser of (6) for 0/1 weights
    (``L > 0``, ``miss > 0``) by the exact subset DP. The value is a float: an
    integer exactly for counts below ~1e12, relative error ~1e-14 above. On
    full gating it equals Σ_k C(N,k)·C(M,k)·k!.
    """
    from jointtrack.association.exact import exact_log_normalizer

    L, miss = check_cluster(L, miss)
    if L.shape[0] == 0:
        return 1.0
    try:
        lc = exact_log_normalizer((L > 0).astype(float), (miss > 0).astype(float))
    except InfeasibleAssignmentError:
        return 0.0
    c = math.exp(lc) if lc < 709.0 else math.inf
    return float(round(c)) if c < 2.0**52 else c


def _levels(L, miss, order="gate_count"):
    """Depth-first levels: track order, group sizes, option pointers, measurements, multipliers.

    ``order="gate_count"`` sorts tracks by increasing group size (ties keep the
    input order), which minimises M'; ``"given"`` keeps the input order.
    """
    N, M = L.shape
    gated = L > 0
    sizes = gated.sum(axis=1) + (miss > 0)
    if order == "gate_count":
        order = np.argsort(sizes, kind="stable")
    elif order == "given":
        order = np.arange(N)
    else:
        raise ValueError(f"order must be 'gate_count' or 'given', got {order!r}")
    ptr = np.zeros(N + 1, np.int64)
    meas = []
    mult = []
    for k, i in enumerate(order):
        if miss[i] > 0:
            meas.append(-1)
            mult.append(miss[i])
        for j in np.flatnonzero(gated[i]):
            meas.append(j)
            mult.append(L[i, j])
        ptr[k + 1] = len(meas)
    return (
        order,
        sizes[order].astype(np.int64),
        ptr,
        np.array(meas, np.int64),
        np.array(mult, np.float64),
    )


def _best_scales(L, miss, order, ptr, meas, mult):
    """Split multipliers ``(mantissa, exponent)`` scaled so the best hypothesis is ≈ 1 per level.

    Every multiplier is carried as a mantissa in [0.5, 1) and an integer power-of-two
    exponent (:func:`numpy.frexp`), so neither a subnormal miss weight nor a huge
    likelihood ratio can over/underflow. Each level's exponents are shifted by the
    power of two that brings the option picked by the most probable hypothesis (an
    assignment solve on −log weights, :func:`~jointtrack.assignment.linear_assignment`)
    to [0.5, 1): a factor common to every hypothesis, cancelled by (6), after which
    every hypothesis weighs ≤ 1 and the best one ≥ 2^-N.

    Returns ``(mantissas, exponents, shift)`` with ``shift`` the total exponent added.
    """
    from jointtrack.assignment import linear_assignment

    N, M = L.shape
    with np.errstate(divide="ignore"):
        cost = np.full((N, M + N), np.inf)
        cost[:, :M] = np.where(L > 0, -np.log(np.where(L > 0, L, 1.0)), np.inf)
        cost[np.arange(N), M + np.arange(N)] = np.where(
            miss > 0, -np.log(np.where(miss > 0, miss, 1.0)), np.inf
        )
    try:
        best = linear_assignment(cost)
    except InfeasibleAssignmentError:
        raise InfeasibleAssignmentError(
            "no feasible joint hypothesis: tracks with miss = 0 (certainly detected) cannot "
            "all be given distinct gated measurements"
        ) from None
    pick = np.empty(N)
    for r, c in zip(best.rows, best.cols, strict=True):
        pick[r] = L[r, c] if c < M else miss[r]
    k = -np.frexp(pick[order])[1].astype(np.int64)
    mant, expo = np.frexp(mult)
    expo = expo.astype(np.int64)
    for lev in range(N):
        expo[ptr[lev] : ptr[lev + 1]] += k[lev]
    return np.ascontiguousarray(mant), expo, int(k.sum())


@numba.njit(cache=True)
def _dfs(ptr, meas, mant, expo, M, naive, shift):
    """Depth-first generation on split multipliers ``mant · 2^expo``.

    Partial products are a mantissa product (the one counted multiplication per
    hypothesis) with the exponents added alongside (integer additions, not
    counted), so no partial product over/underflows. Each hypothesis adds
    ``p · 2^(x + shift)`` to the sums. Returns ``(acc per option, Z, counts, xmax)``
    with ``xmax`` the largest ``x`` of a hypothesis (for the caller's range check).
    """
    N = ptr.size - 1
    nopt = meas.size
    acc = np.zeros(nopt)
    P = np.empty(N + 1)
    X = np.zeros(N + 1, np.int64)
    P[0] = 1.0
    idx = np.empty(N, np.int64)
    used = np.zeros(max(M, 1), np.bool_)
    Z = 0.0
    nhyp = 0
    nmul = 0
    nadd = 0
    xmax = np.iinfo(np.int64).min
    k = 0
    idx[0] = ptr[0] - 1
    while k >= 0:
        o = idx[k]
        if o >= ptr[k]:
            m = meas[o]
            if m >= 0:
                used[m] = False
        o += 1
        while o < ptr[k + 1] and meas[o] >= 0 and used[meas[o]]:
            o += 1
        if o >= ptr[k + 1]:
            k -= 1
            continue
        idx[k] = o
        if meas[o] >= 0:
            used[meas[o]] = True
        if not naive:
            if k == 0:
                P[1] = mant[o]
                X[1] = expo[o]
            else:
                p = P[k] * mant[o]
                nmul += 1
                x = X[k] + expo[o]
                if p < _LO:
                    f, e = math.frexp(p)
                    p = f
                    x += e
                P[k + 1] = p
                X[k + 1] = x
        if k == N - 1:
            nhyp += 1
            if naive:
                p = mant[idx[0]]
                x = expo[idx[0]]
                for lev in range(1, N):
                    p *= mant[idx[lev]]
                    x += expo[idx[lev]]
                    nmul += 1
                    if p < _LO:
                        f, e = math.frexp(p)
                        p = f
                        x += e
            else:
                p = P[N]
                x = X[N]
            if x > xmax:
                xmax = x
            x += shift
            if x != 0:
                p = math.ldexp(p, x) if x > -1100 else 0.0
            Z += p
            for lev in range(N):
                acc[idx[lev]] += p
            nadd += N + 1
        else:
            k += 1
            idx[k] = ptr[k] - 1
    return acc, Z, nhyp, nmul, nadd, xmax


def _check_limit(L, miss, sizes, max_hypotheses):
    """Refuse before enumerating when the cluster has more than ``max_hypotheses``.

    Cheap bounds first: Π n_i above (all combinations feasible); 2^m below when
    every track may miss (m = a greedy matching's size: each matched track may
    independently take its partner or nothing). Only in between is the exact
    count computed, by the subset DP of :func:`count_hypotheses`.
    """
    if max_hypotheses is None:
        return
    bound = math.prod(int(s) for s in sizes)
    if bound <= max_hypotheses:
        return
    count = None
    if np.all(miss > 0):
        taken = np.zeros(L.shape[1], bool)
        m = 0
        for i in range(L.shape[0]):
            free = np.flatnonzero((L[i] > 0) & ~taken)
            if free.size:
                taken[free[0]] = True
                m += 1
        if 2.0**m > max_hypotheses:
            count = f"at least 2^{m} = {2.0**m:.4g}"
    if count is None:
        try:
            c = count_hypotheses(L, miss)
        except ValueError:  # too large even for the exact DP count
            c = math.inf
        if c <= max_hypotheses:
            return
        count = f"{c:.4g}" if math.isfinite(c) else f"more than {max_hypotheses}"
    raise ValueError(
        f"this cluster has {count} feasible joint hypotheses, above max_hypotheses="
        f"{max_hypotheses}; enumeration would not finish in reasonable time. Use "
        "marginals(L, miss, method='exact') (same probabilities, no enumeration) or raise "
        "max_hypotheses"
    )


def enumerate_jpda(
    L,
    miss,
    *,
    naive: bool = False,
    max_hypotheses: int | None = DEFAULT_MAX_HYPOTHESES,
    order: str = "gate_count",
) -> EnumerationResult:
    """JPDA by Bojilov's feasible-hypothesis enumeration, with operation counts.

    Implements section 3 of the paper: hypotheses (5)/(7) generated depth-first
    over targets ordered by increasing gate count, probability computed during
    generation with the partial product of the outer levels kept (``naive=False``:
    one multiplication per new hypothesis) or recomputed per hypothesis
    (``naive=True``: N−1 multiplications each), normalised by (6), summed into
    ``p_ij = Σ_{l ∈ L_j} P(H_l)``.

    Parameters
    ----------
    L, miss
        Cluster in the DESIGN.md convention (``L`` N×M likelihood ratios, 0 = not
        gated; ``miss`` = 1 − P_D·P_G).
    naive
        Use the product-recomputing variant (for Table 2's comparison).
    max_hypotheses
        Refuse clusters with more feasible hypotheses than this (counted first,
        without enumerating); ``None`` = no limit.
    order
        ``"gate_count"`` (default): levels by increasing group size, as the paper
        recommends; ``"given"``: the input track order (e.g. Table 1's listing).

    Raises
    ------
    ValueError
        bad input, or too many hypotheses (the message names ``method='exact'``).
    InfeasibleAssignmentError
        no feasible joint hypothesis.
    """
    L, miss = check_cluster(L, miss)
    N, M = L.shape
    if N == 0:
        return EnumerationResult(
            np.zeros((0, M + 1)), 1, 0, 0, np.zeros(0, np.int64), np.zeros(0, np.int64), naive, 0.0
        )
    order, sizes, ptr, meas, mult = _levels(L, miss, order)
    _check_limit(L, miss, sizes, max_hypotheses)
    mant, expo, kshift = _best_scales(L, miss, order, ptr, meas, mult)
    shift = 0
    acc, Z, nhyp, nmul, nadd, xmax = _dfs(ptr, meas, mant, expo, M, naive, shift)
    if nhyp == 0:  # pragma: no cover - the assignment solve found a feasible hypothesis
        raise InfeasibleAssignmentError("no feasible joint hypothesis in this cluster")
    if not (0.0 < Z < math.inf) or xmax > 900:
        # the best-hypothesis scaling should keep every hypothesis ≤ 1; should the
        # assignment solve have missed the optimum (rounding), re-reference the sums
        # to the largest hypothesis found instead
        shift = -int(xmax)
        acc, Z, nhyp, nmul, nadd, xmax = _dfs(ptr, meas, mant, expo, M, naive, shift)
    if not Z > 0:  # pragma: no cover - the best hypothesis alone weighs ≥ 2^-N
        raise InfeasibleAssignmentError("no feasible joint hypothesis in this cluster")
    beta = np.zeros((N, M + 1))
    for lev, i in enumerate(order):
        for o in range(ptr[lev], ptr[lev + 1]):
            beta[i, meas[o] + 1] = acc[o] / Z
    beta /= beta.sum(axis=1, keepdims=True)
    logZ = math.log(Z) - (kshift + shift) * math.log(2.0)
    return EnumerationResult(
        beta,
        int(nhyp),
        int(nmul),
        int(nadd),
        order.astype(np.int64),
        sizes,
        bool(naive),
        float(logZ),
    )


def enumerate_marginals(
    L,
    miss,
    *,
    naive: bool = False,
    stats: bool = False,
    max_hypotheses: int | None = DEFAULT_MAX_HYPOTHESES,
    order: str = "gate_count",
):
    """JPDA marginals by Bojilov's enumeration (eqs. (5)–(7), section 3).

    Returns ``beta`` (N × (M+1)), or the full :class:`EnumerationResult`
    (hypothesis and multiplication counts) when ``stats=True``. See
    :func:`enumerate_jpda` for the parameters.
    """
    res = enumerate_jpda(L, miss, naive=naive, max_hypotheses=max_hypotheses, order=order)
    return res if stats else res.beta


def iter_hypotheses(
    L, miss, *, max_hypotheses: int | None = DEFAULT_MAX_HYPOTHESES, order: str = "gate_count"
) -> Iterator[tuple[np.ndarray, float]]:
    """Yield every feasible joint hypothesis with its probability P(H) of eq. (6).

    Hypotheses come in Bojilov's depth-first order (targets by increasing gate
    count, or the input order with ``order="given"``; options as in Table 1:
    0 first, then gated measurements ascending).
    Each is ``(a, p)`` with ``a[i]`` the beta column of track i (0 = no
    measurement, j+1 = measurement j) in the original track order, and ``p``
    computed in log space from the (7) weights and the exact normaliser.
    """
    from jointtrack.association.exact import exact_log_normalizer

    L, miss = check_cluster(L, miss)
    N, M = L.shape
    if N == 0:
        yield np.zeros(0, np.int64), 1.0
        return
    order, sizes, ptr, meas, mult = _levels(L, miss, order)
    _check_limit(L, miss, sizes, max_hypotheses)
    logZ = exact_log_normalizer(L, miss)
    logm = np.log(mult)
    a = np.zeros(N, np.int64)
    used = np.zeros(M, bool)

    def rec(lev, logw):
        if lev == N:
            yield a.copy(), math.exp(logw - logZ)
            return
        i = order[lev]
        for o in range(ptr[lev], ptr[lev + 1]):
            j = meas[o]
            if j >= 0:
                if used[j]:
                    continue
                used[j] = True
            a[i] = j + 1
            yield from rec(lev + 1, logw + logm[o])
            if j >= 0:
                used[j] = False

    yield from rec(0, 0.0)
