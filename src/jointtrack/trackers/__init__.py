"""Trackers built on the association engine."""

from jointtrack.trackers.jpda import ClusterRecord, JPDATracker, ScanResult, TrackerConfig

__all__ = ["ClusterRecord", "JPDATracker", "ScanResult", "TrackerConfig"]
