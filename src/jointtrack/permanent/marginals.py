"""All assignment marginals at once (every minor of the permanent).

``P[t, i] = A[t, i] · Per(A without row t and column i) / Per(A)`` is the
probability that row t is assigned to column i when assignments are weighted by
their products — Schaub's track-to-identity matrix (eq. 33, 78) and, with miss
and clutter terms, the JPDA β. A forward and a backward pass of the
cancellation-free DP give every entry for about the cost of two permanents.
"""

from __future__ import annotations

import numpy as np

from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.permanent import multiset as _ms
from jointtrack.permanent import subset as _ss
from jointtrack.permanent._validate import check_problem
from jointtrack.permanent.exact import (
    _balanced,
    _multiset_check,
    _plan,
    make_square,
    multiset_items,
)
from jointtrack.permanent.structure import has_feasible_assignment


def assignment_marginals(A, row_counts=None, col_counts=None) -> np.ndarray:
    """Marginal assignment probabilities of a non-negative n×m matrix (n ≤ m).

    ``P[t, i] = A[t, i] · Per(A₍₋ₜ,₋ᵢ₎) / Per(A)`` (Schaub eq. 33/78: the
    posterior probability that identity/column i sits on track/row t), from one
    forward and one backward pass of the cancellation-free DP (subset or
    repeated-row/column, whichever is cheaper; see :mod:`jointtrack.permanent.exact`).

    Parameters
    ----------
    A : (n, m) array_like, non-negative and finite.
    row_counts, col_counts : optional group sizes of a compressed matrix (see
        :func:`jointtrack.permanent.log_permanent`). P is then compressed too:
        ``P[q, j]`` is the probability for any one member of row group q and any
        one member of column group j.

    Returns
    -------
    P : (n, m) ndarray
        Rows (of the expanded matrix) sum to 1 — ``P @ col_counts == 1`` — and,
        when square, columns too: ``row_counts @ P == 1``.

    Raises
    ------
    InfeasibleAssignmentError
        when no assignment has positive weight (Per(A) = 0): the probabilities
        are undefined.
    ValueError
        bad input, or a problem too large for the exact programme.
    """
    A, rows, cols = check_problem(A, row_counts, col_counts)
    if int(rows.sum()) == 0:
        return np.zeros(A.shape)
    if not has_feasible_assignment(A > 0, rows, cols):
        raise InfeasibleAssignmentError(
            "no feasible assignment exists: every way of giving each row its own column "
            "includes a zero entry, so Per(A) = 0 and the marginals are undefined"
        )
    n_groups = A.shape[0]
    A2, rows2, cols2, _ = make_square(A, rows, cols)
    kind, W, r, c, row_of, col_of = _plan(A2, rows2, cols2, "dp", marginals=True)
    # Marginals are invariant under diagonal scaling, so the balancing shift is dropped.
    if kind == "multiset":
        _multiset_check(r, c, marginals=True)
        B, _ = _balanced(W, r, c)
        Wt, items, cnt, transposed = multiset_items(B, r, c)
        M = _ms.noskip_marginals(Wt, items, np.asarray(cnt, np.int64))
        P = _group_mean(M, items, Wt.shape[0])
        if transposed:
            P = P.T
    else:
        ones = np.ones(W.shape[0], np.int64)
        B, _ = _balanced(W, ones, ones)
        P = _ss.pull_marginals(B)
    P = P[row_of][:, col_of][:n_groups]
    # Rounding can leave values a few ulps outside [0, 1]; probabilities are clipped there.
    return np.clip(np.ascontiguousarray(P), 0.0, 1.0)


def _group_mean(M, items, groups):
    # Members of one group have equal marginals; averaging them costs nothing.
    out = np.zeros((groups, M.shape[1]))
    np.add.at(out, items, M)
    return out / np.bincount(items, minlength=groups)[:, None]
