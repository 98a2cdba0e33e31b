"""Issue 22 item 18: ``jointtrack reproduce schaub`` — the process-noise reading, the
max-weight statistics over many seeds beside the paper's step, and an exit code that
reflects the self-checks (not the paper comparison)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from jointtrack.cli import app
from jointtrack.experiments import schaub
from jointtrack.identity.filterbank import IdentityBank
from jointtrack.models.motion import cv_transition

QUICK = ["reproduce", "schaub", "--quick", "--steps", "3", "--seeds", "2", "--no-progress"]


@pytest.fixture(scope="module")
def quick_std(tmp_path_factory):
    """One cheap CLI run with the std reading, shared by the tests that read its output."""
    out = tmp_path_factory.mktemp("schaub-std")
    r = CliRunner().invoke(app, [*QUICK, "--process-noise-reading", "std", "--out", str(out)])
    return r, json.loads((out / "schaub.json").read_text()) if r.exit_code == 0 else None


def test_process_noise_reading_option_is_labelled(quick_std):
    r, data = quick_std
    assert r.exit_code == 0, r.output
    text = " ".join(r.output.split())  # the console wraps long lines
    assert "process-noise reading: std" in text
    assert data["settings"]["process_noise_reading"] == "std"
    assert "c^2" in data["settings"]["process_noise_reading_meaning"]
    assert all(res["process_noise_reading"] == "std" for res in data["examples"].values())
    # quick says it used fewer seeds than the full run
    assert "quick: fewer seeds and steps than the full run" in text
    assert data["settings"]["seeds"] == [0, 1]


def test_paper_step_printed_beside_both_readings_with_quartiles(quick_std):
    r, data = quick_std
    assert r.exit_code == 0, r.output
    for ex in ("1", "2", "3"):
        by_reading = data["maxweight_statistics"][ex]
        assert set(by_reading) == {"variance", "std"}
        for reading, c in by_reading.items():
            assert c["process_noise_reading"] == reading
            assert c["paper_step"] == schaub.PAPER["maxweight_correct_from"][ex]
            assert len(c["quartiles"]) == 3 and c["seeds"] == 2
            assert len(c["stays_right_from"]) == 2
    text = " ".join(r.output.split())
    assert "variance (Σ_P = c I)" in text and "std (Σ_P = c² I)" in text
    assert "quartiles 25 / 50 / 75 %" in text
    for ex, paper in schaub.PAPER["maxweight_correct_from"].items():
        assert f"example {ex}: paper's max-weight step {paper}" in text
    # the paper comparison is measured, never a FAIL
    assert "FAIL" not in r.output and "PASS" in r.output


def test_unknown_reading_is_a_clear_error(tmp_path):
    r = CliRunner().invoke(
        app, [*QUICK, "--process-noise-reading", "sigma", "--out", str(tmp_path)]
    )
    assert r.exit_code == 2
    assert "--process-noise-reading must be one of variance, std" in " ".join(r.output.split())
    with pytest.raises(ValueError, match="process_noise_reading must be one of"):
        schaub.example_setup(3, "stdev")


@pytest.mark.parametrize("example", [1, 3])
@pytest.mark.parametrize("reading", ["variance", "std"])
def test_filter_bank_predicts_with_c_or_c_squared(example, reading):
    # The bank's own prediction: P(t + dt) − F P Fᵀ is the Q it used; compare it with
    # G Σ_P Gᵀ built here from the tables' numbers, Σ_P = c I (variance) or c² I (std).
    setup = schaub.example_setup(example, reading)
    db = setup["database"]
    bank = IdentityBank(db)
    if db.attribute_dim:  # examples 1-2: the attribute unobserved (infinite variance)
        bank.add_track("t", 0.0, [3.0, -1.0, np.nan], np.diag([4.0, 4.0, math.inf]))
    else:
        bank.add_track("t", 0.0, [3.0, -1.0], np.eye(2) * 4.0)
    fb = bank.tracks["t"]
    P0 = fb.cov.copy()
    dt = 2.0
    fb.predict(dt)
    F = cv_transition(dt, 2)
    Q_used = fb.cov - F @ P0 @ F.T
    G = np.vstack([dt * dt / 2 * np.eye(2), dt * np.eye(2)])
    for i in range(schaub.N_IDENTITIES):
        c = (i // 2) if example == 1 else (1 if i < 60 else 2 if i < 90 else 3)
        sigma = c if reading == "variance" else c * c
        np.testing.assert_allclose(
            Q_used[db.classes[i]], sigma * G @ G.T, rtol=1e-12, atol=1e-9, err_msg=f"identity {i}"
        )


def _run_cli(tmp_path):
    return CliRunner().invoke(app, [*QUICK, "--out", str(tmp_path)])


def test_failing_q_self_check_exits_nonzero(tmp_path, monkeypatch):
    monkeypatch.setattr(schaub, "_q_matches_table", lambda example, reading: False)
    r = _run_cli(tmp_path)
    assert r.exit_code == 1, r.output
    assert "FAIL the filter bank's Q" in " ".join(r.output.split())


def test_failing_reference_self_check_exits_nonzero(tmp_path, monkeypatch):
    import jointtrack.permanent.reference as reference

    real = reference.reference_marginals

    def off_by_a_little(*args, **kwargs):
        return real(*args, **kwargs) + 1e-6

    monkeypatch.setattr(reference, "reference_marginals", off_by_a_little)
    r = _run_cli(tmp_path)
    assert r.exit_code == 1, r.output
    assert "FAIL exact agrees with the rational reference" in " ".join(r.output.split())


@settings(max_examples=60, deadline=None)
@given(st.lists(st.booleans(), min_size=1, max_size=30))
def test_stays_right_from_is_the_first_step_of_the_final_right_run(right):
    got = schaub._stays_right_from(right)
    # brute force: the smallest 1-based k with right[k-1:] all true
    expect = next((k + 1 for k in range(len(right)) if all(right[k:])), None)
    assert got == expect
    kl = [0.0 if r else math.inf for r in right]
    assert schaub._correct_from(kl) == expect


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(st.none(), st.integers(1, 500)), min_size=1, max_size=40))
def test_quartiles_are_sample_order_statistics_with_never_last(steps):
    q = schaub._quartiles(steps)
    x = sorted(math.inf if v is None else v for v in steps)
    n = len(x)
    # inverted CDF: the smallest sample with at least a share p of samples ≤ it
    for p, got in zip((0.25, 0.5, 0.75), q, strict=True):
        expect = next(v for v in x if sum(w <= v for w in x) >= p * n)
        assert got == expect


def test_paper_comparison_counts():
    stats = {
        "example": 2,
        "steps": 12,
        "seeds": [0, 1, 2, 3],
        "process_noise_reading": "std",
        "stays_right_from": [3, 9, 11, None],
        "right": [
            [k >= 2 for k in range(12)],
            [k >= 8 for k in range(12)],
            [k in (8,) or k >= 10 for k in range(12)],
            [k == 8 for k in range(12)],
        ],
    }
    c = schaub.paper_comparison(stats)  # paper: step 9
    assert c["paper_step"] == 9
    assert c["right_at_paper_step"] == 4
    assert c["share_settled_by_paper_step"] == 0.5
    assert c["paper_is_ordinary"] is True
    assert c["never_settles"] == 1
    assert c["quartiles"] == [3.0, 9.0, 11.0]


def test_batched_statistics_match_single_seed_runs():
    # all seeds in one filter bank give each seed's own max-weight answers
    n_steps = 6
    st_ = schaub.maxweight_statistics(3, n_steps, [0, 1], "std")
    for j, seed in enumerate((0, 1)):
        r = schaub.run_example(3, n_steps, seed, reference_every=0, process_noise_reading="std")
        assert [v == 0.0 for v in r["max_kl"]["maxweight"]] == st_["right"][j]
        assert r["maxweight_correct_from"] == st_["stays_right_from"][j]
