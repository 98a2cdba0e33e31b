"""Exceptions shared by every jointtrack module."""


class InfeasibleAssignmentError(ValueError):
    """No assignment with positive weight exists.

    Raised where a probability would otherwise be 0/0: the permanent (or the
    JPDA normaliser) of the input is zero, so no marginal is defined.
    """
