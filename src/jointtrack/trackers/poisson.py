"""Gaussian mixtures of the PMB/PMBM filters: moment matching, pruning and merging.

The Poisson intensity of undetected targets is a Gaussian mixture (weights,
means, covariances) and, with the uniform birth model, one more term of
constant density per unit area; a Bernoulli's density after association is a
mixture to be collapsed to one Gaussian. These are the mixture operations both
need (B.-N. Vo and W.-K. Ma, "The Gaussian mixture probability hypothesis
density filter", *IEEE Transactions on Signal Processing* 54(11), 2006,
Table II for pruning and merging).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["moment_match", "prune_and_merge"]


def moment_match(weights, group, x, P, n_groups: int):
    """Collapse the components of each group to one Gaussian (same mean and covariance).

    ``weights`` (K,) ≥ 0, ``group`` (K,) in [0, n_groups), ``x`` (K, n),
    ``P`` (K, n, n). Returns ``(total, mean, cov)``: per group the summed
    weight (G,), and the mixture's mean (G, n) and covariance (G, n, n)
    (spread of the means included). Groups with zero total weight get the
    unweighted mean of their components (or zeros if they have none).
    """
    n = x.shape[1]
    total = np.bincount(group, weights, minlength=n_groups)
    safe = np.where(total > 0, total, 1.0)
    # weights relative to their group's total; empty-weight groups: equal weights
    count = np.bincount(group, minlength=n_groups)
    rel = np.where(total[group] > 0, weights / safe[group], 1.0 / np.maximum(count[group], 1))
    mean = np.zeros((n_groups, n))
    np.add.at(mean, group, rel[:, None] * x)
    d = x - mean[group]
    cov = np.zeros((n_groups, n, n))
    np.add.at(cov, group, rel[:, None, None] * (P + d[:, :, None] * d[:, None, :]))
    cov = 0.5 * (cov + cov.transpose(0, 2, 1))
    return total, mean, cov


def prune_and_merge(w, m, P, *, prune: float, merge: float, cap: int):
    """Drop components lighter than ``prune``, merge near ones, keep the ``cap`` heaviest.

    Greedy merging (Vo & Ma 2006, Table II): the heaviest remaining component
    absorbs every component within squared Mahalanobis distance ``merge`` of
    it, measured in that component's own covariance, by moment matching;
    ``merge = 0`` never merges.
    Returns ``(w, m, P)``.
    """
    keep = w >= prune if prune > 0 else w > 0
    w, m, P = w[keep], m[keep], P[keep]
    if merge > 0 and len(w) > 1:
        order = np.argsort(-w, kind="stable")
        # each component's inverse once: every round measures the remaining ones in
        # their own covariance (below), and the first round inverts all of them anyway
        with np.errstate(over="ignore"):
            inv = np.linalg.inv(P)
        group, g = _greedy_groups(
            order.astype(np.int64), np.ascontiguousarray(m, float), inv, float(merge)
        )
        w, m, P = moment_match(w, group, m, P, g)
    if len(w) > cap:
        top = np.argsort(-w, kind="stable")[:cap]
        w, m, P = w[top], m[top], P[top]
    return w, m, P


@njit(cache=True)
def _greedy_groups(order, m, inv, merge):
    """:func:`prune_and_merge`'s greedy rounds: ``(group of each component, groups)``.

    Round after round the heaviest component not yet grouped (first in ``order``)
    leads a group of every ungrouped component i with
    (m_i − m_lead)ᵀ inv_i (m_i − m_lead) ≤ ``merge`` — in each candidate's own
    covariance (Vo & Ma Table II: in the lead's, a heavy broad prior would absorb
    every sharp component within its 2σ, a recycled track's evidence 150 m broad on
    the coalescence scene). The lead is in its own group whatever its covariance
    (0 · inf is NaN: a loop that never ends), and so is a component at its mean.
    Compiled: the rounds were a Python loop of numpy calls each, half of PMB's step
    on the ``many`` scene (≈ 150 components, ≈ 150 rounds a scan; issue 34).
    """
    n, k = m.shape
    group = np.full(n, -1, np.int64)
    d = np.empty(k)
    g = 0
    for a in range(n):
        lead = order[a]
        if group[lead] >= 0:
            continue
        for b in range(a, n):
            i = order[b]
            if group[i] >= 0:
                continue
            moved = False
            for p in range(k):
                d[p] = m[i, p] - m[lead, p]
                moved = moved or d[p] != 0.0
            d2 = 0.0
            for p in range(k):
                row = 0.0
                for q in range(k):
                    row += inv[i, p, q] * d[q]
                d2 += d[p] * row
            if d2 <= merge or not moved:
                group[i] = g
        g += 1
    return group, g
