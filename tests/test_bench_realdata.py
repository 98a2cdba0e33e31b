"""The real-data benchmark's Stone Soup side, data fetch and harness, on tiny files of our own.

Stone Soup is a test extra, so nothing here is skipped without it. The real
data is never used: the fetch runs against a fake pip that builds small
archives of the same layout.
"""

from __future__ import annotations

import hashlib
import io
import json
import subprocess
import tarfile
import zipfile

import numpy as np
import pytest
from typer.testing import CliRunner

from jointtrack.bench import realdata, realdata_data
from jointtrack.bench.realdata_data import DataFile, RealDataError, fetch_realdata
from jointtrack.bench.stonesoup_realdata import (
    check_inputs,
    demo_pipeline_reports,
    run_stonesoup,
    track_stonesoup,
)
from jointtrack.cli import app

SENSOR = dict(measurement_noise=15.0, p_d=0.9, clutter_density=1e-9)


def stationary(positions, n_scans=5, window=60.0, labels=True):
    """One report per vessel per window (as the demo's MetadataReducer leaves them), each
    vessel fixed at its position, vessel v reporting v + 1 seconds into each window."""
    rows = sorted((k * window + v + 1.0, v) for k in range(n_scans) for v in range(len(positions)))
    t = np.array([r[0] for r in rows])
    z = np.array([positions[r[1]] for r in rows], dtype=float)
    lab = np.array([f"v{r[1]}" for r in rows]) if labels else None
    st = np.arange(1, n_scans + 1) * window
    return t, z, lab, np.searchsorted(st, t), st


def tracks_of(table):
    """track id → its (x, y) rows."""
    return {int(i): table[table[:, 1] == i, 2:4] for i in np.unique(table[:, 1])}


@pytest.mark.parametrize("config", ["demo", "nn", "gnn", "jpda"])
def test_two_separate_stationary_vessels_give_two_tracks(config):
    vessels = [(0.0, 0.0), (5000.0, 300.0)]
    t, z, lab, k, st = stationary(vessels)
    r = track_stonesoup(config, t, z, lab, k, st, **SENSOR)
    assert r["scans_done"] == r["scans_total"] == 5 and not r["stopped"]
    tracks = tracks_of(r["table"])
    assert len(tracks) == 2
    # each track stays on one vessel; the two tracks are on different vessels
    owners = set()
    for xy in tracks.values():
        d = np.hypot(*(xy[:, None, :] - np.array(vessels)[None]).transpose(2, 0, 1))
        owner = int(np.argmin(d[0]))
        assert np.all(d[:, owner] < 60.0), (config, d)
        owners.add(owner)
    assert owners == {0, 1}
    # times on the scene's time base, never after the last scan
    assert r["table"][:, 0].min() >= t[0] and r["table"][:, 0].max() <= st[-1]


def test_demo_gates_on_the_label_and_nn_does_not():
    # A reports in scans 0 and 2, B (5 m from A) only in scan 1: nearest neighbour hands
    # B's report to A's track; the demo's MMSI gater refuses it and starts B's own track
    t = np.array([1.0, 61.0, 121.0])
    z = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 0.0]])
    lab = np.array(["A", "B", "A"])
    k = np.array([0, 1, 2])
    st = np.array([60.0, 120.0, 180.0])
    demo = tracks_of(track_stonesoup("demo", t, z, lab, k, st)["table"])
    nn = tracks_of(track_stonesoup("nn", t, z, lab, k, st)["table"])
    assert len(nn) == 1
    assert len(demo) == 2
    assert sorted(float(xy[0, 0]) for xy in demo.values()) == [0.0, 5.0]
    for xy in demo.values():  # neither track ever moves onto the other vessel
        assert np.ptp(xy[:, 0]) < 1e-9


def test_unlabelled_reports_match_any_track_under_the_demo_gater():
    t, z, lab, k, st = stationary([(0.0, 0.0)], n_scans=4)
    lab = np.array(["A", "", "", "A"])
    tracks = tracks_of(track_stonesoup("demo", t, z, lab, k, st)["table"])
    assert len(tracks) == 1


@pytest.mark.parametrize(
    "change, exc, needle",
    [
        (dict(positions=np.ones((2, 2), dtype=bool)), TypeError, "positions"),
        (dict(positions=np.array([[0.0, np.nan], [1.0, 1.0]])), ValueError, "positions"),
        (dict(positions=np.zeros((2, 3))), ValueError, "positions"),
        (dict(times=np.array([1.0, 130.0])), ValueError, "scan's time"),
        (dict(times=np.array([1.0, 60.0])), ValueError, "previous scan"),
        (dict(scan_times=np.array([60.0, 60.0])), ValueError, "scan_times"),
        (dict(scan_index=np.array([1, 0])), ValueError, "scan_index"),
        (dict(scan_index=np.array([0, 2])), ValueError, "scan_index"),
        (dict(scan_index=np.array([0.0, 1.0])), TypeError, "scan_index"),
        (dict(labels=np.array([1, 2])), TypeError, "labels"),
        (dict(labels=np.array(["a"])), ValueError, "labels"),
    ],
)
def test_bad_inputs_are_named(change, exc, needle):
    args = dict(
        times=np.array([1.0, 61.0]),
        positions=np.zeros((2, 2)),
        labels=np.array(["a", "b"]),
        scan_index=np.array([0, 1]),
        scan_times=np.array([60.0, 120.0]),
    )
    args.update(change)
    with pytest.raises(exc, match=needle):
        check_inputs(**args)


@pytest.mark.parametrize(
    "sensor, needle",
    [
        (dict(measurement_noise=None), "measurement_noise"),
        (dict(measurement_noise=True), "measurement_noise"),
        (dict(measurement_noise=15.0, p_d=1.5, clutter_density=1e-9), "p_d"),
        (dict(measurement_noise=15.0, p_d=0.9, clutter_density=-1.0), "clutter_density"),
    ],
)
def test_sensor_figures_are_checked_before_a_child_starts(sensor, needle, tmp_path):
    t, z, _, k, st = stationary([(0.0, 0.0)], n_scans=2)
    with pytest.raises((TypeError, ValueError), match=needle):
        run_stonesoup("jpda", t, z, None, k, st, workdir=tmp_path, **sensor)
    assert not (tmp_path / "input.npz").exists()


def test_child_run_matches_the_in_process_run_and_is_measured(tmp_path):
    t, z, lab, k, st = stationary([(0.0, 0.0), (3000.0, 0.0), (0.0, 4000.0)], n_scans=6)
    seen = []
    r = run_stonesoup(
        "demo", t, z, lab, k, st, poll=0.1, workdir=tmp_path, progress=lambda d, n: seen.append(n)
    )
    assert r.error is None and r.completed and r.stopped_by is None
    assert r.scans_done == r.scans_total == 6 and set(seen) == {6}
    here = track_stonesoup("demo", t, z, lab, k, st)["table"]
    assert len(np.unique(r.track_ids)) == 3
    # the same states (ids may be numbered differently: by first appearance in a set)
    child = np.column_stack([r.track_times, r.track_positions])
    mine = here[:, [0, 2, 3]]
    order = np.lexsort(child.T[::-1]), np.lexsort(mine.T[::-1])
    np.testing.assert_allclose(child[order[0]], mine[order[1]], atol=1e-5)
    # measured: a Python process with Stone Soup imported holds tens of MiB
    assert r.peak_rss > 30 * 2**20 and len(r.rss) == len(r.rss_times) >= 1
    assert r.cpu > 0 and r.wall >= r.loop_wall > 0
    files = {p.name for p in tmp_path.iterdir()}
    assert {"input.npz", "params.json", "tracks.csv", "status.json"} <= files
    assert not any(name.endswith((".pkl", ".pickle")) for name in files)


def test_a_stop_ends_the_run_after_the_last_completed_scan():
    from jointtrack.bench.stonesoup_realdata import StopTracking

    t, z, _, k, st = stationary([(0.0, 0.0), (0.0, 3000.0)], n_scans=8)

    def stop_after_three(done):
        if done == 3:
            raise StopTracking

    r = track_stonesoup("nn", t, z, None, k, st, on_scan=stop_after_three)
    assert r["stopped"] and r["scans_done"] == 3 and r["scans_total"] == 8
    times = r["table"][:, 0]
    assert times.max() <= st[2] and np.count_nonzero(times > st[1]) == 2  # scan 3 kept


def test_wall_cap_stops_the_child_which_writes_what_it_completed(tmp_path):
    # far more cheap scans than fit in the cap; the stop may come while Stone Soup is
    # still importing on a busy machine (then no scan is done) — either way a clean exit
    n = 20_000
    t = np.arange(n) * 10.0 + 1.0
    z = np.zeros((n, 2))
    st = np.arange(1, n + 1) * 10.0
    r = run_stonesoup("nn", t, z, None, np.arange(n), st, wall_cap=2.0, poll=0.2, workdir=tmp_path)
    assert r.stopped_by == "wall_cap" and r.error is None, r.error
    assert r.scans_done < n and not r.completed
    assert json.loads((tmp_path / "status.json").read_text())["stopped"]
    if r.scans_done:
        assert r.track_times.max() <= st[r.scans_done - 1]


def test_demo_pipeline_reduction_follows_stone_soups_feeders(tmp_path):
    csv = tmp_path / "ais.csv"
    csv.write_text(
        "Time,MMSI,Latitude_degrees,Longitude_degrees,COG_degrees,SOG_knots\n"
        "2016-01-12 13:00:00.000,111,50.0,-1.0,0,0\n"
        "2016-01-12 13:00:10.000,111,50.001,-1.0,0,0\n"
        "2016-01-12 13:00:20.000,222,50.1,-1.1,0,0\n"
        "2016-01-12 13:00:50.000,111,50.002,-1.0,0,0\n"
        "2016-01-12 13:03:00.000,222,50.2,-1.2,0,0\n"
    )
    d = demo_pipeline_reports(csv, window=60.0)
    # TimeSyncFeeder: the first report alone at its own time, then windows (a, a + 60],
    # empty ones included; MetadataReducer: the latest report of each MMSI per window
    assert d["time_origin"] == "2016-01-12T13:00:00.000Z"
    np.testing.assert_array_equal(d["scan_times"], [0.0, 60.0, 120.0, 180.0])
    np.testing.assert_array_equal(d["times"], [0.0, 20.0, 50.0, 180.0])
    np.testing.assert_array_equal(d["labels"], ["111", "222", "111", "222"])
    np.testing.assert_array_equal(d["scan_index"], [0, 1, 1, 3])
    np.testing.assert_array_equal(d["lat"], [50.0, 50.1, 50.002, 50.2])
    np.testing.assert_array_equal(d["lon"], [-1.0, -1.1, -1.0, -1.2])
    assert d["n_raw"] == 5
    with pytest.raises(FileNotFoundError, match="csv_path"):
        demo_pipeline_reports(tmp_path / "missing.csv")


# ------------------------------------------------------------------ fetch


def _fake_data(monkeypatch):
    """Small stand-ins for the four files, with DATA_FILES' hashes set to theirs."""
    contents = {key: f"{key} test data\n".encode() for key in realdata_data.DATA_FILES}
    files = {
        key: DataFile(f.archive, f.member, hashlib.sha256(contents[key]).hexdigest())
        for key, f in realdata_data.DATA_FILES.items()
    }
    monkeypatch.setattr(realdata_data, "DATA_FILES", files)
    return contents, files


class FakePip:
    """``subprocess.run`` replaced: 'downloads' an archive holding the fake files."""

    def __init__(self, contents, files, returncode=0):
        self.contents, self.files, self.returncode = contents, files, returncode
        self.calls = []

    def __call__(self, command, **kwargs):
        self.calls.append(command)
        cache = realdata_data.Path(command[command.index("-d") + 1])
        key = next(k for k, (_, req, _) in realdata_data.ARCHIVES.items() if req in command)
        assert "--no-deps" in command
        if self.returncode == 0:
            name = realdata_data.ARCHIVES[key][0]
            members = [
                (f.member, self.contents[k]) for k, f in self.files.items() if f.archive == key
            ]
            if name.endswith(".tar.gz"):
                with tarfile.open(cache / name, "w:gz") as tar:
                    for member, data in members:
                        info = tarfile.TarInfo(member)
                        info.size = len(data)
                        tar.addfile(info, io.BytesIO(data))
            else:
                with zipfile.ZipFile(cache / name, "w") as zf:
                    for member, data in members:
                        zf.writestr(member, data)
        return subprocess.CompletedProcess(command, self.returncode, "", "ERROR: no network")


def test_fetch_downloads_extracts_verifies_and_caches(monkeypatch, tmp_path):
    contents, files = _fake_data(monkeypatch)
    pip = FakePip(contents, files)
    paths = fetch_realdata(tmp_path / "cache", progress=None, _run=pip)
    assert set(paths) == {"solent_ais", "opensky_states", "quickstart", "switzerland"}
    for key, path in paths.items():
        assert path.parent == tmp_path / "cache" / "extracted"
        assert path.read_bytes() == contents[key]
    assert len(pip.calls) == 2
    assert "--no-binary" in pip.calls[0] and "stonesoup==1.9.1" in pip.calls[0]
    # second call: everything verified in place, pip not called
    assert fetch_realdata(tmp_path / "cache", progress=None, _run=pip) == paths
    assert len(pip.calls) == 2
    # a damaged extracted file is re-extracted from the cached archive, no download
    paths["quickstart"].write_bytes(b"damaged")
    fetch_realdata(tmp_path / "cache", progress=None, _run=pip)
    assert paths["quickstart"].read_bytes() == contents["quickstart"] and len(pip.calls) == 2


def test_fetch_without_network_says_what_to_download(monkeypatch, tmp_path):
    contents, files = _fake_data(monkeypatch)
    with pytest.raises(RealDataError, match="by hand") as err:
        fetch_realdata(tmp_path, progress=None, _run=FakePip(contents, files, returncode=1))
    assert "pip download --no-deps" in str(err.value) and "stonesoup==1.9.1" in str(err.value)
    assert "no network" in str(err.value)

    def no_pip(command, **kwargs):
        raise FileNotFoundError("python")

    with pytest.raises(RealDataError, match="cannot run pip"):
        fetch_realdata(tmp_path, progress=None, _run=no_pip)


def test_fetch_refuses_a_wrong_hash_and_bad_cache_dirs(monkeypatch, tmp_path):
    contents, files = _fake_data(monkeypatch)
    pip = FakePip(contents, files)
    wrong = dict(files)
    f = files["switzerland"]
    wrong["switzerland"] = DataFile(f.archive, f.member, "0" * 64)
    monkeypatch.setattr(realdata_data, "DATA_FILES", wrong)
    with pytest.raises(RealDataError, match="SHA-256"):
        fetch_realdata(tmp_path / "c", progress=None, _run=pip)
    assert not (tmp_path / "c" / "extracted" / "switzerland.json.gz").exists()

    a_file = tmp_path / "file"
    a_file.write_text("x")
    with pytest.raises(RealDataError, match="not a folder"):
        fetch_realdata(a_file, progress=None, _run=pip)
    with pytest.raises(RealDataError, match="cannot create"):
        fetch_realdata(a_file / "below", progress=None, _run=pip)
    # a corrupt archive in the cache
    monkeypatch.setattr(realdata_data, "DATA_FILES", files)
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "stonesoup-1.9.1.tar.gz").write_bytes(b"not a tar")
    with pytest.raises(RealDataError, match="damaged"):
        fetch_realdata(bad, progress=None, _run=pip)


def test_default_cache_dir_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("JOINTTRACK_DATA", str(tmp_path / "d"))
    assert realdata_data.default_cache_dir() == tmp_path / "d"
    monkeypatch.delenv("JOINTTRACK_DATA")
    assert realdata_data.default_cache_dir().parts[-3:] == (".cache", "jointtrack", "realdata")


def test_cli_bad_cache_dir_exits_non_zero_with_one_line(tmp_path):
    a_file = tmp_path / "file"
    a_file.write_text("x")
    result = CliRunner().invoke(app, ["bench", "realdata", "--cache-dir", str(a_file)])
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    errors = [ln for ln in result.output.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1 and "not a folder" in errors[0]
    result = CliRunner().invoke(app, ["bench", "realdata", "--scene", "nowhere"])
    assert result.exit_code == 2 and "--scene" in result.output
    result = CliRunner().invoke(app, ["bench", "realdata", "--stamp", "now"])
    assert result.exit_code == 2 and "--stamp" in result.output
    result = CliRunner().invoke(app, ["bench", "realdata", "--seeds", "0"])
    assert result.exit_code == 2 and "--seeds" in result.output
    result = CliRunner().invoke(app, ["bench", "realdata", "--bare-tracker", "gnn"])
    assert result.exit_code == 2 and "--bare-tracker" in result.output


# ------------------------------------------------------------------ harness


class Frame:
    """A stand-in local frame: the harness only needs the reference and the way back to
    lat/lon for the map (a crude flat-earth inverse is enough for a picture)."""

    reference = (50.0, -1.0, 0.0)

    def to_geodetic(self, xy):
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return 50.0 + xy[:, 1] / 111_000.0, -1.0 + xy[:, 0] / 71_000.0


def tiny_scene(labels=False):
    vessels = [(0.0, 0.0), (4000.0, 0.0)]
    t, z, lab, k, st = stationary(vessels, n_scans=4, labels=labels)
    truth_t = np.repeat(np.arange(0.0, 241.0, 30.0), 2)
    truth_ids = np.tile([0, 1], len(truth_t) // 2)
    truth_xy = np.array(vessels)[truth_ids]
    return realdata.Scene(
        name="tiny",
        description="two moored vessels",
        time_origin="2016-01-12T13:00:00.000Z",
        frame=Frame(),
        times=t,
        positions=z,
        labels=lab,
        scan_index=k,
        scan_times=st,
        measurement_noise=15.0,
        p_d=0.9,
        clutter_density=1e-9,
        window=60.0,
        truth=lambda: (truth_t, truth_ids, truth_xy),
        default_runners=("stonesoup-nn", "jointtrack-handset"),
    )


def in_process(config):
    def runner(scene, *, wall_cap, workdir=None, progress=None):
        r = track_stonesoup(
            config,
            scene.times,
            scene.positions,
            scene.labels,
            scene.scan_index,
            scene.scan_times,
            measurement_noise=scene.measurement_noise,
        )
        tab = r["table"]
        return realdata.RunResult(
            runner=f"stonesoup-{config}",
            scene=scene.name,
            wall=r["loop_wall"],
            cpu=r["loop_cpu"],
            peak_rss=0,
            scans_done=r["scans_done"],
            scans_total=r["scans_total"],
            rss_times=np.array([0.0, 1.0]),
            rss=np.array([1, 2]) * 2**20,
            track_times=tab[:, 0],
            track_ids=tab[:, 1].astype(int),
            track_positions=tab[:, 2:4],
        )

    return runner


def not_yet(scene, **kwargs):
    raise NotImplementedError("waits for the tracker")


def test_run_writes_json_tracks_and_plot_and_lists_unrun_runners(monkeypatch, tmp_path):
    scene = tiny_scene()
    monkeypatch.setattr(realdata_data, "fetch_realdata", lambda *a, **k: {})
    monkeypatch.setattr(realdata, "build_scenes", lambda *a, **k: [scene])
    monkeypatch.setitem(realdata.RUNNERS, "stonesoup-nn", in_process("nn"))
    monkeypatch.setitem(realdata.RUNNERS, "jointtrack-handset", not_yet)
    report = realdata.run(  # jointtrack-jipda: the handset runner's former name
        out=str(tmp_path / "out"), runners=["stonesoup-nn", "jointtrack-jipda", "stonesoup-demo"]
    )
    entry = report["scenes"]["tiny"]
    assert entry["not_run"]["jointtrack-handset"].startswith("not implemented")
    assert "labels" in entry["not_run"]["stonesoup-demo"]
    assert list(entry["runs"]["stonesoup-nn"]["per_seed"]) == ["unseeded"]
    nn = entry["runs"]["stonesoup-nn"]["per_seed"]["unseeded"]
    assert nn["n_track_ids"] == 2 and nn["completed"]
    out = tmp_path / "out"
    assert json.loads((out / "realdata.json").read_text())["scenes"]["tiny"]["runs"]
    tracks = np.loadtxt(out / "tracks_tiny_stonesoup-nn.csv", delimiter=",", skiprows=1)
    assert len(tracks) == nn["n_track_states"]
    assert (out / "rss_tiny.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    try:
        import jointtrack.metrics.selfreport  # noqa: F401
    except ImportError:
        assert "selfreport" in nn["score_error"]
    else:  # two moored vessels held by two tracks: perfect scores
        assert nn["score"]["coverage"] == 1.0 and nn["score"]["purity"] == 1.0
    try:
        import jointtrack.experiments.map_plot  # noqa: F401
    except ImportError:
        assert nn.get("map_png") is None
    else:
        assert (out / nn["map_png"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_stonesoup_runner_reports_the_child_run(monkeypatch):
    from jointtrack.bench import stonesoup_realdata as ss

    calls = []
    stamped = []

    def child(config, times, positions, labels, scan_index, scan_times, **kwargs):
        # the child's work, in this process (test_child_run_… runs a real child)
        calls.append((config, labels is not None, kwargs["wall_cap"]))
        stamped.append(np.array(times))
        r = track_stonesoup(config, times, positions, labels, scan_index, scan_times)
        tab = r["table"]
        return ss.StoneSoupRun(
            config=config,
            scans_done=r["scans_done"],
            scans_total=r["scans_total"],
            completed=True,
            stopped_by=None,
            wall=2.0,
            cpu=1.5,
            loop_wall=r["loop_wall"],
            loop_cpu=r["loop_cpu"],
            peak_rss=123,
            rss_times=np.array([0.0]),
            rss=np.array([123]),
            track_times=tab[:, 0],
            track_ids=tab[:, 1].astype(np.int64),
            track_positions=tab[:, 2:4],
        )

    monkeypatch.setattr(ss, "run_stonesoup", child)
    scene = tiny_scene(labels=True)
    r = realdata.RUNNERS["stonesoup-demo"](scene, wall_cap=60.0)
    assert calls == [("demo", True, 60.0)]
    assert r.completed and r.runner == "stonesoup-demo" and r.scene == "tiny"
    assert (r.wall, r.cpu, r.peak_rss) == (2.0, 1.5, 123)
    assert len(np.unique(r.track_ids)) == 2
    realdata.RUNNERS["stonesoup-nn"](scene, wall_cap=5.0)
    assert calls[-1] == ("nn", False, 5.0)  # labels never reach the label-blind trackers
    with pytest.raises(ValueError, match="labels"):
        realdata.RUNNERS["stonesoup-demo"](tiny_scene(labels=False), wall_cap=60.0)
    # detection times: each report's own by default, its scan's on request
    np.testing.assert_array_equal(stamped[0], scene.times)
    realdata.RUNNERS["stonesoup-nn"](scene, wall_cap=5.0, stamp="scan")
    np.testing.assert_array_equal(stamped[-1], scene.scan_times[scene.scan_index])
    assert np.any(stamped[-1] != scene.times)
    with pytest.raises(ValueError, match="stamp"):
        realdata.RUNNERS["stonesoup-nn"](scene, wall_cap=5.0, stamp="now")
    d = r.as_dict()
    assert d["scans_done"] == 4 and d["details"]["loop_cpu_s"] > 0
    with pytest.raises(ValueError, match="name"):
        realdata.register_runner("", not_yet)
    with pytest.raises(TypeError, match="runner"):
        realdata.register_runner("x", 3)


def test_scanning_sensor_interpolates_each_identity_to_the_scan_times():
    # needs jointtrack.io.reports (issue 24 item 3); runs once that is merged
    reports_mod = pytest.importorskip("jointtrack.io.reports")
    from jointtrack.io.geodetic import LocalFrame

    frame = LocalFrame(50.0, -1.0)
    # "a": reports at 0, 7, 26 s (east 0, 70, 260 m); "b": at 3 s and 900 s (a gap > max_gap)
    t = np.array([0.0, 3.0, 7.0, 26.0, 900.0])
    east = np.array([0.0, 500.0, 70.0, 260.0, 600.0])
    ident = np.array(["a", "b", "a", "a", "b"])
    lat, lon = frame.to_geodetic(np.column_stack([east, np.zeros(5)]))[:2]
    reports = reports_mod.Reports(
        times=t, time_origin="2020-01-01T00:00:00Z", lat=lat, lon=lon, identity=ident
    )
    sensor, scan_times = realdata.scanning_sensor(reports, frame, 10.0, max_gap=600.0)
    np.testing.assert_allclose(scan_times[:4], [0.0, 10.0, 20.0, 30.0])
    # "a" at 0 (its report), 10 and 20 (between 7 and 26 s), not at 30 (after its last);
    # "b" only at 900 s, its report on a scan time: not across its 897 s gap
    assert sensor.identity.tolist() == ["a", "a", "a", "b"]
    np.testing.assert_array_equal(sensor.times, [0.0, 10.0, 20.0, 900.0])
    xy = frame.to_local(sensor.lat, sensor.lon)
    expected = np.interp([0.0, 10.0, 20.0], [0.0, 7.0, 26.0], [0.0, 70.0, 260.0])
    np.testing.assert_allclose(xy[:, 0], [*expected, 600.0], atol=1e-6)
    np.testing.assert_allclose(xy[:, 1], 0.0, atol=1e-6)
    # with a longer max_gap "b" is seen at every scan time from 10 s to 900 s
    sensor, _ = realdata.scanning_sensor(reports, frame, 10.0, max_gap=1000.0)
    b = sensor.identity == "b"
    np.testing.assert_array_equal(sensor.times[b], np.arange(10.0, 901.0, 10.0))
    xy = frame.to_local(sensor.lat[b], sensor.lon[b])
    np.testing.assert_allclose(
        xy[:, 0], np.interp(sensor.times[b], [3, 900], [500, 600]), atol=1e-6
    )


def test_rss_sampler_sees_an_allocation():
    import time

    with realdata.RssSampler(poll=0.02) as s:
        time.sleep(0.1)
        block = np.ones(64 * 2**20 // 8)  # 64 MiB, touched
        time.sleep(0.2)
        del block
    assert len(s.times) == len(s.rss) >= 5 and np.all(np.diff(s.times) > 0)
    assert max(s.rss) - s.rss[0] > 48 * 2**20
    assert s.peak >= max(s.rss)


# ------------------------------------------------------------------ issue 32.6: runners, seeds


def moving_scene(labels=False, seed=None, name="moving"):
    """Two aircraft flying straight and level 20 km apart, seen by a perfect 10 s scanning
    sensor (1 m noise) for 20 scans, in a real local frame about 47 °N 8 °E."""
    from jointtrack.io.geodetic import LocalFrame

    scan_times = 10.0 * np.arange(20)
    start = np.array([[0.0, 0.0], [20_000.0, 0.0]])
    vel = np.array([[15.0, 5.0], [-10.0, 12.0]])
    rng = np.random.default_rng(7)
    rows = [(k, v, start[v] + vel[v] * t) for k, t in enumerate(scan_times) for v in (0, 1)]
    scan_index = np.array([r[0] for r in rows])
    truth_xy = np.array([r[2] for r in rows])
    truth_ids = np.array([r[1] for r in rows])
    return realdata.Scene(
        name=name,
        description="two aircraft",
        time_origin="2020-06-01T10:00:00.5Z",
        frame=LocalFrame(47.0, 8.0),
        times=scan_times[scan_index],
        positions=truth_xy + rng.normal(0.0, 1.0, truth_xy.shape),
        labels=np.array([f"a{v}" for v in truth_ids]) if labels else None,
        scan_index=scan_index,
        scan_times=scan_times,
        measurement_noise=1.0,
        p_d=1.0,
        clutter_density=0.0,
        window=10.0,
        truth=lambda: (scan_times[scan_index], truth_ids, truth_xy),
        stamp="scan",
        seed=seed,
    )


@pytest.mark.parametrize("labels", [False, True])
def test_bare_runner_runs_the_plain_file_through_the_default_run_path(tmp_path, labels):
    from jointtrack.bench.jointtrack_realdata import run_bare
    from jointtrack.io import read_detections

    scene = moving_scene(labels=labels)
    r = run_bare(scene, wall_cap=60.0, workdir=tmp_path)
    # the plain file: time, lat, lon (+ label where the scene has labels), the rows' own
    # positions and times, read back by the detections reader into the same places
    head = (tmp_path / "plain.csv").read_text().splitlines()[0]
    assert head == ("time,lat,lon,label" if labels else "time,lat,lon")
    det = read_detections(tmp_path / "plain.csv")
    assert det.n_detections == len(scene.times) and (det.labels is not None) == labels
    # rows in time order (stable): the file's scans hold the scene's rows in that order
    frame = det.geo_frame()
    back = scene.frame.to_local(*frame.to_geodetic(np.concatenate(det.scans))[:2])
    order = np.argsort(scene.times, kind="stable")
    np.testing.assert_allclose(back, scene.positions[order], rtol=0, atol=1e-6)
    assert r.runner == "jointtrack-bare" and r.error is None and r.completed
    # the run's own peak (its samples), not this process's peak so far (ru_maxrss)
    assert r.peak_rss == max(r.rss) > 0
    assert "no config" in r.details["command"]
    # tracks back on the scene's clock (its origin is 0.5 s before the file's first
    # timestamp would be if shifted) and frame: both aircraft held, on their tracks
    assert set(np.round(r.track_times, 6)) <= set(scene.scan_times)
    realdata.score_run(scene, r)
    assert r.score["coverage"] >= 0.8 and r.score["tracks_per_identity"] == 1.0
    assert r.score["gospa_localisation"] ** 0.5 < 50.0


def test_a_refused_bare_run_is_recorded_not_raised(monkeypatch, tmp_path):
    from jointtrack.experiments import run as run_mod
    from jointtrack.experiments.config import RunConfigError

    calls = []

    def refuse(detections, **kwargs):
        calls.append(kwargs.get("tracker"))
        raise RunConfigError("tracker = 'pmbm' does not run on report files")

    monkeypatch.setattr(run_mod, "run_detections", refuse)
    scene = moving_scene()
    r = realdata.RUNNERS["jointtrack-bare-pmbm"](scene, wall_cap=60.0)
    assert calls == ["pmbm"] and r.runner == "jointtrack-bare-pmbm"
    assert "report files" in r.error and not r.completed and len(r.track_ids) == 0
    realdata.score_run(scene, r)
    assert r.score is None and r.score_error
    figures = realdata.run_figures(r, scene.scan_times)
    assert figures["coverage"] is None and figures["x_real_time"] is None
    # a run stopped after 10 of the 20 scans: × real time over the 90 s it covered
    r.error, r.scans_done, r.cpu = None, 10, 3.0
    assert realdata.run_figures(r, scene.scan_times)["x_real_time"] == 30.0
    from jointtrack.bench.jointtrack_realdata import run_bare

    with pytest.raises(ValueError, match="tracker"):
        run_bare(scene, tracker="gnn", wall_cap=1.0)


def _keep_every(k_of_seed):
    """A runner reporting the scene's truth as tracks at every k-th instant (k by seed),
    one track id per identity: coverage 1/k, known per seed."""

    def runner(scene, *, wall_cap, workdir=None, progress=None):
        t, ids, xy = scene.truth()
        k = k_of_seed[scene.seed]
        keep = np.searchsorted(scene.scan_times, t) % k == 0
        return realdata.RunResult(
            runner="keep",
            scene=scene.name,
            wall=1.0,
            cpu=float(k),
            peak_rss=2**20 * k,
            scans_done=scene.n_scans,
            scans_total=scene.n_scans,
            rss_times=np.array([0.0]),
            rss=np.array([2**20]),
            track_times=t[keep],
            track_ids=ids[keep] + 100,
            track_positions=xy[keep],
        )

    return runner


def test_seeds_give_per_seed_figures_their_spread_the_table_and_the_class_chart(
    monkeypatch, tmp_path
):
    builds = []

    def build(names, paths, *, quick=False, seed=0):
        builds.append((tuple(names), seed))
        return [moving_scene(seed=seed, name="air")]

    monkeypatch.setattr(realdata_data, "fetch_realdata", lambda *a, **k: {})
    monkeypatch.setattr(realdata, "build_scenes", build)
    monkeypatch.setitem(realdata.RUNNERS, "keep", _keep_every({3: 1, 4: 2, 5: 4}))
    out = tmp_path / "out"
    report = realdata.run(out=str(out), scenes=["air"], runners=["keep"], seed=3, seeds=3)
    assert builds == [(("air",), 3), (("air",), 4), (("air",), 5)]
    entry = report["scenes"]["air"]
    assert entry["seeds"] == [3, 4, 5]
    runs = entry["runs"]["keep"]
    cov = {s: runs["per_seed"][s]["figures"]["coverage"] for s in ("3", "4", "5")}
    assert cov == {"3": 1.0, "4": 0.5, "5": 0.25}
    assert runs["spread"]["coverage"] == {"mean": 1.75 / 3, "min": 0.25, "max": 1.0, "n": 3}
    # both aircraft fly straight and 20 km apart: every truth point is straight flight
    assert runs["spread"]["coverage_straight"] == runs["spread"]["coverage"]
    assert runs["spread"]["coverage_manoeuvre"] is None
    assert runs["spread"]["lost_straight"]["max"] == 75.0  # in %
    # × real time = 190 s of scene / CPU (1, 2, 4 s)
    assert runs["spread"]["x_real_time"] == {
        "mean": (190 + 95 + 47.5) / 3,
        "min": 47.5,
        "max": 190.0,
        "n": 3,
    }
    saved = json.loads((out / "realdata.json").read_text())
    assert saved["scenes"]["air"]["runs"]["keep"]["per_seed"]["5"]["figures"]["coverage"] == 0.25
    md = (out / "realdata.md").read_text()
    row = next(ln for ln in md.splitlines() if ln.startswith("| air | keep |"))
    assert "0.583 (0.250–1.000)" in row and "| 3 |" in row
    assert (out / "coverage_classes.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert {p.name for p in out.glob("tracks_air_keep_s*.csv")} == {
        "tracks_air_keep_s3.csv",
        "tracks_air_keep_s4.csv",
        "tracks_air_keep_s5.csv",
    }
    with pytest.raises(ValueError, match="seeds"):
        realdata.run(scenes=["air"], runners=["keep"], seeds=0)
    with pytest.raises(ValueError, match="bare_trackers"):
        realdata.run(scenes=["air"], runners=["keep"], bare_trackers=("gnn",))


@pytest.mark.parametrize("tracker", ["jipda", "pmb", "pmbm"])
def test_handset_runner_runs_each_tracker_kind_and_names_it(tracker):
    from jointtrack.bench.jointtrack_realdata import run_jointtrack

    scene = moving_scene()
    r = run_jointtrack(scene, tracker=tracker, wall_cap=60.0)
    suffix = "" if tracker == "jipda" else f"-{tracker}"
    assert r.runner == f"jointtrack-handset{suffix}" and r.completed
    realdata.score_run(scene, r)
    # two aircraft 20 km apart, 1 m noise, P_D 1: each held by one track
    assert r.score["coverage"] >= 0.8 and r.score["tracks_per_identity"] == 1.0


def test_handset_runner_names_an_unknown_tracker():
    from jointtrack.bench.jointtrack_realdata import run_jointtrack

    with pytest.raises(ValueError, match="tracker must be one of jipda, pmb, pmbm, got 'gnn'"):
        run_jointtrack(moving_scene(), tracker="gnn", wall_cap=60.0)
