"""score_self_reports: hand-checked scenes, interpolation against exact rational
arithmetic, consistency with track_statistics, and bad input."""

from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from jointtrack.metrics import track_statistics
from jointtrack.metrics.selfreport import score_self_reports

C = 100.0


def _rows(rows):
    """rows of (time, id, x, y) → (times, ids, positions)."""
    a = np.array(rows, dtype=np.float64).reshape(-1, 4)
    return a[:, 0], a[:, 1].astype(np.int64), a[:, 2:4]


# ----------------------------------------------------------------------------- hand cases


def test_one_identity_perfect_track():
    # reports at irregular times on x = 3 t; the track sits exactly on the
    # reported line at its own (different) times, inside every window
    rt = np.array([0.0, 7.0, 11.0, 26.0, 33.0, 40.0])
    truth = (rt, np.full(rt.size, 5), np.c_[3.0 * rt, np.zeros(rt.size)])
    kt = np.arange(0.0, 41.0, 10.0)  # the instants themselves: 0, 10, 20, 30, 40
    tracks = (kt, np.full(kt.size, 1), np.c_[3.0 * kt, np.zeros(kt.size)])
    s = score_self_reports(*truth, *tracks, window=10.0, c=C)
    np.testing.assert_array_equal(s.instants, [0.0, 10.0, 20.0, 30.0, 40.0])
    assert s.n_instants == 5 and s.n_identity_instants == 5
    assert s.coverage == 1.0 and s.purity == 1.0 and s.purity_unweighted == 1.0
    assert s.gospa_mean < 1e-9 and s.n_id_switches == 0 and s.n_false_tracks == 0
    assert s.tracks_per_identity == 1.0 and s.n_confirmed_track_ids == 1
    assert s.identity_coverage.tolist() == [1.0]


def _swap_scene():
    """Identities 1 on y = 0 and 2 on y = 1000, reported every 10 s for t = 0 … 70.
    Track 10 follows identity 1 at t < 40 and identity 2 from t = 40; track 20 the
    reverse. Each identity is covered throughout and changes partner once."""
    truth, tracks = [], []
    for t in range(0, 80, 10):
        truth += [(t, 1, t, 0.0), (t, 2, t, 1000.0)]
        a, b = (0.0, 1000.0) if t < 40 else (1000.0, 0.0)
        tracks += [(t, 10, t + 1.0, a), (t, 20, t + 1.0, b)]
    return _rows(truth), _rows(tracks)


def test_swapped_identities_purity_half_and_switches():
    truth, tracks = _swap_scene()
    s = score_self_reports(*truth, *tracks, window=10.0, c=C)
    assert s.n_instants == 8
    assert s.coverage == 1.0
    assert s.purity == 0.5 and s.purity_unweighted == 0.5
    assert s.track_purity.tolist() == [0.5, 0.5]
    assert s.identity_switches.tolist() == [1, 1] and s.n_id_switches == 2
    assert s.identity_tracks.tolist() == [2, 2] and s.tracks_per_identity == 2.0
    # each track sits on one identity in exactly half its instants: true, not false
    assert s.n_false_tracks == 0
    # localisation only: every pair 1 m apart, two pairs per instant
    assert s.gospa_localisation == pytest.approx(2.0, rel=1e-12)
    assert s.gospa_mean == pytest.approx(math.sqrt(2.0), rel=1e-12)


def test_track_silent_beyond_window_is_absent():
    # truth at x = 0 reported every 5 s for 0 … 90; the track estimates at
    # t = 0, 10, …, 50 at x = t / 10 (so an instant shows which estimate it used)
    rt = np.arange(0.0, 91.0, 5.0)
    truth = (rt, np.zeros(rt.size, int), np.zeros((rt.size, 2)))
    kt = np.arange(0.0, 51.0, 10.0)
    tracks = (kt, np.full(kt.size, 7), np.c_[kt / 10.0, np.zeros(kt.size)])
    s = score_self_reports(*truth, *tracks, window=15.0, c=C)
    np.testing.assert_array_equal(s.instants, np.arange(0.0, 91.0, 15.0))  # 0, 15, …, 90
    # instant 60: latest estimate at 50, 10 s old < 15 → present; 75: 25 s old → absent
    assert s.n_tracks_per_instant.tolist() == [1, 1, 1, 1, 1, 0, 0]
    # the estimate is used as is: at 15 the estimate of t = 10 (x = 1), at 60 that of 50
    t_s, _, p_s = s.tracks_sampled
    np.testing.assert_array_equal(t_s, [0.0, 15.0, 30.0, 45.0, 60.0])
    np.testing.assert_array_equal(p_s[:, 0], [0.0, 1.0, 3.0, 4.0, 5.0])
    assert s.coverage == 5 / 7
    # an estimate exactly one window old is outside (t − window, t]
    s10 = score_self_reports(*truth, *tracks, window=10.0, c=C)
    assert s10.n_tracks_per_instant.tolist() == [1] * 6 + [0] * 4


def test_max_gap_respected():
    rt = np.array([0.0, 10.0, 700.0, 710.0])
    truth = (rt, np.full(4, 3), np.c_[rt, -rt])
    empty = (np.zeros(0), np.zeros(0, int), np.zeros((0, 2)))
    s = score_self_reports(*truth, *empty, window=5.0, c=C, max_gap=600.0)
    np.testing.assert_array_equal(s.truth_sampled[0], [0.0, 5.0, 10.0, 700.0, 705.0, 710.0])
    np.testing.assert_array_equal(s.truth_sampled[2][:, 0], [0.0, 5.0, 10.0, 700.0, 705.0, 710.0])
    # a gap of 690 s ≤ max_gap: interpolated across it, every instant 0 … 710
    s2 = score_self_reports(*truth, *empty, window=5.0, c=C, max_gap=690.0)
    assert s2.n_identity_instants == 143
    np.testing.assert_allclose(s2.truth_sampled[2][:, 0], s2.truth_sampled[0], rtol=0, atol=1e-9)
    # nothing tracked: every identity-instant is a missed target at c²/2
    assert s.coverage == 0.0 and math.isnan(s.tracks_per_identity)
    assert s.gospa_missed == pytest.approx(C**2 / 2 * 6 / s.n_instants, rel=1e-12)


def test_duplicate_reports_are_averaged_and_no_extrapolation():
    truth = _rows([(0, 1, 0, 0), (10, 1, 0, 0), (10, 1, 2, 4), (20, 1, 1, 2), (25, 4, 0, 0)])
    empty = (np.zeros(0), np.zeros(0, int), np.zeros((0, 2)))
    s = score_self_reports(*truth, *empty, window=10.0, c=C)
    t_s, i_s, p_s = s.truth_sampled
    # identity 1 at 0, 10 (mean of (0,0) and (2,4)), 20; identity 4 only at its
    # report 25, which is no instant (instants 0, 10, 20): never present
    assert t_s.tolist() == [0.0, 10.0, 20.0] and i_s.tolist() == [1, 1, 1]
    np.testing.assert_array_equal(p_s, [[0, 0], [1, 2], [1, 2]])
    assert s.identity_instants.tolist() == [3, 0]
    d = s.as_dict()
    assert d["per_identity"]["4"] == {
        "instants": 0,
        "coverage": None,
        "tracks": 0,
        "tracks_held": 0,
        "switches": 0,
    }


def test_false_track_and_rate():
    truth = _rows([(t, 1, 0.0, 0.0) for t in range(0, 3601, 60)])
    far = _rows([(t, 9, 5000.0, 0.0) for t in range(0, 3601, 60)])
    s = score_self_reports(*truth, *far, window=60.0, c=C)
    assert s.n_false_tracks == 1 and s.hours == 1.0 and s.false_tracks_per_hour == 1.0
    assert s.n_confirmed_track_ids == 1 and s.n_tracks_present == 1
    assert math.isnan(s.purity)  # no associated track: undefined
    # each instant: one missed and one false target, GOSPA = c
    assert s.gospa_mean == pytest.approx(C, rel=1e-12)
    assert s.missed_per_instant == 1.0 and s.false_per_instant == 1.0
    s2 = score_self_reports(*truth, *far, window=60.0, c=C, duration=7200.0)
    assert s2.false_tracks_per_hour == 0.5


def test_as_dict_plain_json_and_summary():
    truth, tracks = _swap_scene()
    s = score_self_reports(*truth, *tracks, window=10.0, c=C)
    d = s.as_dict()
    text = json.dumps(d, allow_nan=False)  # no NaN, no numpy types
    assert json.loads(text)["purity"] == 0.5
    assert "\n" not in s.summary() and "coverage 1.000" in s.summary()
    empty = (np.zeros(0), np.zeros(0, int), np.zeros((0, 2)))
    e = score_self_reports(*empty, *empty, window=10.0, c=C)
    de = e.as_dict()
    json.dumps(de, allow_nan=False)
    assert de["n_instants"] == 0 and de["coverage"] is None and de["gospa_mean"] is None
    assert "n/a" in e.summary()


# ----------------------------------------------------------------------------- exact interpolation


def _exact_truth(times, pos, t, max_gap):
    """Brute force in rationals: the reference at instant t (None if not present)."""
    T = [Fraction(x) for x in times]
    t = Fraction(t)
    order = sorted(range(len(T)), key=lambda i: T[i])
    for i in order:
        if T[i] == t:
            return [Fraction(v) for v in pos[i]]
    before = [i for i in order if T[i] < t]
    after = [i for i in order if T[i] > t]
    if not before or not after:
        return None
    a, b = before[-1], after[0]
    if T[b] - T[a] > Fraction(max_gap):
        return None
    w = (t - T[a]) / (T[b] - T[a])
    return [
        Fraction(pa) + w * (Fraction(pb) - Fraction(pa))
        for pa, pb in zip(pos[a], pos[b], strict=True)
    ]


@settings(max_examples=80, deadline=None)
# a gap of 2 + 5.6e-120 rounds to max_gap = 2: the rounded comparison kept it
@example(
    gaps=[2.0], start=-5.6385143376026816e-120, coords=[(0.0, 0.0)] * 9, window=1.0, max_gap=2.0
)
@given(
    gaps=st.lists(st.floats(0.5, 400.0), min_size=1, max_size=8),
    start=st.floats(-1e4, 1e4),
    coords=st.lists(st.tuples(st.floats(-1e5, 1e5), st.floats(-1e5, 1e5)), min_size=9, max_size=9),
    window=st.floats(1.0, 200.0),
    max_gap=st.floats(1.0, 500.0),
)
def test_interpolation_matches_exact_rationals(gaps, start, coords, window, max_gap):
    times = np.cumsum([start, *gaps])
    pos = np.array(coords[: times.size])
    empty = (np.zeros(0), np.zeros(0, int), np.zeros((0, 2)))
    s = score_self_reports(
        times, np.zeros(times.size, int), pos, *empty, window=window, c=C, max_gap=max_gap
    )
    t_s, _, p_s = s.truth_sampled
    got = dict(zip(t_s.tolist(), p_s.tolist(), strict=True))
    scale = float(np.max(np.abs(pos))) + 1.0
    assert s.instants[0] == times[0]
    for t in s.instants.tolist():
        want = _exact_truth(times, pos, t, max_gap)
        assert (t in got) == (want is not None)
        if want is not None:
            assert max(abs(float(w) - g) for w, g in zip(want, got[t], strict=True)) <= 1e-9 * scale


@settings(max_examples=60, deadline=None)
@given(
    t_reports=st.lists(st.floats(0.0, 1000.0), min_size=2, max_size=12, unique=True),
    a=st.tuples(st.floats(-1e5, 1e5), st.floats(-1e5, 1e5)),
    v=st.tuples(st.floats(-50.0, 50.0), st.floats(-50.0, 50.0)),
    window=st.floats(1.0, 300.0),
)
def test_linear_motion_is_reproduced(t_reports, a, v, window):
    # reports of x(t) = a + v t at any times (any order): with max_gap = ∞ the
    # reference at every instant between the first and last report is x(t)
    t = np.array(t_reports)
    pos = np.array(a) + t[:, None] * np.array(v)
    empty = (np.zeros(0), np.zeros(0, int), np.zeros((0, 2)))
    s = score_self_reports(t, np.ones(t.size, int), pos, *empty, window=window, c=C, max_gap=np.inf)
    t_s, _, p_s = s.truth_sampled
    np.testing.assert_array_equal(t_s, s.instants[s.instants <= t.max()])
    for ti, pi in zip(t_s.tolist(), p_s.tolist(), strict=True):
        exact = [Fraction(ak) + Fraction(vk) * Fraction(ti) for ak, vk in zip(a, v, strict=True)]
        scale = 1.0 + max(abs(x) for x in exact)
        assert max(abs(float(e) - g) for e, g in zip(exact, pi, strict=True)) <= 1e-9 * float(scale)


# ----------------------------------------------------------------------------- consistency


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_figures_agree_with_track_statistics(data):
    n_id = data.draw(st.integers(1, 3))
    n_trk = data.draw(st.integers(0, 4))
    truth, tracks = [], []
    for i in range(n_id):
        for t in sorted(set(data.draw(st.lists(st.integers(0, 60), min_size=1, max_size=8)))):
            truth.append((t, i, data.draw(st.floats(0, 300)), data.draw(st.floats(0, 300))))
    for j in range(n_trk):
        for t in sorted(set(data.draw(st.lists(st.integers(0, 60), max_size=8)))):
            tracks.append((t, 100 + j, data.draw(st.floats(0, 300)), data.draw(st.floats(0, 300))))
    window = float(data.draw(st.integers(1, 20)))
    s = score_self_reports(*_rows(truth), *_rows(tracks), window=window, c=C)
    ref = track_statistics(*s.truth_sampled, *s.tracks_sampled, gate=C)
    assert s.n_id_switches == ref.n_id_switches
    assert s.n_false_tracks == ref.n_false_tracks
    assert s.n_associated == ref.assoc_times.size
    if s.n_identity_instants:
        assert s.coverage == ref.coverage
    assert s.identity_instants.sum() == s.n_identity_instants
    assert s.identity_associated.sum() == s.n_associated
    ok = ~np.isnan(s.track_purity)
    assert np.all((s.track_purity[ok] > 0) & (s.track_purity[ok] <= 1))
    if ok.any():
        assert min(s.track_purity[ok]) - 1e-12 <= s.purity <= max(s.track_purity[ok]) + 1e-12
    # every sampled track estimate is one the tracker gave, at most a window old
    tt, ti, tp = _rows(tracks)
    for t, i, p in zip(*s.tracks_sampled, strict=True):
        cand = (ti == i) & (tt <= t) & (tt > t - window)
        assert cand.any()
        k = np.flatnonzero(cand)[np.argmax(tt[cand])]
        np.testing.assert_array_equal(tp[k], p)
    json.dumps(s.as_dict(), allow_nan=False)


# ----------------------------------------------------------------------------- bad input


def _good():
    truth, tracks = _swap_scene()
    return [*truth, *tracks]


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"window": 0.0}, "window"),
        ({"window": -5.0}, "window"),
        ({"window": float("nan")}, "window"),
        ({"window": True}, "window"),
        ({"window": 1e-9}, "window"),  # far too many instants
        ({"c": 0.0}, "c must"),
        ({"c": float("inf")}, "c must"),
        ({"c": True}, "c must"),
        ({"max_gap": 0.0}, "max_gap"),
        ({"max_gap": -1.0}, "max_gap"),
        ({"duration": 0.0}, "duration"),
        ({"t0": float("nan")}, "t0"),
    ],
)
def test_bad_parameters(kw, match):
    args = {"window": 10.0, "c": C, **kw}
    with pytest.raises(ValueError, match=match):
        score_self_reports(*_good(), **args)


def _replace(i, value):
    args = _good()
    args[i] = value
    return args


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (_replace(2, np.where(np.arange(16)[:, None] == 3, np.nan, _good()[2])), "truth_positions"),
        (_replace(5, np.full((16, 2), np.nan)), "track_positions"),
        (_replace(0, np.arange(15.0)), "truth_ids has 16 entries but truth_times has 15"),
        (_replace(4, np.arange(3)), "track_ids has 3 entries"),
        (_replace(5, np.zeros((4, 2))), "track_positions has 4 rows"),
        (_replace(1, np.array([True, False] * 8)), "truth_ids holds booleans"),
        (_replace(4, [True] * 16), "track_ids holds booleans"),
        (_replace(0, [True] * 16), "truth_times"),
        (_replace(2, np.ones((16, 2), dtype=bool)), "truth_positions"),
        (_replace(1, np.arange(16) + 0.5), "truth_ids"),
        (_replace(1, [str(i) for i in range(16)]), "truth_ids"),
        (_replace(3, np.arange(16) + 1j), "track_times"),
        (_replace(5, np.zeros((16, 3))), "3-D"),
        (_replace(0, [10**400] * 16), "truth_times"),
        (_replace(3, np.zeros(16)), "a track id appears twice"),
    ],
)
def test_bad_tables(args, match):
    with pytest.raises(ValueError, match=match):
        score_self_reports(*args, window=10.0, c=C)


# ----------------------------------------------------------------------------- issue 32.6:
# ids held ≥ 1 min, and coverage split into straight / manoeuvre / close pair


@settings(max_examples=30, deadline=None)
@given(
    lengths=st.lists(st.integers(1, 12), min_size=1, max_size=6),
    gap=st.integers(0, 3),
    hold=st.sampled_from([10.0, 30.0, 60.0, 120.0]),
)
def test_ids_held_counts_only_ids_associated_for_hold_seconds(lengths, gap, hold):
    # one identity reported every 10 s on a line; consecutive track segments of the
    # drawn lengths (in instants), each with a new id, with `gap` untracked instants
    # between them: an id is held when its length · 10 s ≥ hold
    n = sum(lengths) + gap * len(lengths)
    t = 10.0 * np.arange(n)
    truth = (t, np.ones(n, int), np.c_[200.0 * t, 0.0 * t])
    rows, k = [], 0
    for seg, length in enumerate(lengths):
        rows += [(10.0 * j, 100 + seg, 2000.0 * j, 0.0) for j in range(k, k + length)]
        k += length + gap
    s = score_self_reports(*truth, *_rows(rows), window=10.0, c=C, hold=hold)
    held = sum(10.0 * length >= hold for length in lengths)
    assert s.tracks_per_identity == len(lengths)
    assert s.identity_tracks_held.tolist() == [held]
    assert s.n_identities_held == (held > 0)
    if held:
        assert s.tracks_per_identity_held == held
    else:
        assert math.isnan(s.tracks_per_identity_held)
    d = s.as_dict()
    assert d["per_identity"]["1"]["tracks_held"] == held and d["hold"] == hold


def _circle(t, speed, omega, centre):
    """Positions on a constant-rate turn (rad/s) at constant speed about ``centre``."""
    r = speed / abs(omega)
    a = omega * t
    return np.c_[centre[0] + r * np.sin(a), centre[1] - np.sign(omega) * r * np.cos(a)]


@settings(max_examples=30, deadline=None)
@example(n=8, speed=20.0, heading=0.0, omega_deg=1.5, pair=(0, 1), dist=1999.0, partner=1, seed=0)
@given(
    n=st.integers(8, 30),
    speed=st.floats(20.0, 300.0),
    heading=st.floats(-math.pi, math.pi),
    omega_deg=st.floats(1.5, 5.5) | st.floats(-5.5, -1.5),
    pair=st.tuples(st.integers(0, 29), st.integers(1, 30)),
    dist=st.floats(100.0, 1999.0),
    partner=st.sampled_from([0, 1]),
    seed=st.integers(0, 2**32 - 1),
)
def test_coverage_split_by_class_matches_the_construction(
    n, speed, heading, omega_deg, pair, dist, partner, seed
):
    # A (id 1) flies straight; B (id 2) turns at omega (> 1 °/s) 1,000 km away; C (id 3)
    # flies at a constant offset `dist` (< 2 km) from A or B over instants [k1, k2) only.
    # Reports every 10 s on the instants, so t ± 30 s are report times and B's chords
    # turn by exactly omega · 30 s. Tracks sit on the truth at a random subset of points.
    k1 = min(pair[0], n - 1)
    k2 = min(max(pair[1], k1 + 1), n)
    t = 10.0 * np.arange(n)
    a = np.c_[speed * np.cos(heading) * t, speed * np.sin(heading) * t]
    b = _circle(t, speed, math.radians(omega_deg), (1e6, 0.0))
    off = dist * np.array([math.cos(heading + 1.0), math.sin(heading + 1.0)])
    c = (a if partner == 0 else b)[k1:k2] + off
    times = np.r_[t, t, t[k1:k2]]
    ids = np.r_[np.full(n, 1), np.full(n, 2), np.full(k2 - k1, 3)]
    pos = np.r_[a, b, c]
    # by construction: 0 straight, 1 manoeuvre, 2 close pair
    cls_a = np.zeros(n, int)
    cls_b = np.zeros(n, int)
    cls_b[3 : n - 3] = 1  # B's points with both t ± 30 s inside its reports
    (cls_a if partner == 0 else cls_b)[k1:k2] = 2
    expected = np.r_[cls_a, cls_b, np.full(k2 - k1, 2)]
    tracked = np.random.default_rng(seed).random(times.size) < 0.6
    tracks = (times[tracked], 100 + ids[tracked], pos[tracked])
    s = score_self_reports(times, ids, pos, *tracks, window=10.0, c=50.0)
    # the score's class of every truth point, matched to the construction by (id, time)
    got = {
        (int(i), float(x)): int(k)
        for i, x, k in zip(s.truth_sampled[1], s.truth_sampled[0], s.class_of, strict=True)
    }
    want = {(int(i), float(x)): int(k) for i, x, k in zip(ids, times, expected, strict=True)}
    assert got == want
    for k, name in enumerate(("straight", "manoeuvre", "close_pair")):
        n_k = int(np.sum(expected == k))
        hit = int(np.sum(tracked & (expected == k)))
        assert getattr(s, f"n_{name}") == n_k
        if n_k:
            assert getattr(s, f"coverage_{name}") == hit / n_k
            assert getattr(s, f"lost_{name}") == (n_k - hit) / n_k
        else:
            assert math.isnan(getattr(s, f"coverage_{name}"))
            assert s.as_dict()[f"coverage_{name}"] is None
    assert s.n_straight + s.n_manoeuvre + s.n_close_pair == s.n_identity_instants


def test_a_slow_or_stationary_target_is_not_manoeuvring_and_thresholds_are_named():
    # a vessel at anchor jittering by metres: its heading swings wildly but it moves
    # < min_speed along its chords; at min_speed = 0 the same jitter is a "manoeuvre"
    t = 10.0 * np.arange(20)
    jitter = np.random.default_rng(5).normal(0.0, 3.0, (20, 2))
    truth = (t, np.ones(20, int), jitter)
    empty = (np.zeros(0), np.zeros(0, int), np.zeros((0, 2)))
    s = score_self_reports(*truth, *empty, window=10.0, c=C)
    assert s.n_manoeuvre == 0 and s.n_straight == 20
    s0 = score_self_reports(*truth, *empty, window=10.0, c=C, min_speed=0.0)
    assert s0.n_manoeuvre > 0
    for key, bad in [
        ("hold", 0.0),
        ("turn_rate", -1.0),
        ("turn_span", math.nan),
        ("min_speed", -0.5),
        ("pair_distance", True),
        ("turn_rate", 1j),
    ]:
        with pytest.raises((ValueError, TypeError), match=key):
            score_self_reports(*truth, *empty, window=10.0, c=C, **{key: bad})


_coord = st.one_of(
    st.just(0.0),
    st.floats(5e-324, 1e300),
    st.floats(-1e300, -5e-324),
    st.floats(-1e4, 1e4),
)


@settings(max_examples=25, deadline=None)
@given(
    xy=st.lists(st.tuples(_coord, _coord), min_size=9, max_size=9),
    k=st.integers(-30, 30),
)
def test_classes_at_any_magnitude_warn_nothing_and_scale_by_powers_of_two(xy, k):
    # three identities with three reports each at values from subnormal to 1e300 and
    # zeros: no warning, every point classified, counts adding up; scaling positions,
    # pair_distance and min_speed by 2**k (exact) changes no class where nothing
    # over- or underflows
    import warnings

    t = np.tile([0.0, 30.0, 60.0], 3)
    ids = np.repeat([1, 2, 3], 3)
    pos = np.array(xy, dtype=np.float64)
    empty = (np.zeros(0), np.zeros(0, int), np.zeros((0, 2)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = score_self_reports(t, ids, pos, *empty, window=30.0, c=C)
    assert set(s.class_of.tolist()) <= {0, 1, 2} and s.class_of.size == s.n_identity_instants
    assert s.n_straight + s.n_manoeuvre + s.n_close_pair == s.n_identity_instants == 9
    assert s.coverage_straight in (0.0,) or math.isnan(s.coverage_straight)
    if np.all((np.abs(pos) < 1e200) & ((pos == 0) | (np.abs(pos) > 1e-200))):
        f = 2.0**k
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            s2 = score_self_reports(
                t,
                ids,
                pos * f,
                *empty,
                window=30.0,
                c=C * f,
                pair_distance=2000.0 * f,
                min_speed=1.0 * f,
            )
        assert s2.class_of.tolist() == s.class_of.tolist()
