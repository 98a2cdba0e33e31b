"""Configuration of the JPDA tracker: one frozen dataclass of plain, TOML-friendly numbers."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

__all__ = ["MISS_MODELS", "TrackerConfig"]

#: How the weight of "track detected nothing" is formed (see ``TrackerConfig.miss_model``).
MISS_MODELS = ("1-pd*pg", "1-pd")


@dataclass(frozen=True)
class TrackerConfig:
    """Everything that defines a JPDA tracker; plain numbers, TOML-friendly.

    Attributes
    ----------
    dim : 2 or 3, spatial dimension; measurements are positions ``[x, y(, z)]``.
    motion : ``"cv"`` (nearly constant velocity) or ``"ca"`` (constant acceleration).
    process_noise : q of the motion model (m²/s³ for CV, m²/s⁵ for CA).
    measurement_noise : σ² of each position coordinate (R = σ² I), for
        ``sensor="position"``.
    sensor : ``"position"`` (linear, measurements ``[x, y(, z)]``) or
        ``"range-bearing"`` (2-D only; measurements ``[r, θ]`` from a sensor at
        ``sensor_position``, EKF with the bearing residual wrapped to (−π, π]).
    sensor_position : position of the range–bearing sensor.
    range_noise, bearing_noise : σ_r² (m²) and σ_θ² (rad²) of the range–bearing
        sensor; ``clutter_density`` is then per unit of range × bearing.
    p_d : detection probability P_D.
    p_g : gate probability P_G (chi-square gate γ = χ²_d⁻¹(P_G)).
    clutter_density : λ, false returns per unit volume; ``None`` estimates it per
        cluster by Bojilov's heuristic (8), λ = Σ m_i / Σ V_i.
    association : method for clusters within budget (``"exact"`` by default).
    exact_max_tracks : clusters with more tracks than this use ``approximation``
        (logged as a warning with the cluster size).
    approximation : ``"lbp"``, ``"mcmc"``, ``"kbest"`` or ``"pda"``.
    initiation : ``"two-point"`` (velocity from two unassociated returns of
        consecutive scans no further apart than ``max_speed·dt``) or
        ``"one-point"`` (zero velocity, σ_v = max_speed/2).
    max_speed : largest target speed, m/s.
    max_acceleration : largest target acceleration, m/s² (initial acceleration
        uncertainty σ_a = max_acceleration/2 of constant-acceleration tracks).
    confirm_m, confirm_n : M-of-N confirmation (hits = scans with a gated return).
    delete_misses : consecutive scans without a gated return that delete a
        confirmed track.
    max_position_std : delete a track whose position standard deviation
        √(tr P_pos / dim) exceeds this (covariance growth).
    existence : use JIPDA existence probabilities (default) instead of M-of-N
        logic; M-of-N confirms nearly every clutter-born track once gates hold
        about one false return each.
    p_survive : probability that a target survives one scan (JIPDA).
    r_init, r_confirm, r_delete : initial, confirmation and deletion thresholds
        of the existence probability (JIPDA).
    seed : seed of the random generator used by randomised approximations.
    miss_model : weight of "track detected nothing" in the cluster's joint
        events: ``"1-pd*pg"`` (default; a target-originated return may fall
        outside the gate, Bar-Shalom, Daum & Huang 2009) or ``"1-pd"``
        (Bojilov et al. eqs. (1)/(5), which assume the gate holds every
        target-originated return). JIPDA multiplies either by the existence.
    """

    dim: int = 2
    motion: str = "cv"
    process_noise: float = 1.0
    measurement_noise: float = 100.0
    sensor: str = "position"
    sensor_position: tuple = (0.0, 0.0)
    range_noise: float = 25.0
    bearing_noise: float = 1e-4
    p_d: float = 0.9
    p_g: float = 0.99
    clutter_density: float | None = None
    association: str = "exact"
    exact_max_tracks: int = 16
    approximation: str = "lbp"
    initiation: str = "two-point"
    max_speed: float = 50.0
    max_acceleration: float = 10.0
    confirm_m: int = 2
    confirm_n: int = 3
    delete_misses: int = 3
    max_position_std: float = math.inf
    existence: bool = True
    p_survive: float = 0.99
    r_init: float = 0.05
    r_confirm: float = 0.9
    r_delete: float = 0.01
    seed: int | None = 0
    miss_model: str = "1-pd*pg"

    def __post_init__(self):
        def need(cond, msg):
            if not cond:
                raise ValueError(f"TrackerConfig: {msg}")

        need(self.dim in (2, 3), f"dim must be 2 or 3, got {self.dim}")
        need(
            self.sensor in ("position", "range-bearing"),
            f"sensor must be 'position' or 'range-bearing', got {self.sensor!r}",
        )
        need(self.sensor == "position" or self.dim == 2, "the range-bearing sensor is 2-D")
        try:
            pos = tuple(float(v) for v in self.sensor_position)
        except (TypeError, ValueError):
            pos = ()
        need(len(pos) == 2 and all(map(math.isfinite, pos)), "sensor_position must be (x, y)")
        object.__setattr__(self, "sensor_position", pos)
        need(self.motion in ("cv", "ca"), f"motion must be 'cv' or 'ca', got {self.motion!r}")
        for name in (
            "process_noise",
            "measurement_noise",
            "max_speed",
            "max_acceleration",
            "range_noise",
            "bearing_noise",
        ):
            v = getattr(self, name)
            need(math.isfinite(v) and v > 0, f"{name} must be positive and finite, got {v}")
        for name in ("p_d", "p_g", "p_survive"):
            v = getattr(self, name)
            need(0 < v <= 1 and (name != "p_g" or v < 1), f"{name} must lie in (0, 1], got {v}")
        if self.clutter_density is not None:
            c = self.clutter_density
            need(math.isfinite(c) and c > 0, f"clutter_density must be positive, got {c}")
        from jointtrack.association.core import METHODS

        need(self.association in METHODS, f"association must be one of {METHODS}")
        need(
            self.approximation in ("lbp", "mcmc", "kbest", "pda"),
            f"approximation must be lbp, mcmc, kbest or pda, got {self.approximation!r}",
        )
        need(self.exact_max_tracks >= 1, "exact_max_tracks must be ≥ 1")
        need(
            self.miss_model in MISS_MODELS,
            f"miss_model must be one of {', '.join(MISS_MODELS)}, got {self.miss_model!r}",
        )
        need(self.initiation in ("two-point", "one-point"), "initiation: two-point|one-point")
        need(1 <= self.confirm_m <= self.confirm_n <= 30, "need 1 ≤ confirm_m ≤ confirm_n ≤ 30")
        need(self.delete_misses >= 1, "delete_misses must be ≥ 1")
        need(self.max_position_std > 0, "max_position_std must be positive")
        need(0 < self.r_delete < self.r_init < 1, "need 0 < r_delete < r_init < 1")
        need(self.r_delete < self.r_confirm <= 1, "need r_delete < r_confirm ≤ 1")

    @classmethod
    def from_dict(cls, d: dict) -> TrackerConfig:
        """Build from a (TOML) mapping; unknown keys are an error naming them."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(
                f"unknown tracker setting(s): {', '.join(unknown)}; "
                f"known: {', '.join(sorted(known))}"
            )
        return cls(**d)

    def to_dict(self) -> dict:
        return asdict(self)

    def detection_in_gate(self) -> float:
        """The P_D·P_G or P_D that the miss weight subtracts (see ``miss_model``)."""
        return self.p_d * self.p_g if self.miss_model == "1-pd*pg" else self.p_d
