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
    bad.write_text("[sensors.north]\nmeasurement_noise = 4.0\n")
    with pytest.raises(RunConfigError, match=r"\[sensors.north\].*integer"):
        load_config(bad)
    bad.write_text("[sensors.1]\nnoise = 4.0\n")
    with pytest.raises(RunConfigError, match="unknown key"):
        load_config(bad)
    good = tmp_path / "good.toml"
    good.write_text('[sensors.north]\nid = 3\np_d = 0.8\n[sensors.2]\ntype = "position"\n')
    assert set(load_config(good).sensors) == {3, 2}
