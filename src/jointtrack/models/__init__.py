"""Motion and measurement models.

State layout everywhere in jointtrack: blocked by derivative order, positions
first — ``[x, y(, z), vx, vy(, vz)(, ax, ay(, az))]`` — so a position is
``x[..., :dim]``. Motion models are continuous-time white-noise kinematic models
(see :mod:`jointtrack.models.motion`).
"""

from jointtrack.models.measurement import (
    LinearPosition,
    LinearPositionVelocity,
    RangeBearing,
    wrap_angle,
)
from jointtrack.models.motion import (
    ConstantAcceleration,
    ConstantVelocity,
    CoordinatedTurn,
    Stationary,
    ca_noise,
    ca_transition,
    cv_noise,
    cv_transition,
)

__all__ = [
    "ConstantAcceleration",
    "ConstantVelocity",
    "CoordinatedTurn",
    "LinearPosition",
    "LinearPositionVelocity",
    "RangeBearing",
    "Stationary",
    "ca_noise",
    "ca_transition",
    "cv_noise",
    "cv_transition",
    "wrap_angle",
]
