"""Permanents: a thin face on the assignment-sum core.

``Per(A) = Σ_σ Π_t A[t, σ(t)]`` over injective maps of rows into columns
(Schaub eq. 32) is the assignment sum of :mod:`jointtrack.assignment.core` with
no null weights. The methods map onto the core's:

* ``"dp"``: the frontier subset DP (cancellation-free; relative error of the
  log of order n·2⁻⁵³ on any non-negative input; banded and block-sparse
  matrices cost layers·2^frontier, not 2^n);
* ``"multiset"``: the group-count DP for repeated rows/columns (Schaub eq. 36–37);
* ``"glynn"``, ``"ryser"``: inclusion–exclusion on the scaled and balanced
  matrix, with a measured error estimate (the DP's value is returned with a
  warning when the estimate exceeds 1e-11);
* ``"auto"``: whichever exact method is cheapest for the input (Glynn for the
  value of a dense square matrix from n = 15 up to 40 when accurate, the group
  DP when rows or columns repeat, the frontier DP otherwise);
* ``"reference"``: exact rational arithmetic (:mod:`jointtrack.permanent.reference`).
"""

from __future__ import annotations

import math

import numpy as np

from jointtrack.assignment.core import (
    DEFAULT_MAX_BITS,
    DEFAULT_MAX_MEMORY,
    GLYNN_TOLERANCE,
    solve_checked,
)
from jointtrack.permanent._validate import check_problem

__all__ = ["GLYNN_TOLERANCE", "METHODS", "log_permanent", "permanent"]

# exp(log Per) carries a relative error up to ~|log|·2⁻⁵³ ≈ 1.6e-13 near the top of
# the range: values this close to the largest float may truly lie beyond it
_FLOAT_MAX_SAFE = 1.7976931348623157e308 * (1.0 - 4e-13)
_LOG_FLOAT_MAX = math.log(1.7976931348623157e308)

METHODS = ("auto", "dp", "multiset", "glynn", "ryser", "reference")
_CORE_METHOD = {
    "auto": "auto",
    "dp": "frontier",
    "multiset": "groups",
    "glynn": "glynn",
    "ryser": "ryser",
}


def _check_method(method) -> None:
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")


def log_permanent(A, method: str = "auto", *, row_counts=None, col_counts=None) -> float:
    """Natural log of the permanent of a non-negative n×m matrix (n ≤ m).

    ``Per(A) = Σ_σ Π_t A[t, σ(t)]`` over injective σ (Schaub eq. 32); for
    compressed input (``row_counts``/``col_counts``) that of the expanded matrix
    with row group q repeated ``row_counts[q]`` times and column group j
    ``col_counts[j]`` times (Schaub eq. 36). Never under- or overflows.

    Parameters
    ----------
    A : (n, m) array_like, non-negative, finite, real, n ≤ m (after expansion).
    method : {"auto", "dp", "multiset", "glynn", "ryser", "reference"}
        See the module docstring.
    row_counts, col_counts : sequences of positive ints, optional
        Group sizes of a compressed matrix.

    Returns
    -------
    float
        ``log Per(A)``; ``-inf`` when no assignment has positive weight.

    Raises
    ------
    ValueError
        bad input (named), an unknown method, or a problem too large for the
        exact methods.

    Examples
    --------
    >>> from jointtrack.permanent import log_permanent
    >>> round(log_permanent([[1e-300, 1.0], [1.0, 1e-300]]), 6)
    0.0
    """
    _check_method(method)
    A, rows, cols = check_problem(A, row_counts, col_counts)
    return _log_permanent(A, rows, cols, method)


def _log_permanent(A, rows, cols, method: str) -> float:
    """:func:`log_permanent` on input :func:`check_problem` has already validated."""
    if method == "reference":
        from jointtrack.permanent.reference import reference_log_permanent

        return reference_log_permanent(A, row_counts=rows, col_counts=cols)
    result = solve_checked(
        A,
        np.zeros(A.shape[0]),
        rows,
        cols,
        False,
        _CORE_METHOD[method],
        DEFAULT_MAX_BITS,
        DEFAULT_MAX_MEMORY,
        False,
    )
    return result.log_normalizer


def permanent(A, method: str = "auto", *, row_counts=None, col_counts=None) -> float:
    """Permanent of a non-negative n×m matrix (n ≤ m); see :func:`log_permanent`.

    Returns 0.0 exactly when no assignment has positive weight.

    Raises
    ------
    OverflowError
        if the permanent is positive but outside the float64 range (it neither
        silently becomes ``inf`` nor ``0.0``); use :func:`log_permanent`.

    Examples
    --------
    >>> from jointtrack.permanent import permanent
    >>> permanent([[1.0, 2.0], [3.0, 4.0]])
    10.0
    """
    _check_method(method)
    A, rows, cols = check_problem(A, row_counts, col_counts)
    if method == "reference":
        from jointtrack.permanent.reference import reference_permanent

        value = reference_permanent(A, row_counts=rows, col_counts=cols)
        if value == 0.0 or value == math.inf:
            log_value = _log_permanent(A, rows, cols, "reference")
            if log_value != -math.inf:
                _exp_or_raise(log_value)  # raises: the exact value is outside float64
        return value
    log_value = _log_permanent(A, rows, cols, method)
    if abs(log_value - _LOG_FLOAT_MAX) <= 1e-12 * _LOG_FLOAT_MAX and int(rows.sum()) <= 10:
        # within rounding of the float64 limit: let the exact rational value decide
        return permanent(A, "reference", row_counts=rows, col_counts=cols)
    return _exp_or_raise(log_value)


def _exp_or_raise(log_value: float) -> float:
    """exp of a log-permanent, or OverflowError when it leaves the float64 range.

    ``log(max float64) ≈ 709.7827``: a log within a few ulps of it may round to
    either side, so the boundary is decided on the exponentiated value (an
    overflowing exp, or a result at the largest finite float, is refused
    rather than returned as a value that may be 1 ulp beyond the range).
    """
    if log_value == -math.inf:
        return 0.0
    try:
        value = math.exp(log_value)
    except OverflowError:
        value = math.inf
    if value == math.inf or value == 0.0:
        kind = "overflows" if log_value > 0 else "underflows"
        raise OverflowError(
            f"the permanent is e^{log_value:.6g}, which {kind} float64; use log_permanent"
        )
    if value >= _FLOAT_MAX_SAFE:
        raise OverflowError(
            f"the permanent is e^{log_value:.15g}, within rounding of the float64 limit, so "
            "whether it is representable cannot be decided; use log_permanent"
        )
    # exp(log) is off by |log|·2⁻⁵³ relative at most; round the integer-valued case
    nearest = round(value)
    if nearest != 0 and abs(value - nearest) <= 4e-16 * abs(log_value) * value:
        return float(nearest)
    return value
