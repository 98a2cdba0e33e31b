"""Monte Carlo sweeps on Dask (issue 15): exactly-once rows, worker kills, resume,
serial equality, failures, spec validation and the command line.

One LocalCluster of 2 worker processes serves the cluster tests; the cells are
small crossing scenarios (a few scans, ~0.05 s each) so the file stays well
under a minute on a 2-core machine.
"""

from __future__ import annotations

import json
import math
import os
import signal

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from cli_checks import one_line_error
from jointtrack.cli import app
from jointtrack.sweep import ResultStore, parse_spec, run_cell, run_id, run_sweep
from jointtrack.sweep import engine as engine_mod
from jointtrack.sweep.cell import TIMING_METRICS

distributed = pytest.importorskip("distributed")

# 2 × 2 cells × 3 seeds = 12 runs
SPEC = {
    "sweep": {
        "seeds": 3,
        "tracker": {"association": ["exact", "pda"]},
        "scenario": {"clutter_per_scan": [2.0, 5.0]},
    },
    "scenario": {"name": "crossing", "n_scans": 12},
}
SPEC_TOML = """
[sweep]
seeds = 2
scenario.n_scans = [6, 1]   # n_scans = 1 is refused by the scenario: those runs fail

[scenario]
name = "crossing"
"""


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        silence_logs=40,
    )
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def finished(client, tmp_path_factory):
    """The 12-run sweep, run once on the cluster."""
    spec = parse_spec(SPEC)
    out = tmp_path_factory.mktemp("sweep")
    outcome = run_sweep(spec, out, client=client)
    return spec, out, outcome


def _rows_by_id(out):
    rows = ResultStore(out / "results").read_rows()
    ids = [r["run_id"] for r in rows]
    assert len(ids) == len(set(ids)), "a run has two rows"
    return {r["run_id"]: r for r in rows}


def _metrics(row):
    return {k: v for k, v in row.items() if k.startswith("metric.")}


def test_every_run_present_exactly_once(finished):
    spec, out, outcome = finished
    assert spec.n_runs == 12 and outcome.total == 12
    assert outcome.complete and outcome.ran == 12 and outcome.failed == 0
    assert not outcome.missing
    rows = _rows_by_id(out)
    assert set(rows) == {r.run_id for r in spec.runs()}
    row = next(iter(rows.values()))
    assert row["status"] == "ok" and row["error"] is None
    assert row["version"] and row["host"] and row["worker"].startswith("tcp://")
    assert row["run_seconds"] > 0 and row["queue_seconds"] >= 0
    assert json.loads(row["params"])["scenario.name"] == "crossing"
    # no leftover temporary file, the directory reads as one dataset
    assert not list((out / "results").glob(".*"))
    import pyarrow.dataset as ds

    assert ds.dataset(out / "results").count_rows() == 12


def test_results_equal_serial_runs(finished):
    spec, out, _ = finished
    rows = _rows_by_id(out)
    for run in spec.runs():
        serial = run_cell(run.params, run.seed)
        assert serial["status"] == "ok"
        stored = _metrics(rows[run.run_id])
        want = {f"metric.{k}": v for k, v in serial["metrics"].items() if k not in TIMING_METRICS}
        assert want and set(want) <= set(stored)
        for key, value in want.items():
            # bit for bit: the runs do not depend on the process's history (the frontier
            # kernels sum in load-only loops, tests/test_assignment_determinism.py)
            assert stored[key] == value or (math.isnan(stored[key]) and math.isnan(value)), key


def test_report_mean_and_ci_per_cell(finished, tmp_path):
    from jointtrack.sweep import write_report

    spec, out, _ = finished
    written = write_report(ResultStore(out / "results").read_rows(), spec.axes, tmp_path)
    assert len(written["cells"]) == 4
    cell = written["cells"][0]
    assert cell["n_ok"] == 3 and cell["metrics"]["gospa"][2] == 3
    assert written["summary"].read_text().count("\n") == 5
    # each metric vs each of the two axes, one line per method
    names = {p.name for p in written["plots"]}
    assert "gospa_vs_scenario_clutter_per_scan.png" in names
    assert "gospa_vs_tracker_association.png" in names


def test_mixed_int_and_float_axis_values_read_as_one_dataset(tmp_path):
    import pyarrow.dataset as ds

    store = ResultStore(tmp_path / "results")
    for i, value in enumerate([1, 0.5, 2]):  # the int first: its file must not set the type
        params = {"scenario.clutter_density": value, "tracker.existence": i != 1}
        store.write({"run_id": f"r{i}", "params": json.dumps(params), **params, "status": "ok"})
    table = ds.dataset(tmp_path / "results").to_table()
    assert table.num_rows == 3
    assert str(table.schema.field("scenario.clutter_density").type) == "double"
    assert sorted(table["scenario.clutter_density"].to_pylist()) == [0.5, 1.0, 2.0]
    assert str(table.schema.field("tracker.existence").type) == "bool"
    rows = {r["run_id"]: r for r in store.read_rows()}
    assert json.loads(rows["r0"]["params"])["scenario.clutter_density"] == 1  # exact, an int


def test_killed_worker_loses_nothing(client, tmp_path):
    spec = parse_spec(SPEC)
    pids = client.run(os.getpid)  # worker address -> pid
    killed, in_flight = [], []

    def kill_one(row):
        # after the first result, SIGKILL the other worker in the middle of a run
        if not killed:
            addr = next(a for a in pids if a != row["worker"])
            in_flight.extend(client.processing([addr])[addr])
            os.kill(pids[addr], signal.SIGKILL)
            killed.append(addr)

    outcome = run_sweep(spec, tmp_path, client=client, on_row=kill_one)
    assert killed
    assert outcome.complete and outcome.ran == 12 and not outcome.missing
    rows = _rows_by_id(tmp_path)
    assert set(rows) == {r.run_id for r in spec.runs()}
    # the runs the killed worker held were retried elsewhere and finished there
    assert in_flight
    retried = [r for r in rows.values() if any(r["run_id"] in k for k in in_flight)]
    assert retried and all(r["status"] == "ok" and r["worker"] != killed[0] for r in retried)
    client.wait_for_workers(2, timeout=60)  # the nanny restarted it for the next tests


def test_resume_runs_only_what_is_missing(client, tmp_path):
    spec = parse_spec(SPEC)
    seen = []

    def interrupt(row):
        seen.append(row["run_id"])
        if len(seen) == 4:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(spec, tmp_path, client=client, on_row=interrupt)
    first = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "results").glob("*.parquet")}
    assert len(first) == 4
    again = []
    outcome = run_sweep(spec, tmp_path, client=client, on_row=lambda r: again.append(r["run_id"]))
    assert outcome.skipped == 4 and outcome.ran == 8 and outcome.complete
    assert set(again).isdisjoint(seen) and len(again) == 8
    for p in (tmp_path / "results").glob("*.parquet"):
        if p.name in first:
            assert p.stat().st_mtime_ns == first[p.name], "a finished run was rewritten"
    assert len(_rows_by_id(tmp_path)) == 12
    # nothing left: a third start runs nothing and needs no cluster
    third = run_sweep(spec, tmp_path)
    assert third.ran == 0 and third.workers == 0 and third.complete


def test_failing_cell_is_recorded_and_the_others_finish(client, tmp_path):
    import tomllib

    spec = parse_spec(tomllib.loads(SPEC_TOML))
    outcome = run_sweep(spec, tmp_path, client=client)
    assert outcome.total == 4 and outcome.ok == 2 and outcome.failed == 2
    assert not outcome.complete
    failed = [r for r in _rows_by_id(tmp_path).values() if r["status"] == "failed"]
    assert len(failed) == 2
    assert all("n_scans" in r["error"] and r["scenario.n_scans"] == 1 for r in failed)
    # a failed run is rerun on resume and its row replaced, never duplicated
    again = run_sweep(spec, tmp_path, client=client)
    assert again.skipped == 2 and again.ran == 2 and len(_rows_by_id(tmp_path)) == 4


def test_fail_fast_stops_at_the_first_failure(client, tmp_path):
    import tomllib

    spec = parse_spec(tomllib.loads(SPEC_TOML.replace("seeds = 2", "seeds = 8")))
    outcome = run_sweep(spec, tmp_path, client=client, fail_fast=True)
    assert outcome.failed >= 1 and not outcome.complete
    assert outcome.ok + outcome.failed + len(outcome.missing) == outcome.total == 16
    assert outcome.ran == outcome.ok + outcome.failed


# ----------------------------------------------------------------------------- spec


def _base(**sweep):
    return {"sweep": {"seeds": 2, **sweep}, "scenario": {"name": "crossing"}}


@pytest.mark.parametrize(
    ("data", "needle"),
    [
        (_base(**{"tracker.bogus": [1]}), "bogus"),  # unknown tracker key as an axis
        (_base(**{"radar.p_d": [0.9]}), "radar.p_d"),  # unknown axis table
        (_base(**{"scenario.n_scans": []}), "scenario.n_scans"),  # empty axis
        (_base(**{"scenario.n_scans": 5}), "scenario.n_scans"),  # not a list
        (_base(**{"tracker.p_d": ["high"]}), "p_d"),  # wrong type
        (_base(**{"tracker.association": ["exact", "exact"]}), "tracker.association"),
        (_base(**{"scenario.speed": [1.0], "scenario.nope": [1]}), "nope"),
        ({"sweep": {"seeds": 2}, "scenario": {"name": "crossing", "wobble": 1}}, "wobble"),
        ({"sweep": {"seeds": 2}, "tracker": {"warp": 9}}, "warp"),  # unknown table key
        ({"sweep": {"seeds": 2}, "metrics": {"c": -1.0}}, "'c'"),
        ({"sweep": {"seeds": 2}, "tracks": {}}, "tracks"),  # unknown table
        ({"sweep": {"seeds": 2}, "scenario": {"seed": 3}}, "seed"),
        ({"sweep": {"seeds": 0}}, "seeds"),
        ({"sweep": {"seeds": [1, 1]}}, "seeds"),
        ({"sweep": {"seeds": "10"}}, "seeds"),
        ({"sweep": {}}, "seeds"),
        ({"scenario": {"name": "crossing"}}, "sweep"),
        ({"sweep": {"seeds": 1}, "scenario": {"name": "mars"}}, "name"),
        ({"sweep": {"seeds": 1}, "filter": {"name": "sps-mb"}}, r"\[filter\] key .name."),
        (
            {"sweep": {"seeds": 1}, "scenario": {"name": "acoustic"}, "tracker": {"p_d": 0.9}},
            "tracker",
        ),
        (
            {"sweep": {"seeds": 1, "filter.particles": [0]}, "scenario": {"name": "acoustic"}},
            "filter.particles",
        ),
        ({"sweep": {"seeds": 1, "tracker.weights": ["saddle"]}}, "weights"),  # not particle
    ],
)
def test_bad_spec_raises_value_error_naming_the_key(data, needle):
    with pytest.raises(ValueError, match=needle):
        parse_spec(data)


def test_spec_of_every_runnable_kind():
    spec = parse_spec(
        {
            "sweep": {"seeds": [3, 7], "filter": {"name": ["sps-mb", "sps-phd"]}},
            "scenario": {"name": "acoustic"},
            "filter": {"n_scans": 10, "particles": 50},
        }
    )
    assert spec.n_runs == 4 and [r.seed for r in spec.runs()] == [3, 7, 3, 7]
    particle = parse_spec(
        {
            "sweep": {"seeds": 1, "tracker.weights": ["exact", "saddle"]},
            "scenario": {"name": "abreast", "n_scans": 5},
            "tracker": {"kind": "particle", "particles": 50},
        }
    )
    assert particle.n_cells == 2


_values = st.one_of(
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=False, allow_infinity=False, width=32),
    st.text(max_size=5),
    st.booleans(),
)


@settings(max_examples=60, deadline=None)
@given(
    st.dictionaries(st.text(min_size=1, max_size=8), _values, max_size=5),
    st.integers(0, 10**6),
)
def test_run_id_is_stable_and_order_free(params, seed):
    reordered = dict(reversed(list(params.items())))
    assert run_id(params, seed) == run_id(reordered, seed)
    assert run_id(params, seed) != run_id(params, seed + 1)
    assert len(run_id(params, seed)) == 20


@settings(max_examples=30, deadline=None)
@given(
    st.lists(
        st.lists(st.integers(2, 40), min_size=1, max_size=4, unique=True), min_size=1, max_size=2
    ),
    st.integers(1, 5),
)
def test_grid_size_and_unique_run_ids(axis_values, n_seeds):
    keys = ["scenario.n_scans", "scenario.clutter_per_scan"]
    sweep = {"seeds": n_seeds} | dict(zip(keys, axis_values, strict=False))
    spec = parse_spec({"sweep": sweep, "scenario": {"name": "crossing"}})
    expected = n_seeds
    for v in axis_values:
        expected *= len(v)
    assert spec.n_runs == expected
    runs = spec.runs()
    assert len({r.run_id for r in runs}) == expected
    assert [r.run_id for r in runs] == [r.run_id for r in parse_spec(spec_data(sweep)).runs()]


def spec_data(sweep):
    return {"sweep": dict(sweep), "scenario": {"name": "crossing"}}


# ----------------------------------------------------------------------------- command line

runner = CliRunner()


def test_cli_without_dask_says_how_to_install(tmp_path, monkeypatch):
    path = tmp_path / "spec.toml"
    path.write_text(SPEC_TOML)
    monkeypatch.setattr(engine_mod, "dask_available", lambda: False)
    result = runner.invoke(app, ["sweep", str(path)])
    one_line_error(result, "pip install 'jointtrack[dask]'")


def test_cli_bad_spec_names_the_key(tmp_path):
    path = tmp_path / "spec.toml"
    path.write_text('[sweep]\nseeds = 2\ntracker.p_d = []\n[scenario]\nname = "crossing"\n')
    one_line_error(runner.invoke(app, ["sweep", str(path)]), "tracker.p_d", "empty")


def test_cli_dry_run_and_sweep(tmp_path):
    path = tmp_path / "spec.toml"
    path.write_text(SPEC_TOML)
    out = tmp_path / "out"
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "grid: 2 cells x 2 seeds = 4 runs" in result.output
    assert "pilot crossing jpda/exact" in result.output and "estimate:" in result.output
    assert not out.exists()  # a dry run writes nothing
    # the command's own LocalCluster: one worker process (each imports the package and
    # loads its kernels, ~15 CPU-s); runs spread over two workers are the cluster tests'
    result = runner.invoke(app, ["sweep", str(path), "--workers", "1", "--out", str(out)])
    # two runs fail on purpose: recorded, the others finish, the exit code says so
    assert result.exit_code == 1, result.output
    assert "4 runs: 2 ok, 2 failed, 0 missing" in result.output
    assert (out / "summary.csv").is_file() and len(list((out / "results").iterdir())) == 4
    result = runner.invoke(app, ["sweep", str(path), "--dry-run", "--out", str(out)])
    assert "done already: 2 (failed before, to rerun: 2); to run: 2" in result.output
