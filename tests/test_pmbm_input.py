"""Bad input to the PMB/PMBM trackers: a ValueError (or TypeError) naming what is wrong.

:class:`PMBMConfig` fields (bools, complex numbers, NaN, infinities, huge
integers, negative numbers, wrong shapes of the Gaussian birth mixture),
unknown or missing keys in ``from_dict``, and ``step`` with bad returns or
times — never a traceback from deep inside numpy, never a silently accepted
value. A failed ``step`` leaves the tracker unchanged.
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from jointtrack.trackers import JPDATracker, TrackerConfig
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker
from state_checks import assert_same_state

EYE4 = tuple(tuple(float(v) for v in row) for row in np.eye(4))
MEAN = (0.0, 0.0, 0.0, 0.0)
BAD_NUMBERS = [True, 1 + 2j, float("nan"), float("inf"), -1.0, 10**400, "1", None]
# counts and seeds take any size of integer (numpy seeds with big ints)
ANY_INT = ("exact_max_tracks", "seed")

# (field, a bad value) for the PMBM-specific scalar fields
PMBM_SCALARS = [
    "clutter_density",
    "birth_density",
    "prior_density",
    "prior_weight",
    "poisson_prune",
    "poisson_merge",
    "max_poisson_components",
    "r_prune",
    "r_estimate",
    "max_hypotheses",
    "hypothesis_prune",
]
SHARED = ["p_d", "p_g", "p_survive", "process_noise", "max_speed", "exact_max_tracks", "seed"]


def _cases():
    for name in PMBM_SCALARS + SHARED:
        for value in BAD_NUMBERS:
            if value is None and name in ("prior_density", "seed"):
                continue  # None means "steady state" / "no seed"
            if value == 10**400 and name in ANY_INT:
                continue
            yield name, value
    for name in ("poisson_prune", "r_prune", "hypothesis_prune", "r_estimate"):
        yield name, 1.5  # probabilities
    for name in ("max_poisson_components", "max_hypotheses"):
        yield name, 0
        yield name, 2.0  # a count is an integer
        yield name, 10**7
    yield "r_estimate", 0.0
    yield "clutter_density", 0.0  # must be known and positive
    yield "birth_model", "poisson"
    yield "birth_model", 1


@pytest.mark.parametrize("name, value", list(_cases()))
def test_bad_scalar_fields_name_the_field(name, value):
    with pytest.raises(ValueError, match=name):
        PMBMConfig(**{name: value})


def _gauss(**kw):
    base = dict(birth_model="gaussian", birth_weights=(1.0,), birth_means=(MEAN,),
                birth_covs=(EYE4,))  # fmt: skip
    base.update(kw)
    return base


BIRTH_CASES = [
    # bools, complex, NaN, huge ints and strings inside the mixture
    (_gauss(birth_weights=(True,)), "birth_weights"),
    (_gauss(birth_weights=(1j,)), "birth_weights"),
    (_gauss(birth_weights=(float("nan"),)), "birth_weights"),
    (_gauss(birth_weights=(10**400,)), "birth_weights"),
    (_gauss(birth_weights=(-1.0,)), "birth_weights"),
    (_gauss(birth_weights="1"), "birth_weights"),
    (_gauss(birth_means=((True, 0.0, 0.0, 0.0),)), "birth_means"),
    (_gauss(birth_means=((0.0, 0.0, 0.0, float("inf")),)), "birth_means"),
    (_gauss(birth_means=((0.0, 0.0, 1j, 0.0),)), "birth_means"),
    (_gauss(birth_covs=((("a",) * 4,) + EYE4[1:],)), "birth_covs"),
    (_gauss(birth_covs=(tuple(tuple(bool(v) for v in r) for r in EYE4),)), "birth_covs"),
    # shapes: means of the wrong length, covariances of the wrong size, counts
    (_gauss(birth_means=((0.0, 0.0, 0.0),)), "birth_means"),
    (_gauss(birth_means=(MEAN, MEAN)), "birth_means"),
    (_gauss(birth_means=((0.0, 0.0, 0.0), MEAN)), "birth_means"),  # ragged
    (_gauss(birth_covs=(tuple(tuple(r[:3]) for r in EYE4[:3]),)), "birth_covs"),
    (_gauss(birth_covs=(EYE4, EYE4)), "birth_covs"),
    (_gauss(birth_covs=EYE4), "birth_covs"),
    # covariances that are none
    (_gauss(birth_covs=((EYE4[0], (0.5, 1.0, 0.0, 0.0)) + EYE4[2:],)), "birth_covs"),
    (_gauss(birth_covs=(tuple(tuple(-v for v in r) for r in EYE4),)), "birth_covs"),
    (_gauss(birth_weights=()), "birth_weights"),  # the Gaussian model needs a component
    # regions
    ({"birth_region": ((0.0, 1.0),)}, "birth_region"),
    ({"birth_region": ((1.0, 0.0), (0.0, 1.0))}, "birth_region"),
    ({"birth_region": ((0.0, float("nan")), (0.0, 1.0))}, "birth_region"),
    ({"birth_region": ((False, True), (0.0, 1.0))}, "birth_region"),
    ({"birth_region": "everywhere"}, "birth_region"),
]


@pytest.mark.parametrize("kw, name", BIRTH_CASES)
def test_bad_birth_mixture_and_region_name_the_field(kw, name):
    with pytest.raises(ValueError, match=name):
        PMBMConfig(**kw)


def test_good_birth_mixture_is_normalised_to_plain_floats():
    cfg = PMBMConfig(**_gauss(birth_weights=[np.float32(2.0)], birth_means=[list(MEAN)]))
    assert cfg.birth_weights == (2.0,) and type(cfg.birth_weights[0]) is float
    assert cfg.birth_means == (MEAN,) and cfg.birth_covs == (EYE4,)
    # a Gaussian mixture whose state length disagrees with the motion model
    with pytest.raises(ValueError, match="birth_means"):
        PMBMConfig(**_gauss(motion="ca"))


def test_from_dict_names_unknown_and_missing_keys():
    with pytest.raises(ValueError, match="unknown PMBM tracker setting.*pd"):
        PMBMConfig.from_dict({"p_d": 0.9, "pd": 0.8})
    with pytest.raises(ValueError, match="missing PMBM tracker setting"):
        PMBMConfig.from_dict({"p_d": 0.9}, complete=True)
    full = PMBMConfig(clutter_density=2e-4).to_dict()
    assert PMBMConfig.from_dict(full, complete=True) == PMBMConfig(clutter_density=2e-4)
    with pytest.raises(ValueError, match="p_d"):
        PMBMConfig.from_dict(dict(full, p_d=True))


def test_config_of_the_wrong_class_is_refused():
    with pytest.raises(TypeError, match="PMBMConfig"):
        PMBMTracker(TrackerConfig())
    with pytest.raises(TypeError, match="TrackerConfig"):
        JPDATracker(PMBMConfig())


BAD_SCANS = [
    ((1.0, [[0.0, 0.0, 0.0]]), ValueError, "shape"),
    ((1.0, [[np.nan, 0.0]]), ValueError, "non-finite"),
    ((1.0, [[np.inf, 0.0]]), ValueError, "non-finite"),
    ((1.0, [[1j, 0.0]]), ValueError, "measurements z"),
    ((1.0, [[True, False]]), ValueError, "measurements z"),
    ((1.0, [["a", "b"]]), ValueError, "measurements z"),
    ((1.0, [[10**400, 0]]), ValueError, "measurements z"),
    ((0.5, [[0.0, 0.0]]), ValueError, "increase"),  # before the previous scan
    ((float("nan"), [[0.0, 0.0]]), ValueError, "scan time t"),
    ((True, [[0.0, 0.0]]), ValueError, "scan time t"),
    ((1 + 1j, [[0.0, 0.0]]), ValueError, "scan time t"),
    (("2024-01-01", [[0.0, 0.0]]), TypeError, "scan time t"),
    ((dt.datetime(2024, 1, 1), [[0.0, 0.0]]), ValueError, "not both"),
]


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
@pytest.mark.parametrize("args, exc, match", BAD_SCANS)
def test_bad_scans_are_refused_and_leave_the_tracker_unchanged(kind, args, exc, match):
    trk = kind(PMBMConfig(birth_density=1e-5))
    trk.step(0.0, [[0.0, 0.0], [50.0, 50.0]])
    trk.step(0.75, [[1.0, 0.0], [50.0, 51.0]])
    before = trk.state_dict()
    with pytest.raises(exc, match=match):
        trk.step(*args)
    after = trk.state_dict()
    assert_same_state(after, before)
    trk.step(2.0, [[2.0, 0.0]])  # and it carries on
    assert trk.n_scans == 3


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_unknown_sensor_and_wrong_state_dim_birth(kind):
    trk = kind(PMBMConfig())
    with pytest.raises(ValueError, match="unknown sensor"):
        trk.step(0.0, [[0.0, 0.0]], sensor="radar")
    from jointtrack.models import ConstantAcceleration

    with pytest.raises(ValueError, match="birth_means"):
        kind(PMBMConfig(**_gauss()), motion=ConstantAcceleration(dim=2, q=1.0))
