"""Input checks shared by the permanent functions.

Every public function of :mod:`jointtrack.permanent` funnels its input through
:func:`check_matrix` so that bad input fails early with a message that names the
problem, instead of surfacing later as a numpy traceback or a silent NaN.
"""

from __future__ import annotations

import numpy as np


def check_matrix(A, name: str = "A") -> np.ndarray:
    """Return `A` as a C-contiguous float64 array after checking it.

    Raises
    ------
    ValueError
        if `A` is not 2-D, has more rows than columns, or holds negative,
        NaN or infinite entries.
    """
    try:
        arr = np.asarray(A, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 2-D array of real numbers: {exc}") from None
    if arr.ndim != 2:
        raise ValueError(f"{name} must be 2-D, got an array with {arr.ndim} dimension(s)")
    n, m = arr.shape
    if n > m:
        raise ValueError(
            f"{name} has more rows than columns ({n} > {m}); the permanent of an n×m matrix "
            "is defined here for n ≤ m (transpose it: Per(A) = Per(Aᵀ) for square A)"
        )
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name} has a non-finite entry ({arr[tuple(bad)]}) at {tuple(bad)}")
    if np.any(arr < 0):
        bad = np.argwhere(arr < 0)[0]
        raise ValueError(
            f"{name} has a negative entry ({arr[tuple(bad)]}) at {tuple(bad)}; "
            "jointtrack permanents are of non-negative matrices"
        )
    return np.ascontiguousarray(arr)


def check_counts(counts, length: int, name: str) -> np.ndarray:
    """Check group sizes for compressed (repeated-row/column) input."""
    if counts is None:
        return np.ones(length, dtype=np.int64)
    try:
        c = np.asarray(counts)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 1-D array of positive integers: {exc}") from None
    if c.ndim != 1 or c.shape[0] != length:
        raise ValueError(
            f"{name} must have one entry per {'row' if 'row' in name else 'column'} of the "
            f"compressed matrix ({length}), got shape {c.shape}"
        )
    if c.size and not np.issubdtype(c.dtype, np.integer):
        if not np.all(np.isfinite(c)) or np.any(c != np.round(c)):
            raise ValueError(f"{name} must hold integers, got {c}")
    c = c.astype(np.int64)
    if np.any(c < 1):
        raise ValueError(f"{name} must be ≥ 1 (a group has at least one member), got {c}")
    return c


def check_compressed(A, row_counts, col_counts, name: str = "A"):
    """Validate a compressed matrix with group sizes; returns (A, rows, cols)."""
    try:
        arr = np.asarray(A, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 2-D array of real numbers: {exc}") from None
    if arr.ndim != 2:
        raise ValueError(f"{name} must be 2-D, got an array with {arr.ndim} dimension(s)")
    rows = check_counts(row_counts, arr.shape[0], "row_counts")
    cols = check_counts(col_counts, arr.shape[1], "col_counts")
    n, m = int(rows.sum()), int(cols.sum())
    if n > m:
        raise ValueError(
            f"{name} expands to more rows than columns ({n} > {m}); the permanent of an "
            "n×m matrix is defined here for n ≤ m"
        )
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name} has a non-finite entry ({arr[tuple(bad)]}) at {tuple(bad)}")
    if np.any(arr < 0):
        bad = np.argwhere(arr < 0)[0]
        raise ValueError(
            f"{name} has a negative entry ({arr[tuple(bad)]}) at {tuple(bad)}; "
            "jointtrack permanents are of non-negative matrices"
        )
    return np.ascontiguousarray(arr), rows, cols


def expand(A: np.ndarray, row_counts, col_counts) -> np.ndarray:
    """Expand a compressed matrix to the full one (testing and references)."""
    A = np.asarray(A, dtype=np.float64)
    r = np.ones(A.shape[0], int) if row_counts is None else np.asarray(row_counts, int)
    c = np.ones(A.shape[1], int) if col_counts is None else np.asarray(col_counts, int)
    return np.repeat(np.repeat(A, r, axis=0), c, axis=1)


def check_problem(A, row_counts=None, col_counts=None):
    """``(A, rows, cols)`` for plain or compressed input, group sizes as int64 arrays."""
    if row_counts is None and col_counts is None:
        A = check_matrix(A)
        return A, np.ones(A.shape[0], np.int64), np.ones(A.shape[1], np.int64)
    return check_compressed(A, row_counts, col_counts)
