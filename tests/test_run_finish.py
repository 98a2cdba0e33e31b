"""`jointtrack run` finishes what it started: a kill while it writes its outputs resumes
(issue 31, defect 1).

After the last scan is checkpointed a run writes its outputs — the tracks file (a
report run's with its lat/lon columns), scene.png, gospa.png, map.png, metrics.json —
each atomically, the checkpoint recording each one (see
:mod:`jointtrack.experiments.writers`). Here the CLI runs in a subprocess that is
killed (SIGKILL) at each step of that phase (fault hooks, ``JOINTTRACK_FAULT``), from
outside as soon as its tracks file exists (the issue's reproduction) and at seeded
random wall-clock instants over the whole run; ``--resume CHECKPOINT`` alone then
ends with every output of the uninterrupted run: the tracks file (CSV or Parquet) and
the PNGs byte for byte, metrics.json equal but for its wall-clock fields
(:data:`WALL_CLOCK`) and, when a kill fell in the tracking phase, ``n_scans_this_run``.
Cases: a built-in scenario (JIPDA, CSV), a detections file (PMBM, Parquet) and a
synthetic AIS report file (CSV; JIPDA, and PMBM killed at a random instant).
``benchmarks/kill_campaign.py`` kills many more runs.
"""

from __future__ import annotations

import contextlib
import copy
import json
import os
import signal
import time

import numpy as np
import pytest
from typer.testing import CliRunner

import cli_process
from cli_checks import one_line_error
from jointtrack.cli import app
from jointtrack.scenarios import crossing
from jointtrack.trackers.state_io import read_run
from test_run_durable import _cli, _cli_env
from test_run_realdata import write_ais

runner = CliRunner()

#: metrics.json "timing" fields that are wall-clock measurements, different in any two
#: runs (killed or not); every other field of a resumed run equals the uninterrupted one
WALL_CLOCK = ("association_seconds", "loop_seconds", "scans_per_second", "total_seconds")
#: the same, per row of "timing" "clusters"
WALL_CLOCK_PER_CLUSTER = ("mean_seconds", "max_seconds", "total_seconds")
#: outputs of each case, in the order the finishing phase writes them
OUTPUTS = {
    "scenario": ["tracks.csv", "scene.png", "gospa.png", "metrics.json"],
    "detections": ["tracks.parquet", "scene.png", "metrics.json"],
    "ais": ["tracks.csv", "scene.png", "map.png", "metrics.json"],
    # the AIS file with the PMBM tracker (asynchronous reporting model and labels)
    "ais-pmbm": ["tracks.csv", "scene.png", "map.png", "metrics.json"],
    # a plain lat/lon detection file: the same geodetic outputs as a report file
    "geo": ["tracks.csv", "scene.png", "map.png", "metrics.json"],
}


def _case_args(base, case):
    return {
        "scenario": ["--config", base / "crossing.toml"],
        "detections": [
            "--detections",
            base / "det.csv",
            "--tracker",
            "pmbm",
            "--format",
            "parquet",
        ],
        "ais": ["--detections", base / "ais.csv"],
        "ais-pmbm": ["--detections", base / "ais.csv", "--tracker", "pmbm"],
        "geo": ["--detections", base / "geo.csv"],
    }[case]


def _write_detections(path):
    sc = crossing(1, n_scans=10, clutter_per_scan=3.0)
    with open(path, "w") as fh:
        fh.write("time,x,y\n")
        for t, z in zip(sc.times, sc.detections, strict=True):
            for p in z:
                fh.write(f"{float(t)!r},{float(p[0])!r},{float(p[1])!r}\n")


def _write_geodetic(path):
    """The crossing scenario's detections as a plain ``time, lat, lon`` file (near 50.8° N)."""
    from jointtrack.io.geodetic import LocalFrame

    sc = crossing(1, n_scans=10, clutter_per_scan=3.0)
    frame = LocalFrame(50.8, -1.2)
    with open(path, "w") as fh:
        fh.write("time,lat,lon\n")
        for t, z in zip(sc.times, sc.detections, strict=True):
            lat, lon = frame.to_geodetic(np.asarray(z, dtype=float).reshape(-1, 2))
            for la, lo in zip(lat, lon, strict=True):
                fh.write(f"{float(t)!r},{float(la)!r},{float(lo)!r}\n")


def _files(out) -> dict:
    """Every file under ``out`` (hidden ones too) → its bytes."""
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


def _without_wall_clock(metrics: dict, tracking_killed: bool = False) -> dict:
    m = copy.deepcopy(metrics)
    for key in WALL_CLOCK:
        m["timing"].pop(key)
    for row in m["timing"]["clusters"]:
        for key in WALL_CLOCK_PER_CLUSTER:
            row.pop(key)
    if tracking_killed:  # the scans of the process that tracked last
        m.pop("n_scans_this_run")
    return m


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Inputs, and each case's uninterrupted run in ref-CASE/out — a subprocess, timed,
    for the cases killed at random instants (:data:`RANDOM_KILLS`), in this process
    for the others: ``(base, {case: (outputs, seconds from its first write to its end
    or None)})``."""
    base = tmp_path_factory.mktemp("finish")
    (base / "crossing.toml").write_text(
        '[scenario]\nname = "crossing"\nseed = 4\nn_scans = 12\nclutter_per_scan = 4.0\n'
    )
    _write_detections(base / "det.csv")
    write_ais(base / "ais.csv")
    _write_geodetic(base / "geo.csv")
    ref = {}
    timed = {case for case, _ in RANDOM_KILLS}
    for case in OUTPUTS:
        cwd = base / f"ref-{case}"
        cwd.mkdir()
        cmd = ["run", "--no-progress", *_case_args(base, case), "--out", "out"]
        if case in timed:
            started, ended, _ = supervise(cmd, cwd)
            # the seconds from the run's first write (its output directory prepared) to its end
            seconds = ended - started
        else:  # no random kill needs its time: run in this process (CI time)
            with contextlib.chdir(cwd):
                r = runner.invoke(app, list(map(str, cmd)))
            assert r.exit_code == 0, r.output
            seconds = None
        files = _files(cwd / "out")
        assert sorted(files) == sorted(OUTPUTS[case])
        ref[case] = (files, seconds)
    return base, ref


def _assert_like_the_uninterrupted_run(out, want: dict, tracking_killed: bool) -> None:
    got = _files(out)
    assert sorted(got) == sorted(want)  # every output, and nothing else (no parts, no tmp)
    for name, data in want.items():
        if name == "metrics.json":
            a, b = json.loads(got[name]), json.loads(data)
            assert _without_wall_clock(a, tracking_killed) == _without_wall_clock(
                b, tracking_killed
            )
        else:
            assert got[name] == data, name


def _assert_outputs_so_far_are_final(out, want: dict) -> None:
    """A killed run's visible outputs are each absent or complete (never half written)."""
    for p in out.iterdir():
        if p.is_file() and not p.name.startswith("."):
            if p.name == "metrics.json":
                json.loads(p.read_text())
            else:
                assert p.read_bytes() == want[p.name], p.name


#: scans between checkpoints (the AIS file has a scan per report time: hundreds)
EVERY = {"scenario": 4, "detections": 4, "ais": 50, "ais-pmbm": 50, "geo": 4}


def _first(base, case):
    return ["run", "--no-progress", *_case_args(base, case), "--out", "out"] + [
        "--checkpoint", "ck.npz", "--checkpoint-every", EVERY[case],
    ]  # fmt: skip


# ----------------------------------------------------------------------------- fault hooks

# every step of the finishing phase, numbered as the case's OUTPUTS: each kill stops the
# run (or the resume before it) there; the next resume continues
CHAINS = {
    # (the write stage of a file, between its temp file and its rename, in the others)
    "scenario": ["finishing:0", "output:1", "recorded:2", "done:0", "cleanup:1"],
    "detections": ["write:0", "output:1:INT", "output:2"],  # INT: Ctrl-C
    "ais": ["output:0", "write:2", "recorded:3"],
    # one kill (CI time): after map.png, the output only geodetic runs add
    "geo": ["output:2"],
}


@pytest.mark.parametrize("case", list(CHAINS))
def test_a_kill_at_each_step_of_the_finishing_phase_resumes(runs, case, tmp_path, monkeypatch):
    from jointtrack.experiments.writers import PARTS_DIR, run_is_complete

    base, ref = runs
    want = ref[case][0]
    out = tmp_path / "out"
    for i, fault in enumerate(CHAINS[case]):
        cmd = _first(base, case) if i == 0 else ["run", "--no-progress", "--resume", "ck.npz"]
        killed = _cli(cmd, tmp_path, fault)
        if fault.endswith(":INT"):  # one line saying how to continue, exit 130
            assert killed.returncode == 130, killed.stderr
            assert "interrupted" in killed.stderr and "--resume" in killed.stderr
            assert "Traceback" not in killed.stderr
        else:
            assert killed.returncode == -signal.SIGKILL, (fault, killed.stderr)
        info = read_run(tmp_path / "ck.npz")
        stage, n = fault.split(":")[:2]
        assert info["phase"] == ("done" if stage in ("done", "cleanup") else "finishing")
        assert info["outputs"] == OUTPUTS[case]
        if stage == "recorded":
            assert OUTPUTS[case][int(n)] in info["outputs_done"]
        if stage in ("write", "output"):
            assert OUTPUTS[case][int(n)] not in info["outputs_done"]
        if stage != "cleanup":  # the parts stay until every output is written
            parts = sorted((out / PARTS_DIR).iterdir())
            assert [p.name[:11] for p in parts] == [f"part-{k:06d}" for k in range(info["parts"])]
        _assert_outputs_so_far_are_final(out, want)
        if stage == "finishing":
            # a new run does not overwrite the checkpoint of a run still writing its outputs
            monkeypatch.chdir(tmp_path)
            r = runner.invoke(app, _first(base, case))
            one_line_error(r, "--checkpoint ck.npz", "unfinished run", "writing its outputs")
        if stage == "cleanup":
            # half the parts are gone, but the run is done: a new run may replace it
            assert (out / PARTS_DIR).is_dir() and run_is_complete(info, out / PARTS_DIR)
    monkeypatch.chdir(tmp_path)
    resumed = runner.invoke(app, ["run", "--no-progress", "--resume", "ck.npz"])
    assert resumed.exit_code == 0, resumed.output
    _assert_like_the_uninterrupted_run(out, want, tracking_killed=False)
    # once more: every output is there, nothing is done and nothing is touched
    stamps = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    again = runner.invoke(app, ["run", "--no-progress", "--resume", "ck.npz"])
    assert again.exit_code == 0, again.output
    assert "already complete, nothing to do" in again.output
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == stamps


# ----------------------------------------------------------------------------- kills from outside


def supervise(cmd, cwd, kill=None, deadline: float = 900.0):
    """Run the CLI (``cmd``, a subprocess in ``cwd``) and watch its output directory
    ``cwd/out``; returns ``(started, ended, killed)``: the seconds from the launch to the
    moment the run had prepared its output directory (its parts directory appeared;
    None if never seen) and to its end, and whether it was killed. ``kill(elapsed,
    started)``: SIGKILL the run as soon as it returns true (a run that ended before
    exits 0)."""
    parts = cwd / "out" / ".tracks-parts"
    t0 = time.monotonic()
    proc = cli_process.start(cmd, cwd, _cli_env(), keep_stdout=False)
    started = None
    killed = False
    try:
        while proc.poll() is None:
            elapsed = time.monotonic() - t0
            assert elapsed < deadline, "the run took too long"
            if started is None and parts.is_dir():
                started = elapsed
            if kill is not None and kill(elapsed, started):
                proc.kill()
                killed = True
                break
            time.sleep(0.002)
        proc.wait()
        assert killed or proc.returncode == 0, proc.stderr
        return started, time.monotonic() - t0, killed
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _resume_or_restart(base, case, tmp_path, monkeypatch) -> bool:
    """Resume the killed run with ``--resume ck.npz`` alone (or, killed before its first
    checkpoint, start it again) in this process; returns whether a checkpoint of the
    tracking phase was resumed or the run restarted (the tracking was killed)."""
    monkeypatch.chdir(tmp_path)
    ck = tmp_path / "ck.npz"
    tracking = not ck.exists() or read_run(ck).get("phase", "tracking") == "tracking"
    cmd = ["run", "--no-progress", "--resume", "ck.npz"] if ck.exists() else _first(base, case)
    r = runner.invoke(app, cmd)
    assert r.exit_code == 0, r.output
    return tracking


# "ais" writes what "geo" and "ais-pmbm" write
@pytest.mark.parametrize("case", [c for c in OUTPUTS if c not in ("geo", "ais-pmbm")])
def test_killed_as_soon_as_the_tracks_file_exists(runs, case, tmp_path, monkeypatch):
    # the reproduction: SIGKILL once OUT/tracks.* exists, then --resume alone
    base, ref = runs
    tracks = tmp_path / "out" / OUTPUTS[case][0]
    supervise(_first(base, case), tmp_path, lambda elapsed, started: tracks.exists())
    _resume_or_restart(base, case, tmp_path, monkeypatch)
    _assert_like_the_uninterrupted_run(tmp_path / "out", ref[case][0], tracking_killed=False)


# seeded instants across each run, from its first write (the seconds before, loading
# modules and kernels and reading the inputs, write nothing) to past its end: a fraction
# of the uninterrupted run's time from its first write to its end
RANDOM_KILLS = [("scenario", 0), ("detections", 1), ("ais", 2), ("ais-pmbm", 3)]


@pytest.mark.parametrize("case, seed", RANDOM_KILLS)
def test_killed_at_a_random_instant_the_resumed_run_is_the_uninterrupted_one(
    runs, case, seed, tmp_path, monkeypatch
):
    base, ref = runs
    want, seconds = ref[case]
    delay = seconds * float(np.random.default_rng([31, seed]).uniform(0.0, 1.05))
    _, _, killed = supervise(
        _first(base, case),
        tmp_path,
        lambda t, started: started is not None and t >= started + delay,
    )
    tracking = _resume_or_restart(base, case, tmp_path, monkeypatch)
    print(
        f"{case}: killed {delay:.2f} s after its first write (of {seconds:.2f} s): "
        f"{killed=}, {tracking=}"
    )
    _assert_like_the_uninterrupted_run(tmp_path / "out", want, tracking_killed=tracking)


# ----------------------------------------------------------------------------- in process


def _small_scenario():
    return crossing(4, n_scans=9, clutter_per_scan=3.0)


def test_a_failing_output_leaves_the_run_resumable(tmp_path, monkeypatch):
    from jointtrack.experiments import plots
    from jointtrack.experiments.run import run_scenario

    run_scenario(_small_scenario(), None, tmp_path / "full")
    want = _files(tmp_path / "full")
    ck = tmp_path / "ck.npz"
    plot_gospa = plots.plot_gospa

    def disk_full(path, *args, **kwargs):
        path.write_bytes(b"\x89PNG half")  # a part of the file, then the failure
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(plots, "plot_gospa", disk_full)
    with pytest.raises(OSError, match="No space left"):
        run_scenario(_small_scenario(), None, tmp_path / "o", checkpoint=ck, checkpoint_every=4)
    # nothing half written is left, and the checkpoint says what is done
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == [
        ".tracks-parts", "scene.png", "tracks.csv",
    ]  # fmt: skip
    info = read_run(ck)
    assert info["phase"] == "finishing" and info["outputs_done"] == ["tracks.csv", "scene.png"]
    monkeypatch.setattr(plots, "plot_gospa", plot_gospa)
    run_scenario(_small_scenario(), None, tmp_path / "o", resume=ck)
    got = _files(tmp_path / "o")
    assert sorted(got) == sorted(want)
    for name in ("tracks.csv", "scene.png", "gospa.png"):
        assert got[name] == want[name], name
    assert read_run(ck)["phase"] == "done"


def test_resume_of_a_complete_run_with_an_output_removed_names_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "small.toml").write_text('[scenario]\nname = "crossing"\nn_scans = 6\n')
    base = ["run", "--no-progress", "--config", "small.toml", "--out", "o"]
    assert runner.invoke(app, [*base, "--checkpoint", "ck.npz"]).exit_code == 0
    (tmp_path / "o" / "gospa.png").unlink()
    r = runner.invoke(app, ["run", "--resume", "ck.npz"])
    line = one_line_error(r, "gospa.png", "missing", "start the run again")
    assert "scene.png" not in line and "tracks.csv" not in line


def test_a_stopped_run_writes_again_only_a_removed_output(tmp_path):
    from jointtrack.experiments.run import RunAlreadyComplete, RunConfigError, run_scenario

    ck = tmp_path / "ck.npz"
    out = tmp_path / "o"
    run_scenario(_small_scenario(), None, out, checkpoint=ck, checkpoint_every=2, max_scans=5)
    before = _files(out)
    assert read_run(ck)["phase"] == "done"  # done with its 5 scans, the parts kept
    with pytest.raises(RunAlreadyComplete, match="scans 1-5 of 9 .*nothing to resume"):
        run_scenario(_small_scenario(), None, out, resume=ck, max_scans=5)
    metrics_written = (out / "metrics.json").stat().st_mtime_ns
    (out / "scene.png").unlink()
    run_scenario(_small_scenario(), None, out, resume=ck, max_scans=5)
    assert _files(out) == before  # the figure again, as it was
    assert (out / "metrics.json").stat().st_mtime_ns == metrics_written  # not rewritten
    # fewer scans than the checkpoint has processed cannot be made from it
    with pytest.raises(RunConfigError, match="processed 5 scans, more than --max-scans 3"):
        run_scenario(_small_scenario(), None, out, resume=ck, max_scans=3)
    assert _files(out) == before


def test_a_report_run_writes_each_output_once_in_its_final_form(tmp_path, monkeypatch):
    # the tracks file is renamed into place once, already with its lat/lon columns (it
    # was written without them and rewritten afterwards, a kill between losing them)
    from jointtrack.experiments.realdata import run_reports

    write_ais(tmp_path / "ais.csv")
    out = tmp_path / "o"
    renames: list = []
    replace = os.replace

    def spy(src, dst):
        dst = os.fspath(dst)
        # renames onto hidden temporary files are a writer's own atomic write (io's
        # writers are atomic by themselves too); the outputs are the visible names
        if os.path.dirname(dst) == str(out) and not os.path.basename(dst).startswith("."):
            header = open(src, "rb").read(200) if dst.endswith(".csv") else b""
            renames.append((os.path.basename(dst), header.split(b"\n")[0]))
        replace(src, dst)

    monkeypatch.setattr(os, "replace", spy)
    real_write = type(out).write_text

    def no_direct_write(self, *args, **kwargs):
        # temporary files (hidden) are written; an output itself only renamed into place
        assert self.parent != out or self.name.startswith("."), f"{self} written in place"
        return real_write(self, *args, **kwargs)

    monkeypatch.setattr(type(out), "write_text", no_direct_write)
    run_reports(tmp_path / "ais.csv", out_dir=out, checkpoint=tmp_path / "ck.npz")
    assert [name for name, _ in renames] == OUTPUTS["ais"]
    assert renames[0][1].startswith(b"time,track_id,x,y,lat,lon,vx,vy,existence")
    assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUTS["ais"])


def test_a_checkpoint_with_a_malformed_phase_is_refused_naming_it(tmp_path):
    from jointtrack.experiments.run import RunConfigError, load_tracker, run_scenario

    ck = tmp_path / "ck.npz"
    out = tmp_path / "o"
    run_scenario(_small_scenario(), None, out, plots=False, checkpoint=ck, max_scans=4)
    trk, info = load_tracker(ck), read_run(ck)
    for key, value, needle in [
        ("phase", "writing", "phase 'writing'"),
        ("outputs_done", ["tracks.csv", "../x"], "outputs_done"),
        ("stop", -1, "stop = -1"),
    ]:
        trk.save(ck, run={**info, key: value})
        with pytest.raises(RunConfigError, match=needle):
            run_scenario(_small_scenario(), None, out, plots=False, resume=ck)
