"""Issue 31, the JPDA/JIPDA tracker and the shared tracker layer (defect 13).

* 13 — ``save(<directory>)`` raised a raw IsADirectoryError and left ``<dir>.tmp``.
"""

from __future__ import annotations

import errno
import os

import numpy as np
import pytest

from jointtrack.trackers import JPDATracker, StateFileError, TrackerConfig, state_io


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
