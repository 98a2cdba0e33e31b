"""The CLI in a process of its own that does not import the package again (CI time).

The kill tests need ``jointtrack run`` as a real process: the fault hooks of
:mod:`jointtrack.experiments.writers` SIGKILL it (``JOINTTRACK_FAULT``), the
supervisors SIGKILL it from outside, a Ctrl-C stops it with exit code 130. Started as
``python -c "...main()"`` each such process spent ≈ 2.5 CPU-seconds importing numpy,
numba, scipy, matplotlib and the package before its first scan — most of a run killed
at its fourth scan. Here each run is a child forked from a server process that
imported those modules once (multiprocessing's ``forkserver`` start method with this
module preloaded): a process of its own with its own pid, environment, working
directory, file descriptors and exit status, killed by the same signals, that finds the
modules already imported (:data:`PRELOAD`). Nothing runs in the server but the imports: no kernel is
loaded or called there, so no thread pool (numba's OpenMP layer) exists when it forks.
The server is started by the first run of a pytest process and lives as long as it.

Only what imports the package once per process is the same here as in a fresh
interpreter: module-level state the run changes is not shared (each child is a fresh
fork of the server), but environment variables read at import time (``NUMBA_*``) are
the server's, so a test that sets those starts ``python`` itself.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: the modules every `jointtrack run` imports (`python -X importtime`), imported once by
#: the server: by name, as the server does not have the tests' directory on its path
#: (Python 3.11 passes it the path but does not set it). Importing them starts no thread.
PRELOAD = (
    "matplotlib.pyplot",
    "jointtrack.cli",
    "jointtrack.experiments.config",
    "jointtrack.experiments.plots",
    "jointtrack.experiments.run",
    "jointtrack.experiments.writers",
    "jointtrack.trackers.pmbm",
)

_context = None


def _forkserver():
    global _context
    if _context is None:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(list(PRELOAD))
        _context = ctx
    return _context


def _child(args, cwd, env, stdout, stderr):
    """The child: ``jointtrack ARGS`` in ``cwd`` with ``env``, output to the two files."""
    os.environ.clear()
    os.environ.update(env)
    os.chdir(cwd)
    for fd, path in ((1, stdout), (2, stderr)):
        target = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
        os.dup2(target, fd)
        os.close(target)
    # Ctrl-C as from a terminal: pytest-xdist's workers ignore SIGINT and the forkserver
    # passes their handlers on; Python then installs no KeyboardInterrupt
    signal.signal(signal.SIGINT, signal.default_int_handler)
    sys.argv = ["jointtrack", *args]
    from jointtrack.cli import main

    main()


class CliProcess:
    """``jointtrack ARGS`` running as a forked child; a small part of :class:`subprocess.Popen`.

    ``poll()``, ``kill()``, ``wait(timeout)``, ``returncode`` (negative: the signal that
    ended it) and, once it has ended, ``stdout`` and ``stderr`` (text; ``""`` for a
    stream not kept).
    """

    def __init__(self, args, cwd, env, *, keep_stdout=True, keep_stderr=True):
        self._dir = tempfile.TemporaryDirectory(prefix="jointtrack-cli-")
        self._paths = [
            Path(self._dir.name) / name if keep else None
            for name, keep in (("stdout", keep_stdout), ("stderr", keep_stderr))
        ]
        self.args = [str(a) for a in args]
        self._proc = _forkserver().Process(
            target=_child,
            args=(self.args, str(cwd), dict(env), *(str(p or os.devnull) for p in self._paths)),
        )
        self._proc.start()
        self.pid = self._proc.pid
        self.returncode = None
        self.stdout = self.stderr = None

    def poll(self):
        if self.returncode is None and self._proc.exitcode is not None:
            self.returncode = self._proc.exitcode
            # a child that died before it opened its files (it could not start) wrote nothing
            self.stdout, self.stderr = (
                p.read_text(errors="replace") if p is not None and p.exists() else ""
                for p in self._paths
            )
            self._proc.close()
            self._dir.cleanup()
        return self.returncode

    def wait(self, timeout=None):
        if self.returncode is not None:
            return self.returncode
        self._proc.join(timeout)
        if self.poll() is None:
            raise subprocess.TimeoutExpired(self.args, timeout)
        return self.returncode

    def kill(self):
        if self.returncode is None:
            self._proc.kill()


def start(args, cwd, env, **keep) -> CliProcess:
    """Start ``jointtrack ARGS`` in ``cwd`` with the environment ``env``."""
    return CliProcess(args, cwd, env, **keep)


def run(args, cwd, env, timeout: float) -> subprocess.CompletedProcess:
    """``jointtrack ARGS`` to its end, like ``subprocess.run(..., capture_output=True,
    text=True, timeout=timeout)``: killed and :class:`subprocess.TimeoutExpired` past it."""
    proc = start(args, cwd, env)
    deadline = time.monotonic() + timeout
    try:
        proc.wait(max(0.0, deadline - time.monotonic()))
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return subprocess.CompletedProcess(proc.args, proc.returncode, proc.stdout, proc.stderr)
