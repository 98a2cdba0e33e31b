"""The run and sweep plots read without the code: what the figure objects hold.

Axis labels carry units, legends explain every mark and sit outside the axes,
tracks have a start dot and an arrow at their end, long runs say what they
leave out, categorical sweep axes are bars, and extreme coordinates draw with
no warning (issue 25, item 2).
"""

from __future__ import annotations

import io
import json
import math
import warnings

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.collections import PathCollection  # noqa: E402
from matplotlib.container import BarContainer  # noqa: E402
from matplotlib.quiver import Quiver  # noqa: E402

from jointtrack.experiments.plots import PLOT_LIMIT, gospa_figure, scene_figure  # noqa: E402
from jointtrack.metrics.ospa import gospa_series  # noqa: E402
from jointtrack.sweep.report import metric_figure, metric_label  # noqa: E402


def _tracks(paths: dict) -> tuple:
    """Flat (times, ids, positions) from {id: (K, 2) positions at times 0..K-1}."""
    t, i, p = [], [], []
    for k, pos in paths.items():
        pos = np.asarray(pos, dtype=float)
        t.append(np.arange(len(pos), dtype=float))
        i.append(np.full(len(pos), k))
        p.append(pos)
    return np.concatenate(t), np.concatenate(i), np.concatenate(p)


def _legend_outside(fig, ax, legend) -> bool:
    # a bare Figure (the sweep's, no pyplot) has no renderer of its own
    canvas = fig.canvas if hasattr(fig.canvas, "get_renderer") else FigureCanvasAgg(fig)
    canvas.draw()  # lays the figure out
    r = canvas.get_renderer()
    box = legend.get_window_extent(r)
    # right of the axes, and not cut off by the figure's edge
    return box.x0 >= ax.get_window_extent(r).x1 - 1.0 and box.x1 <= fig.bbox.x1 + 1.0


def _scene(rng, n_scans=12):
    a = np.column_stack([np.linspace(0, 110, n_scans), np.linspace(0, 30, n_scans)])
    b = np.column_stack([np.linspace(100, -10, n_scans), np.full(n_scans, 50.0)])
    truth = _tracks({0: a, 1: b})
    tracks = _tracks({7: a + rng.normal(0, 1, a.shape), 9: b[2:] + rng.normal(0, 1, b[2:].shape)})
    scans, origins = [], []
    for k in range(n_scans):
        clutter = rng.uniform(-20, 120, (3, 2))
        scans.append(np.vstack([a[k], b[k], clutter]))
        origins.append(np.array([0, 1, -1, -1, -1]))
    return dict(
        times=np.arange(n_scans, dtype=float),
        scans=scans,
        origins=origins,
        truth=truth,
        tracks=tracks,
        region=np.array([[-20.0, 120.0], [-10.0, 60.0]]),
        title="test scene",
    )


def test_scene_units_marks_and_legend_outside():
    kw = _scene(np.random.default_rng(3))
    fig = scene_figure(**kw)
    try:
        ax = fig.axes[0]
        assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
        assert ax.get_title() == "test scene — 12 scans, 2 confirmed tracks"
        leg = ax.get_legend()
        labels = [t.get_text() for t in leg.get_texts()]
        for word in ("clutter", "target detections", "truth", "confirmed tracks", "start"):
            assert any(word in lab for lab in labels), (word, labels)
        assert any("direction" in lab for lab in labels)
        assert _legend_outside(fig, ax, leg)
        # a start dot at the first position of every track and truth line
        _, ids, pos = kw["tracks"]
        starts = {tuple(np.round(pos[ids == k][0], 9)) for k in (7, 9)}
        starts |= {tuple(np.round(p, 9)) for p in ((0.0, 0.0), (100.0, 50.0))}
        dots = {
            tuple(np.round(o, 9))
            for c in ax.collections
            if isinstance(c, PathCollection) and c.get_zorder() >= 4
            for o in c.get_offsets()
        }
        assert starts <= dots
        # an arrow at the end of every line, pointing along its last move
        quivers = [c for c in ax.collections if isinstance(c, Quiver)]
        ends = {}
        for q in quivers:
            for xy, u, v in zip(q.get_offsets(), q.U, q.V, strict=True):
                ends[tuple(np.round(xy, 9))] = (u, v)
        p7 = pos[ids == 7]
        d = p7[-1] - p7[-2]
        u, v = ends[tuple(np.round(p7[-1], 9))]
        assert np.allclose((u, v), d / np.hypot(*d))
        assert len(ends) == 4  # two tracks, two truth lines
    finally:
        plt.close(fig)


def test_long_run_draws_only_tracks_of_five_scans_or_more_and_says_so():
    rng = np.random.default_rng(0)
    lengths = rng.integers(1, 12, 150)  # 150 tracks: a long run
    paths = {k: np.cumsum(rng.normal(0, 5, (n, 2)), axis=0) for k, n in enumerate(lengths)}
    shown = int((lengths >= 5).sum())
    assert 0 < shown < 150
    fig = scene_figure(times=np.arange(12.0), scans=[], tracks=_tracks(paths))
    try:
        ax = fig.axes[0]
        assert f"150 confirmed tracks, {shown} shown (those of ≥ 5 scans)" in ax.get_title()
        assert "ids not shown" in ax.get_title()
        track_lines = [ln for ln in ax.get_lines() if ln.get_zorder() == 4]
        assert len(track_lines) == shown
        assert all(ln.get_linewidth() < 1.0 for ln in track_lines)
    finally:
        plt.close(fig)


def test_short_run_draws_every_track():
    paths = {k: np.array([[0.0, k], [1.0, k]]) for k in range(3)}  # 2-scan tracks
    fig = scene_figure(times=np.arange(2.0), scans=[], tracks=_tracks(paths))
    try:
        ax = fig.axes[0]
        assert ax.get_title() == "2 scans, 3 confirmed tracks"
        assert len([ln for ln in ax.get_lines() if ln.get_zorder() == 4]) == 3
    finally:
        plt.close(fig)


@pytest.mark.parametrize("big", [1e300, 1.7e308, np.inf, np.nan])
def test_extreme_coordinates_draw_without_warnings(big):
    kw = _scene(np.random.default_rng(1), n_scans=6)
    tt, ti, tp = kw["truth"]
    tp = tp.copy()
    tp[2] = (big, -big)  # a truth file may hold what the tracker would refuse
    kw["truth"] = (tt, ti, tp)
    kw["scans"][3] = np.vstack([kw["scans"][3], [[big, 1.0]]])
    kw["origins"][3] = np.append(kw["origins"][3], -1)
    kw["region"] = np.array([[-big, big], [-1.0, 1.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = scene_figure(**kw)
        try:
            fig.savefig(io.BytesIO(), format="png")
            ax = fig.axes[0]
            if abs(big) <= PLOT_LIMIT:  # never: every case here is beyond the limit
                pytest.fail("the case must lie beyond PLOT_LIMIT")
            assert f"2 points not finite or beyond ±{PLOT_LIMIT:.0e} m not drawn" in (
                ax.get_title()
            )
            lo, hi = ax.get_xlim()
            assert np.isfinite([lo, hi]).all() and hi - lo < 1e3
        finally:
            plt.close(fig)


def test_gospa_figure_units_and_typeset_square():
    rng = np.random.default_rng(2)
    t = np.repeat(np.arange(10.0), 2)
    ids = np.tile([0, 1], 10)
    truth = rng.uniform(0, 100, (20, 2))
    series = gospa_series(t, ids, truth, t[2:], ids[2:], truth[2:] + 1.0, c=20.0, p=2)
    fig = gospa_figure(series, title="g")
    try:
        top, bottom = fig.axes
        assert top.get_ylabel() == "GOSPA (m)"
        assert bottom.get_ylabel() == "GOSPA$^{2}$ parts (m$^{2}$)"
        assert bottom.get_xlabel() == "time (s)"
        assert "c = 20 m" in top.get_title() and f"{series.mean:.3g} m" in top.get_title()
        labels = [x.get_text() for x in bottom.get_legend().get_texts()]
        assert labels[0].startswith("localisation") and "missed" in labels[1]
        assert "false" in labels[2]
        assert _legend_outside(fig, bottom, bottom.get_legend())
        assert np.allclose(top.get_lines()[0].get_ydata(), series.gospa)
    finally:
        plt.close(fig)


def _rows(cells: dict, seeds=(0, 1, 2)) -> list[dict]:
    """Sweep rows: cells maps (method, params) → a metric value per seed (its function)."""
    rows = []
    for (method, params), value in cells.items():
        for s in seeds:
            rows.append(
                {
                    "status": "ok",
                    "method": method,
                    "seed": s,
                    "params": json.dumps(dict(params), sort_keys=True),
                    "metric.gospa": value(s),
                }
            )
    return rows


def test_sweep_method_axis_is_bars_with_scenario_and_seeds_in_title():
    axes = {"tracker.association": ["exact", "lbp"]}
    means = {"exact": 3.0, "lbp": 5.0}
    cells = {
        (f"jpda/{a}", (("scenario.name", "crossing"), ("tracker.association", a))): (
            lambda s, a=a: means[a] + s - 1
        )
        for a in axes["tracker.association"]
    }
    fig = metric_figure(_rows(cells), axes, "tracker.association", "gospa")
    ax = fig.axes[0]
    bars = [c for c in ax.containers if isinstance(c, BarContainer)]
    assert [b.patches[0].get_height() for b in bars] == [3.0, 5.0]  # means over seeds 0..2
    assert not [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 1]
    assert ax.get_title().startswith("crossing: gospa vs tracker.association")
    assert "3 seeds per cell" in ax.get_title()
    assert ax.get_ylabel().startswith("mean GOSPA per scan (m)")
    assert [t.get_text() for t in ax.get_xticklabels()] == ["exact", "lbp"]
    assert _legend_outside(fig, ax, ax.get_legend())


def test_sweep_numeric_axis_is_lines_pooled_over_the_other_axis():
    axes = {"scenario.clutter_per_scan": [5.0, 20.0, 50.0], "tracker.association": ["exact", "lbp"]}
    cells = {}
    for a in axes["tracker.association"]:
        for c in axes["scenario.clutter_per_scan"]:
            key = (("scenario.clutter_per_scan", c), ("scenario.name", "bojilov"))
            key += (("tracker.association", a),)
            cells[(f"jpda/{a}", key)] = lambda s, c=c, a=a: c / 10 + (a == "lbp")
    fig = metric_figure(_rows(cells, seeds=(0, 1)), axes, "scenario.clutter_per_scan", "gospa")
    ax = fig.axes[0]
    assert not [c for c in ax.containers if isinstance(c, BarContainer)]
    lines = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]  # not the CI caps
    assert len(lines) == 2
    assert np.allclose(lines[0].get_ydata(), [0.5, 2.0, 5.0])
    assert np.allclose(lines[1].get_ydata(), [1.5, 3.0, 6.0])
    # shifted apart by 1.2 % of the span each side, no more
    assert np.allclose(lines[1].get_xdata() - lines[0].get_xdata(), 0.012 * 45.0)
    assert np.allclose((lines[0].get_xdata() + lines[1].get_xdata()) / 2, [5.0, 20.0, 50.0])
    # tracker.association is the method itself here: nothing is pooled
    assert ax.get_title().endswith("\n2 seeds per cell")
    assert ax.get_xlabel() == "scenario.clutter_per_scan"
    # along the association axis every method has one value: bars
    fig2 = metric_figure(_rows(cells, seeds=(0, 1)), axes, "tracker.association", "gospa")
    assert [c for c in fig2.axes[0].containers if isinstance(c, BarContainer)]


def test_metric_labels_carry_units():
    assert metric_label("gospa") == "mean GOSPA per scan (m)"
    assert metric_label("gospa_localisation", p=1) == (
        "GOSPA$^{1}$ part: localisation, mean per scan (m$^{1}$)"
    )
    assert metric_label("seconds_per_scan").endswith("(s)")
    assert metric_label("scans_per_second").endswith("(scans/s)")


def test_run_of_more_than_500_scans_draws_a_density_and_the_last_100_scans():
    n = 600
    k = np.arange(n, dtype=float)
    paths = {j: np.column_stack([k, np.full(n, 10.0 * j)]) for j in range(3)}
    tracks = _tracks(paths)
    scans = [np.array([[x, 0.0], [x, 10.0], [x, 20.0]]) for x in k]
    origins = [np.array([0, 1, 2])] * n
    fig = scene_figure(
        times=k,
        scans=scans,
        origins=origins,
        tracks=tracks,
        truth=tracks,
        region=np.array([[0.0, 600.0], [-5.0, 25.0]]),
        title="long",
    )
    try:
        ax_all, ax_end = fig.axes[:2]
        assert fig.get_suptitle() == "long — 600 scans, 3 confirmed tracks"
        # the density counts every track estimate once
        (mesh,) = [c for c in ax_all.collections if hasattr(c, "get_array")]
        assert mesh.get_array().sum() == 3 * n
        assert "per cell" in fig.axes[2].get_ylabel() and " m × " in fig.axes[2].get_ylabel()
        assert ax_all.get_xlabel() == "x (m)" and ax_end.get_ylabel() == "y (m)"
        assert ax_end.get_title().startswith("the last 100 scans (t ≥ 500 s): 3 tracks")
        track_lines = [ln for ln in ax_end.get_lines() if ln.get_zorder() == 4]
        assert sorted(len(ln.get_xdata()) for ln in track_lines) == [100, 100, 100]
        assert min(min(ln.get_xdata()) for ln in track_lines) == 500.0
        labels = [t.get_text() for t in ax_end.get_legend().get_texts()]
        assert "start (first position in these scans)" in labels
        assert _legend_outside(fig, ax_end, ax_end.get_legend())
    finally:
        plt.close(fig)


def test_sweep_title_names_an_axis_pooled_within_a_method():
    axes = {"scenario.clutter_per_scan": [5.0, 20.0], "scenario.p_d": [0.8, 0.9]}
    cells = {}
    for c in axes["scenario.clutter_per_scan"]:
        for pd in axes["scenario.p_d"]:
            key = (("scenario.clutter_per_scan", c), ("scenario.name", "crossing"))
            cells[("jpda/exact", key + (("scenario.p_d", pd),))] = lambda s, c=c, pd=pd: c * pd
    fig = metric_figure(_rows(cells, seeds=(0,)), axes, "scenario.clutter_per_scan", "gospa")
    ax = fig.axes[0]
    assert ax.get_title() == (
        "crossing: gospa vs scenario.clutter_per_scan\n1 seed per cell; pooled over scenario.p_d"
    )
    (line,) = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
    assert np.allclose(line.get_ydata(), [5.0 * 0.85, 20.0 * 0.85])  # mean over p_d


def test_acoustic_figure_explains_estimate_colours_and_start_dots():
    from jointtrack.experiments.acoustic_run import acoustic_figure
    from jointtrack.scenarios.acoustic import acoustic

    sc = acoustic(seed=0, n_scans=10)  # the first 4 scans are drawn
    rows = [
        [float(sc.times[k]), j, 10.0 + k + 5 * j, 20.0 - k, 1.0, -1.0]
        for k in range(4)
        for j in (3, 8)
    ]
    fig = acoustic_figure(sc, rows, np.array([1.0, 2.0, 0.5, 0.2]), "sps-cphd", "gaussian", 4)
    try:
        ax, ax2 = fig.axes
        assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (m)", "y (m)")
        assert ax2.get_xlabel() == "time (s)" and ax2.get_ylabel().startswith("OSPA (m)")
        assert "4 scans, 2 estimate tracks" in ax.get_title()
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert labels[0] == "sensors" and "truth start" in labels
        assert any(lab.startswith("estimates: one colour per track") for lab in labels)
        assert "first estimate of a track" in labels
        assert "arrow: direction at the end" in labels
        assert _legend_outside(fig, ax, ax.get_legend())
        # a ringed dot at each track's first estimate, an arrow at its last
        rings = {
            (float(ln.get_xdata()[0]), float(ln.get_ydata()[0]))
            for ln in ax.get_lines()
            if ln.get_marker() == "o" and ln.get_markeredgecolor() == "k" and ln.get_zorder() == 5
        }
        assert rings == {(25.0, 20.0), (50.0, 20.0)}  # x = 10 + k + 5·id at k = 0
        quivers = [c for c in ax.collections if isinstance(c, Quiver)]
        tips = {tuple(np.round(xy, 9)) for q in quivers for xy in q.get_offsets()}
        assert {(28.0, 17.0), (53.0, 17.0)} <= tips  # k = 3
    finally:
        plt.close(fig)


@given(
    st.lists(
        st.floats(min_value=-1.7e308, max_value=1.7e308, allow_nan=False, allow_infinity=False),
        min_size=1,
        max_size=6,
    )
)
@settings(max_examples=60, deadline=None)
def test_mean_ci_near_the_float_limit_matches_exact_rationals(xs):
    from fractions import Fraction

    from scipy.stats import t

    from jointtrack.sweep.report import mean_ci

    m, h, n = mean_ci(xs)
    exact = sum(Fraction(x) for x in xs) / len(xs)
    assert n == len(xs)
    assert abs(Fraction(m) - exact) <= Fraction(1e-12) * max(abs(Fraction(x)) for x in xs)
    if len(xs) == 1:
        assert h is None
        return
    big = max(abs(Fraction(x)) for x in xs) or Fraction(1)
    # the exact variance in units of the largest |x|², so that float() cannot overflow
    var = sum(((Fraction(x) - exact) / big) ** 2 for x in xs) / (len(xs) - 1)
    want = float(t.ppf(0.975, len(xs) - 1)) * math.sqrt(float(var)) / math.sqrt(len(xs))
    want *= float(big)  # inf beyond the float range
    if math.isinf(want):
        assert h == math.inf
    else:
        assert h == pytest.approx(want, rel=1e-9, abs=1e-300)


def test_sweep_figure_with_means_near_the_float_limit_draws_without_warnings():
    axes = {"tracker.association": ["exact", "lbp"]}
    huge = {"exact": (1e300, 1.7e308), "lbp": (1.0, 2.0)}
    cells = {
        (f"jpda/{a}", (("scenario.name", "crossing"), ("tracker.association", a))): (
            lambda s, a=a: huge[a][s]
        )
        for a in axes["tracker.association"]
    }
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = metric_figure(_rows(cells, seeds=(0, 1)), axes, "tracker.association", "gospa")
        fig.savefig(io.BytesIO(), format="png")
    ax = fig.axes[0]
    assert "1 mean(s) beyond ±1e+150 not drawn" in ax.get_title()
    bars = [c for c in ax.containers if isinstance(c, BarContainer)]
    assert [b.patches[0].get_height() for b in bars] == [1.5]
