"""Adaptation policies: how a filter forms its predicted covariance from the innovation
statistics. They only rescale the predicted covariance; the Kalman loop is elsewhere.

All act on a batch of B episodes. Notation (ALGORITHMS.md section 2.2):
``PhiPPhi = Phi P Phi^T``, ``Q`` the discrete process noise, ``H`` the measurement matrix,
``R`` the measurement noise, ``e`` the innovation ``z - H x_pred``. The innovation
covariance is estimated recursively (003 eq. 50, with C_{k-1} on the right-hand side):
C_1 = e e^T, C_k = (rho C_{k-1} + e e^T) / (1 + rho).
"""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np


def _sandwich(H: np.ndarray, P: np.ndarray) -> np.ndarray:
    """H P H^T for H (B, m, n) and P (B, n, n)."""
    return H @ P @ np.swapaxes(H, -1, -2)


def _diagonal_selection(H: np.ndarray) -> np.ndarray:
    """s_i of H = [S 0] with S = diag(s) (B, m); raises for any other H."""
    m = H.shape[-2]
    S = H[..., :m]
    s = np.diagonal(S, axis1=-2, axis2=-1)
    off = S - s[..., None] * np.eye(m)
    if np.any(off != 0.0) or np.any(H[..., m:] != 0.0) or np.any(s == 0.0):
        raise ValueError("multiple fading factors need H = [diag(s) 0]; use the single "
                         "fading factor for this model")
    return s


class AdaptationPolicy(ABC):
    """Maps the predicted pieces to P_pred, and reports its factors (B, k)."""

    n_factors: int = 0
    name: str = "none"
    basis: np.ndarray | None = None
    """Optional (B, m, m) rotation of the measurement axes in which per-axis factors are
    formed (set by the model each epoch); None: the measurement's own axes (the papers)."""

    def reset(self, batch: int, m: int) -> None:
        """Start a new batch of episodes with m measurements."""

    @abstractmethod
    def predicted_covariance(self, PhiPPhi: np.ndarray, Q: np.ndarray, H: np.ndarray,
                             R: np.ndarray, innovation: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
        """P_pred (B, n, n) and the factors used (B, n_factors)."""


class NoAdaptation(AdaptationPolicy):
    """The conventional Kalman filter: P_pred = Phi P Phi^T + Q."""

    def predicted_covariance(self, PhiPPhi, Q, H, R, innovation):
        return PhiPPhi + Q, np.zeros((PhiPPhi.shape[0], 0))


class InnovationFading(AdaptationPolicy):
    """Base of the fading-factor policies: the innovation-covariance estimator of
    003 eq. (50), a floor and an optional cap on the factors.

    rho: forgetting factor in (0, 1]; floor: lower bound of each factor (1 in the papers;
    an agent may raise it); cap: upper bound (inf in the papers).
    """

    def __init__(self, rho: float = 0.95, floor: float = 1.0, cap: float = np.inf) -> None:
        if not 0.0 < rho <= 1.0:
            raise ValueError(f"rho must be in (0, 1], got {rho}")
        if not (floor > 0.0 and cap >= floor):
            raise ValueError(f"need 0 < floor <= cap, got floor={floor}, cap={cap}")
        self.rho, self.floor, self.cap = rho, floor, cap
        self._C: np.ndarray | None = None

    def reset(self, batch: int, m: int) -> None:
        self._C = None
        if self.n_factors != 1:
            self.n_factors = m  # one factor per measured state

    def innovation_covariance(self, innovation: np.ndarray) -> np.ndarray:
        """Update and return C_k (B, m, m) from the innovation e_k (B, m)."""
        outer = innovation[..., :, None] * innovation[..., None, :]
        self._C = outer if self._C is None else (self.rho * self._C + outer) / (1.0 + self.rho)
        return self._C

    def _bound(self, factors: np.ndarray) -> np.ndarray:
        factors = np.where(np.isfinite(factors), factors, self.floor)
        return np.clip(factors, self.floor, self.cap)


class SingleFadingFactor(InnovationFading):
    """SAKF (Xia, Rao, Ying & Shen 1994; same form as Zhou & Frank's STF):
    P_pred = lambda Phi P Phi^T + Q, lambda = max(1, tr N / tr M),
    N = C_k - H Q H^T - beta R, M = H Phi P Phi^T H^T."""

    n_factors = 1
    name = "single-fading"

    def __init__(self, rho: float = 0.95, beta: float = 1.0, floor: float = 1.0,
                 cap: float = np.inf) -> None:
        super().__init__(rho, floor, cap)
        self.beta = beta

    def factors(self, PhiPPhi, Q, H, R, innovation) -> np.ndarray:
        C = self.innovation_covariance(innovation)
        N = C - _sandwich(H, Q) - self.beta * R
        M = _sandwich(H, PhiPPhi)
        lam = np.trace(N, axis1=-2, axis2=-1) / np.trace(M, axis1=-2, axis2=-1)
        return self._bound(lam)[:, None]

    def predicted_covariance(self, PhiPPhi, Q, H, R, innovation):
        lam = self.factors(PhiPPhi, Q, H, R, innovation)
        return lam[:, :, None] * PhiPPhi + Q, lam


class _PerAxisFading(InnovationFading):
    """Shared part of MAKF and IMAKF: factors per measured state,
    lambda_i = max(1, sqrt(N_ii / (s_i^2 J_ii))), applied as the congruence
    L J L with L = diag(lambda_1..m, 1, ..., 1). With a ``basis`` U (orthogonal, H = [I 0])
    the factors are formed along U's axes and L's measured block is U^T diag(lambda) U."""

    n_factors = 0  # set to m at reset

    def _factors(self, N: np.ndarray, J: np.ndarray, H: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Factors (B, m) and the full congruence matrix L (B, n, n)."""
        s = _diagonal_selection(H)
        m, n = s.shape[-1], J.shape[-1]
        J_mm = s[..., :, None] * J[..., :m, :m] * s[..., None, :]
        U = self.basis
        if U is not None:
            if np.any(s != 1.0):
                raise ValueError("a factor basis needs H = [I 0]")
            N = U @ N @ np.swapaxes(U, -1, -2)
            J_mm = U @ J_mm @ np.swapaxes(U, -1, -2)
        with np.errstate(invalid="ignore", divide="ignore"):
            lam = np.sqrt(np.maximum(np.diagonal(N, axis1=-2, axis2=-1), 0.0)
                          / np.diagonal(J_mm, axis1=-2, axis2=-1))
        lam = self._bound(lam)
        L = np.broadcast_to(np.eye(n), J.shape).copy()
        if U is None:
            L[..., np.arange(m), np.arange(m)] = lam
        else:
            L[..., :m, :m] = np.swapaxes(U, -1, -2) @ (lam[..., :, None] * U)
        return lam, L


class MultipleFadingFactors(_PerAxisFading):
    """MAKF (003 eq. 37; Geng & Wang 2008): P_pred = L Phi P Phi^T L + Q with
    N = C_k - H Q H^T - R and J = Phi P Phi^T. Needs H = [diag(s) 0]."""

    name = "multiple-fading"

    def predicted_covariance(self, PhiPPhi, Q, H, R, innovation):
        C = self.innovation_covariance(innovation)
        lam, L = self._factors(C - _sandwich(H, Q) - R, PhiPPhi, H)
        return L @ PhiPPhi @ np.swapaxes(L, -1, -2) + Q, lam


class ImprovedMultipleFadingFactors(_PerAxisFading):
    """IMAKF (003 eqs. 41-42, 50-53): the process noise is faded too,
    P_pred = L (Phi P Phi^T + Q) L with N = C_k - R and J = Phi P Phi^T + Q.
    Needs H = [diag(s) 0]."""

    name = "improved-multiple-fading"

    def predicted_covariance(self, PhiPPhi, Q, H, R, innovation):
        C = self.innovation_covariance(innovation)
        J = PhiPPhi + Q
        lam, L = self._factors(C - R, J, H)
        return L @ J @ np.swapaxes(L, -1, -2), lam
