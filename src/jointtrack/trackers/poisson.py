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
        order = list(np.argsort(-w, kind="stable"))
        group = np.full(len(w), -1)
        g = 0
        # each component's inverse once: every round measures the remaining ones in
        # their own covariance (below), and the first round inverts all of them anyway
        with np.errstate(over="ignore"):
            inv = np.linalg.inv(P)
        while order:
            lead = order[0]
            rest = np.array(order)
            d = m[rest] - m[lead]
            # in each candidate's own covariance (Vo & Ma Table II): in the lead's, a
            # heavy broad prior would absorb every sharp component within its 2σ (a
            # recycled track's evidence, 150 m broad on the coalescence scene)
            with np.errstate(invalid="ignore", over="ignore"):
                d2 = np.einsum("ki,kij,kj->k", d, inv[rest], d)
            # the lead is in its own group whatever its covariance (0 · inf is NaN: a
            # loop that never ends), and so is a component at its mean
            close = rest[(d2 <= merge) | ~d.any(axis=1)]
            group[close] = g
            g += 1
            taken = set(close.tolist())
            order = [i for i in order if i not in taken]
        w, m, P = moment_match(w, group, m, P, g)
    if len(w) > cap:
        top = np.argsort(-w, kind="stable")[:cap]
        w, m, P = w[top], m[top], P[top]
    return w, m, P
