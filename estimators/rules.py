"""Gaussian integration rules (ALGORITHMS.md 3.2, 4.2). A rule computes the moments of a
map of a Gaussian (the dynamax shape): given y = map(x) with x ~ N(mean, cov), it returns
E[y], Cov[y] and Cov[x, y]; the generic filter adds the noise. A linear map (a model
that declares its matrix) is exact under every rule; nonlinear maps are where the rules
differ.

- LinearizationRule: the EKF: the map at the mean and its Jacobian (analytic, or central
  differences).
- UnscentedRule(alpha, beta, kappa): scaled unscented transform, 2n+1 points.
- CubatureRule: third-degree spherical-radial cubature, 2n points.
- GaussHermiteRule(order): tensor product of m-point Gauss-Hermite rules, m^n points.
- SparseGridGaussHermiteRule(level): Smolyak sparse grid of Gauss-Hermite rules, exact
  for polynomials of total degree <= 2L - 1.
- ReducedGaussHermiteRule(order): quadrature over the map's nonlinear states only, exact
  conditional moments over the rest (the conditionally linear partition, 000 eqs. 40-57).
"""
from __future__ import annotations

import itertools
from abc import ABC, abstractmethod
from functools import lru_cache
from math import comb

import numpy as np

from aligngym.estimators.model import GaussianMap, wrap_angle

MAX_POINTS = 200_000
"""Largest tensor-product grid per episode (memory: points x episodes x n x 8 bytes)."""


Moments = tuple[np.ndarray, np.ndarray, np.ndarray]


def symmetric(A: np.ndarray) -> np.ndarray:
    """(A + A^T) / 2 over the last two axes."""
    return 0.5 * (A + np.swapaxes(A, -1, -2))


def _linear_moments(fmap: GaussianMap, mean: np.ndarray, cov: np.ndarray) -> Moments:
    """Exact moments of y = M x: M mean, M cov M^T, cov M^T."""
    M = fmap.matrix
    Mt = np.swapaxes(M, -1, -2)
    return np.einsum("bij,bj->bi", M, mean), M @ cov @ Mt, cov @ Mt


class IntegrationRule(ABC):
    """Moments of a map of a Gaussian (see the module docstring)."""

    name: str
    has_negative_weights: bool = False
    needs: frozenset[str] = frozenset()
    """What the rule needs of the model's maps (keys of
    ``adaptation.OBSERVATION_FEATURES``)."""

    def moments(self, fmap: GaussianMap, mean: np.ndarray, cov: np.ndarray) -> Moments:
        """E[y] (B, d), Cov[y] (B, d, d) without the map's noise, Cov[x, y] (B, n, d) for
        y = fmap(x), x ~ N(mean (B, n), cov (B, n, n))."""
        if fmap.linear:
            return _linear_moments(fmap, mean, cov)
        return self._moments(fmap, mean, cov)

    @abstractmethod
    def _moments(self, fmap: GaussianMap, mean: np.ndarray, cov: np.ndarray) -> Moments:
        """Moments of a map given as a function."""

    def point_count(self, n: int) -> int:
        """Number of evaluations of the map per episode in dimension n."""
        return 1


class LinearizationRule(IntegrationRule):
    """First-order linearization at the mean (the EKF): E[y] = f(mean), Cov[y] = J P J^T,
    Cov[x, y] = P J^T, with J the model's Jacobian or central differences of f."""

    name = "linearization"

    def __init__(self, step: float | np.ndarray = 1e-6) -> None:
        self.step = step

    def _moments(self, fmap, mean, cov):
        y = fmap(mean[:, None, :])[:, 0]
        J = fmap.jacobian_at(mean, self.step)
        Jt = np.swapaxes(J, -1, -2)
        return y, J @ cov @ Jt, cov @ Jt


@lru_cache(maxsize=None)
def gauss_hermite_1d(m: int) -> tuple[np.ndarray, np.ndarray]:
    """m-point Gauss-Hermite rule for N(0, 1) (probabilists'), Golub-Welsch: points (m,)
    are the eigenvalues of the tridiagonal J with J[i, i+1] = sqrt(i), weights the squared
    first components of the normalised eigenvectors."""
    if m < 1:
        raise ValueError(f"Gauss-Hermite order must be >= 1, got {m}")
    off = np.sqrt(np.arange(1, m))
    J = np.diag(off, 1) + np.diag(off, -1)
    points, vectors = np.linalg.eigh(J)
    weights = vectors[0] ** 2
    points[np.abs(points) < 1e-14] = 0.0
    return points, weights / weights.sum()


class SigmaPointRule(IntegrationRule):
    """A rule given by points (N, n) and mean/covariance weights (N,)."""

    def points(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """xi (N, n), W_mean (N,), W_cov (N,) for dimension n (computed once per n)."""
        cache = self.__dict__.setdefault("_point_cache", {})
        if n not in cache:
            cache[n] = self._weights(n)
        return cache[n]

    def _weights(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xi, w = self._points(n)
        return xi, w, w

    def _points(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def point_count(self, n: int) -> int:
        return len(self.points(n)[1])

    def _moments(self, fmap, mean, cov):
        n = mean.shape[-1]
        xi, wm, wc = self.points(n)
        S = _sqrt_psd(cov)
        chi = mean[:, None, :] + xi @ np.swapaxes(S, -1, -2)
        centre = int(np.argmin(np.einsum("ki,ki->k", xi, xi)))
        reference = None
        if fmap.angles and np.any(xi[centre]):      # no point at the mean: map the mean
            reference = fmap(mean[:, None, :])[:, 0]
        return weighted_moments(fmap(chi), chi - mean[:, None, :], wm, wc, fmap.angles,
                                centre, reference)


def weighted_moments(y: np.ndarray, dx: np.ndarray, wm: np.ndarray, wc: np.ndarray,
                     angles: tuple[int, ...] = (), centre: int = 0,
                     reference: np.ndarray | None = None) -> Moments:
    """Mean (B, d), covariance (B, d, d) and cross-covariance with x (B, n, d) from mapped
    points y (B, P, d), point offsets dx = chi - mean (B, P, n) and mean/covariance
    weights (P,). Angle components of y are averaged around a reference and their
    residuals wrapped: the image of the mean, ``reference`` (B, d), for a rule without a
    point at the mean, else the value at the point ``centre`` (the one at the mean). A
    reference at an outer point would wrap the opposite points by 2 pi once the spread
    of an angle passes +-90 deg (the cubature rule from paper 002's large starts)."""
    if angles:
        idx = list(angles)
        ref = (y[:, centre:centre + 1, idx] if reference is None
               else reference[:, None, idx])
        y = y.copy()
        y[..., idx] = ref + wrap_angle(y[..., idx] - ref)
    mean = (wm @ y)                                    # (B, d)
    d = y - mean[:, None, :]
    if angles:
        mean[:, idx] = wrap_angle(mean[:, idx])
    d_w = np.swapaxes(d * wc[:, None], -1, -2)         # (B, d, P)
    cov = d_w @ d
    cross = np.swapaxes(d_w @ dx, -1, -2)
    return mean, symmetric(cov), cross


def _sqrt_psd(P: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor (B, n, n); an episode whose P is not positive definite (the
    filter has flagged it) gets the square root V sqrt(max(D, 0)) of its eigenvalue-
    floored matrix (NaN entries as 0), without changing the other episodes' factors."""
    try:
        return np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        S = np.empty_like(P)
        for b in range(P.shape[0]):
            try:
                S[b] = np.linalg.cholesky(P[b])
            except np.linalg.LinAlgError:
                vals, vecs = np.linalg.eigh(np.where(np.isfinite(P[b]), P[b], 0.0))
                S[b] = vecs * np.sqrt(np.maximum(vals, 0.0))
        return S


class UnscentedRule(SigmaPointRule):
    """Scaled unscented transform (Julier & Uhlmann 2004): lambda = alpha^2 (n + kappa) - n,
    points 0 and +-sqrt(n + lambda) e_j; W_0 = lambda / (n + lambda),
    W_0^c = W_0 + 1 - alpha^2 + beta, W_j = 1 / (2 (n + lambda)). kappa None means 3 - n;
    spread, when given, sets n + kappa itself (with alpha 1 the points sit at
    +-sqrt(spread) sigma whatever n; alpha scales them)."""

    def __init__(self, alpha: float = 1.0, beta: float = 2.0, kappa: float | None = 0.0,
                 spread: float | None = None):
        if not (alpha > 0.0 and np.isfinite(alpha)):
            raise ValueError(f"unscented alpha must be > 0, got {alpha}")
        if spread is not None and not (spread > 0.0 and np.isfinite(spread)):
            raise ValueError(f"unscented spread n + kappa must be > 0, got {spread}")
        if spread is not None and kappa not in (0.0, None):
            raise ValueError(f"unscented: give kappa ({kappa}) or spread ({spread}), not both")
        self.alpha, self.beta, self.kappa, self.spread = alpha, beta, kappa, spread
        self.has_negative_weights = (spread is not None or kappa is None or kappa < 0.0
                                     or alpha < 1.0)
        self.name = (f"unscented(alpha={alpha:g}, beta={beta:g}, "
                     + (f"n+kappa={spread:g})" if spread is not None else f"kappa={kappa})"))

    def _weights(self, n):
        kappa = (self.spread - n if self.spread is not None
                 else 3.0 - n if self.kappa is None else self.kappa)
        lam = self.alpha ** 2 * (n + kappa) - n
        scale = np.sqrt(n + lam)
        xi = np.vstack([np.zeros(n), scale * np.eye(n), -scale * np.eye(n)])
        wm = np.full(2 * n + 1, 1.0 / (2.0 * (n + lam)))
        wm[0] = lam / (n + lam)
        wc = wm.copy()
        wc[0] += 1.0 - self.alpha ** 2 + self.beta
        return xi, wm, wc


class CubatureRule(SigmaPointRule):
    """Third-degree cubature (Arasaratnam & Haykin 2009): +-sqrt(n) e_j, W = 1/(2n)."""

    name = "cubature"

    def _points(self, n):
        xi = np.sqrt(n) * np.vstack([np.eye(n), -np.eye(n)])
        return xi, np.full(2 * n, 1.0 / (2 * n))


class GaussHermiteRule(SigmaPointRule):
    """Tensor-product Gauss-Hermite rule of order m: m^n points, exact when every
    per-variable exponent is <= 2m - 1."""

    def __init__(self, order: int = 3):
        self.order = order
        self.name = f"gauss-hermite({order})"

    def point_count(self, n: int) -> int:
        return self.order ** n

    def _points(self, n):
        count = self.order ** n
        if count > MAX_POINTS:
            raise ValueError(f"tensor-product Gauss-Hermite of order {self.order} in {n} "
                             f"dimensions needs {count:.3g} points (> {MAX_POINTS:.0e}); "
                             "use the sparse-grid rule")
        p, w = gauss_hermite_1d(self.order)
        xi = np.array(list(itertools.product(p, repeat=n)))
        W = np.prod(np.array(list(itertools.product(w, repeat=n))), axis=1)
        return xi, W


class SparseGridGaussHermiteRule(SigmaPointRule):
    """Smolyak sparse grid of 1-D Gauss-Hermite rules (Heiss & Winschel 2008; Jia, Xin &
    Cheng 2012), ALGORITHMS eq. (3.8):
    I_{n,L} = sum_{q=max(0,L-n)}^{L-1} (-1)^{L-1-q} C(n-1, L-1-q)
              sum_{|l| = n+q} I_{l_1} x ... x I_{l_n},
    with m_l = 2l - 1 points per 1-D level ("odd", the default) or m_l = l ("linear").
    Identical points are merged and weights below 1e-14 dropped."""

    def __init__(self, level: int = 2, growth: str = "odd"):
        if level < 1:
            raise ValueError(f"sparse-grid level must be >= 1, got {level}")
        if growth not in ("odd", "linear"):
            raise ValueError(f"growth must be 'odd' or 'linear', got {growth!r}")
        self.level, self.growth = level, growth
        self.has_negative_weights = level >= 2
        self.name = f"sparse-grid-gauss-hermite(L={level}, {growth})"

    def _points(self, n):
        return _smolyak(n, self.level, self.growth)


@lru_cache(maxsize=32)
def _smolyak(n: int, L: int, growth: str) -> tuple[np.ndarray, np.ndarray]:
    m_of = (lambda l: 2 * l - 1) if growth == "odd" else (lambda l: l)
    acc: dict[tuple, float] = {}
    for q in range(max(0, L - n), L):
        coef = (-1) ** (L - 1 - q) * comb(n - 1, L - 1 - q)
        for levels in _compositions(n + q, n):
            rules = [gauss_hermite_1d(m_of(l)) for l in levels]
            for combo in itertools.product(*[range(len(r[0])) for r in rules]):
                point = tuple(round(float(rules[d][0][i]), 12) for d, i in enumerate(combo))
                weight = coef * np.prod([rules[d][1][i] for d, i in enumerate(combo)])
                acc[point] = acc.get(point, 0.0) + weight
    items = [(p, w) for p, w in acc.items() if abs(w) > 1e-14]
    xi = np.array([p for p, _ in items], dtype=float)
    W = np.array([w for _, w in items])
    return xi, W


def _compositions(total: int, parts: int):
    """All tuples of `parts` positive integers summing to `total`."""
    if parts == 1:
        yield (total,)
        return
    for first in range(1, total - parts + 2):
        for rest in _compositions(total - first, parts - 1):
            yield (first,) + rest


class ReducedGaussHermiteRule(IntegrationRule):
    """Reduced-dimension Gauss-Hermite rule (Morelande & Ristic 2006; 000 eqs. 40-57;
    ALGORITHMS 4.2): an m-point GH tensor grid over the map's ``nonlinear`` states zeta
    only; given zeta the map y = F(zeta) x + g(zeta) is linear, so the other states enter
    through their exact conditional mean and covariance. With P = S S^T (lower Cholesky,
    zeta ordered first): Theta_i = mean + S[:, :l] xi_i, Sigma_c = S[:, l:] S[:, l:]^T,
    y_i = F_i Theta_i + g_i, Cov[y] = sum W_i [(y_i - y)(.)^T + F_i Sigma_c F_i^T],
    Cov[x, y] = sum W_i [(Theta_i - mean)(y_i - y)^T + Sigma_c F_i^T]."""

    needs = frozenset({"conditionally-linear"})

    def __init__(self, order: int = 7) -> None:
        if order < 1:
            raise ValueError(f"Gauss-Hermite order must be >= 1, got {order}")
        self.order = order
        self.name = f"reduced-gauss-hermite({order})"

    def _moments(self, fmap, mean, cov):
        if fmap.conditional is None or not fmap.nonlinear:
            raise ValueError("the reduced-dimension Gauss-Hermite rule needs the model's "
                             "conditionally linear form (conditional, nonlinear states)")
        n = mean.shape[-1]
        zeta = list(fmap.nonlinear)
        rest = [i for i in range(n) if i not in zeta]
        perm = np.array(zeta + rest)
        l = len(zeta)
        S = _sqrt_psd(cov[:, perm][:, :, perm])               # lower, zeta first
        inverse = np.argsort(perm)
        S_zeta = S[:, :, :l][:, inverse]                       # (B, n, l) original order
        S_rest = S[:, :, l:][:, inverse]
        Sigma_c = S_rest @ np.swapaxes(S_rest, -1, -2)          # (B, n, n)
        p, w = gauss_hermite_1d(self.order)
        xi = np.array(list(itertools.product(p, repeat=l)))     # (P, l)
        W = np.prod(np.array(list(itertools.product(w, repeat=l))), axis=1)
        offsets = np.einsum("bil,kl->bki", S_zeta, xi)          # (B, P, n)
        theta = mean[:, None, :] + offsets
        F, g = fmap.conditional(theta[..., zeta])               # (B, P, d, n), (B, P, d)
        y = np.einsum("bkij,bkj->bki", F, theta) + g
        centre = int(np.argmin(np.einsum("kl,kl->k", xi, xi)))
        reference = None
        if fmap.angles and np.any(xi[centre]):      # no point at the mean: map the mean
            F0, g0 = fmap.conditional(mean[:, None, zeta])
            reference = np.einsum("bij,bj->bi", F0[:, 0], mean) + g0[:, 0]
        y_mean, cov_y, cross = weighted_moments(y, offsets, W, W, fmap.angles, centre,
                                                reference)
        F_Sigma = F @ Sigma_c[:, None]                          # (B, P, d, n)
        cov_y = cov_y + np.einsum("k,bkij,bklj->bil", W, F_Sigma, F)
        cross = cross + np.einsum("k,bkij->bji", W, F_Sigma)
        return y_mean, symmetric(cov_y), cross

    def point_count(self, n: int, nonlinear: int = 1) -> int:
        """order ** (number of nonlinear states) points; the rest is exact."""
        return self.order ** nonlinear
