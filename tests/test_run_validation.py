"""Validation of tracker settings: TrackerConfig and the ``[tracker]`` TOML table."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jointtrack.experiments.config import (
    RunConfigError,
    load_config,
    make_tracker_config,
    steady_state_covariance,
)
from jointtrack.models import LinearPosition
from jointtrack.trackers import JPDATracker, TrackerConfig

NAN = float("nan")

# (settings, field the message must name)
BAD = [
    ({"dim": 4}, "dim"),
    ({"dim": 2.0}, "dim"),
    ({"dim": "2"}, "dim"),
    ({"dim": True}, "dim"),
    ({"motion": "cc"}, "motion"),
    ({"motion": 3}, "motion"),
    ({"process_noise": "1.0"}, "process_noise"),
    ({"process_noise": True}, "process_noise"),
    ({"process_noise": NAN}, "process_noise"),
    ({"process_noise": -1.0}, "process_noise"),
    ({"process_noise": [1.0]}, "process_noise"),
    ({"measurement_noise": "100"}, "measurement_noise"),
    ({"measurement_noise": True}, "measurement_noise"),
    ({"measurement_noise": NAN}, "measurement_noise"),
    ({"measurement_noise": 0.0}, "measurement_noise"),
    ({"measurement_noise": math.inf}, "measurement_noise"),
    ({"measurement_noise": [25.0, 100.0, 4.0]}, "measurement_noise"),  # length ≠ dim
    ({"measurement_noise": [25.0, -1.0]}, "measurement_noise"),
    ({"measurement_noise": [25.0, NAN]}, "measurement_noise"),
    ({"measurement_noise": [25.0, "a"]}, "measurement_noise"),
    ({"measurement_noise": []}, "measurement_noise"),
    ({"measurement_noise": [[1.0, 2.0], [2.0, 1.0]]}, "measurement_noise"),  # not PD
    ({"measurement_noise": [[1.0, 0.5], [0.0, 1.0]]}, "measurement_noise"),  # asymmetric
    ({"measurement_noise": [[1.0, 0.0]]}, "measurement_noise"),  # not square
    ({"measurement_noise": [[1.0, 0.0, 0.0]] * 3}, "measurement_noise"),  # 3×3 for dim 2
    ({"sensor": "sonar"}, "sensor"),
    ({"sensor": "range-bearing", "dim": 3}, "sensor"),
    ({"sensor_position": 3}, "sensor_position"),
    ({"sensor_position": [1.0]}, "sensor_position"),
    ({"sensor_position": "ab"}, "sensor_position"),
    ({"sensor_position": [0.0, NAN]}, "sensor_position"),
    ({"sensor_position": [True, 0.0]}, "sensor_position"),
    ({"range_noise": 0}, "range_noise"),
    ({"bearing_noise": "1e-4"}, "bearing_noise"),
    ({"p_d": 0.0}, "p_d"),
    ({"p_d": 1.5}, "p_d"),
    ({"p_d": NAN}, "p_d"),
    ({"p_d": True}, "p_d"),
    ({"p_d": "high"}, "p_d"),
    ({"p_d": [0.9]}, "p_d"),
    ({"p_g": 0.0}, "p_g"),
    ({"p_g": 1.01}, "p_g"),
    ({"p_g": NAN}, "p_g"),
    ({"clutter_density": -1.0}, "clutter_density"),
    ({"clutter_density": NAN}, "clutter_density"),
    ({"clutter_density": "lots"}, "clutter_density"),
    ({"association": "magic"}, "association"),
    ({"exact_max_tracks": 0}, "exact_max_tracks"),
    ({"exact_max_tracks": 2.5}, "exact_max_tracks"),
    ({"approximation": "exact"}, "approximation"),
    ({"initiation": "three-point"}, "initiation"),
    ({"max_speed": 0.0}, "max_speed"),
    ({"max_speed": NAN}, "max_speed"),
    ({"max_acceleration": "10"}, "max_acceleration"),
    ({"confirm_m": 0}, "confirm_m"),
    ({"confirm_m": 2.0}, "confirm_m"),
    ({"confirm_m": "2"}, "confirm_m"),
    ({"confirm_n": 31}, "confirm_n"),
    ({"confirm_m": 4, "confirm_n": 3}, "confirm_m"),
    ({"delete_misses": 0}, "delete_misses"),
    ({"delete_misses": True}, "delete_misses"),
    ({"max_position_std": 0.0}, "max_position_std"),
    ({"max_position_std": NAN}, "max_position_std"),
    ({"existence": 1}, "existence"),
    ({"existence": "yes"}, "existence"),
    ({"p_survive": 0.0}, "p_survive"),
    ({"r_init": 0.95}, "r_init"),  # > r_confirm = 0.9
    ({"r_init": 0.5, "r_confirm": 0.4}, "r_init"),
    ({"r_delete": 0.05}, "r_delete"),  # = r_init
    ({"r_delete": 0.1, "r_init": 0.05}, "r_delete"),
    ({"r_init": NAN}, "r_init"),
    ({"r_confirm": 1.5}, "r_confirm"),
    ({"r_delete": 0.0}, "r_delete"),
    ({"seed": 1.5}, "seed"),
    ({"seed": -1}, "seed"),
    ({"seed": "0"}, "seed"),
    ({"miss_model": "1-pg"}, "miss_model"),
]


@pytest.mark.parametrize(("settings", "field"), BAD, ids=lambda v: repr(v)[:40])
def test_bad_config_names_the_field(settings, field):
    with pytest.raises(ValueError) as info:
        TrackerConfig(**settings)
    assert field in str(info.value)
    assert "\n" not in str(info.value)
    # through make_tracker_config (as `jointtrack run` builds it): a RunConfigError
    with pytest.raises(RunConfigError) as info:
        make_tracker_config(None, settings)
    assert field in str(info.value)


_TOML = {
    bool: lambda v: "true" if v else "false",
    str: lambda v: f'"{v}"',
}


def _toml_value(v):
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, float) and math.isnan(v):
        return "nan"
    if isinstance(v, float) and math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return _TOML.get(type(v), repr)(v)


@pytest.mark.parametrize(("settings", "field"), BAD, ids=lambda v: repr(v)[:40])
def test_bad_toml_tracker_table_names_the_field(tmp_path, settings, field):
    p = tmp_path / "bad.toml"
    p.write_text(
        "[tracker]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in settings.items()),
        encoding="utf-8",
    )
    with pytest.raises(RunConfigError) as info:
        cfg = load_config(p)  # checks each key on its own ...
        make_tracker_config(None, cfg.tracker, source=cfg.source)  # ... then the whole
    msg = str(info.value)
    assert field in msg and str(p) in msg and "\n" not in msg


def test_toml_type_error_message_names_key_and_value(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text('[tracker]\nprocess_noise = "1.0"\n', encoding="utf-8")
    with pytest.raises(RunConfigError) as info:
        load_config(p)
    assert "[tracker] key 'process_noise' must be a positive finite number, got '1.0'" in str(
        info.value
    )


def test_r_init_above_r_confirm_is_rejected():
    """Was accepted: every new track started confirmed (10 tracks for 2 targets)."""
    with pytest.raises(ValueError, match=r"r_init must be ≤ r_confirm"):
        TrackerConfig(r_init=0.95, r_confirm=0.9)
    TrackerConfig(r_init=0.5, r_confirm=0.5)  # equal is allowed


def test_good_edge_values():
    TrackerConfig(p_d=1.0, p_survive=1.0, r_confirm=1.0, confirm_m=3, confirm_n=3)
    TrackerConfig(clutter_density=None, seed=None, max_position_std=math.inf)
    cfg = TrackerConfig(dim=np.int64(3), process_noise=np.float32(2.0), existence=np.bool_(False))
    assert type(cfg.dim) is int and type(cfg.process_noise) is float
    assert type(cfg.existence) is bool


def test_p_g_one_is_an_infinite_gate_setting():
    cfg = TrackerConfig(p_g=1.0, clutter_density=1e-4)
    assert cfg.p_g == 1.0
    assert cfg.detection_in_gate() == pytest.approx(cfg.p_d)
    assert make_tracker_config(None, {"p_g": 1, "clutter_density": 1e-4}).p_g == 1.0
    with pytest.raises(ValueError, match="p_g = 1 .* clutter_density"):
        TrackerConfig(p_g=1.0)


def test_p_g_one_tracks():
    trk = JPDATracker(TrackerConfig(p_g=1.0, clutter_density=1e-4))
    trk.step(0.0, np.array([[0.0, 0.0], [100.0, 0.0]]))
    trk.step(1.0, np.array([[1.0, 0.0], [101.0, 0.0]]))
    assert len(trk.ids) > 0  # tracks exist, so the next scan is gated
    r = trk.step(2.0, np.array([[2.0, 0.0], [102.0, 0.0], [1e6, -1e6]]))
    assert r.n_unassociated == 0  # an infinite gate takes every return


GOOD_NOISE = [
    (2, 100.0, np.diag([100.0, 100.0])),
    (2, [25, 100], np.diag([25.0, 100.0])),
    (2, (25.0, 100.0), np.diag([25.0, 100.0])),
    (2, np.array([25.0, 100.0]), np.diag([25.0, 100.0])),
    (2, [[25.0, 10.0], [10.0, 100.0]], np.array([[25.0, 10.0], [10.0, 100.0]])),
    (3, [1.0, 4.0, 9.0], np.diag([1.0, 4.0, 9.0])),
    (3, np.diag([1.0, 4.0, 9.0]), np.diag([1.0, 4.0, 9.0])),
]


@pytest.mark.parametrize(("dim", "noise", "R"), GOOD_NOISE, ids=lambda v: repr(v)[:30])
def test_per_axis_measurement_noise_builds_a_tracker(dim, noise, R):
    cfg = TrackerConfig(dim=dim, measurement_noise=noise, clutter_density=1e-4)
    assert isinstance(cfg.measurement_noise, float | tuple)
    hash(cfg)  # stays hashable
    assert np.array_equal(cfg.measurement_covariance(), R)
    assert TrackerConfig.from_dict(cfg.to_dict()) == cfg
    trk = JPDATracker(cfg)
    assert isinstance(trk._sensor, LinearPosition)
    assert np.allclose(trk._sensor.R, R)
    z = np.array([[0.0] * dim, [500.0] * dim])
    trk.step(0.0, z)
    trk.step(1.0, z + 1.0)
    assert trk.n_scans == 2


def test_per_axis_noise_from_toml(tmp_path):
    p = tmp_path / "run.toml"
    p.write_text(
        "[tracker]\nmeasurement_noise = [25, 100]\nclutter_density = 1e-4\n", encoding="utf-8"
    )
    cfg = load_config(p)
    tc = make_tracker_config({"dim": 2}, cfg.tracker, source=cfg.source)
    assert tc.measurement_noise == (25.0, 100.0)
    p.write_text("[tracker]\nmeasurement_noise = [[25, 5], [5, 100]]\n", encoding="utf-8")
    tc = make_tracker_config({"dim": 2}, load_config(p).tracker)
    assert tc.measurement_noise == ((25.0, 5.0), (5.0, 100.0))


def test_steady_state_covariance_per_axis():
    P = steady_state_covariance(1.0, 1.0, [25.0, 100.0], dim=2)
    Px = steady_state_covariance(1.0, 1.0, 25.0, dim=2)
    Py = steady_state_covariance(1.0, 1.0, 100.0, dim=2)
    assert P[0, 0] == pytest.approx(Px[0, 0]) and P[1, 1] == pytest.approx(Py[1, 1])
    assert P[0, 0] < P[1, 1]
