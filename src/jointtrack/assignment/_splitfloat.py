"""Split floats: ``value = m · 2^e`` with ``m ∈ [0.5, 1)`` (or ``m = 0``).

Step 1 of :mod:`jointtrack.assignment.core` (leaf folding) multiplies and adds
likelihood ratios and miss weights of arbitrary magnitude; a chain of folds can
take a product far outside the float64 range. Carrying a float mantissa and an
integer power-of-two exponent separately means nothing over/underflows and every
operation rounds once, whatever the magnitude (no precision lost to exp(log(·))).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def split_normalize(m, e):
    if m == 0.0:
        return 0.0, np.int64(0)
    f, k = math.frexp(m)
    return f, e + k


@numba.njit(cache=True)
def split_add(m1, e1, m2, e2):
    if m1 == 0.0:
        return m2, e2
    if m2 == 0.0:
        return m1, e1
    if e1 >= e2:
        d = e2 - e1
        return split_normalize(m1 + (math.ldexp(m2, d) if d > -1100 else 0.0), e1)
    d = e1 - e2
    return split_normalize(m2 + (math.ldexp(m1, d) if d > -1100 else 0.0), e2)


@numba.njit(cache=True)
def split_ratio(m1, e1, m2, e2):
    """(m1·2^e1) / (m2·2^e2) as a float (m2 > 0)."""
    d = e1 - e2
    if d < -1100:
        return 0.0
    return math.ldexp(m1 / m2, d)
