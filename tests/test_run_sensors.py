"""Several sensors: scans split per (time, sensor) and processed one after another."""

from __future__ import annotations

import numpy as np
import pytest

from jointtrack.experiments.run import RunConfigError, run_detections
from jointtrack.io import Detections, read_tracks, write_detections
from jointtrack.models import LinearPosition
from jointtrack.trackers import JPDATracker, TrackerConfig
from jointtrack.trackers.sensors import Sensor


def _two_sensor_detections(n_scans=30, seed=0):
    rng = np.random.default_rng(seed)
    times = np.arange(n_scans, dtype=float)
    scans, sensors = [], []
    for t in times:
        truth = np.array([[10.0 * t, 0.0], [10.0 * t, 500.0]])
        z1 = truth + rng.normal(0, 5.0, truth.shape)  # sensor 1: σ = 5 m
        z2 = truth + rng.normal(0, 20.0, truth.shape)  # sensor 2: σ = 20 m
        scans.append(np.vstack([z1, z2]))
        sensors.append(np.array([1, 1, 2, 2]))
    return Detections(times=times, scans=tuple(scans), sensors=tuple(sensors))


CFG = dict(clutter_density=1e-6, measurement_noise=25.0, max_speed=20.0, process_noise=0.1)
TABLES = {1: {"measurement_noise": 25.0}, 2: {"measurement_noise": 400.0, "p_d": 0.9}}


def test_two_sensors_on_two_targets_give_two_tracks(tmp_path):
    det = _two_sensor_detections()
    path = write_detections(det, tmp_path / "det.csv")
    from jointtrack.io import read_detections

    det = read_detections(path)
    assert det.sensors is not None
    run_detections(det, CFG, tmp_path / "out", sensors=TABLES, plots=False)
    tr = read_tracks(tmp_path / "out" / "tracks.csv")
    last = tr["time"] == tr["time"].max()
    assert len(np.unique(tr["track_id"][last])) == 2
    # one row per track and scan time, although each time had two sensor updates
    pairs = set(zip(tr["time"].tolist(), tr["track_id"].tolist(), strict=True))
    assert len(pairs) == len(tr["time"])


def test_sequential_update_uses_each_sensors_noise():
    cfg = TrackerConfig(**CFG)
    trk = JPDATracker(cfg, sensors={1: Sensor(LinearPosition(2, 25.0)), 2: LinearPosition(2, 1e4)})
    trk.start_tracks([[0.0, 0.0, 10.0, 0.0]], np.diag([100.0, 100.0, 25.0, 25.0]), existence=1.0)
    r1 = trk.step(1.0, [[10.0, 0.0]], sensor=1)
    var1 = r1.P[0, 0, 0]
    r2 = trk.step(1.0, [[10.0, 0.0]], sensor=2)  # same time: no prediction in between
    assert r2.P[0, 0, 0] < var1 and r2.P[0, 0, 0] > var1 * (1 - 25.0 / 1e4) * 0.9
    with pytest.raises(ValueError, match="unknown sensor 3"):
        trk.step(2.0, [[20.0, 0.0]], sensor=3)
    with pytest.raises(ValueError, match="must increase"):
        trk.step(0.5, [[20.0, 0.0]], sensor=1)


def test_bad_sensor_tables(tmp_path):
    from jointtrack.experiments.config import load_config

    bad = tmp_path / "bad.toml"
    # a table name is a string id (issue 22); an id that is neither integer nor string is not
    bad.write_text("[sensors.north]\nid = 1.5\nmeasurement_noise = 4.0\n")
    with pytest.raises(RunConfigError, match=r"\[sensors.north\].*integer or a string"):
        load_config(bad)
    bad.write_text("[sensors.1]\nnoise = 4.0\n")
    with pytest.raises(RunConfigError, match="unknown key"):
        load_config(bad)
    good = tmp_path / "good.toml"
    good.write_text('[sensors.north]\nid = 3\np_d = 0.8\n[sensors.2]\ntype = "position"\n')
    assert set(load_config(good).sensors) == {3, 2}


# ----------------------------------------------------------------------------- mixed sensors

RB_STATION = np.array([0.0, -2000.0])  # the fixed range-bearing sensor of the mixed tests
MIXED_CFG = dict(clutter_density=1e-6, measurement_noise=25.0, max_speed=20.0, process_noise=0.1)
MIXED_TABLES = {
    1: {"type": "position", "measurement_noise": 25.0},
    2: {
        "type": "range-bearing",
        "range_noise": 25.0,
        "bearing_noise": 4e-6,
        "sensor_position": RB_STATION.tolist(),
        "clutter_density": 1e-4,
    },
}


def _polar(p, s):
    d = np.atleast_2d(p) - s
    return np.column_stack([np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0])])


def _mixed_detections(n_scans=30, seed=1):
    """Two targets seen at every time by position sensor 1 and range-bearing sensor 2."""
    rng = np.random.default_rng(seed)
    times = np.arange(n_scans, dtype=float)
    scans, sensors, kinds = [], [], []
    for t in times:
        truth = np.array([[10.0 * t, 0.0], [10.0 * t, 500.0]])
        z1 = truth + rng.normal(0, 5.0, truth.shape)
        z2 = _polar(truth, RB_STATION) + rng.normal(0, [5.0, 2e-3], truth.shape)
        scans.append(np.vstack([z1, z2]))
        sensors.append(np.array([1, 1, 2, 2]))
        kinds.append(np.array([False, False, True, True]))  # True: range-bearing row
    return Detections(
        times=times, scans=tuple(scans), sensors=tuple(sensors), kind="mixed", row_kinds=kinds
    )


@pytest.mark.parametrize("suffix", ["csv", "parquet"])
def test_mixed_file_round_trip(tmp_path, suffix):
    from jointtrack.io import read_detections

    det = _mixed_detections(n_scans=3)
    path = write_detections(det, tmp_path / f"mixed.{suffix}")
    if suffix == "csv":
        text = path.read_text().splitlines()
        assert text[0] == "time,x,y,range,bearing,sensor"
        assert text[1].split(",")[3:5] == ["", ""]  # the set a row does not fill: empty
        assert text[3].split(",")[1:3] == ["", ""]
    back = read_detections(path)
    assert back.kind == "mixed" and back.dim == 2 and back.sensor_positions is None
    assert back.sensor_kinds() == {1: "position", 2: "range-bearing"}
    for k in range(3):
        np.testing.assert_array_equal(back.scans[k], det.scans[k])
        assert back.row_kinds[k].tolist() == ["position"] * 2 + ["range-bearing"] * 2
    # the Cartesian form converts range-bearing rows with their sensor's position
    cart = back.cartesian({2: RB_STATION})
    np.testing.assert_allclose(cart[0][2:], [[0.0, 0.0], [0.0, 500.0]], atol=30.0)
    np.testing.assert_array_equal(cart[0][:2], back.scans[0][:2])


def test_mixed_sensors_track_two_targets(tmp_path):
    from jointtrack.io import read_detections

    path = write_detections(_mixed_detections(), tmp_path / "mixed.csv")
    det = read_detections(path)
    m = run_detections(det, MIXED_CFG, tmp_path / "out", sensors=MIXED_TABLES, plots=True)
    tr = read_tracks(tmp_path / "out" / "tracks.csv")
    last = tr["time"] == tr["time"].max()
    assert len(np.unique(tr["track_id"][last])) == 2
    pairs = set(zip(tr["time"].tolist(), tr["track_id"].tolist(), strict=True))
    assert len(pairs) == len(tr["time"])  # one row per (time, track)
    # the tracks follow the targets (range-bearing rows were not read as positions)
    y = np.sort(np.column_stack([tr["x"][last], tr["y"][last]])[:, 1])
    np.testing.assert_allclose(y, [0.0, 500.0], atol=15.0)
    assert (tmp_path / "out" / "scene.png").stat().st_size > 0
    assert m["files"]["scene"].endswith("scene.png")


def test_mixed_file_from_the_command_line(tmp_path):
    from typer.testing import CliRunner

    from jointtrack.cli import app

    path = write_detections(_mixed_detections(n_scans=12), tmp_path / "mixed.csv")
    cfg = tmp_path / "c.toml"
    cfg.write_text(
        "[tracker]\nclutter_density = 1e-6\nmeasurement_noise = 25.0\nmax_speed = 20.0\n"
        "process_noise = 0.1\n"
        '[sensors.radar]\nid = 1\ntype = "position"\n'
        '[sensors.2]\ntype = "range-bearing"\nrange_noise = 25.0\nbearing_noise = 4e-6\n'
        "sensor_position = [0.0, -2000.0]\nclutter_density = 1e-4\n"
    )
    out = tmp_path / "out"
    res = CliRunner().invoke(
        app,
        [
            "run",
            "--no-progress",
            "--detections",
            str(path),
            "--config",
            str(cfg),
            "--out",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    tr = read_tracks(out / "tracks.csv")
    assert len(np.unique(tr["track_id"][tr["time"] == tr["time"].max()])) == 2
    # a sensor whose type does not match its rows: a one-line error naming it
    cfg.write_text(cfg.read_text().replace('type = "range-bearing"', 'type = "position"'))
    res = CliRunner().invoke(
        app,
        [
            "run",
            "--no-progress",
            "--detections",
            str(path),
            "--config",
            str(cfg),
            "--out",
            str(out),
        ],
    )
    assert res.exit_code == 2 and "sensor 2" in res.output and "range-bearing rows" in res.output


def test_sensor_type_must_match_its_rows(tmp_path):
    det = _mixed_detections(n_scans=4)
    tables = {**MIXED_TABLES, 2: {**MIXED_TABLES[2], "type": "position"}}
    with pytest.raises(RunConfigError, match=r"sensor 2: .*range-bearing rows.*type = 'position'"):
        run_detections(det, MIXED_CFG, tmp_path / "a", sensors=tables, plots=False)
    # no table: the [tracker] sensor (position) is used, which cannot read sensor 2's rows
    with pytest.raises(RunConfigError, match=r"sensor 2: .*no \[sensors\] table"):
        run_detections(det, MIXED_CFG, tmp_path / "b", sensors={1: {}}, plots=False)
    # a pure position file with a range-bearing table for its sensor
    pos = _two_sensor_detections(n_scans=3)
    with pytest.raises(RunConfigError, match=r"sensor 2: .*position rows"):
        run_detections(
            pos, CFG, tmp_path / "c", sensors={2: {"type": "range-bearing"}}, plots=False
        )


def _mixed_csv(tmp_path, body, header="time,x,y,range,bearing,sensor"):
    p = tmp_path / "bad.csv"
    p.write_text(header + "\n" + body)
    return p


@pytest.mark.parametrize(
    ("body", "line", "column", "words"),
    [
        ("0,1,2,,,1\n0,3,4,100,0.5,2\n", 3, "range", "both"),
        ("0,1,2,,,1\n0,,,,,2\n", 3, "x", "neither"),
        ("0,1,2,,,1\n0,,5,,,2\n", 3, "x", "empty value"),
        ("0,1,2,,,1\n0,,,100,,2\n", 3, "bearing", "empty value"),
        ("0,1,2,,,1\n1,,,100,0.5,1\n", 3, "range", "sensor 1 gives a range-bearing row"),
        ("0,,,100,0.5,2\n1,3,4,nan,nan,2\n", 3, "x", "sensor 2 gives a position row"),
        ("0,,,-1,0.5,2\n", 2, "range", "negative range"),
        # a sensor id is a label ("x" is one, issue 22); an empty one is missing
        ("0,,,100,0.5,2\n0,1,2,,, \n", 3, "sensor", "empty value"),
    ],
)
def test_bad_mixed_rows(tmp_path, body, line, column, words):
    from jointtrack.io import DetectionFileError, read_detections

    p = _mixed_csv(tmp_path, body)
    with pytest.raises(DetectionFileError) as info:
        read_detections(p)
    e = info.value
    assert (e.line, e.column) == (line, column), str(e)
    assert str(p) in str(e) and f"line {line}" in str(e) and words in str(e)


def test_bad_mixed_rows_in_parquet(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    from jointtrack.io import DetectionFileError, read_detections

    p = tmp_path / "bad.parquet"
    cols = {
        "time": [0.0, 0.0, 1.0],
        "x": [1.0, None, float("nan")],
        "y": [2.0, None, float("nan")],
        "range": [None, 100.0, 5.0],
        "bearing": [None, 0.5, 0.1],
        "sensor": [1, 2, 1],
    }
    pq.write_table(pa.table(cols), p)
    with pytest.raises(DetectionFileError, match=r"data row 3, column 'range'.*sensor 1"):
        read_detections(p)
    cols["sensor"] = [1, 2, 2]
    pq.write_table(pa.table(cols), p)
    d = read_detections(p)  # nulls and NaN both leave a set empty
    assert d.kind == "mixed" and d.sensor_kinds() == {1: "position", 2: "range-bearing"}


def test_mixed_detections_need_consistent_sensors():
    with pytest.raises(ValueError, match="need sensors"):
        Detections(times=[0.0], scans=[[[1.0, 2.0]]], kind="mixed", row_kinds=[[False]])
    with pytest.raises(ValueError, match="sensor 1 has position rows"):
        Detections(
            times=[0.0, 1.0],
            scans=[[[1.0, 2.0]], [[100.0, 0.5]]],
            sensors=[[1], [1]],
            kind="mixed",
            row_kinds=[["position"], ["range-bearing"]],
        )
    with pytest.raises(ValueError, match="row_kinds are for mixed"):
        Detections(times=[0.0], scans=[[[1.0, 2.0]]], row_kinds=[[False]])


# ----------------------------------------------------------------------------- a moving sensor

RANGE_NOISE = 100.0  # σ_r = 10 m
BEARING_NOISE = 1.6e-5  # σ_θ = 4 mrad: r σ_θ ≤ 7.3 m < σ_r at the ranges below (≤ 1.8 km)


def _moving_sensor_detections(n_scans=40, seed=3):
    """One target at (10 t, 0) seen by range-bearing sensor 7 on a platform moving
    from (-1000, -1500) at 40 m/s along x: its position changes every scan."""
    rng = np.random.default_rng(seed)
    times = np.arange(n_scans, dtype=float)
    truth = np.column_stack([10.0 * times, np.zeros(n_scans)])
    where = np.column_stack([-1000.0 + 40.0 * times, np.full(n_scans, -1500.0)])
    noise = rng.normal(0, [np.sqrt(RANGE_NOISE), np.sqrt(BEARING_NOISE)], (n_scans, 2))
    scans = [_polar(truth[k], where[k]) + noise[k] for k in range(n_scans)]
    det = Detections(
        times=times,
        scans=tuple(scans),
        sensors=tuple(np.array([7]) for _ in times),
        kind="range-bearing",
        sensor_positions=tuple(where[k : k + 1] for k in range(n_scans)),
    )
    return det, truth, where


def _rms_after(tracks, truth, times, burn_in=5):
    """RMS distance of the nearest track to the truth over the scans after ``burn_in``."""
    err = []
    for k, t in enumerate(times):
        if k < burn_in:
            continue
        at = tracks["time"] == t
        if not at.any():
            return np.inf  # lost the target
        d = np.hypot(tracks["x"][at] - truth[k, 0], tracks["y"][at] - truth[k, 1])
        err.append(d.min())
    return float(np.sqrt(np.mean(np.square(err))))


RB_CFG = dict(
    sensor="range-bearing",
    range_noise=RANGE_NOISE,
    bearing_noise=BEARING_NOISE,
    clutter_density=1e-4,
    max_speed=30.0,
    process_noise=0.1,
)


def test_moving_range_bearing_sensor(tmp_path):
    from jointtrack.io import read_detections

    det, truth, where = _moving_sensor_detections()
    path = write_detections(det, tmp_path / "moving.csv")
    assert path.read_text().splitlines()[0] == "time,range,bearing,sensor,sensor_x,sensor_y"
    det = read_detections(path)
    np.testing.assert_array_equal(det.sensor_positions[5], where[5:6])
    # no sensor_position in the table: the rows give it; p_d / clutter of the table kept
    tables = {7: {"type": "range-bearing", "p_d": 0.95}}
    run_detections(det, RB_CFG, tmp_path / "out", sensors=tables, plots=True)
    tr = read_tracks(tmp_path / "out" / "tracks.csv")
    # Bound: one detection's position error has std σ_r along the line of sight and
    # r σ_θ ≤ 7.3 m < σ_r across it, i.e. an RMS 2-D error ≤ √2 σ_r ≈ 14 m for a
    # single measurement; the filter averages over scans, so its RMS error is below
    # that. 3 σ_r = 30 m leaves room for the initiation transient and linearisation.
    bound = 3.0 * np.sqrt(RANGE_NOISE)
    assert _rms_after(tr, truth, det.times) < bound
    # the test can fail: the same rows read as if the sensor stayed where it started
    fixed = Detections(times=det.times, scans=det.scans, sensors=det.sensors, kind="range-bearing")
    still = {7: {**tables[7], "sensor_position": where[0].tolist()}}
    run_detections(fixed, RB_CFG, tmp_path / "still", sensors=still, plots=False)
    assert _rms_after(read_tracks(tmp_path / "still" / "tracks.csv"), truth, det.times) > bound


def test_moving_sensor_without_a_sensor_column(tmp_path):
    det, truth, _ = _moving_sensor_detections(n_scans=25)
    det = Detections(
        times=det.times,
        scans=det.scans,
        kind="range-bearing",
        sensor_positions=det.sensor_positions,
    )
    run_detections(det, RB_CFG, tmp_path / "out", plots=False)
    tr = read_tracks(tmp_path / "out" / "tracks.csv")
    assert _rms_after(tr, truth, det.times) < 3.0 * np.sqrt(RANGE_NOISE)


@pytest.mark.parametrize(
    ("body", "line", "column", "words"),
    [
        ("0,100,0.5,7,1,2\n0,200,0.5,7,1,3\n", 3, "sensor_y", "same time"),
        ("0,100,0.5,7,1,2\n1,200,0.5,7,,\n", 3, "sensor_x", "on some rows but not"),
        ("0,100,0.5,7,1,\n", 2, "sensor_y", "empty value"),
    ],
)
def test_bad_sensor_positions(tmp_path, body, line, column, words):
    from jointtrack.io import DetectionFileError, read_detections

    p = _mixed_csv(tmp_path, body, header="time,range,bearing,sensor,sensor_x,sensor_y")
    with pytest.raises(DetectionFileError) as info:
        read_detections(p)
    e = info.value
    assert (e.line, e.column) == (line, column), str(e)
    assert str(p) in str(e) and words in str(e)


def test_position_row_with_a_sensor_position(tmp_path):
    from jointtrack.io import DetectionFileError, read_detections

    p = _mixed_csv(
        tmp_path,
        "0,1,2,,,1,5,5\n",
        header="time,x,y,range,bearing,sensor,sensor_x,sensor_y",
    )
    with pytest.raises(DetectionFileError, match=r"line 2 \(data row 1\), column 'sensor_x'"):
        read_detections(p)
