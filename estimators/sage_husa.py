"""The textbook innovation-based adaptive filter, as a baseline that no paper of the
testbed proposes: Sage-Husa estimation of the measurement noise with a forgetting factor
(Sage & Husa 1969; the exponentially weighted form of e.g. Groves, Principles of GNSS,
Inertial, and Multisensor Integrated Navigation Systems, 2nd ed., section 3.4.4)."""
from __future__ import annotations

import numpy as np

from aligngym.estimators.adaptation import Adjustment, AdaptationContext, AdaptationPolicy

SAGE_HUSA_FORGETTING = 0.97
"""b: the weight of the newest innovation tends to 1 - b (a memory of about 1 / (1 - b) =
33 updates, half a minute at 1 Hz: short against the disturbances that change within an
episode, long against one epoch's noise)."""


class SageHusaNoise(AdaptationPolicy):
    """R estimated from the innovations, per measurement component i:
    r_i,k = (1 - d_k) r_i,k-1 + d_k (e_i,k^2 - (H P_pred H^T)_ii),
    d_k = (1 - b) / (1 - b^(k+1)) (k: the component's updates so far; d_0 = 1),
    r_i,-1 = R_ii. The estimate is held within [floor, cap] x R_ii (the sample term is
    negative whenever |e| is small; an unbounded r may turn R indefinite), and
    R_k = D R D with D = diag(sqrt(r_i / R_ii)): the model's correlations are kept. A
    missing component keeps its estimate and its count. P_pred is not changed. factors
    (B, m): r_i / R_ii.

    forgetting: b in (0, 1); floor, cap: bounds of r_i / R_ii, 0 < floor <= 1 <= cap."""

    name = "sage-husa"

    def __init__(self, forgetting: float = SAGE_HUSA_FORGETTING, floor: float = 0.1,
                 cap: float = 1e4) -> None:
        if not 0.0 < forgetting < 1.0:
            raise ValueError(f"forgetting must be in (0, 1), got {forgetting}")
        if not (0.0 < floor <= 1.0 <= cap < np.inf):
            raise ValueError(f"need 0 < floor <= 1 <= cap < inf, got floor={floor}, cap={cap}")
        self.forgetting, self.floor, self.cap = forgetting, floor, cap
        self._ratio: np.ndarray | None = None
        self._count: np.ndarray | None = None

    def reset(self, batch: int) -> None:
        self._ratio = self._count = None

    def restart(self, members: np.ndarray) -> None:
        if self._ratio is not None:
            self._ratio[members] = 1.0
            self._count[members] = 0

    def adapt(self, ctx: AdaptationContext) -> Adjustment:
        R = ctx.R
        r_model = np.diagonal(R, axis1=-2, axis2=-1)
        predicted = np.diagonal(ctx.S, axis1=-2, axis2=-1) - r_model     # (H P_pred H^T)_ii
        valid = (np.ones(r_model.shape, bool) if ctx.valid is None
                 else np.asarray(ctx.valid, bool))
        if self._ratio is None or self._ratio.shape != r_model.shape:   # a new m: start again
            self._ratio = np.ones(r_model.shape)
            self._count = np.zeros(r_model.shape, int)
        b = self.forgetting
        d = (1.0 - b) / (1.0 - b ** (self._count + 1.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            sample = (np.square(ctx.innovation) - predicted) / r_model
            ratio = np.clip((1.0 - d) * self._ratio + d * sample, self.floor, self.cap)
        update = valid & np.isfinite(ratio) & (r_model > 0.0)
        self._ratio = np.where(update, ratio, self._ratio)
        self._count = np.where(update, self._count + 1, self._count)
        self.n_factors = r_model.shape[-1]
        s = np.sqrt(self._ratio)
        return Adjustment(None, s[:, :, None] * R * s[:, None, :], self._ratio.copy())
