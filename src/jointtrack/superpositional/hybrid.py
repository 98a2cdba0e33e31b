r"""Hybrid likelihood: exact mixture terms where they matter at y0, conditioned moments elsewhere.

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015 (equation numbers below refer to it);
the filters that use I and R(x): S. Nannuru, M. Coates and R. Mahler,
"Computationally-tractable approximate PHD and CPHD filters for superpositional
sensors", IEEE J. Sel. Topics Signal Process. 7(3):410-420, 2013.

Algorithm
---------
For linear g and Gaussian components, :math:`\mathbf y = \sum_{x\in\Xi} g(x)`
is a Gaussian mixture indexed by discrete latent variables, and I of (3) is
:math:`\sum_c w_c\,\mathcal N(\mathbf y_0; m_c, S_c + \Sigma_0)`. The variables
are put in a fixed order, part after part of a Union:

* multi-Bernoulli: one existence bit per component (children "exists" with
  :math:`\log r_i`, adding :math:`H\mu_i, H\Sigma_i H^\top`; "absent" with
  :math:`\log(1 - r_i)`);
* IIDC (and Poisson, its cardinality truncated where the tail is below 1e-16):
  first the cardinality n (children weighted by :math:`\pi(n)`), then the counts
  :math:`c_1, \dots, c_{K-1}` of the K spatial mixture components one after
  the other, each binomial given the draws left,
  :math:`c_k \sim \mathrm{Bin}(n_r, s_k / \sum_{j \ge k} s_j)` (the multinomial
  factorised), the last count being what is left;
* an IIDC or Poisson part whose spatial density is a uniform box: the
  cardinality only (the sum of n uniforms is not a finite mixture). Such parts
  come first: their count is the least Gaussian variable of all.

A node of the tree fixes a prefix of the variables. Its term is its weight
times the Gaussian with the fixed contributions plus the **conditioned**
Campbell moments (4)-(7) of everything not fixed: the remaining Bernoulli
components (sum of their moments), :math:`n_r` iid draws from the
renormalised remaining spatial components (:math:`n_r` times one draw's mean
and covariance), the whole of the parts not reached yet (their (4)-(6)). The
root is the paper's Gaussian approximation (9); a leaf is an exact mixture
term, so the sum over any frontier of the tree is an approximation of I that
becomes exact when every frontier node is a leaf.

Once the count n of a uniform-box part is fixed, its n targets are not
replaced by moments: with the node's Gaussian :math:`\mathcal N(m, S)` for
the rest (noise included) the term is

.. math::

    \int \mathcal N(\mathbf y_0 - m - A s;\, S)\, f_n(s)\, ds
    = c\;\mathrm E_{s \sim \mathcal N(\hat s, P^{-1})} f_n(s),\qquad
    P = A^\top S^{-1} A,\ \hat s = P^{-1} A^\top S^{-1}(\mathbf y_0 - m),

with :math:`f_n` the density of the sum of n uniform points (a product of
Irwin-Hall densities per coordinate) and A = H. For one coordinate that
expectation is closed form (the n-th finite difference of the n-fold
integrated normal density); for two, the second coordinate is closed form
given the first, and the first is integrated by Gauss-Legendre (12 points per
polynomial piece for n ≤ 2, over ±6 sd for n ≥ 3; relative error below 3e-3).
This needs linear g, a full-column-rank H and dx ≤ 2 for the first uniform
part; otherwise (and for further uniform parts) the counts enter through
their moments: a leaf is evaluated by its Gaussian moments
(``remainder="gaussian"``, default) or by the saddlepoint of its own CGF
:math:`t^\top m + \tfrac12 t^\top S t + n \log M_{\text{box}}(t)`
(``remainder="saddlepoint"``). Neither is accurate for one or two uniform
targets in a box much wider than the noise (measured in dx = 3, box 4³,
Σ0 = 0.5 I: one target 22 % (Gaussian) and 35 % (saddlepoint) too high, two
targets 1 % and 20 %).

Best-first refinement: starting from the root, the frontier node with the
largest term at y0 (a binary heap) is replaced by its children, as long as the
frontier holds at most ``budget`` terms (a node whose children do not fit is
left as it is). Terms below ``1e-12`` of the current total are not refined.
Because every frontier node has at least one leaf below it and the leaves of
different nodes differ, the frontier never holds more terms than the full
mixture: when the full mixture fits in ``budget``, every node is refined to
its leaves and the result **is** the exact mixture (the negligible-term cut
is then off). The refinement is compiled (numba); its cost is about one
Gaussian evaluation per created node.

A multi-Bernoulli component given by particles (or a general g, through the
quadrature of :mod:`jointtrack.superpositional.saddlepoint`) enters through
its moments when it exists (its position is not enumerated); an IIDC/Poisson
spatial density given by particles enumerates counts per particle.

The ratio R(x) of (16)/(18) uses the reduced mixture of (17)
(:func:`jointtrack.superpositional.models.reduced_mixture`): each submodel's
tree is refined once for all the L points :math:`\mathbf y_0 - g(x)` together,
a node's priority being its largest term relative to each point's current
total, so the work is shared across states (vectorised over them).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.stats import poisson

from jointtrack._numba_linalg import cholesky_lower, cholesky_solve, mahalanobis_sq
from jointtrack.assignment._checks import as_float, as_int
from jointtrack.superpositional.models import reduced_mixture
from jointtrack.superpositional.saddlepoint import (
    _DEFAULT_QUADRATURE,
    _BernoulliPart,
    _BoxLaw,
    _CardinalityPart,
    _GaussianPart,
    _model_parts,
    _PoissonPart,
    solve_saddlepoint,
)

__all__ = ["DEFAULT_BOX_BUDGET", "DEFAULT_BUDGET", "log_likelihood", "log_likelihood_ratio"]

#: Default maximum number of mixture terms: every multi-Bernoulli set of up to 8
#: components exactly. A model with a uniform-box part gets fewer: its terms are
#: integrated by quadrature (about 5× the cost of a Gaussian term); 96 keeps the
#: report's Table III within ≤ 1 ms (benchmarks/RESULTS.md).
DEFAULT_BUDGET = 256
DEFAULT_BOX_BUDGET = 96
#: Terms below exp(_NEGLIGIBLE) of a point's current total are not refined.
_NEGLIGIBLE = math.log(1e-12)
#: A Poisson cardinality is truncated where its upper tail is below this.
_POISSON_TAIL = 1e-16
#: A node covariance's Cholesky pivot ≤ 0 (rounding on a singular remainder) is set to this.
_PIVOT_FLOOR = 1e-300
#: Gauss-Legendre rule per polynomial piece of a uniform-sum density (outer coordinate).
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(12)
_WINDOW = 6.0
_LOG_2PI = math.log(2.0 * math.pi)


def _logsumexp(a, axis=0):
    """logsumexp along ``axis`` (-inf if every entry is); cheaper than scipy's on small arrays."""
    m = np.max(a, axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        return np.squeeze(m, axis=axis) + np.log(np.sum(np.exp(a - m), axis=axis))


#: Per-variable fields of :class:`_Tree`: number of dy-sized axes and dtype.
_FIELDS = {
    "kind": (0, np.int64),
    "vm": (1, np.float64),
    "vC": (2, np.float64),
    "la": (0, np.float64),
    "lb": (0, np.float64),
    "last": (0, np.bool_),
    "mlast": (1, np.float64),
    "Clast": (2, np.float64),
    "end": (0, np.int64),
    "mode": (0, np.int64),
    "boxidx": (0, np.int64),
    "A_m": (1, np.float64),
    "A_S": (2, np.float64),
    "B_m": (1, np.float64),
    "B_S": (2, np.float64),
}


class _Tree:
    """The ordered latent variables of a model, as flat arrays for :func:`_refine_kernel`.

    Per depth d: ``kind`` (0 Bernoulli bit, 1 cardinality, 2 count of one spatial
    component), the component's moments ``vm``/``vC``, log probabilities
    ``la``/``lb`` (exists/absent, or log p_k / log(1 - p_k) of the binomial),
    ``last`` (the next count is what is left: ``mlast``/``Clast``), ``end`` (the
    depth where the part ends), for a cardinality its ``mode`` (0 counts follow,
    1 a single spatial component, 2 a uniform box number ``boxidx``) and support
    ``sup``/``slogp``/``slen``; the remainder moments A[d] + n_r B[d].
    """

    def __init__(self, parts, dy):
        self.dy = dy
        self.box_laws = []
        self.full_size = 1
        # uniform-box parts first: their count is the least Gaussian variable
        parts = sorted(parts, key=lambda part: not isinstance(getattr(part, "law", None), _BoxLaw))
        moments, sure_m, sure_S = [], np.zeros(dy), np.zeros((dy, dy))
        for part in parts:
            mean, cov = part.moments()
            if isinstance(part, _BernoulliPart):  # components with r = 1: the root offset
                m, C = part.component_moments()
                sure = part.r == 1.0
                dm, dS = m[sure].sum(axis=0), C[sure].sum(axis=0)
                sure_m, sure_S = sure_m + dm, sure_S + dS
                mean, cov = mean - dm, cov - dS
            moments.append((mean, cov))
        self.root_m, self.root_S = sure_m, sure_S
        after_m = np.zeros((len(parts) + 1, dy))
        after_S = np.zeros((len(parts) + 1, dy, dy))
        for p in range(len(parts) - 1, -1, -1):
            after_m[p] = after_m[p + 1] + moments[p][0]
            after_S[p] = after_S[p + 1] + moments[p][1]
        blocks = []  # one dict of per-variable arrays per part, concatenated below
        for p, part in enumerate(parts):
            depth = sum(b["n"] for b in blocks)
            if isinstance(part, _BernoulliPart):
                m, C = part.component_moments()
                keep = (part.r > 0.0) & (part.r < 1.0)  # r = 0, 1: no variable
                m, C, r = m[keep], C[keep], part.r[keep]
                n = r.size
                if n == 0:
                    continue
                # Campbell moments of components j.. (suffix sums) plus the later parts
                cm = (r[:, None] * m)[::-1].cumsum(axis=0)[::-1]
                # r(1 − r) m mᵀ as the outer product of √(r(1 − r)) m: m mᵀ alone
                # overflows for a mean of 1e155 even when r = 1e-300 makes the share small
                v = np.sqrt(r * (1.0 - r))[:, None] * m
                cS = (r[:, None, None] * C + v[:, :, None] * v[:, None, :])[::-1]
                blocks.append(
                    self._block(
                        n,
                        dy,
                        kind=0,
                        vm=m,
                        vC=C,
                        la=np.log(r),
                        lb=np.log1p(-r),
                        end=depth + n,
                        A_m=after_m[p + 1] + cm,
                        A_S=after_S[p + 1] + cS.cumsum(axis=0)[::-1],
                    )
                )
                self.full_size *= 2**n
                continue
            if isinstance(part, _PoissonPart):
                lam = part.mean_count
                n_max = int(poisson.isf(_POISSON_TAIL, lam)) + 1 if lam > 0 else 0
                pmf = poisson.pmf(np.arange(n_max + 1), lam)
                part = _CardinalityPart(pmf / pmf.sum(), part.law)
            support = np.flatnonzero(part.pmf > 0)
            law = part.law
            K = 1 if isinstance(law, _BoxLaw) else law.means.shape[0]
            n_count = 0 if K == 1 else K - 1
            card = {
                "kind": 1,
                "sup": support,
                "slogp": part.log_pmf[support],
                "end": depth + 1 + n_count,
                "A_m": after_m[p],
                "A_S": after_S[p],
            }
            if isinstance(law, _BoxLaw):
                blocks.append(self._block(1, dy, mode=2, boxidx=len(self.box_laws), **card))
                self.box_laws.append(law)
                self.full_size *= int(support.size)
                continue
            if K == 1:
                blocks.append(self._block(1, dy, mode=1, vm=law.means, vC=law.covs, **card))
                self.full_size *= int(support.size)
                continue
            blocks.append(self._block(1, dy, **card))
            self.full_size *= sum(math.comb(int(n) + K - 1, K - 1) for n in support)
            # one draw from the renormalised components k.. (suffix mixtures)
            w = np.exp(law.logw)
            tw = w[::-1].cumsum()[::-1]
            M1 = (w[:, None] * law.means)[::-1].cumsum(axis=0)[::-1] / tw[:, None]
            M2 = (w[:, None, None] * (law.covs + law.means[:, :, None] * law.means[:, None, :]))[
                ::-1
            ].cumsum(axis=0)[::-1] / tw[:, None, None]
            pk = (w / tw)[: K - 1]
            with np.errstate(divide="ignore"):
                lb = np.log1p(-pk)
            blocks.append(
                self._block(
                    K - 1,
                    dy,
                    kind=2,
                    vm=law.means[: K - 1],
                    vC=law.covs[: K - 1],
                    la=np.log(pk),
                    lb=lb,
                    last=np.arange(K - 1) == K - 2,
                    mlast=law.means[K - 1],
                    Clast=law.covs[K - 1],
                    end=depth + 1 + n_count,
                    A_m=after_m[p + 1],
                    A_S=after_S[p + 1],
                    B_m=M1[: K - 1],
                    B_S=M2[: K - 1] - M1[: K - 1, :, None] * M1[: K - 1, None, :],
                )
            )
        D = self.depth = sum(b["n"] for b in blocks)
        cat = {}
        for key, (axes, dtype) in _FIELDS.items():
            arr = np.zeros((D, *((dy,) * axes)), dtype=dtype)
            d = 0
            for b in blocks:
                if key in b:
                    arr[d : d + b["n"]] = b[key]
                d += b["n"]
            cat[key] = arr
        for key in ("kind", "vm", "vC", "la", "lb", "last", "mlast", "Clast", "end"):
            setattr(self, key, cat[key])
        self.mode, self.boxidx = cat["mode"], cat["boxidx"]
        # the remainder after the last variable is nothing
        self.A_m = np.concatenate([cat["A_m"], np.zeros((1, dy))])
        self.A_S = np.concatenate([cat["A_S"], np.zeros((1, dy, dy))])
        self.B_m = np.concatenate([cat["B_m"], np.zeros((1, dy))])
        self.B_S = np.concatenate([cat["B_S"], np.zeros((1, dy, dy))])
        smax = max([b["support"][0].size for b in blocks if "support" in b], default=1)
        self.sup = np.zeros((D, smax), dtype=np.int64)
        self.slogp = np.full((D, smax), -np.inf)
        self.slen = np.zeros(D, dtype=np.int64)
        d = 0
        for b in blocks:
            if "support" in b:  # a single cardinality variable
                sup, slogp = b["support"]
                self.slen[d] = sup.size
                self.sup[d, : sup.size] = sup
                self.slogp[d, : sup.size] = slogp
            d += b["n"]
        nb = len(self.box_laws)
        self.box_mean = np.array([b.mean() for b in self.box_laws]).reshape(nb, dy)
        self.box_cov = np.array(
            [b.second_moment() - np.outer(b.mean(), b.mean()) for b in self.box_laws]
        ).reshape(nb, dy, dy)

    @staticmethod
    def _block(n, dy, sup=None, slogp=None, **fields):
        """n consecutive variables: the fields given (the others are zero).

        A cardinality variable's support and log pmf are kept as ``support``.
        """
        out = {"n": n, **fields}
        if sup is not None:
            out["support"] = (sup, slogp)
        return out

    def quadrature(self):
        """``quad`` argument of the kernel: the first uniform-box part by quadrature when possible.

        Possible when its g is linear with a full-column-rank H and dx ≤ 2; else
        (off) the box counts enter through their moments like everything else.
        """
        on = False
        if self.box_laws:
            A = self.box_laws[0].A
            AtA = A.T @ A
            on = bool(A.shape[1] <= 2 and np.linalg.det(AtA) > 1e-12 * np.trace(AtA) ** A.shape[1])
        if not on:
            z = np.zeros(1)
            return (False, np.zeros((self.dy, 1)), z, z + 1.0, _GL_NODES, _GL_WEIGHTS)
        b = self.box_laws[0]
        low = b.center - 0.5 * b.width
        return (True, np.array(b.A, order="C"), low, b.width.copy(), _GL_NODES, _GL_WEIGHTS)

    def kernel_arrays(self):
        """The arrays :func:`_refine_kernel` takes, in its argument order."""
        return (
            self.kind, self.vm, self.vC, self.la, self.lb, self.last, self.mlast, self.Clast,
            self.end, self.mode, self.boxidx, self.sup, self.slogp, self.slen,
            self.A_m, self.A_S, self.B_m, self.B_S, self.box_mean, self.box_cov,
            self.root_m, self.root_S,
        )  # fmt: skip


@numba.njit(cache=True)
def _normal_partial_moment(u, m):
    """E[(u - Z)_+^m] for Z ~ N(0, 1): h_m = u h_{m-1} + (m - 1) h_{m-2}."""
    if u > 9.0:  # Φ(u) = 1 and φ(u) = 0 to double precision: the full moment E[(u - Z)^m]
        Phi, phi = 1.0, 0.0
    else:
        Phi = 0.5 * math.erfc(-u / math.sqrt(2.0))
        phi = math.exp(-0.5 * u * u) / math.sqrt(2.0 * math.pi)
    if m == 0:
        return Phi
    h0, h1 = Phi, u * Phi + phi
    for j in range(2, m + 1):
        h0, h1 = h1, u * h1 + (j - 1) * h0
    return h1


@numba.njit(cache=True)
def _uniform_sum_density(x, n, lo, w, sd):
    """Density at x of U_1 + … + U_n (iid uniform on [lo, lo + w]) plus N(0, sd²), sd ≥ 0.

    The n-th finite difference of the n-th antiderivative of the smoothing
    density: w^{-n} Σ_k (-1)^k C(n, k) F_n(x - n lo - k w), with F_n the n-fold
    integral of N(0, sd²) (sd^{n-1} h_{n-1}(z / sd) / (n-1)!) or, for sd = 0,
    of a point mass ((z)_+^{n-1} / (n-1)!: the Irwin-Hall density).
    """
    y = x - n * lo
    tot = 0.0
    coef = 1.0
    for k in range(n + 1):
        z = y - k * w
        # z only decreases with k: once a term vanishes (below -9 sd its share is
        # < φ(9) ≈ 1e-18 of the scale sd^(n-1)), so do all later ones
        if sd > 0.0:
            u = z / sd
            if u <= -9.0:
                break
            tot += coef * _normal_partial_moment(u, n - 1)
        else:
            if z <= 0.0:
                break
            tot += coef * z ** (n - 1)
        coef = -coef * (n - k) / (k + 1)
    scale = sd ** (n - 1) if sd > 0.0 else 1.0
    return max(tot, 0.0) * scale / (math.exp(math.lgamma(n)) * w**n)


@numba.njit(cache=True)
def _uniform_sum_expectation(mu, cov, n, lo, w, glx, glw):
    """E f(s) for s ~ N(mu, cov) (dx = 1 or 2), f the density of a sum of n uniforms on the box.

    dx = 2: the outer coordinate by Gauss-Legendre within ±``_WINDOW`` sd (mass
    outside < 2e-9), on each polynomial piece of its Irwin-Hall density for n ≤ 2
    (a jump or a kink), in one panel for n ≥ 3 (continuously differentiable); the
    inner coordinate in closed form given the outer.
    """
    if mu.size == 1:
        return _uniform_sum_density(mu[0], n, lo[0], w[0], math.sqrt(cov[0, 0]))
    sd1 = math.sqrt(cov[0, 0])
    beta = cov[0, 1] / cov[0, 0]
    sd21 = math.sqrt(max(cov[1, 1] - cov[0, 1] * beta, 0.0))
    a = max(n * lo[0], mu[0] - _WINDOW * sd1)
    b = min(n * (lo[0] + w[0]), mu[0] + _WINDOW * sd1)
    tot = 0.0
    k0 = max(int(math.floor((a - n * lo[0]) / w[0])), 0)
    # n ≥ 3: the density is C¹ across its knots, one panel over the window suffices
    pieces = n if n <= 2 else k0 + 1
    for k in range(k0, pieces):
        p = max(a, n * lo[0] + k * w[0]) if n <= 2 else a
        q = min(b, n * lo[0] + (k + 1) * w[0]) if n <= 2 else b
        if q <= p:
            continue
        half, mid = 0.5 * (q - p), 0.5 * (q + p)
        for g in range(glx.size):
            s1 = mid + half * glx[g]
            e = (s1 - mu[0]) / sd1
            dens = math.exp(-0.5 * e * e) / (sd1 * math.sqrt(2.0 * math.pi))
            f1 = _uniform_sum_density(s1, n, lo[0], w[0], 0.0)
            f2 = _uniform_sum_density(mu[1] + beta * (s1 - mu[0]), n, lo[1], w[1], sd21)
            tot += half * glw[g] * dens * f1 * f2
    return tot


@numba.njit(cache=True)
def _box_node_terms(i, Y, n, mean, L, logdet, lw, qA, qlo, qw, glx, glw, term):
    """term[i, p] = lw + log ∫ N(Y[p] - mean - A s; S) f_n(s) ds, S = L Lᵀ, logdet = log det S.

    With P = AᵀS⁻¹A and ŝ = P⁻¹AᵀS⁻¹r, the Gaussian factor is a Gaussian in s
    times a constant, so the integral is that constant × E f_n(s), s ~ N(ŝ, P⁻¹).
    """
    dy, dx = qA.shape
    X = np.empty((dy, dx))  # S⁻¹ A, column by column
    for c in range(dx):
        cholesky_solve(L, qA[:, c], X[:, c])
    Pm = np.zeros((dx, dx))
    for a in range(dx):
        for b in range(dx):
            for k in range(dy):
                Pm[a, b] += qA[k, a] * X[k, b]
    Pinv = np.empty((dx, dx))
    if dx == 1:
        detP = Pm[0, 0]
        Pinv[0, 0] = 1.0 / detP
    else:
        detP = Pm[0, 0] * Pm[1, 1] - Pm[0, 1] * Pm[1, 0]
        Pinv[0, 0], Pinv[1, 1] = Pm[1, 1] / detP, Pm[0, 0] / detP
        Pinv[0, 1] = Pinv[1, 0] = -0.5 * (Pm[0, 1] + Pm[1, 0]) / detP
    const = lw - 0.5 * (logdet + math.log(detP) + (dy - dx) * _LOG_2PI)
    z = np.empty(dy)
    r = np.empty(dy)
    bvec = np.empty(dx)
    shat = np.empty(dx)
    for p in range(Y.shape[0]):
        q = mahalanobis_sq(L, Y[p], mean, z)
        for a in range(dy):
            r[a] = Y[p, a] - mean[a]
        for a in range(dx):
            bvec[a] = 0.0
            for k in range(dy):
                bvec[a] += X[k, a] * r[k]
        bs = 0.0
        for a in range(dx):
            shat[a] = 0.0
            for b in range(dx):
                shat[a] += Pinv[a, b] * bvec[b]
            bs += bvec[a] * shat[a]
        e = _uniform_sum_expectation(shat, Pinv, n, qlo, qw, glx, glw)
        if e > 0.0:
            term[i, p] = const - 0.5 * (q - bs) + math.log(e)
        else:
            term[i, p] = -np.inf


@numba.njit(cache=True)
def _node_terms(
    i, Y, noise, lw, om, oS, dep, nr, boxn, Am, AS, Bm, BS, boxm, boxC, term, work, quad
):  # fmt: skip
    """term[i, p] = lw[i] + log N(Y[p]; node i's mean, covariance) for every point p.

    The node's Gaussian is its fixed part plus the remainder moments A[d] + n_r B[d]
    (and the uniform-box counts' moments) plus the noise, factored by
    :func:`~jointtrack._numba_linalg.cholesky_lower` in ``work``, a (dy + 2, dy)
    scratch array. With ``quad`` = (on, A, low, width, Gauss-Legendre nodes,
    weights) switched on, the first uniform-box part's count enters through
    :func:`_box_node_terms` instead of its moments.
    """
    use_quad, qA, qlo, qw, glx, glw = quad
    dy = Y.shape[1]
    d = dep[i]
    n_r = nr[i]
    mean = work[0]
    z = work[1]
    L = work[2 : 2 + dy]
    for a in range(dy):
        mean[a] = om[i, a] + Am[d, a] + n_r * Bm[d, a]
        for b in range(a + 1):
            L[a, b] = oS[i, a, b] + AS[d, a, b] + n_r * BS[d, a, b] + noise[a, b]
    first_box = 1 if use_quad and boxn.shape[1] > 0 and boxn[i, 0] > 0 else 0
    for bx in range(first_box, boxm.shape[0]):
        c = boxn[i, bx]
        if c > 0:
            for a in range(dy):
                mean[a] += c * boxm[bx, a]
                for b in range(a + 1):
                    L[a, b] += c * boxC[bx, a, b]
    # a pivot ≤ 0 is rounding on a singular remainder (the noise keeps it > 0 otherwise):
    # floored, so the node keeps a finite term. With the floor, only an overflowed
    # covariance (a +inf pivot) fails: its Gaussian density is taken as 0
    ok, logdet = cholesky_lower(L, L, _PIVOT_FLOOR)
    if not ok:
        for p in range(Y.shape[0]):
            term[i, p] = -np.inf
        return
    if first_box:
        _box_node_terms(i, Y, boxn[i, 0], mean, L, logdet, lw[i], qA, qlo, qw, glx, glw, term)
        return
    const = lw[i] - 0.5 * (logdet + dy * _LOG_2PI)
    for p in range(Y.shape[0]):
        term[i, p] = const - 0.5 * mahalanobis_sq(L, Y[p], mean, z)


@numba.njit(cache=True)
def _heap_push(hk, hi, size, key, idx):
    j = size
    hk[j] = key
    hi[j] = idx
    while j > 0:
        parent = (j - 1) // 2
        if hk[parent] >= hk[j]:
            break
        hk[parent], hk[j] = hk[j], hk[parent]
        hi[parent], hi[j] = hi[j], hi[parent]
        j = parent
    return size + 1


@numba.njit(cache=True)
def _heap_pop(hk, hi, size):
    key, idx = hk[0], hi[0]
    size -= 1
    hk[0], hi[0] = hk[size], hi[size]
    j = 0
    while True:
        a, b, m = 2 * j + 1, 2 * j + 2, j
        if a < size and hk[a] > hk[m]:
            m = a
        if b < size and hk[b] > hk[m]:
            m = b
        if m == j:
            break
        hk[m], hk[j] = hk[j], hk[m]
        hi[m], hi[j] = hi[j], hi[m]
        j = m
    return key, idx, size


@numba.njit(cache=True)
def _refine_kernel(
    Y, noise, kind, vm, vC, la, lb, last, mlast, Clast, end, mode, boxidx, sup, slogp, slen,
    Am, AS, Bm, BS, boxm, boxC, root_m, root_S, budget, exact_fit, cut, quad,
):  # fmt: skip
    """Best-first refinement (module docstring); returns the frontier's node indices and arrays."""
    P, dy = Y.shape
    D = kind.size
    nb = boxm.shape[0]
    cap = 2 * budget + 4 * D + 64  # budget is already capped by the full mixture size
    lw = np.zeros(cap)
    om = np.zeros((cap, dy))
    oS = np.zeros((cap, dy, dy))
    dep = np.zeros(cap, dtype=np.int64)
    nr = np.zeros(cap, dtype=np.int64)
    boxn = np.zeros((cap, nb), dtype=np.int64)
    term = np.zeros((cap, P))
    alive = np.zeros(cap, dtype=np.bool_)
    hk = np.empty(cap)
    hi = np.empty(cap, dtype=np.int64)
    work = np.empty((2 + dy, dy))
    om[0] = root_m
    oS[0] = root_S
    _node_terms(
        0, Y, noise, lw, om, oS, dep, nr, boxn, Am, AS, Bm, BS, boxm, boxC, term, work, quad
    )
    alive[0] = True
    ref = term[0].copy()
    rel = np.ones(P)  # Σ over the frontier of exp(term - ref), per point
    n_nodes, frontier, hsize, expansions = 1, 1, 0, 0
    if D > 0:
        hsize = _heap_push(hk, hi, hsize, 0.0, 0)
    while hsize > 0:
        key, i, hsize = _heap_pop(hk, hi, hsize)
        d = dep[i]
        k = kind[d]
        c = 2 if k == 0 else (slen[d] if k == 1 else nr[i] + 1)
        if frontier + c - 1 > budget or n_nodes + c > cap:
            continue
        if not exact_fit:
            share = -np.inf
            for p in range(P):
                share = max(share, term[i, p] - ref[p] - math.log(max(rel[p], 1e-300)))
            if share < cut:
                continue
        for j in range(n_nodes, n_nodes + c):
            lw[j] = lw[i]
            om[j] = om[i]
            oS[j] = oS[i]
            nr[j] = nr[i]
            boxn[j] = boxn[i]
            dep[j] = d + 1
        if k == 0:
            lw[n_nodes] += la[d]
            om[n_nodes] += vm[d]
            oS[n_nodes] += vC[d]
            lw[n_nodes + 1] += lb[d]
        elif k == 1:
            for s in range(c):
                j = n_nodes + s
                n = sup[d, s]
                lw[j] += slogp[d, s]
                if mode[d] == 0:
                    nr[j] = n
                    dep[j] = d + 1 if n > 0 else end[d]
                elif mode[d] == 1:
                    om[j] += n * vm[d]
                    oS[j] += n * vC[d]
                    dep[j] = end[d]
                else:
                    boxn[j, boxidx[d]] = n
                    dep[j] = end[d]
        else:
            n_r = nr[i]
            base = math.lgamma(n_r + 1.0)
            for cc in range(c):
                j = n_nodes + cc
                left = n_r - cc
                lwc = base - math.lgamma(cc + 1.0) - math.lgamma(left + 1.0)
                if cc > 0:
                    lwc += cc * la[d]
                if left > 0:
                    lwc += left * lb[d]
                lw[j] += lwc
                om[j] += cc * vm[d]
                oS[j] += cc * vC[d]
                if last[d]:
                    om[j] += left * mlast[d]
                    oS[j] += left * Clast[d]
                    nr[j] = 0
                    dep[j] = end[d]
                else:
                    nr[j] = left
                    dep[j] = d + 1 if left > 0 else end[d]
        alive[i] = False
        for p in range(P):
            rel[p] -= math.exp(term[i, p] - ref[p])
        for j in range(n_nodes, n_nodes + c):
            _node_terms(
                j, Y, noise, lw, om, oS, dep, nr, boxn, Am, AS, Bm, BS, boxm, boxC, term, work, quad
            )
            alive[j] = True
            best = -np.inf
            for p in range(P):
                rel[p] += math.exp(term[j, p] - ref[p])
                best = max(best, term[j, p] - ref[p])
            # a node whose Gaussian term underflows at every point (a far or singular
            # remainder) can still hold leaves that matter: with the whole mixture in
            # the budget it is refined too (last), so the result is the exact mixture
            if dep[j] < D and (np.isfinite(best) or exact_fit):
                hsize = _heap_push(hk, hi, hsize, best if np.isfinite(best) else -np.inf, j)
        n_nodes += c
        frontier += c - 1
        expansions += 1
    idx = np.flatnonzero(alive[:n_nodes])
    return idx, lw, om, oS, dep, boxn, term, expansions


class _Frontier:
    """The refined frontier: per node log weight, fixed mean/cov, depth, uniform-box counts."""

    def __init__(self, lw, om, oS, depth, boxn):
        self.lw, self.om, self.oS, self.depth, self.boxn = lw, om, oS, depth, boxn


def _refine(tree, Y, noise_cov, budget):
    """Run :func:`_refine_kernel`: the frontier, its log terms (F, P), the expansions made
    and whether the first uniform-box part was integrated by quadrature."""
    exact_fit = tree.full_size <= budget
    quad = tree.quadrature()
    # fresh writable C arrays: one compiled signature whatever the caller passed
    idx, lw, om, oS, dep, boxn, term, expansions = _refine_kernel(
        np.array(Y, dtype=np.float64, order="C"),
        np.array(noise_cov, dtype=np.float64, order="C"),
        *tree.kernel_arrays(),
        int(min(budget, tree.full_size)),
        bool(exact_fit),
        _NEGLIGIBLE,
        quad,
    )
    fr = _Frontier(lw[idx], om[idx], oS[idx], dep[idx], boxn[idx])
    return fr, term[idx], int(expansions), bool(quad[0])


def _box_saddlepoint_terms(tree, fr, terms, Y, noise_cov, options):
    """Replace the terms of leaves holding uniform-box targets by their saddlepoint values."""
    if not tree.box_laws:
        return terms
    leaf = (fr.depth == tree.depth) & (fr.boxn > 0).any(axis=1)
    if not leaf.any():
        return terms
    terms = terms.copy()
    groups = {}
    for i in np.flatnonzero(leaf):
        groups.setdefault(tuple(int(v) for v in fr.boxn[i]), []).append(i)
    P = Y.shape[0]
    for counts, rows in groups.items():
        rows = np.array(rows)
        R = rows.size
        mean = np.repeat(fr.om[rows], P, axis=0)
        cov = np.repeat(fr.oS[rows] + noise_cov, P, axis=0)
        parts = [_GaussianPart(mean, cov)]
        for b, n in enumerate(counts):
            if n > 0:
                pmf = np.zeros(n + 1)
                pmf[n] = 1.0
                parts.append(_CardinalityPart(pmf, tree.box_laws[b]))
        logf, _ = solve_saddlepoint(parts, np.tile(Y, (R, 1)), **options)
        terms[rows] = fr.lw[rows, None] + logf.reshape(R, P)
    return terms


def _check_options(budget, remainder, max_iter, tol, quadrature_points):
    budget = None if budget is None else as_int(budget, "budget", minimum=1)
    if not isinstance(remainder, str) or remainder not in ("gaussian", "saddlepoint"):
        raise ValueError(f"remainder must be 'gaussian' or 'saddlepoint', got {remainder!r}")
    max_iter = as_int(max_iter, "max_iter", minimum=1)
    tol = as_float(tol, "tol", minimum=0.0, open_min=True)
    quadrature_points = as_int(quadrature_points, "quadrature_points", minimum=1, maximum=64)
    return budget, remainder, {"max_iter": max_iter, "tol": tol}, quadrature_points


def _evaluate(model, measurement, noise_cov, Y, budget, remainder, sp_options, quadrature_points):
    parts = _model_parts(model, measurement, quadrature_points)
    tree = _Tree(parts, measurement.dy)
    if budget is None:
        budget = DEFAULT_BOX_BUDGET if tree.box_laws else DEFAULT_BUDGET
    fr, terms, expansions, quadrature = _refine(tree, Y, noise_cov, budget)
    if remainder == "saddlepoint" and not quadrature:
        terms = _box_saddlepoint_terms(tree, fr, terms, Y, noise_cov, sp_options)
    leaves = fr.depth == tree.depth
    exact = bool(leaves.all()) and not tree.box_laws
    # frontier nodes left unrefined whose Gaussian stand-in underflowed at every point
    # (a singular or far remainder) though they carry weight: the mixture below them may
    # not be 0, so the value is then only a lower bound (−inf possibly where I > 0)
    underflowed = ~leaves & np.isfinite(fr.lw) & ~np.isfinite(terms).any(axis=1)
    info = {
        "terms": int(fr.lw.size),
        "underflowed_terms": int(underflowed.sum()),
        "leaf_terms": int(leaves.sum()),
        "full_mixture_terms": tree.full_size,
        "exact": exact,
        "expansions": expansions,
        "budget": budget,
        "box_quadrature": quadrature,
    }
    return _logsumexp(terms, axis=0), info


def log_likelihood(
    y0,
    model,
    measurement,
    noise_cov,
    *,
    budget=None,
    remainder="gaussian",
    max_iter=100,
    tol=1e-12,
    quadrature_points=_DEFAULT_QUADRATURE,
):
    r"""Hybrid approximation of log I of (2)-(3) (algorithm in the module docstring).

    Parameters
    ----------
    y0 : ndarray, shape (dy,)
    model : MultiBernoulli, IIDC, Poisson or Union
    measurement : LinearMeasurement or FunctionMeasurement
    noise_cov : ndarray, shape (dy, dy)
    budget : int, optional
        Maximum number of mixture terms (≥ 1; 1 is the Gaussian approximation (9)).
        Default :data:`DEFAULT_BUDGET` (256), :data:`DEFAULT_BOX_BUDGET` (96) for a
        model with a uniform-box part.
    remainder : {"gaussian", "saddlepoint"}, optional
        How a leaf holding uniform-box targets is evaluated when the quadrature
        does not apply (module docstring).
    max_iter, tol, quadrature_points : optional
        Saddlepoint options (see :mod:`jointtrack.superpositional.saddlepoint`).

    Returns
    -------
    log_value : float
    info : dict
        ``terms`` (frontier size), ``leaf_terms`` (exact mixture terms among them),
        ``underflowed_terms`` (unrefined nodes whose Gaussian term underflowed
        to 0 though they carry weight: when > 0 the value is only a lower bound,
        raise ``budget``), ``full_mixture_terms``, ``exact`` (the result is the
        exact mixture),
        ``expansions`` (nodes refined), ``budget``, ``box_quadrature`` (a
        uniform-box part integrated by quadrature).

    Examples
    --------
    >>> import numpy as np
    >>> from jointtrack.superpositional.models import MultiBernoulli
    >>> from jointtrack.superpositional.measurement import LinearMeasurement
    >>> model = MultiBernoulli([0.5, 0.9], [[0.0], [3.0]], [[[1.0]], [[1.0]]])
    >>> lv, info = log_likelihood(np.array([3.0]), model, LinearMeasurement([[1.0]]), np.eye(1))
    >>> info["exact"], info["terms"]
    (True, 4)
    """
    budget, remainder, sp_options, quadrature_points = _check_options(
        budget, remainder, max_iter, tol, quadrature_points
    )
    Y = np.asarray(y0, dtype=np.float64).reshape(1, -1)
    logv, info = _evaluate(
        model, measurement, noise_cov, Y, budget, remainder, sp_options, quadrature_points
    )
    return float(logv[0]), info


def log_likelihood_ratio(
    y0,
    x,
    model,
    measurement,
    noise_cov,
    *,
    budget=None,
    remainder="gaussian",
    max_iter=100,
    tol=1e-12,
    quadrature_points=_DEFAULT_QUADRATURE,
    part=None,
):
    r"""Hybrid approximation of log R(x) of (16)/(18) for the states x (L, dx).

    Each submodel of the reduced mixture of (17) is refined once for all the
    points :math:`\mathbf y_0 - g(x)` (module docstring); ``budget`` applies per
    submodel. ``part`` reduces only that part of a Union.

    Returns
    -------
    ndarray, shape (L,)

    Examples
    --------
    >>> import numpy as np
    >>> from jointtrack.superpositional.models import MultiBernoulli
    >>> from jointtrack.superpositional.measurement import LinearMeasurement
    >>> model = MultiBernoulli([0.5, 0.9], [[0.0], [3.0]], [[[1.0]], [[1.0]]])
    >>> log_likelihood_ratio(np.array([3.0]), np.array([[0.0], [3.0]]), model,
    ...                      LinearMeasurement([[1.0]]), np.eye(1)).shape
    (2,)
    """
    budget, remainder, sp_options, quadrature_points = _check_options(
        budget, remainder, max_iter, tol, quadrature_points
    )
    y0 = np.asarray(y0, dtype=np.float64).ravel()
    x = np.asarray(x, dtype=np.float64)
    log_den, _ = _evaluate(
        model, measurement, noise_cov, y0[None], budget, remainder, sp_options, quadrature_points
    )
    Y = y0[None] - measurement(x)
    log_w, submodels = reduced_mixture(model, x, part)
    log_num = np.full(x.shape[0], -np.inf)
    for k, sub in enumerate(submodels):
        rows = np.flatnonzero(np.isfinite(log_w[:, k]))
        if rows.size == 0:
            continue
        logv, _ = _evaluate(
            sub, measurement, noise_cov, Y[rows], budget, remainder, sp_options, quadrature_points
        )
        log_num[rows] = np.logaddexp(log_num[rows], log_w[rows, k] + logv)
    return log_num - log_den[0]
