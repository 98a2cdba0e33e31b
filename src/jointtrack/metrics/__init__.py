"""Performance metrics: OSPA, GOSPA (with its decomposition and over time), track statistics.

* :func:`ospa`, :func:`gospa` — distances between two finite sets of points
  (:mod:`jointtrack.metrics.ospa`), accurate at any finite scale; OSPA also
  for p = inf (bottleneck assignment).
* :func:`gospa_series` — GOSPA per scan between truth and tracks with an
  identity-switch penalty (``switch_convention="partner"`` or Stone Soup's
  ``"stonesoup"``: half a switch for assigned ↔ unassigned).
* :func:`track_statistics` — true/false tracks, breaks, fragmentations,
  identity switches and RMSE (:mod:`jointtrack.metrics.tracks`).
* :func:`tracking_quality` — time to confirm, targets held after
  confirmation, false confirmed tracks per scan, breaks, switches and GOSPA
  with its parts, built on both (:mod:`jointtrack.metrics.quality`).
* :func:`score_self_reports` — the same figures against the targets' own
  reports (AIS, ADS-B), sampled at window ends: coverage, purity, tracks per
  identity, switches, false tracks per hour, GOSPA
  (:mod:`jointtrack.metrics.selfreport`).
"""

from jointtrack.metrics.ospa import GOSPA, GOSPASeries, gospa, gospa_series, ospa
from jointtrack.metrics.quality import TrackingQuality, tracking_quality
from jointtrack.metrics.selfreport import SelfReportScore, score_self_reports
from jointtrack.metrics.tracks import TrackStatistics, track_statistics

__all__ = [
    "GOSPA",
    "GOSPASeries",
    "SelfReportScore",
    "TrackStatistics",
    "TrackingQuality",
    "gospa",
    "gospa_series",
    "ospa",
    "score_self_reports",
    "track_statistics",
    "tracking_quality",
]
