"""One cluster's association probabilities under a cost budget: exact, then an approximation.

The exact methods ("exact", "enumerate") cost exponentially in the worst case:
the frontier DP of :mod:`jointtrack.assignment.core` needs a state of 2^K
subsets for a block of frontier width K. The policy, shared by the JPDA tracker
(:class:`jointtrack.trackers.JPDATracker`) and the Stone Soup associators
(:mod:`jointtrack.interop.stonesoup`), is:

1. a cluster with more than ``max_tracks`` tracks goes to ``approximation``
   without trying the exact method (reason ``"exact_max_tracks"``);
2. otherwise the exact method runs; if it refuses the cluster because its state
   or memory would exceed the budget (:class:`~jointtrack.errors.ExactLimitError`,
   raised before any work), the cluster goes to ``approximation`` (reason
   ``"refused: …"`` with the engine's message).

The result says which method produced each cluster's β and why, so callers can
count and report every fallback.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointtrack.association.core import marginals
from jointtrack.errors import ExactLimitError

__all__ = ["APPROXIMATIONS", "EXACT_METHODS", "BudgetedMarginals", "budgeted_marginals"]

EXACT_METHODS = ("exact", "enumerate")
APPROXIMATIONS = ("lbp", "mcmc", "kbest", "pda")


@dataclass(frozen=True)
class BudgetedMarginals:
    """β of one cluster and how it was obtained.

    ``beta`` (N, M+1), column 0 = no measurement; ``method`` the method that
    produced it; ``reason`` empty when that is the requested method, else why the
    approximation was used.
    """

    beta: np.ndarray
    method: str
    reason: str


def budgeted_marginals(
    L,
    miss,
    *,
    method: str = "exact",
    approximation: str | None = "lbp",
    max_tracks: int | None = None,
    rng=None,
    exact_options: dict | None = None,
) -> BudgetedMarginals:
    """JPDA marginals of one cluster by ``method``, falling back to ``approximation``.

    Parameters
    ----------
    L, miss
        the cluster (:func:`jointtrack.association.marginals` convention).
    method : str
        any of :data:`jointtrack.association.METHODS`; only the exact ones
        ("exact", "enumerate") are subject to the budget.
    approximation : str or None
        one of :data:`APPROXIMATIONS`, used past the budget; None raises
        :class:`~jointtrack.errors.ExactLimitError` there instead.
    max_tracks : int or None
        clusters with more tracks go straight to ``approximation``.
    rng
        random generator for ``"mcmc"`` (either as method or as approximation).
    exact_options : dict or None
        the exact method's budget, e.g. ``{"max_bits": 24, "max_memory": 2**28}``
        (:func:`jointtrack.association.exact.exact_marginals`).

    Raises
    ------
    ExactLimitError
        past the budget with ``approximation=None``.
    ValueError
        an unknown approximation, or bad ``L``/``miss`` (named by the method).
    """
    if approximation is not None and approximation not in APPROXIMATIONS:
        raise ValueError(
            f"approximation must be one of {', '.join(APPROXIMATIONS)}, got {approximation!r}"
        )
    reason = ""
    n_tracks = np.shape(L)[0] if np.ndim(L) == 2 else 0
    if method in EXACT_METHODS and max_tracks is not None and n_tracks > max_tracks:
        if approximation is None:
            raise ExactLimitError(
                f"a cluster of {n_tracks} tracks is above max_tracks = {max_tracks}"
            )
        method, reason = approximation, "exact_max_tracks"
    try:
        options = dict(exact_options or {}) if method == "exact" else _options(method, rng)
        beta = marginals(L, miss, method=method, **options)
    except ExactLimitError as exc:
        if method not in EXACT_METHODS or approximation is None:
            raise
        method, reason = approximation, f"refused: {exc}"
        beta = marginals(L, miss, method=method, **_options(method, rng))
    return BudgetedMarginals(beta, method, reason)


def _options(method: str, rng) -> dict:
    return {"rng": rng} if method == "mcmc" and rng is not None else {}
