"""`jointtrack run` loses nothing: SIGKILL at any stage of any scan, then `--resume` alone.

Each case runs the CLI in a process of its own that kills itself (fault injection,
``JOINTTRACK_FAULT``, see :mod:`jointtrack.experiments.writers`) at a chosen
stage of a chosen scan, then resumes with ``--resume CHECKPOINT`` and no other
flag, and compares the tracks with an uninterrupted run row for row. Only the
killed runs need a process of their own; the uninterrupted runs, the resumes and
the refusals run the CLI in this process (:func:`_cli_here`; CI time: each
process of its own pays for loading kernels and, unless forked from
:mod:`cli_process`'s server, ≈ 2.5 CPU-seconds of imports).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal

import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

import cli_process
from cli_checks import one_line_error
from jointtrack.cli import app

CONFIG = """
[scenario]
name = "crossing"
seed = 4
n_scans = 20
clutter_per_scan = 4.0
"""


def _cli_env(fault=None) -> dict:
    """This process's environment with the fault to inject (or None)."""
    env = dict(os.environ)
    env.pop("JOINTTRACK_FAULT", None)
    if fault:
        env["JOINTTRACK_FAULT"] = fault
    return env


def _cli(args, cwd, fault=None):
    """The CLI in a process of its own (:mod:`cli_process`), to its end or its fault."""
    return cli_process.run(args, cwd, _cli_env(fault), timeout=300)


def _cli_here(args, cwd):
    """The CLI in this process, in ``cwd`` (a typer ``Result``: exit_code, output)."""
    with contextlib.chdir(cwd):
        return CliRunner().invoke(app, list(map(str, args)))


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
        r = _cli_here(
            ["run", "--config", "run.toml", "--out", f"full-{fmt}", "--format", fmt], base
        )
        assert r.exit_code == 0, r.output
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
        resumed = _cli_here(["run", "--resume", "ck.npz"], tmp_path)
    else:  # killed before the first checkpoint: nothing to resume, run again
        resumed = _cli_here(args, tmp_path)
    assert resumed.exit_code == 0, resumed.output
    rows, metrics = reference[fmt]
    assert _rows(tmp_path / "part", fmt) == rows
    got = json.loads((tmp_path / "part" / "metrics.json").read_text())
    assert got["gospa"] == metrics["gospa"] and got["tracks"] == metrics["tracks"]
    assert got["n_scans"] == metrics["n_scans"]


def test_resume_alone_extends_a_shortened_run(tmp_path, reference):
    (tmp_path / "run.toml").write_text(CONFIG)
    args = ["run", "--config", "run.toml", "--out", "part", "--checkpoint", "ck.npz"]
    assert _cli_here([*args, "--max-scans", "9"], tmp_path).exit_code == 0
    short = np.loadtxt(tmp_path / "part" / "tracks.csv", delimiter=",", skiprows=1, ndmin=2)
    assert short[:, 0].max() <= 8
    r = _cli_here(["run", "--resume", "ck.npz"], tmp_path)
    assert r.exit_code == 0, r.output
    assert _rows(tmp_path / "part", "csv") == reference["csv"][0]


@pytest.fixture(scope="module")
def shortened(tmp_path_factory):
    """A run stopped after 6 scans with its checkpoint: the refusals below leave it as it is."""
    base = tmp_path_factory.mktemp("short")
    (base / "run.toml").write_text(CONFIG)
    args = ["run", "--config", "run.toml", "--out", "part", "--checkpoint", "ck.npz"]
    assert _cli_here([*args, "--max-scans", "6"], base).exit_code == 0
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
    r = _cli_here(["run", "--resume", "ck.npz", *extra], shortened)
    one_line_error(r, flag, "conflicts with the checkpoint ck.npz")  # exit 2, no traceback
    # refused before anything was written: the next case finds the same run
    assert {p: p.stat().st_mtime_ns for p in shortened.rglob("*")} == before


def test_bad_output_paths_fail_before_the_first_scan(tmp_path):
    (tmp_path / "run.toml").write_text(CONFIG)
    (tmp_path / "afile").write_text("x")
    r = _cli_here(["run", "--config", "run.toml", "--out", "afile"], tmp_path)
    one_line_error(r, "--out afile", "is a file")
    r = _cli_here(
        ["run", "--config", "run.toml", "--out", "o", "--checkpoint", "missing/dir/ck.npz"],
        tmp_path,
    )
    one_line_error(r, "--checkpoint missing/dir/ck.npz", "does not exist")
    assert not (tmp_path / "o" / "tracks.csv").exists()


def test_reused_out_is_cleared_of_old_outputs(tmp_path):
    (tmp_path / "run.toml").write_text(CONFIG)
    out = tmp_path / "o"
    r = _cli_here(["run", "--config", "run.toml", "--out", "o", "--format", "parquet"], tmp_path)
    assert r.exit_code == 0, r.output  # (was `assert CompletedProcess`: always true)
    assert (out / "tracks.parquet").exists()
    r = _cli_here(["run", "--config", "run.toml", "--out", "o", "--max-scans", "5"], tmp_path)
    assert r.exit_code == 0, r.output
    assert not (out / "tracks.parquet").exists()  # the old run's file is gone
    assert (out / "tracks.csv").exists()
