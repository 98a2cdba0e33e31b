"""How ``jointtrack run`` starts its tracks: ``--start-from truth | nothing``.

The default Bojilov run is the paper's experiment (tracks started from the
truth); ``--start-from nothing`` (or ``start_from = "nothing"`` in
``[scenario]``, older spelling ``start_from_truth = false``) lets the tracker
initiate them. Short Bojilov runs (6–8 scans) keep the file fast.
"""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from cli_checks import one_line_error
from jointtrack.cli import app
from jointtrack.experiments.config import RunConfigError, load_config, start_setting
from jointtrack.experiments.run import run_scenario
from jointtrack.experiments.summary import start_description, summary_tables, tracks_line
from jointtrack.io import read_tracks, write_detections
from jointtrack.scenarios import crossing

runner = CliRunner()

SHORT = "[scenario]\nn_scans = 6\n"  # Bojilov's scenario (the default), six scans


def _config(tmp_path, text: str = SHORT, name: str = "run.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def _run(*args):
    return runner.invoke(app, ["run", "--no-progress", *map(str, args)])


def _metrics(out) -> dict:
    return json.loads((out / "metrics.json").read_text(encoding="utf-8"))


# ----------------------------------------------------------------------------- runs


def test_default_bojilov_run_starts_from_the_truth(tmp_path):
    out = tmp_path / "o"
    r = _run("--config", _config(tmp_path), "--out", out)
    assert r.exit_code == 0, r.output
    m = _metrics(out)
    assert m["start"] == "truth" and m["start_from_truth"] is True
    assert m["source"]["scenario"] == "bojilov"
    assert "tracks started from the truth (the paper's experiment" in r.output
    tr = read_tracks(out / "tracks.csv")
    assert sorted(tr["track_id"][tr["time"] == 0.0].tolist()) == [1, 2, 3, 4, 5]


def test_start_from_nothing_initiates_the_tracks(tmp_path):
    out = tmp_path / "o"
    r = _run("--config", _config(tmp_path), "--out", out, "--start-from", "nothing")
    assert r.exit_code == 0, r.output
    m = _metrics(out)
    assert m["start"] == "nothing" and m["start_from_truth"] is False
    assert m["source"]["start_from_truth"] is False
    assert not any("not initiation" in n for n in m["notes"])
    assert "tracks started from nothing (one-point initiation" in " ".join(r.output.split())
    assert "the paper's experiment starts from the truth" in start_description(m)
    # a track initiated from the detections cannot be confirmed at the first scan
    tr = read_tracks(out / "tracks.csv")
    assert not np.any(tr["time"] == 0.0)
    # the summary says how well the targets were followed (issue 23 item 5)
    assert "coverage" in r.output and "breaks" in r.output
    row = _summary_row(m, "tracks")
    t = m["tracks"]
    for part in (
        f"coverage {t['coverage']:.3g}",
        f"{t['n_breaks']} breaks",
        f"{t['n_id_switches']} identity switches",
    ):
        assert part in row, row


def _summary_row(metrics: dict, name: str) -> str:
    """The text of one row of the run summary's main table, rendered wide (no wrap)."""
    from rich.console import Console

    console = Console(width=400, record=True, file=io.StringIO())
    console.print(summary_tables(metrics)[0])
    rows = [ln for ln in console.export_text().splitlines() if ln.strip("│ ").startswith(name)]
    assert len(rows) == 1, rows
    return " ".join(rows[0].split())


def test_tracks_row_gives_coverage_breaks_and_switches_before_targets_tracked():
    # issue 23 item 5: every target was tracked at some scan, but only for half the
    # truth-scans, with breaks and identity switches; "5/5 targets tracked" alone hid it
    tr = {
        "n_tracks": 12,
        "n_true_tracks": 7,
        "n_false_tracks": 5,
        "n_truths": 5,
        "n_truths_tracked": 5,
        "n_breaks": 5,
        "n_fragmentations": 4,
        "n_id_switches": 7,
        "coverage": 0.49,
        "rmse": 3.2,
        "gate": 50.0,
    }
    line = tracks_line(tr)
    for part in ("coverage 0.49", "5 breaks", "7 identity switches", "for 5 targets"):
        assert part in line, line
    # the count of targets tracked is still there, but qualified: after the coverage
    assert line.index("coverage") < line.index("5/5 targets tracked at some scan")
    assert tracks_line({**tr, "coverage": float("nan")}).count("coverage –") == 1


def test_the_flag_overrides_the_config_and_both_spellings_agree(tmp_path):
    cfg = _config(tmp_path, SHORT + 'start_from = "nothing"\n')
    r = _run("--config", cfg, "--out", tmp_path / "a", "--start-from", "truth", "--max-scans", 2)
    assert r.exit_code == 0, r.output
    assert _metrics(tmp_path / "a")["start"] == "truth"
    old = _config(tmp_path, SHORT + "start_from_truth = false\n", "old.toml")
    r = _run("--config", old, "--out", tmp_path / "b", "--max-scans", 2)
    assert r.exit_code == 0, r.output
    assert _metrics(tmp_path / "b")["start"] == "nothing"


def test_detections_run_starts_from_nothing(tmp_path):
    dets = write_detections(
        crossing(seed=1, n_scans=5, clutter_per_scan=2.0).as_detections(), tmp_path / "d.csv"
    )
    r = _run("--detections", dets, "--out", tmp_path / "o", "--start-from", "nothing")
    assert r.exit_code == 0, r.output
    assert _metrics(tmp_path / "o")["start"] == "nothing"
    assert "tracks started from nothing" in r.output
    assert "paper's experiment" not in r.output
    r = _run("--detections", dets, "--out", tmp_path / "t", "--start-from", "truth")
    one_line_error(r, "--start-from truth", "--detections", "--start-from nothing")
    assert not (tmp_path / "t").exists()


# ----------------------------------------------------------------------------- errors


@pytest.mark.parametrize("value", ["Truth", "none", ""])
def test_bad_start_from_value(tmp_path, value):
    r = _run("--config", _config(tmp_path), "--out", tmp_path / "o", "--start-from", value)
    one_line_error(r, "--start-from", "truth or nothing", repr(value))
    assert not (tmp_path / "o").exists()


def test_config_start_keys_are_checked(tmp_path):
    p = tmp_path / "c.toml"
    for text, needles in [
        ('[scenario]\nstart_from = "nowhere"\n', ["'start_from'", "'nowhere'"]),
        ("[scenario]\nstart_from = true\n", ["'start_from'", '"truth" or "nothing"']),
        ('[scenario]\nstart_from_truth = "yes"\n', ["'start_from_truth'", "true or false"]),
        (
            '[scenario]\nstart_from = "nothing"\nstart_from_truth = true\n',
            ["'start_from' = \"nothing\"", "'start_from_truth' = true", "disagree"],
        ),
    ]:
        p.write_text(text)
        with pytest.raises(RunConfigError) as exc:
            load_config(p)
        msg = str(exc.value)
        assert str(p) in msg and "\n" not in msg
        for n in needles:
            assert n in msg, msg
    p.write_text('[scenario]\nstart_from = "truth"\nstart_from_truth = true\n')
    assert load_config(p).scenario["start_from"] == "truth"  # agreeing spellings are fine
    assert start_setting(None, None) is None  # neither: the scenario's default


def test_run_scenario_start_arguments(tmp_path):
    with pytest.raises(RunConfigError, match="disagree"):
        run_scenario(
            "bojilov",
            out_dir=tmp_path,
            scenario_kwargs={"n_scans": 3},
            start_from="nothing",
            start_from_truth=True,
        )
    with pytest.raises(RunConfigError, match="'start_from'"):
        run_scenario("bojilov", out_dir=tmp_path, scenario_kwargs={"n_scans": 3}, start_from="x")


def test_start_description_of_older_metrics():
    # metrics.json written before "start" existed: start_from_truth tells
    old = {"start_from_truth": True, "source": {"scenario": "bojilov"}}
    assert "the paper's experiment" in start_description(old)
    text = start_description({"start_from_truth": False, "source": {"scenario": "crossing"}})
    assert text.startswith("tracks started from nothing") and "paper" not in text


# ----------------------------------------------------------------------------- resume


def test_resume_keeps_the_start_and_refuses_another(tmp_path):
    cfg = _config(tmp_path, "[scenario]\nn_scans = 8\n")
    full, part, ck = tmp_path / "full", tmp_path / "part", tmp_path / "ck.npz"
    r = _run("--config", cfg, "--out", full, "--start-from", "nothing")
    assert r.exit_code == 0, r.output
    r = _run(
        "--config",
        cfg,
        "--out",
        part,
        "--start-from",
        "nothing",
        "--checkpoint",
        ck,
        "--checkpoint-every",
        2,
        "--max-scans",
        4,
    )
    assert r.exit_code == 0, r.output
    # the checkpoint's tracks started from nothing: truth is a conflict naming the flag
    msg = one_line_error(_run("--resume", ck, "--start-from", "truth"), "--start-from truth")
    assert "started from nothing" in msg and "omit --start-from" in msg
    # so is a config that starts from the truth
    truth_cfg = _config(tmp_path, '[scenario]\nn_scans = 8\nstart_from = "truth"\n', "t.toml")
    one_line_error(_run("--resume", ck, "--config", truth_cfg), "--config", "truth")
    # the same start (or none: the checkpoint's) continues to the uninterrupted tracks
    r = _run("--resume", ck, "--start-from", "nothing")
    assert r.exit_code == 0, r.output
    assert _metrics(part)["start"] == "nothing"
    assert (part / "tracks.csv").read_bytes() == (full / "tracks.csv").read_bytes()
    assert "tracks started from nothing" in r.output
