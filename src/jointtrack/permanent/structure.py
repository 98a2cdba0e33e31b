"""Structural (support-only) facts about a non-negative matrix."""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_array
from scipy.sparse.csgraph import maximum_bipartite_matching


def has_feasible_assignment(support: np.ndarray, rows=None, cols=None) -> bool:
    """True if every (expanded) row can get its own column with a positive entry.

    Maximum bipartite matching (Hopcroft–Karp, SciPy) on the support; groups of
    identical rows/columns are expanded, which is cheap at the sizes where it
    matters (a group larger than the opposite side cannot all be matched).
    """
    support = np.asarray(support, bool)
    if rows is not None or cols is not None:
        r = np.ones(support.shape[0], int) if rows is None else np.asarray(rows, int)
        c = np.ones(support.shape[1], int) if cols is None else np.asarray(cols, int)
        support = np.repeat(np.repeat(support, r, axis=0), c, axis=1)
    n, m = support.shape
    if n == 0:
        return True
    if n > m or not support.any(axis=1).all():
        return False
    match = maximum_bipartite_matching(csr_array(support.astype(np.int8)), perm_type="column")
    return bool(np.all(match >= 0))
