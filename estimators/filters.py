"""The generic Gaussian filter on a batch of independent episodes, and the filter registry.

A filter = process/measurement model x integration rule x adaptation policy (SPEC 5).
The Kalman loop exists once, here. Every update keeps P symmetric, checks it (and the
innovation covariance) positive definite and finite; an episode that fails is marked
diverged with the time and the reason and frozen, while the rest of the batch goes on.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from estimators.rules import (CubatureRule, IntegrationRule, LinearRule,
                              SparseGridGaussHermiteRule, UnscentedRule)
from estimators.adaptation import (AdaptationPolicy, ImprovedMultipleFadingFactors,
                                   InnovationFading,
                                   MultipleFadingFactors, NoAdaptation, SingleFadingFactor)


def _cholesky_ok(A: np.ndarray) -> np.ndarray:
    """(B,) True where A[b] is finite and positive definite."""
    ok = np.all(np.isfinite(A), axis=(-2, -1))
    try:
        np.linalg.cholesky(np.where(ok[:, None, None], A, np.eye(A.shape[-1])))
        return ok
    except np.linalg.LinAlgError:
        for b in np.flatnonzero(ok):
            try:
                np.linalg.cholesky(A[b])
            except np.linalg.LinAlgError:
                ok[b] = False
        return ok


@dataclass
class FilterHealth:
    """Per-episode status: diverged (B,), time of divergence (B,) s (nan if none), reason."""

    diverged: np.ndarray
    time: np.ndarray
    reason: list[str]

    @classmethod
    def healthy(cls, batch: int) -> "FilterHealth":
        return cls(np.zeros(batch, bool), np.full(batch, np.nan), [""] * batch)

    def flag(self, mask: np.ndarray, t: float, reason: str) -> None:
        for b in np.flatnonzero(mask & ~self.diverged):
            self.diverged[b], self.time[b], self.reason[b] = True, t, reason


class GaussianFilter:
    """Kalman-type filter with a pluggable integration rule and adaptation policy.

    State x (B, n), covariance P (B, n, n). ``predict`` then ``update`` per epoch; the
    adaptation policy forms P_pred at the update, from the innovation.
    """

    def __init__(self, name: str, rule: IntegrationRule, adaptation: AdaptationPolicy,
                 joseph: bool = True) -> None:
        self.name, self.rule, self.adaptation, self.joseph = name, rule, adaptation, joseph
        self.factor_axes = "measurement"
        self.x = self.P = None
        self.factors = np.zeros((0, 0))
        self.innovation = self.S = None
        self._pending: tuple[np.ndarray, np.ndarray] | None = None

    def reset(self, x0: np.ndarray, P0: np.ndarray, m: int) -> None:
        """Start B episodes from x0 (B, n), P0 (B, n, n); m measurements per update."""
        self.x = np.array(x0, dtype=float)
        self.P = 0.5 * (P0 + np.swapaxes(P0, -1, -2))
        batch = self.x.shape[0]
        self.health = FilterHealth.healthy(batch)
        self.adaptation.reset(batch, m)
        self.factors = np.zeros((batch, self.adaptation.n_factors))
        self._pending = None
        bad = ~_cholesky_ok(self.P)
        self.health.flag(bad, 0.0, "initial covariance not positive definite")

    def predict(self, Phi: np.ndarray, Q: np.ndarray) -> None:
        """Propagate with transition Phi (B, n, n) and discrete process noise Q (B, n, n)."""
        if self._pending is not None:  # no update since the last predict
            self.P = self._pending[0] + self._pending[1]
        x_pred, PhiPPhi = self.rule.predict(self.x, self.P, Phi)
        live = ~self.health.diverged
        self.x = np.where(live[:, None], x_pred, self.x)
        self._pending = (PhiPPhi, Q)

    def update(self, z: np.ndarray, H: np.ndarray, R: np.ndarray, t: float) -> None:
        """Measurement update with z (B, m), H (B, m, n), R (B, m, m) at time t (s)."""
        if self._pending is None:
            raise RuntimeError("update() needs a predict() first")
        PhiPPhi, Q = self._pending
        self._pending = None
        live = ~self.health.diverged
        self.health.flag(~np.all(np.isfinite(z), axis=-1) & live, t, "measurement is NaN/inf")
        live = ~self.health.diverged
        z = np.where(live[:, None], z, 0.0)
        innovation = z - np.einsum("bij,bj->bi", H, self.x)
        P_pred, factors = self.adaptation.predicted_covariance(PhiPPhi, Q, H, R, innovation)
        P_pred = 0.5 * (P_pred + np.swapaxes(P_pred, -1, -2))
        Ht = np.swapaxes(H, -1, -2)
        S = H @ P_pred @ Ht + R
        S_ok = _cholesky_ok(S)
        self.health.flag(~S_ok & live, t, "innovation covariance not positive definite")
        live &= S_ok
        S_safe = np.where(live[:, None, None], S, np.eye(S.shape[-1]))
        K = np.swapaxes(np.linalg.solve(S_safe, H @ P_pred), -1, -2)
        x_new = self.x + np.einsum("bij,bj->bi", K, innovation)
        I_KH = -(K @ H)
        I_KH[..., np.arange(I_KH.shape[-1]), np.arange(I_KH.shape[-1])] += 1.0
        if self.joseph:
            P_new = I_KH @ P_pred @ np.swapaxes(I_KH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
        else:
            P_new = I_KH @ P_pred
        P_new = 0.5 * (P_new + np.swapaxes(P_new, -1, -2))
        P_ok = _cholesky_ok(P_new) & np.all(np.isfinite(x_new), axis=-1)
        self.health.flag(~P_ok & live, t, "covariance not positive definite or state NaN")
        live &= P_ok
        self.x = np.where(live[:, None], x_new, self.x)
        self.P = np.where(live[:, None, None], P_new, self.P)
        self.innovation, self.S = innovation, S
        self.factors = factors


@dataclass(frozen=True)
class FilterEntry:
    """A named filter of the catalogue: rule and adaptation factories, its source, and
    the axes along which a model forms per-axis fading factors ("measurement": the
    measurement's own axes, as printed in the papers; "local-level": E, N, U)."""

    rule: Callable[[], IntegrationRule]
    adaptation: Callable[..., AdaptationPolicy]
    description: str
    factor_axes: str = "measurement"


FILTERS: dict[str, FilterEntry] = {
    "kf": FilterEntry(LinearRule, NoAdaptation, "conventional Kalman filter"),
    "sakf": FilterEntry(LinearRule, SingleFadingFactor,
                        "single fading factor (Xia et al. 1994)"),
    "makf": FilterEntry(LinearRule, MultipleFadingFactors,
                        "multiple fading factors (003 eq. 37)"),
    "imakf": FilterEntry(LinearRule, ImprovedMultipleFadingFactors,
                         "improved multiple fading factors (003 eqs. 41-42, 50)"),
    "makf-n": FilterEntry(LinearRule, MultipleFadingFactors,
                          "MAKF with factors along local E, N, U", "local-level"),
    "imakf-n": FilterEntry(LinearRule, ImprovedMultipleFadingFactors,
                           "IMAKF with factors along local E, N, U", "local-level"),
    "ukf": FilterEntry(UnscentedRule, NoAdaptation,
                       "unscented KF (alpha 1, beta 2, kappa 0)"),
    "ckf": FilterEntry(CubatureRule, NoAdaptation, "cubature KF"),
    "sghkf-2": FilterEntry(lambda: SparseGridGaussHermiteRule(2), NoAdaptation,
                           "sparse-grid Gauss-Hermite KF, level 2"),
    "sghkf-3": FilterEntry(lambda: SparseGridGaussHermiteRule(3), NoAdaptation,
                           "sparse-grid Gauss-Hermite KF, level 3"),
}


def make_filter(name: str, **adaptation_options) -> GaussianFilter:
    """A filter of the registry by name; unknown names list the known ones."""
    try:
        entry = FILTERS[name]
    except KeyError:
        raise KeyError(f"unknown filter {name!r}; known filters: "
                       + ", ".join(sorted(FILTERS))) from None
    if adaptation_options and not issubclass(entry.adaptation, InnovationFading):
        adaptation_options = {}  # options of the fading factors do not apply
    adaptation = entry.adaptation(**adaptation_options)
    filt = GaussianFilter(name, entry.rule(), adaptation)
    filt.factor_axes = entry.factor_axes
    return filt
