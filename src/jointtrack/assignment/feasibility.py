"""The one feasibility test: does any assignment have positive weight?

An assignment (every row with null weight 0 gets its own column with a positive
weight; rows with a positive null weight may stay unassigned) exists exactly
when the bipartite support graph has a matching covering those rows — a maximum
bipartite matching (Hopcroft–Karp, :func:`scipy.sparse.csgraph.maximum_bipartite_matching`)
on the support, with groups of identical rows/columns expanded.
"""

from __future__ import annotations

import numpy as np

from jointtrack.assignment._checks import as_counts, as_null_weights, as_weights

__all__ = ["is_feasible"]


def is_feasible(W, null=None, row_counts=None, col_counts=None) -> bool:
    """True if some assignment of ``W`` weighs > 0.

    ``null[r] > 0`` lets row r stay unassigned; group counts expand rows/columns.
    Arguments are checked as by :func:`~jointtrack.assignment.assignment_sum`
    (a NaN is refused, not read as a zero weight).

    Raises
    ------
    ValueError, TypeError
        bad input, naming the argument.
    """
    # scipy.sparse.csgraph costs ~0.3 s to import: only when a test is asked for
    from scipy.sparse import csr_array
    from scipy.sparse.csgraph import maximum_bipartite_matching

    W = as_weights(W, "W")
    support = W > 0
    must = ~(as_null_weights(null, W.shape[0], "null") > 0)
    if row_counts is not None or col_counts is not None:
        r = as_counts(row_counts, support.shape[0], "row_counts")
        c = as_counts(col_counts, support.shape[1], "col_counts")
        support = np.repeat(np.repeat(support, r, axis=0), c, axis=1)
        must = np.repeat(must, r)
    support = support[must]
    n, m = support.shape
    if n == 0:
        return True
    if n > m or not support.any(axis=1).all():
        return False
    match = maximum_bipartite_matching(csr_array(support.astype(np.int8)), perm_type="column")
    return bool(np.all(match >= 0))
