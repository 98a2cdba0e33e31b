"""Shared assertions of the tests' state checks: a failing step leaves state unchanged, a
saved-and-loaded tracker steps alike, a state file written before a setting existed loads."""

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


def load_state_without(tracker, key: str, folder, cls=None):
    """``tracker`` saved, its config's ``key`` removed from the file (a state file of a
    version before that setting existed, written as it wrote them) and loaded back with
    ``cls.load`` (default: the tracker's class); returns the loaded tracker."""
    from jointtrack.trackers.state_io import read_state, write_state

    arrays, config, scalars, rng = read_state(tracker.save(folder / "now.npz"))
    assert key in config, key  # the setting is saved now: the test removes it
    config.pop(key)
    write_state(folder / "before.npz", arrays, config, scalars, rng)
    return (cls or type(tracker)).load(folder / "before.npz")
