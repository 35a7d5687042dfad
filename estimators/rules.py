"""Gaussian integration rules: points xi_i and weights W_i for N(0, I_n) (ALGORITHMS.md
3.2). A rule only returns points and weights; the generic filter propagates the
Gaussian through them (``SigmaPointRule.predict``).

- UnscentedRule(alpha, beta, kappa): scaled unscented transform, 2n+1 points.
- CubatureRule: third-degree spherical-radial cubature, 2n points.
- GaussHermiteRule(order): tensor product of m-point Gauss-Hermite rules, m^n points.
- SparseGridGaussHermiteRule(level): Smolyak sparse grid of Gauss-Hermite rules, exact
  for polynomials of total degree <= 2L - 1.
"""
from __future__ import annotations

import itertools
from abc import ABC, abstractmethod
from functools import lru_cache
from math import comb

import numpy as np

MAX_POINTS = 2_000_000


class IntegrationRule(ABC):
    """How the filter propagates a Gaussian through the process model."""

    name: str

    @abstractmethod
    def predict(self, x: np.ndarray, P: np.ndarray, Phi: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Predicted mean (B, n) and Phi P Phi^T (B, n, n), without the process noise."""


class LinearRule(IntegrationRule):
    """Exact propagation through a linear(ised) model: the KF."""

    name = "linear"

    def predict(self, x, P, Phi):
        return (np.einsum("bij,bj->bi", Phi, x), Phi @ P @ np.swapaxes(Phi, -1, -2))


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
        """xi (N, n), W_mean (N,), W_cov (N,) for dimension n."""
        xi, w = self._points(n)
        return xi, w, w

    def _points(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def predict(self, x, P, Phi):
        """Mean and covariance of Phi x for x ~ N(x, P), from the points."""
        n = x.shape[-1]
        xi, wm, wc = self.points(n)
        S = _sqrt_psd(P)
        chi = x[:, None, :] + np.einsum("bij,kj->bki", S, xi)
        f = np.einsum("bij,bkj->bki", Phi, chi)
        mean = np.einsum("k,bki->bi", wm, f)
        d = f - mean[:, None, :]
        cov = np.einsum("k,bki,bkj->bij", wc, d, d)
        return mean, 0.5 * (cov + np.swapaxes(cov, -1, -2))


def _sqrt_psd(P: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor; episodes whose P is not positive definite (the filter has
    flagged them) get the symmetric square root of the eigenvalue-floored matrix."""
    try:
        return np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        vals, vecs = np.linalg.eigh(P)
        return vecs * np.sqrt(np.maximum(vals, 0.0))[..., None, :]


class UnscentedRule(SigmaPointRule):
    """Scaled unscented transform (Julier & Uhlmann 2004): lambda = alpha^2 (n + kappa) - n,
    points 0 and +-sqrt(n + lambda) e_j; W_0 = lambda / (n + lambda),
    W_0^c = W_0 + 1 - alpha^2 + beta, W_j = 1 / (2 (n + lambda)). kappa None means 3 - n."""

    def __init__(self, alpha: float = 1.0, beta: float = 2.0, kappa: float | None = 0.0):
        self.alpha, self.beta, self.kappa = alpha, beta, kappa
        self.name = f"unscented(alpha={alpha:g}, beta={beta:g}, kappa={kappa})"

    def points(self, n):
        kappa = 3.0 - n if self.kappa is None else self.kappa
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
        self.name = f"sparse-grid-gauss-hermite(L={level}, {growth})"

    def _m(self, l: int) -> int:
        return 2 * l - 1 if self.growth == "odd" else l

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
