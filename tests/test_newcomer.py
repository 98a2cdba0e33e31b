"""Issue 25: what a newcomer reads first — help texts, the package map, hints where a
user is surely wrong, and plain output in logs."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from rich.console import Console
from typer.testing import CliRunner

import jointtrack
from cli_checks import one_line_error
from jointtrack.cli import app
from jointtrack.experiments.run import (
    RunConfigError,
    make_scenario,
    print_summary,
    run_scenario,
)


def test_sweep_help_keeps_the_table_names():
    out = CliRunner().invoke(app, ["sweep", "--help"], env={"COLUMNS": "200"}).output
    text = re.sub(r"[│\s]+", " ", out)
    for table in ("[sweep]", "[tracker]", "[scenario]", "[metrics]", "[filter]"):
        assert table in text, table
    assert ", , " not in text


def test_package_map_and_lazy_names():
    doc = jointtrack.__doc__
    assert "jointtrack.assignment` — the one assignment-sum core" in doc
    for sub in ("permanent", "association", "trackers", "io", "metrics", "interop"):
        assert f":mod:`jointtrack.{sub}`" in doc
    names = dir(jointtrack)
    assert "JPDATracker" in names and "TrackerConfig" in names
    import textwrap

    quick = doc.split("Quick start::", 1)[1].split("Map of the package", 1)[0]
    exec(textwrap.dedent(quick.strip("\n")), {})


# ----------------------------------------------------------------------------- item 3: help

HELP_PAGES = [
    [],
    ["run"],
    ["sweep"],
    ["reproduce", "bojilov"],
    ["reproduce", "schaub"],
    ["reproduce", "streit"],
    ["reproduce", "nannuru"],
    ["bench", "tracker"],
    ["bench", "realdata"],
]


def _help(*args) -> str:
    r = CliRunner().invoke(app, [*args, "--help"], env={"COLUMNS": "200"})
    assert r.exit_code == 0, r.output
    return r.output


@pytest.mark.parametrize("args", HELP_PAGES, ids=lambda a: " ".join(a) or "jointtrack")
def test_flags_are_shown_as_flags_not_bool_values(args):
    out = _help(*args)
    assert "--help" in out
    assert "<bool>" not in out and "bool" not in out.lower().replace("boolean", "")


def test_a_flag_refuses_a_value():
    r = CliRunner().invoke(app, ["reproduce", "bojilov", "--quick", "true"])
    assert r.exit_code != 0
    r = CliRunner().invoke(app, ["reproduce", "bojilov", "--quick=true"])
    assert r.exit_code != 0 and "does not take a value" in r.output


def test_scenario_help_and_error_list_every_scenario():
    from jointtrack.cli import RUN_SCENARIOS
    from jointtrack.scenarios import GENERATORS

    assert RUN_SCENARIOS == (*GENERATORS, "acoustic")
    text = re.sub(r"[│\s]+", " ", _help("run"))
    assert f"[{'|'.join(RUN_SCENARIOS)}]" in text.replace(" ", "")
    for name in RUN_SCENARIOS:
        assert re.search(rf"\b{name}\b", text.split("--scenario", 1)[1].split("--out", 1)[0])
    msg = one_line_error(CliRunner().invoke(app, ["run", "--scenario", "bogus"]), "--scenario")
    for name in RUN_SCENARIOS:
        assert name in msg


def test_seed_errors_name_the_seed_once():
    msg = one_line_error(CliRunner().invoke(app, ["run", "--seed", "-1"]), "--seed", "-1")
    assert "scenario scenario" not in msg
    with pytest.raises(RunConfigError) as err:
        make_scenario("crossing", -3)
    assert str(err.value).startswith("scenario crossing: seed must be a non-negative integer")
    with pytest.raises(RunConfigError) as err:
        make_scenario("crossing", -3, source="run.toml")
    assert str(err.value).startswith('run.toml: [scenario] name = "crossing": seed must be')
    with pytest.raises(RunConfigError) as err:
        make_scenario("crossing", 0, {"bogus": 1.0}, source="run.toml")
    assert str(err.value).startswith("run.toml: [scenario] unknown key 'bogus'")


def test_errors_and_package_help_say_when_raised():
    import pydoc

    from jointtrack import errors

    for cls in (
        errors.InfeasibleAssignmentError,
        errors.ExactLimitError,
        errors.CoincidentReturnsWarning,
    ):
        assert re.search(r"\b(Raised|Warned) by\b|\bRaised where\b", cls.__doc__), cls
    text = pydoc.render_doc(jointtrack, renderer=pydoc.plaintext)
    assert "jointtrack.errors" in text and "ExactLimitError" in text
    # the exception shown in help(jointtrack) says when it is raised, not only what it inherits
    infeasible = text.split("class InfeasibleAssignmentError", 1)[1][:1500]
    assert "P_D = 1" in infeasible and "Handle it" in infeasible
    assert "class JPDATracker" in text and "class TrackerConfig" in text


def test_summary_and_metrics_say_the_cli_scenario_name(tmp_path):
    from jointtrack.scenarios import many_targets

    kw = {"n_targets": 6, "clutter_per_scan": 2.0, "n_scans": 4}
    for scenario in ("many", many_targets(seed=0, **kw)):
        console = Console(record=True, width=300)
        args = {"scenario_kwargs": kw} if scenario == "many" else {}
        metrics = run_scenario(scenario, out_dir=tmp_path, plots=False, **args)
        print_summary(metrics, console)
        assert metrics["source"]["scenario"] == "many"
        text = console.export_text()
        assert "scenario many (seed 0" in text and "many_targets" not in text
        saved = json.loads((tmp_path / "metrics.json").read_text())
        assert saved["source"]["scenario"] == "many"
        assert "many_targets" not in json.dumps(saved)


# ----------------------------------------------------------------------------- item 5: hints


def _box_scans(n_scans, per_scan, side, seed=0):
    rng = np.random.default_rng(seed)
    scans = [rng.uniform(0.0, side, size=(per_scan, 2)) for _ in range(n_scans)]
    for z in scans:  # the bounding box is exactly side × side
        z[0], z[1] = (0.0, 0.0), (side, side)
    return scans


@pytest.mark.parametrize(
    "lam, warned",
    [
        (1e-3, False),  # 4,096 × 1e-3 ≈ 4 expected ≤ 10 × 16 returns per scan
        (160 / 4096, False),  # 160 = 10 × 16 exactly (binary fractions): not more
        (164 / 4096, True),  # 164 > 160
        (1.0, True),  # 4,096 expected: per m² read as per km², say
        (None, False),  # estimated from the data
    ],
)
def test_clutter_hint_compares_expected_clutter_with_the_returns(lam, warned):
    from jointtrack.experiments.run import clutter_hint

    scans = _box_scans(5, 16, 64.0)  # bounding box 64 × 64 = 4,096
    msg = clutter_hint(scans, "position", lam)
    assert (msg is not None) is warned
    if warned:
        expected = f"{lam * 4096.0:,.0f}"
        assert f"clutter_density {lam:g} per unit area expects {expected} false returns" in msg
        assert "(x 64 × y 64)" in msg
        assert "16 detections on average" in msg and "check its units" in msg


def test_clutter_hint_for_range_bearing_and_3d():
    from jointtrack.experiments.run import clutter_hint

    rb = [np.array([[100.0, -0.5], [2100.0, 0.5]])] * 3  # range 2,000 × 1 rad
    msg = clutter_hint(rb, "range-bearing", 0.1)  # 200 expected vs 2 returns
    assert "per unit range × radian expects 200 false returns" in msg
    assert clutter_hint(rb, "range-bearing", 0.01) is None  # 20 ≤ 10 × 2
    cube = [np.array([[0.0, 0.0, 0.0], [10.0, 10.0, 10.0]])]
    assert "per unit volume expects 1,000" in clutter_hint(cube, "position", 1.0)
    assert clutter_hint(cube, "position", 0.01) is None


def test_a_run_with_clutter_far_off_says_so(tmp_path):
    kw = {"n_scans": 6}
    wrong = run_scenario(
        "bojilov", {"clutter_density": 0.3}, tmp_path / "w", plots=False, scenario_kwargs=kw
    )
    assert any("expects" in n and "check its units" in n for n in wrong["notes"]), wrong["notes"]
    right = run_scenario("bojilov", None, tmp_path / "r", plots=False, scenario_kwargs=kw)
    assert not any("check its units" in n for n in right["notes"]), right["notes"]


def _sensor_file(path):
    rng = np.random.default_rng(1)
    rows = ["time,x,y,sensor"]
    for t in range(6):
        for s in (1, 2):
            for k in range(3):
                rows.append(f"{t},{10 * k + t + rng.normal():.3f},{50 * k + rng.normal():.3f},{s}")
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize(
    "tables, words",
    [
        ({"1": {"p_d": 0.8}}, "sensor(s) 2 of the detections have no [sensors.ID] table"),
        ({}, "the detections name sensor(s) 1, 2 but the config has no [sensors.ID] tables"),
        ({"1": {"p_d": 0.8}, "2": {"p_d": 0.7}}, None),
    ],
)
def test_sensors_without_a_table_are_named(tmp_path, tables, words):
    from jointtrack.experiments.run import run_detections
    from jointtrack.io import read_detections

    dets = read_detections(_sensor_file(tmp_path / "d.csv"))
    cfg = {"clutter_density": 1e-4, "measurement_noise": 1.0}
    m = run_detections(dets, cfg, tmp_path / "o", plots=False, sensors=tables)
    notes = [n for n in m["notes"] if "[sensors.ID]" in n]
    if words is None:
        assert not notes, notes
    else:
        assert len(notes) == 1 and notes[0].startswith(words), notes
        assert "[tracker] sensor (position, measurement_noise 1.0, p_d 0.9" in notes[0]


def _run_cli(cwd, *args):
    return CliRunner().invoke(app, ["run", *map(str, args)], catch_exceptions=False)


def test_a_new_run_does_not_overwrite_an_unfinished_checkpoint(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "small.toml").write_text("[scenario]\nn_scans = 8\n")
    base = ("--config", "small.toml", "--out", "o", "--checkpoint", "ck.npz")
    assert _run_cli(tmp_path, *base, "--max-scans", 4).exit_code == 0
    msg = one_line_error(_run_cli(tmp_path, *base), "--checkpoint ck.npz", "unfinished run")
    assert "4 scans done" in msg and "`jointtrack run --resume ck.npz`" in msg
    r = _run_cli(tmp_path, "--resume", "ck.npz")  # what the message says works
    assert r.exit_code == 0, r.output
    # the run is complete: a new run may replace its checkpoint, and says so
    r = _run_cli(tmp_path, *base)
    assert r.exit_code == 0, r.output
    assert "held the checkpoint of a completed run" in r.output
    # a file that is not a checkpoint is never overwritten
    (tmp_path / "notes.txt").write_text("keep me")
    one_line_error(
        _run_cli(tmp_path, "--config", "small.toml", "--checkpoint", "notes.txt"),
        "--checkpoint notes.txt exists and is not the checkpoint",
    )
    assert (tmp_path / "notes.txt").read_text() == "keep me"
    # a new file: no message
    r = _run_cli(tmp_path, "--config", "small.toml", "--out", "n", "--checkpoint", "new.npz")
    assert r.exit_code == 0 and "checkpoint" not in r.output, r.output


# ----------------------------------------------------------------------------- item 6: logs

BOX_DRAWING = re.compile("[\u2500-\u257f\u2580-\u259f]")


def test_piped_output_is_plain_whole_lines(tmp_path):
    code = "import sys; from jointtrack.cli import main; sys.argv[0] = 'jointtrack'; main()"
    r = subprocess.run(
        [sys.executable, "-c", code, "run", "--max-scans", "4", "--out", str(tmp_path / "o")],
        capture_output=True,  # stdout is a pipe, as in `jointtrack run | tee log`
        timeout=600,
        env={**os.environ, "COLUMNS": "60"},
    )
    assert r.returncode == 0, r.stderr.decode("utf-8", "replace")
    text = r.stdout.decode("utf-8")  # strict: no character cut in half
    assert not BOX_DRAWING.search(text), text
    assert "…" not in text and "\x1b[" not in text  # nothing elided, no colour codes
    lines = text.splitlines()
    # every row whole on its line, however narrow COLUMNS is
    assert any(ln.startswith("tracks ") and ln.endswith("targets tracked at some scan")
               for ln in lines), text  # fmt: skip
    assert any("GOSPA mean" in ln and "[parts² mean: localisation" in ln for ln in lines), text
    assert any(re.fullmatch(r"tracks in cluster +clusters +mean meas\. +mean ms +max ms", ln)
               for ln in lines), text  # fmt: skip


def test_plain_table_aligns_columns():
    from rich.table import Table
    from rich.text import Text

    from jointtrack._console import PlainConsole, plain_table

    t = Table(title="sizes")
    t.add_column("name")
    t.add_column("n", justify="right")
    t.add_row("alpha", "1")
    t.add_row(Text("b [x]"), "1234")  # text: brackets kept
    t.add_row("[bold]c[/bold]", "7")  # markup, read as the rich table reads it
    t.add_row("two\nlines", "5")
    console = PlainConsole()
    out = plain_table(t, console).plain.splitlines()
    assert out == [
        "sizes",
        "name      n",
        "-----  ----",
        "alpha     1",
        "b [x]  1234",
        "c         7",
        "two       5",
        "lines",
    ]
