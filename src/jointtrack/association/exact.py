"""Exact JPDA marginals without enumerating joint hypotheses.

The JPDA association probabilities of a cluster are ratios of sums over joint
association events (Bojilov et al., eqs. (5)–(7) and the marginal sum
``p_ij = Σ_{l ∈ L_j} P(H_l)`` after (6)). With the DESIGN.md convention
(likelihood ratios ``L`` and miss weights ``miss``, i.e. (7) with the common
factor ``β^{N_M}`` removed) an event's weight is

    w(H) = Π_{(i,j) ∈ H} L[i, j] · Π_{tracks i unassigned in H} miss[i],

measurements not assigned in ``H`` are clutter (weight 1), and

    beta[i, 0] = Σ_{H: i unassigned} w(H) / Z,   beta[i, j+1] = Σ_{H ∋ (i,j)} w(H) / Z,

with ``Z = Σ_H w(H)`` the normaliser of (6).

How it is computed (never enumerating events):

1. **Leaf folding.** A measurement gated by a single track, or a track gating a
   single measurement, is summed out exactly into its neighbour (the neighbour's
   "unassigned" weight absorbs the leaf's alternatives); repeated until every
   remaining node has ≥ 2 gated partners. Tree-shaped clusters disappear entirely.
   Done on split floats (mantissa, power-of-two exponent), so nothing
   over/underflows and nothing loses precision to exp(log(·)).
2. **Independent blocks.** What remains splits into connected components.
3. **Dual scaling.** Per block, the optimal dual of the max-weight association
   (a shortest-augmenting-path assignment solve on log weights) gives row and
   column scale factors, rounded to powers of two (exact), after which every
   factor is ≤ ~1 and the best event has weight ≈ 1. Every event that matters
   (≥ 1e-300 of the best) then has all partial products ≥ ~1e-300 — no underflow
   anywhere in the DP, for any scale of L (a DP merely normalised per layer by
   its maximum loses such paths; see the tests).
4. **Frontier subset DP, forward–backward.** One side (tracks or measurements,
   whichever gives the smaller frontier) is the state: the subset of the *open*
   items (seen and still gated by an unprocessed item of the other side) that
   are already used. Items of the other side are processed one layer at a time
   in a greedy order that keeps the frontier small; an item leaving the frontier
   is summed out. The forward pass stores its layer inputs; the backward (adjoint)
   pass contracts them with the backward messages, giving every marginal for the
   cost of about three forward passes. The state array is processed in
   cache-sized blocks so that every inner loop is a contiguous AXPY or dot
   product. Powers of two renormalise a layer only if it leaves [2^-600, 2^600].

The DP only adds and multiplies non-negative numbers: the result is exact to
rounding (relative error of order (layers + items)·1e-16 on every marginal).

This module holds the public API and the orchestration (:func:`_solve`,
:func:`_solve_block`); the numba kernels live in private single-purpose modules:
:mod:`._scaled` (split-float arithmetic), :mod:`._fold` (steps 1–2: leaf
folding, unfolding, components), :mod:`._dual_scaling` (step 3),
:mod:`._exact_plan` (step 4: layer order and frontier slots),
:mod:`._exact_kernels` (step 4: blocked layer kernels) and :mod:`._exact_dp`
(step 4: forward–backward driver with checkpointing). numba's on-disk cache does
not notice edits to a callee defined in another file: after changing one of
these modules, delete its dependants' ``__pycache__/*.nbi`` / ``*.nbc`` files.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from jointtrack.association._dual_scaling import _block, _scatter
from jointtrack.association._exact_dp import _dp_run
from jointtrack.association._exact_plan import _plan
from jointtrack.association._fold import _finish, _prepare
from jointtrack.association._validate import check_cluster
from jointtrack.errors import InfeasibleAssignmentError

__all__ = [
    "ExactResult",
    "exact_jpda",
    "exact_log_normalizer",
    "exact_marginals",
]

_PAR_MIN_BITS = 16  # use the multi-thread kernels from 2^16 states up
DEFAULT_MAX_BITS = 30
DEFAULT_MAX_MEMORY = 2 * 1024**3


@dataclass(frozen=True)
class ExactResult:
    """Result of :func:`exact_jpda`.

    Attributes
    ----------
    beta : ndarray (N, M+1)
        Association probabilities; column 0 = no measurement (Bojilov's p_i0).
    log_normalizer : float
        ``log Z``, natural log of the sum of (7)-weights of all feasible joint
        events (the denominator of (6)).
    n_components : int
        Independent blocks solved by the subset DP after leaf folding.
    max_frontier : int
        Largest DP state width (bits) over the blocks (0 if everything folded).
    n_folded : int
        Nodes (tracks + measurements) summed out by leaf folding.
    state_bytes : int
        Bytes of DP state arrays allocated at the peak (the dominant memory).
    """

    beta: np.ndarray
    log_normalizer: float
    n_components: int
    max_frontier: int
    n_folded: int
    state_bytes: int


_INFEASIBLE_MSG = (
    "no feasible joint association event: tracks with miss = 0 (certainly detected) "
    "cannot all be given distinct gated measurements"
)


def _solve_block(W, u, v, max_bits, max_memory, parallel=False):
    """Forward–backward DP of one dual-scaled block (rows = tracks, cols = measurements).

    Returns (pu, pv, pe, logZ', K, state_bytes) with pu/pv the rows'/cols'
    unassigned probabilities and pe[r, c] the pair probabilities.
    """
    G = W > 0.0
    R, C = G.shape
    # orientation: state over columns (layers = rows) or over rows (layers = cols)
    plan_a = _plan(G)
    plan_b = _plan(np.ascontiguousarray(G.T))
    # cost ≈ layers · 2^K (layers = rows for plan_a, columns for plan_b)
    transpose = C * 2.0 ** plan_b[1] < R * 2.0 ** plan_a[1]
    if transpose:
        W, u, v = np.ascontiguousarray(W.T), v, u
        plan = plan_b
    else:
        plan = plan_a
    _, K, op_kind, op_arg, slot_of, lay_slot, term = plan
    if K > max_bits:
        raise ValueError(
            f"exact JPDA needs a DP state of 2^{K} subsets for this cluster "
            f"({R} tracks, {C} measurements in one inseparable block), above the "
            f"limit 2^{max_bits}; use method='lbp', 'mcmc' or 'kbest', or raise max_bits"
        )
    n = 1 << K
    nops = op_kind.size
    per = 8 * n
    stride = 1
    if (nops + 3) * per > max_memory:
        stride = max(2, int(math.ceil(math.sqrt(nops))))
        if (math.ceil(nops / stride) + stride + 4) * per > max_memory:
            raise ValueError(
                f"exact JPDA for this block needs more than max_memory = {max_memory} bytes "
                f"(2^{K} states × {nops} layers even with checkpointing); use method='lbp', "
                "'mcmc' or 'kbest'"
            )
    if stride == 1:
        state_bytes = (nops + 3) * per
    else:
        state_bytes = (math.ceil(nops / stride) + stride + 4) * per
    nchunk = 1
    if parallel and K >= _PAR_MIN_BITS and numba.get_num_threads() > 1:
        nchunk = 4 * numba.get_num_threads()
    pl, pi, pe, logZ = _dp_run(W, u, v, K, op_kind, op_arg, slot_of, lay_slot, term, stride, nchunk)
    if not np.isfinite(logZ):
        raise InfeasibleAssignmentError(_INFEASIBLE_MSG)
    if transpose:
        return pi, pl, np.ascontiguousarray(pe.T), logZ, K, state_bytes
    return pl, pi, pe, logZ, K, state_bytes


def _solve(L, miss, max_bits=DEFAULT_MAX_BITS, max_memory=DEFAULT_MAX_MEMORY, parallel=False):
    L, miss = check_cluster(L, miss)
    N, M = L.shape
    if N == 0:
        return ExactResult(np.zeros((0, M + 1)), 0.0, 0, 0, 0, 0)
    folds, graph, ncomp, infeasible, logZ = _prepare(L, miss)
    if infeasible:
        raise InfeasibleAssignmentError(_INFEASIBLE_MSG)
    pu = np.zeros(N)
    pv = np.zeros(M)
    pe = np.zeros((N, M))
    kmax = 0
    peak = 0
    for k in range(ncomp):
        rows, cols, W, u, v, shift, ok = _block(k, *graph)
        if not ok:
            raise InfeasibleAssignmentError(_INFEASIBLE_MSG)
        bu, bv, be, lz, K, sb = _solve_block(W, u, v, max_bits, max_memory, parallel)
        _scatter(rows, cols, bu, bv, be, pu, pv, pe)
        logZ += lz - shift
        kmax = max(kmax, K)
        peak = max(peak, sb)
    beta = _finish(*folds, pu, pv, pe)
    n_folded = len(folds[0])
    return ExactResult(beta, float(logZ), int(ncomp), int(kmax), int(n_folded), int(peak))


def exact_jpda(
    L,
    miss,
    *,
    max_bits: int = DEFAULT_MAX_BITS,
    max_memory: int = DEFAULT_MAX_MEMORY,
    parallel: bool = False,
) -> ExactResult:
    """Exact JPDA association probabilities and normaliser (Bojilov eqs. (5)–(7)).

    Computes ``p_ij = Σ_{l ∈ L_j} P(H_l)`` (the marginal sum following (6)) for
    every track i and measurement j, and p_i0, exactly, by the leaf-folding +
    frontier subset DP described in the module docstring — never enumerating
    joint hypotheses.

    Parameters
    ----------
    L : array (N, M)
        Likelihood ratios ``P_D g_ij / λ`` (0 = not gated).
    miss : array (N,)
        ``1 − P_D P_G`` per track.
    max_bits : int
        Refuse blocks whose DP state would exceed 2^max_bits subsets.
    max_memory : int
        Byte budget for the DP state arrays; above it the forward pass is
        checkpointed (one extra forward pass), and beyond that refused.
    parallel : bool
        Split large layers (≥ 2^16 states) over numba's threads. Off by default:
        the kernels are memory-bound and, on a machine whose cores are busy,
        thread barriers cost more than they save.

    Returns
    -------
    ExactResult

    Raises
    ------
    ValueError
        bad input (see :func:`~jointtrack.association._validate.check_cluster`),
        or a block too large for ``max_bits`` / ``max_memory``.
    InfeasibleAssignmentError
        no feasible joint event (certainly-detected tracks cannot all be served).
    """
    return _solve(L, miss, max_bits, max_memory, parallel)


def exact_marginals(
    L,
    miss,
    *,
    max_bits: int = DEFAULT_MAX_BITS,
    max_memory: int = DEFAULT_MAX_MEMORY,
    parallel: bool = False,
) -> np.ndarray:
    """Exact JPDA marginals ``beta`` (N × (M+1)), Bojilov eqs. (5)–(7) and the sum after (6).

    ``beta[i, 0]`` is the probability that track i has no measurement,
    ``beta[i, j+1]`` that measurement j is track i's. Rows sum to 1. See
    :func:`exact_jpda` for the parameters and errors.
    """
    return _solve(L, miss, max_bits, max_memory, parallel).beta


def exact_log_normalizer(
    L, miss, *, max_bits: int = DEFAULT_MAX_BITS, max_memory: int = DEFAULT_MAX_MEMORY
) -> float:
    """``log Σ_H P'(H)``: natural log of the normaliser of Bojilov eq. (6) with (7) weights.

    With ``L = (L > 0)`` and ``miss = (miss > 0)`` this is the log of the number
    of feasible joint hypotheses (used by :func:`count_hypotheses`).
    """
    return _solve(L, miss, max_bits, max_memory).log_normalizer
