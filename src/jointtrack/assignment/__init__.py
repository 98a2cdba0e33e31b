r"""The assignment-sum core: one exact engine under every face of jointtrack.

Every hard step of the four papers behind jointtrack is one sum over the
(partial) assignments of a non-negative matrix:

.. math::

    Z = \sum_{\sigma} \prod_{r:\,\sigma(r) \ne \varnothing} W_{r\sigma(r)}
        \prod_{r:\,\sigma(r) = \varnothing} u_r .

Permanents (u = 0), JPDA association probabilities (u = miss), Streit's particle
weights and Schaub's identity probabilities are thin faces on
:func:`assignment_sum`; see :mod:`jointtrack.assignment.core` for the algorithm
and its references.

Layout
------
``core``             :func:`assignment_sum`, :class:`AssignmentResult`, method choice
``_checks``          argument validation shared by the whole package
``feasibility``      :func:`is_feasible` — the one feasibility test (bipartite matching)
``lsap``             :func:`linear_assignment` — the one assignment solver (with duals)
``scaling``          power-of-two scaling from the assignment dual
``_sinkhorn``        :func:`sinkhorn` (Schaub eq. 38) and pre-balancing for Glynn
``_splitfloat``      mantissa/exponent arithmetic for leaf folding
``_fold``            leaf folding, unfolding, components
``_plan``            frontier-DP layer order and slots
``_kernels``         blocked frontier-DP layer kernels
``_frontier``        frontier-DP forward–backward driver
``_groups``          group-count DP for repeated rows/columns (Schaub eq. 36–37)
``_inclusion_exclusion``  Glynn's and Ryser's formulas with error estimates
"""

from jointtrack.assignment.core import METHODS, AssignmentResult, assignment_sum
from jointtrack.assignment.feasibility import is_feasible
from jointtrack.assignment.lsap import LinearAssignment, linear_assignment

__all__ = [
    "METHODS",
    "AssignmentResult",
    "LinearAssignment",
    "assignment_sum",
    "is_feasible",
    "linear_assignment",
    "sinkhorn",
]


def __getattr__(name):
    # sinkhorn pulls in nothing heavy, but keep the import graph one-way. Its module
    # is _sinkhorn: a submodule named sinkhorn would replace this function as the
    # package attribute as soon as anything imported it.
    if name == "sinkhorn":
        from jointtrack.assignment._sinkhorn import sinkhorn

        return sinkhorn
    raise AttributeError(f"module 'jointtrack.assignment' has no attribute {name!r}")
