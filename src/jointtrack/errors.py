"""Exceptions and warnings shared by every jointtrack module.

* :class:`InfeasibleAssignmentError` — no assignment has positive weight;
* :class:`ExactLimitError` — an exact computation would exceed its budget;
* :class:`CoincidentReturnsWarning` — a scan held identical returns.

Bad arguments raise :class:`ValueError` or :class:`TypeError` with a message
naming the argument; both errors here are :class:`ValueError` subclasses, so
``except ValueError`` catches them too.
"""


class InfeasibleAssignmentError(ValueError):
    """No assignment with positive weight exists, so no probability is defined.

    Raised where a probability would otherwise be 0/0: the permanent (or the
    JPDA normaliser) of the input is zero, so no marginal is defined. For
    example :func:`jointtrack.permanent.assignment_marginals` of a matrix whose rows
    cannot all be matched to distinct columns through non-zero entries, or a
    JPDA cluster (:func:`jointtrack.association.marginals`) in which a track
    with miss weight 0 (P_D = 1) gates no measurement. The message names what
    is infeasible; the JPDA tracker never raises it for data it generated
    itself (its miss weights are positive).

    Handle it by checking the model (P_D < 1, gates, zero rows) rather than by
    retrying: the input has no answer.
    """


class ExactLimitError(ValueError):
    """An exact computation would exceed its state or memory budget.

    Raised by the exact engines (:mod:`jointtrack.assignment`, JPDA ``method =
    "exact"``, exact permanents) before any large allocation; the message says
    which budget (``max_bits``, ``max_memory``) and how much the problem needs.
    The tracker catches it and solves that cluster by its ``approximation``
    (the count is in ``metrics.json`` ``association.fallbacks``); a direct
    caller may raise the budget or choose an approximate method (``lbp``,
    ``mcmc``, ``kbest``).
    """


class CoincidentReturnsWarning(UserWarning):
    """A scan held exactly coincident returns (identical measurement vectors).

    Warned by :meth:`jointtrack.trackers.JPDATracker.step` when a stuck or
    replayed detector repeats a return: the tracker keeps one of each set of
    identical returns of a scan (the message gives the count), since two
    identical returns would split one target's weight between them. ``jointtrack
    run`` counts them in ``metrics.json`` (``coincident_returns``) instead of
    warning per scan.
    """
