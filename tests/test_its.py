"""Tentative tracks as integrated track-splitting filters (issue 33):
``TrackerConfig.tentative_association = "splitting"``.

The reference is the exact posterior over measurement histories, enumerated here from
the model (each history's Kalman filter written out, its weight the product of its
scans' "no return" 1 − P_D P_G or P_D g / λ; the existence the Bayes posterior of the
chain "alive through scan k / died before scan j / never existed"), not taken from the
tracker. ITS with no pruning must equal it; with one component it is "alternatives".
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from jointtrack.models import ConstantVelocity
from jointtrack.trackers import JPDATracker, TrackerConfig
from jointtrack.trackers.state_io import StateFileError, read_state, write_state
from jointtrack.trackers.track_splitting import prune_children
from state_checks import assert_steps_alike
from test_tentative_alternatives import _two_lanes

# ---------------------------------------------------------------------------
# reference: every measurement history, written out
# ---------------------------------------------------------------------------


def enumerate_histories(x0, P0, r0, scans, *, R, p_d, p_g, lam, p_survive, q):
    """Exact posterior after ``scans`` [(dt, z (M, 2)), …] of one target started at
    ``(x0, P0)`` with existence ``r0``: ``(existence, [(weight, x, P), …])`` with the
    weights of the histories given that the target exists (summing to one)."""
    cv = ConstantVelocity(dim=2, q=q)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    gamma = chi2.ppf(p_g, 2)
    choices = [range(-1, len(z)) for _, z in scans]  # -1: no return
    ratios = [[] for _ in range(len(scans) + 1)]  # Σ_h Π factors after each scan
    ratios[0] = [1.0]
    finals = []
    for history in itertools.product(*choices):
        x, P, w = x0.copy(), P0.copy(), 1.0
        for k, ((dt, z), m) in enumerate(zip(scans, history, strict=True)):
            F, Q = cv.transition(dt), cv.noise(dt)
            x, P = F @ x, F @ P @ F.T + Q
            S = H @ P @ H.T + R
            if m < 0:
                w *= 1.0 - p_d * p_g
            else:
                nu = z[m] - H @ x
                d2 = nu @ np.linalg.solve(S, nu)
                if d2 > gamma:  # outside the gate: not a history the filter keeps
                    w = 0.0
                    break
                w *= p_d * np.exp(-0.5 * d2) / (2 * np.pi * np.sqrt(np.linalg.det(S))) / lam
                K = P @ H.T @ np.linalg.inv(S)
                x = x + K @ nu
                P = (np.eye(4) - K @ H) @ P
            # the prefix's weight counts once per distinct prefix: only on its first
            # extension (all later scans' choices -1)
            if all(c == -1 for c in history[k + 1 :]):
                ratios[k + 1].append(w)
        if w > 0:
            finals.append((w, x, P))
    A = [sum(v) for v in ratios]  # A_k = Σ over histories of scans 1..k
    n = len(scans)
    alive = r0 * p_survive**n * A[n]
    died = sum(r0 * p_survive ** (j - 1) * (1 - p_survive) * A[j - 1] for j in range(1, n + 1))
    existence = alive / (alive + died + (1 - r0))
    total = sum(w for w, _, _ in finals)
    return existence, [(w / total, x, P) for w, x, P in finals]


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    sigma=st.floats(0.5, 20.0),
    p_d=st.floats(0.05, 0.99),
    p_g=st.floats(0.5, 0.999),
    log_lam=st.floats(-4.0, 0.0),
    r0=st.floats(0.001, 0.5),
    p_survive=st.floats(0.5, 1.0),
    offsets=st.lists(
        # distinct: identical returns of one scan are one return to the tracker
        st.lists(
            st.tuples(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0)),
            min_size=0,
            max_size=3,
            unique=True,
        ),
        min_size=1,
        max_size=3,
    ),
    v=st.tuples(st.floats(-5.0, 5.0), st.floats(-5.0, 5.0)),
)
def test_unpruned_mixture_is_the_exact_history_posterior(
    sigma, p_d, p_g, log_lam, r0, p_survive, offsets, v
):
    """With room for every history (K = 256) the track's existence and its components'
    weights equal the enumeration (relative 1e-12), and its moment-matched state the
    enumeration's mean (1e-9)."""
    lam = 10.0**log_lam
    q = 0.1
    x0 = np.array([0.0, 0.0, v[0], v[1]])
    P0 = np.diag([sigma**2, sigma**2, 4.0, 4.0])
    # returns around the truth, offsets in units of σ (some outside the gate)
    scans = [
        (1.0, np.array([[(k + 1) * v[0], (k + 1) * v[1]]]) + sigma * np.array(o).reshape(-1, 2))
        for k, o in enumerate(offsets)
    ]
    # returns that round to one point are one return to the tracker (merge_coincident)
    scans = [(dt, z[np.sort(np.unique(z, axis=0, return_index=True)[1])]) for dt, z in scans]
    cfg = TrackerConfig(
        measurement_noise=sigma**2,
        process_noise=q,
        p_d=p_d,
        p_g=p_g,
        p_survive=p_survive,
        clutter_density=lam,
        r_init=0.02,
        r_delete=1e-300,
        r_confirm=1.0,
        merge_threshold=0.0,
        tentative_association="splitting",
        tentative_components=256,
    )
    trk = JPDATracker(cfg)
    (tid,) = trk.start_tracks(x0, P0, confirmed=False, existence=r0, time=0.0)
    for k, (_, z) in enumerate(scans):
        trk.step(float(k + 1), z)
    r_want, comps = enumerate_histories(
        x0,
        P0,
        r0,
        scans,
        R=sigma**2 * np.eye(2),
        p_d=p_d,
        p_g=p_g,
        lam=lam,
        p_survive=p_survive,
        q=q,
    )
    (i,) = np.flatnonzero(trk.ids == tid)
    assert trk.existence[i] == pytest.approx(r_want, rel=1e-12, abs=0.0)
    k = trk.comp_n[i]
    assert k == len(comps)
    w_have = np.sort(np.exp(trk.comp_log_w[i, :k]))
    w_want = np.sort([w for w, _, _ in comps])
    np.testing.assert_allclose(w_have, w_want, rtol=1e-12, atol=0.0)
    mean = sum(w * x for w, x, _ in comps)
    np.testing.assert_allclose(trk.x[i], mean, rtol=1e-9, atol=1e-9 * sigma)


def test_one_component_is_alternatives_bit_for_bit():
    """K = 1 keeps each scan's most probable child: the "alternatives" run exactly
    (two lanes in clutter: confirmations, duplicates held, merges, deletions)."""
    scans, _, lam = _two_lanes(2, n_scans=30)
    cfg = dict(measurement_noise=9.0, p_d=0.95, clutter_density=lam, max_speed=7.5)
    a = JPDATracker(TrackerConfig(tentative_association="alternatives", **cfg))
    b = JPDATracker(TrackerConfig(tentative_association="splitting", tentative_components=1, **cfg))
    confirmed = 0
    for t, z in scans:
        ra, rb = a.step(t, z), b.step(t, z)
        for name in ("ids", "x", "P", "existence"):
            np.testing.assert_array_equal(getattr(ra, name), getattr(rb, name), err_msg=name)
        np.testing.assert_array_equal(a.existence, b.existence)
        np.testing.assert_array_equal(a.x, b.x)
        confirmed = max(confirmed, len(rb.ids))
    assert confirmed == 2  # both targets confirmed: the comparison covered confirmation


def test_components_stay_bounded_and_confirmed_tracks_hold_none():
    """K bounds every track's components; a confirmed track holds one Gaussian (with
    "dominant", its most probable component at confirmation)."""
    scans, _, lam = _two_lanes(3, n_scans=12)
    cfg = dict(measurement_noise=9.0, p_d=0.95, clutter_density=lam, max_speed=7.5)
    for state in ("moment", "dominant"):
        trk = JPDATracker(
            TrackerConfig(
                tentative_association="splitting",
                tentative_components=3,
                tentative_confirm_state=state,
                **cfg,
            )
        )
        most = 0
        for t, z in scans:
            trk.step(t, z)
            assert (trk.comp_n <= 3).all()
            assert (trk.comp_n[trk.confirmed] == 0).all()
            assert (trk.comp_n[~trk.confirmed] >= 1).all()
            most = max(most, int(trk.comp_n.max(initial=0)))
        assert most == 3
        assert trk.confirmed.sum() >= 2


@settings(max_examples=40, deadline=None)
@given(
    owner=st.lists(st.integers(0, 3), min_size=1, max_size=12),
    data=st.data(),
    k_max=st.integers(1, 5),
)
def test_pruning_keeps_the_most_probable(owner, data, k_max):
    """Against sorting each track's children by hand: the kept are the k_max largest
    (earlier first on ties, −∞ never), renormalised to sum to one."""
    weights = st.one_of(
        st.just(-np.inf),
        st.floats(-745.0, 700.0),
        st.sampled_from([0.0, -1e-300, np.log(5e-324)]),
    )
    log_w = np.array(data.draw(st.lists(weights, min_size=len(owner), max_size=len(owner))))
    owner = np.array(owner)
    keep, kept = prune_children(owner, log_w, k_max)
    for track in np.unique(owner):
        mine = [i for i in range(len(owner)) if owner[i] == track and np.isfinite(log_w[i])]
        want = sorted(mine, key=lambda i: (-log_w[i], i))[:k_max]
        got = keep[owner[keep] == track]
        assert list(got) == want
        if want:
            tot = np.logaddexp.reduce(kept[owner[keep] == track])
            assert abs(tot) < 1e-12
            assert np.isfinite(kept[owner[keep] == track]).all()


# ---------------------------------------------------------------------------
# settings, state files
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("field", "bad"),
    [
        ("tentative_components", 0),
        ("tentative_components", 257),
        ("tentative_components", 2.5),
        ("tentative_components", True),
        ("tentative_components", "8"),
        ("tentative_components", 1 + 2j),
        ("tentative_components", 10**400),
        ("tentative_confirm_state", "mean"),
        ("tentative_confirm_state", 1),
        ("tentative_association", "split"),
    ],
)
def test_bad_settings_are_named(field, bad):
    with pytest.raises(ValueError, match=field):
        TrackerConfig(**{field: bad})


@pytest.mark.parametrize(
    "other",
    [
        {"existence": False},
        {"motion": "imm"},
        {"reporting": "async", "clutter_density": 1e-4},
    ],
)
def test_splitting_refuses_what_it_cannot_do(other):
    with pytest.raises(ValueError, match="splitting"):
        TrackerConfig(tentative_association="splitting", **other)


def _mid_run(n_scans=8, **kw):
    scans, _, lam = _two_lanes(4, n_scans=16)
    cfg = dict(measurement_noise=9.0, p_d=0.95, clutter_density=lam, max_speed=7.5)
    trk = JPDATracker(
        TrackerConfig(tentative_association="splitting", tentative_components=4, **cfg, **kw)
    )
    for t, z in scans[:n_scans]:
        trk.step(t, z)
    return trk, scans


def test_saved_splitting_run_continues_identically(tmp_path):
    """Stopped at scan 8 and loaded, the run continues bit for bit (the components are
    in the file)."""
    a, scans = _mid_run()
    assert a.comp_n.max() > 1
    b = JPDATracker.load(a.save(tmp_path / "mid.npz"))
    for name in ("comp_x", "comp_P", "comp_log_w", "comp_n"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)
    assert_steps_alike(a, b, scans[8:])
    np.testing.assert_array_equal(a.comp_x, b.comp_x)


def _damaged(trk, tmp_path, edit):
    arrays, config, scalars, rng = read_state(trk.save(tmp_path / "ok.npz"))
    edit(arrays, config)
    return write_state(tmp_path / "bad.npz", arrays, config, scalars, rng)


def _first_tentative(trk):
    return int(np.flatnonzero(~trk.confirmed & (trk.comp_n > 1))[0])


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda a, c, i: a.pop("comp_log_w"), "comp_log_w"),
        (lambda a, c, i: a["comp_log_w"].__setitem__((i, 0), 0.5), "comp_log_w"),
        (lambda a, c, i: a["comp_n"].__setitem__(i, 5), "comp_n"),
        (lambda a, c, i: a["comp_n"].__setitem__(i, 0), "comp_n"),
        (lambda a, c, i: a["comp_P"].__setitem__((i, 0, 0, 0), -1.0), "comp_P"),
        (lambda a, c, i: a["comp_x"].__setitem__((i, 3, 0), np.nan), "comp_x"),
        (lambda a, c, i: c.__setitem__("tentative_components", 3), "comp_x"),
        (lambda a, c, i: a.__setitem__("comp_n", a["comp_n"].astype(float)), "comp_n"),
    ],
)
def test_damaged_components_are_refused_by_name(tmp_path, edit, message):
    trk, _ = _mid_run()
    i = _first_tentative(trk)
    path = _damaged(trk, tmp_path, lambda a, c: edit(a, c, i))
    with pytest.raises(StateFileError, match=message):
        JPDATracker.load(path)


def test_unused_slots_must_be_empty(tmp_path):
    trk, _ = _mid_run()
    i = int(np.flatnonzero(trk.comp_n < 4)[0])
    path = _damaged(trk, tmp_path, lambda a, c: a["comp_x"].__setitem__((i, 3, 0), 1.0))
    with pytest.raises(StateFileError, match="slots no component uses"):
        JPDATracker.load(path)


def test_state_written_before_the_setting_loads_without_components(tmp_path):
    """A state file of main before track splitting (no settings, no arrays) loads with
    no components and continues as it ran."""
    scans, _, lam = _two_lanes(5, n_scans=12)
    cfg = dict(measurement_noise=9.0, p_d=0.95, clutter_density=lam, max_speed=7.5)
    trk = JPDATracker(TrackerConfig(tentative_association="alternatives", **cfg))
    for t, z in scans[:8]:
        trk.step(t, z)
    arrays, config, scalars, rng = read_state(trk.save(tmp_path / "now.npz"))
    for key in ("tentative_components", "tentative_confirm_state"):
        config.pop(key)
    for key in ("comp_x", "comp_P", "comp_log_w", "comp_n"):
        arrays.pop(key)
    write_state(tmp_path / "before.npz", arrays, config, scalars, rng)
    loaded = JPDATracker.load(tmp_path / "before.npz")
    assert loaded.comp_x.shape == (len(loaded.ids), 0, 4)
    assert_steps_alike(trk, loaded, scans[8:])


# ---------------------------------------------------------------------------
# one scan's arithmetic, exactly; a failing step
# ---------------------------------------------------------------------------

_MAGNITUDES = st.one_of(
    st.just(0.0),
    st.floats(1e-300, 1e300),
    st.sampled_from([5e-324, 2.2250738585072014e-308, 1e-300, 1e300]),
)


@settings(max_examples=50, deadline=None)
@given(data=st.data(), n_comp=st.integers(1, 3), n_ret=st.integers(0, 3))
def test_one_scan_equals_exact_rationals(data, n_comp, n_ret):
    """its_update against the same scan in exact rationals (fractions of the float
    inputs): existence and every child's weight to relative 1e-12, whatever the
    magnitudes of the likelihood ratios (0, subnormal … 1e300) and of r."""
    from fractions import Fraction as Fr

    from jointtrack.trackers.track_splitting import its_update

    r = data.draw(st.floats(1e-300, 1.0))
    pdg = data.draw(st.floats(0.0, 1.0))
    missed = 1.0 - pdg
    raw_w = data.draw(st.lists(st.floats(1e-3, 1.0), min_size=n_comp, max_size=n_comp))
    log_w = np.log(np.array(raw_w) / np.sum(raw_w))
    pair_comp = np.repeat(np.arange(n_comp), n_ret)
    L = np.array(data.draw(st.lists(_MAGNITUDES, min_size=len(pair_comp), max_size=len(pair_comp))))
    if r * missed == 0.0 and not (L > 0).any():
        return  # nothing can happen: no return and no miss (refused upstream)
    r_post, miss_lw, hit_lw, _ = its_update(
        np.array([r]),
        log_w,
        np.zeros(n_comp, np.int64),
        pair_comp,
        L,
        np.array([missed]),
        np.array([pdg]),
    )
    w = [Fr(float(v)) for v in np.exp(log_w)]
    hits = [w[c] * Fr(float(v)) for c, v in zip(pair_comp, L, strict=True)]
    exists_missed = Fr(r) * Fr(missed)
    # exact: r' = (r·missed + Σ w L) / ((1 − r) + r·missed + Σ w L); given existence the
    # miss children share r·missed by the components' weights, the hits their w L
    total = (1 - Fr(r)) + exists_missed + sum(hits)
    given = exists_missed + sum(hits)
    want_r = given / total
    assert float(r_post[0]) == pytest.approx(float(want_r), rel=1e-12, abs=0.0)
    for got, want in zip(
        np.concatenate([miss_lw, hit_lw]),
        [wc * exists_missed / given for wc in w] + [h / given for h in hits],
        strict=True,
    ):
        if want == 0:
            assert got == -np.inf
        else:
            assert np.exp(got) == pytest.approx(float(want), rel=1e-12, abs=1e-300)
            assert np.isfinite(got) or float(want) < 1e-300


def test_a_failing_step_leaves_the_components_unchanged(monkeypatch):
    """A step that fails inside the splitting update (after the existence changed)
    leaves every array — components included — as it was."""
    from jointtrack.trackers import jpda
    from state_checks import assert_same_state

    trk, scans = _mid_run()
    before = trk.state_dict()

    def broken(*args, **kwargs):
        raise RuntimeError("injected")

    monkeypatch.setattr(jpda, "pda_pairs_update", broken)
    with pytest.raises(RuntimeError, match="injected"):
        trk.step(*scans[8])
    assert_same_state(trk.state_dict(), before)
    monkeypatch.undo()
    fresh, _ = _mid_run()
    assert_steps_alike(trk, fresh, scans[8:])
