"""LocalFrame and velocity_en against pymap3d itself, and their input checks."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.io.geodetic import FOOT, KNOT, LocalFrame, velocity_en

lat0s = st.floats(-89.0, 89.0)
lon0s = st.floats(-180.0, 360.0)
alts = st.floats(-500.0, 12_000.0)
offsets = st.lists(st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)), min_size=1, max_size=8)


def _points(lat0, lon0, offs):
    lat = np.clip(lat0 + np.array([a for a, _ in offs]), -90, 90)
    lon = lon0 + np.array([b for _, b in offs])
    lon = np.where(lon > 360, lon - 360, np.where(lon < -180, lon + 360, lon))
    return lat, lon


def test_units_are_exact_definitions():
    assert KNOT == 1852 / 3600 and FOOT == 0.3048


@settings(max_examples=150, deadline=None)
@given(lat0=lat0s, lon0=lon0s, alt0=alts, offs=offsets)
def test_2d_projection_is_pymap3d_enu_at_the_reference_height(lat0, lon0, alt0, offs):
    lat, lon = _points(lat0, lon0, offs)
    f = LocalFrame(lat0, lon0, alt0)
    xy = f.to_local(lat, lon)
    e, n, _ = pymap3d.geodetic2enu(lat, lon, np.full(lat.shape, alt0), lat0, lon0, alt0)
    assert xy.shape == (lat.size, 2)
    assert np.array_equal(xy[:, 0], e) and np.array_equal(xy[:, 1], n)
    # inverse: the point at height alt0 with these east/north coordinates
    la, lo = f.to_geodetic(xy)
    assert np.allclose(la, lat, rtol=0, atol=1e-9)
    dlon = np.mod(lo - lon + 180.0, 360.0) - 180.0
    assert np.all(np.abs(dlon) * np.cos(np.deg2rad(lat)) < 1e-9)
    assert np.allclose(f.to_local(la, lo), xy, rtol=0, atol=1e-6)


@settings(max_examples=150, deadline=None)
@given(lat0=lat0s, lon0=lon0s, alt0=alts, offs=offsets, alt=alts)
def test_3d_round_trip_against_pymap3d(lat0, lon0, alt0, offs, alt):
    lat, lon = _points(lat0, lon0, offs)
    h = np.full(lat.shape, alt)
    f = LocalFrame(lat0, lon0, alt0)
    enu = f.to_local(lat, lon, h)
    want = np.column_stack(pymap3d.geodetic2enu(lat, lon, h, lat0, lon0, alt0))
    assert np.array_equal(enu, want)
    la, lo, hh = f.to_geodetic(enu)
    assert np.allclose(la, lat, rtol=0, atol=1e-9) and np.allclose(hh, h, rtol=0, atol=1e-6)
    dlon = np.mod(lo - lon + 180.0, 360.0) - 180.0
    assert np.all(np.abs(dlon) * np.cos(np.deg2rad(lat)) < 1e-9)
    assert np.allclose(f.to_local(la, lo, hh), enu, rtol=0, atol=1e-6)


def test_known_distance_north():
    # one minute of latitude at 45° is 1852.2 m on WGS-84 (a nautical mile, nearly)
    f = LocalFrame(45.0 - 1 / 120, 7.0)
    xy = f.to_local([45.0 - 1 / 120, 45.0 + 1 / 120], [7.0, 7.0])
    assert xy[0].tolist() == [0.0, 0.0]
    assert abs(xy[1, 1] - 1852.25) < 0.5 and abs(xy[1, 0]) < 1e-6


@settings(max_examples=100, deadline=None)
@given(
    lat=st.lists(st.floats(-80, 80), min_size=1, max_size=6),
    lon=st.lists(st.floats(-180, 360), min_size=1, max_size=6),
)
def test_centre_is_the_middle_of_the_narrower_box(lat, lon):
    n = min(len(lat), len(lon))
    lat, lon = np.array(lat[:n]), np.array(lon[:n])
    c = LocalFrame.centre(lat, lon)
    assert c.reference[0] == 0.5 * (lat.min() + lat.max()) and c.reference[2] == 0.0
    assert -180.0 <= c.reference[1] < 180.0
    # every point is within half the box's width of the centre, the box is the narrowest
    # of the two representations, so the largest distance is at most 180°
    d = np.abs(np.mod(lon - c.reference[1] + 180.0, 360.0) - 180.0)
    west = np.mod(lon + 180, 360) - 180
    east = np.mod(lon, 360)
    width = min(np.ptp(west), np.ptp(east))
    assert np.all(d <= width / 2 + 1e-9)


def test_centre_across_the_antimeridian():
    assert LocalFrame.centre([0.0, 2.0], [179.0, -179.0]).reference == (1.0, -180.0, 0.0)
    assert LocalFrame.centre([0.0, 2.0], [10.0, 350.0]).reference == (1.0, 0.0, 0.0)
    assert LocalFrame.centre([0.0, 2.0], [-10.0, 20.0]).reference == (1.0, 5.0, 0.0)
    with pytest.raises(ValueError, match="empty"):
        LocalFrame.centre([], [])


@pytest.mark.parametrize(
    ("args", "exc", "words"),
    [
        ((True, 0.0), TypeError, "lat0"),
        ((0.0, 1j), TypeError, "lon0"),
        (("50", 0.0), TypeError, "lat0"),
        ((0.0, 0.0, np.float64("nan")), ValueError, "alt0"),
        ((90.5, 0.0), ValueError, "lat0"),
        ((0.0, -181.0), ValueError, "lon0"),
        ((0.0, 361.0), ValueError, "lon0"),
        ((10**400, 0.0), ValueError, "lat0"),
        (([1.0, 2.0], 0.0), ValueError, "lat0"),
        ((0.0, float("inf")), ValueError, "lon0"),
    ],
)
def test_frame_refuses_bad_references(args, exc, words):
    with pytest.raises(exc, match=words):
        LocalFrame(*args)


@pytest.mark.parametrize(
    ("call", "exc", "words"),
    [
        (lambda f: f.to_local([True], [0.0]), TypeError, "lat"),
        (lambda f: f.to_local([0.0], [1j]), TypeError, "lon"),
        (lambda f: f.to_local(["a"], [0.0]), TypeError, "lat"),
        (lambda f: f.to_local([91.0], [0.0]), ValueError, "lat"),
        (lambda f: f.to_local([0.0, 1.0], [0.0]), ValueError, "shape"),
        (lambda f: f.to_local([0.0], [0.0], [np.nan]), ValueError, "alt"),
        (lambda f: f.to_geodetic(np.zeros((2, 4))), ValueError, "xy"),
        (lambda f: f.to_geodetic([[np.inf, 0.0]]), ValueError, "xy"),
    ],
)
def test_conversions_refuse_bad_input(call, exc, words):
    with pytest.raises(exc, match=words):
        call(LocalFrame(0.0, 0.0))


def test_empty_input():
    f = LocalFrame(0.0, 0.0)
    assert f.to_local([], []).shape == (0, 2) and f.to_local([], [], []).shape == (0, 3)
    assert [a.size for a in f.to_geodetic(np.zeros((0, 2)))] == [0, 0]


@settings(max_examples=100, deadline=None)
@given(
    speed=st.lists(st.floats(0, 1000) | st.just(float("nan")), min_size=1, max_size=5),
    course=st.floats(-720, 720) | st.just(float("nan")),
)
def test_velocity_en(speed, course):
    v = velocity_en(speed, [course] * len(speed))
    for (e, n), s in zip(v.tolist(), speed, strict=True):
        if np.isnan(s) or np.isnan(course):
            assert np.isnan(e) and np.isnan(n)
        else:
            assert abs(np.hypot(e, n) - s) <= 1e-9 * max(s, 1)
            # clockwise from north: 90° is east
            assert abs(e - s * np.sin(np.deg2rad(course))) <= 1e-12 * max(s, 1)
            assert abs(n - s * np.cos(np.deg2rad(course))) <= 1e-12 * max(s, 1)
    assert np.allclose(velocity_en([2.0], [90.0]), [[2.0, 0.0]], atol=1e-15)


@pytest.mark.parametrize(
    ("args", "exc", "words"),
    [
        (([-1.0], [0.0]), ValueError, "speed_mps"),
        (([True], [0.0]), TypeError, "speed_mps"),
        (([1.0], [1j]), TypeError, "course_deg"),
        (([1.0], [np.inf]), ValueError, "course_deg"),
        (([1.0, 2.0], [0.0]), ValueError, "shape"),
    ],
)
def test_velocity_en_refuses_bad_input(args, exc, words):
    with pytest.raises(exc, match=words):
        velocity_en(*args)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
@pytest.mark.parametrize("dim", [2, 3])
def test_tracks_written_with_a_frame_carry_lat_lon(tmp_path, suffix, dim):
    from jointtrack.io import read_tracks, write_tracks

    rng = np.random.default_rng(dim)
    n = 6
    table = {
        "time": np.arange(n, dtype=float),
        "track_id": np.repeat([3, 7], n // 2),
        "x": rng.normal(0, 5e4, n),
        "y": rng.normal(0, 5e4, n),
        "vx": rng.normal(0, 10, n),
        "vy": rng.normal(0, 10, n),
        "existence": rng.uniform(0, 1, n),
    }
    names = ["time", "track_id", "x", "y", "lat", "lon", "vx", "vy", "existence"]
    if dim == 3:
        table.update(z=rng.normal(1e4, 100, n), vz=rng.normal(0, 1, n))
        names = ["time", "track_id", "x", "y", "z", "lat", "lon", "alt", "vx", "vy", "vz"]
        names.append("existence")
    frame = LocalFrame(50.7, -1.1, 12.0)
    p = write_tracks(table, tmp_path / f"t{suffix}", frame=frame)
    got = read_tracks(p)
    assert sorted(got) == sorted(names)
    if suffix == ".csv":
        assert p.read_text().splitlines()[0].split(",") == names
    local = np.column_stack([table[c] for c in ("x", "y", "z")[:dim]])
    geo = frame.to_geodetic(local)
    for name, v in zip(("lat", "lon", "alt"), geo, strict=False):
        assert np.array_equal(got[name], v)
    back = frame.to_local(got["lat"], got["lon"], got["alt"] if dim == 3 else None)
    assert np.allclose(back, local, rtol=0, atol=1e-6)
    for c, v in table.items():
        assert np.array_equal(got[c], v)
    # a tuple reference works the same; a clash or a bad frame is refused
    q = write_tracks(table, tmp_path / f"u{suffix}", frame=(50.7, -1.1, 12.0))
    assert np.array_equal(read_tracks(q)["lat"], got["lat"])
    with pytest.raises(ValueError, match="already has"):
        write_tracks({**table, "lat": np.zeros(n)}, tmp_path / "v.csv", frame=frame)
    with pytest.raises(TypeError, match="frame"):
        write_tracks(table, tmp_path / "w.csv", frame=(True, 0.0))
    with pytest.raises(ValueError, match="frame"):
        write_tracks(table, tmp_path / "w.csv", frame="50,1")
