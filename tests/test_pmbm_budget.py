"""Issue 31, defect 2: the PMBM tracker's ranking has a work budget with cheaper tiers.

Murty's ranking of a cluster's ⌈max_hypotheses · w_h⌉ best events costs about
k · n² · (n + m) for n Bernoullis and m returns: a 3 m blob of K returns cost
1.4 s of CPU at K = 100, 174 s at K = 400, and 2,000 returns did not finish three
scans in 15 minutes. ``PMBMConfig.max_ranking_work`` bounds the estimated work of
each cluster; past it the cluster is ranked with fewer events per hypothesis
(``"murty-truncated"``) or merged into one Bernoulli per track, PMB style
(``"pmb-<tier>"``). The tests check

* within the budget, exactly the results without it (and the exact ranked
  enumeration: ``tests/test_pmbm_hypotheses.py`` runs with the default budget);
* past it, against exact rational enumeration: a truncated cluster keeps each
  prior hypothesis's best min(⌈K w_h⌉, cap) events; a merged cluster is the PMB
  update of the cluster's PMB-projected prior (mixture moments computed here);
* the bound itself: no Murty call and no sparse-LBP call of a burst exceeds the
  budget's estimate, each fallback is named in ``ScanResult``, counted in
  ``fallback_counts``, logged once at WARNING and tallied by ``jointtrack run``;
* the setting: validated, and a state saved before it existed loads with no
  budget and continues exactly.
"""

from __future__ import annotations

import inspect
import json
import logging
import re
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, event, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import jointtrack.association.budget as budget_module
import jointtrack.trackers.pmbm as pmbm_module
from jointtrack.cli import app
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker
from jointtrack.trackers.state_io import read_state, write_state
from state_checks import assert_same_state
from test_pmbm_hypotheses import (
    _check_against,
    _children,
    _close,
    _enumerate,
    _top,
    _tracker,
    pmbm_prior,
)

BURST = dict(clutter_density=1e-5, measurement_noise=1.0, process_noise=1.0, birth_density=1e-6)


def _blob(kind, K, scans=3, seed=0, **config):
    """The issue's burst: ``scans`` scans of K returns N(0, 3²) in each axis."""
    trk = kind(PMBMConfig(**BURST, **config))
    rng = np.random.default_rng(seed)
    results = [trk.step(float(t), rng.normal(0, 3, (K, 2))) for t in range(scans)]
    return trk, results


def _state_equal(a, b):
    sa, sb = a.state_dict(), b.state_dict()
    for k, v in sa.items():
        if isinstance(v, np.ndarray):
            np.testing.assert_array_equal(v, sb[k], err_msg=k)


# ------------------------------------------------------------------------ the setting


@pytest.mark.parametrize("value", [0, -1, 2**62 + 1, 10**400, 1.5, 1e8, True, 1j, "1", [1]])
def test_bad_budgets_name_the_field(value):
    with pytest.raises(ValueError, match="max_ranking_work"):
        PMBMConfig(max_ranking_work=value)


def test_budget_takes_integers_and_none():
    assert PMBMConfig(max_ranking_work=np.int64(5)).max_ranking_work == 5
    assert type(PMBMConfig(max_ranking_work=np.int64(5)).max_ranking_work) is int
    assert PMBMConfig(max_ranking_work=None).max_ranking_work is None
    assert PMBMConfig.from_dict({"max_ranking_work": 7}).max_ranking_work == 7


def test_state_saved_before_the_budget_existed_continues_exactly(tmp_path):
    """Its configuration has no ``max_ranking_work``: it loads with None (no budget),
    the ranking its run had, not the new default."""
    trk, _ = _blob(PMBMTracker, 60, scans=2, max_ranking_work=None)
    arrays, config, scalars, rng = read_state(trk.save(tmp_path / "new.npz"))
    del config["max_ranking_work"]
    old = write_state(tmp_path / "old.npz", arrays, config, scalars, rng)
    loaded = PMBMTracker.load(old)
    assert loaded.config.max_ranking_work is None
    z = np.random.default_rng(7).normal(0, 3, (60, 2))
    a, b = trk.step(2.0, z), loaded.step(2.0, z)
    assert a.cluster_methods == b.cluster_methods == ["murty"]  # unbudgeted: full ranking
    np.testing.assert_array_equal(a.x, b.x)
    _state_equal(trk, loaded)
    # a complete saved configuration is still required for every other setting
    del config["max_hypotheses"]
    bad = write_state(tmp_path / "bad.npz", arrays, config, scalars, rng)
    with pytest.raises(ValueError, match="max_hypotheses"):
        PMBMTracker.load(bad)


# ------------------------------------------------------------- within the budget: as before


def test_within_the_budget_the_results_are_those_without_it():
    """A crossing with clutter: every cluster ranked in full, bit-identical to no budget."""
    from jointtrack.scenarios import crossing

    sc = crossing(seed=3)
    runs = []
    for budget in (PMBMConfig.max_ranking_work, None):
        cfg = PMBMConfig(process_noise=0.05, measurement_noise=float(sc.R[0, 0]), p_d=sc.p_d,
                         clutter_density=sc.clutter_density, max_speed=15.0,
                         birth_density=1e-6, max_ranking_work=budget)  # fmt: skip
        trk = PMBMTracker(cfg)
        results = [trk.step(sc.times[k], sc.detections[k]) for k in range(len(sc.times))]
        runs.append((trk, results))
    (a, ra), (b, rb) = runs
    methods = [m for r in ra for m in r.cluster_methods]
    assert methods and set(methods) == {"murty"}  # multi-track clusters, none past the budget
    assert not any(f for r in ra for f in r.cluster_fallbacks)
    for x, y in zip(ra, rb, strict=True):
        np.testing.assert_array_equal(x.ids, y.ids)
        np.testing.assert_array_equal(x.x, y.x)
        np.testing.assert_array_equal(x.existence, y.existence)
    _state_equal(a, b)
    assert a.fallback_counts == {}


# ------------------------------------------------------------------- past the budget: exact


def _cap(result) -> int | None:
    (reason,) = result.cluster_fallbacks
    found = re.search(r"ranked at most (\d+) per hypothesis", reason)
    return int(found.group(1)) if found else None


def _merged_prior(sc):
    """Each track's PMB projection over the prior hypotheses (r, mean, cov), by hand."""
    w = np.asarray(sc["w"], float)
    out = []
    for t in range(sc["T"]):
        comps = [(w[h] * sc["r"][s], sc["x"][s], sc["P"][s])
                 for h, row in enumerate(sc["hyp"]) if (s := row[t]) >= 0]  # fmt: skip
        if not comps:
            continue
        r = sum(c for c, _, _ in comps)
        mean = sum(c * x for c, x, _ in comps) / r
        cov = sum(c * (P + np.outer(x - mean, x - mean)) for c, x, P in comps) / r
        out.append((t, r, mean, 0.5 * (cov + cov.T)))
    return out


@settings(max_examples=80, deadline=None)
@given(sc=pmbm_prior(), K=st.integers(2, 12), extra=st.integers(0, 900))
def test_past_the_budget_the_tiers_are_exact(sc, K, extra):
    """One cluster (p_g = 1), a budget around its ranking's cost: every tier is reached.

    * full ranking: each hypothesis's ⌈K w_h⌉ best events (the exact enumeration);
    * truncated to ``cap``: each hypothesis's min(⌈K w_h⌉, cap) best events, then the
      K best — exact as well, only fewer;
    * merged: one hypothesis whose Bernoullis are PMBTracker's update of the PMB
      projection of the prior (r = Σ_h w_h r_h, the mixture's moments).
    """
    # each distinct tuple's set-up, and some: the tiers' thresholds
    budget = pmbm_module._TUPLE_WORK * len(sc["hyp"]) + extra
    # duplicate_distance 0: the PMB step it is compared with keeps every Bernoulli
    trk = _tracker(sc, p_g=1.0, max_hypotheses=K, max_ranking_work=budget, duplicate_distance=0.0)
    k_h = np.maximum(1, np.ceil(K * trk.hypothesis_weights())).astype(int)
    res = trk.step(0.0, sc["z"])
    # no record: no tuple with two Bernoullis to rank, and within the budget
    (method,) = res.cluster_methods or ["murty"]
    assert len(res.cluster_fallbacks) == len(res.cluster_methods)
    event(method.split("-")[0] + ("-truncated" if method.endswith("truncated") else ""))
    if method.startswith("pmb-"):
        assert res.cluster_fallbacks[0].startswith("ranking_merged: ")
        assert trk.n_hypotheses == 1
        prior = _merged_prior(sc)
        pmb = PMBTracker(trk.config)
        pmb.ids = np.array([t + 1 for t, *_ in prior], np.int64)
        pmb.existence = np.array([min(r, 1.0) for _, r, _, _ in prior])
        pmb.x = np.array([m for *_, m, _ in prior])
        pmb.P = np.array([c for *_, c in prior])
        pmb.reported = np.zeros(len(prior), bool)
        pmb.born, pmb.report_count = np.zeros(len(prior)), np.zeros(len(prior))
        pmb.next_id = sc["T"] + 1
        pmb.step(0.0, sc["z"])
        s = trk.hyp[0][trk.hyp[0] >= 0]
        got = {int(trk.track_ids[trk.sth_track[i]]): i for i in s}
        want = {int(i): k for k, i in enumerate(pmb.ids)}
        assert got.keys() == want.keys()
        for tid, i in got.items():
            k = want[tid]
            assert abs(trk.sth_r[i] - pmb.existence[k]) <= 1e-12 * pmb.existence[k]
            np.testing.assert_allclose(trk.sth_x[i], pmb.x[k], rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(trk.sth_P[i], pmb.P[k], rtol=1e-9, atol=1e-9)
        return
    cap = None
    if method == "murty-truncated":
        cap = _cap(res)
        assert cap is not None and 2 <= cap < k_h.max()
    else:
        assert method == "murty" and not any(res.cluster_fallbacks)
    for kids in _children(sc).values():  # the tracker's STHs are told apart by their moments
        for a in range(len(kids)):
            for b in range(a):
                assume(not (_close(kids[a][2], kids[b][2]) and _close(kids[a][3], kids[b][3])))
    per_h = [min(int(k), cap or int(k)) for k in k_h]
    kept = [kw for events, k in zip(_enumerate(sc), per_h, strict=True) for kw in _top(events, k)]
    exact = {}
    for key, w in _top(kept, K):
        exact[key] = exact.get(key, Fraction(0)) + w
    _check_against(trk, sc, exact)


# ------------------------------------------------------------------ the bound, the reports


def _estimate(n, m, k):
    """The documented estimate of one Murty call (PMBMConfig.max_ranking_work)."""
    return (1 + (k - 1) * n) * n * (n + m)


@pytest.mark.parametrize("K, budget, tier", [(60, None, "murty-truncated"), (300, None, "pmb-"),
                                             (40, 10**5, "pmb-")])  # fmt: skip
def test_a_burst_is_ranked_within_the_budget(monkeypatch, caplog, K, budget, tier):
    """Every Murty call and sparse-LBP call of a burst scan fits the budget; the tier
    is named in the result, counted and logged (the first time at WARNING)."""
    config = {} if budget is None else {"max_ranking_work": budget}
    budget = budget or PMBMConfig.max_ranking_work
    calls, lbp = [], []
    kbest = pmbm_module.kbest_hypotheses
    fallback = budget_module.fallback_pair_marginals

    def counted_kbest(L, miss, *, k):
        calls.append(_estimate(L.shape[0], L.shape[1], k))
        return kbest(L, miss, k=k)

    def counted_fallback(*args, max_work, **kw):
        lbp.append(max_work)
        return fallback(*args, max_work=max_work, **kw)

    monkeypatch.setattr(pmbm_module, "kbest_hypotheses", counted_kbest)
    monkeypatch.setattr(budget_module, "fallback_pair_marginals", counted_fallback)
    caplog.set_level(logging.DEBUG, logger="jointtrack.tracker")
    trk, results = _blob(PMBMTracker, K, **config)
    assert max(calls, default=0) <= budget
    assert max(lbp, default=0) <= budget
    last = results[-1]
    assert len(last.cluster_methods) == 1 and last.cluster_methods[0].startswith(tier)
    assert last.cluster_sizes == [(K, K)]
    kind = "ranking_truncated" if tier == "murty-truncated" else "ranking_merged"
    (reason,) = last.cluster_fallbacks
    assert reason.startswith(f"{kind}: ") and f"max_ranking_work = {budget}" in reason
    assert last.n_fallbacks == 1
    assert sum(v for k, v in trk.fallback_counts.items() if k.startswith(kind)) >= 1
    warned = [r for r in caplog.records if r.levelno == logging.WARNING and kind in r.message]
    assert len(warned) == 1  # the first of its kind; the rest are counted, not logged
    if tier == "pmb-":
        assert trk.n_hypotheses == 1
        assert np.isfinite(trk.sth_x).all() and ((trk.sth_r > 0) & (trk.sth_r <= 1)).all()


@pytest.mark.parametrize("kind", ["jipda", "pmb"])
def test_a_burst_never_starts_an_unbounded_dense_approximation(monkeypatch, kind):
    """A 2,000-return burst went to the dense LBP (1,000 sweeps: PMB 177 s, JIPDA 85 s
    per scan); a cluster whose dense sweeps could exceed the sparse tier's work goes
    to the sparse tiers within it (budgeted_marginals, shared by every tracker)."""
    from jointtrack.association.budget import MAX_LBP_WORK
    from jointtrack.trackers import JPDATracker, TrackerConfig

    seen = []
    fallback = budget_module.fallback_pair_marginals

    def counted(*args, max_work, **kw):
        seen.append(max_work)
        return fallback(*args, max_work=max_work, **kw)

    monkeypatch.setattr(budget_module, "fallback_pair_marginals", counted)
    if kind == "pmb":  # not merged as one target's duplicates: a cluster of ≥ 100
        trk, results = _blob(PMBTracker, 300, duplicate_distance=0.0)
    else:
        trk = JPDATracker(TrackerConfig(**{k: v for k, v in BURST.items() if k != "birth_density"}))
        rng = np.random.default_rng(0)
        results = [trk.step(float(t), rng.normal(0, 3, (300, 2))) for t in range(3)]
    big = [i for i, (n, _) in enumerate(results[-1].cluster_sizes) if n >= 100]
    assert big, results[-1].cluster_sizes
    for i in big:
        assert results[-1].cluster_methods[i] == "lbp-sparse"
        assert results[-1].cluster_fallbacks[i].startswith("dense_budget: ")
    assert seen and set(seen) == {MAX_LBP_WORK}


def test_the_run_tallies_the_ranking_tiers(tmp_path):
    """``jointtrack run --tracker pmbm``: metrics.json counts the merged clusters."""
    rng = np.random.default_rng(0)
    rows = [f"{t},{x:.6f},{y:.6f}" for t in range(3) for x, y in rng.normal(0, 3, (40, 2))]
    det = tmp_path / "burst.csv"
    det.write_text("time,x,y\n" + "\n".join(rows) + "\n", encoding="utf-8")
    cfg = tmp_path / "run.toml"
    cfg.write_text(
        "[tracker]\nclutter_density = 1e-5\nmeasurement_noise = 1.0\nprocess_noise = 1.0\n"
        "[pmbm]\nbirth_density = 1e-6\nmax_ranking_work = 100000\n",
        encoding="utf-8",
    )
    out = tmp_path / "o"
    r = CliRunner().invoke(app, ["run", "--no-progress", "--detections", str(det), "--config",
                                 str(cfg), "--tracker", "pmbm", "--out", str(out)])  # fmt: skip
    assert r.exit_code == 0, r.output
    rows = json.loads((out / "metrics.json").read_text())["association"]["clusters"]
    merged = [row for row in rows if row["reason"] == "ranking_merged"]
    assert merged and all(row["method"].startswith("pmb-") for row in merged)
    assert sum(row["count"] for row in merged) >= 1


# ------------------------------------------------------------------ atomic past the budget


class Injected(RuntimeError):
    pass


@pytest.mark.parametrize(
    "K, budget, stage",
    [(60, None, s) for s in ("_ranking_cap", "rank_tuples", "combine_events", "_children")]
    + [(40, 10**5, s) for s in ("_merge_cluster", "_pmb_update", "moment_match", "_gate",
                                "fallback_pair_marginals", "existence_update",
                                "pda_pairs_update")],
)  # fmt: skip
def test_a_failing_stage_past_the_budget_leaves_the_state_unchanged(monkeypatch, K, budget, stage):
    """Fault injection in every stage of the truncated and merged tiers: the step raises,
    the state is as before, and the retried scan gives what an unfailed tracker gives."""
    config = {} if budget is None else {"max_ranking_work": budget}
    trk, _ = _blob(PMBMTracker, K, scans=2, **config)
    ref, _ = _blob(PMBMTracker, K, scans=2, **config)
    if stage in ("_gate", "moment_match"):  # a merged cluster of two prior tuples
        trk.hyp = np.concatenate([trk.hyp, np.full((1, trk.hyp.shape[1]), -1)])
        trk.hyp_logw = np.array([0.0, -1.0])
        ref.hyp, ref.hyp_logw = trk.hyp.copy(), trk.hyp_logw.copy()
    before = trk.state_dict()
    z = np.random.default_rng(9).normal(0, 3, (K, 2))

    # the sparse tiers are the shared budget's (association.budget), the rest PMBM's
    owner = next(o for o in (PMBMTracker, pmbm_module, budget_module) if hasattr(o, stage))
    real = getattr(owner, stage)

    def boom(*args, **kwargs):
        # _gate and moment_match serve the Poisson part too: fail them in the merge only
        if stage in ("_gate", "moment_match") and not any(
            f.function == "_merge_cluster" for f in inspect.stack()
        ):
            return real(*args, **kwargs)
        raise Injected(stage)

    monkeypatch.setattr(owner, stage, boom)
    with pytest.raises(Injected):
        trk.step(2.0, z)
    monkeypatch.undo()
    after = trk.state_dict()
    assert_same_state(after, before)
    a, b = trk.step(2.0, z), ref.step(2.0, z)
    assert a.cluster_methods == b.cluster_methods and a.cluster_methods[0] != "murty"
    np.testing.assert_array_equal(a.x, b.x)
    _state_equal(trk, ref)
