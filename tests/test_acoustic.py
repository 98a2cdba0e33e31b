"""The ``acoustic`` scenario and ``jointtrack run --scenario acoustic``."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from cli_checks import one_line_error
from jointtrack.cli import app
from jointtrack.scenarios import acoustic
from jointtrack.scenarios.acoustic import acoustic_gain, acoustic_sensor_grid

runner = CliRunner()
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_sensor_grid_and_gain():
    s = acoustic_sensor_grid()
    assert s.shape == (25, 2)
    assert sorted(set(s[:, 0])) == [0, 10, 20, 30, 40] == sorted(set(s[:, 1]))
    x = np.array([[3.0, 4.0, 9.0, 9.0]])  # 5 m from the sensor at the origin
    g = acoustic_gain(x, s)
    assert g.shape == (1, 25)
    assert g[0, 0] == pytest.approx(10.0 / 5.1)
    assert acoustic_gain(x[:, :2], s) == pytest.approx(g)  # velocities are ignored


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n_scans=st.integers(10, 60))
def test_scenario_has_three_to_five_targets_with_births_and_a_death(seed, n_scans):
    sc = acoustic(seed=seed, n_scans=n_scans)
    assert sc.measurements.shape == (n_scans, 25)
    assert 3 <= sc.n_targets <= 5
    born, died = sc.info["born"], sc.info["died"]
    assert born.count(0) >= 2 and any(b > 0 for b in born)
    assert any(d is not None for d in died)
    for k in range(n_scans):
        alive = [i for i in range(len(born)) if born[i] <= k and (died[i] is None or died[i] > k)]
        assert sc.truth_ids[k].tolist() == alive
        assert sc.truth_states[k].shape == (len(alive), 4)
        assert np.all((sc.truth_positions[k] >= 0) & (sc.truth_positions[k] <= 40))


def test_readings_are_the_sum_of_contributions_plus_the_stated_noise():
    sc = acoustic(seed=3, n_scans=400)
    clean = np.stack([sc.g(s).sum(axis=0) for s in sc.truth_states])
    resid = sc.measurements - clean
    # 10,000 draws of N(0, 0.01): mean within 4 sd (0.004), variance within 5 %
    assert abs(resid.mean()) < 4e-3
    assert resid.var() == pytest.approx(0.01, rel=0.05)
    np.testing.assert_allclose(sc.noise_cov, 0.01 * np.eye(25))


def test_same_seed_same_scenario_and_bad_input():
    a, b = acoustic(seed=5), acoustic(seed=5)
    np.testing.assert_array_equal(a.measurements, b.measurements)
    t = a.truth_table()
    assert t[2].shape == (t[0].size, 2)
    with pytest.raises(ValueError, match="n_scans"):
        acoustic(n_scans=5)
    with pytest.raises(ValueError, match="noise_variance"):
        acoustic(noise_variance=0.0)
    with pytest.raises(ValueError, match="speed_range"):
        acoustic(speed_range=(1.0, 0.5))
    with pytest.raises(ValueError, match="seed"):
        acoustic(seed=-1)


@pytest.mark.parametrize("filt", ["sps-cphd", "sps-mb", "sps-phd"])
def test_run_writes_tracks_metrics_and_plot(tmp_path, filt):
    out = tmp_path / "out"
    args = ["run", "--scenario", "acoustic", "--max-scans", "4", "--particles", "300"]
    args += ["--out", str(out), "--no-progress"]
    if filt != "sps-cphd":
        args += ["--filter", filt]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    assert f"{filt} (gaussian likelihood)" in res.output
    with open(out / "tracks.csv", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time", "track_id", "x", "y", "vx", "vy"]
    m = json.loads((out / "metrics.json").read_text(encoding="utf-8"))
    assert m["filter"]["name"] == filt and m["filter"]["likelihood"] == "gaussian"
    assert len(m["ospa"]["per_scan"]) == 4 == len(m["gospa"]["per_scan"])
    assert all(0 <= v <= 10 for v in m["ospa"]["per_scan"])
    assert m["cardinality"]["estimated"] == [
        sum(1 for r in rows[1:] if float(r[0]) == t) for t in range(4)
    ]
    assert (out / "acoustic.png").read_bytes()[:8] == PNG_MAGIC


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--detections", "d.csv"], "--detections does not apply"),
        (["--tracker", "particle"], "--tracker does not apply"),
        (["--checkpoint", "c.ckpt"], "--checkpoint does not apply"),
        (["--resume", "c.ckpt"], "--resume does not apply"),
        (["--weights", "exact"], "--weights does not apply"),
        (["--format", "parquet"], "tracks.csv only"),
        (["--filter", "sps-foo"], "--filter must be one of"),
        (["--likelihood", "magic"], "--likelihood must be one of"),
    ],
)
def test_run_refuses_flags_that_do_not_apply(tmp_path, extra, needle):
    res = runner.invoke(
        app, ["run", "--scenario", "acoustic", "--out", str(tmp_path / "o"), *extra]
    )
    one_line_error(res, needle)


def test_filter_flag_needs_the_acoustic_scenario():
    res = runner.invoke(app, ["run", "--filter", "sps-mb"])
    one_line_error(res, "--scenario acoustic only")
