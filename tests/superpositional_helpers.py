"""Setup shared by the tests of ``jointtrack.superpositional`` (sensor, noise, option checks)."""

from __future__ import annotations

import numpy as np
import pytest

from jointtrack.superpositional import MultiBernoulli, likelihood

#: the measurement matrix of the report's examples (dx = 2 → dy = 3), as in
#: ``jointtrack.experiments.nannuru.PAPER["H"]``
H3 = np.array([[0.1, 0.7], [0.5, 0.5], [0.8, 0.2]])
#: measurement noise covariance Σ0 of the likelihood tests
S0 = 0.25 * np.eye(3)


def assert_option_rejected(method, option, value, match):
    """``likelihood(..., method=method, option=value)`` raises a ValueError matching ``match``."""
    model = MultiBernoulli([0.5], [[0.0, 0.0]], [np.eye(2)])
    with pytest.raises(ValueError, match=match):
        likelihood(np.zeros(3), model, H3, S0, method=method, **{option: value})
