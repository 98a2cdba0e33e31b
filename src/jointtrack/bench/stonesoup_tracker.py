"""Stone Soup's tutorial JPDA tracker on a jointtrack scene, under a time budget.

The construction and why it deviates from Stone Soup's example are described in
:mod:`jointtrack.bench.quality`; Stone Soup is imported lazily (the ``bench``
extra).
"""

from __future__ import annotations

import datetime
import signal
import threading
import time
from contextlib import contextmanager

import numpy as np

from jointtrack.bench.tracking_runs import TrackRun, max_true_speed, rows_to_run, tracker_q


def stonesoup_available() -> bool:
    try:
        import stonesoup  # noqa: F401
    except ImportError:
        return False
    return True


def stonesoup_tracker(sc, data_associator=None, hypothesiser_class=None):
    """Stone Soup's tutorial JPDA tracker with the scene's physical settings (module docstring).

    ``data_associator`` is a factory ``hypothesiser → DataAssociator`` for the
    tracker's JPDA associator (default Stone Soup's ``JPDAwithEHM2``), e.g.
    :class:`jointtrack.interop.stonesoup.JPDAExact`; the initiator keeps its own
    ``GNNWith2DAssignment``. ``hypothesiser_class`` replaces Stone Soup's
    ``PDAHypothesiser`` for both (e.g.
    :class:`jointtrack.interop.stonesoup.FastPDAHypothesiser`). Returns
    ``(tracker, measurement_model)``.
    """
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.dataassociator.probability import JPDAwithEHM2
    from stonesoup.deleter.time import UpdateTimeStepsDeleter
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.initiator.simple import MultiMeasurementInitiator
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
    )
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.tracker.simple import MultiTargetMixtureTracker
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import KalmanUpdater

    q = tracker_q(sc)
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])
    measurement = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.asarray(sc.R))
    predictor = KalmanPredictor(transition)
    updater = KalmanUpdater(measurement)

    def hypothesiser():
        return (hypothesiser_class or PDAHypothesiser)(
            predictor=predictor,
            updater=updater,
            clutter_spatial_density=float(sc.clutter_density),
            prob_detect=float(sc.p_d),
        )

    deleter = UpdateTimeStepsDeleter(3)
    sv2 = (1.5 * max_true_speed(sc) / 2) ** 2 or 1.0
    initiator = MultiMeasurementInitiator(
        prior_state=GaussianState(np.zeros((4, 1)), np.diag([0.0, sv2, 0.0, sv2])),
        measurement_model=measurement,
        deleter=deleter,
        data_associator=GNNWith2DAssignment(hypothesiser()),
        updater=updater,
        min_points=2,
    )
    tracker = MultiTargetMixtureTracker(
        initiator=initiator,
        deleter=deleter,
        detector=None,
        data_associator=(data_associator or JPDAwithEHM2)(hypothesiser()),
        updater=updater,
    )
    return tracker, measurement


class _OutOfTime(BaseException):
    """Raised by the budget alarm; a BaseException so no ``except Exception`` swallows it."""


@contextmanager
def _time_limit(seconds: float | None):
    """Raise :class:`_OutOfTime` after ``seconds`` (SIGALRM; main thread on POSIX only,
    elsewhere no limit)."""
    if (
        seconds is None
        or not hasattr(signal, "setitimer")
        or threading.current_thread() is not threading.main_thread()
    ):
        yield
        return

    def alarm(signum, frame):
        raise _OutOfTime

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


EPOCH = datetime.datetime(2000, 1, 1)


def run_stonesoup(sc, budget: float | None = None) -> TrackRun:
    """Run Stone Soup's tutorial JPDA tracker over the scene from nothing.

    Times ``update_tracker`` only (the Stone Soup ``Detection`` objects are built
    first). With ``budget`` seconds, the run stops at the budget and reports the
    scans it completed.
    """
    from stonesoup.types.detection import Detection

    tracker, mm = stonesoup_tracker(sc)
    stamps = [EPOCH + datetime.timedelta(seconds=float(t)) for t in sc.times]
    scans = [
        {Detection(z.reshape(-1, 1), timestamp=ts, measurement_model=mm) for z in Z}
        for ts, Z in zip(stamps, sc.detections, strict=True)
    ]
    labels: dict = {}  # Stone Soup track → integer id
    rows: list = []
    done = 0
    seconds = 0.0
    t0 = time.perf_counter()
    try:
        with _time_limit(budget):
            for k, (ts, dets) in enumerate(zip(stamps, scans, strict=True)):
                t0 = time.perf_counter()
                _, tracks = tracker.update_tracker(ts, dets)
                seconds += time.perf_counter() - t0
                t = float(sc.times[k])
                rows.extend(
                    (
                        t,
                        labels.setdefault(trk.id, len(labels)),
                        trk.state_vector[0, 0],
                        trk.state_vector[2, 0],
                    )
                    for trk in tracks
                )
                done = k + 1
    except _OutOfTime:
        seconds += time.perf_counter() - t0  # the scan the budget interrupted took this long
    completed = done == sc.n_scans
    # rows of a scan interrupted between its update and its count are dropped
    rows = [r for r in rows if r[0] <= sc.times[done - 1]] if done else []
    return rows_to_run(rows, seconds, done, completed)
