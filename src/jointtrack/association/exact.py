"""Exact JPDA marginals: a thin face on the assignment-sum core.

The JPDA association probabilities of a cluster are ratios of sums over joint
association events (Bojilov et al., eqs. (5)–(7) and the marginal sum
``p_ij = Σ_{l ∈ L_j} P(H_l)`` after (6)). With the DESIGN.md convention
(likelihood ratios ``L`` and miss weights ``miss``, i.e. (7) with the common
factor ``β^{N_M}`` removed) an event's weight is

    w(H) = Π_{(i,j) ∈ H} L[i, j] · Π_{tracks i unassigned in H} miss[i],

measurements not assigned in ``H`` are clutter (weight 1), so ``Z = Σ_H w(H)``
is exactly the assignment sum of :mod:`jointtrack.assignment.core` with null
weights ``miss``, and ``beta = [null | P]`` its marginals. Leaf folding,
components, dual scaling and the frontier DP all live there; this module checks
the cluster convention and packages the result.

Reference: S. Bojilov, K. Alexiev and P. Konstantinova, "One particular program
realization of JPDA algorithm", *Information & Security* 9, 2002.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointtrack.assignment._checks import as_int
from jointtrack.assignment.core import DEFAULT_MAX_BITS, DEFAULT_MAX_MEMORY, solve_checked
from jointtrack.association._validate import NO_FEASIBLE_EVENT, check_cluster
from jointtrack.errors import ExactLimitError, InfeasibleAssignmentError

__all__ = [
    "ExactResult",
    "exact_jpda",
    "exact_log_normalizer",
    "exact_marginals",
]


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


def _solve(
    L,
    miss,
    max_bits=DEFAULT_MAX_BITS,
    max_memory=DEFAULT_MAX_MEMORY,
    parallel=False,
    marginals=True,
):
    L, miss = check_cluster(L, miss)
    N, M = L.shape
    if N == 0:
        return ExactResult(np.zeros((0, M + 1)), 0.0, 0, 0, 0, 0)
    try:
        res = solve_checked(
            L,
            miss,
            np.ones(N, np.int64),
            np.ones(M, np.int64),
            marginals,
            "frontier",
            as_int(max_bits, "max_bits", 0, 62),
            as_int(max_memory, "max_memory", 0),
            bool(parallel),
        )
    except InfeasibleAssignmentError:
        raise InfeasibleAssignmentError(NO_FEASIBLE_EVENT) from None
    except ExactLimitError as exc:
        raise ExactLimitError(
            f"{exc}; for this cluster use method='lbp', 'mcmc' or 'kbest', or raise the budget"
        ) from None
    if res.log_normalizer == -np.inf:
        raise InfeasibleAssignmentError(NO_FEASIBLE_EVENT)
    info = res.info
    return ExactResult(
        res.beta if marginals else None,
        float(res.log_normalizer),
        int(info.get("n_components", 0)),
        int(info.get("max_frontier", 0)),
        int(info.get("n_folded", 0)),
        int(info.get("state_bytes", 0)),
    )


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
    return _solve(L, miss, max_bits, max_memory, marginals=False).log_normalizer
