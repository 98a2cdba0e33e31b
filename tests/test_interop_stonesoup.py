"""Stone Soup drop-in associators and converters (jointtrack.interop.stonesoup).

On Stone Soup's own objects (a linear-Gaussian PDAHypothesiser, tracks and
detections, as in their test fixtures) our associators must give exactly what
``JPDAwithEHM2`` gives, a Stone Soup tracker must run unchanged with ours, and
Stone Soup's metric generators must run on our tracker's output.
"""

from __future__ import annotations

import datetime
import logging

import numpy as np
import pytest

pytest.importorskip("stonesoup")

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from stonesoup.dataassociator.probability import JPDAwithEHM2, JPDAwithLBP  # noqa: E402
from stonesoup.hypothesiser.distance import DistanceHypothesiser  # noqa: E402
from stonesoup.hypothesiser.probability import PDAHypothesiser  # noqa: E402
from stonesoup.measures import Mahalanobis  # noqa: E402
from stonesoup.models.measurement.linear import LinearGaussian  # noqa: E402
from stonesoup.models.transition.linear import (  # noqa: E402
    CombinedLinearGaussianTransitionModel,
    ConstantVelocity,
)
from stonesoup.predictor.kalman import KalmanPredictor  # noqa: E402
from stonesoup.types.detection import Clutter, Detection, TrueDetection  # noqa: E402
from stonesoup.types.groundtruth import GroundTruthPath, GroundTruthState  # noqa: E402
from stonesoup.types.state import GaussianState  # noqa: E402
from stonesoup.types.track import Track  # noqa: E402
from stonesoup.updater.kalman import KalmanUpdater  # noqa: E402

from jointtrack.association.lbp import lbp_marginals  # noqa: E402
from jointtrack.errors import ExactLimitError  # noqa: E402
from jointtrack.interop.stonesoup import (  # noqa: E402
    JPDALBP,
    FastPDAHypothesiser,
    JPDAExact,
    scans_from_stonesoup,
    tracks_to_stonesoup,
    truth_from_stonesoup,
)
from jointtrack.metrics import gospa_series  # noqa: E402
from jointtrack.trackers import JPDATracker, TrackerConfig  # noqa: E402

T0 = datetime.datetime(2025, 1, 1)
T1 = T0 + datetime.timedelta(seconds=1)
TRANSITION = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.05)] * 2)
MEASUREMENT = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2))


def _hypothesiser(p_d=0.9, clutter=1e-3, p_g=0.99, include_all=False):
    return PDAHypothesiser(
        predictor=KalmanPredictor(TRANSITION),
        updater=KalmanUpdater(MEASUREMENT),
        clutter_spatial_density=clutter,
        prob_detect=p_d,
        prob_gate=p_g,
        include_all=include_all,
    )


def _track(x, y, vx=1.0, vy=0.0, var=1.0):
    return Track([GaussianState([[x], [vx], [y], [vy]], np.diag([var, 0.5, var, 0.5]), T0)])


def _detection(x, y):
    return Detection([[x], [y]], timestamp=T1, measurement_model=MEASUREMENT)


def _as_table(result):
    """track → [(measurement, probability)] in the associator's order."""
    return {trk: [(h.measurement, float(h.probability)) for h in mh] for trk, mh in result.items()}


def _assert_same(ours, theirs, tol=1e-12):
    assert set(ours) == set(theirs)
    for trk in theirs:
        a, b = ours[trk], theirs[trk]
        assert len(a) == len(b)
        for (ma, pa), (mb, pb) in zip(a, b, strict=True):
            if mb:  # the same detection object, or both missed detections
                assert ma is mb
            else:
                assert not ma
            assert abs(pa - pb) <= tol, (pa, pb)
        assert abs(sum(p for _, p in a) - 1.0) <= 1e-12


coordinate = st.floats(-6.0, 6.0, allow_nan=False, allow_infinity=False)


@st.composite
def scenes(draw):
    """Tracks and detections drawn near each other, plus far-away ones of each kind."""
    tracks = [
        _track(draw(coordinate), draw(coordinate), var=draw(st.floats(0.2, 3.0)))
        for _ in range(draw(st.integers(0, 5)))
    ]
    if draw(st.booleans()):  # a track whose gate holds no detection
        tracks.append(_track(500.0, 500.0))
    dets = [_detection(draw(coordinate), draw(coordinate)) for _ in range(draw(st.integers(0, 8)))]
    if draw(st.booleans()):  # a detection no track gates
        dets.append(_detection(-400.0, 300.0))
    p_d = draw(st.sampled_from([0.5, 0.9, 0.999]))
    clutter = draw(st.sampled_from([1e-6, 1e-3, 0.1]))
    include_all = draw(st.booleans())  # every pair hypothesised, gated or not
    return set(tracks), set(dets), p_d, clutter, include_all


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenes())
def test_exact_equals_ehm2_on_random_scenes(scene):
    tracks, dets, p_d, clutter, include_all = scene
    hyp = _hypothesiser(p_d=p_d, clutter=clutter, include_all=include_all)
    theirs = JPDAwithEHM2(hyp).associate(tracks, dets, T1)
    ours = JPDAExact(hyp).associate(tracks, dets, T1)
    _assert_same(_as_table(ours), _as_table(theirs))
    for mh in ours.values():  # missed detection first, as Stone Soup's hypothesiser gives it
        assert not mh[0].measurement
        assert type(mh[0]).__name__ == "SingleProbabilityHypothesis"


def test_exact_equals_ehm2_in_the_cases_named():
    hyp = _hypothesiser()
    near = [_track(0, 0), _track(1.5, 0), _track(3, 0)]
    lonely = _track(300, 300)  # no gated detection
    dets = {_detection(x, 0.2) for x in (0.1, 1.4, 2.0, 2.9)} | {_detection(-200, -200)}
    for tracks, scan in [
        (set(near) | {lonely}, dets),
        (set(near), set()),  # an empty scan
        (set(), dets),  # no tracks
        ({}, dets),  # Stone Soup's own tests pass empty dicts
        (set(near), {}),
        ({lonely}, dets),  # only a track with nothing gated
    ]:
        ours = JPDAExact(hyp).associate(tracks, scan, T1)
        theirs = JPDAwithEHM2(hyp).associate(tracks, scan, T1)
        _assert_same(_as_table(ours), _as_table(theirs))
        for trk, mh in theirs.items():
            assert (ours[trk].normalise, ours[trk].total_weight) == (mh.normalise, mh.total_weight)
    out = JPDAExact(hyp).associate({lonely}, dets, T1)
    assert [float(h.probability) for h in out[lonely]] == [1.0]


def test_lbp_associator_is_our_lbp_and_exact_for_single_tracks():
    hyp = _hypothesiser()
    tracks = [_track(0, 0), _track(1.0, 0.3), _track(2.0, 0)]
    dets = [_detection(x, y) for x, y in [(0.2, 0.1), (1.1, 0.2), (1.9, -0.1), (0.9, 0.5)]]
    assoc = JPDALBP(hyp)
    ours = _as_table(assoc.associate(set(tracks), set(dets), T1))
    assert assoc.last_clusters[0][2] == "lbp"
    hyps = {t: hyp.hypothesise(t, set(dets), T1) for t in tracks}
    L = np.zeros((3, 4))
    miss = np.zeros(3)
    for i, t in enumerate(tracks):
        for h in hyps[t]:
            if h:
                L[i, dets.index(h.measurement)] = float(h.probability)
            else:
                miss[i] = float(h.probability)
    beta, _ = lbp_marginals(L / miss[:, None], np.ones(3))
    for i, t in enumerate(tracks):
        got = {(id(m) if m else None): p for m, p in ours[t]}
        assert got[None] == pytest.approx(beta[i, 0], abs=1e-12)
        for j, d in enumerate(dets):
            if id(d) in got:
                assert got[id(d)] == pytest.approx(beta[i, j + 1], abs=1e-12)
    # LBP is approximate on this loopy cluster, but close to Stone Soup's own LBP
    theirs = _as_table(JPDAwithLBP(hyp).associate(set(tracks), set(dets), T1))
    for t in tracks:
        mine = {(id(m) if m else None): p for m, p in ours[t]}
        other = {(id(m) if m else None): p for m, p in theirs[t]}
        assert mine.keys() == other.keys()
        assert max(abs(mine[k] - other[k]) for k in mine) < 1e-2
    single = {tracks[0]}
    _assert_same(
        _as_table(JPDALBP(hyp).associate(single, set(dets), T1)),
        _as_table(JPDAwithEHM2(hyp).associate(single, set(dets), T1)),
    )


def _dense_cluster(n):
    tracks = {_track(1.2 * i, 0, var=4.0) for i in range(n)}
    dets = {_detection(1.2 * i + 0.3, 0.2) for i in range(n + 2)}
    return tracks, dets


def test_budget_policy_falls_back_to_lbp_and_says_so(caplog):
    hyp = _hypothesiser(clutter=1e-2)
    tracks, dets = _dense_cluster(7)
    exact = JPDAExact(hyp).associate(tracks, dets, T1)
    assert JPDAExact(hyp).associate(tracks, dets, T1) is not None
    small = JPDAExact(hyp, max_bits=2)
    with caplog.at_level(logging.WARNING, logger="jointtrack.interop.stonesoup"):
        approx = small.associate(tracks, dets, T1)
    (n_tracks, _, method, reason), *_ = sorted(small.last_clusters, reverse=True)
    assert n_tracks == 7 and method == "lbp" and reason.startswith("refused")
    assert "past the exact budget" in caplog.text
    gap = max(
        abs(pa - pb)
        for t in tracks
        for (_, pa), (_, pb) in zip(_as_table(approx)[t], _as_table(exact)[t], strict=True)
    )
    assert 0 < gap < 0.05  # an approximation, and a good one
    few = JPDAExact(hyp, exact_max_tracks=3)
    few.associate(tracks, dets, T1)
    assert any(r == "exact_max_tracks" for *_, r in few.last_clusters)
    with pytest.raises(ExactLimitError, match="past the exact budget"):
        JPDAExact(hyp, max_bits=2, approximation="raise").associate(tracks, dets, T1)


def test_bad_input_is_named():
    hyp = _hypothesiser()
    with pytest.raises(ValueError, match="approximation"):
        JPDAExact(hyp, approximation="guess")
    with pytest.raises(ValueError, match="max_bits"):
        JPDAExact(hyp, max_bits=-1)
    with pytest.raises(ValueError, match="exact_max_tracks"):
        JPDAExact(hyp, exact_max_tracks=True)
    distance = DistanceHypothesiser(
        KalmanPredictor(TRANSITION), KalmanUpdater(MEASUREMENT), Mahalanobis(), 10
    )
    with pytest.raises(TypeError, match="probability hypotheses"):
        JPDAExact(distance).associate({_track(0, 0)}, {_detection(0, 0)}, T1)


def test_extreme_weights_stay_exact():
    # weights far outside float range once exponentiated: Stone Soup keeps them in
    # log space (Probability), and so do we
    hyp = _hypothesiser(clutter=1e-300, p_d=0.999999)
    tracks = {_track(0, 0, var=1e-6), _track(0.5, 0, var=1e-6)}
    dets = {_detection(0.0, 0.0), _detection(0.5, 0.0), _detection(0.25, 0.0)}
    _assert_same(
        _as_table(JPDAExact(hyp).associate(tracks, dets, T1)),
        _as_table(JPDAwithEHM2(hyp).associate(tracks, dets, T1)),
        tol=1e-12,
    )


# ------------------------------------------------------------- the tracker
def _scene(seed, n_steps=50):
    """Three targets crossing, P_D 0.9, a few clutter returns per scan (Stone Soup objects)."""
    rng = np.random.default_rng(seed)
    starts = [(-20.0, -20.0, 1.0, 1.0), (-20.0, 20.0, 1.0, -1.0), (-25.0, 0.0, 1.0, 0.0)]
    paths = [GroundTruthPath(id=f"target-{k}") for k in range(3)]
    scans = []
    for k in range(n_steps):
        t = T0 + datetime.timedelta(seconds=k)
        dets = set()
        for path, (x, y, vx, vy) in zip(paths, starts, strict=True):
            sv = np.array([[x + vx * k], [vx], [y + vy * k], [vy]])
            path.append(GroundTruthState(sv, timestamp=t))
            if rng.random() < 0.9:
                z = MEASUREMENT.function(path[-1], noise=False) + rng.normal(0, 1, (2, 1))
                dets.add(
                    TrueDetection(
                        z, timestamp=t, measurement_model=MEASUREMENT, groundtruth_path=path
                    )
                )
        for _ in range(rng.poisson(2)):
            z = rng.uniform(-40, 40, (2, 1))
            dets.add(Clutter(z, timestamp=t, measurement_model=MEASUREMENT))
        scans.append((t, dets))
    return paths, scans


def _stonesoup_tracker(associator_class, hypothesiser_class=PDAHypothesiser):
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.deleter.time import UpdateTimeStepsDeleter
    from stonesoup.initiator.simple import MultiMeasurementInitiator
    from stonesoup.tracker.simple import MultiTargetMixtureTracker

    updater = KalmanUpdater(MEASUREMENT)

    def hypothesiser():
        return hypothesiser_class(
            predictor=KalmanPredictor(TRANSITION),
            updater=updater,
            clutter_spatial_density=2 / 80**2,
            prob_detect=0.9,
            prob_gate=0.99,
        )

    deleter = UpdateTimeStepsDeleter(3)
    initiator = MultiMeasurementInitiator(
        prior_state=GaussianState(np.zeros((4, 1)), np.diag([0.0, 4.0, 0.0, 4.0])),
        measurement_model=MEASUREMENT,
        deleter=deleter,
        data_associator=GNNWith2DAssignment(hypothesiser()),
        updater=updater,
        min_points=2,
    )
    return MultiTargetMixtureTracker(
        initiator=initiator,
        deleter=deleter,
        detector=None,
        data_associator=associator_class(hypothesiser()),
        updater=updater,
    )


def _states(tracks):
    return sorted(tuple(np.round(np.ravel(t.state_vector), 6)) for t in tracks)


def test_stonesoup_tracker_runs_50_steps_unchanged_with_ours():
    _, scans = _scene(seed=3)
    theirs, ours = _stonesoup_tracker(JPDAwithEHM2), _stonesoup_tracker(JPDAExact)
    n_multi = 0
    for t, dets in scans:
        _, a = theirs.update_tracker(t, dets)
        _, b = ours.update_tracker(t, dets)
        assert len(a) == len(b)
        sa = np.array(_states(a)).reshape(len(a), 4)
        sb = np.array(_states(b)).reshape(len(b), 4)
        np.testing.assert_allclose(sb, sa, rtol=0, atol=1e-5)
        n_multi += any(n > 1 for n, *_ in ours.data_associator.last_clusters)
    assert len(b) >= 3  # the targets are tracked ...
    assert n_multi >= 5  # ... and the JPDA had real multi-track clusters to solve


# ------------------------------------------------------------- converters
def test_scans_from_stonesoup_sorts_and_keeps_everything():
    _, scans = _scene(seed=1, n_steps=5)
    ours = scans_from_stonesoup(scans)
    assert [t for t, _ in ours] == [t for t, _ in scans]
    for (_, z), (_, dets) in zip(ours, scans, strict=True):
        assert z.shape == (len(dets), 2)
        want = sorted(tuple(np.ravel(d.state_vector)) for d in dets)
        assert [tuple(r) for r in z] == want
    assert scans_from_stonesoup([(T0, set())])[0][1].shape == (0, 0)
    with pytest.raises(TypeError, match="pairs"):
        scans_from_stonesoup([1, 2])
    with pytest.raises(TypeError, match="not a Stone Soup detection"):
        scans_from_stonesoup([(T0, {"a"})])
    with pytest.raises(TypeError, match="TrackHistory"):
        tracks_to_stonesoup([1, 2, 3], epoch=T0)


def test_truth_round_trip_and_reordering():
    paths, _ = _scene(seed=0, n_steps=4)
    time, ids, x = truth_from_stonesoup(paths, epoch=T0)
    assert time.tolist() == [0.0, 1.0, 2.0, 3.0] * 3
    assert sorted(set(ids.tolist())) == [0, 1, 2]
    first = np.ravel(paths[0][1].state_vector)  # [x, vx, y, vy]
    np.testing.assert_array_equal(x[1], first[[0, 2, 1, 3]])  # ours: [x, y, vx, vy]
    with pytest.raises(ValueError, match="permutation"):
        truth_from_stonesoup(paths, epoch=T0, state_index=[0, 0, 1, 2])


def test_stonesoup_metric_generator_runs_on_our_tracks():
    """Our tracker on Stone Soup detections; their GOSPA on our output = ours on arrays."""
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.ospametric import GOSPAMetric

    paths, scans = _scene(seed=2, n_steps=30)
    cfg = TrackerConfig(
        process_noise=0.05, measurement_noise=1.0, p_d=0.9, clutter_density=2 / 80**2
    )
    trk = JPDATracker(cfg)
    for t, z in scans_from_stonesoup(scans):
        trk.step(t, z)
    history = trk.history()
    assert len(history) > 0 and history.time_origin is not None
    tracks = tracks_to_stonesoup(history)
    assert len(tracks) == len(history.track_ids)
    some = next(iter(tracks))
    tid = int(some.id.split("-")[1])
    rows = history.track_id == tid
    np.testing.assert_array_equal(
        np.ravel(some.states[0].state_vector), history.x[rows][0][[0, 2, 1, 3]]
    )
    np.testing.assert_array_equal(
        some.states[0].covar, history.P[rows][0][np.ix_([0, 2, 1, 3], [0, 2, 1, 3])]
    )
    truth = truth_from_stonesoup(paths, epoch=T0)
    # Stone Soup's generator on Stone Soup objects made from our output
    metric = GOSPAMetric(c=10, p=2, measure=Euclidean(mapping=(0, 2)))
    track_states = [s for t in sorted(tracks, key=lambda t: t.id) for s in t.states]
    track_ids = [t.id for t in sorted(tracks, key=lambda t: t.id) for _ in t.states]
    truth_states = [s for p in sorted(paths, key=lambda p: p.id) for s in p.states]
    truth_ids = [p.id for p in sorted(paths, key=lambda p: p.id) for _ in p.states]
    theirs = metric.compute_over_time(track_states, track_ids, truth_states, truth_ids)
    by_time = {v.timestamp: v.value["distance"] for v in theirs.value}
    # ours on the arrays, scans with tracks only (Stone Soup skips track-less scans)
    assert history.time_origin == "2025-01-01T00:00:00+00:00"  # time 0 is the first scan
    mine = gospa_series(
        *(truth[0], truth[1], truth[2][:, :2]),
        *(history.time, history.track_id, history.x[:, :2]),
        c=10,
        p=2,
    )
    compared = 0
    for t, value in zip(mine.times, mine.gospa, strict=True):
        stamp = T0 + datetime.timedelta(seconds=float(t))
        if stamp in by_time:
            assert by_time[stamp] == pytest.approx(value, rel=1e-12, abs=1e-12)
            compared += 1
    assert compared >= 20


def test_tracks_to_stonesoup_needs_a_time_origin_or_epoch():
    cfg = TrackerConfig(process_noise=0.05, measurement_noise=1.0, clutter_density=2 / 80**2)
    trk = JPDATracker(cfg)
    for k, (_, z) in enumerate(scans_from_stonesoup(_scene(seed=2, n_steps=20)[1])):
        trk.step(float(k), z)  # numeric scan times: no time origin
    h = trk.history()
    assert len(h) > 0
    with pytest.raises(ValueError, match="epoch"):
        tracks_to_stonesoup(h)
    out = tracks_to_stonesoup(h, epoch=T0)
    stamps = sorted(s.timestamp for t in out for s in t.states)
    assert stamps == sorted(T0 + datetime.timedelta(seconds=float(t)) for t in h.time)


# ------------------------------------------------------------- the hypothesiser
def _fast(**kw):
    base = _hypothesiser(**kw)
    return FastPDAHypothesiser(
        predictor=base.predictor,
        updater=base.updater,
        clutter_spatial_density=base.clutter_spatial_density,
        prob_detect=base.prob_detect,
        prob_gate=base.prob_gate,
        include_all=base.include_all,
    )


def _assert_same_hypotheses(ours, theirs):
    assert [h.measurement for h in ours if h] == [h.measurement for h in theirs if h]
    assert len(ours) == len(theirs)
    for a, b in zip(ours, theirs, strict=True):
        assert abs(float(a.probability) - float(b.probability)) <= 1e-12
        np.testing.assert_allclose(a.prediction.state_vector, b.prediction.state_vector, 1e-13)
        if b:
            mp_a, mp_b = a.measurement_prediction, b.measurement_prediction
            np.testing.assert_allclose(mp_a.state_vector, mp_b.state_vector, rtol=1e-13)
            np.testing.assert_allclose(mp_a.covar, mp_b.covar, rtol=1e-13)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenes(), st.booleans())
def test_fast_hypothesiser_equals_pda_hypothesiser(scene, estimate_clutter):
    tracks, dets, p_d, clutter, include_all = scene
    if estimate_clutter:  # Stone Soup's validation-region form (needs include_all off)
        clutter, include_all = None, False
    kw = {"p_d": p_d, "clutter": clutter, "include_all": include_all}
    fast, slow = _fast(**kw), _hypothesiser(**kw)
    for trk in tracks:
        _assert_same_hypotheses(fast.hypothesise(trk, dets, T1), slow.hypothesise(trk, dets, T1))


def test_fast_hypothesiser_falls_back_for_nonlinear_models():
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange

    radar = CartesianToBearingRange(
        ndim_state=4, mapping=(0, 2), noise_covar=np.diag([1e-4, 1.0]), translation_offset=None
    )
    trk = _track(10.0, 5.0)
    dets = {
        Detection(
            radar.function(_track(x, y).state, noise=False), timestamp=T1, measurement_model=radar
        )
        for x, y in [(11.0, 5.2), (9.0, 4.0), (40.0, -3.0)]
    }
    from stonesoup.updater.kalman import ExtendedKalmanUpdater

    base = PDAHypothesiser(
        KalmanPredictor(TRANSITION), ExtendedKalmanUpdater(radar), clutter_spatial_density=1e-3
    )
    fast = FastPDAHypothesiser(
        KalmanPredictor(TRANSITION), ExtendedKalmanUpdater(radar), clutter_spatial_density=1e-3
    )
    a, b = fast.hypothesise(trk, dets, T1), base.hypothesise(trk, dets, T1)
    assert [float(h.probability) for h in a] == [float(h.probability) for h in b]
    assert len(a) >= 2


def test_stonesoup_tracker_with_fast_hypothesiser_and_ours_tracks_as_ehm2():
    _, scans = _scene(seed=4)
    theirs = _stonesoup_tracker(JPDAwithEHM2)
    ours = _stonesoup_tracker(JPDAExact, hypothesiser_class=FastPDAHypothesiser)
    assert isinstance(ours.data_associator.hypothesiser, FastPDAHypothesiser)
    for t, dets in scans:
        _, a = theirs.update_tracker(t, dets)
        _, b = ours.update_tracker(t, dets)
        assert len(a) == len(b)
        np.testing.assert_allclose(
            np.array(_states(b)).reshape(len(b), 4),
            np.array(_states(a)).reshape(len(a), 4),
            rtol=0,
            atol=1e-5,
        )
    assert len(b) >= 3


# ------------------------------------------------------------- YAML configurations
def test_stonesoup_yaml_configuration_with_our_components_round_trips():
    from ruamel.yaml.constructor import ConstructorError
    from stonesoup.serialise import YAML

    yaml = YAML()
    original = _stonesoup_tracker(JPDAExact, hypothesiser_class=FastPDAHypothesiser)
    original.data_associator.max_bits = 20
    text = yaml.dumps(original)
    assert "!jointtrack.interop.stonesoup.associators.JPDAExact" in text
    loaded = yaml.load(text)
    assert type(loaded.data_associator) is JPDAExact and loaded.data_associator.max_bits == 20
    assert type(loaded.data_associator.hypothesiser) is FastPDAHypothesiser
    _, scans = _scene(seed=5, n_steps=12)
    for t, dets in scans:
        _, a = original.update_tracker(t, dets)
        _, b = loaded.update_tracker(t, dets)
        assert _states(a) == _states(b)
    with pytest.raises(ConstructorError, match="not a jointtrack Stone Soup component"):
        yaml.load("!jointtrack.errors.ExactLimitError\n- x: 1\n")
    with pytest.raises(ConstructorError, match="not a jointtrack Stone Soup component"):
        yaml.load("!jointtrack.nowhere.Thing\n- x: 1\n")
