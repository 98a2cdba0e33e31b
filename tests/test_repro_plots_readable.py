"""The four reproductions' figures read without the code (issue 25, item 2).

Everything is read back from the :class:`matplotlib.figure.Figure` objects the
``*_figure`` builders return, after ``fig.canvas.draw()`` (so layout, tick
labels and legend positions are final): axis labels carry units, legends lie
outside every axes, tick labels do not run together, and extreme inputs
(1e300, inf, NaN, 0 on a log axis) neither leak a warning nor vanish silently.
The inputs are synthetic, of the shape each ``reproduce`` returns, so the
tests take a few seconds.
"""

from __future__ import annotations

import io
import re
import warnings

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from jointtrack.experiments import (  # noqa: E402
    bojilov,
    bojilov_plots,
    nannuru_plots,
    schaub,
    schaub_plots,
    streit,
    streit_plots,
)
from jointtrack.experiments._plot_values import OFF_SCALE, UNITS, plottable  # noqa: E402

_UNIT = re.compile(r"\((" + "|".join(re.escape(u[1:-1]) for u in UNITS) + r")\)")

# ----------------------------------------------------------------------------- inputs


def _streit_result(rng, *, extreme: bool = False) -> dict:
    """A Streit result of the shape ``streit.reproduce`` returns (N = 7, M = 5 figures).

    The saddle-corrected ratios sit within 3e-4 of 0.9993: the narrow
    histogram whose default tick labels ran together.
    """
    n = 200
    saddle = rng.normal(1.468, 0.0064, n)
    corrected = rng.normal(0.9993, 0.0003, n)
    exact = rng.gamma(3.0, 90.0, n)
    if extreme:
        saddle[:3] = (1e300, np.inf, np.nan)
        exact[:2] = (1e300, -np.inf)
    rows = []
    for N in (3, 7):
        for M in (5, 10, 20):
            methods = {
                m: {"seconds_per_particle": 1e-5 * M * (k + 1), "status": "ok"}
                for k, m in enumerate(streit.COST_METHODS)
            }
            parts = {"coefficients": 2e-6, "saddle_search": 1e-5, "determinants": 4e-9 * M**3}
            if N == 7 and M == 20:
                methods["exact"]["status"] = "stopped"
                if extreme:
                    methods["saddle"]["seconds_per_particle"] = 1e300
                    methods["exact-batched"]["seconds_per_particle"] = 0.0
                    parts["coefficients"] = float("inf")
            rows.append({"N": N, "M": M, "methods": methods, "parts": parts})
    variants = {
        "saddle": {"status": "ok", "mean": 1.468, "std": 0.0064},
        "saddle-corrected": {"status": "ok", "mean": 0.9993, "std": 0.0003},
    }
    return {
        "settings": {"trials": n, "seed": 0, "particles": 100},
        "figure1": streit.figure1(401),
        "figure3": {
            "N": 7,
            "M": 5,
            "ratios": {"saddle": saddle.tolist(), "saddle-corrected": corrected.tolist()},
            "variants": variants,
            "paper": streit.PAPER["figure3"],
        },
        "figure4": {
            "N": 7,
            "M": 5,
            "exact": exact.tolist(),
            "min": float(np.nanmin(exact[np.isfinite(exact)])),
            "max": float(np.nanmax(exact[np.isfinite(exact)])),
            "paper": streit.PAPER["figure4"],
        },
        "cost": {"rows": rows},
    }


def _nannuru_inputs(rng, *, extreme: bool = False):
    hists = []
    for n0 in (4, 6, 8):
        y = rng.gamma(n0, 8.0, size=(2000, 3))
        if extreme:
            y[:3, 0] = (1e300, np.inf, -1e300)
        hists.append({"n0": n0, "y": y, "mean": np.full(3, 8.0 * n0), "var": np.full(3, 64.0 * n0)})
    x = np.linspace(0.8, 3.5, 10)
    bins = {
        "x": x.tolist(),
        "mean": (0.9 * x).tolist(),
        "median": (0.85 * x).tolist(),
        "p10": (0.5 * x).tolist(),
        "p90": (1.3 * x).tolist(),
    }
    if extreme:
        bins["p90"][-1] = 1e300
        bins["mean"][0] = float("nan")
    return hists, bins


def _bojilov_result(*, extreme: bool = False) -> dict:
    results = {}
    for beta in (1.0, 2.0):
        rows = [
            {
                "targets": t,
                "n_clusters": 5,
                "mean_seconds_naive": 1e-4 * t,
                "mean_seconds_optimised": 8e-5 * t,
                "mean_seconds_exact": 5e-5 * t,
                "mean_mult_naive": 10.0**t,
                "mean_mult_optimised": 4.0**t,
            }
            for t in (2, 3, 4, 5)
        ]
        if extreme:
            rows[-1]["mean_seconds_naive"] = 1e300
            rows[0]["mean_mult_optimised"] = 0.0
            rows[1]["mean_seconds_exact"] = None
        results[f"beta={beta:g}"] = {"rows": rows}
    return {
        "paper": bojilov.PAPER_TABLES,
        "betas": [1.0, 2.0],
        "results": results,
        "settings": {"runs": 2},
    }


def _schaub_res(example: int, *, extreme: bool = False) -> dict:
    steps = 40
    k = np.arange(1, steps + 1)
    kl = {
        "exact": (5.0 * np.exp(-k / 15) + 1.0).tolist(),
        "sinkhorn": (5.2 * np.exp(-k / 15) + 1.0).tolist(),
        "local": (4.6 * np.exp(-k / 15) + 0.7).tolist(),
        "maxweight": [float("inf")] * 18 + [0.0] + [float("inf")] * (steps - 19),
    }
    if extreme:
        kl["local"][5] = 1e300
        kl["exact"][6] = float("nan")
    return {
        "example": example,
        "seed": 0,
        "max_kl": kl,
        "plotted_kl": "per identity",
        "n_observed_tracks": 6,
        "n_identities": 100,
        "seconds_per_step": {"exact": 0.02},
        "over_seeds": {"seeds": [0, 1, 2], "median_max_kl": kl},
    }


def _figures(*, extreme: bool = False) -> dict:
    """Every reproduction figure, by name, built from synthetic inputs."""
    rng = np.random.default_rng(25)
    sr = _streit_result(rng, extreme=extreme)
    hists, bins = _nannuru_inputs(rng, extreme=extreme)
    return {
        "streit-figure1": lambda: streit_plots.figure1(sr["figure1"], 401),
        "streit-figure3": lambda: streit_plots.figure3(sr),
        "streit-figure4": lambda: streit_plots.figure4(sr),
        "streit-cost": lambda: streit_plots.cost_figure(sr),
        "nannuru-figure1": lambda: nannuru_plots.histogram_figure(hists, "Figure 1"),
        "nannuru-figure4": lambda: nannuru_plots.bins_figure(bins, "Figure 4"),
        "bojilov": lambda: bojilov_plots.bojilov_figure(_bojilov_result(extreme=extreme)),
        "schaub-example1": lambda: schaub_plots.schaub_figure(
            _schaub_res(1, extreme=extreme), schaub.PAPER
        ),
    }


NAMES = list(_figures())


@pytest.fixture(scope="module")
def drawn():
    """Every figure built and drawn once (layout final), closed after the module."""
    figs = {}
    for name, build in _figures().items():
        fig = build()
        fig.canvas.draw()
        figs[name] = fig
    yield figs
    for fig in figs.values():
        plt.close(fig)


def _axes(fig):
    return [ax for ax in fig.axes if ax.get_visible()]


def _overlap(a, b, pad: float = 0.0) -> bool:
    """Whether display-space boxes ``a`` and ``b`` overlap (by more than ``pad`` pixels)."""
    return min(a.x1, b.x1) - max(a.x0, b.x0) > pad and min(a.y1, b.y1) - max(a.y0, b.y0) > pad


# ----------------------------------------------------------------------------- labels


@pytest.mark.parametrize("name", NAMES)
def test_every_axis_label_names_its_unit(drawn, name):
    fig = drawn[name]
    labelled = 0
    for ax in _axes(fig):
        for label in (ax.get_xlabel(), ax.get_ylabel()):
            if label:
                labelled += 1
                assert _UNIT.search(label), f"{name}: axis label {label!r} has no unit"
    assert labelled >= 2, f"{name}: no axis labels at all"


@pytest.mark.parametrize("name", NAMES)
def test_every_row_and_column_of_panels_is_labelled(drawn, name):
    """Each panel's row has a y label and its column an x label (shared labels count)."""
    fig = drawn[name]
    axes = _axes(fig)
    rows, cols = {}, {}
    for ax in axes:
        ss = ax.get_subplotspec()
        for r in range(ss.rowspan.start, ss.rowspan.stop):
            rows.setdefault(r, []).append(bool(ax.get_ylabel()))
        for c in range(ss.colspan.start, ss.colspan.stop):
            cols.setdefault(c, []).append(bool(ax.get_xlabel()))
    assert all(any(v) for v in rows.values()), f"{name}: a row of panels has no y label"
    assert all(any(v) for v in cols.values()), f"{name}: a column of panels has no x label"


def test_nannuru_figure1_has_x_and_y_labels_in_metres(drawn):
    fig = drawn["nannuru-figure1"]
    axes = np.array(_axes(fig)).reshape(3, 3)
    for j, ax in enumerate(axes[-1]):
        assert ax.get_xlabel() == f"$y_{j + 1}$ (m)"
    for ax in axes[:, 0]:
        assert ax.get_ylabel() == "density (1/m)"


def test_titles_say_what_is_plotted(drawn):
    assert "Streit Figure 3" in drawn["streit-figure3"]._suptitle.get_text()
    assert "cost per particle" in drawn["streit-cost"]._suptitle.get_text()
    assert "max KL (58)" in _axes(drawn["schaub-example1"])[0].get_title()
    assert "(nats)" in _axes(drawn["schaub-example1"])[0].get_ylabel()
    assert "(s)" in _axes(drawn["bojilov"])[0].get_ylabel()


# ----------------------------------------------------------------------------- legends


def _legends(fig):
    return [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend() is not None)]


@pytest.mark.parametrize("name", NAMES)
def test_no_legend_over_any_axes(drawn, name):
    fig = drawn[name]
    renderer = fig.canvas.get_renderer()
    for leg in _legends(fig):
        box = leg.get_window_extent(renderer)
        for ax in _axes(fig):
            assert not _overlap(box, ax.get_window_extent(renderer), pad=1.0), (
                f"{name}: a legend covers the data area of an axes"
            )


@pytest.mark.parametrize(
    "name", ["streit-figure3", "streit-cost", "nannuru-figure1", "bojilov", "schaub-example1"]
)
def test_legend_names_every_drawn_series(drawn, name):
    """Every labelled artist of every axes is in some legend of the figure."""
    fig = drawn[name]
    texts = {t.get_text() for leg in _legends(fig) for t in leg.get_texts()}
    assert texts, f"{name}: no legend"
    for ax in _axes(fig):
        for lab in ax.get_legend_handles_labels()[1]:
            assert lab in texts, f"{name}: {lab!r} is drawn but not in a legend"


# ----------------------------------------------------------------------------- ticks


def _tick_boxes(ax, renderer):
    return [
        t.get_window_extent(renderer)
        for t in ax.get_xticklabels()
        if t.get_visible() and t.get_text()
    ]


@pytest.mark.parametrize("name", NAMES)
def test_x_tick_labels_do_not_run_together(drawn, name):
    fig = drawn[name]
    renderer = fig.canvas.get_renderer()
    for ax in _axes(fig):
        boxes = sorted(_tick_boxes(ax, renderer), key=lambda b: b.x0)
        for a, b in zip(boxes, boxes[1:], strict=False):
            assert b.x0 - a.x1 > 2.0, f"{name}: x tick labels touch ({a} / {b})"


def test_streit_figure3_right_ticks_are_few_and_apart(drawn):
    fig = drawn["streit-figure3"]
    renderer = fig.canvas.get_renderer()
    right = _axes(fig)[1]
    labels = [t.get_text() for t in right.get_xticklabels() if t.get_text()]
    assert 3 <= len(labels) <= 6
    # the fewest decimals that tell the ticks apart: no trailing zero on all of them
    assert not all(s.endswith("0") for s in labels), labels
    boxes = sorted(_tick_boxes(right, renderer), key=lambda b: b.x0)
    gaps = [b.x0 - a.x1 for a, b in zip(boxes, boxes[1:], strict=False)]
    assert min(gaps) > 10.0, gaps


def test_the_old_default_ticks_of_figure3_right_did_run_together():
    """The tick test can fail: matplotlib's default ticks on the same data overlap."""
    rng = np.random.default_rng(25)
    r = rng.normal(0.9993, 0.0003, 200)
    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    ax.hist(r, bins=40)
    ax.axvline(1.0)
    fig.canvas.draw()
    boxes = sorted(_tick_boxes(ax, fig.canvas.get_renderer()), key=lambda b: b.x0)
    gaps = [b.x0 - a.x1 for a, b in zip(boxes, boxes[1:], strict=False)]
    plt.close(fig)
    assert min(gaps) <= 10.0


# ----------------------------------------------------------------------------- extreme values


@pytest.fixture(scope="module")
def extreme_drawn():
    """Every figure built from inputs with 1e300, ±inf, NaN and 0 on log axes, and
    written to PNG under ``simplefilter("error")``: the figure, or the warning it raised."""
    out = {}
    for name, build in _figures(extreme=True).items():
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                fig = build()
                buf = io.BytesIO()
                fig.savefig(buf, format="png", dpi=50)
                out[name] = (fig, buf.getvalue())
            except Warning as w:  # reported by the test, not here
                out[name] = (None, w)
    yield out
    for fig, _ in out.values():
        if fig is not None:
            plt.close(fig)


@pytest.mark.parametrize("name", NAMES)
def test_extreme_values_draw_without_any_warning(extreme_drawn, name):
    fig, png = extreme_drawn[name]
    assert fig is not None, f"{name}: {png!r}"
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "name", ["streit-figure3", "streit-figure4", "streit-cost", "nannuru-figure1", "bojilov"]
)
def test_values_left_out_are_counted_in_the_figure(extreme_drawn, name):
    fig, _ = extreme_drawn[name]
    assert fig is not None
    texts = [t.get_text() for t in fig.findobj(matplotlib.text.Text)]
    assert any("not drawn" in t for t in texts), f"{name}: the skipped values are not mentioned"


def test_a_1e300_time_on_a_log_axis_would_warn_inside_matplotlib():
    """Why the values are filtered: drawn as is, 1e300 on a log axis warns from site-packages."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fig, ax = plt.subplots()
        ax.plot([1, 2], [1e-3, 1e300])
        ax.set_yscale("log")
        fig.canvas.draw()
    plt.close(fig)
    assert any("matplotlib" in w.filename for w in caught)


def test_clean_inputs_mention_nothing_left_out(drawn):
    for name, fig in drawn.items():
        texts = [t.get_text() for t in fig.findobj(matplotlib.text.Text)]
        assert not any("not drawn" in t for t in texts), name


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True)), max_size=20),
    st.booleans(),
)
def test_plottable_keeps_exactly_the_drawable_values(values, log):
    y, n_off = plottable(values, log=log)
    assert y.shape == (len(values),)
    expected_off = 0
    for v, out in zip(values, y, strict=True):
        drawable = (
            v is not None
            and np.isfinite(v)
            and abs(v) <= OFF_SCALE
            and (not log or v >= 1.0 / OFF_SCALE)
        )
        expected_off += v is not None and not drawable
        assert (out == v) if drawable else np.isnan(out)
    assert n_off == expected_off
