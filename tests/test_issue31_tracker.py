"""Issue 31, the JPDA/JIPDA tracker and the shared tracker layer (defects 9, 13).

* 9 — ``max_speed = 1e200`` was accepted and the first step overflowed; every
  setting squared into a covariance is bounded now (``MAX_STD``, ``MAX_VARIANCE``).
* 13 — ``save(<directory>)`` raised a raw IsADirectoryError and left ``<dir>.tmp``.
"""

from __future__ import annotations

import errno
import math
import os
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jointtrack.io.detections import MAX_COORDINATE
from jointtrack.trackers import JPDATracker, StateFileError, TrackerConfig, state_io
from jointtrack.trackers.config import MAX_STD, MAX_VARIANCE
from jointtrack.trackers.pmbm import PMBMTracker, PMBTracker
from jointtrack.trackers.pmbm_config import PMBMConfig

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ------------------------------------------------------------- 9. bounded settings
def test_the_std_limit_is_the_coordinate_limit():
    assert MAX_STD == MAX_COORDINATE
    assert MAX_VARIANCE == pytest.approx(MAX_STD**2, rel=1e-15)


_STD_FIELDS = ("max_speed", "max_acceleration")
_VARIANCE_FIELDS = ("process_noise", "range_noise", "bearing_noise", "measurement_noise")
_TRACKERS = [(JPDATracker, TrackerConfig), (PMBTracker, PMBMConfig), (PMBMTracker, PMBMConfig)]


def _run_scans(trk, n=4):
    rng = np.random.default_rng(1)
    for t in range(n):
        z = np.array([[3.0 * t, 0.0], [50.0, 2.0 * t]]) + rng.normal(0, 1, (2, 2))
        trk.step(float(t), z)


@pytest.mark.parametrize(("tracker", "config"), _TRACKERS)
@pytest.mark.parametrize("motion", ["cv", "ca"])
@pytest.mark.parametrize(
    "limits",
    [
        {"max_speed": MAX_STD},
        {"max_acceleration": MAX_STD},
        {"process_noise": MAX_VARIANCE},
        {"max_speed": MAX_STD, "max_acceleration": MAX_STD, "process_noise": MAX_VARIANCE},
    ],
)
def test_settings_at_their_limit_step_without_overflow(tracker, config, motion, limits):
    """At the limit a run steps with no overflow warning and finite states (at ef50439
    max_speed = 1e200 was accepted and the first step raised OverflowError)."""
    trk = tracker(config(motion=motion, **limits))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an overflow (RuntimeWarning) fails the test
        _run_scans(trk)
    if tracker is JPDATracker:
        assert np.isfinite(trk.x).all() and np.isfinite(trk.P).all()
        assert np.isfinite(trk.existence).all()


def test_jpda_at_every_limit_at_once_and_reported_velocities():
    cfg = TrackerConfig(
        motion="ca",
        max_speed=MAX_STD,
        max_acceleration=MAX_STD,
        process_noise=MAX_VARIANCE,
        measurement_noise=MAX_VARIANCE,
        velocity_std=MAX_STD,
    )
    trk = JPDATracker(cfg)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _run_scans(trk)
        for t in range(4, 8):  # tracks seeded with reported velocities of σ = MAX_STD
            trk.step(float(t), np.array([[0.0, 1e3 * t]]), velocities=[[1.0, 2.0]])
    assert np.isfinite(trk.x).all() and np.isfinite(trk.P).all()


def _beyond(limit):
    return st.one_of(
        st.just(float(np.nextafter(limit, math.inf))),
        st.floats(limit, 1.7976931348623157e308, exclude_min=True),
        st.just(10**400),  # an int beyond the float range
    )


@SETTINGS
@given(data=st.data(), cls=st.sampled_from([TrackerConfig, PMBMConfig]))
def test_settings_beyond_their_limit_are_refused_naming_field_and_limit(data, cls):
    fields = (*_STD_FIELDS, *_VARIANCE_FIELDS) + (("velocity_std",) if cls is TrackerConfig else ())
    field = data.draw(st.sampled_from(fields))
    limit = MAX_VARIANCE if field in _VARIANCE_FIELDS else MAX_STD
    value = data.draw(_beyond(limit))
    with pytest.raises(ValueError) as info:
        cls(**{field: value})
    message = str(info.value)
    assert message.startswith(f"{cls.__name__}: {field}")
    if not isinstance(value, int):
        assert f"{limit:g}" in message
    # the limit itself is accepted
    cls(**{field: limit})


def test_measurement_noise_the_filters_cannot_factor_is_refused_naming_the_settings():
    """Accepted before, then the first update (or the tracker's constructor) refused a
    "numerically singular" R naming no setting."""
    cases = [
        (dict(measure_velocity=True, velocity_std=1e9, measurement_noise=1.0), "velocity_std"),
        (dict(measure_velocity=True, velocity_std=MAX_STD), "velocity_std"),
        (dict(measurement_noise=[[1e300, 0.0], [0.0, 1.0]]), "measurement_noise"),
        (dict(sensor="range-bearing", range_noise=1e8, bearing_noise=1e-10), "bearing_noise"),
    ]
    for kwargs, name in cases:
        with pytest.raises(ValueError, match=name) as info:
            TrackerConfig(**kwargs)
        assert str(info.value).startswith("TrackerConfig:")
    with pytest.raises(ValueError, match="^PMBMConfig: measurement_noise"):
        PMBMConfig(measurement_noise=[[1e300, 0.0], [0.0, 1.0]])
    # within the filters' range: accepted, and a run steps
    cfg = TrackerConfig(measure_velocity=True, velocity_std=1e6, measurement_noise=1.0)
    trk = JPDATracker(cfg)
    trk.step(0.0, np.array([[0.0, 0.0]]), velocities=[[1.0, 0.0]])
    trk.step(1.0, np.array([[1.0, 0.0]]), velocities=[[1.0, 0.0]])


# ------------------------------------------------------------- 13. save
def _tracker_with_state():
    trk = JPDATracker(TrackerConfig(clutter_density=1e-4))
    for t in range(3):
        trk.step(float(t), np.array([[t, 0.0], [40.0, t]]))
    return trk


def _leftovers(directory):
    return sorted(p.name for p in directory.iterdir())


def test_save_to_a_directory_is_refused_naming_it_and_leaves_nothing(tmp_path):
    target = tmp_path / "state"
    target.mkdir()
    (target / "keep.txt").write_text("mine")
    trk = _tracker_with_state()
    with pytest.raises(StateFileError, match="state: cannot write the tracker state") as info:
        trk.save(target)
    assert str(target) in str(info.value) and "directory" in str(info.value)
    assert _leftovers(tmp_path) == ["state"]  # no state.tmp
    assert _leftovers(target) == ["keep.txt"]


def test_save_into_a_missing_directory_is_refused_naming_it(tmp_path):
    trk = _tracker_with_state()
    target = tmp_path / "nowhere" / "state.npz"
    with pytest.raises(StateFileError, match="does not exist") as info:
        trk.save(target)
    assert str(target) in str(info.value)
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("stage", ["savez", "fsync", "replace"])
@pytest.mark.parametrize(
    "fault", [OSError(errno.ENOSPC, "No space left on device"), KeyboardInterrupt]
)
def test_a_failing_save_leaves_the_old_state_and_no_temporary_file(
    tmp_path, monkeypatch, stage, fault
):
    """Fault injection at each stage of the write: a full disk becomes StateFileError
    naming the file, an interrupt stays an interrupt; either way the state file already
    there is byte for byte the old one (and loads), and no temporary file remains."""
    trk = _tracker_with_state()
    path = tmp_path / "run.npz"
    trk.save(path)
    before = path.read_bytes()
    trk.step(3.0, np.array([[3.0, 0.0], [40.0, 3.0]]))

    def boom(*args, **kwargs):
        if stage == "savez" and args:  # write part of the archive first
            args[0].write(b"PK\x03\x04 partial")
        raise fault

    target = {
        "savez": (state_io.np, "savez"),
        "fsync": (state_io.os, "fsync"),
        "replace": (state_io.os, "replace"),
    }[stage]
    monkeypatch.setattr(*target, boom)
    expected = StateFileError if isinstance(fault, OSError) else KeyboardInterrupt
    with pytest.raises(expected) as info:
        trk.save(path)
    monkeypatch.undo()
    if expected is StateFileError:
        assert str(path) in str(info.value) and "No space left" in str(info.value)
    assert path.read_bytes() == before
    assert _leftovers(tmp_path) == ["run.npz"]
    assert JPDATracker.load(path).n_scans == 3


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_save_into_a_read_only_directory_is_refused_and_changes_nothing(tmp_path):
    trk = _tracker_with_state()
    path = tmp_path / "run.npz"
    trk.save(path)
    before = path.read_bytes()
    tmp_path.chmod(0o500)
    try:
        with pytest.raises(StateFileError, match="cannot write the tracker state"):
            trk.save(path)
    finally:
        tmp_path.chmod(0o700)
    assert path.read_bytes() == before
    assert _leftovers(tmp_path) == ["run.npz"]
