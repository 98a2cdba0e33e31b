"""Trackers built on the association engine.

:mod:`~jointtrack.trackers.config` holds :class:`TrackerConfig`,
:mod:`~jointtrack.trackers.jpda` the JPDA/JIPDA tracker loop,
:mod:`~jointtrack.trackers.history` the table of confirmed estimates
(:class:`TrackHistory`) and :mod:`~jointtrack.trackers.state_io` the safe
state-file format.
"""

from jointtrack.trackers.base import ClusterRecord, ScanResult, ScanTracker
from jointtrack.trackers.config import TrackerConfig
from jointtrack.trackers.history import TrackHistory
from jointtrack.trackers.jpda import JPDATracker
from jointtrack.trackers.state_io import StateFileError

__all__ = [
    "ClusterRecord",
    "ScanTracker",
    "JPDATracker",
    "ScanResult",
    "StateFileError",
    "TrackHistory",
    "TrackerConfig",
]
