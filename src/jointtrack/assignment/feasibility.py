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

__all__ = ["is_feasible", "is_feasible_pairs"]


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
    W = as_weights(W, "W")
    support = W > 0
    must = ~(as_null_weights(null, W.shape[0], "null") > 0)
    if row_counts is not None or col_counts is not None:
        r = as_counts(row_counts, support.shape[0], "row_counts")
        c = as_counts(col_counts, support.shape[1], "col_counts")
        support = np.repeat(np.repeat(support, r, axis=0), c, axis=1)
        must = np.repeat(must, r)
    rows, cols = np.nonzero(support[must])
    return _saturating(rows, cols, int(must.sum()), support.shape[1])


def is_feasible_pairs(rows, cols, null, n_cols: int) -> bool:
    """:func:`is_feasible` of a problem given by its positive pairs (memory O(pairs)).

    ``(rows[k], cols[k])`` are the entries with positive weight, each once;
    ``null[r] > 0`` lets row r stay unassigned; ``n_cols`` columns. For
    problems too large for a dense matrix (the pair tier of the JPDA budget).
    Arguments are trusted (validated by the caller).
    """
    rows = np.asarray(rows, np.int64)
    cols = np.asarray(cols, np.int64)
    must = ~(np.asarray(null) > 0)
    k = int(must.sum())
    if k == 0:
        return True
    index = np.cumsum(must) - 1  # row r's index among the rows that must be assigned
    keep = must[rows]
    return _saturating(index[rows[keep]], cols[keep], k, int(n_cols))


def _saturating(rows, cols, n, m) -> bool:
    """Whether the bipartite graph of n rows, m columns and edges (rows, cols) matches every row."""
    if n == 0:
        return True
    if n > m or np.unique(rows).size < n:
        return False
    # scipy.sparse.csgraph costs ~0.3 s to import: only when a matching is needed
    from scipy.sparse import csr_array
    from scipy.sparse.csgraph import maximum_bipartite_matching

    graph = csr_array((np.ones(rows.size, np.int8), (rows, cols)), shape=(n, m))
    match = maximum_bipartite_matching(graph, perm_type="column")
    return bool(np.all(match >= 0))
