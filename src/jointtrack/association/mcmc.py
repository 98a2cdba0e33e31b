"""JPDA marginals by Markov chain Monte Carlo data association (MCMCDA).

S. Oh, S. Russell and S. Sastry, "Markov chain Monte Carlo data association for
multi-target tracking", IEEE Trans. Automatic Control 54(3):481–497, 2009 —
the single-scan MCMCDA sampler for JPDA with a fixed set of tracks (their
Algorithm "MCMC data association for JPDA", after Jerrum & Sinclair's chain on
bipartite matchings).

State: a joint association event ω, i.e. a matching in the bipartite gating
graph (gated pairs (i, j) with L_ij > 0). Target density

    π(ω) ∝ Π_{(i,j)∈ω} L_ij · Π_{i unmatched} miss_i        (Bojilov eq. (7))

Move: choose a gated edge e = (i, j) uniformly at random, then

* e ∈ ω                      → delete e;
* i and j both free          → add e;
* exactly one of i, j covered by an edge e' ∈ ω (the other free)
                             → swap: ω − e' + e;
* both covered by other edges → stay.

Each move is proposed with probability 1/|E| and its reverse move (same e for
add/delete; e' for a swap, which then has exactly one covered end) with the
same probability, so the proposal is symmetric and the Metropolis acceptance
min(1, π(ω')/π(ω)) gives detailed balance with respect to π. Every event can
reach the empty event by deletions and back by additions, so the chain is
irreducible on the feasible events (when all miss_i > 0). Oh et al. add a lazy
half-step for aperiodicity, which matters for mixing-time bounds but not for
the ergodic averages used here; it is omitted (it would halve the efficiency).

Certainly detected tracks (miss_i = 0) make the empty event infeasible and can
disconnect the feasible events under these moves. The chain is then run with
miss_i replaced by ε_i = ¼ min_j {L_ij > 0} and only the states in which every
such track is matched are averaged: conditioned on that event, π_ε equals π, so
the estimate stays consistent.

Marginals are the fraction of post-burn-in steps in which track i holds
measurement j (column 0: holds none). The Monte Carlo error decays like
n_samples^{-1/2}; measured here on 20 dense random 5×10 clusters
(L = 5·U[0,1], miss = 0.1) the maximum absolute marginal error is 0.10 on
average at 2·10³ steps, 0.045 (worst 0.074) at 10⁴ steps and 0.010 (worst
0.014) at 2·10⁵ steps; 2·10⁵ steps take ≈ 5 ms (also at 20×40).
"""

from __future__ import annotations

import numba
import numpy as np

from jointtrack.association._validate import check_cluster, check_integer, require_feasible_event

__all__ = ["mcmc_marginals"]

_CHUNK = 1 << 16


@numba.njit(cache=True)
def _mcmc_chunk(ei, ej, logW, logm, required, edge, logu, at, am, counts, record, state):
    """Run len(edge) MCMCDA steps in place.

    at[i] = measurement of track i or −1; am[j] = track of measurement j or −1;
    state[0] = number of required (miss = 0) tracks currently unmatched;
    state[1] = number of recorded steps in which state[0] == 0.
    """
    n = at.shape[0]
    for s in range(edge.shape[0]):
        e = edge[s]
        i = ei[e]
        j = ej[e]
        ti = at[i]
        mj = am[j]
        if ti == j:  # delete (i, j)
            if logu[s] < logm[i] - logW[i, j]:
                at[i] = -1
                am[j] = -1
                if required[i]:
                    state[0] += 1
        elif ti < 0 and mj < 0:  # add (i, j)
            if logu[s] < logW[i, j] - logm[i]:
                at[i] = j
                am[j] = i
                if required[i]:
                    state[0] -= 1
        elif ti >= 0 and mj < 0:  # track i moves from ti to the free j
            if logu[s] < logW[i, j] - logW[i, ti]:
                am[ti] = -1
                at[i] = j
                am[j] = i
        elif ti < 0 and mj >= 0:  # measurement j moves from track mj to the free track i
            if logu[s] < logW[i, j] + logm[mj] - logW[mj, j] - logm[i]:
                at[mj] = -1
                at[i] = j
                am[j] = i
                if required[mj]:
                    state[0] += 1
                if required[i]:
                    state[0] -= 1
        # else: both ends covered by other edges → stay
        if record and state[0] == 0:
            state[1] += 1
            for t in range(n):
                counts[t, at[t] + 1] += 1.0


def mcmc_marginals(L, miss, *, n_samples: int = 10_000, burn_in: int | None = None, rng=None):
    """Approximate JPDA marginals with the MCMCDA sampler of Oh, Russell & Sastry (2009).

    Add / delete / swap moves on the gated-edge matching with Metropolis
    acceptance (see the module docstring for the detailed-balance and
    irreducibility argument), run in a numba kernel on random numbers drawn
    from a NumPy Generator, so results are reproducible for a fixed seed.

    Parameters
    ----------
    L : (N, M) likelihood ratios, 0 = not gated
    miss : (N,) miss weights 1 − P_D P_G
    n_samples : int ≥ 1
        chain steps averaged after burn-in.
    burn_in : int ≥ 0, default ``n_samples // 10``
        steps discarded first (the chain starts at the event "no detections",
        or, with certainly detected tracks, at that event under π_ε).
    rng : numpy.random.Generator, int seed or None

    Returns
    -------
    beta : (N, M+1) array, column 0 = no measurement, rows sum to 1

    Raises
    ------
    ValueError
        bad input, ``n_samples`` < 1, ``burn_in`` < 0, or (only possible with
        certainly detected tracks) no recorded step had them all matched.
    InfeasibleAssignmentError
        no joint event has positive weight.
    """
    L, miss = check_cluster(L, miss)
    n_samples = check_integer(n_samples, "n_samples")
    if burn_in is None:
        burn_in = n_samples // 10
    burn_in = check_integer(burn_in, "burn_in", 0)
    rng = np.random.default_rng(rng)
    require_feasible_event(L, miss)
    n, m = L.shape
    beta = np.zeros((n, m + 1))
    ei, ej = np.nonzero(L > 0)
    if n == 0:
        return beta
    if ei.size == 0:
        beta[:, 0] = 1.0
        return beta
    required = miss == 0
    # row scaling: the event weight changes by a common factor only
    scale = np.maximum(miss, L.max(axis=1))
    gated = L > 0
    with np.errstate(divide="ignore"):
        logW = np.where(gated, np.log(np.where(gated, L, 1.0) / scale[:, None]), -np.inf)
        eps = 0.25 * np.where(gated, L, np.inf).min(axis=1)
        mw = np.where(required, eps, miss) / scale
        logm = np.log(mw)
    ei = ei.astype(np.int64)
    ej = ej.astype(np.int64)
    at = np.full(n, -1, dtype=np.int64)
    am = np.full(m, -1, dtype=np.int64)
    counts = np.zeros((n, m + 1))
    state = np.array([int(required.sum()), 0], dtype=np.int64)
    for total, record in ((burn_in, False), (n_samples, True)):
        done = 0
        while done < total:
            k = min(_CHUNK, total - done)
            edge = rng.integers(0, ei.size, size=k)
            with np.errstate(divide="ignore"):
                logu = np.log(rng.random(k))
            _mcmc_chunk(ei, ej, logW, logm, required, edge, logu, at, am, counts, record, state)
            done += k
    if state[1] == 0:
        raise ValueError(
            "no recorded MCMC step had every certainly detected track (miss = 0) matched; "
            "increase n_samples or use method='exact'"
        )
    return counts / counts.sum(axis=1, keepdims=True)
