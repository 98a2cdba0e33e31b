"""Sensors of a multi-sensor tracker: a measurement model with its own P_D and clutter.

Scans from several sensors are processed one after another (sequential-update
JPDA): ``JPDATracker.step(t, z, sensor=id)`` gates, associates and updates with
that sensor's model, detection probability and clutter density; scans of
different sensors may share a time stamp (no prediction between them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Sensor", "check_model"]


def check_model(model) -> tuple[bool, int]:
    """``(linear, measurement_dim)`` of a measurement model; ValueError naming what is missing.

    Linear models have an ``H`` matrix and ``R``; nonlinear ones (EKF) ``h``,
    ``jacobian``, ``residual`` and ``R``; both need ``position_and_covariance(z)``
    for track initiation.
    """
    linear = isinstance(getattr(model, "H", None), np.ndarray)
    needed = ("H", "R") if linear else ("h", "jacobian", "residual", "R")
    for attr in (*needed, "position_and_covariance"):
        if not hasattr(model, attr):
            raise ValueError(f"sensor model {model!r} has no {attr!r}")
    return linear, int(np.asarray(model.R).shape[-1])


@dataclass(frozen=True)
class Sensor:
    """One sensor: its measurement ``model`` and, optionally, its own ``p_d`` and
    ``clutter_density`` (``None``: the tracker configuration's)."""

    model: object
    p_d: float | None = None
    clutter_density: float | None = None

    def __post_init__(self):
        check_model(self.model)
        if self.p_d is not None and not (0.0 < float(self.p_d) <= 1.0):
            raise ValueError(f"Sensor p_d must lie in (0, 1], got {self.p_d}")
        if self.clutter_density is not None:
            lam = float(self.clutter_density)
            if not (math.isfinite(lam) and lam > 0):
                raise ValueError(f"Sensor clutter_density must be positive, got {lam}")
