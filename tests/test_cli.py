"""The ``jointtrack`` command line: ``run``, ``reproduce bojilov``, ``--version``, ``--help``.

Small scenarios throughout (a 12–16-scan crossing via ``--config``), so the
file runs in well under a minute on a busy 2-core machine.
"""

from __future__ import annotations

import csv
import hashlib
import json

import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from cli_checks import one_line_error
from jointtrack import __version__
from jointtrack.cli import app
from jointtrack.io import Detections, read_tracks, write_detections
from jointtrack.scenarios import crossing

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
TRACK_COLUMNS = ["time", "track_id", "x", "y", "vx", "vy", "existence", "P_x_x", "P_x_y", "P_y_y"]

runner = CliRunner()


def _config(tmp_path, text: str, name: str = "run.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


SMALL = """
[scenario]
name = "crossing"
seed = 2
n_scans = 16
clutter_per_scan = 4.0

[metrics]
c = 40.0
"""


def _run(*args):
    return runner.invoke(app, ["run", "--no-progress", *map(str, args)])


def _png(path):
    assert path.exists(), path
    assert path.read_bytes()[:8] == PNG_MAGIC


# ----------------------------------------------------------------------------- basics


def test_version():
    r = runner.invoke(app, ["--version"])
    assert r.exit_code == 0
    assert r.output.strip() == f"jointtrack {__version__}"


def test_help_lists_commands_and_options():
    r = runner.invoke(app, ["--help"])
    assert r.exit_code == 0
    for cmd in ("run", "reproduce", "bench"):
        assert cmd in r.output
    r = runner.invoke(app, ["run", "--help"])
    assert r.exit_code == 0
    for opt in (
        "--detections",
        "--config",
        "--scenario",
        "--out",
        "--seed",
        "--format",
        "--checkpoint",
        "--checkpoint-every",
        "--resume",
    ):
        assert opt in r.output
    r = runner.invoke(app, ["reproduce", "bojilov", "--help"])
    assert r.exit_code == 0 and "--runs" in r.output and "--quick" in r.output
    r = runner.invoke(app, ["bench", "--help"])
    assert r.exit_code == 0 and "permanent" in r.output and "association" in r.output


# ----------------------------------------------------------------------------- run


def test_run_smoke_every_output_parses(tmp_path):
    cfg = _config(tmp_path, SMALL)
    out = tmp_path / "out"
    r = _run("--config", cfg, "--out", out)
    assert r.exit_code == 0, r.output
    assert "GOSPA" in r.output and "association time" in r.output
    with open(out / "tracks.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == TRACK_COLUMNS
    assert len(rows) > 1
    tracks = read_tracks(out / "tracks.csv")
    assert set(np.unique(tracks["time"])) <= set(np.arange(16.0))
    m = json.loads((out / "metrics.json").read_text())
    for key in ("gospa", "ospa", "tracks", "timing", "tracker", "source", "files"):
        assert key in m
    g = m["gospa"]
    assert g["c"] == 40.0
    for key in ("mean", "mean_localisation", "mean_missed", "mean_false", "n_switches"):
        assert key in g
    assert m["ospa"]["mean"] >= 0
    for key in ("n_true_tracks", "n_false_tracks", "n_breaks", "n_id_switches", "rmse"):
        assert key in m["tracks"]
    t = m["timing"]
    assert t["scans_per_second"] > 0 and t["loop_seconds"] > 0
    for row in t["clusters"]:
        assert set(row) >= {"n_tracks", "count", "mean_seconds", "max_seconds"}
        assert row["n_tracks"] >= 2 and row["max_seconds"] >= row["mean_seconds"]
    assert m["source"]["scenario"] == "crossing" and m["n_scans"] == 16
    _png(out / "scene.png")
    _png(out / "gospa.png")


def test_run_default_is_bojilov_into_jointtrack_out(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = runner.invoke(app, ["run", "--no-progress"])
    assert r.exit_code == 0, r.output
    out = tmp_path / "jointtrack-out"
    for name in ("tracks.csv", "metrics.json", "scene.png", "gospa.png"):
        assert (out / name).exists()
    m = json.loads((out / "metrics.json").read_text())
    assert m["source"]["scenario"] == "bojilov" and m["source"]["seed"] == 0
    assert m["start_from_truth"] is True
    assert m["tracks"]["n_truths"] == 5 and m["tracks"]["n_truths_tracked"] == 5
    assert any(row["n_tracks"] == 5 for row in m["timing"]["clusters"])
    assert "not initiation" in r.output  # the truth-start note is in the summary


def test_run_parquet_matches_csv(tmp_path):
    cfg = _config(tmp_path, SMALL)
    r1 = _run("--config", cfg, "--out", tmp_path / "c")
    r2 = _run("--config", cfg, "--out", tmp_path / "p", "--format", "parquet")
    assert r1.exit_code == 0 and r2.exit_code == 0, r2.output
    assert not (tmp_path / "p" / "tracks.csv").exists()
    table = pq.read_table(tmp_path / "p" / "tracks.parquet")
    assert table.schema.names == TRACK_COLUMNS
    c = read_tracks(tmp_path / "c" / "tracks.csv")
    for name in TRACK_COLUMNS:
        np.testing.assert_array_equal(table.column(name).to_numpy(), c[name])


def test_run_seed_and_scenario_options(tmp_path):
    cfg = _config(tmp_path, SMALL)
    r = _run("--config", cfg, "--seed", 7, "--out", tmp_path / "o")
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["source"]["seed"] == 7
    r = _run("--scenario", "nope", "--out", tmp_path / "x")
    one_line_error(r, "--scenario", "nope")
    r = _run("--config", cfg, "--format", "xml", "--out", tmp_path / "x")
    one_line_error(r, "xml")


# ----------------------------------------------------------------------------- detections


def test_run_on_detections_file(tmp_path):
    sc = crossing(seed=1, n_scans=25, clutter_per_scan=2.0)
    det = write_detections(sc.as_detections(), tmp_path / "det.csv")
    cfg = _config(tmp_path, "[tracker]\nclutter_density = 1e-5\nmax_speed = 20.0\n")
    out = tmp_path / "out"
    r = _run("--detections", det, "--config", cfg, "--out", out)
    assert r.exit_code == 0, r.output
    assert "no truth" in r.output
    m = json.loads((out / "metrics.json").read_text())
    assert "gospa" not in m and "ospa" not in m
    assert m["source"]["detections"] == str(det.resolve())
    assert m["source"]["sha256"] == hashlib.sha256(det.read_bytes()).hexdigest()
    assert m["n_scans"] == 25 and m["tracks"]["n_tracks"] >= 1
    assert m["tracker"]["clutter_density"] == 1e-5
    tracks = read_tracks(out / "tracks.csv")
    assert list(tracks) == TRACK_COLUMNS
    _png(out / "scene.png")
    assert not (out / "gospa.png").exists()


def test_bad_detections_file_one_line_exit_2(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("time,x,y\n0,1,2\n1,abc,3\n")
    r = _run("--detections", bad, "--out", tmp_path / "o")
    line = one_line_error(r, "bad.csv", "abc")
    assert "row 2" in line
    r = _run("--detections", tmp_path / "missing.csv", "--out", tmp_path / "o")
    one_line_error(r, "missing.csv")
    nocol = tmp_path / "nocol.csv"
    nocol.write_text("time,x\n0,1\n")
    one_line_error(_run("--detections", nocol, "--out", tmp_path / "o"), "nocol.csv", "y")


def test_detections_with_scenario_is_an_error(tmp_path):
    sc = crossing(seed=1, n_scans=3)
    det = write_detections(sc.as_detections(), tmp_path / "det.csv")
    one_line_error(_run("--detections", det, "--scenario", "crossing"), "--detections")


# ----------------------------------------------------------------------------- range–bearing

SENSOR = (2000.0, 0.0)
RB_TRACKER = """
[tracker]
sensor = "range-bearing"
sensor_position = [2000.0, 0.0]
range_noise = 100.0
bearing_noise = 2.5e-5
process_noise = 0.05
max_speed = 15.0
"""


def _range_bearing_file(tmp_path, n_scans=20, seed=0, name="rb.csv"):
    """The crossing targets turned so that target 1 flies along y = 0 towards a
    range–bearing sensor due east (its bearing sits on the ±π branch cut), as
    ``range_bearing_scene`` of test_tracker.py, with fewer scans; σ_r = 10 m,
    σ_θ = 0.005 rad, 4 clutter returns per scan uniform in r ∈ [1500, 2500],
    θ ∈ π ± 0.25. Returns the file and the true positions per scan."""
    sc = crossing(seed=seed, n_scans=n_scans)
    v = sc.truth_states[0][0, 2:4]
    phi = np.arctan2(v[1], v[0])
    rot = np.array([[np.cos(phi), np.sin(phi)], [-np.sin(phi), np.cos(phi)]])
    positions = [s[:, :2] @ rot.T for s in sc.truth_states]
    rng = np.random.default_rng(1000 + seed)
    scans = []
    for pos in positions:
        d = pos[rng.random(len(pos)) < sc.p_d] - np.asarray(SENSOR)
        z = np.column_stack([np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0])])
        z += rng.normal(size=z.shape) * [10.0, 0.005]
        k = rng.poisson(4.0)
        cz = np.column_stack([rng.uniform(1500, 2500, k), np.pi + rng.uniform(-0.25, 0.25, k)])
        z = np.vstack([z, cz])
        z[:, 1] = np.angle(np.exp(1j * z[:, 1]))  # bearings in (−π, π]
        scans.append(z)
    det = Detections(times=sc.times, scans=scans, kind="range-bearing")
    return write_detections(det, tmp_path / name), sc.times, positions


@pytest.mark.parametrize(
    ("clutter", "n_scans", "min_rows"),
    [
        # 4 returns per scan over 1000 m × 0.5 rad
        ("clutter_density = 0.008\n", 20, 15),
        # omitted: Bojilov's heuristic (8) per cluster, λ = Σ m_i / Σ V_i in r × θ
        # units; it confirms later (as with positions), hence more scans
        ("", 30, 5),
    ],
)
def test_run_on_range_bearing_detections_file(tmp_path, clutter, n_scans, min_rows):
    det, times, truth = _range_bearing_file(tmp_path, n_scans=n_scans)
    assert det.read_text().splitlines()[0] == "time,range,bearing"
    cfg = _config(tmp_path, RB_TRACKER + clutter)
    out = tmp_path / "out"
    r = _run("--detections", det, "--config", cfg, "--out", out)
    assert r.exit_code == 0, r.output
    assert "no truth" in r.output
    m = json.loads((out / "metrics.json").read_text())
    assert m["source"]["detections"] == str(det.resolve())
    assert m["source"]["sha256"] == hashlib.sha256(det.read_bytes()).hexdigest()
    assert m["tracker"]["sensor"] == "range-bearing"
    assert m["tracker"]["sensor_position"] == list(SENSOR)
    assert m["tracker"]["clutter_density"] == (0.008 if clutter else None)
    assert m["n_scans"] == n_scans and m["tracks"]["n_tracks"] >= 1
    tracks = read_tracks(out / "tracks.csv")
    assert list(tracks) == TRACK_COLUMNS  # Cartesian states, as for positions
    assert len(tracks["time"]) >= min_rows
    # distance of every track position to the nearest target at its scan
    k = np.searchsorted(times, tracks["time"])
    miss = np.array(
        [
            np.hypot(*(truth[i] - [x, y]).T).min()
            for i, x, y in zip(k, tracks["x"], tracks["y"], strict=True)
        ]
    )
    assert np.mean(miss < 30.0) >= 0.8, miss
    _png(out / "scene.png")
    assert not (out / "gospa.png").exists()


def test_range_bearing_parquet_detections(tmp_path):
    det, _, _ = _range_bearing_file(tmp_path, n_scans=8, name="rb.parquet")
    cfg = _config(tmp_path, RB_TRACKER + "clutter_density = 0.008\n")
    r = _run("--detections", det, "--config", cfg, "--out", tmp_path / "o", "--format", "parquet")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "o" / "tracks.parquet").exists()


def test_bad_range_bearing_files_one_line_exit_2(tmp_path):
    cfg = _config(tmp_path, RB_TRACKER)
    mixed = tmp_path / "mixed.csv"
    mixed.write_text("time,x,y,range,bearing\n0,1,2,3,0.1\n")
    r = _run("--detections", mixed, "--config", cfg, "--out", tmp_path / "o")
    one_line_error(r, "mixed.csv", "x, y", "range, bearing", "one kind")
    neither = tmp_path / "neither.csv"
    neither.write_text("time,east,north\n0,1,2\n")  # (time, lat, lon: geodetic, issue 24)
    r = _run("--detections", neither, "--config", cfg, "--out", tmp_path / "o")
    one_line_error(r, "neither.csv", "x, y", "range, bearing", "lat, lon")
    neg = tmp_path / "neg.csv"
    neg.write_text("time,range,bearing\n0,10,0.1\n1,-3,0.1\n")
    r = _run("--detections", neg, "--config", cfg, "--out", tmp_path / "o")
    one_line_error(r, "neg.csv", "row 2", "'range'", "negative range")


def test_sensor_must_match_the_detections(tmp_path):
    rb, _, _ = _range_bearing_file(tmp_path, n_scans=4)
    # range–bearing file, position sensor: say what to set
    r = _run("--detections", rb, "--out", tmp_path / "o")
    one_line_error(r, "rb.csv", 'sensor = "range-bearing"', "sensor_position", "--config")
    cfg = _config(tmp_path, "[tracker]\nclutter_density = 0.008\n", "pos.toml")
    r = _run("--detections", rb, "--config", cfg, "--out", tmp_path / "o")
    one_line_error(r, "rb.csv", "pos.toml", 'sensor = "range-bearing"', "range_noise")
    # position file or scenario, range–bearing sensor
    sc = crossing(seed=1, n_scans=3)
    pos = write_detections(sc.as_detections(), tmp_path / "pos.csv")
    cfg = _config(tmp_path, RB_TRACKER, "rb.toml")
    r = _run("--detections", pos, "--config", cfg, "--out", tmp_path / "o")
    one_line_error(r, "rb.toml", "pos.csv", "position detections", 'sensor = "position"')
    r = _run("--config", cfg, "--scenario", "crossing", "--out", tmp_path / "o")
    one_line_error(r, "rb.toml", "scenario crossing", 'sensor = "position"')
    # range–bearing settings are checked like the others
    for text, needle in (
        ("[tracker]\nsensor_position = 3\n", "'sensor_position'"),
        ("[tracker]\nsensor_position = [1.0]\n", "'sensor_position'"),
        ('[tracker]\nsensor = "sonar"\n', "sensor"),
        ('[tracker]\nsensor = "range-bearing"\nbearing_noise = -1.0\n', "bearing_noise"),
        ('[tracker]\nsensor = "range-bearing"\ndim = 3\n', "2-D"),
    ):
        cfg = _config(tmp_path, text, "bad.toml")
        r = _run("--detections", rb, "--config", cfg, "--out", tmp_path / "o")
        one_line_error(r, "bad.toml", needle)
    assert not (tmp_path / "o").exists()


# ----------------------------------------------------------------------------- config errors


@pytest.mark.parametrize(
    ("text", "needles"),
    [
        ("[tracker]\np_d = 0.9\nfoo = 3\n", ["bad.toml", "'foo'", "[tracker]"]),
        ("[tracker\np_d = 0.9\n", ["bad.toml", "TOML"]),
        ("[tracker]\np_d = 1.5\n", ["bad.toml", "p_d"]),
        ('[tracker]\np_d = "high"\n', ["bad.toml", "'p_d'"]),
        ("[tracker]\nexistence = 1\n", ["bad.toml", "'existence'"]),
        ("[tracker]\ndim = 3\n", ["bad.toml", "'dim'", "2-D"]),
        ('[scenario]\nname = "crossing"\nn_scanz = 4\n', ["bad.toml", "'n_scanz'"]),
        ('[scenario]\nname = "elsewhere"\n', ["bad.toml", "'name'"]),
        ('[scenario]\nname = "crossing"\nn_scans = -3\n', ["bad.toml", "n_scans"]),
        ("[metrics]\ncutoff = 3\n", ["bad.toml", "'cutoff'"]),
        ("[metrics]\nc = -1\n", ["bad.toml", "'c'"]),
        ("[plots]\nx = 1\n", ["bad.toml", "'plots'"]),
    ],
)
def test_bad_config_one_line_exit_2(tmp_path, text, needles):
    cfg = _config(tmp_path, text, "bad.toml")
    one_line_error(_run("--config", cfg, "--out", tmp_path / "o"), *needles)


def test_missing_config_file(tmp_path):
    one_line_error(_run("--config", tmp_path / "none.toml"), "none.toml")


# ----------------------------------------------------------------------------- checkpoints


def test_checkpoint_resume_gives_the_same_tracks(tmp_path):
    cfg = _config(tmp_path, SMALL)
    full, part = tmp_path / "full", tmp_path / "part"
    r = _run("--config", cfg, "--out", full)
    assert r.exit_code == 0, r.output
    ck = tmp_path / "state.npz"
    r = _run(
        "--config",
        cfg,
        "--out",
        part,
        "--checkpoint",
        ck,
        "--checkpoint-every",
        4,
        "--max-scans",
        9,
    )
    assert r.exit_code == 0, r.output
    assert ck.exists()
    assert len(np.unique(read_tracks(part / "tracks.csv")["time"])) <= 9
    r = _run("--config", cfg, "--out", part, "--resume", ck)
    assert r.exit_code == 0, r.output
    assert (part / "tracks.csv").read_bytes() == (full / "tracks.csv").read_bytes()
    mf = json.loads((full / "metrics.json").read_text())
    mp = json.loads((part / "metrics.json").read_text())
    assert mp["gospa"] == mf["gospa"] and mp["tracks"] == mf["tracks"]
    assert [c["count"] for c in mp["timing"]["clusters"]] == [
        c["count"] for c in mf["timing"]["clusters"]
    ]
    # a checkpoint belongs to its run
    r = _run("--config", cfg, "--seed", 5, "--out", part, "--resume", ck)
    one_line_error(r, "checkpoint", "seed 2")


def test_killed_run_resumes_to_the_same_tracks(tmp_path, monkeypatch):
    from jointtrack.trackers import JPDATracker

    cfg = _config(tmp_path, SMALL)
    full, part = tmp_path / "full", tmp_path / "part"
    assert _run("--config", cfg, "--out", full).exit_code == 0
    step = JPDATracker.step

    def dying_step(self, t, z):
        if self.n_scans == 11:
            raise KeyboardInterrupt
        return step(self, t, z)

    ck = tmp_path / "ck.npz"
    monkeypatch.setattr(JPDATracker, "step", dying_step)
    r = _run("--config", cfg, "--out", part, "--checkpoint", ck, "--checkpoint-every", 5)
    assert r.exit_code == 130
    assert "--resume" in r.output and "Traceback" not in r.output
    kept = read_tracks(part / "tracks.csv")  # every finished scan was flushed
    assert kept["time"].max() == 10.0
    monkeypatch.setattr(JPDATracker, "step", step)
    r = _run("--config", cfg, "--out", part, "--resume", ck)  # checkpoint of scan 10
    assert r.exit_code == 0, r.output
    assert (part / "tracks.csv").read_bytes() == (full / "tracks.csv").read_bytes()


def test_resume_bad_checkpoint_file(tmp_path):
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a pickle")
    cfg = _config(tmp_path, SMALL)
    one_line_error(_run("--config", cfg, "--resume", junk, "--out", tmp_path / "o"), "junk.npz")


# ----------------------------------------------------------------------------- reproduce


def test_reproduce_bojilov_quick(tmp_path):
    out = tmp_path / "rep"
    r = runner.invoke(
        app, ["reproduce", "bojilov", "--runs", "1", "--quick", "--out", str(out), "--no-progress"]
    )
    assert r.exit_code == 0, r.output
    assert "Table 2" in r.output and "Table 3" in r.output
    assert "Trend" in r.output
    assert "HOLDS" in r.output or "DOES NOT HOLD" in r.output
    assert "5-target cluster association ≤ 1 ms (paper optimised 0.438 s)" in r.output
    assert "PASS" in r.output or "FAIL" in r.output
    data = json.loads((out / "reproduce-bojilov.json").read_text())
    assert data["settings"]["runs"] == 1
    assert data["betas"] == [1.0, 2.0]
    for key in ("beta=1", "beta=2"):
        rows = data["results"][key]["rows"]
        assert [row["targets"] for row in rows][:4] == [2, 3, 4, 5]
        for row in rows[:4]:
            for k in (
                "n_clusters",
                "mean_hypotheses",
                "mean_mult_naive",
                "mean_mult_optimised",
                "mult_ratio",
                "mean_seconds_naive",
                "mean_seconds_optimised",
                "mean_seconds_exact",
                "paper_table2",
                "paper_table3",
            ):
                assert k in row
        assert rows[3]["paper_table2"]["opt"] in (24290, 103598)
    assert data["paper"]["table3_seconds_per_cluster"]["rows"][2][2] == 0.438
    assert isinstance(data["target"]["pass"], bool)
    _png(out / "reproduce-bojilov.png")
