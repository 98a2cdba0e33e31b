"""Issue 32, item 5: every geodetic input gets the same treatment.

A plain ``time, lat, lon`` detection file and a report file (AIS, OpenSky,
traffic) both write lat/lon tracks, ``geo_reference`` and ``map.png`` through one
path (``realdata.geodetic_outputs``), and both centre their frame with one robust
rule (``geodetic.data_centre``): a corrupt report far from the bulk (the Solent AIS
file's one report at 54.8° E among ships near 1° W) is an outlier, left out and
counted, and does not move the centre.
"""

from __future__ import annotations

import json

import numpy as np
import pymap3d
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.io import read_detections
from jointtrack.io.geodetic import (
    OUTLIER_MEDIANS,
    OUTLIER_MIN_DISTANCE,
    LocalFrame,
    data_centre,
)

#: the Solent AIS file's corrupt report (data row 5,843 of Stone Soup's demo CSV)
GLITCH = (50.79, 54.83172)
SETTINGS = settings(max_examples=30, deadline=None)


def _distance(lat0, lon0, lat, lon):
    """Metres along the ground (the local plane's, fine at these distances)."""
    e, n, _ = pymap3d.geodetic2enu(lat, lon, 0.0, lat0, lon0, 0.0)
    return float(np.hypot(e, n))


def _solent(rng, n):
    """``n`` positions in a Solent-like box (50.70–50.90° N, 1.45–0.95° W)."""
    return rng.uniform(50.70, 50.90, n), rng.uniform(-1.45, -0.95, n)


# ----------------------------------------------------------------------------- the centre


@SETTINGS
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(3, 300),
    glitch=st.tuples(st.floats(-80.0, 80.0), st.floats(-180.0, 180.0)),
    where=st.floats(0.0, 1.0),
)
def test_a_far_report_is_an_outlier_and_does_not_move_the_centre(seed, n, glitch, where):
    rng = np.random.default_rng(seed)
    lat, lon = _solent(rng, n)
    i = int(where * n)
    lat, lon = np.insert(lat, i, glitch[0]), np.insert(lon, i, glitch[1])
    c = data_centre(lat, lon)
    # the bulk's median distance from its median point (inside the box) is at most
    # ~40 km, so the bound is the 500 km floor, and the glitch is an outlier iff it is
    # farther than that from the median point: decided here where it is clear from
    # anywhere in the box (its corners and centre; 50 km to spare)
    assert c.bound == OUTLIER_MIN_DISTANCE
    box = [(la, lo) for la in (50.70, 50.80, 50.90) for lo in (-1.45, -1.2, -0.95)]
    d = [_distance(la, lo, *glitch) for la, lo in box]
    bulk = np.delete(np.arange(n + 1), i)
    if min(d) > OUTLIER_MIN_DISTANCE + 50_000:
        assert c.outliers.tolist() == [k == i for k in range(n + 1)] and c.n_outliers == 1
        # the centre is the bulk's, as if the glitch were not there
        assert c.frame == LocalFrame.centre(lat[bulk], lon[bulk])
    elif max(d) < OUTLIER_MIN_DISTANCE - 50_000:
        assert c.n_outliers == 0 and c.frame == LocalFrame.centre(lat, lon)
    # the median point is in the bulk whatever the glitch
    assert 50.69 <= c.median[0] <= 50.91 and -1.46 <= c.median[1] <= -0.94


def test_the_solent_glitch_one_report_at_54_8_east():
    # issue 32: the bounding-box centre was 1,886 km from Solent because of this report
    rng = np.random.default_rng(0)
    lat, lon = _solent(rng, 1000)
    lat, lon = np.r_[lat, GLITCH[0]], np.r_[lon, GLITCH[1]]
    old = LocalFrame.centre(lat, lon).reference
    assert _distance(50.8, -1.2, old[0], old[1]) > 1_800_000
    c = data_centre(lat, lon)
    lat0, lon0, alt0 = c.frame.reference
    assert _distance(50.8, -1.2, lat0, lon0) < 3_000 and alt0 == 0.0
    assert c.outliers.tolist() == [False] * 1000 + [True]
    assert _distance(*c.median, 50.8, -1.2) < 5_000


def test_data_spread_too_widely_has_no_outliers():
    # half the reports on each side of the Pacific: no area with strays, nothing left out
    c = data_centre([0.0, 0.0, 0.0, 0.0], [-100.0, -99.0, 99.0, 100.0])
    assert c.bound is None and c.n_outliers == 0
    # a wide but representable area: the bound is 10 × the median distance
    rng = np.random.default_rng(1)
    lat, lon = rng.uniform(40, 50, 400), rng.uniform(0, 20, 400)
    c = data_centre(lat, lon)
    d = np.median(LocalFrame(*c.median).plane_angle(lat, lon))
    assert c.bound == pytest.approx(OUTLIER_MEDIANS * np.deg2rad(d) * 6_371_008.8)
    assert c.n_outliers == 0 and c.frame == LocalFrame.centre(lat, lon)


@pytest.mark.parametrize(
    "lat, lon, exc, needle",
    [
        ([], [], ValueError, "empty"),
        ([50.0, 51.0], [1.0], ValueError, "one shape"),
        ([91.0], [0.0], ValueError, "lat"),
        ([50.0], [1j], TypeError, "lon"),
        ([True], [0.0], TypeError, "lat"),
        ([np.nan], [0.0], ValueError, "lat"),
    ],
)
def test_data_centre_refuses_bad_input(lat, lon, exc, needle):
    with pytest.raises(exc, match=needle):
        data_centre(lat, lon)


# ----------------------------------------------------------------------------- files


def _plain_file(path, rng, n=120, glitch_row=40):
    """A plain ``time, lat, lon`` file of ``n`` reports at irregular times, one per time,
    the ``glitch_row``-th (0-based) at :data:`GLITCH`."""
    lat, lon = _solent(rng, n)
    lat[glitch_row], lon[glitch_row] = GLITCH
    t = np.cumsum(rng.exponential(2.0, n))
    with open(path, "w") as fh:
        fh.write("time,lat,lon\n")
        for k in range(n):
            fh.write(f"{float(t[k])!r},{float(lat[k])!r},{float(lon[k])!r}\n")
    return t, lat, lon


def test_a_plain_file_leaves_the_outlier_out_and_counts_it(tmp_path):
    rng = np.random.default_rng(2)
    t, lat, lon = _plain_file(tmp_path / "p.csv", rng)
    d = read_detections(tmp_path / "p.csv")
    bulk = np.delete(np.arange(t.size), 40)
    assert d.geo_outliers == 1 and d.geo_outlier_bound == OUTLIER_MIN_DISTANCE
    assert d.geo_reference == LocalFrame.centre(lat[bulk], lon[bulk]).reference
    # its time alone made a scan: it is gone with the row
    assert d.times.tolist() == t[bulk].tolist() and d.n_detections == t.size - 1
    want = LocalFrame(*d.geo_reference).to_local(lat[bulk], lon[bulk])
    assert np.array_equal(np.concatenate(d.scans), want)
    # a given reference keeps every row
    g = read_detections(tmp_path / "p.csv", reference=(50.8, -1.2))
    assert g.geo_outliers == 0 and g.geo_outlier_bound is None and g.n_detections == t.size


def test_detections_check_the_outlier_fields():
    from jointtrack.io import Detections

    base = dict(times=[0.0], scans=[np.zeros((1, 2))])
    with pytest.raises(ValueError, match="geo_reference"):
        Detections(**base, geo_outliers=1, geo_outlier_bound=5e5)
    for bad, exc in ((True, TypeError), (-1, ValueError), (1.5, TypeError)):
        with pytest.raises(exc, match="geo_outliers"):
            Detections(**base, geo_reference=(50.0, 0.0), geo_outliers=bad)
    for bad, exc in ((0.0, ValueError), (np.inf, ValueError), ("5", TypeError)):
        with pytest.raises(exc, match="geo_outlier_bound"):
            Detections(**base, geo_reference=(50.0, 0.0), geo_outlier_bound=bad)
    with pytest.raises(ValueError, match="geo_outlier_bound"):
        Detections(**base, geo_reference=(50.0, 0.0), geo_outliers=2)


def _read_tracks(path):
    import csv

    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    return rows


def _run_geodetic_outputs(out, m, ref):
    """What a geodetic run writes: lat/lon tracks that are the frame's x, y, the
    reference with its outliers in metrics.json, and a map."""
    assert (out / "map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = _read_tracks(out / "tracks.csv")
    assert rows and list(rows[0])[:6] == ["time", "track_id", "x", "y", "lat", "lon"]
    frame = LocalFrame(*ref)
    xy = np.array([[float(r["x"]), float(r["y"])] for r in rows])
    got = np.array([[float(r["lat"]), float(r["lon"])] for r in rows])
    assert np.allclose(frame.to_local(got[:, 0], got[:, 1]), xy, atol=1e-6, rtol=0)
    assert m["files"]["map"].endswith("map.png")


def test_a_plain_lat_lon_file_gets_what_a_report_file_gets(tmp_path):
    from jointtrack.experiments.run import run_detections

    rng = np.random.default_rng(3)
    # a scanning sensor: two ships 3 km apart every 5 s, and the glitch
    n = 60
    t = 5.0 * (np.arange(n) // 2)
    ship = np.arange(n) % 2
    frame = LocalFrame(50.8, -1.2)
    xy = np.column_stack([3000.0 * ship + 2.0 * t, 500.0 * ship]) + rng.normal(0, 5, (n, 2))
    lat, lon = frame.to_geodetic(xy)
    lat[27], lon[27] = GLITCH
    with open(tmp_path / "p.csv", "w") as fh:
        fh.write("time,lat,lon\n")
        for k in range(n):
            fh.write(f"{float(t[k])!r},{float(lat[k])!r},{float(lon[k])!r}\n")
    d = read_detections(tmp_path / "p.csv")
    out = tmp_path / "o"
    m = run_detections(d, {"clutter_density": 1e-9}, out)
    on_disk = json.loads((out / "metrics.json").read_text())
    geo = on_disk["geo_reference"]
    assert [geo["lat"], geo["lon"], geo["alt"]] == list(d.geo_reference)
    assert geo["outliers_excluded"] == 1 and geo["outlier_bound_m"] == OUTLIER_MIN_DISTANCE
    assert any("1 rows left out as outliers" in note for note in on_disk["notes"])
    assert m["tracks"]["n_tracks"] >= 2
    _run_geodetic_outputs(out, on_disk, d.geo_reference)


def test_a_report_file_leaves_the_outlier_out_of_tracking_and_scoring(tmp_path):
    from jointtrack.experiments.realdata import run_reports
    from test_run_realdata import write_ais

    rows = write_ais(tmp_path / "ais.csv")
    # one corrupt longitude: the Solent glitch
    text = (tmp_path / "ais.csv").read_text().splitlines()
    cells = text[30].split(",")
    cells[3] = repr(GLITCH[1])
    text[30] = ",".join(cells)
    (tmp_path / "ais.csv").write_text("\n".join(text) + "\n")
    out = tmp_path / "o"
    m = run_reports(tmp_path / "ais.csv", out_dir=out)
    geo = m["geo_reference"]
    lat = np.array([float(r[2]) for r in rows])
    lon = np.array([float(r[3]) for r in rows])
    keep = np.ones(lat.size, bool)
    keep[29] = False
    want = LocalFrame.centre(lat[keep], lon[keep]).reference
    assert (geo["lat"], geo["lon"]) == pytest.approx(want[:2], abs=1e-12)
    assert geo["outliers_excluded"] == 1
    assert m["n_detections"] == len(rows) - 1
    # the corrupt report is not one of its ship's positions when scoring
    assert m["self_reports"]["coverage"] >= 0.99
    _run_geodetic_outputs(out, m, (geo["lat"], geo["lon"], geo["alt"]))


# ----------------------------------------------------------------------------- reporting


def _dets(times, per_time):
    from jointtrack.io import Detections

    return Detections(times=times, scans=[np.zeros((per_time, 2)) + k for k in range(len(times))])


def test_report_like_detections_get_the_async_model_and_say_why():
    from jointtrack.experiments.run import REPORT_LIKE_SETTINGS, reporting_from_data
    from jointtrack.trackers.config import TrackerConfig

    rng = np.random.default_rng(4)
    irregular = np.cumsum(rng.exponential(0.3, 200))  # Poisson reporters: gap CV ≈ 1
    table, note = reporting_from_data(_dets(irregular, 1), {})
    assert table == REPORT_LIKE_SETTINGS and "from the data" in note
    assert "1.00 returns per time" in note and "report_interval 60 s" in note
    TrackerConfig(**table)  # a valid configuration
    # the user's keys win, and a table that sets reporting is left alone
    table, _ = reporting_from_data(_dets(irregular, 1), {"clutter_density": 1e-9})
    assert table["clutter_density"] == 1e-9 and table["reporting"] == "async"
    assert reporting_from_data(_dets(irregular, 1), {"reporting": "scan"}) == (
        {"reporting": "scan"},
        None,
    )
    # M-of-N JPDA has no existence to decay; PMB and PMBM take it as JIPDA does (issue 32)
    assert reporting_from_data(_dets(irregular, 1), {}, "jpda") == ({}, None)
    for kind in ("pmb", "pmbm"):
        assert reporting_from_data(_dets(irregular, 1), {}, kind)[0]["reporting"] == "async"
    # a scanning sensor: a fixed period, or several returns per time
    assert reporting_from_data(_dets(np.arange(200.0), 1), {}) == ({}, None)
    assert reporting_from_data(_dets(irregular, 3), {}) == ({}, None)
    assert reporting_from_data(_dets(irregular[:10], 1), {}) == ({}, None)  # too few


def test_a_run_that_confirms_nothing_says_so_with_the_likely_reason():
    from jointtrack.experiments.summary import no_tracks_reason

    m = {"n_scans": 100, "n_detections": 117, "tracker": {"kind": "jipda", "reporting": "scan"}}
    assert 'reporting = "async"' in no_tracks_reason(m)
    m["tracker"]["reporting"] = "async"
    m["tracker"]["measurement_noise"] = 100.0
    text = no_tracks_reason(m)
    assert text.startswith("no track was confirmed") and "measurement_noise (100.0)" in text
    assert "no detections" in no_tracks_reason({"n_scans": 3, "n_detections": 0})
