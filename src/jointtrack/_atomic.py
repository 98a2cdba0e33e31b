"""Files written atomically: the one temporary-file-and-rename of the package.

A file is written to a temporary name beside it, flushed to disk (``fsync``),
renamed over the final name (``os.replace``, atomic on POSIX) and the rename
made durable by syncing the directory. A kill at any instant therefore leaves
either the old file or the new one whole, never a mixture; on any failure the
temporary file is removed and the old file is untouched. Used for the run's
outputs (:mod:`jointtrack.experiments.writers`), tracker state files
(:mod:`jointtrack.trackers.state_io`) and the sweep store
(:mod:`jointtrack.sweep.store`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_file", "fsync_directory"]


def fsync_directory(path) -> None:
    """Make renames in the directory ``path`` durable (best effort: some file systems
    cannot sync a directory, and there the rename is as durable as it gets)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextmanager
def atomic_file(
    path, tmp=None, *, before_rename: Callable[[], None] | None = None
) -> Iterator[Path]:
    """Write ``path`` atomically: the body writes the path yielded, a temporary file.

    Parameters
    ----------
    path : the final file.
    tmp : the temporary file (default: ``path`` with ``.tmp`` appended), in the same
        directory so that the rename is atomic.
    before_rename : called between the complete, synced temporary file and the
        rename (the fault-injection points of the kill tests).

    On success the temporary file is synced, renamed over ``path`` and the directory
    synced. If the body or any of these fails (an exception, Ctrl-C included), the
    temporary file is removed, ``path`` is as it was, and the exception propagates.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp") if tmp is None else Path(tmp)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        if before_rename is not None:
            before_rename()
        os.replace(tmp, path)
    except BaseException:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass  # e.g. the directory is gone or not writable: nothing was created there
        raise
    fsync_directory(path.parent)
