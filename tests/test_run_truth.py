"""``jointtrack run --detections FILE --truth FILE``: your own data, scored; the epoch stated.

A built-in scenario written to files (its detections and its truth table) and
run with ``--detections … --truth …`` under the scenario's own tracker
settings must be scored exactly as ``--scenario`` scores it. Small crossings
(16–20 scans) keep the file fast.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from cli_checks import one_line_error
from jointtrack.cli import app
from jointtrack.experiments.config import FROM_NOTHING_JIPDA, scenario_tracker_settings
from jointtrack.experiments.run import run_detections
from jointtrack.io import (
    DataFileError,
    Detections,
    TruthFileError,
    read_truth,
    write_detections,
    write_truth,
)
from jointtrack.scenarios import crossing

runner = CliRunner()
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SEED, N_SCANS, CLUTTER = 2, 20, 4.0
ORIGIN = "2026-11-23T10:00:00Z"


def _run(*args):
    return runner.invoke(app, ["run", "--no-progress", *map(str, args)])


def _toml_value(v):
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


def _scenario():
    return crossing(seed=SEED, n_scans=N_SCANS, clutter_per_scan=CLUTTER)


@pytest.fixture(scope="module")
def scenario_run(tmp_path_factory):
    """``--scenario crossing`` and the files that hold the same run."""
    tmp = tmp_path_factory.mktemp("scenario")
    sc = _scenario()
    # a detections file cannot hold an empty scan: the comparison needs none
    assert min(len(z) for z in sc.detections) > 0
    cfg = tmp / "scenario.toml"
    cfg.write_text(
        f'[scenario]\nname = "crossing"\nseed = {SEED}\nn_scans = {N_SCANS}\n'
        f"clutter_per_scan = {CLUTTER}\n",
        encoding="utf-8",
    )
    out = tmp / "scenario-out"
    r = _run("--config", cfg, "--out", out)
    assert r.exit_code == 0, r.output
    settings = scenario_tracker_settings(sc)
    metrics = json.loads((out / "metrics.json").read_text())
    # the keys the detections run's fit would choose beyond the scenario's settings
    # (id continuation, JPDA*, the motion model), and those a scenario run from nothing
    # takes (experiments.config.FROM_NOTHING_JIPDA; detections runs do not, yet), pinned
    # to the scenario run's values: the same run, so the same scores
    pinned = ("id_continuation", "coalescence_avoidance", "motion", "turn_rate_std")
    for key in pinned + tuple(FROM_NOTHING_JIPDA):
        settings.setdefault(key, metrics["tracker"][key])
    assert None not in settings.values()  # TOML has no null
    tracker = tmp / "tracker.toml"
    tracker.write_text(
        "[tracker]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in settings.items()),
        encoding="utf-8",
    )
    det = write_detections(sc.as_detections(), tmp / "det.csv")
    truth = write_truth(sc.truth_table(), tmp / "truth.csv")
    assert metrics["tracks"]["n_truths"] == 2 and metrics["gospa"]["mean"] > 0
    return sc, out, metrics, tracker, det, truth


def _same_scores(m, ref):
    assert m["gospa"] == ref["gospa"]
    assert m["ospa"] == ref["ospa"]
    assert m["tracks"] == ref["tracks"]
    assert m["n_scans"] == ref["n_scans"] and m["n_detections"] == ref["n_detections"]


# ------------------------------------------------------------------ scored like a scenario


def test_detections_and_truth_files_score_like_the_scenario(tmp_path, scenario_run):
    _sc, ref_out, ref, tracker, det, truth = scenario_run
    out = tmp_path / "out"
    r = _run("--detections", det, "--truth", truth, "--config", tracker, "--out", out)
    assert r.exit_code == 0, r.output
    m = json.loads((out / "metrics.json").read_text())
    _same_scores(m, ref)
    assert m["tracker"] == ref["tracker"]
    assert (out / "tracks.csv").read_bytes() == (ref_out / "tracks.csv").read_bytes()
    assert m["source"]["truth"] == str(truth.resolve())
    assert m["source"]["truth_sha256"] == hashlib.sha256(truth.read_bytes()).hexdigest()
    for name in ("scene.png", "gospa.png"):
        assert (out / name).read_bytes()[:8] == PNG_MAGIC
    assert set(m["files"]) >= {"scene", "gospa"}
    assert "GOSPA mean" in r.output and "truth.csv" in r.output
    assert "time_origin" not in m and "seconds since" not in r.output  # numeric times
    assert not any("no scan" in n for n in m["notes"])


def test_iso_times_in_parquet_score_alike_and_state_the_epoch(tmp_path, scenario_run):
    sc, _ref_out, ref, tracker, _det, _truth = scenario_run
    assert sc.times[0] == 0.0
    dets = Detections(times=sc.times, scans=sc.detections, dim=sc.dim, time_origin=ORIGIN)
    det = write_detections(dets, tmp_path / "det.parquet")
    truth = write_truth(sc.truth_table(), tmp_path / "truth.parquet", time_origin=ORIGIN)
    out = tmp_path / "out"
    r = _run("--detections", det, "--truth", truth, "--config", tracker, "--out", out)
    assert r.exit_code == 0, r.output
    m = json.loads((out / "metrics.json").read_text())
    _same_scores(m, ref)
    assert m["time_origin"] == ORIGIN
    assert "seconds since time_origin" in m["time_unit"]
    assert f"seconds since {ORIGIN}" in r.output


def test_iso_times_without_truth_state_the_epoch(tmp_path):
    sc = crossing(seed=1, n_scans=6, clutter_per_scan=1.0)
    dets = Detections(times=sc.times, scans=sc.detections, dim=2, time_origin="2026-01-02T03:04:05")
    det = write_detections(dets, tmp_path / "det.csv")
    r = _run("--detections", det, "--out", tmp_path / "out")
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert m["time_origin"] == "2026-01-02T03:04:05" and "gospa" not in m
    assert "seconds since 2026-01-02T03:04:05" in r.output


def test_truth_table_in_memory(tmp_path, scenario_run):
    sc, _ref_out, ref, _tracker, _det, _truth = scenario_run
    cfg = scenario_tracker_settings(sc) | FROM_NOTHING_JIPDA  # as the scenario run from nothing
    m = run_detections(
        sc.as_detections(), cfg, tmp_path / "out", truth=sc.truth_table(), plots=False,
        metrics_opts={"c": ref["gospa"]["c"]},
    )  # fmt: skip
    _same_scores(m, ref)
    assert m["source"]["truth"] == "<memory>"


# ------------------------------------------------------------- truth at times with no scan


def test_truth_rows_at_times_without_a_scan_are_noted_and_ignored(tmp_path, scenario_run):
    sc, _ref_out, _ref, tracker, _det, _truth = scenario_run
    gone = sc.times[[5, 6]]
    keep = [k for k in range(len(sc.times)) if sc.times[k] not in gone]
    dets = Detections(times=sc.times[keep], scans=[sc.detections[k] for k in keep], dim=2)
    det = write_detections(dets, tmp_path / "det.csv")
    full = write_truth(sc.truth_table(), tmp_path / "truth.csv")
    tt, ti, tp = sc.truth_table()
    at = ~np.isin(tt, gone)
    cut = write_truth((tt[at], ti[at], tp[at]), tmp_path / "truth-at-scans.csv")
    n_off = int((~at).sum())
    assert n_off == 4

    a, b = tmp_path / "a", tmp_path / "b"
    r = _run("--detections", det, "--truth", full, "--config", tracker, "--out", a)
    assert r.exit_code == 0, r.output
    ma = json.loads((a / "metrics.json").read_text())
    notes = [n for n in ma["notes"] if "no scan" in n]
    assert len(notes) == 1, ma["notes"]
    assert f"{n_off} truth row(s) at 2 time(s) with no scan" in notes[0]
    assert "t = 5" in notes[0] and "truth.csv" in notes[0]
    assert "no scan" in r.output  # the summary shows the note
    r = _run("--detections", det, "--truth", cut, "--config", tracker, "--out", b)
    assert r.exit_code == 0, r.output
    mb = json.loads((b / "metrics.json").read_text())
    assert not any("no scan" in n for n in mb["notes"])
    _same_scores(ma, mb)  # the rows off the scans were not scored
    assert ma["n_scans"] == N_SCANS - 2


def test_truth_on_another_clock_is_an_error(tmp_path, scenario_run):
    sc, _ref_out, _ref, _tracker, det, _truth = scenario_run
    tt, ti, tp = sc.truth_table()
    shifted = write_truth((tt + 0.5, ti, tp), tmp_path / "shifted.csv")
    r = _run("--detections", det, "--truth", shifted, "--out", tmp_path / "o")
    one_line_error(r, "shifted.csv", "no truth row is at a scan time", "t = 0.5")


def test_truth_kind_of_time_must_match_the_detections(tmp_path, scenario_run):
    sc, _ref_out, _ref, _tracker, det, _truth = scenario_run
    iso = write_truth(sc.truth_table(), tmp_path / "iso.csv", time_origin=ORIGIN)
    r = _run("--detections", det, "--truth", iso, "--out", tmp_path / "o")
    one_line_error(r, "iso.csv", "column 'time'", "timestamps", "numbers")


def test_truth_dimension_must_match(tmp_path, scenario_run):
    _sc, _ref_out, _ref, _tracker, det, _truth = scenario_run
    t3 = tmp_path / "t3.csv"
    t3.write_text("time,id,x,y,z\n0,1,0,0,0\n")
    r = _run("--detections", det, "--truth", t3, "--out", tmp_path / "o")
    one_line_error(r, "t3.csv", "3-D", "2-D")


def test_truth_without_detections_is_an_error(tmp_path, scenario_run):
    _sc, _ref_out, _ref, _tracker, _det, truth = scenario_run
    r = _run("--scenario", "crossing", "--truth", truth, "--out", tmp_path / "o")
    one_line_error(r, "--truth", "--detections")
    r = _run("--truth", truth, "--out", tmp_path / "o")
    one_line_error(r, "--truth", "--detections")


# ----------------------------------------------------------------------------- resume


def test_resume_rereads_the_truth(tmp_path, scenario_run):
    _sc, _ref_out, ref, tracker, det, truth_src = scenario_run
    truth = tmp_path / "truth.csv"
    truth.write_bytes(truth_src.read_bytes())
    part, ck = tmp_path / "part", tmp_path / "state.npz"
    args = ("--detections", det, "--truth", truth, "--config", tracker)
    r = _run(*args, "--out", part, "--checkpoint", ck, "--checkpoint-every", 4, "--max-scans", 9)
    assert r.exit_code == 0, r.output
    m9 = json.loads((part / "metrics.json").read_text())
    assert m9["n_scans"] == 9 and "gospa" in m9

    # --truth that disagrees with the checkpoint
    other = tmp_path / "other.csv"
    other.write_bytes(truth.read_bytes())
    one_line_error(_run("--resume", ck, "--truth", other), "--truth", "other.csv", "truth.csv")

    r = _run("--resume", ck)  # the truth comes back from the checkpoint
    assert r.exit_code == 0, r.output
    m = json.loads((part / "metrics.json").read_text())
    _same_scores(m, ref)
    assert m["source"]["truth"] == str(truth.resolve())
    assert m["n_scans_this_run"] == N_SCANS - 9

    # a changed truth file is noticed
    lines = truth.read_text().splitlines()
    lines[1] = lines[1].rsplit(",", 1)[0] + ",123.0"
    truth.write_text("\n".join(lines) + "\n")
    one_line_error(_run("--resume", ck), "truth file", "changed since the checkpoint")


def test_resume_of_a_run_without_truth_refuses_truth(tmp_path, scenario_run):
    _sc, _ref_out, _ref, tracker, det, truth = scenario_run
    ck, out = tmp_path / "ck.npz", tmp_path / "out"
    r = _run("--detections", det, "--config", tracker, "--out", out, "--checkpoint", ck,
             "--max-scans", 5)  # fmt: skip
    assert r.exit_code == 0, r.output
    one_line_error(_run("--resume", ck, "--truth", truth), "--truth", "without a truth")
    r = _run("--resume", ck)
    assert r.exit_code == 0, r.output
    assert "gospa" not in json.loads((out / "metrics.json").read_text())


# ----------------------------------------------------------------------------- read_truth


def test_read_truth_round_trip_csv_and_parquet(tmp_path):
    sc = crossing(seed=3, n_scans=5)
    table = sc.truth_table()
    for name in ("t.csv", "t.parquet", "t.csv.gz"):
        back = read_truth(write_truth(table, tmp_path / name))
        assert back[1].dtype == np.int64 and back[2].shape == table[2].shape
        for a, b in zip(back, table, strict=True):
            np.testing.assert_array_equal(a, b)


def test_read_truth_measures_timestamps_from_the_detections_origin(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text(
        "time,id,x,y\n"
        "2026-11-23T10:00:02Z,1,0,0\n"
        "2026-11-23T11:00:02.25+01:00,2,1,1\n"  # = 10:00:02.25Z
        "2026-11-23T10:00:03Z,1,2,2\n"
    )
    t, ids, pos = read_truth(p, time_origin="2026-11-23T10:00:00Z")
    assert t.tolist() == [2.0, 2.25, 3.0] and ids.tolist() == [1, 2, 1]
    assert pos.tolist() == [[0, 0], [1, 1], [2, 2]]
    with pytest.raises(TruthFileError, match="t.csv.*column 'time'.*UTC offset"):
        read_truth(p, time_origin="2026-11-23T10:00:00")
    with pytest.raises(TruthFileError, match="t.csv.*timestamps.*numbers"):
        read_truth(p)
    num = tmp_path / "num.csv"
    num.write_text("time,id,x,y\n0,1,0,0\n")
    with pytest.raises(TruthFileError, match="num.csv.*numbers.*timestamps"):
        read_truth(num, time_origin="2026-11-23T10:00:00Z")


@pytest.mark.parametrize(
    "text, needles",
    [
        ("time,x,y\n0,1,2\n", ["missing required column(s): id"]),
        ("time,id,x,y\n0,a,1,2\n", ["line 2 (data row 1)", "column 'id'", "'a'"]),
        ("time,id,x,y\n0,1,1,2\n0,1.5,1,2\n", ["data row 2", "column 'id'", "not an integer"]),
        ("time,id,x,y\n0,1,nan,2\n", ["data row 1", "column 'x'", "non-finite"]),
        ("time,id,x,y\n0,1,1,2\n0,2,1,inf\n", ["data row 2", "column 'y'", "non-finite"]),
        ("time,id,x,y\n1,1,1,2\n0,1,1,2\n", ["data row 2", "column 'time'", "earlier"]),
        ("time,id,x,y\n0,1,1,2\n0,2,1,2\n0,1,5,5\n", ["data row 3", "column 'id'", "twice"]),
        ("time,id,x,y\n0,1,1,2\nnow,1,1,2\n", ["data row 2", "column 'time'", "'now'"]),
        ("time,id,x,y\n", ["no truth rows"]),
    ],
)
def test_bad_truth_files(tmp_path, text, needles):
    p = tmp_path / "bad_truth.csv"
    p.write_text(text)
    with pytest.raises(TruthFileError) as exc:
        read_truth(p)
    msg = str(exc.value)
    assert isinstance(exc.value, DataFileError) and "\n" not in msg
    assert msg.startswith(str(p)), msg
    for n in needles:
        assert n in msg, msg


def test_bad_truth_file_on_the_command_line(tmp_path, scenario_run):
    _sc, _ref_out, _ref, _tracker, det, _truth = scenario_run
    bad = tmp_path / "bad.csv"
    bad.write_text("time,id,x,y\n0,1,1,2\n1,x,1,2\n")
    one_line_error(
        _run("--detections", det, "--truth", bad, "--out", tmp_path / "o"),
        "bad.csv",
        "column 'id'",
        "'x'",
    )
    one_line_error(
        _run("--detections", det, "--truth", tmp_path / "none.csv", "--out", tmp_path / "o"),
        "none.csv",
        "not found",
    )
