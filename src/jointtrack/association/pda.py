"""Independent per-track PDA association probabilities (no joint constraint).

Bojilov et al. eqs. (1)–(3): for one track with N gated observations,
``p'_i0 = β^N (1 − P_D)`` and ``p'_ij = β^{N−1} P_D g_ij``, normalised by (3).
Dividing both by ``β^N`` gives the DESIGN.md convention: ``p_i0 ∝ miss[i]``,
``p_ij ∝ L[i, j]``. Each track is treated as if it were alone, so two tracks may
both claim the same measurement with high probability — the comparison point
that JPDA improves on.
"""

from __future__ import annotations

import numpy as np

from jointtrack.association._validate import check_cluster

__all__ = ["pda_marginals", "pda_pair_marginals"]


def pda_marginals(L, miss) -> np.ndarray:
    """Per-track PDA probabilities, Bojilov eqs. (1)–(3), in the ``beta`` layout.

    ``beta[i, 0] = miss[i] / s_i`` and ``beta[i, j+1] = L[i, j] / s_i`` with
    ``s_i = miss[i] + Σ_j L[i, j]``. Each row is first scaled by a power of two
    (exact) so that its largest entry is in [0.5, 1): no overflow for any scale.

    Raises
    ------
    ValueError, InfeasibleAssignmentError
        as :func:`~jointtrack.association._validate.check_cluster`.
    """
    L, miss = check_cluster(L, miss)
    N, M = L.shape
    beta = np.empty((N, M + 1))
    if N == 0:
        return beta
    beta[:, 0] = miss
    beta[:, 1:] = L
    _, e = np.frexp(beta.max(axis=1))
    beta = np.ldexp(beta, -e[:, None])
    beta /= beta.sum(axis=1, keepdims=True)
    return beta


def pda_pair_marginals(rows, L_values, miss) -> tuple[np.ndarray, np.ndarray]:
    """Per-track PDA (Bojilov eqs. (1)–(3)) on gated pairs: ``(beta0 (N,), beta per pair)``.

    The sparse face of :func:`pda_marginals` for scans with thousands of
    tracks: pair p = (rows[p], ·) has likelihood ratio ``L_values[p]``;
    ``beta0[i] = miss[i]/s_i``, ``beta_p = L_p/s_{rows[p]}``, ``s_i = miss[i] + Σ_p L_p``.
    Each track's weights are first scaled by a power of two (exact), so nothing
    overflows. A track without pairs gets ``beta0 = 1`` (it needs ``miss > 0``).
    """
    rows = np.asarray(rows, np.int64)
    L_values = np.asarray(L_values, np.float64)
    miss = np.asarray(miss, np.float64)
    n = miss.shape[0]
    top = miss.copy()
    np.maximum.at(top, rows, L_values)
    if not (top > 0).all():
        from jointtrack.errors import InfeasibleAssignmentError

        i = int(np.argmin(top > 0))
        raise InfeasibleAssignmentError(f"track {i} has miss = 0 and no gated measurement")
    _, e = np.frexp(top)
    m0 = np.ldexp(miss, -e)
    lp = np.ldexp(L_values, -e[rows])
    tot = m0.copy()
    np.add.at(tot, rows, lp)
    return m0 / tot, lp / tot[rows] if n else lp
