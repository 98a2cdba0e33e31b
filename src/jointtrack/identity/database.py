"""Identity database: the models of the identities and their equivalence classes.

Reference: D. E. Schaub, "Joint Identification of Multiple Tracked Targets",
*Journal of Advances in Information Fusion*, vol. 12, no. 1, 2017. Equation
numbers below are that paper's.

Model of one identity
---------------------
Identity i has a kinematic state ``[x, y, vx, vy]`` (``dim`` axes, positions
first, as everywhere in jointtrack) that moves by the discrete white-noise
acceleration model of eqs. (44)–(46)::

    x_{k+1} = F x_k + G P_i,    F = [[I, dt I], [0, I]],    G = [dt²/2 I; dt I],
    P_i ~ N(0, Σ_P,i),          so  Q_i(dt) = G Σ_P,i Gᵀ.

``Σ_P,i`` is the identity's *own* acceleration covariance and may be 0 (an
identity that never accelerates: Table I scales the noise by ``⌊i/2⌋``, which is 0
for the first identities). This is not the continuous white-noise model
of :func:`jointtrack.models.cv_noise`; for dt = 1 it is the block matrix
``[[Σ/4, Σ/2], [Σ/2, Σ]]`` printed in Tables I–III.

An identity may also carry a *static* attribute ``A_i`` (a scalar or a vector,
e.g. a length). Its state-space measure is the Dirac measure at ``A_i`` (eq. 3,
footnote 4): a measured attribute is scored by evaluating the measurement
density at ``A_i``, never estimated from a flat prior (which would erase the
very information that tells identities apart). Either every identity of a
database has an attribute of the same dimension or none has one: the
likelihood of a measured attribute under an identity without one is undefined.

Finally an identity has a detection probability ``p_d`` (eq. 23; default 1)
and an optional class label, which is metadata only.

Equivalence classes
-------------------
Identities with the same ``(Σ_P, A, p_d)`` are indistinguishable to every
sensor (end of §2-C, eq. 53): their filters, and hence their columns of the
matrix M (eqs. 30, 77), are identical. The database groups them into classes
automatically, numbered in order of first appearance; a filter bank runs one
filter per class, and the deconfliction receives one column per class with its
multiplicity (Appendix C: repeated columns). The label does not enter the
class: two identically modelled identities with different labels still get
identical columns, and their (equal) marginal probabilities can be summed by
label afterwards.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from jointtrack.assignment._checks import _as_real_array, as_float, as_int
from jointtrack.filters.kalman import _check_psd, _check_sym

__all__ = ["Identity", "IdentityDatabase"]


# ----------------------------------------------------------------------------- checks
# Shared with :mod:`jointtrack.identity.filterbank`, so both modules reject bad
# input with the same messages.


def _real(value, name: str, *, allow_nonfinite: bool = False) -> np.ndarray:
    """``value`` as a float64 array (copy); ValueError naming ``name`` unless real and finite.

    ``_as_real_array`` already refuses complex numbers, booleans, strings and
    Python integers too large for a float.
    """
    if value is None:
        raise ValueError(f"{name} must be a real number or array, got None")
    arr = np.array(_as_real_array(value, name), dtype=np.float64)
    if not allow_nonfinite and arr.size and not np.isfinite(arr).all():
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(arr))[0])
        where = f"[{', '.join(map(str, bad))}]" if bad else ""
        raise ValueError(f"{name}{where} is not finite ({arr[bad]})")
    return arr


def _probability_of_detection(value, name: str = "p_d") -> float:
    return as_float(value, name, minimum=0.0, maximum=1.0, open_min=True)


def _covariance(value, name: str, dim: int | None = None) -> np.ndarray:
    """A covariance: a scalar σ² ≥ 0 (→ σ² I) or a symmetric PSD (dim, dim) matrix.

    With ``dim`` None a scalar is returned as a 0-d array and a matrix may have
    any size (the database checks it against its ``dim`` later). Returns a
    symmetrised copy.
    """
    arr = _real(value, name)
    if arr.ndim == 0:
        if arr < 0:
            raise ValueError(f"{name} must be ≥ 0 (a variance), got {float(arr)}")
        return arr if dim is None else float(arr) * np.eye(dim)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        want = "(dim, dim)" if dim is None else f"({dim}, {dim})"
        raise ValueError(f"{name} must be a scalar variance or a {want} matrix, got {arr.shape}")
    if dim is not None and arr.shape != (dim, dim):
        raise ValueError(
            f"{name} must be a scalar variance or a ({dim}, {dim}) matrix, got {arr.shape}"
        )
    arr = _check_sym(arr[None], name, False)
    _check_psd(arr, name, False)
    return arr[0]


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr = np.ascontiguousarray(arr)
    arr.flags.writeable = False
    return arr


# ----------------------------------------------------------------------------- identities


@dataclass(frozen=True)
class Identity:
    """One identity: its motion model, static attribute, detection probability and label.

    Values are checked and stored as plain Python floats and tuples, so
    identities compare and hash by value.

    Parameters
    ----------
    name : str
        unique, non-empty name (e.g. a registration number).
    process_noise : float or (dim, dim) array_like
        Σ_P, the covariance of the identity's white acceleration noise P_i in
        eq. (44): a scalar σ² ≥ 0 means σ² I; 0 is allowed (an identity that
        never accelerates). Symmetric positive semi-definite.
    attribute : float, 1-D array_like or None
        the static attribute A_i (Dirac measure, eq. 3), or None.
    label : str or None
        class label (metadata; it does not enter the equivalence classes).
    p_d : float in (0, 1]
        detection probability p_d,i (eq. 23), used when an update does not
        override it.
    """

    name: str
    process_noise: float | tuple[tuple[float, ...], ...]
    attribute: float | tuple[float, ...] | None = None
    label: str | None = None
    p_d: float = 1.0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name must be a non-empty string, got {self.name!r}")
        who = f"identity {self.name!r}"
        noise = _covariance(self.process_noise, f"process_noise of {who}")
        noise = float(noise) if noise.ndim == 0 else tuple(map(tuple, noise.tolist()))
        object.__setattr__(self, "process_noise", noise)
        if self.attribute is not None:
            attr = _real(self.attribute, f"attribute of {who}")
            if attr.ndim > 1 or attr.size == 0:
                raise ValueError(
                    f"attribute of {who} must be a scalar or a non-empty 1-D vector, "
                    f"got shape {attr.shape}"
                )
            attr = float(attr) if attr.ndim == 0 else tuple(attr.tolist())
            object.__setattr__(self, "attribute", attr)
        if self.label is not None and not isinstance(self.label, str):
            raise ValueError(f"label of {who} must be a string or None, got {self.label!r}")
        object.__setattr__(self, "p_d", _probability_of_detection(self.p_d, f"p_d of {who}"))


class IdentityDatabase:
    """The identities I of one scene, grouped into equivalence classes.

    Parameters
    ----------
    identities : sequence of Identity
        at least one; names unique; all with an attribute of one dimension, or
        all without.
    dim : {1, 2, 3}
        number of spatial axes of the kinematic state ``[pos(dim), vel(dim)]``.

    Attributes
    ----------
    identities : tuple of Identity
    names : tuple of str
    dim : int
    n_identities, n_classes : int
        I and C.
    attribute_dim : int
        length of the attribute vector (0 when the identities have none).
    classes : (I,) int ndarray
        class index of each identity; classes are numbered in order of first
        appearance.
    class_counts : (C,) int ndarray
        number of identities in each class (the column multiplicities of M).
    representatives : (C,) int ndarray
        index of the first identity of each class.
    process_noise : (C, dim, dim) ndarray
        Σ_P of each class.
    attributes : (C, attribute_dim) ndarray
        A of each class.
    p_d : (C,) ndarray
        default detection probability of each class.

    Examples
    --------
    >>> db = IdentityDatabase([Identity("a", 1.0, 3.0), Identity("b", 1.0, 3.0),
    ...                        Identity("c", 0.0, 3.0)])
    >>> db.classes.tolist(), db.class_counts.tolist()
    ([0, 0, 1], [2, 1])
    """

    def __init__(self, identities: Sequence[Identity], *, dim: int = 2):
        self._dim = as_int(dim, "dim", minimum=1, maximum=3)
        if isinstance(identities, (str, bytes)) or not isinstance(identities, Sequence):
            raise ValueError(
                f"identities must be a sequence of Identity, got {type(identities).__name__}"
            )
        identities = tuple(identities)
        if not identities:
            raise ValueError("identities is empty: a database needs at least one identity")
        for k, ident in enumerate(identities):
            if not isinstance(ident, Identity):
                raise ValueError(f"identities[{k}] is not an Identity: {ident!r}")
        self._identities = identities
        self._names = tuple(ident.name for ident in identities)
        self._index = {}
        for k, name in enumerate(self._names):
            if name in self._index:
                raise ValueError(
                    f"identities[{k}] has the duplicate name {name!r} "
                    f"(also identities[{self._index[name]}]); names must be unique"
                )
            self._index[name] = k
        noise = np.stack([self._noise_matrix(k, ident) for k, ident in enumerate(identities)])
        attrs = self._attribute_matrix(identities)
        p_d = np.array([ident.p_d for ident in identities])
        self._build_classes(noise, attrs, p_d)

    # ------------------------------------------------------------------ construction

    def _noise_matrix(self, k: int, ident: Identity) -> np.ndarray:
        noise = np.asarray(ident.process_noise, dtype=np.float64)
        if noise.ndim == 0:
            return float(noise) * np.eye(self._dim)
        if noise.shape != (self._dim, self._dim):
            raise ValueError(
                f"process_noise of identities[{k}] ({ident.name!r}) has shape {noise.shape}, "
                f"but the database has dim = {self._dim}: give a scalar or a "
                f"({self._dim}, {self._dim}) matrix"
            )
        return noise

    @staticmethod
    def _attribute_matrix(identities: tuple[Identity, ...]) -> np.ndarray:
        """(I, m) attributes; all identities must agree on having one and on its length."""
        sizes = [
            None if ident.attribute is None else np.size(ident.attribute) for ident in identities
        ]
        for k, size in enumerate(sizes):
            if size != sizes[0]:
                first = "no attribute" if sizes[0] is None else f"an attribute of length {sizes[0]}"
                this = "no attribute" if size is None else f"an attribute of length {size}"
                raise ValueError(
                    f"attribute of identities[{k}] ({identities[k].name!r}): it has {this} "
                    f"but identities[0] has {first}; all identities need attributes of one "
                    "dimension, or none"
                )
        m = sizes[0] or 0
        if m == 0:
            return np.zeros((len(identities), 0))
        return np.array([np.atleast_1d(ident.attribute) for ident in identities], dtype=np.float64)

    def _build_classes(self, noise: np.ndarray, attrs: np.ndarray, p_d: np.ndarray) -> None:
        # Exact equality of the models defines a class. Keys are tuples of Python
        # floats, so 0.0 and -0.0 are the same key (as they are the same model).
        keys = [
            (tuple(noise[k].ravel().tolist()), tuple(attrs[k].tolist()), float(p_d[k]))
            for k in range(len(p_d))
        ]
        class_of: dict = {}
        reps: list[int] = []
        classes = np.empty(len(keys), np.int64)
        for k, key in enumerate(keys):
            if key not in class_of:
                class_of[key] = len(reps)
                reps.append(k)
            classes[k] = class_of[key]
        reps = np.array(reps, np.int64)
        self._classes = _frozen(classes)
        self._representatives = _frozen(reps)
        self._class_counts = _frozen(np.bincount(classes, minlength=len(reps)).astype(np.int64))
        self._noise = _frozen(noise[reps])
        self._attrs = _frozen(attrs[reps])
        self._p_d = _frozen(p_d[reps])

    # ------------------------------------------------------------------ sizes and classes

    @property
    def identities(self) -> tuple[Identity, ...]:
        return self._identities

    @property
    def names(self) -> tuple[str, ...]:
        return self._names

    @property
    def dim(self) -> int:
        return self._dim

    @property
    def state_dim(self) -> int:
        """Length of the kinematic state, ``2·dim``."""
        return 2 * self._dim

    @property
    def n_identities(self) -> int:
        return len(self._identities)

    @property
    def n_classes(self) -> int:
        return len(self._representatives)

    @property
    def attribute_dim(self) -> int:
        return self._attrs.shape[1]

    @property
    def measurement_dim(self) -> int:
        """Length of a measurement ``z = [position; attribute]``: ``dim + attribute_dim``."""
        return self._dim + self.attribute_dim

    @property
    def classes(self) -> np.ndarray:
        return self._classes

    @property
    def class_counts(self) -> np.ndarray:
        return self._class_counts

    @property
    def representatives(self) -> np.ndarray:
        return self._representatives

    @property
    def process_noise(self) -> np.ndarray:
        return self._noise

    @property
    def attributes(self) -> np.ndarray:
        return self._attrs

    @property
    def p_d(self) -> np.ndarray:
        return self._p_d

    def index(self, name: str) -> int:
        """Position of the identity called ``name`` (KeyError if there is none)."""
        try:
            return self._index[name]
        except (KeyError, TypeError):
            raise KeyError(f"no identity is called {name!r}") from None

    def class_of(self, name: str) -> int:
        """Class index of the identity called ``name``."""
        return int(self._classes[self.index(name)])

    def members(self, c: int) -> np.ndarray:
        """Indices of the identities in class ``c``."""
        c = as_int(c, "c", minimum=0, maximum=self.n_classes - 1)
        return np.flatnonzero(self._classes == c)

    def __len__(self) -> int:
        return self.n_identities

    def __repr__(self) -> str:
        return (
            f"IdentityDatabase({self.n_identities} identities in {self.n_classes} classes, "
            f"dim={self._dim}, attribute_dim={self.attribute_dim})"
        )

    # ------------------------------------------------------------------ per-class values

    def per_class(self, values, name: str) -> np.ndarray:
        """Reduce a per-identity quantity to one value per class.

        Parameters
        ----------
        values : float or (I,) array_like
            a scalar (the same for every identity) or one finite value per identity.
        name : str
            argument name for error messages.

        Returns
        -------
        (C,) float ndarray

        Raises
        ------
        ValueError
            if an (I,) array differs inside a class: the members of a class
            share one filter, so a per-identity value that splits them would
            break the class structure (give those identities different models).
        """
        arr = _real(values, name)
        if arr.ndim == 0:
            return np.full(self.n_classes, float(arr))
        if arr.shape != (self.n_identities,):
            raise ValueError(
                f"{name} must be a scalar or have one entry per identity "
                f"({self.n_identities},), got shape {arr.shape}"
            )
        rep = arr[self._representatives]
        split = arr != rep[self._classes]
        if split.any():
            k = int(np.argmax(split))
            c = int(self._classes[k])
            r = int(self._representatives[c])
            raise ValueError(
                f"{name} differs inside identity class {c}: {name}[{r}] = {arr[r]} "
                f"({self._names[r]!r}) but {name}[{k}] = {arr[k]} ({self._names[k]!r}); "
                "identities of one class share one filter, so they must share this value"
            )
        return rep

    # ------------------------------------------------------------------ process noise

    def process_noise_cov(self, dt) -> np.ndarray:
        """Process noise of each class over a step dt: ``Q_c(dt) = G Σ_P,c Gᵀ``.

        ``G = [dt²/2 I; dt I]`` (eqs. 44, 46), so per class::

            Q = [[dt⁴/4 Σ, dt³/2 Σ],
                 [dt³/2 Σ, dt²   Σ]]

        in the layout ``[pos(dim), vel(dim)]``. This discrete white-noise
        acceleration model holds the acceleration constant over the step, so
        two steps of dt/2 do not give the same Q as one step of dt.

        Parameters
        ----------
        dt : float ≥ 0

        Returns
        -------
        (C, 2·dim, 2·dim) ndarray
        """
        dt = np.float64(as_float(dt, "dt", minimum=0.0))  # numpy powers overflow to inf, not raise
        with np.errstate(over="ignore", invalid="ignore"):
            block = np.array([[dt**4 / 4.0, dt**3 / 2.0], [dt**3 / 2.0, dt**2]])
            Q = block[None, :, None, :, None] * self._noise[:, None, :, None, :]
        if not np.isfinite(Q).all():
            raise ValueError(f"dt = {dt:g} is too large: the process noise Q(dt) overflows")
        n = self.state_dim
        return Q.reshape(self.n_classes, n, n)
