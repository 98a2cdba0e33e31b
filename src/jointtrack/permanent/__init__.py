"""Permanents of non-negative matrices and assignment marginals.

The permanent of an n×m non-negative matrix A (n ≤ m) is the sum over injective
maps σ of rows into columns of Π_t A[t, σ(t)] (Schaub eq. 32). Every hard step
of jointtrack (JPDA marginals, particle weights, identity probabilities) is this
sum or one of its minors.

Exact methods
-------------
``"dp"``        cancellation-free subset dynamic programme (only adds and
                multiplies non-negative numbers: relative error ≤ 2n·u).
``"multiset"``  the same programme over group counts for repeated rows/columns
                (Schaub eq. 36–37: Π(n_j+1) states, smaller orientation chosen).
``"glynn"``     Glynn's formula in Gray-code order with power-of-two Sinkhorn
                pre-balancing and double-double row sums (fast, square only).
``"ryser"``     Ryser's formula (Schaub eq. 35), same safeguards.
``"reference"`` exact rational arithmetic (slow; for tests).

Approximations
--------------
:func:`bethe_permanent` (belief propagation) and :func:`sample_permanent`
(sequential importance sampling with a standard error).
"""

from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.assignment.sinkhorn import sinkhorn
from jointtrack.permanent.exact import log_permanent, permanent
from jointtrack.permanent.marginals import assignment_marginals

# The approximations pull in scipy.optimize (~0.2 s); import them on first use so
# that a process computing exact permanents starts fast.
_LAZY = {
    "BethePermanent": "bethe",
    "bethe_permanent": "bethe",
    "SampledPermanent": "sampling",
    "sample_permanent": "sampling",
}


def __getattr__(name):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"jointtrack.permanent.{_LAZY[name]}"), name)
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
