"""Joint identification of tracked targets (Schaub): filter banks and identity deconfliction.

D. E. Schaub, "Joint identification of multiple tracked targets", *Journal of
Advances in Information Fusion* 12(1), 2017.

Layout
------
``database``    :class:`Identity`, :class:`IdentityDatabase`: motion model, static
                attribute, detection probability; equivalence classes
``filterbank``  :class:`FilterBank` (one Kalman filter per identity class on a track)
                and :class:`IdentityBank` (all tracks + hidden tracks): the
                coefficients a[t, i], b[t] and the matrix M (eqs. 27–30, 77)
``deconflict``  :func:`deconflict`: P = M ∘ Per(minors)/Per(M) on the
                assignment-sum core, and the baselines (local, belief matrix,
                max-weight, Bethe, sampling)
``metrics``     the asymptotic matrix V (53), class aggregation, max KL (58)
``jpda``        :class:`IdentityJPDA`: JPDA whose association uses the identity-weighted
                densities (§2-D), with filter banks on every track
``crossing``    :func:`identity_crossing` (a seeded crossing where identities
                prevent the swap position-only JPDA makes) and :func:`track_swapped`

Example
-------
>>> import numpy as np
>>> from jointtrack.identity import Identity, IdentityDatabase, IdentityBank, deconflict
>>> db = IdentityDatabase([Identity("a", 1.0, attribute=0.0), Identity("b", 1.0, attribute=5.0)])
>>> bank = IdentityBank(db)
>>> R = np.diag([4.0, 4.0, 4.0])                 # position and attribute noise
>>> _ = bank.add_track("t0", 0.0, [0.0, 0.0, 4.6], R)
>>> _ = bank.add_track("t1", 0.0, [90.0, 0.0, 0.3], R)
>>> log_A, log_b, rows, cols = bank.log_M()
>>> deconflict(log_M=log_A, row_counts=rows, col_counts=cols).P.round(3).tolist()
[[0.005, 0.995], [0.995, 0.005]]
"""

from jointtrack.identity.crossing import CrossingScenario, identity_crossing, track_swapped
from jointtrack.identity.database import Identity, IdentityDatabase
from jointtrack.identity.deconflict import METHODS, Deconfliction, deconflict
from jointtrack.identity.filterbank import FilterBank, IdentityBank
from jointtrack.identity.jpda import IdentityJPDA, IdentityJPDAConfig, IdentityScan
from jointtrack.identity.metrics import (
    aggregate_classes,
    asymptotic_matrix,
    expand_columns,
    kl_rows,
    max_kl,
)

__all__ = [
    "METHODS",
    "CrossingScenario",
    "Deconfliction",
    "FilterBank",
    "Identity",
    "IdentityBank",
    "IdentityDatabase",
    "IdentityJPDA",
    "IdentityJPDAConfig",
    "IdentityScan",
    "aggregate_classes",
    "asymptotic_matrix",
    "deconflict",
    "expand_columns",
    "identity_crossing",
    "kl_rows",
    "max_kl",
    "track_swapped",
]
