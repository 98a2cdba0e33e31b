"""Sensors of a multi-sensor tracker: a measurement model with its own P_D and clutter.

Scans from several sensors are processed one after another (sequential-update
JPDA): ``JPDATracker.step(t, z, sensor=id)`` gates, associates and updates with
that sensor's model, detection probability and clutter density; scans of
different sensors may share a time stamp (no prediction between them).
A moving sensor (e.g. a range–bearing sensor on a platform) is the same
:class:`Sensor` placed anew for each of its scans: :meth:`Sensor.at`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

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
    # from the model, checked once: linear (an H matrix) and the measurement length
    linear: bool = field(init=False, repr=False, compare=False)
    measurement_dim: int = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        linear, mdim = check_model(self.model)
        object.__setattr__(self, "linear", linear)
        object.__setattr__(self, "measurement_dim", mdim)
        if self.p_d is not None and not (0.0 < float(self.p_d) <= 1.0):
            raise ValueError(f"Sensor p_d must lie in (0, 1], got {self.p_d}")
        if self.clutter_density is not None:
            lam = float(self.clutter_density)
            if not (math.isfinite(lam) and lam > 0):
                raise ValueError(f"Sensor clutter_density must be positive, got {lam}")

    @property
    def kind(self) -> str:
        """``"position"`` for a linear model (an ``H`` matrix), else ``"range-bearing"``
        (the nonlinear models the run reads: :class:`~jointtrack.models.RangeBearing`)."""
        return "position" if self.linear else "range-bearing"

    def at(self, position) -> Sensor:
        """This sensor with its model moved to ``position`` (same noise, P_D, clutter).

        The model must be a dataclass with a ``sensor_position`` field (e.g.
        :class:`~jointtrack.models.RangeBearing`); ValueError otherwise.
        """
        model = self.model
        if not (dataclasses.is_dataclass(model) and hasattr(model, "sensor_position")):
            raise ValueError(f"sensor model {model!r} has no sensor_position to move")
        pos = tuple(float(v) for v in np.asarray(position, dtype=np.float64).reshape(-1))
        return dataclasses.replace(self, model=dataclasses.replace(model, sensor_position=pos))
