"""plot_track_map: the PNG, what the figure holds (labels, one line per track drawn,
aspect, arrows along each track's last leg, legend below the map), no warnings,
and bad input."""

from __future__ import annotations

import math
import warnings

import matplotlib.pyplot as plt
import numpy as np
import pytest

from jointtrack.experiments.map_plot import plot_track_map

LAT0, LON0 = 50.78, -1.1


def _scene(n_tracks=4, points=6):
    """Reports of three ships and ``n_tracks`` tracks heading north-east, the last
    one with only two points (skipped at ``min_points = 3``)."""
    rng = np.random.default_rng(7)
    rlat = LAT0 + rng.uniform(-0.02, 0.02, 60)
    rlon = LON0 + rng.uniform(-0.03, 0.03, 60)
    rid = np.repeat(["235000001", "235000002", "235000003"], 20)
    tlat, tlon, tid = [], [], []
    for k in range(n_tracks):
        n = points if k < n_tracks - 1 else 2
        s = np.arange(n) * 1e-3
        tlat.append(LAT0 + 0.004 * k + s)
        tlon.append(LON0 + 0.002 * k + s)
        tid.append(np.full(n, 10 + k))
    return rlat, rlon, np.concatenate(tlat), np.concatenate(tlon), np.concatenate(tid), rid


def test_png_and_what_it_shows(tmp_path):
    rlat, rlon, tlat, tlon, tid, rid = _scene()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m = plot_track_map(
            tmp_path / "maps" / "map.png",
            rlat,
            rlon,
            tlat,
            tlon,
            tid,
            title="four tracks",
            report_ids=rid,
            keep_figure=True,
        )
    assert not caught, [str(w.message) for w in caught]
    try:
        assert m.path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        ax = m.figure.axes[0]
        assert ax.get_xlabel() == "longitude (°E)" == m.xlabel
        assert ax.get_ylabel() == "latitude (°N)" == m.ylabel
        assert ax.get_title() == "four tracks"
        # three tracks of 6 points drawn, the 2-point one skipped
        assert len(ax.lines) == 3 == m.n_track_lines and m.n_tracks_skipped == 1
        assert m.n_reports == 60 and m.n_identities == 3
        lat_mid = 0.5 * sum(ax.get_ylim())
        assert ax.get_aspect() == pytest.approx(1 / math.cos(math.radians(lat_mid)), rel=1e-12)
        # one arrow per drawn track, from its last leg's start to its last point
        arrows = [c for c in ax.get_children() if type(c).__name__ == "Annotation"]
        ends = sorted((a.xy, a.xyann) for a in arrows)
        want = sorted(
            ((tlon[tid == k][-1], tlat[tid == k][-1]), (tlon[tid == k][-2], tlat[tid == k][-2]))
            for k in (10, 11, 12)
        )
        np.testing.assert_allclose(np.array(ends, dtype=float), np.array(want), rtol=0, atol=0)
        # the legend explains the four marks and sits below the map
        (legend,) = m.figure.legends
        texts = [t.get_text() for t in legend.get_texts()]
        assert texts[0].startswith("self-reports (60 from 3 identities)") and len(texts) == 4
        m.figure.canvas.draw()
        r = m.figure.canvas.get_renderer()
        assert legend.get_window_extent(r).y1 < ax.get_window_extent(r).y0
    finally:
        plt.close(m.figure)


def test_track_times_order_the_points(tmp_path):
    # rows shuffled: with track_times each track is joined in time order and its
    # arrow points at its latest point
    t = np.arange(5.0)
    lat, lon = LAT0 + 1e-3 * t, LON0 + 2e-3 * t
    perm = np.array([3, 0, 4, 1, 2])
    m = plot_track_map(
        tmp_path / "m.png",
        [],
        [],
        lat[perm],
        lon[perm],
        np.full(5, 1),
        title="t",
        track_times=t[perm],
        keep_figure=True,
    )
    try:
        ax = m.figure.axes[0]
        np.testing.assert_array_equal(ax.lines[0].get_xdata(), lon)
        (arrow,) = [c for c in ax.get_children() if type(c).__name__ == "Annotation"]
        assert arrow.xy == (lon[-1], lat[-1]) and arrow.xyann == (lon[-2], lat[-2])
    finally:
        plt.close(m.figure)


def test_garbage_position_is_left_out_of_view(tmp_path):
    # one report at 54.8° E among ships near 1.1° W (as in the Solent AIS file):
    # the view holds the ships, the stray point is counted and named in the legend
    rlat, rlon, tlat, tlon, tid, rid = _scene()
    rlon = rlon.copy()
    rlon[5] = 54.83
    m = plot_track_map(tmp_path / "o.png", rlat, rlon, tlat, tlon, tid, title="o", keep_figure=True)
    try:
        ax = m.figure.axes[0]
        x0, x1 = ax.get_xlim()
        others = np.delete(rlon, 5)
        assert x0 <= min(others.min(), tlon.min()) and max(others.max(), tlon.max()) <= x1 < 0
        assert m.n_outside == 1
        texts = [t.get_text() for t in m.figure.legends[0].get_texts()]
        assert texts[-1] == "1 points outside this view"
    finally:
        plt.close(m.figure)
    # an explicit extent is used as given
    box = (-1.2, -1.0, 50.7, 50.9)
    m2 = plot_track_map(
        tmp_path / "b.png", rlat, rlon, tlat, tlon, tid, title="b", extent=box, keep_figure=True
    )
    try:
        ax = m2.figure.axes[0]
        assert ax.get_xlim() == box[:2] and ax.get_ylim() == box[2:]
        assert m2.aspect == pytest.approx(1 / math.cos(math.radians(50.8)), rel=1e-12)
    finally:
        plt.close(m2.figure)


def test_closed_by_default_and_empty_input(tmp_path):
    before = plt.get_fignums()
    m = plot_track_map(tmp_path / "e.png", [], [], [], [], [], title="nothing")
    assert plt.get_fignums() == before and m.figure is None
    assert m.n_track_lines == 0 and m.path.stat().st_size > 0


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"report_lat": [91.0] * 60}, "report_lat"),
        ({"track_lon": np.full(20, np.nan)}, "track_lon"),
        ({"track_lat": np.zeros(3)}, "track_lat has 3 entries but track_lon has 20"),
        ({"track_ids": np.ones(20, dtype=bool)}, "track_ids holds booleans"),
        ({"track_ids": np.arange(20) + 0.5}, "track_ids must be integers"),
        ({"track_ids": np.arange(4)}, "track_ids must be 1-D with one id per track point"),
        ({"report_ids": np.arange(5)}, "report_ids"),
        ({"min_points": 0}, "min_points"),
        ({"min_points": True}, "min_points"),
        ({"title": None}, "title"),
        ({"report_lon": [1j] * 60}, "report_lon"),
        ({"track_times": np.arange(3.0)}, "track_times"),
        ({"extent": (0.0, 1.0, 2.0)}, "extent"),
        ({"extent": (1.0, 0.0, 50.0, 51.0)}, "extent"),
        ({"extent": (0.0, 1.0, 50.0, 95.0)}, "extent"),
    ],
)
def test_bad_input(tmp_path, change, match):
    rlat, rlon, tlat, tlon, tid, rid = _scene()
    args = {
        "report_lat": rlat,
        "report_lon": rlon,
        "track_lat": tlat,
        "track_lon": tlon,
        "track_ids": tid,
        "title": "x",
        "report_ids": rid,
        **change,
    }
    before = plt.get_fignums()
    with pytest.raises(ValueError, match=match):
        plot_track_map(tmp_path / "bad.png", **args)
    assert plt.get_fignums() == before and not (tmp_path / "bad.png").exists()


@pytest.mark.parametrize("east_of_180", ["negative", "over180"])
def test_data_across_the_antimeridian_is_drawn_together(tmp_path, capfd, east_of_180):
    # issue 31.14: ships crossing 180° spread the map over a 360° axis (and a raw
    # matplotlib warning reached stderr); now the longitudes are unwrapped about the data
    k = np.arange(60)
    rlat = np.concatenate([51.0 + 1e-4 * k + d for d in (0.0, 0.05, 0.1)])
    rlon = np.tile(179.97 + 1e-3 * k, 3)
    if east_of_180 == "negative":
        rlon = np.where(rlon >= 180.0, rlon - 360.0, rlon)
    tid = np.repeat([1, 2, 3], 60)
    # the tracks' lat/lon come from LocalFrame.to_geodetic: always within [-180, 180]
    tlon = np.where(rlon >= 180.0, rlon - 360.0, rlon)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = plot_track_map(
            tmp_path / "map.png", rlat, rlon, rlat, tlon, tid, title="across", keep_figure=True
        )
    try:
        assert capfd.readouterr().err == ""
        ax = m.figure.axes[0]
        lo, hi = ax.get_xlim()
        assert 179.9 < lo < 179.97 and 180.03 < hi < 180.1 and m.n_outside == 0
        for line in ax.lines:  # each track is one short line, not a stroke across the map
            x = line.get_xdata()
            assert np.ptp(x) < 0.07 and np.all(np.diff(x) > 0)
        labels = [t.get_text() for t in ax.get_xticklabels()]
        values = [float(t.replace("−", "-")) for t in labels]
        assert all(-180.0 < v <= 180.0 for v in values) and "180.00" in labels
        assert any(v < 0 for v in values)  # west of the antimeridian: negative °E
    finally:
        plt.close(m.figure)


def test_an_extent_across_the_antimeridian_unwraps_the_data_about_it(tmp_path):
    lat = np.array([10.0, 10.1, 10.2])
    lon = np.array([179.9, -179.9, -179.8])
    m = plot_track_map(
        tmp_path / "m.png", lat, lon, lat, lon, np.array([1, 1, 1]), title="x",
        extent=(179.5, 180.5, 9.5, 10.5), keep_figure=True,
    )  # fmt: skip
    try:
        assert m.n_outside == 0
        (line,) = m.figure.axes[0].lines
        assert np.allclose(line.get_xdata(), [179.9, 180.1, 180.2])
    finally:
        plt.close(m.figure)
