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


def assert_steps_alike(a, b, scans, fields=("ids", "x", "P", "existence")) -> None:
    """Trackers ``a`` and ``b`` (e.g. a run and its saved-and-loaded copy) step through
    ``scans`` (``(t, z)`` pairs) to the same ``fields`` of every ScanResult, bit for bit."""
    for t, z in scans:
        ra, rb = a.step(t, z), b.step(t, z)
        for name in fields:
            np.testing.assert_array_equal(getattr(ra, name), getattr(rb, name), err_msg=name)
