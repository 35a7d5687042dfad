"""Yang's robust adaptive policies (paper 001; ALGORITHMS 5.2-5.3): IGG-III weights of the
standardised predicted residuals inflate R and reject outliers (``equivalent_noise``);
the three-segment adaptive factor alpha inflates the prediction (``RobustAdaptive``), or
per-state selective weights along the directly measured state directions do
(``SelectiveWeights``). They act only while the carrier moves. Weights and factors are
dimensionless. Notation and the policy protocol: ``estimators.adaptation``.
"""
from __future__ import annotations

import numpy as np

from aligngym.estimators.adaptation import AdaptationContext, AdaptationPolicy, Adjustment


def igg3_weights(standardized: np.ndarray, k0: float, k1: float) -> np.ndarray:
    """IGG-III observation weights (Yang 1994; ALGORITHMS (5.6)) of standardised residuals:
    1 within k0, (k0/|v|)((k1 - |v|)/(k1 - k0))^2 up to k1, 0 beyond."""
    a = np.abs(standardized)
    with np.errstate(divide="ignore", invalid="ignore"):
        middle = (k0 / a) * ((k1 - a) / (k1 - k0)) ** 2
    return np.where(a <= k0, 1.0, np.where(a <= k1, middle, 0.0))


def adaptive_factor(statistic: np.ndarray, c0: float, c1: float,
                    smallest: float = 1e-3) -> np.ndarray:
    """Yang's three-segment adaptive factor alpha (ALGORITHMS (5.5)) of the statistic
    Delta: 1 up to c0, (c0/Delta)((c1 - Delta)/(c1 - c0))^2 up to c1, then 0, clamped at
    ``smallest`` (alpha = 0 would discard the prediction)."""
    d = np.asarray(statistic, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        middle = (c0 / d) * ((c1 - d) / (c1 - c0)) ** 2
    alpha = np.where(d <= c0, 1.0, np.where(d <= c1, middle, 0.0))
    return np.maximum(alpha, smallest)


def _moving(ctx: AdaptationContext) -> np.ndarray:
    """(B,) True where the policy may act: the carrier moves (all, without a flag)."""
    batch = ctx.innovation.shape[0]
    return np.ones(batch, bool) if ctx.motion is None else np.asarray(ctx.motion, bool)


def equivalent_noise(R: np.ndarray, w: np.ndarray) -> np.ndarray:
    """R_bar = D R D, D = diag(w^-1/2), for observation weights w (B, m); components with
    w = 0 keep their R (they are rejected: ``Adjustment.rejected``)."""
    d = 1.0 / np.sqrt(np.where(w > 0.0, w, 1.0))
    return d[:, :, None] * R * d[:, None, :]


class _RobustObservations(AdaptationPolicy):
    """Shared part of Yang's family (ALGORITHMS 5.2-5.3): IGG-III weights (k0, k1) of the
    standardised predicted residuals e_i / sqrt(S_ii), acting only in motion (001: the
    classic KF while static). A component weighed 0 is rejected (left out), but not more
    than ``max_rejections`` epochs in a row: a misclosure that persists is the state's,
    not an outlier's, and rejecting it for ever would lock the filter out (after a GPS
    outage that left it overconfident)."""

    def __init__(self, k0: float = 2.0, k1: float = 6.0, max_rejections: int = 3) -> None:
        if not 0.0 < k0 < k1 < np.inf:
            raise ValueError(f"need 0 < k0 < k1 < inf, got k0={k0}, k1={k1}")
        if not isinstance(max_rejections, int) or max_rejections < 0:
            raise ValueError(f"max_rejections must be an integer >= 0, got {max_rejections!r}")
        self.k0, self.k1, self.max_rejections = k0, k1, max_rejections
        self._streak: np.ndarray | None = None

    def reset(self, batch: int) -> None:
        self._streak = None

    def restart(self, members: np.ndarray) -> None:
        if self._streak is not None:
            self._streak[members] = 0

    def _acting(self, ctx: AdaptationContext) -> np.ndarray:
        return _moving(ctx) & ctx.valid.any(-1)

    def _weights(self, ctx: AdaptationContext, acting: np.ndarray) -> np.ndarray:
        """IGG-III weights (B, m): 1 where missing or not acting; a rejection streak
        longer than max_rejections ends with weight 1."""
        valid = ctx.valid
        diag_S = np.diagonal(ctx.S, axis1=-2, axis2=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            standardized = np.where(valid, ctx.innovation / np.sqrt(diag_S), 0.0)
        w = np.where(acting[:, None] & valid, igg3_weights(standardized, self.k0, self.k1),
                     1.0)
        if self._streak is None or self._streak.shape != w.shape:
            self._streak = np.zeros(w.shape, int)
        w = np.where((w == 0.0) & (self._streak >= self.max_rejections), 1.0, w)
        self._streak = np.where(valid, np.where(w == 0.0, self._streak + 1, 0), self._streak)
        return w


class RobustAdaptive(_RobustObservations):
    """Yang's robust adaptive KF (Yang, He & Xu 2001; ALGORITHMS 5.2) as 001 uses it: the
    adaptive factor alpha from the predicted residuals (m < n),
    Delta = sqrt(V^T V / tr(H P_pred H^T + R)), three-segment (c0, c1), inflates the
    prediction, P_pred / alpha; IGG-III weights of the standardised predicted residuals
    inflate R (``equivalent_noise``), and a component they weigh 0 is left out of the
    update and of Delta. Only in motion. Factors: alpha, then the weights."""

    name = "robust-adaptive"
    n_factors = 1

    def __init__(self, c0: float = 1.0, c1: float = 3.0, k0: float = 2.0,
                 k1: float = 6.0, max_rejections: int = 3) -> None:
        super().__init__(k0, k1, max_rejections)
        if not 0.0 < c0 < c1 < np.inf:
            raise ValueError(f"need 0 < c0 < c1 < inf, got c0={c0}, c1={c1}")
        self.c0, self.c1 = c0, c1

    def adapt(self, ctx):
        acting = self._acting(ctx)
        w = self._weights(ctx, acting)
        R = equivalent_noise(ctx.R, w)
        kept = ctx.valid & (w > 0.0)       # a rejected outlier says nothing of the state
        e = ctx.innovation
        diag_S = np.diagonal(ctx.S, axis1=-2, axis2=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            delta = np.sqrt(np.sum(np.where(kept, e * e, 0.0), -1)
                            / np.sum(np.where(kept, diag_S, 0.0), -1))
        alpha = np.where(acting, adaptive_factor(np.nan_to_num(delta), self.c0, self.c1), 1.0)
        self.n_factors = 1 + w.shape[-1]
        P_pred = (ctx.PhiPPhi + ctx.Q) / alpha[:, None, None]
        return Adjustment(P_pred, R, np.concatenate([alpha[:, None], w], -1),
                          rejected=w == 0.0)


class SelectiveWeights(_RobustObservations):
    """Selective-weight adaptive KF (001 eqs. 14-21; ALGORITHMS 5.3). 001: "the model is
    the robust adaptive filter's", with one weight per state instead of one alpha for
    all: per directly measured state direction u_i (``Observation.directions``), with the
    misclosure L_i (the innovation) and sigma_i = sqrt(u_i^T P_pred u_i):
    w_i = m sigma_i / |L_i| if |L_i| > m sigma_i, else 1; P_pred <- W^-1 P_pred W^-1 with
    W^-1 = I + sum_i (1/w_i - 1) u_i u_i^T (001: diag(1/w_i) on position and velocity,
    R_Le^T diag(1, 1, 1/w_psi) R_Le on the misalignment, 1 on the sensor errors); the
    observations keep their IGG-III weights (``equivalent_noise``; robust=False: R as
    modelled; ALGORITHMS 5.3 gives the selective-weight filter no observation weights,
    001's "the robust adaptive filter's model" does), and an observation they reject
    forms no state weight. Only in motion (001: W = I while static). Factors: the state
    weights w_i, then the observation weights."""

    name = "selective-weights"
    n_factors = 1
    needs = frozenset({"directions"})

    def __init__(self, m: float = 2.5, robust: bool = True, k0: float = 2.0,
                 k1: float = 6.0, max_rejections: int = 3) -> None:
        super().__init__(k0, k1, max_rejections)
        if not (np.isfinite(m) and m > 0.0):
            raise ValueError(f"selective-weight threshold m must be > 0, got {m}")
        self.m, self.robust = m, robust

    def adapt(self, ctx):
        if ctx.directions is None:
            raise ValueError("selective weights need the observation's state directions")
        U = ctx.directions
        J = ctx.PhiPPhi + ctx.Q
        sigma = np.sqrt(np.maximum(np.einsum("bin,bnk,bik->bi", U, J, U), 0.0))
        misclosure = np.abs(ctx.innovation)
        acting = self._acting(ctx)
        if self.robust:
            w_obs = self._weights(ctx, acting)
            R = equivalent_noise(ctx.R, w_obs)
        else:
            R, w_obs = None, np.ones(misclosure.shape)
        # A rejected observation (an outlier) says nothing of the state: no state weight.
        measured = ctx.valid & np.any(U != 0.0, -1) & acting[:, None] & (w_obs > 0.0)
        # A direction known exactly (sigma 0) keeps weight 1, a convention: the scaling
        # W^-1 J W^-1 cannot widen a zero variance (1 / w = inf would make every state NaN),
        # though its limit for sigma -> 0 would set that variance to (|L| / m)^2.
        outside = measured & (sigma > 0.0) & (misclosure > self.m * sigma)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.where(outside, self.m * sigma / misclosure, 1.0)
        W_inv = np.eye(J.shape[-1]) + np.einsum("bi,bin,bik->bnk", 1.0 / w - 1.0, U, U)
        self.n_factors = 2 * w.shape[-1]
        return Adjustment(W_inv @ J @ W_inv, R, np.concatenate([w, w_obs], -1),
                          rejected=w_obs == 0.0)
