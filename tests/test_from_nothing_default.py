"""JIPDA runs from nothing take ``FROM_NOTHING_JIPDA`` unless ``[tracker]`` sets its keys
(issue 33).

The settings a run used are read back from its ``metrics.json`` (``tracker``), for
the library call (:func:`run_scenario`) and for the CLI, which builds the tracker
configuration itself.
"""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from jointtrack.cli import app
from jointtrack.experiments import run as runmod
from jointtrack.experiments.config import FROM_NOTHING_JIPDA, from_nothing_overrides
from jointtrack.experiments.run import resolved_start, run_scenario, start_settings
from jointtrack.trackers.config import TrackerConfig

SHORT = {"plots": False, "max_scans": 4}


def _tracker(metrics):
    return metrics["tracker"]


def test_a_jipda_run_from_nothing_takes_the_from_nothing_settings(tmp_path):
    m = run_scenario("crossing", out_dir=tmp_path, start_from="nothing", **SHORT)
    tr = _tracker(m)
    assert tr["kind"] == "jipda"
    assert tr["tentative_association"] == "alternatives"
    assert tr["r_confirm"] == FROM_NOTHING_JIPDA["r_confirm"]


def test_a_run_from_the_truth_keeps_the_tracker_defaults(tmp_path):
    m = run_scenario("bojilov", out_dir=tmp_path, **SHORT)  # bojilov starts from the truth
    tr = _tracker(m)
    assert m["start"] == "truth"
    assert tr["tentative_association"] == TrackerConfig().tentative_association == "joint"
    assert tr["r_confirm"] == TrackerConfig().r_confirm


@pytest.mark.parametrize(
    "table",
    [
        {"tentative_association": "joint"},
        {"r_confirm": 0.95},
        {"tentative_association": "joint", "r_confirm": 0.9},
    ],
)
def test_the_users_keys_win(tmp_path, table):
    m = run_scenario("crossing", table, out_dir=tmp_path, start_from="nothing", **SHORT)
    tr = _tracker(m)
    for key, value in (FROM_NOTHING_JIPDA | table).items():
        assert tr[key] == value


def test_m_of_n_jpda_and_poisson_kinds_are_left_alone():
    assert from_nothing_overrides("jpda", {"existence": False}) == {"existence": False}
    assert from_nothing_overrides(None, {"existence": False}) == {"existence": False}
    assert from_nothing_overrides("pmb", {}) == {}
    assert from_nothing_overrides("jipda", {"existence": True}) == (
        {"existence": True} | FROM_NOTHING_JIPDA
    )


def test_a_users_r_init_between_the_two_confirmation_defaults_is_taken(tmp_path):
    """r_init 0.95 is refused with TrackerConfig's r_confirm 0.9, taken from nothing (0.97)."""
    with pytest.raises(ValueError, match="r_init"):
        TrackerConfig(r_init=0.95)
    m = run_scenario("crossing", {"r_init": 0.95}, out_dir=tmp_path, start_from="nothing", **SHORT)
    assert _tracker(m)["r_init"] == 0.95


def test_resolved_start():
    assert resolved_start("truth", "crossing", "jipda") == "truth"
    assert resolved_start(None, "bojilov", None) == "truth"
    assert resolved_start(None, "bojilov", "pmb") == "nothing"
    assert resolved_start(None, "crossing", None) == "nothing"
    assert resolved_start(None, "crossing", None, particle=object()) == "truth"


def test_the_cli_builds_the_same_settings(tmp_path):
    out = tmp_path / "cli"
    r = CliRunner().invoke(
        app,
        ["run", "--scenario", "crossing", "--max-scans", "4", "--out", str(out)],
    )
    assert r.exit_code == 0, r.output
    tr = json.loads((out / "metrics.json").read_text(encoding="utf-8"))["tracker"]
    assert tr["tentative_association"] == "alternatives"
    assert tr["r_confirm"] == FROM_NOTHING_JIPDA["r_confirm"]
    assert "scored as alternatives" in r.output


def test_start_settings():
    assert start_settings(None, "crossing", "jipda", {}) == (
        "nothing",
        {"existence": True} | FROM_NOTHING_JIPDA,
    )
    assert start_settings(None, "bojilov", None, {"r_confirm": 0.95}) == (
        "truth",
        {"r_confirm": 0.95},
    )
    assert start_settings("nothing", "crossing", "jpda", {}) == ("nothing", {"existence": False})
    assert start_settings("nothing", "crossing", None, {}, particle=object()) == ("nothing", {})


def test_the_library_and_the_cli_resolve_the_start_through_one_helper(tmp_path, monkeypatch):
    """Both take the settings run.start_settings returns (a stand-in that changes them)."""
    calls = []

    def changed(start, name, kind, tracker, particle=None):
        calls.append(name)
        s, over = start_settings(start, name, kind, tracker, particle)
        return s, over | {"r_confirm": 0.991}

    monkeypatch.setattr(runmod, "start_settings", changed)
    m = run_scenario("crossing", out_dir=tmp_path / "lib", start_from="nothing", **SHORT)
    assert _tracker(m)["r_confirm"] == 0.991
    out = tmp_path / "cli"
    r = CliRunner().invoke(
        app, ["run", "--scenario", "crossing", "--max-scans", "4", "--out", str(out)]
    )
    assert r.exit_code == 0, r.output
    tr = json.loads((out / "metrics.json").read_text(encoding="utf-8"))["tracker"]
    assert tr["r_confirm"] == 0.991
    assert calls and set(calls) == {"crossing"}
