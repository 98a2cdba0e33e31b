"""Trackers built on the association engine."""

from jointtrack.trackers.jpda import JPDATracker, ScanResult, TrackerConfig

__all__ = ["JPDATracker", "ScanResult", "TrackerConfig"]
