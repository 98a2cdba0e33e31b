r"""Power-of-two scaling from the dual of the best assignment: every problem in range.

A row or column scaling multiplies every assignment's weight by the same factor,
so the marginals are unchanged and the log of the removed scale is added back to
the log normaliser. The scale factors come from the optimal dual of the
max-weight assignment (:mod:`jointtrack.assignment.lsap`), with the problem
embedded in an (R+C)×(C+R) assignment problem (row r ↔ col c; row r ↔ its own
"null" dummy; col c ↔ its "unused" dummy; dummy ↔ dummy where (r, c) is allowed).
Writing α_r, γ_c for the log scales, dual feasibility gives

.. math::

    \log W_{rc} \le \alpha_r + \gamma_c, \qquad
    \log u_r \le \alpha_r, \qquad \log v_c \le \gamma_c,

with equality along the best assignment: after rounding α, γ to multiples of
log 2 (so applying them is exact in floating point) every factor is ≤ ~1 and the
best assignment weighs ≈ 1. Every assignment that matters (≥ 1e-300 of the best)
then has all partial products ≥ ~1e-300 — no underflow anywhere in a DP, for any
scale of the input (a DP merely normalised per layer by its maximum loses such
paths).

Repeated rows/columns: the constraints above are symmetric under permuting the
members of a group and the dual objective is linear, so averaging an optimal
dual over each group gives an optimal dual that is constant on groups
(:func:`group_exponents`); the group-count DP needs exactly that.

:func:`scaled_block` extracts one connected component (after leaf folding) and
scales it; :func:`scatter_block` writes a block's marginals back.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from jointtrack.assignment.lsap import _shortest_augmenting_paths

_LN2 = math.log(2.0)
#: Largest expanded problem (rows + columns) whose group dual is computed by one
#: assignment solve on the expansion; the solve is O((R+C)^3) at worst.
GROUP_SCALING_MAX = 4000


@numba.njit(cache=True)
def _dual_scale(lw, lu, lv):
    """Row/column log scale factors (α, γ) making every factor ≤ 1 and the best event = 1.

    The association problem is embedded in an (R+C)×(C+R) assignment problem
    (row r ↔ col c, row r ↔ its own "unassigned" dummy, col c ↔ its dummy, dummy ↔
    dummy where (r, c) is gated); its optimal dual gives the scales. Returns
    ``(alpha, gamma, log_best, ok)``.
    """
    R, C = lw.shape
    n = R + C
    cost = np.full((n, n), np.inf)
    for r in range(R):
        for c in range(C):
            if lw[r, c] > -np.inf:
                cost[r, c] = -lw[r, c]
                cost[R + c, C + r] = 0.0
        if lu[r] > -np.inf:
            cost[r, C + r] = -lu[r]
    for c in range(C):
        if lv[c] > -np.inf:
            cost[R + c, c] = -lv[c]
    _, u, v, ok = _shortest_augmenting_paths(cost)
    alpha = np.empty(R)
    gamma = np.empty(C)
    for r in range(R):
        alpha[r] = u[r] + v[C + r]
    for c in range(C):
        gamma[c] = v[c] + u[R + c]
    return alpha, gamma, -(u.sum() + v.sum()), ok


@numba.njit(cache=True)
def scaled_block(k, lab_r, lab_c, E, Wm, We, um, ue, vm, ve):
    """Extract block k, dual-scale it by exact powers of two.

    Returns (rows, cols, W, u, v, shift, ok): every scaled factor ≤ ~1, the best
    event ≈ 1, ``shift`` = log of the scale removed (add back to log Z).
    """
    rows = np.flatnonzero(lab_r == k)
    cols = np.flatnonzero(lab_c == k)
    R = rows.size
    C = cols.size
    ln2 = math.log(2.0)
    lw = np.full((R, C), -np.inf)
    lu = np.full(R, -np.inf)
    lv = np.full(C, -np.inf)
    for a in range(R):
        r = rows[a]
        if um[r] > 0:
            lu[a] = math.log(um[r]) + ue[r] * ln2
        for b in range(C):
            c = cols[b]
            if E[r, c] and Wm[r, c] > 0:
                lw[a, b] = math.log(Wm[r, c]) + We[r, c] * ln2
    for b in range(C):
        c = cols[b]
        if vm[c] > 0:
            lv[b] = math.log(vm[c]) + ve[c] * ln2
    alpha, gamma, _, ok = _dual_scale(lw, lu, lv)
    W = np.zeros((R, C))
    u = np.zeros(R)
    v = np.zeros(C)
    ka = np.empty(R, np.int64)
    kg = np.empty(C, np.int64)
    for a in range(R):
        ka[a] = np.int64(np.rint(alpha[a] / ln2)) if ok else 0
    for b in range(C):
        kg[b] = np.int64(np.rint(gamma[b] / ln2)) if ok else 0
    # exact power-of-two scales (a row/column scaling leaves the marginals unchanged)
    for a in range(R):
        r = rows[a]
        u[a] = math.ldexp(um[r], ue[r] + ka[a])
        for b in range(C):
            c = cols[b]
            if E[r, c]:
                W[a, b] = math.ldexp(Wm[r, c], We[r, c] + ka[a] + kg[b])
    for b in range(C):
        c = cols[b]
        v[b] = math.ldexp(vm[c], ve[c] + kg[b])
    shift = (ka.sum() + kg.sum()) * ln2
    return rows, cols, W, u, v, shift, ok


@numba.njit(cache=True)
def scatter_block(rows, cols, bu, bv, be, pu, pv, pe):
    for a in range(rows.size):
        pu[rows[a]] = bu[a]
        for b in range(cols.size):
            pe[rows[a], cols[b]] = be[a, b]
    for b in range(cols.size):
        pv[cols[b]] = bv[b]


def group_log_scales(lw, lu, row_counts, col_counts):
    """Natural-log scales (α per row group, γ per column group, ok) from log weights.

    ``lw`` (R, C) and ``lu`` (R,) are the logs of the compressed weights and
    null weights (−inf for 0). ``W·e^(α_p + γ_q)`` and ``null·e^(α_p)`` are
    then ≤ ~1, the column-unused weight e^(γ_q) too, and the best assignment
    ≈ 1. Computed on the expanded problem and averaged over each group (see the
    module docstring). ``ok`` is False when no assignment has positive weight.
    """
    R, C = int(row_counts.sum()), int(col_counts.sum())
    if R + C > GROUP_SCALING_MAX:
        raise ValueError(
            f"the expanded problem has {R} rows and {C} columns; its scaling needs an "
            f"assignment solve of size {R + C} > {GROUP_SCALING_MAX}"
        )
    ri = np.repeat(np.arange(lw.shape[0]), row_counts)
    ci = np.repeat(np.arange(lw.shape[1]), col_counts)
    alpha, gamma, _, ok = _dual_scale(
        np.ascontiguousarray(lw[np.ix_(ri, ci)]), np.ascontiguousarray(lu[ri]), np.zeros(C)
    )
    if not ok:
        return np.zeros(lw.shape[0]), np.zeros(lw.shape[1]), False
    a = np.bincount(ri, weights=alpha, minlength=lw.shape[0]) / row_counts
    g = np.bincount(ci, weights=gamma, minlength=lw.shape[1]) / col_counts
    return a, g, True


def group_exponents(W, null, row_counts, col_counts):
    """Integer power-of-two exponents (er per row group, ec per column group, ok).

    Scaled weights ``W[p, q]·2^(er_p + ec_q)``, null ``null[p]·2^er_p`` and unused
    column weight ``2^ec_q`` are all ≤ ~1 with the best assignment ≈ 1
    (:func:`group_log_scales` rounded to powers of two, so applying them is
    exact). ``ok`` is False when no assignment has positive weight.
    """
    with np.errstate(divide="ignore"):
        lw = np.log(W)
        lu = np.log(null)
    return group_log_exponents(lw, lu, row_counts, col_counts)


def group_log_exponents(lw, lu, row_counts, col_counts):
    """:func:`group_exponents` of weights given by their logarithms (−inf for 0)."""
    a, g, ok = group_log_scales(lw, lu, row_counts, col_counts)
    if not ok:
        return np.zeros(lw.shape[0], np.int64), np.zeros(lw.shape[1], np.int64), False
    return np.rint(a / _LN2).astype(np.int64), np.rint(g / _LN2).astype(np.int64), True


def from_log_weights(lw, lu, row_counts, col_counts):
    """Weights in float range from their logarithms: ``(W, null, log_shift, ok)``.

    For weights outside the float64 range (Schaub's a[t,i]: running products of
    hundreds of likelihoods). ``W = exp(lw + α + γ)``, ``null = exp(lu + α)``
    with the scales of :func:`group_log_scales`: every factor ≤ ~1 and the best
    assignment ≈ 1, so only entries below 1e-308 of the best assignment's
    factors flush to 0 — an assignment through them weighs < 1e-308 of the best
    and changes no marginal by more than that. The unused-column weight becomes
    ``e^γ``, not 1, so this is exact only where every column is used (a
    square permanent: ``log_shift`` then restores ``log Z = log Z' + log_shift``);
    ``ok`` is False when no assignment has positive weight.
    """
    a, g, ok = group_log_scales(lw, lu, row_counts, col_counts)
    if not ok:  # no assignment has positive weight: nothing to bring in range
        return np.zeros(lw.shape), np.zeros(lu.shape), 0.0, False
    with np.errstate(under="ignore"):
        W = np.exp(lw + a[:, None] + g[None, :])
        null = np.exp(lu + a)
    shift = -float(np.dot(row_counts, a) + np.dot(col_counts, g))
    return np.ascontiguousarray(W), null, shift, ok


def scale_problem(W, null):
    """Power-of-two scaled copy of a plain problem for the approximate methods.

    Returns ``(W', null', unused', log_shift, ok)``: ``W'[r, c] = W[r, c]·2^(er_r+ec_c)``,
    ``null'[r] = null[r]·2^er_r`` and the column-unused weights ``unused'[c] = 2^ec_c``
    (no longer 1), every factor ≤ ~1 and the best assignment ≈ 1, with
    ``log Z = log Z' − log_shift``. Marginals are unchanged by the scaling.
    ``ok`` is False when no assignment has positive weight.
    """
    W = np.asarray(W, np.float64)
    null = np.asarray(null, np.float64)
    R, C = W.shape
    er, ec, ok = group_exponents(W, null, np.ones(R, np.int64), np.ones(C, np.int64))
    Ws = np.ldexp(W, er[:, None] + ec[None, :])
    return Ws, np.ldexp(null, er), np.ldexp(1.0, ec), float(er.sum() + ec.sum()) * _LN2, ok
