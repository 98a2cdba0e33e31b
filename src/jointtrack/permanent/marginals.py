"""All assignment marginals at once (every minor of the permanent): a face on the core.

``P[t, i] = A[t, i] · Per(A without row t and column i) / Per(A)`` is the
probability that row t is assigned to column i when assignments are weighted by
their products — Schaub's track-to-identity matrix (eq. 33, 78). One
forward–backward pass of the core's DP (:mod:`jointtrack.assignment.core`)
gives every entry.
"""

from __future__ import annotations

import numpy as np

from jointtrack.assignment.core import DEFAULT_MAX_BITS, DEFAULT_MAX_MEMORY, solve_checked
from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.permanent._validate import check_problem

__all__ = ["assignment_marginals"]


def assignment_marginals(A, row_counts=None, col_counts=None) -> np.ndarray:
    """Marginal assignment probabilities of a non-negative n×m matrix (n ≤ m).

    ``P[t, i] = A[t, i] · Per(A₍₋ₜ,₋ᵢ₎) / Per(A)`` (Schaub eq. 33/78: the
    posterior probability that identity/column i sits on track/row t).

    Parameters
    ----------
    A : (n, m) array_like, non-negative, finite and real.
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

    Examples
    --------
    >>> from jointtrack.permanent import assignment_marginals
    >>> assignment_marginals([[1.0, 3.0], [3.0, 1.0]]).tolist()
    [[0.1, 0.9], [0.9, 0.1]]
    """
    A, rows, cols = check_problem(A, row_counts, col_counts)
    try:
        result = solve_checked(
            A,
            np.zeros(A.shape[0]),
            rows,
            cols,
            True,
            "auto",
            DEFAULT_MAX_BITS,
            DEFAULT_MAX_MEMORY,
            False,
        )
    except InfeasibleAssignmentError:
        raise InfeasibleAssignmentError(
            "no feasible assignment exists: every way of giving each row its own column "
            "includes a zero entry, so Per(A) = 0 and the marginals are undefined"
        ) from None
    return result.P
