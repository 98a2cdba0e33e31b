"""JPDA marginals by Markov chain Monte Carlo data association (MCMCDA).

S. Oh, S. Russell and S. Sastry, "Markov chain Monte Carlo data association for
multi-target tracking", IEEE Trans. Automatic Control 54(3):481–497, 2009 —
the single-scan MCMCDA sampler for JPDA with a fixed set of tracks (their
Algorithm "MCMC data association for JPDA", after Jerrum & Sinclair's chain on
bipartite matchings).

State: a joint association event ω, i.e. a matching in the bipartite gating
graph (gated pairs (i, j) with L_ij > 0). Target density

    π(ω) ∝ Π_{(i,j)∈ω} L_ij · Π_{i unmatched} miss_i        (Bojilov eq. (7))

Scaling (every feasible cluster in range): the chain runs on the exact
power-of-two row/column scaling of
:func:`jointtrack.assignment.scaling.scale_problem` (every factor ≤ ~1, the best
event ≈ 1, π unchanged), whose column scaling gives each measurement j left
unassigned a weight v_j instead of 1, so the target is used in its general form

    π(ω) ∝ Π_{(i,j)∈ω} L'_ij · Π_{i unmatched} miss'_i · Π_{j unmatched} v_j,

and the acceptance ratios below include the v_j of the measurements a move
frees or takes. Positive factors the scaling takes below 2^-400 are raised to
2^-400 (only events ≲ 2^-400 of the best change), so no log weight is −∞ and
no move between events that matter is blocked by an over/underflow.

Move: choose a gated edge e = (i, j) uniformly at random, then

* e ∈ ω                      → delete e;
* i and j both free          → add e;
* exactly one of i, j covered by an edge e' ∈ ω (the other free)
                             → swap: ω − e' + e;
* both covered by other edges, (i, t) and (k, j) ∈ ω, with (k, t) gated
                             → exchange: ω − (i, t) − (k, j) + (i, j) + (k, t);
* otherwise                  → stay.

Each move is proposed with probability 1/|E| and its reverse move (same e for
add/delete; e' for a swap, which then has exactly one covered end; (i, t) for
an exchange, which (k, j) and (k, t) also propose) with the same probability,
so the proposal is symmetric and the Metropolis acceptance
min(1, π(ω')/π(ω)) gives detailed balance with respect to π. Every event can
reach the empty event by deletions and back by additions, so the chain is
irreducible on the feasible events (when all miss_i > 0). Oh et al. add a lazy
half-step for aperiodicity, which matters for mixing-time bounds but not for
the ergodic averages used here; it is omitted (it would halve the efficiency).
The exchange move is an addition to Oh et al.'s moves: it lets two certainly
detected tracks trade measurements directly instead of through an event in
which one of them is unmatched, which can weigh next to nothing.

Certainly detected tracks (miss_i = 0) make the empty event infeasible and can
disconnect the feasible events under these moves. The chain is then run with
miss_i replaced by ε_i = ¼ max_j L'_ij (on the scaled problem, where a track's
best factor is ≈ 1, so a state with the track unmatched weighs about a quarter
of one with it matched) and only the states in which every such track is
matched are averaged: conditioned on that event, π_ε equals π, so the estimate
stays consistent. (ε_i from the smallest ratio instead could be negligible next
to the other tracks' weights and trap the chain in unrecorded states.)

Marginals are the fraction of post-burn-in steps in which track i holds
measurement j (column 0: holds none). The Monte Carlo error decays like
n_samples^{-1/2}; measured here on 20 dense random 5×10 clusters
(L = 5·U[0,1], miss = 0.1) the maximum absolute marginal error is 0.062 on
average (worst 0.083) at 2·10³ steps, 0.029 (worst 0.058) at 10⁴ steps and
0.0067 (worst 0.0097) at 2·10⁵ steps (with the exchange move and the start at
the most probable event; without them 0.10, 0.045 and 0.010); 2·10⁵ steps take
≈ 5–8 ms at 5×10 and ≈ 10–14 ms at 20×40 on a loaded machine.

Hostile clusters: on ~2500 random feasible clusters with N, M ≤ 4, ratios in
{0} ∪ [1e-320, 1e300] and miss in {0, 5e-324} ∪ [1e-300, 1] (``tests/
test_association_hostile``), 2·10³ steps always returned a valid beta; the
error was ≤ 0.02 on 90% of them, but a few (≈ 0.2%) are multimodal with
barriers of ~1e-300 between the modes that no local move crosses — MCMC is
then wrong however long it runs; use ``method='exact'``.
"""

from __future__ import annotations

import numba
import numpy as np

from jointtrack.assignment import linear_assignment
from jointtrack.assignment._checks import as_int, as_rng
from jointtrack.assignment.scaling import scale_problem
from jointtrack.association._validate import check_cluster, require_feasible_event

__all__ = ["mcmc_marginals"]

_CHUNK = 1 << 16
#: Positive factors are kept ≥ this after scaling (events below it are negligible).
_FLOOR = 2.0**-400


@numba.njit(cache=True)
def _mcmc_chunk(ei, ej, logW, logm, logv, required, edge, logu, at, am, counts, record, state):
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
            if logu[s] < logm[i] + logv[j] - logW[i, j]:
                at[i] = -1
                am[j] = -1
                if required[i]:
                    state[0] += 1
        elif ti < 0 and mj < 0:  # add (i, j)
            if logu[s] < logW[i, j] - logm[i] - logv[j]:
                at[i] = j
                am[j] = i
                if required[i]:
                    state[0] -= 1
        elif ti >= 0 and mj < 0:  # track i moves from ti to the free j
            if logu[s] < logW[i, j] + logv[ti] - logW[i, ti] - logv[j]:
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
        elif logW[mj, ti] > -np.inf:  # exchange: i takes j, track mj takes i's ti
            if logu[s] < logW[i, j] + logW[mj, ti] - logW[i, ti] - logW[mj, j]:
                at[i] = j
                am[j] = i
                at[mj] = ti
                am[ti] = mj
        # else: both ends covered by other edges, no exchange possible → stay
        if record and state[0] == 0:
            state[1] += 1
            for t in range(n):
                counts[t, at[t] + 1] += 1.0


def _map_event(L, miss):
    """The most probable joint event (the chain's start), by one assignment solve.

    Track i takes measurement j (cost −log L_ij) or nothing (its own dummy column,
    cost −log miss_i); logs of the raw weights, so any scale works. Returns
    ``(at, am)``: measurement of each track (−1 = none), track of each measurement.
    """
    n, m = L.shape
    cost = np.full((n, m + n), np.inf)
    with np.errstate(divide="ignore"):
        cost[:, :m] = np.where(L > 0, -np.log(np.where(L > 0, L, 1.0)), np.inf)
        cost[np.arange(n), m + np.arange(n)] = np.where(
            miss > 0, -np.log(np.where(miss > 0, miss, 1.0)), np.inf
        )
    best = linear_assignment(cost)
    at = np.full(n, -1, dtype=np.int64)
    am = np.full(m, -1, dtype=np.int64)
    for i, c in zip(best.rows, best.cols, strict=True):
        if c < m:
            at[i] = c
            am[c] = i
    return at, am


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
        chain steps averaged after burn-in (a whole number; not a bool).
    burn_in : int ≥ 0, default ``n_samples // 10``
        steps discarded first (the chain starts at the most probable event, found
        by one assignment solve, so every certainly detected track starts matched).
    rng : numpy.random.Generator, SeedSequence, non-negative int seed or None

    Returns
    -------
    beta : (N, M+1) array, column 0 = no measurement, rows sum to 1

    Raises
    ------
    ValueError
        bad input, ``n_samples`` < 1, ``burn_in`` < 0, a bad ``rng``, or (only possible with
        certainly detected tracks) no recorded step had them all matched.
    InfeasibleAssignmentError
        no joint event has positive weight.
    """
    L, miss = check_cluster(L, miss)
    n_samples = as_int(n_samples, "n_samples", minimum=1)
    burn_in = n_samples // 10 if burn_in is None else as_int(burn_in, "burn_in", minimum=0)
    rng = as_rng(rng)
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
    gated = L > 0
    W, mw, v, _shift, ok = scale_problem(L, miss)
    if not ok:  # pragma: no cover - feasibility was checked first
        W, mw, v = L.copy(), miss.copy(), np.ones(m)
    W = np.where(gated, np.maximum(W, _FLOOR), 0.0)
    eps = 0.25 * W.max(axis=1)
    mw = np.where(required, np.maximum(eps, _FLOOR), np.maximum(mw, _FLOOR))
    v = np.maximum(v, _FLOOR)
    with np.errstate(divide="ignore"):
        logW = np.log(W)
    logm = np.log(mw)
    logv = np.log(v)
    ei = ei.astype(np.int64)
    ej = ej.astype(np.int64)
    at, am = _map_event(L, miss)
    counts = np.zeros((n, m + 1))
    state = np.array([int(required[at < 0].sum()), 0], dtype=np.int64)
    for total, record in ((burn_in, False), (n_samples, True)):
        done = 0
        while done < total:
            k = min(_CHUNK, total - done)
            edge = rng.integers(0, ei.size, size=k)
            with np.errstate(divide="ignore"):
                logu = np.log(rng.random(k))
            _mcmc_chunk(
                ei, ej, logW, logm, logv, required, edge, logu, at, am, counts, record, state
            )
            done += k
    if state[1] == 0:
        raise ValueError(
            "no recorded MCMC step had every certainly detected track (miss = 0) matched; "
            "increase n_samples or use method='exact'"
        )
    return counts / counts.sum(axis=1, keepdims=True)
