"""Issue 23 item 3: the PMB/PMBM trackers in `jointtrack run`, checkpoints, sweeps and
`jointtrack bench quality`.

Small scenes throughout (coalescence with 9 steps, a 10-scan detections file), so
the file runs in about a minute on a busy 2-core machine.
"""

from __future__ import annotations

import json
import signal

import numpy as np
import pytest
from typer.testing import CliRunner

from cli_checks import one_line_error
from jointtrack.cli import app
from jointtrack.scenarios import coalescence, crossing
from test_run_durable import _cli

runner = CliRunner()
SMALL = "[scenario]\nseed = 2\nn_steps = 9\n"  # odd: the midpoint is a step


def _run(*args):
    return runner.invoke(app, ["run", "--no-progress", *map(str, args)])


def _config(tmp_path, text, name="run.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def _tracks(path):
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


# ----------------------------------------------------------------------------- scenario runs


@pytest.mark.parametrize("kind", ["pmb", "pmbm"])
def test_poisson_tracker_on_coalescence_runs_the_papers_model(tmp_path, kind):
    from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker

    cfg_file = _config(tmp_path, SMALL)
    out = tmp_path / "o"
    r = _run(
        "--scenario", "coalescence", "--config", cfg_file, "--tracker", kind, "--out", out
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    assert f"{kind}: " in r.output  # the summary's tracker row names the kind
    m = json.loads((out / "metrics.json").read_text())
    t = m["tracker"]
    sc = coalescence(2, n_steps=9)
    assert t["kind"] == kind and t["birth_model"] == "gaussian"
    assert t["birth_weights"] == [0.005] and t["birth_means"] == [[100.0, 100.0, 0.0, 0.0]]
    assert t["birth_covs"] == [np.diag([150.0**2, 150.0**2, 1.0, 1.0]).tolist()]
    assert t["prior_weight"] == 3.0 and t["p_survive"] == 0.99
    assert t["clutter_density"] == pytest.approx(sc.clutter_density)
    assert t["p_g"] == 0.9999  # the Poisson trackers' own gate, not the JPDA scenes' 0.99
    assert t["measurement_noise"] == 1.0 and t["p_d"] == 0.9
    assert m["gospa"]["c"] == 10.0 and m["start"] == "nothing"
    # the run is exactly that tracker on the scenario's detections
    cfg = PMBMConfig.from_dict({k: (tuple(v) if isinstance(v, list) else v)
                                for k, v in t.items() if k != "kind"})  # fmt: skip
    trk = (PMBMTracker if kind == "pmbm" else PMBTracker)(cfg)
    rows = []
    for time, z in zip(sc.times, sc.detections, strict=True):
        res = trk.step(float(time), z)
        order = np.argsort(res.ids)
        rows += [(time, i, *x[:2]) for i, x in zip(res.ids[order], res.x[order], strict=True)]
    got = _tracks(out / "tracks.csv")
    assert len(got) == len(rows) > 0
    np.testing.assert_allclose(got[:, :4], np.array(rows, dtype=float), rtol=1e-9, atol=1e-9)


def test_default_kind_is_jipda_and_jpda_means_m_of_n(tmp_path):
    cfg_file = _config(tmp_path, SMALL)
    base = ["--scenario", "coalescence", "--config", cfg_file]
    r = _run(*base, "--out", tmp_path / "d")
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "d" / "metrics.json").read_text())
    assert m["tracker"]["kind"] == "jipda" and m["tracker"]["existence"] is True
    r = _run(*base, "--tracker", "jpda", "--out", tmp_path / "j")
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "j" / "metrics.json").read_text())
    assert m["tracker"]["kind"] == "jpda" and m["tracker"]["existence"] is False
    assert "M-of-N" in r.output


def test_uniform_birth_of_a_scene_without_a_birth_model(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    from jointtrack.experiments.config import DEFAULT_BIRTHS_PER_SCAN, DEFAULT_PRIOR_TARGETS

    cfg_file = _config(tmp_path, "[scenario]\nseed = 1\nn_scans = 6\n")
    r = _run("--scenario", "crossing", "--config", cfg_file, "--tracker", "pmb", "--out", "o")
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    sc = crossing(1, n_scans=6)
    area = float(np.prod(sc.region[:, 1] - sc.region[:, 0]))
    t = m["tracker"]
    assert t["birth_model"] == "uniform"
    assert t["birth_density"] == pytest.approx(DEFAULT_BIRTHS_PER_SCAN / area)
    assert t["prior_density"] == pytest.approx(DEFAULT_PRIOR_TARGETS / area)
    vmax = max(float(np.hypot(*s[:, 2:].T).max()) for s in sc.truth_states)
    assert t["max_speed"] == pytest.approx(1.5 * vmax)
    assert any("uniform" in n and "default" in n for n in m["notes"])


# ----------------------------------------------------------------------------- detections file


def _write_detections(path, seed=1, n_scans=10):
    sc = crossing(seed, n_scans=n_scans, clutter_per_scan=3.0)
    with open(path, "w") as fh:
        fh.write("time,x,y\n")
        for t, z in zip(sc.times, sc.detections, strict=True):
            for p in z:
                fh.write(f"{float(t)!r},{float(p[0])!r},{float(p[1])!r}\n")
    return sc


def test_detections_run_estimates_the_clutter_from_the_bounding_box(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    sc = _write_detections(tmp_path / "det.csv")
    r = _run("--detections", "det.csv", "--tracker", "pmbm", "--out", "o")
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    z = np.concatenate([d for d in sc.detections if len(d)])
    n_scans = sum(1 for d in sc.detections if len(d))  # a file has no empty scans
    area = float(np.prod(z.max(axis=0) - z.min(axis=0)))
    assert m["tracker"]["kind"] == "pmbm"
    assert m["tracker"]["clutter_density"] == pytest.approx(len(z) / n_scans / area, rel=1e-12)
    assert any("upper bound" in n for n in m["notes"])
    assert "estimated" in r.output
    # a clutter density that is given is used as it is, and nothing is estimated
    _config(tmp_path, "[tracker]\nclutter_density = 2e-5\n[pmbm]\nr_estimate = 0.5\n")
    r = _run("--detections", "det.csv", "--tracker", "pmb", "--config", "run.toml", "--out", "g")
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "g" / "metrics.json").read_text())
    assert m["tracker"]["clutter_density"] == 2e-5 and m["tracker"]["r_estimate"] == 0.5
    assert not any("upper bound" in n for n in m["notes"])


# ----------------------------------------------------------------------------- checkpoints


def test_killed_pmbm_run_resumes_to_the_uninterrupted_output(tmp_path):
    from jointtrack.trackers.state_io import read_state

    cfg_file = _config(tmp_path, SMALL)
    base = ["--scenario", "coalescence", "--config", cfg_file, "--tracker", "pmbm"]
    full = _run(*base, "--out", tmp_path / "full")
    assert full.exit_code == 0, full.output
    args = [*base, "--out", "part", "--checkpoint", "ck.npz", "--checkpoint-every", "2"]
    killed = _cli(["run", *args], tmp_path, fault="scan:4")  # a subprocess, killed
    assert killed.returncode == -signal.SIGKILL
    assert read_state(tmp_path / "ck.npz")[2]["tracker"] == "pmbm"
    resumed = _run("--resume", tmp_path / "ck.npz")  # no other flag
    assert resumed.exit_code == 0, resumed.output
    assert (tmp_path / "part" / "tracks.csv").read_bytes() == (
        tmp_path / "full" / "tracks.csv"
    ).read_bytes()
    got = json.loads((tmp_path / "part" / "metrics.json").read_text())
    want = json.loads((tmp_path / "full" / "metrics.json").read_text())
    for key in ("gospa", "tracks", "tracker", "notes", "n_scans"):
        assert got[key] == want[key], key


def test_resume_refuses_another_kind(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg_file = _config(tmp_path, SMALL)
    base = ["--scenario", "coalescence", "--config", cfg_file, "--max-scans", "3"]
    r = _run(*base, "--tracker", "pmbm", "--out", "p", "--checkpoint", "p.npz")
    assert r.exit_code == 0, r.output
    for other in ("pmb", "jipda", "jpda"):
        one_line_error(_run("--resume", "p.npz", "--tracker", other), "--tracker", "pmbm", other)
    r = _run(*base, "--out", "j", "--checkpoint", "j.npz")  # the default: JIPDA
    assert r.exit_code == 0, r.output
    one_line_error(_run("--resume", "j.npz", "--tracker", "pmbm"), "jipda", "pmbm")
    # the kind of a config file is checked too
    _config(tmp_path, '[tracker]\nkind = "pmb"\n', "k.toml")
    one_line_error(_run("--resume", "p.npz", "--config", "k.toml"), "pmb", "pmbm")
    # and the API says so as well
    from jointtrack.experiments.run import RunConfigError, run_scenario

    with pytest.raises(RunConfigError, match="pmbm tracker, but this run asks for the pmb"):
        run_scenario(
            "coalescence",
            {},
            tmp_path / "p",
            seed=2,
            scenario_kwargs={"n_steps": 9},
            resume=tmp_path / "p.npz",
            tracker="pmb",
            plots=False,
        )


# ----------------------------------------------------------------------------- bad settings


@pytest.mark.parametrize(
    "toml, flags, needles",
    [
        ("[tracker]\nr_confirm = 0.95\n", ["--tracker", "pmbm"], ["r_confirm", "pmbm"]),
        ("[pmbm]\nr_estimate = 0.5\n", ["--tracker", "jipda"], ["[pmbm]", "jipda"]),
        ("[pmbm]\nr_estimate = 0.5\n", [], ["[pmbm]"]),
        ("[tracker]\nexistence = true\n", ["--tracker", "jpda"], ["existence", "jipda"]),
        ("[pmbm]\nbogus = 1\n", ["--tracker", "pmbm"], ["bogus", "[pmbm]"]),
        ("[pmbm]\nr_estimate = 1.5\n", ["--tracker", "pmbm"], ["r_estimate"]),
        ("", ["--tracker", "pmbm", "--start-from", "truth"], ["--start-from truth", "PMB"]),
        ("", ["--tracker", "kalman"], ["--tracker", "pmbm"]),
    ],
)
def test_settings_that_do_not_fit_the_kind_are_refused(tmp_path, toml, flags, needles):
    cfg_file = _config(tmp_path, SMALL + toml)
    r = _run("--scenario", "coalescence", "--config", cfg_file, *flags, "--out", tmp_path / "o")
    one_line_error(r, *needles)


# ----------------------------------------------------------------------------- sweeps


def test_sweep_with_a_tracker_kind_axis(tmp_path):
    from jointtrack.experiments.run import run_scenario
    from jointtrack.sweep import parse_spec, run_cell
    from jointtrack.sweep.cell import method_label

    spec = parse_spec(
        {
            "sweep": {"seeds": [3], "tracker": {"kind": ["jpda", "jipda", "pmb", "pmbm"]}},
            "scenario": {"name": "coalescence", "n_steps": 7},
            # along a kind axis each cell takes its own kind's settings
            "tracker": {"r_confirm": 0.95},
            "pmbm": {"r_estimate": 0.5},
        }
    )
    assert spec.n_runs == 4
    rows = {}
    for run in spec.runs():
        row = run_cell(run.params, run.seed)
        assert row["status"] == "ok", row["error"]
        rows[run.params["tracker.kind"]] = row["metrics"]
        assert method_label(run.params) == f"{run.params['tracker.kind']}/exact"
    # the PMBM cell is `run_scenario` of that kind with the cell's settings and seed
    m = run_scenario(
        "coalescence",
        {"seed": 3},
        tmp_path / "direct",
        seed=3,
        scenario_kwargs={"n_steps": 7},
        tracker="pmbm",
        pmbm={"r_estimate": 0.5},
        plots=False,
    )
    assert rows["pmbm"]["gospa"] == m["gospa"]["mean"]
    assert m["tracker"]["r_estimate"] == 0.5
    # JPDA and JIPDA differ (M-of-N vs existence): the axis compares different trackers
    assert rows["jpda"]["gospa"] != rows["jipda"]["gospa"]
    # without a kind axis, a setting of another kind is refused before anything runs
    with pytest.raises(ValueError, match="r_confirm"):
        parse_spec(
            {
                "sweep": {"seeds": 1, "scenario": {"n_steps": [7, 9]}},
                "scenario": {"name": "coalescence"},
                "tracker": {"kind": "pmbm", "r_confirm": 0.95},
            }
        )
    with pytest.raises(ValueError, match="kind"):
        parse_spec({"sweep": {"seeds": 1, "tracker": {"kind": ["pmbm", "mht"]}}})


# ----------------------------------------------------------------------------- bench quality


def test_bench_quality_quick_has_the_poisson_trackers_and_gospa_parts(tmp_path, monkeypatch):
    from jointtrack.bench import quality as bench

    tiny = bench.Scene(
        "coalescence",
        "tiny",
        lambda seed, quick: coalescence(seed, n_steps=7),
        10.0,
    )
    monkeypatch.setattr(bench, "SCENES", (tiny,))
    monkeypatch.setattr(bench, "POISSON_BUDGET", {True: 300.0, False: 300.0})  # no cut-off
    out = tmp_path / "q.json"
    res = bench.run(quick=True, out=str(out))
    scene = res["scenes"]["coalescence"]
    names = ["jointtrack PMB", "jointtrack PMBM", bench.CONFIGURATIONS[0][0]]
    if bench.stonesoup_available():
        names.append(bench.STONESOUP)
    for name in names:
        assert name in scene["rows"], name
        s = {k: np.asarray(v, dtype=float) for k, v in scene["series"][name].items()}
        # one seed: GOSPA² per scan is exactly the sum of its three parts
        parts = s["gospa_localisation"] + s["gospa_missed"] + s["gospa_false"]
        np.testing.assert_allclose(s["gospa"] ** 2, parts, rtol=1e-9, atol=1e-9)
        assert scene["rows"][name]["scans"] == 7
    png = tmp_path / "q_gospa_parts.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads(out.read_text())["parts_plot"] == str(png)
