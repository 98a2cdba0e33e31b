"""Permanents of non-negative matrices and assignment marginals: faces on the core.

The permanent of an n×m non-negative matrix A (n ≤ m) is the sum over injective
maps σ of rows into columns of Π_t A[t, σ(t)] (Schaub eq. 32): the assignment
sum of :mod:`jointtrack.assignment` with no null weights. Every exact method
here runs on that one core.

Exact methods
-------------
``"dp"``        the core's frontier subset DP (cancellation-free: only adds and
                multiplies non-negative numbers; banded and block-sparse
                matrices cost layers·2^frontier, not 2^n).
``"multiset"``  the core's group-count DP for repeated rows/columns (Schaub
                eq. 36–37: Π(n_j+1) states, smaller orientation chosen).
``"glynn"``     Glynn's formula on the dual-scaled, balanced matrix with
                double-double sums and a measured error estimate (square only).
``"ryser"``     Ryser's formula (Schaub eq. 35), same safeguards.
``"reference"`` exact rational arithmetic (slow; the test oracle).

Approximations
--------------
:func:`bethe_permanent` (belief propagation) and :func:`sample_permanent`
(sequential importance sampling with a standard error); :func:`sinkhorn`
(Schaub eq. 38).
"""

from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.permanent.exact import log_permanent, permanent
from jointtrack.permanent.marginals import assignment_marginals

# The approximations pull in scipy.optimize (~0.2 s); import them on first use so
# that a process computing exact permanents starts fast.
_LAZY = {
    "BethePermanent": "bethe",
    "bethe_permanent": "bethe",
    "SampledPermanent": "sampling",
    "sample_permanent": "sampling",
    "sinkhorn": "sinkhorn",
}


def __getattr__(name):
    if name in _LAZY:
        import importlib

        module = (
            "jointtrack.assignment._sinkhorn"
            if name == "sinkhorn"
            else (f"jointtrack.permanent.{_LAZY[name]}")
        )
        return getattr(importlib.import_module(module), name)
    raise AttributeError(f"module 'jointtrack.permanent' has no attribute {name!r}")


__all__ = [
    "BethePermanent",
    "InfeasibleAssignmentError",
    "SampledPermanent",
    "assignment_marginals",
    "bethe_permanent",
    "log_permanent",
    "permanent",
    "sample_permanent",
    "sinkhorn",
]
