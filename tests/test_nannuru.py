"""Nannuru & Coates reproduction (``experiments.nannuru``): tables, truth, figures, CLI."""

from __future__ import annotations

import functools
import io
import json
import math
import sys

import numpy as np
import pytest
from rich.console import Console

from jointtrack.experiments import nannuru
from jointtrack.superpositional import likelihood

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
# the extra methods ("saddlepoint", "hybrid") are exercised by test_extra_methods_columns
TINY = {
    "trials": 2,
    "n0s": (3, 4),
    "ratio_sets": 3,
    "ratio_states": 8,
    "hist_samples": 2000,
    "methods": (),
}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("nannuru")
    result = nannuru.reproduce(True, out_dir=out, **TINY)
    buf = io.StringIO()
    nannuru.print_report(result, Console(file=buf, width=250, color_system=None))
    return out, result, buf.getvalue()


def test_writes_json_and_pngs(tiny):
    out, result, text = tiny
    data = json.loads((out / "nannuru.json").read_text())
    for k in range(1, 6):
        assert (out / f"nannuru-figure{k}.png").read_bytes()[:8] == PNG_MAGIC
    for key in ("tables", "ratio", "settings", "paper", "notes", "figure_bins", "histograms"):
        assert key in data
    assert set(data["tables"]) == {"table1", "table2", "table3"}
    assert "uniform on {0, 1, ..., n0}" in data["settings"]["table3_iidc_part"]
    assert "Table I" in text and "Table IV" in text and "paper" in text


def test_rows_carry_the_papers_values_and_our_intervals(tiny):
    _, result, _ = tiny
    for t, key in (
        ("table1", "table1_iidc_percent_error"),
        ("table2", "table2_multibernoulli_percent_error"),
        ("table3", "table3_union_percent_error"),
    ):
        rows = result["tables"][t]
        assert [r["n0"] for r in rows] == [3, 4]
        for r in rows:
            assert r["paper"] == nannuru.PAPER[key][r["n0"] - 3]
            g = r["methods"]["gaussian"]
            assert g["status"] == "ok" and len(g["errors"]) == 2
            assert 0.0 <= g["lo"] <= g["mean"] <= g["hi"]
            assert "gaussian N_v" in r["methods"]
        assert rows[0]["truth"] == ("Rao-Blackwellised Monte Carlo" if t == "table3" else "exact")
    assert [r["name"] for r in result["ratio"]] == [n for n, _, _ in nannuru.RATIO_ROWS]
    for r in result["ratio"]:
        c = r["methods"]["gaussian"]
        assert c["status"] == "ok" and -1.0 <= c["corr"] <= 1.0


def test_percent_error_matches_direct_computation():
    model, y0, _ = nannuru.draw_model("table2", 3, 0)
    ex = likelihood(y0, model, nannuru.H, nannuru.SIGMA0, method="exact").log_value
    ga = likelihood(y0, model, nannuru.H, nannuru.SIGMA0).log_value
    want = 100 * abs(math.exp(ex) - math.exp(ga)) / math.exp(ex)
    assert nannuru.percent_error(ex, ga) == pytest.approx(want, rel=1e-12)
    # far in the tail: no underflow, still finite
    assert nannuru.percent_error(-1e4, -1e4 + 1e-3) == pytest.approx(0.1, rel=1e-3)


def test_paper_setup():
    pmf = nannuru.truncated_poisson(8)
    n = np.arange(16)
    assert round(float(pmf @ n), 2) == 7.93 and round(float(pmf @ (n * (n - 1))), 1) == 62.3
    model, y0, mb = nannuru.draw_model("table3", 5, 1)
    assert np.allclose(y0, nannuru.H @ mb.means.sum(axis=0))
    assert (mb.r >= 0.2).all() and (mb.r <= 1.0).all()
    assert np.allclose(model.parts[1].cardinality_pmf, np.full(6, 1 / 6))


def test_union_truth_agrees_with_plain_monte_carlo():
    model, y0, mb = nannuru.draw_model("table3", 3, 0)
    pmf = model.parts[1].cardinality_pmf
    log_i, se = nannuru.union_truth(mb, pmf, y0, 4000, np.random.default_rng(0))
    mc = likelihood(
        y0, model, nannuru.H, nannuru.SIGMA0, method="montecarlo", n_samples=200_000, rng=1
    )
    assert se < 0.05 and mc.std_error < 0.1
    assert abs(log_i - mc.log_value) <= 5 * math.hypot(se, mc.std_error)


def test_bin_plot_groups():
    rng = np.random.default_rng(0)
    r1 = rng.uniform(size=(5, 20))
    r = r1 + 0.01 * rng.standard_normal((5, 20))
    b = nannuru.bin_plot_data(r, r1)
    assert len(b["x"]) == 10 and np.all(np.diff(b["x"]) > 0)
    assert np.all(np.array(b["p10"]) <= np.array(b["p90"]))
    assert np.allclose(b["mean"], b["x"], atol=0.02)


def test_missing_or_failing_method_is_reported_not_raised(monkeypatch):
    lk = sys.modules["jointtrack.superpositional.likelihood"]
    orig = lk._method_module

    def fake(method):
        if method == "hybrid":
            raise NotImplementedError("method 'hybrid' is not available (test)")
        return orig(method)

    monkeypatch.setattr(lk, "_method_module", fake)
    row = nannuru.table_row("table2", 3, 2, methods=("hybrid",), nv_repeats=1)
    assert row["methods"]["hybrid"]["status"].startswith("not available")
    assert row["methods"]["gaussian"]["status"] == "ok"


def test_extra_methods_columns():
    """Every other dispatcher method gets a column: a number, or a stated reason it has none."""
    # the table row with "hybrid" compiles its kernels (~20 s cold): the ratio row covers it
    row = nannuru.table_row("table2", 3, 2, nv_repeats=1, methods=("saddlepoint", "no-such"))
    assert row["methods"]["no-such"]["status"].startswith("not available")
    rat = nannuru.ratio_row("t", ("equal", 0.9), 0.63, n_sets=2, n_x=5)
    for r, ms in ((row, ("saddlepoint",)), (rat, nannuru.EXTRA_METHODS)):
        for m in ms:
            st = r["methods"][m]["status"]
            assert st == "ok" or st.startswith(("not available", "failed"))


@pytest.mark.parametrize("kwargs", [{"trials": 1}, {"seed": -1}, {"n0s": (0,)}])
def test_bad_arguments(kwargs, tmp_path):
    with pytest.raises(ValueError):
        nannuru.reproduce(True, out_dir=tmp_path, write=False, **kwargs)


def test_cli_reproduce_nannuru(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from jointtrack.cli import app

    # the CLI's --quick run takes ~30 s; the wiring is what is tested here
    smaller = TINY | {"n0s": (3,), "ratio_sets": 2, "ratio_states": 4, "hist_samples": 500}
    monkeypatch.setattr(nannuru, "reproduce", functools.partial(nannuru.reproduce, **smaller))
    out = tmp_path / "n"
    r = CliRunner().invoke(
        app, ["reproduce", "nannuru", "--quick", "--out", str(out), "--no-progress"]
    )
    assert r.exit_code == 0, r.output
    assert (out / "nannuru.json").exists()
    assert "Table III" in r.output
