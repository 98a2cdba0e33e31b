"""Issue 22, items 3, 4, 9 and 15: giant clusters, memory, coincident returns, complex masks.

* past every budget a cluster goes to sparse LBP on its gated pairs, then per-track
  PDA; a tracker step never fails for a cluster's size, and the tier is counted;
* a 20,000-detection scan is tracked within 2 GiB (no N × M matrix of a giant
  cluster, no quadratic pair list for identical detections);
* exactly coincident returns of a scan are one return;
* a complex gate mask is refused.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import warnings
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import jointtrack
from brute import brute_assignment
from jointtrack.association.budget import budgeted_marginals, fallback_pair_marginals
from jointtrack.association.clustering import clusters
from jointtrack.association.lbp import lbp_marginals, lbp_pair_marginals
from jointtrack.errors import CoincidentReturnsWarning
from jointtrack.trackers import JPDATracker, TrackerConfig

#: the package under test (CI: the installed one), not the checkout's src/: a subprocess
#: then loads the kernels numba has cached for it instead of compiling them all again
#: into a cold src/ cache under the 2 GiB cap (CI time: ≈ 90 CPU-s)
SRC = Path(jointtrack.__file__).resolve().parents[1]


def exact_beta(L, miss) -> np.ndarray:
    """β = [null | P] of the cluster, from the shared rational brute force (tiny clusters)."""
    _, P, Pn = brute_assignment(L, miss)
    return np.column_stack([np.array(Pn, float), np.array(P, float)])


# ------------------------------------------------------------------ item 3: the tiers


@st.composite
def forests(draw):
    """A cycle-free gating graph (BP is exact there) with values over many magnitudes.

    Each track gets a scale 2^e (e from −700 to 0) and its weights (miss and
    likelihood ratios, zeros allowed) within 2^±300 of it: values from subnormal
    (2^-1001) to 2^300 ≈ 2e90 across the cluster. The sparse tier's messages are
    split floats (no weight scaled or floored), so it is exact on any such forest
    (``tests/test_lbp_sparse`` draws the weights themselves).
    """
    n = draw(st.integers(1, 4))
    m = draw(st.integers(1, 5))
    L = np.zeros((n, m))
    # a forest: each new edge joins a track and a measurement not yet connected
    parent = list(range(n + m))

    def root(x):
        while parent[x] != x:
            x = parent[x]
        return x

    edges = draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, m - 1)), max_size=8))
    e = draw(st.lists(st.integers(-700, 0), min_size=n, max_size=n))
    for i, j in edges:
        a, b = root(i), root(n + j)
        if a == b:
            continue
        parent[a] = b
        u = draw(st.floats(-300, 300))
        L[i, j] = np.ldexp(2.0**u, e[i])
    miss = np.array(
        [
            np.ldexp(draw(st.floats(0.5, 1.0)), e[i]) * draw(st.sampled_from([1.0, 2.0**-300]))
            for i in range(n)
        ]
    )
    return L, miss


@settings(max_examples=40, deadline=None)
@given(forests())
def test_sparse_lbp_tier_is_exact_on_forests(case):
    """Against rational enumeration: |Δβ| ≤ 1e-9 on cycle-free gating graphs."""
    L, miss = case
    rows, cols = np.nonzero(L)
    beta0, pair_beta, info = lbp_pair_marginals(rows, cols, L[rows, cols], miss, L.shape[1])
    assert info.converged
    ref = exact_beta(L, miss)
    np.testing.assert_allclose(beta0, ref[:, 0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(pair_beta, ref[rows, cols + 1], rtol=0, atol=1e-9)


def test_sparse_lbp_tier_on_loopy_clusters_within_stated_error():
    """Dense 5×10 clusters, L = 5·U[0,1], miss = 0.1 (lbp_marginals' stated case):
    |Δβ| ≤ 0.03 against the exact marginals, and the dense method's BP fixed point."""
    from jointtrack.association.exact import exact_marginals

    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(40):
        L = 5.0 * rng.random((5, 10))
        miss = np.full(5, 0.1)
        rows, cols = np.nonzero(L)
        order = rng.permutation(rows.size)  # any pair order
        rows, cols = rows[order], cols[order]
        b0, pb, _ = lbp_pair_marginals(rows, cols, L[rows, cols], miss, 10)
        ref = exact_marginals(L, miss)
        worst = max(worst, np.abs(b0 - ref[:, 0]).max(), np.abs(pb - ref[rows, cols + 1]).max())
        dense, _ = lbp_marginals(L, miss, tol=1e-13)
        b0t, pbt, _ = lbp_pair_marginals(rows, cols, L[rows, cols], miss, 10, tol=1e-13)
        np.testing.assert_allclose(b0t, dense[:, 0], rtol=0, atol=1e-10)
        np.testing.assert_allclose(pbt, dense[rows, cols + 1], rtol=0, atol=1e-10)
    assert worst <= 0.03


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.one_of(st.just(0.0), st.floats(5e-324, 1e300, allow_subnormal=True)),
        min_size=1,
        max_size=6,
    ),
    st.one_of(st.just(0.0), st.just(1.0), st.floats(5e-324, 1.0, allow_subnormal=True)),
)
def test_pda_tier_is_exact_for_one_track(values, miss):
    """The last tier (per-track PDA) on a one-track cluster equals exact JPDA."""
    L = np.array([values])
    if miss == 0 and not (L > 0).any():
        return  # no feasible event
    rows, cols = np.nonzero(L)
    res = fallback_pair_marginals(rows, cols, L[rows, cols], [miss], L.shape[1], max_pairs=0)
    assert res.method == ("pda" if rows.size else "lbp-sparse")
    tot = Fraction(miss) + sum(Fraction(v) for v in values)
    expect0 = float(Fraction(miss) / tot)
    expect = [float(Fraction(float(v)) / tot) for v in L[rows, cols]]
    np.testing.assert_allclose(res.beta0, [expect0], rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(res.pair_beta, expect, rtol=1e-12, atol=1e-300)


def test_dense_lbp_refusal_goes_to_the_sparse_tier():
    """Issue: marginals(ones((2001, 2000)), .1, method='lbp') refused and the step raised.

    Same size here (the dense LBP refuses N + M > 4000), gated on a chain (track i
    gates measurements i−1 and i) so that the test stays fast and, the gating graph
    being a tree, sparse LBP is exact: |Δβ| ≤ 1e-9 against the exact method.
    """
    from jointtrack.association.exact import exact_marginals

    n, m = 2001, 2000
    i = np.arange(n)[:, None]
    j = np.arange(m)[None, :]
    L = np.where((j == i) | (j == i - 1), 2.0, 0.0)
    miss = np.full(n, 0.1)
    ref = exact_marginals(L, miss)
    for method, approximation in (("lbp", "lbp"), ("exact", "lbp")):
        res = budgeted_marginals(L, miss, method=method, approximation=approximation, max_tracks=16)
        assert res.method == "lbp-sparse"
        assert "lbp refused" in res.reason and "4000" in res.reason
        np.testing.assert_allclose(res.beta, ref, rtol=0, atol=1e-9)


def test_tracker_step_on_a_giant_cluster_returns_with_the_tier_counted(monkeypatch):
    """A cluster above the dense budget is solved on its pairs; the step returns."""
    import jointtrack.trackers.base as jpda  # the shared layer holds the dense budget

    monkeypatch.setattr(jpda, "DENSE_MAX_ENTRIES", 50)
    rng = np.random.default_rng(1)
    trk = JPDATracker(TrackerConfig(clutter_density=1e-4))
    x0 = np.zeros((12, 4))
    x0[:, 0] = np.arange(12) * 5.0  # gates overlap along a line: one cluster
    trk.start_tracks(x0, np.diag([25.0, 25.0, 4.0, 4.0]), time=0.0)
    seen = []
    trk.on_cluster = seen.append
    res = trk.step(1.0, x0[:, :2] + rng.normal(0, 1, (12, 2)))
    assert "lbp-sparse" in res.cluster_methods
    k = res.cluster_methods.index("lbp-sparse")
    assert res.cluster_fallbacks[k].startswith("dense_budget")
    assert res.n_fallbacks >= 1 and len(res.ids) == 12
    rec = [r for r in seen if r.method == "lbp-sparse"][0]
    assert rec.L.shape[0] * rec.L.shape[1] > 50
    np.testing.assert_allclose(np.asarray(rec.beta.sum(axis=1)).ravel(), 1.0, rtol=1e-12)


def test_run_metrics_count_the_tier_of_each_fallback(monkeypatch, tmp_path):
    import jointtrack.trackers.base as jpda  # the shared layer holds the dense budget
    from jointtrack.experiments.run import run_detections
    from jointtrack.scenarios import crossing

    monkeypatch.setattr(jpda, "DENSE_MAX_ENTRIES", 1)
    det = crossing(3, n_scans=12).as_detections()
    run_detections(det, {"clutter_density": 1e-4}, tmp_path, plots=False)
    assoc = json.loads((tmp_path / "metrics.json").read_text())["association"]
    tiers = assoc["fallback_tiers"]
    assert sum(v for k, v in tiers.items() if k.startswith("lbp-sparse")) >= 1
    assert sum(tiers.values()) == sum(assoc["fallbacks"].values())
    assert any(k.startswith("dense_budget") for k in assoc["fallbacks"])
    assert assoc["coincident_returns"] == 0


# ------------------------------------------------------------------ item 4: memory

_MEMORY_SCRIPT = textwrap.dedent(
    """
    import resource, sys, warnings
    cap = 2 * 2**30
    resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
    import numpy as np
    from jointtrack.trackers import JPDATracker, TrackerConfig

    warnings.simplefilter("ignore")
    rng = np.random.default_rng(0)
    for kind in ("uniform", "identical"):
        trk = JPDATracker(TrackerConfig())
        x0 = np.zeros((5, 4))
        x0[:, :2] = rng.uniform(0, 1e4, (5, 2))
        trk.start_tracks(x0, np.diag([100.0, 100, 100, 100]), time=0.0)
        for k in (1, 2):  # the second scan meets the 20,000 tracks the first started
            if kind == "uniform":
                z = rng.uniform(0, 1e4, (20000, 2))
            else:
                z = np.tile(x0[0, :2] + 10.0 * k, (20000, 1))
            res = trk.step(float(k), z)
        print(kind, ",".join(sorted(set(res.cluster_methods))), res.n_coincident)
    print("rss", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
    """
)


def test_20000_detection_scans_fit_in_2_gib():
    """Under RLIMIT_AS = 2 GiB: uniform 1e4 m square (a ~20,000-track cluster on the
    second scan) and 20,000 identical detections both complete."""
    env = {"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin"}
    out = subprocess.run(
        [sys.executable, "-c", _MEMORY_SCRIPT],
        capture_output=True,
        text=True,
        timeout=240,
        env=env,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    lines = dict(line.split(" ", 1) for line in out.stdout.strip().splitlines())
    assert "lbp-sparse" in lines["uniform"]  # the giant cluster was solved on its pairs
    assert lines["identical"].split()[-1] == "19999"
    assert int(lines["rss"]) < 2 * 2**30


def test_near_coincident_returns_degrade_instead_of_listing_all_pairs(monkeypatch, caplog):
    """Returns piled on one spot (not identical): the gate and merge searches count
    their pairs first and keep each track's nearest ones past the budget (budgets
    lowered here so that 3,000 returns stand for 20,000)."""
    import logging

    import jointtrack.association.gating as gating
    import jointtrack.trackers.existence as existence

    monkeypatch.setattr(gating, "MAX_CANDIDATES", 2**16)
    monkeypatch.setattr(existence, "_MAX_PAIRS", 2**16)
    rng = np.random.default_rng(3)
    trk = JPDATracker(TrackerConfig())
    trk.start_tracks([[0.0, 0.0, 1.0, 0.0]], np.diag([100.0, 100, 100, 100]), time=0.0)
    with caplog.at_level(logging.WARNING, logger="jointtrack.association"):
        for k in (1, 2):
            res = trk.step(float(k), rng.normal(0, 0.01, (3000, 2)) + [k, 0.0])
    assert "nearest returns" in caplog.text
    assert res.n_measurements == 3000 and res.cluster_methods  # the step returned


# ------------------------------------------------------------------ item 9: coincident returns


def test_500_identical_returns_are_one_return():
    """A stuck detector repeating the target's return 500 times: one confirmed track."""
    rng = np.random.default_rng(2)
    trk = JPDATracker(TrackerConfig(clutter_density=1e-5))
    for k in range(8):
        pos = np.array([100.0 + 10.0 * k, 50.0]) + rng.normal(0, 1, 2)
        with pytest.warns(CoincidentReturnsWarning, match="499 of 500"):
            res = trk.step(float(k), np.repeat(pos[None], 500, axis=0))
        assert res.n_coincident == 499
    assert len(res.ids) == 1 and res.n_tentative == 0
    assert np.linalg.norm(res.x[0, :2] - pos) < 10.0


def test_doubled_detections_file_gives_the_same_tracks(tmp_path):
    from jointtrack.io import read_detections
    from jointtrack.io.detections import Detections, write_detections
    from jointtrack.scenarios import GENERATORS

    det = GENERATORS["crossing"](4).as_detections()
    doubled = Detections(
        times=det.times,
        scans=tuple(np.concatenate([s, s]) for s in det.scans),
        sensors=None,
        dim=det.dim,
        source=None,
    )
    histories = []
    for d, fname in ((det, "once.csv"), (doubled, "twice.csv")):
        d = read_detections(write_detections(d, tmp_path / fname))
        trk = JPDATracker(TrackerConfig(dim=d.dim, clutter_density=1e-4, seed=0))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", CoincidentReturnsWarning)
            for t, z in zip(d.times[:30], d.scans[:30], strict=False):
                trk.step(float(t), z)
        histories.append(trk.history())
    a, b = histories
    assert len(a.track_id) > 0
    np.testing.assert_array_equal(a.track_id, b.track_id)
    np.testing.assert_array_equal(a.time, b.time)
    np.testing.assert_array_equal(a.x, b.x)


def test_returns_that_differ_are_kept():
    trk = JPDATracker(TrackerConfig(clutter_density=1e-4))
    z = np.array([[0.0, 0.0], [0.0, 1e-9], [0.0, 0.0], [5.0, 0.0]])
    with pytest.warns(CoincidentReturnsWarning, match="1 of 4"):
        res = trk.step(0.0, z)
    assert res.n_coincident == 1 and res.n_measurements == 3
    with warnings.catch_warnings():
        warnings.simplefilter("error", CoincidentReturnsWarning)
        assert trk.step(1.0, z[[0, 1, 3]]).n_coincident == 0


# ------------------------------------------------------------------ item 15: complex masks


@pytest.mark.parametrize(
    "mask",
    [np.array([[1j, 0.0]]), [[1 + 0j, 0]], [[True, 2]], [[10**400]], [["a"]], [[-1.0]]],
)
def test_clusters_refuses_bad_masks_by_name(mask):
    with pytest.raises(ValueError, match="mask"):
        clusters(mask)


def test_lbp_pair_marginals_refuses_bad_input_by_name():
    with pytest.raises(ValueError, match="L_values"):
        lbp_pair_marginals([0], [0], [1j], [0.5], 1)
    with pytest.raises(ValueError, match="twice"):
        lbp_pair_marginals([0, 0], [0, 0], [1.0, 1.0], [0.5], 1)
    with pytest.raises(ValueError, match="cols"):
        lbp_pair_marginals([0], [3], [1.0], [0.5], 1)
    with pytest.raises(ValueError, match="miss"):
        lbp_pair_marginals([0], [0], [1.0], [1.5], 1)


def test_sparse_lbp_needs_no_floor_where_per_track_scaling_had_one():
    """Per-track power-of-two scaling could not keep a miss weight 2^-400 below its
    track's likelihood in range and raised it to 2^-400 (β 2× off, reported as
    "floored"). The split-float messages take the cluster as given: exact β, no note."""
    L = np.array([[1.0], [2.0**100], [2.0**71], [1.0]])
    miss = np.array([1.0, 2.0**-300, 2.0**-300, 1.0])
    rows, cols = np.nonzero(L)
    ref = exact_beta(L, miss)
    beta0, pair_beta, info = lbp_pair_marginals(rows, cols, L[rows, cols], miss, 1)
    assert info.converged
    np.testing.assert_allclose(beta0, ref[:, 0], rtol=1e-12, atol=0)
    np.testing.assert_allclose(pair_beta, ref[rows, cols + 1], rtol=1e-12, atol=0)
    res = fallback_pair_marginals(rows, cols, L[rows, cols], miss, 1, reason="test")
    assert (res.method, res.reason) == ("lbp-sparse", "test")
