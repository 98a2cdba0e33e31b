"""One entry point for every JPDA association method: :func:`marginals`."""

from __future__ import annotations

import numpy as np

__all__ = ["METHODS", "marginals"]

METHODS = ("exact", "enumerate", "pda", "lbp", "mcmc", "kbest")


def marginals(L, miss, method: str = "exact", **options) -> np.ndarray:
    """JPDA association probabilities ``beta`` (N × (M+1)) of one cluster.

    Bojilov et al. eq. (3) (PDA) or the JPDA sum ``p_ij = Σ_{l ∈ L_j} P(H_l)``
    over the feasible hypotheses of (5)–(7), exactly or approximately.

    Parameters
    ----------
    L : array (N, M)
        Likelihood ratios ``P_D g_ij / λ`` (0 = measurement j outside track i's gate).
    miss : array (N,)
        ``1 − P_D P_G`` per track.
    method : str
        ``"exact"``      subset DP forward–backward, no enumeration
                         (:func:`~jointtrack.association.exact.exact_marginals`);
        ``"enumerate"``  Bojilov's hypothesis enumeration
                         (:func:`~jointtrack.association.hypotheses.enumerate_jpda`;
                         options ``naive``, ``max_hypotheses``);
        ``"pda"``        independent per-track PDA, eqs. (1)–(3);
        ``"lbp"``        Williams & Lau loopy belief propagation
                         (options ``tol``, ``max_iter``);
        ``"mcmc"``       Oh–Russell–Sastry MCMC (options ``n_samples``, ``rng``, …);
        ``"kbest"``      k best joint events by Murty's algorithm (option ``k``).
    **options
        passed to the method's function.

    Returns
    -------
    beta : ndarray (N, M+1)
        column 0 = no measurement; rows sum to 1.

    Raises
    ------
    ValueError
        unknown method, bad input, or a method's own limits.
    InfeasibleAssignmentError
        no feasible joint event.
    """
    if method == "exact":
        from jointtrack.association.exact import exact_marginals

        return exact_marginals(L, miss, **options)
    if method == "enumerate":
        from jointtrack.association.hypotheses import enumerate_jpda

        return enumerate_jpda(L, miss, **options).beta
    if method == "pda":
        from jointtrack.association.pda import pda_marginals

        return pda_marginals(L, miss, **options)
    if method == "lbp":
        from jointtrack.association.lbp import lbp_marginals

        beta, _info = lbp_marginals(L, miss, **options)
        return beta
    if method == "mcmc":
        from jointtrack.association.mcmc import mcmc_marginals

        return mcmc_marginals(L, miss, **options)
    if method == "kbest":
        from jointtrack.association.kbest import kbest_marginals

        return kbest_marginals(L, miss, **options)
    raise ValueError(f"unknown association method {method!r}; choose one of: " + ", ".join(METHODS))
