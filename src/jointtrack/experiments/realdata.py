"""``jointtrack run`` on real self-reports (AIS, ADS-B): lat/lon in, tracks in lat/lon out.

A report file (:func:`jointtrack.io.reports.read_reports`: Stone Soup's AIS CSV,
OpenSky states CSV, traffic's JSON records) is projected to a local east-north
plane about a reference point (given, or the centre of the data without its
outliers, :func:`~jointtrack.io.geodetic.data_centre`, which are left out and
counted; :class:`~jointtrack.io.geodetic.LocalFrame`, WGS-84 by pymap3d) and tracked by
:func:`jointtrack.experiments.run.run_detections` — by default one scan per
report time with the asynchronous-reporting model (``reporting = "async"`` in
:class:`~jointtrack.trackers.config.TrackerConfig`: each target a Poisson
reporter of its own rate, so a vessel silent for 30 s is not "missed" at
every other vessel's report), or in windows of ``window`` seconds.

Besides the usual outputs the run writes what every run on geodetic data writes
(:func:`geodetic_outputs`, also for a detection file with ``lat, lon`` columns)

* ``tracks.csv`` with ``lat, lon`` columns next to the local ``x, y``;
* ``metrics.json`` ``geo_reference`` (the frame's origin, the outliers left out);
* ``map.png``: the tracks over the reports on lat/lon axes;

and, for a report file, ``metrics.json`` ``self_reports``:
  the tracks scored against the targets' own reports
  (:func:`jointtrack.metrics.selfreport.score_self_reports`: GOSPA per window
  against the reported positions interpolated to the window end, coverage,
  tracks per identity, identity switches, purity, false tracks per hour).

Each is written once, in its final form (the tracks file with its ``lat, lon``
columns from the start), by the run's finishing phase, which a checkpointed run
resumes after a kill (:class:`~jointtrack.experiments.writers.ExtraOutputs`).

The identities in the file (MMSI, icao24) are used as ``labels``:
``"associate"`` (default) — association given the label and scoring;
``"score"`` — hidden from the tracker, used for scoring only; ``"ignore"``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from jointtrack.experiments.config import RunConfigError, make_tracker_config
from jointtrack.experiments.writers import ExtraOutputs

__all__ = ["LABEL_MODES", "MAX_WINDOWS", "REALDATA_TRACKER", "geodetic_outputs", "run_reports"]

#: What the reports' identities are used for (see the module docstring).
LABEL_MODES = ("associate", "score", "ignore")

#: Tracker settings for self-reporting targets, per report format; a ``[tracker]``
#: table overrides them. ``clutter_density`` is false reports per m² per second
#: and, for a JIPDA tracker, also the density of a *new* target's first report:
#: a smaller value lets an existing track claim reports far outside where it
#: should be. Chosen on the Solent AIS file (see benchmarks/RESULTS.md, issue 24).
REALDATA_TRACKER = {
    "ais": {
        "reporting": "async",
        "report_interval": 120.0,
        # per m² per (m/s)² per second: 1e-11 per m² per second spread over a
        # (20 m/s)² box of velocities (the reported speed and course are measured)
        "clutter_density": 2.5e-14,
        "measure_velocity": True,
        "velocity_std": 0.3,
        # confirm later and report surer tracks: on Solent without labels 43.8 false
        # tracks/h against 50.1 at the defaults (0.9, 0.3), coverage 0.784 vs 0.795
        "r_confirm": 0.95,
        "r_report": 0.5,
        "p_d": 0.99,
        "p_survive": 0.9999,
        "p_survive_per": "second",
        "measurement_noise": 225.0,  # σ = 15 m, as Stone Soup's AIS demo
        "process_noise": 0.005,
        "max_speed": 15.0,
        "max_coast": 600.0,  # Stone Soup's demo deletes after 10 min without update
        "r_delete": 0.0005,
        # a scan per report holds 1-3 returns: exact association of a cluster of N
        # tracks costs O(N·2^M), milliseconds even for 60 moored ships in one cluster
        "exact_max_tracks": 64,
    },
    "adsb": {
        "reporting": "async",
        "report_interval": 10.0,
        "clutter_density": 1e-13,
        "p_d": 0.99,
        "p_survive": 0.9999,
        "p_survive_per": "second",
        "measurement_noise": 2500.0,
        "process_noise": 1.0,
        "max_speed": 350.0,
        "max_coast": 120.0,
        "r_delete": 0.0005,
        "exact_max_tracks": 64,
    },
}
#: the most scan windows a run makes (``window`` against the reports' time span)
MAX_WINDOWS = 1_000_000
#: Changes to :data:`REALDATA_TRACKER` when the tracker is given the identities as
#: labels: association is then certain, and measuring the reported velocities
#: (COG jitter of slow vessels) cost purity on the Solent file (0.993 → 0.988).
LABELLED = {"measure_velocity": False, "clutter_density": 1e-11}


def realdata_settings(family: str, *, labelled: bool) -> dict:
    """The tracker settings of a report family (``"ais"``, ``"adsb"``), with or
    without labels given to the tracker (:data:`REALDATA_TRACKER`, :data:`LABELLED`)."""
    base = dict(REALDATA_TRACKER[family])
    if labelled and base.get("measure_velocity"):
        base.update(LABELLED)
    return base


#: report format → settings family
_FAMILY = {"ais": "ais", "opensky": "adsb", "traffic": "adsb"}
#: GOSPA cut-off (m) of the self-report scoring, per family
_SCORE_C = {"ais": 500.0, "adsb": 2000.0}


def run_reports(
    reports,
    config: Mapping | None = None,
    out_dir="jointtrack-out",
    fmt: str = "csv",
    progress: bool = False,
    *,
    report_format: str = "auto",
    window: float | None = None,
    reference=None,
    labels: str = "associate",
    score_window: float | None = None,
    score_c: float | None = None,
    tracker: str | None = None,
    pmbm: Mapping | None = None,
    **options,
) -> dict:
    """Track self-reports and score the tracks against them (see the module docstring).

    Parameters
    ----------
    reports : a report file path (read with ``report_format``) or a
        :class:`~jointtrack.io.reports.Reports`.
    config : ``[tracker]`` overrides on :data:`REALDATA_TRACKER` of the format.
    window : None (one scan per report time) or the scan window in seconds
        (Stone Soup's ``TimeSyncFeeder`` windows; several reports of one target
        in a window then compete as separate returns; reports with a velocity
        are dead-reckoned to the window's end).
    reference : ``(lat, lon[, alt])`` of the local frame's origin; None:
        :meth:`~jointtrack.io.reports.Reports.centre` (the centre of the
        bounding box of the reports that are not outliers; the outliers are left
        out of the run, tracking and scoring, and counted).
    labels : one of :data:`LABEL_MODES`.
    tracker, pmbm : the tracker kind — None or ``"jipda"`` (JIPDA), ``"pmb"`` or
        ``"pmbm"`` (PMB / PMBM with the same reporting model, labels and reported
        velocities; their settings are
        :func:`~jointtrack.experiments.config.make_pmbm_config` of the format's,
        with ``[pmbm]`` table ``pmbm``).
    score_window, score_c : the scoring window (s; default ``window`` or 60)
        and GOSPA cut-off (m; default 500 for AIS, 2000 for ADS-B). The
        tracks file holds the tracks at the last scan at or before each multiple of
        the scoring window (``output_interval`` in ``options`` to change it).
    options : as :func:`~jointtrack.experiments.run.run_detections`
        (``checkpoint``, ``resume``, ``max_scans``, ``console``, ``plots``, …).
    """
    from jointtrack.experiments.run import run_detections
    from jointtrack.io.reports import Reports, read_reports
    from jointtrack.io.reports import report_format as report_format_of

    if labels not in LABEL_MODES:
        raise RunConfigError(f"labels must be one of {', '.join(LABEL_MODES)}, got {labels!r}")
    for name, value in (("window", window), ("score_window", score_window), ("score_c", score_c)):
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, int | float) or not value > 0
        ):
            raise RunConfigError(f"{name} must be a positive number of seconds, got {value!r}")
        if value is not None and not math.isfinite(value):
            raise RunConfigError(f"{name} must be finite, got {value!r}")
    if isinstance(reports, Reports):
        if report_format == "auto":
            raise RunConfigError("give report_format ('ais', 'opensky' or 'traffic') with Reports")
        rep, fmt_name = reports, report_format
    else:
        fmt_name = report_format if report_format != "auto" else report_format_of(reports)
        rep = read_reports(reports, format=fmt_name or "auto")
    if not len(rep):
        raise RunConfigError(f"{rep.source or 'the reports'}: no reports to track")
    if window is not None:
        # Stone Soup's windows keep the empty ones: a window far below the reports'
        # spacing (a typo, ms for s) would make a scan list of billions (MemoryError)
        span = float(rep.times[-1] - rep.times[0])
        n_windows = math.floor(span / float(window)) + 2
        if n_windows > MAX_WINDOWS:
            raise RunConfigError(
                f"window = {window:g} s over the reports' {span:g} s makes {n_windows:,} "
                f"scans, most of them empty (at most {MAX_WINDOWS:,}; there are "
                f"{len(rep):,} reports): use a longer window, or none for one scan per "
                "report time"
            )
    family = _FAMILY.get(fmt_name, "ais")
    centre = None
    if reference is None:  # the one rule of every geodetic input: outliers left out
        centre = rep.centre()
        rep = rep.subset(~centre.outliers)
    frame = centre.frame if centre is not None else rep.frame(reference)
    dets = rep.detections(
        frame,
        scan="report" if window is None else float(window),
        labels=labels != "ignore",
        propagate=True,
        excluded=centre,
    )
    # the PMB/PMBM trackers measure positions only (reported velocities seed new
    # Bernoullis): the positions-only settings, whose clutter is per m² per second
    poisson = tracker in ("pmb", "pmbm")
    over = {
        **realdata_settings(family, labelled=labels == "associate" or poisson),
        **dict(config or {}),
    }
    cfg = make_tracker_config({"dim": 2}, over)
    truth = rep.truth(frame) if labels != "ignore" else None
    swin = float(score_window or window or 60.0)
    c = float(score_c or _SCORE_C[family])
    lat0, lon0, alt0 = frame.reference

    def add_metrics(metrics: dict, tracks) -> None:
        # rows the reader left out (no position: AIS lat 91 / lon 181, ADS-B without one)
        metrics["reports_skipped"] = rep.skipped
        if rep.skipped:
            metrics.setdefault("notes", []).append(
                f"{rep.skipped:,} report rows without a position left out (AIS lat 91 / "
                "lon 181 'not available', ADS-B states without lat/lon)"
            )
        if truth is not None:
            from jointtrack.metrics.selfreport import score_self_reports

            t, ids, xy = tracks
            tt, ti, tp, _ = truth
            score = score_self_reports(
                tt, ti, tp, t, ids, xy, window=swin, c=c, t0=float(rep.times[0])
            )
            metrics["self_reports"] = {
                **score.as_dict(),
                "window_seconds": swin,
                "c": c,
                "labels": labels,
                "rule": "truth: each identity's reports, linearly interpolated to the window "
                "ends (gaps up to max_gap); tracks: their latest estimate in the window",
            }
            metrics.setdefault("notes", []).append("self-reports: " + score.summary())

    return run_detections(
        dets,
        cfg,
        out_dir,
        fmt,
        progress,
        labels_to_tracker=labels == "associate",
        tracker=tracker if poisson else None,
        pmbm=pmbm if poisson else None,
        run_identity={
            "reports": {
                "format": fmt_name,
                "window": window,
                # as given: None recomputes the same centre and outliers on resume
                # (the file's SHA-256 is in the identity), a given one is used again
                "reference": None if centre is not None else [lat0, lon0, alt0],
                "labels": labels,
            }
        },
        # the lat/lon tracks, geo_reference and map.png: run_detections gives them to
        # every geodetic input (geodetic_outputs); the report run adds its scores
        extra=ExtraOutputs(metrics=add_metrics),
        output_interval=options.pop("output_interval", swin),
        **options,
    )


def geodetic_outputs(detections, extra: ExtraOutputs | None = None) -> ExtraOutputs:
    """The outputs every run on geodetic data writes (detections with a
    ``geo_reference``: a detection file's ``lat, lon[, alt]`` or ``x, y`` with
    ``ref_lat, ref_lon``, a report file), merged with a caller's ``extra``.

    * ``tracks.csv`` with ``lat, lon[, alt]`` columns after ``x, y[, z]``;
    * ``metrics.json`` ``geo_reference``: the frame's origin, how it was chosen
      and the rows left out as outliers (``outliers_excluded``, with a note for
      the summary; :func:`~jointtrack.io.geodetic.data_centre`);
    * ``map.png``: the tracks over the detections on lat/lon axes.

    Called by :func:`~jointtrack.experiments.run.run_detections` for every such
    input, so that a plain ``time, lat, lon`` file and a report file get the same.
    """
    extra = extra or ExtraOutputs()
    frame = detections.geo_frame()
    lat0, lon0, alt0 = frame.reference
    n_out, bound = detections.geo_outliers, detections.geo_outlier_bound
    pts = [z for z in detections.scans if len(z)]
    local = np.concatenate(pts) if pts else np.zeros((0, detections.dim))
    name = Path(detections.source or "detections").name

    def add_metrics(metrics: dict, tracks) -> None:
        from jointtrack.io.geodetic import OUTLIER_MEDIANS, OUTLIER_MIN_DISTANCE

        metrics["geo_reference"] = {
            "lat": lat0,
            "lon": lon0,
            "alt": alt0,
            "frame": "x, y: metres east and north of this point (WGS-84, local ENU, pymap3d)",
            "outliers_excluded": n_out,
            "outlier_bound_m": bound,
            "rule": "the reference given, or the centre of the lat/lon bounding box of the "
            "rows that are not outliers; outliers: rows farther from the data's median "
            f"point than max({OUTLIER_MEDIANS:g} x the median distance, "
            f"{OUTLIER_MIN_DISTANCE:g} m) (jointtrack.io.geodetic.data_centre)",
        }
        notes = metrics.setdefault("notes", [])
        notes.append(
            f"positions are metres east/north of lat {lat0:.6f}, lon {lon0:.6f} (WGS-84); "
            "tracks file also in lat/lon"
        )
        if n_out:
            notes.append(
                f"{n_out:,} rows left out as outliers: farther than {bound / 1000:,.0f} km "
                "from the data's median point (corrupt positions; give --reference LAT,LON "
                "to keep every row)"
            )
        if extra.metrics is not None:
            extra.metrics(metrics, tracks)

    def draw_map(path: Path, tracks) -> None:
        from jointtrack.experiments.map_plot import plot_track_map

        t, ids, xy = tracks
        det_lat, det_lon = frame.to_geodetic(local)[:2] if len(local) else ([], [])
        track_lat, track_lon = frame.to_geodetic(xy)[:2] if len(xy) else ([], [])
        plot_track_map(
            path,
            np.asarray(det_lat),
            np.asarray(det_lon),
            np.asarray(track_lat),
            np.asarray(track_lon),
            ids,
            title=f"{name}: {len(np.unique(ids))} tracks",
            track_times=t,
        )

    return ExtraOutputs(
        frame=frame,
        metrics=add_metrics,
        figures=(("map.png", "map", draw_map), *extra.figures),
    )
