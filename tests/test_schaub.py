"""Schaub's examples (``jointtrack reproduce schaub``) and the identity pipeline end to end."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from jointtrack.cli import app
from jointtrack.experiments import schaub
from jointtrack.identity import deconflict
from jointtrack.identity.database import Identity, IdentityDatabase
from jointtrack.identity.filterbank import IdentityBank
from jointtrack.identity.metrics import asymptotic_matrix, max_kl

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_example_setups_follow_tables_i_to_iii():
    s1 = schaub.example_setup(1)
    db = s1["database"]
    assert db.n_identities == 100 and db.n_classes == 100  # unique attributes A_i = i
    assert s1["n_observed"] == 6 and s1["n_hidden"] == 94
    # 0-based: attribute observed on tracks 1, 3, 5 (each kinematic pair has one seen twin)
    assert [math.isinf(v) for v in s1["attribute_variance"]] == [True, False] * 3
    np.testing.assert_array_equal(db.process_noise[5], 2.0 * np.eye(2))  # ⌊5/2⌋ = 2
    assert all(v == 4.0 for v in schaub.example_setup(2)["attribute_variance"])
    s3 = schaub.example_setup(3)
    assert s3["database"].class_counts.tolist() == [60, 30, 10]
    assert s3["n_observed"] == 100 and s3["n_hidden"] == 0
    np.testing.assert_array_equal(s3["database"].process_noise[2], 3.0 * np.eye(2))
    with pytest.raises(ValueError, match="example must be 1, 2 or 3"):
        schaub.example_setup(4)


@pytest.mark.parametrize("example", [1, 3])
def test_short_run_agrees_with_rational_reference(example):
    r = schaub.run_example(example, 6, seed=1, reference_every=2)
    assert r["reference_steps_checked"] == 3
    assert r["reference_max_abs_error"] <= 1e-10
    for m in schaub.METHODS:
        assert len(r["max_kl"][m]) == 6
        assert all(v >= 0 for v in r["max_kl"][m])
    assert r["plotted_kl"] == ("class-aggregated" if example == 3 else "per identity")


def test_local_stalls_at_ln2_where_the_permanent_resolves():
    # Two kinematic twins that differ only in the static attribute; the attribute is
    # unobserved on track 0 and observed on track 1 (Schaub's example 1 in miniature):
    # track-level identification stays at ½/½ on track 0 (KL = ln 2 for ever), the
    # permanent takes track 1's evidence and resolves track 0 too.
    db = IdentityDatabase([Identity("a", 1.0, attribute=0.0), Identity("b", 1.0, attribute=6.0)])
    rng = np.random.default_rng(3)
    bank = IdentityBank(db)
    x = np.zeros((2, 2))
    R_unseen = np.diag([4.0, 4.0, math.inf])
    R_seen = np.diag([4.0, 4.0, 4.0])
    attrs = np.array([0.0, 6.0])
    for k in range(30):
        x += rng.standard_normal((2, 2))  # some motion; the models are identical anyway
        z = np.column_stack(
            [x + 2 * rng.standard_normal((2, 2)), attrs + 2 * rng.standard_normal(2)]
        )
        z[0, 2] = np.nan  # not measured on track 0
        meas = {0: (z[0], R_unseen), 1: (z[1], R_seen)}
        if k == 0:
            for key, (zz, R) in meas.items():
                bank.add_track(key, 0.0, zz, R)
        else:
            bank.step(float(k), meas)
    log_A, log_b, rows, cols = bank.log_M()
    V = asymptotic_matrix([0, 1], db.classes)
    local = deconflict(log_M=log_A, row_counts=rows, col_counts=cols, method="local")
    exact = deconflict(log_M=log_A, row_counts=rows, col_counts=cols)
    assert log_A[0, 0] == log_A[0, 1]  # the twins' filters are identical on track 0
    np.testing.assert_allclose(local.P[0], [0.5, 0.5], rtol=1e-14)
    assert max_kl(V, local.P) == pytest.approx(math.log(2), abs=1e-12)
    assert max_kl(V, exact.P) < 1e-6


def test_cli_reproduce_schaub_writes_json_and_plots(tmp_path):
    out = tmp_path / "s"
    r = CliRunner().invoke(
        app,
        [
            "reproduce",
            "schaub",
            *("--quick", "--steps", "5", "--seeds", "2", "--out", str(out), "--no-progress"),
        ],
    )
    assert r.exit_code == 0, r.output
    assert "vs the paper" in r.output and "150" in r.output and "270" in r.output
    data = json.loads((out / "schaub.json").read_text())
    assert set(data["examples"]) == {"1", "2", "3"}
    assert data["settings"]["steps"] == {"1": 5, "2": 5, "3": 5}
    ex3 = data["examples"]["3"]
    assert ex3["plotted_kl"] == "class-aggregated"
    assert len(ex3["max_kl"]["exact"]) == 5
    assert data["paper"]["seconds_per_step"]["3"] == 0.270
    for ex in (1, 2, 3):
        png = out / f"schaub-example{ex}.png"
        assert png.read_bytes()[:8] == PNG_MAGIC


def test_cli_reproduce_schaub_bad_options(tmp_path):
    r = CliRunner().invoke(app, ["reproduce", "schaub", "--steps", "0", "--out", str(tmp_path)])
    assert r.exit_code == 2
    assert "--steps must be >= 1" in r.output
