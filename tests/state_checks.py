"""Shared assertion of the tests' "a failing step leaves state unchanged" checks."""

from __future__ import annotations

import numpy as np


def assert_same_state(after: dict, before: dict) -> None:
    """Every entry of a tracker's ``state_dict()`` ``before`` equals ``after``'s, exactly."""
    for key, value in before.items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(after[key], value, err_msg=key)
        else:
            assert after[key] == value, key
