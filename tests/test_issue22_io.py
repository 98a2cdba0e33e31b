"""Issue 22, I/O and runs: sensor ids as labels, resume of every scenario, hostile
detection files, the parts directory, scoring with --truth, complex metric input."""

from __future__ import annotations

import json
import signal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
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


# ----------------------------------------------------------------------------- item 15

finite = st.floats(-1e300, 1e300, allow_nan=False, allow_subnormal=True)


@settings(max_examples=25, deadline=None)
@given(
    pts=st.lists(st.tuples(finite, finite), min_size=1, max_size=4),
    imag=finite.filter(lambda v: v != 0),
    which=st.sampled_from(["X", "Y"]),
    fn=st.sampled_from(["ospa", "gospa"]),
)
def test_complex_points_are_refused_naming_the_argument(pts, imag, which, fn):
    from jointtrack.metrics import gospa, ospa

    real = np.array(pts, dtype=np.float64)
    bad = real.astype(np.complex128)
    bad[0, 0] += 1j * imag
    args = {"X": real, "Y": real, which: bad}
    with pytest.raises(ValueError, match=rf"^{which} has complex entries"):
        {"ospa": ospa, "gospa": gospa}[fn](args["X"], args["Y"], c=1.0)


@pytest.mark.parametrize("arg", ["c", "p", "alpha"])
def test_complex_or_boolean_parameters_are_refused(arg):
    from jointtrack.metrics import gospa

    names = {"c": "cut-off c", "p": "order p", "alpha": "alpha"}
    for value in (1 + 1j, True):
        with pytest.raises(ValueError, match=names[arg]):
            gospa([[0.0, 0.0]], [[1.0, 1.0]], **{"c": 5.0, arg: value})


@pytest.mark.parametrize("column", [0, 1, 2])
def test_complex_tables_are_refused_by_gospa_series(column):
    from jointtrack.metrics import gospa_series

    table = [np.array([0.0, 1.0]), np.array([1, 1]), np.array([[0.0, 0.0], [1.0, 1.0]])]
    bad = list(table)
    bad[column] = table[column] + 0.5j
    name = ["truth times", "truth: ids", "truth positions"][column]
    with pytest.raises(ValueError, match=name):
        gospa_series(*bad, *table, c=5.0)
