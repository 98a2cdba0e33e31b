"""Exceptions shared by every jointtrack module."""


class InfeasibleAssignmentError(ValueError):
    """No assignment with positive weight exists.

    Raised where a probability would otherwise be 0/0: the permanent (or the
    JPDA normaliser) of the input is zero, so no marginal is defined.
    """


class ExactLimitError(ValueError):
    """An exact computation would exceed its state or memory budget.

    Raised before any large allocation; the message says which budget
    (``max_bits``, ``max_memory``) and how much the problem needs. Callers such as
    the tracker catch it to switch to an approximation.
    """


class CoincidentReturnsWarning(UserWarning):
    """A scan held exactly coincident returns (identical measurement vectors).

    A stuck or replayed detector repeats a return; the JPDA tracker keeps one of
    each set of identical returns of a scan (the message gives the count).
    """
