"""Every file the package writes goes through one atomic write (jointtrack._atomic):
a failure at any stage — the body, the sync, the rename; an error or Ctrl-C — leaves
the file that was there byte for byte and no temporary file."""

from __future__ import annotations

import errno

import numpy as np
import pytest

import jointtrack._atomic as atomic_module
from jointtrack._atomic import atomic_file
from jointtrack.io import write_metrics, write_tracks

FAULTS = [OSError(errno.ENOSPC, "No space left on device"), KeyboardInterrupt()]


def _table(n):
    return {
        "time": np.arange(n, dtype=float),
        "track_id": np.arange(n),
        "x": np.linspace(0.0, 1.0, n),
        "y": np.zeros(n),
        "vx": np.ones(n),
        "vy": np.zeros(n),
    }


WRITERS = {
    "metrics.json": lambda path, k: write_metrics({"run": k, "gospa": [1.5, k]}, path),
    "tracks.csv": lambda path, k: write_tracks(_table(3 + k), path),
    "tracks.csv.gz": lambda path, k: write_tracks(_table(3 + k), path),
    "tracks.parquet": lambda path, k: write_tracks(_table(3 + k), path),
}


@pytest.mark.parametrize("name", list(WRITERS))
@pytest.mark.parametrize("stage", ["fsync", "replace"])
@pytest.mark.parametrize("fault", FAULTS)
def test_a_failing_write_leaves_the_old_file(tmp_path, monkeypatch, name, stage, fault):
    path = tmp_path / name
    WRITERS[name](path, 0)
    before = path.read_bytes()

    def boom(*args, **kwargs):
        raise fault

    monkeypatch.setattr(atomic_module.os, stage, boom)
    with pytest.raises(type(fault)):
        WRITERS[name](path, 1)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]
    WRITERS[name](path, 1)  # and the next write goes through
    assert path.read_bytes() != before


@pytest.mark.parametrize("fault", FAULTS)
def test_a_failing_body_leaves_the_old_file_and_no_temporary(tmp_path, fault):
    path = tmp_path / "out.bin"
    path.write_bytes(b"old")
    with pytest.raises(type(fault)), atomic_file(path) as tmp:
        tmp.write_bytes(b"half of the ne")
        raise fault
    assert path.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]
    with atomic_file(path, tmp_path / ".out.partial") as tmp:
        assert tmp.name == ".out.partial"
        tmp.write_bytes(b"new")
    assert path.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]
