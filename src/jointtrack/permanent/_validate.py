"""Permanent-specific input rules on top of the package-wide checks.

The checks themselves live in :mod:`jointtrack.assignment._checks` (one set for
every face of the core); a permanent adds one rule: the (expanded) matrix has
no more rows than columns.
"""

from __future__ import annotations

import numpy as np

from jointtrack.assignment._checks import as_counts, as_weights


def _too_many_rows(name: str, n: int, m: int) -> ValueError:
    return ValueError(
        f"{name} has more rows than columns ({n} > {m}); the permanent of an n×m matrix "
        "is defined here for n ≤ m (transpose it: Per(A) = Per(Aᵀ) for square A)"
    )


def check_matrix(A, name: str = "A") -> np.ndarray:
    """``A`` as a C-contiguous float64 array: 2-D, real, finite, ≥ 0, n ≤ m."""
    arr = as_weights(A, name)
    n, m = arr.shape
    if n > m:
        raise _too_many_rows(name, n, m)
    return arr


def check_problem(A, row_counts=None, col_counts=None, name: str = "A"):
    """``(A, rows, cols)`` for plain or compressed input, group sizes as int64 arrays."""
    arr = as_weights(A, name)
    rows = as_counts(row_counts, arr.shape[0], "row_counts")
    cols = as_counts(col_counts, arr.shape[1], "col_counts")
    n, m = int(rows.sum()), int(cols.sum())
    if n > m:
        raise _too_many_rows(
            name + " (expanded)" if row_counts is not None or col_counts is not None else name, n, m
        )
    return arr, rows, cols
