"""`jointtrack run` loses nothing: SIGKILL at any stage of any scan, then `--resume` alone.

Each case runs the CLI in a subprocess that kills itself (fault injection,
``JOINTTRACK_FAULT``, see :mod:`jointtrack.experiments.writers`) at a chosen
stage of a chosen scan, then resumes with ``--resume CHECKPOINT`` and no other
flag, and compares the tracks with an uninterrupted run row for row.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest

CONFIG = """
[scenario]
name = "crossing"
seed = 4
n_scans = 20
clutter_per_scan = 4.0
"""


def _cli_command(args, fault=None):
    """``(argv, env)`` of the CLI in a subprocess, with the fault to inject (or None)."""
    env = dict(os.environ)
    env.pop("JOINTTRACK_FAULT", None)
    if fault:
        env["JOINTTRACK_FAULT"] = fault
    # Ctrl-C as from a terminal: a runner that ignores SIGINT (pytest-xdist's workers do)
    # passes SIG_IGN on to its children, and Python then installs no KeyboardInterrupt
    code = (
        "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
        "from jointtrack.cli import main; sys.argv[0] = 'jointtrack'; main()"
    )
    return [sys.executable, "-c", code, *map(str, args)], env


def _cli(args, cwd, fault=None):
    argv, env = _cli_command(args, fault)
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def _rows(out, fmt):
    if fmt == "csv":
        return (out / "tracks.csv").read_bytes()
    table = pq.read_table(out / "tracks.parquet")
    return {n: table.column(n).to_numpy().tolist() for n in table.column_names}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    base = tmp_path_factory.mktemp("ref")
    (base / "run.toml").write_text(CONFIG)
    out = {}
    for fmt in ("csv", "parquet"):
        r = _cli(["run", "--config", "run.toml", "--out", f"full-{fmt}", "--format", fmt], base)
        assert r.returncode == 0, r.stderr
        out[fmt] = (
            _rows(base / f"full-{fmt}", fmt),
            json.loads((base / f"full-{fmt}" / "metrics.json").read_text()),
        )
    return out


# every stage of the commit protocol, both formats, SIGKILL/SIGTERM/SIGINT, early and late
CASES = [
    ("csv", "scan:2"),
    ("csv", "part:7"),
    ("parquet", "checkpoint:11"),
    ("csv", "scan:13:TERM"),
    ("parquet", "scan:17:INT"),
]


@pytest.mark.parametrize("fmt, fault", CASES)
def test_killed_run_resumes_to_the_uninterrupted_output(tmp_path, reference, fmt, fault):
    (tmp_path / "run.toml").write_text(CONFIG)
    args = ["run", "--config", "run.toml", "--out", "part", "--format", fmt]
    args += ["--checkpoint", "ck.npz", "--checkpoint-every", "4"]
    killed = _cli(args, tmp_path, fault=fault)
    assert killed.returncode != 0, "the fault did not stop the run"
    if fault.endswith(":INT"):
        assert killed.returncode == 130 and "--resume" in killed.stderr + killed.stdout
    elif fault.count(":") == 1:
        assert killed.returncode == -signal.SIGKILL
    if (tmp_path / "ck.npz").exists():
        resumed = _cli(["run", "--resume", "ck.npz"], tmp_path)
    else:  # killed before the first checkpoint: nothing to resume, run again
        resumed = _cli(args, tmp_path)
    assert resumed.returncode == 0, resumed.stderr + resumed.stdout
    rows, metrics = reference[fmt]
    assert _rows(tmp_path / "part", fmt) == rows
    got = json.loads((tmp_path / "part" / "metrics.json").read_text())
    assert got["gospa"] == metrics["gospa"] and got["tracks"] == metrics["tracks"]
    assert got["n_scans"] == metrics["n_scans"]


def test_resume_alone_extends_a_shortened_run(tmp_path, reference):
    (tmp_path / "run.toml").write_text(CONFIG)
    args = ["run", "--config", "run.toml", "--out", "part", "--checkpoint", "ck.npz"]
    assert _cli([*args, "--max-scans", "9"], tmp_path).returncode == 0
    short = np.loadtxt(tmp_path / "part" / "tracks.csv", delimiter=",", skiprows=1, ndmin=2)
    assert short[:, 0].max() <= 8
    r = _cli(["run", "--resume", "ck.npz"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert _rows(tmp_path / "part", "csv") == reference["csv"][0]


@pytest.fixture(scope="module")
def shortened(tmp_path_factory):
    """A run stopped after 6 scans with its checkpoint: the refusals below leave it as it is."""
    base = tmp_path_factory.mktemp("short")
    (base / "run.toml").write_text(CONFIG)
    args = ["run", "--config", "run.toml", "--out", "part", "--checkpoint", "ck.npz"]
    assert _cli([*args, "--max-scans", "6"], base).returncode == 0
    return base


@pytest.mark.parametrize(
    "extra, flag",
    [
        (["--out", "elsewhere"], "--out"),
        (["--format", "parquet"], "--format"),
        (["--seed", "9"], "--seed"),
        (["--scenario", "bojilov"], "--scenario"),
    ],
)
def test_conflicting_flag_on_resume_is_named(shortened, extra, flag):
    before = {p: p.stat().st_mtime_ns for p in shortened.rglob("*")}
    r = _cli(["run", "--resume", "ck.npz", *extra], shortened)
    assert r.returncode != 0
    assert flag in r.stderr + r.stdout and "Traceback" not in r.stderr
    # refused before anything was written: the next case finds the same run
    assert {p: p.stat().st_mtime_ns for p in shortened.rglob("*")} == before


def test_bad_output_paths_fail_before_the_first_scan(tmp_path):
    (tmp_path / "run.toml").write_text(CONFIG)
    (tmp_path / "afile").write_text("x")
    r = _cli(["run", "--config", "run.toml", "--out", "afile"], tmp_path)
    assert r.returncode != 0 and "is a file" in r.stderr + r.stdout
    r = _cli(
        ["run", "--config", "run.toml", "--out", "o", "--checkpoint", "missing/dir/ck.npz"],
        tmp_path,
    )
    assert r.returncode != 0 and "does not exist" in r.stderr + r.stdout
    assert not (tmp_path / "o" / "tracks.csv").exists()


def test_reused_out_is_cleared_of_old_outputs(tmp_path):
    (tmp_path / "run.toml").write_text(CONFIG)
    out = tmp_path / "o"
    assert _cli(["run", "--config", "run.toml", "--out", "o", "--format", "parquet"], tmp_path)
    assert (out / "tracks.parquet").exists()
    r = _cli(["run", "--config", "run.toml", "--out", "o", "--max-scans", "5"], tmp_path)
    assert r.returncode == 0
    assert not (out / "tracks.parquet").exists()  # the old run's file is gone
    assert (out / "tracks.csv").exists()
