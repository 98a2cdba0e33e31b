"""Issue 22, I/O and runs: sensor ids as labels, resume of every scenario, hostile
detection files, the parts directory, scoring with --truth, complex metric input."""

from __future__ import annotations

import json
import signal

import pytest
from typer.testing import CliRunner

from jointtrack.cli import app
from jointtrack.scenarios import GENERATORS
from test_run_durable import _cli, _rows

runner = CliRunner()


def _run(*args):
    """``jointtrack run`` in this process (the kernels stay loaded between calls)."""
    return runner.invoke(app, ["run", "--no-progress", *map(str, args)])


# ----------------------------------------------------------------------------- item 13

# small versions of every built-in detection scenario (the name comes from --scenario)
SMALL = {
    "bojilov": "n_scans = 8",
    "crossing": "n_scans = 8",
    "many": "n_targets = 12\nclutter_per_scan = 5.0\nn_scans = 8",
    "abreast": "n_scans = 8\nclutter_per_scan = 10.0",
}


def test_every_detection_scenario_is_covered():
    assert set(SMALL) == set(GENERATORS)


@pytest.mark.parametrize("name", sorted(SMALL))
def test_killed_scenario_run_resumes_from_the_checkpoint_alone(tmp_path, name):
    (tmp_path / "small.toml").write_text(f"[scenario]\nseed = 2\n{SMALL[name]}\n")
    base = ["--scenario", name, "--config", tmp_path / "small.toml"]
    full = _run(*base, "--out", tmp_path / "full")
    assert full.exit_code == 0, full.output
    args = [*base, "--out", "part", "--checkpoint", "ck.npz", "--checkpoint-every", "2"]
    killed = _cli(["run", *args], tmp_path, fault="scan:4")  # a subprocess, killed
    assert killed.returncode == -signal.SIGKILL
    resumed = _run("--resume", tmp_path / "ck.npz")
    assert resumed.exit_code == 0, resumed.output
    assert _rows(tmp_path / "part", "csv") == _rows(tmp_path / "full", "csv")
    got = json.loads((tmp_path / "part" / "metrics.json").read_text())
    want = json.loads((tmp_path / "full" / "metrics.json").read_text())
    assert got["gospa"] == want["gospa"] and got["n_scans"] == want["n_scans"] == 8
