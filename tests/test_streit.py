"""Streit reproduction (``jointtrack.experiments.streit``): Table 1, figures, cost grid."""

from __future__ import annotations

import io
import json
import math

import numpy as np
import pytest
from rich.console import Console

from jointtrack.experiments import streit
from jointtrack.saddle import log_mixed_derivative

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
PNGS = ("streit-figure1.png", "streit-figure3.png", "streit-figure4.png", "streit-cost.png")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """One quick reproduction on a tiny setting, written to disk and printed."""
    out = tmp_path_factory.mktemp("streit")
    result = streit.reproduce(
        True,
        out_dir=out,
        trials=30,
        cost_N=(2, 3),
        cost_M=(3, 5),
        particles=8,
        time_budget=0.5,
    )
    buf = io.StringIO()
    streit.print_report(result, Console(file=buf, width=200, color_system=None))
    return out, result, buf.getvalue()


def test_writes_json_and_valid_pngs(tiny):
    out, result, _ = tiny
    data = json.loads((out / "streit.json").read_text())
    for name in PNGS:
        assert (out / name).read_bytes()[:8] == PNG_MAGIC
    assert set(result["files"]) == {"json", "figure1", "figure3", "figure4", "cost"}
    # every printed table is in the JSON
    for key in ("table1", "figure1", "cost", "checks", "notes", "settings", "paper"):
        assert key in data
    assert data["settings"]["trials"] == 30 and data["settings"]["seed"] == streit.SEED
    assert len(data["figure4"]["exact"]) == 30
    assert len(data["cost"]["rows"]) == 4


def test_table_has_nine_cells_with_the_papers_values_beside_ours(tiny):
    _, result, text = tiny
    cells = result["table1"]
    assert [(c["N"], c["M"]) for c in cells] == [(n, m) for n in (3, 5, 7) for m in (5, 10, 15)]
    for c in cells:
        i, j = (3, 5, 7).index(c["N"]), (5, 10, 15).index(c["M"])
        assert c["paper"] == {"mean": streit.PAPER["mean"][i][j], "std": streit.PAPER["std"][i][j]}
        s = c["variants"]["saddle"]
        assert s["status"] == "ok" and s["n_failed"] == 0 and s["batched"]
        assert s["invariance_error"] < 1e-8  # the a = 1 rescaling changes nothing
        corr = c["variants"]["saddle-corrected"]
        assert corr["status"] in ("ok", "not available")
    # the printed table shows the paper's numbers and ours
    assert "1.47" in text and "0.0036" in text and "3.36" in text
    assert f"{cells[0]['variants']['saddle']['mean']:.4f}" in text
    assert "saddle: mean within 3 %" in text


def test_saddle_mean_lies_near_the_papers(tiny):
    _, result, _ = tiny
    # 30 trials: a loose band (the full run holds 3 %); the mean tracks (e/√2π)^M
    for c in result["table1"]:
        mean = c["variants"]["saddle"]["mean"]
        assert abs(mean / c["paper"]["mean"] - 1.0) < 0.06
        assert abs(mean / c["stirling"] - 1.0) < 0.06


def test_figure1_saddle_point_is_the_root():
    f1 = streit.figure1()
    root = (19.0 + math.sqrt(601.0)) / 20.0
    assert abs(f1["r_hat"] - root) <= 1e-9
    assert abs(10 * f1["r_hat"] ** 2 - 19 * f1["r_hat"] - 6) < 1e-12
    assert round(f1["r_hat"], 2) == 2.18 and round(f1["r_hat"], 4) == 2.1758
    assert f1["radii"][0] == 1.1 and f1["radii"][2] == 6.3
    # every circle gives [z^6] e^z (1+10z)^4; the saddle circle cancels least
    assert f1["integrals_agree"]
    canc = [c["cancellation"] for c in f1["circles"]]
    assert canc[1] < min(canc[0], canc[2])


def test_checks_and_report(tiny):
    _, result, text = tiny
    ch = result["checks"]
    assert ch["figure1"]["verdict"] == "PASS"
    assert ch["exact_paths"]["verdict"] == "PASS"
    assert ch["saddle-corrected"]["verdict"] in ("PASS", "FAIL", "NOT AVAILABLE")
    assert "PASS" in text or "FAIL" in text
    assert result["n_failed_checks"] >= 0


def test_cost_rows(tiny):
    _, result, _ = tiny
    for r in result["cost"]["rows"]:
        for m in ("exact", "exact-batched", "saddle"):
            v = r["methods"][m]
            assert v["status"] in ("ok", "stopped")
            assert v["seconds_per_particle"] > 0
        assert r["fastest"] in streit.COST_METHODS
        assert r["parts"]["newton_iterations"] >= 1
        assert r["exact_per_particle_vs_batched_max_abs_log"] < 1e-9


def test_rescaled_batch_matches_direct_calls():
    rng = np.random.default_rng(5)
    a, F = streit.draw_problems(rng, 4, 6, 5)
    res = streit._approximate(a, F, "saddle", n_check=0)
    direct = [log_mixed_derivative(0.0, a[t], F[t], "saddle") for t in range(5)]
    np.testing.assert_allclose(res["log"], direct, rtol=0, atol=1e-10)


def test_unknown_variant_is_reported_not_raised():
    rng = np.random.default_rng(1)
    a, F = streit.draw_problems(rng, 3, 4, 3)
    res = streit._approximate(a, F, "no-such-method")
    assert res["status"] == "not available" and res["log"] is None


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"trials": 1}, "trials must be >= 2"),
        ({"seed": -1}, "seed must be an integer >= 0"),
        ({"seed": 1.5}, "seed must be an integer >= 0"),
        ({"cost_N": ()}, "cost_N must be"),
        ({"cost_M": (0, 5)}, "cost_M must be"),
        ({"cost_N": (2.5,)}, "cost_N must be"),
        ({"particles": 0}, "particles must be >= 1"),
        ({"time_budget": 0}, "time_budget must be"),
        ({"time_budget": math.inf}, "time_budget must be"),
    ],
)
def test_bad_arguments_raise(kwargs, match, tmp_path):
    with pytest.raises(ValueError, match=match):
        streit.reproduce(True, out_dir=tmp_path, write=False, **kwargs)
    assert not any(tmp_path.iterdir())


def _fake_corrected(monkeypatch, fail_batched=False):
    """Stand in a "saddle-corrected" (eq. 30 divided by the Stirling factor) for the pipeline."""
    import jointtrack.saddle as js

    orig = js.log_mixed_derivative

    def fake(a0, a, F, method="exact"):
        if method != "saddle-corrected":
            return orig(a0, a, F, method)
        if fail_batched and np.ndim(F) == 3:
            raise js.SaddlePointError("batched call refused (test)")
        M = np.asarray(a).size
        return orig(a0, a, F, "saddle") - M * math.log(math.e / math.sqrt(2 * math.pi))

    monkeypatch.setattr(js, "log_mixed_derivative", fake)


def test_corrected_variant_runs_through_when_the_package_offers_it(monkeypatch):
    _fake_corrected(monkeypatch)
    result = streit.reproduce(
        True, write=False, trials=20, cost_N=(3,), cost_M=(4,), particles=5, time_budget=0.5
    )
    for c in result["table1"]:
        v = c["variants"]["saddle-corrected"]
        assert v["status"] == "ok" and abs(v["mean"] - 1.0) < 0.05
    assert result["checks"]["saddle-corrected"]["verdict"] in ("PASS", "FAIL")
    assert result["cost"]["rows"][0]["methods"]["saddle-corrected"]["status"] == "ok"


def test_a_failed_batch_falls_back_to_trial_by_trial(monkeypatch):
    _fake_corrected(monkeypatch, fail_batched=True)
    rng = np.random.default_rng(2)
    a, F = streit.draw_problems(rng, 3, 5, 4)
    res = streit._approximate(a, F, "saddle-corrected")
    assert res["status"] == "ok" and not res["batched"] and res["n_failed"] == 0
    assert "trial by trial" in res["message"]
    assert np.isfinite(res["log"]).all()


def test_cli_reproduce_streit_quick(tmp_path):
    from typer.testing import CliRunner

    from jointtrack.cli import app

    out = tmp_path / "streit"
    r = CliRunner().invoke(
        app, ["reproduce", "streit", "--quick", "--out", str(out), "--no-progress"]
    )
    assert r.exit_code == 0, r.output
    assert (out / "streit.json").exists()
    for name in ("figure1", "figure3", "figure4", "cost"):
        assert (out / f"streit-{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
