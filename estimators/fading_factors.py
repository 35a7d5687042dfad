"""Fading-factor (strong-tracking) adaptation policies: factors lambda >= floor, formed
from the innovation covariance, that inflate the predicted covariance (SAKF, MAKF, IMAKF;
ALGORITHMS 2.2) or R (ALGORITHMS (2.10)-(2.11)), one per update or one per measurement
axis (the measurement's own, or local East, North, Up). The factors are dimensionless.

The innovation covariance is estimated recursively (003 eq. 50, with C_{k-1} on the
right-hand side): C_1 = e e^T, C_k = (rho C_{k-1} + e e^T) / (1 + rho). Notation and the
policy protocol: ``estimators.adaptation``.
"""
from __future__ import annotations

import numpy as np

from aligngym.estimators.adaptation import (AdaptationContext, AdaptationPolicy, Adjustment,
                                            PolicyTuning)
from aligngym.estimators.linalg import identity_where_not, solve_each
from aligngym.estimators.metrics import chi2_quantile

FACTOR_AXES = ("measurement", "local-level")
"""Axes along which per-axis factors are formed: the measurement's own (the papers), or
local East, North, Up (the observation's ``axes`` rotation)."""


def _sandwich(H: np.ndarray, P: np.ndarray) -> np.ndarray:
    """H P H^T for H (B, m, n) and P (B, n, n)."""
    return H @ P @ np.swapaxes(H, -1, -2)


def _diagonal_selection(H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For a scaled selection H (row i = s_i e_{j_i}^T, distinct j_i, the same in every
    episode; 003's H = [diag(s) 0] is one): s (B, m) and the measured states j (m,).
    Raises for any other H."""
    nonzero = H != 0.0
    cols = np.argmax(nonzero[0], axis=-1)
    m = H.shape[-2]
    selection = np.zeros(H.shape[-2:], bool)
    selection[np.arange(m), cols] = True
    if (np.any(nonzero != selection) or len(set(cols.tolist())) != m):
        raise ValueError("multiple fading factors need H = [diag(s) 0] up to a selection "
                         "of the states; use the single fading factor for this model")
    return H[..., np.arange(m), cols], cols


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
        self._cap = cap                  # as made: a retune may raise an episode's cap
        self._C: np.ndarray | None = None

    def reset(self, batch: int) -> None:
        self._C = None
        self._started = np.zeros(batch, bool)

    def restart(self, members: np.ndarray) -> None:
        self._started[members] = False
        if self._C is not None:
            self._C[members] = 0.0
        if np.ndim(self.cap):
            self.cap[members] = self._cap

    def innovation_covariance(self, innovation: np.ndarray,
                              valid: np.ndarray | None = None) -> np.ndarray:
        """Update and return C_k (B, m, m) from the innovation e_k (B, m). An episode with
        a missing component (valid (B, m) False) keeps its C_{k-1}; its first complete
        innovation starts it (C = e e^T); a change of m restarts the estimate."""
        outer = innovation[..., :, None] * innovation[..., None, :]
        complete = (np.ones(outer.shape[0], bool) if valid is None else valid.all(-1))
        if self._C is None or self._C.shape != outer.shape:
            self._C = np.zeros_like(outer)
            self._started = np.zeros(outer.shape[0], bool)
        recursive = (self.rho * self._C + outer) / (1.0 + self.rho)
        new = np.where(self._started[:, None, None], recursive, outer)
        self._C = np.where(complete[:, None, None], new, self._C)
        self._started = self._started | complete
        return self._C

    def tune(self, tuning: PolicyTuning) -> None:
        self.retune(tuning.floor)

    def retune(self, floor: float | np.ndarray) -> None:
        """An agent's action: a new lower bound of the factors (> 0), one number or one
        per episode (B,); the cap is raised to it if needed."""
        floor_ = np.asarray(floor, float)
        if not (floor_.ndim <= 1 and np.all(np.isfinite(floor_)) and np.all(floor_ > 0.0)):
            raise ValueError(f"fading-factor floor must be > 0, got {floor}")
        self.floor = float(floor_) if floor_.ndim == 0 else floor_
        self.cap = np.maximum(self.cap, self.floor)

    def _bound(self, factors: np.ndarray) -> np.ndarray:
        """factors (B,) or (B, m) within [floor, cap] (each a number or one per episode)."""
        def batched(bound):
            bound = np.asarray(bound)
            return bound.reshape(bound.shape + (1,) * (factors.ndim - 1)) if bound.ndim else bound
        floor, cap = batched(self.floor), batched(self.cap)
        factors = np.where(np.isfinite(factors), factors, floor)
        return np.clip(factors, floor, cap)


class SingleFadingFactor(InnovationFading):
    """SAKF (Xia, Rao, Ying & Shen 1994; same form as Zhou & Frank's STF):
    P_pred = lambda Phi P Phi^T + Q, lambda = max(1, tr N / tr M),
    N = C_k - H Q H^T - beta R, M = H Phi P Phi^T H^T. derivative_free: the strong
    tracking of a derivative-free filter (ALGORITHMS 4.3, 000 eq. 58) takes
    M = P_zz0 - R - H~ Q H~^T from the rule's predicted measurement covariance, which a
    nonlinear measurement makes larger than the statistically linearised H~ P H~^T (the
    two are equal for a linear one)."""

    n_factors = 1
    name = "single-fading"

    def __init__(self, rho: float = 0.95, beta: float = 1.0, floor: float = 1.0,
                 cap: float = np.inf, derivative_free: bool = False,
                 warm_up: float = 0.0, in_motion_only: bool = False,
                 outlier_probability: float | None = None, outlier_run: int = 2) -> None:
        super().__init__(rho, floor, cap)
        if not (np.isfinite(warm_up) and warm_up >= 0.0):
            raise ValueError(f"warm_up must be >= 0 s, got {warm_up}")
        if outlier_probability is not None and not 0.5 < outlier_probability < 1.0:
            raise ValueError(f"outlier_probability must be in (0.5, 1), got "
                             f"{outlier_probability}")
        if not (isinstance(outlier_run, int) and outlier_run >= 1):
            raise ValueError(f"outlier_run must be an integer >= 1 epoch, got {outlier_run!r}")
        self.beta, self.derivative_free = beta, derivative_free
        self.warm_up, self.in_motion_only = warm_up, in_motion_only
        self.outlier_probability, self.outlier_run = outlier_probability, outlier_run
        self._flagged_run = np.zeros(0, int)

    def reset(self, batch: int) -> None:
        super().reset(batch)
        self._flagged_run = np.zeros(batch, int)

    def restart(self, members: np.ndarray) -> None:
        super().restart(members)
        self._flagged_run[members] = 0

    def _outliers(self, ctx, valid: np.ndarray) -> np.ndarray:
        """(B,) bool: this epoch's innovation fails the chi-square test at
        outlier_probability (NIS over the valid components) and is at most the
        outlier_run-th such epoch in a row: a sensor's outlier, not a change of state (a
        longer run is the state's, and fades P as usual)."""
        e = np.where(valid, ctx.innovation, 0.0)
        S = identity_where_not(valid[:, :, None] & valid[:, None, :], ctx.S)
        x, solved = solve_each(S, e[..., None])   # a singular S: its filter flags it
        nis = np.einsum("bi,bi->b", e, x[..., 0])
        dof = np.maximum(valid.sum(-1), 1)
        flagged = solved & (nis > chi2_quantile(self.outlier_probability, dof))
        if self._flagged_run.shape != flagged.shape:
            self._flagged_run = np.zeros(flagged.shape, int)
        self._flagged_run = np.where(flagged, self._flagged_run + 1, 0)
        return flagged & (self._flagged_run <= self.outlier_run)

    def adapt(self, ctx):
        """lambda = 1, and C_k not updated, before ``warm_up`` s (the filter settling: the
        first innovations, predicted by a much larger P, would make C_k fire lambda
        although each is inside its own prediction) and, with in_motion_only, while the
        carrier is still (states unobservable then would be inflated without bound;
        ALGORITHMS 4.3 step 7); with outlier_probability, also not at an outlier
        (``_outliers``: strong tracking would take it for a change of state)."""
        active = np.full(ctx.innovation.shape[0], ctx.t >= self.warm_up - 1e-9)
        if self.in_motion_only and ctx.motion is not None:
            active &= np.asarray(ctx.motion, bool)
        valid = (np.ones(ctx.innovation.shape, bool) if ctx.valid is None
                 else np.asarray(ctx.valid, bool))
        if self.outlier_probability is not None:
            active &= ~self._outliers(ctx, valid)
        C = self.innovation_covariance(ctx.innovation, valid & active[:, None])
        HQH = _sandwich(ctx.H, ctx.Q)
        N = C - HQH - self.beta * ctx.R
        M = (ctx.S - ctx.R - HQH) if self.derivative_free else _sandwich(ctx.H, ctx.PhiPPhi)
        lam = self._bound(np.trace(N, axis1=-2, axis2=-1) / np.trace(M, axis1=-2, axis2=-1))
        lam = np.where(active, lam, 1.0)[:, None]
        return Adjustment(lam[:, :, None] * ctx.PhiPPhi + ctx.Q, None, lam)


class _PerAxisFading(InnovationFading):
    """Shared part of MAKF and IMAKF: factors per measured state,
    lambda_i = max(1, sqrt(N_ii / (s_i^2 J_ii))), applied as the congruence
    L J L with L = diag(lambda_1..m, 1, ..., 1). With axes = "local-level" (H = [I 0])
    the factors are formed along E, N, U, U = the observation's axes rotation, and L's
    measured block is U^T diag(lambda) U."""

    n_factors = 3

    def __init__(self, rho: float = 0.95, floor: float = 1.0, cap: float = np.inf,
                 axes: str = "measurement") -> None:
        super().__init__(rho, floor, cap)
        if axes not in FACTOR_AXES:
            raise ValueError(f"axes = {axes!r}; valid: " + ", ".join(FACTOR_AXES))
        self.axes = axes

    @property
    def needs(self) -> frozenset[str]:
        return frozenset({"selection-H"} | ({"unit-selection-H", "axes"}
                                            if self.axes == "local-level" else set()))

    def _factors(self, N: np.ndarray, J: np.ndarray, ctx: AdaptationContext
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Factors (B, m) and the full congruence matrix L (B, n, n)."""
        s, cols = _diagonal_selection(ctx.H)
        m, n = s.shape[-1], J.shape[-1]
        self.n_factors = m
        J_mm = s[..., :, None] * J[..., cols[:, None], cols] * s[..., None, :]
        U = None
        if self.axes == "local-level":
            if ctx.axes is None:
                raise ValueError("local-level fading factors need the observation's axes")
            U = ctx.axes
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
            L[..., cols, cols] = lam
        else:
            L[..., cols[:, None], cols] = np.swapaxes(U, -1, -2) @ (lam[..., :, None] * U)
        return lam, L


class MultipleFadingFactors(_PerAxisFading):
    """MAKF (003 eq. 37; Geng & Wang 2008): P_pred = L Phi P Phi^T L + Q with
    N = C_k - H Q H^T - R and J = Phi P Phi^T. Needs H = [diag(s) 0]."""

    name = "multiple-fading"

    def adapt(self, ctx):
        C = self.innovation_covariance(ctx.innovation, ctx.valid)
        lam, L = self._factors(C - _sandwich(ctx.H, ctx.Q) - ctx.R, ctx.PhiPPhi, ctx)
        return Adjustment(L @ ctx.PhiPPhi @ np.swapaxes(L, -1, -2) + ctx.Q, None, lam)


class ImprovedMultipleFadingFactors(_PerAxisFading):
    """IMAKF (003 eqs. 41-42, 50-53): the process noise is faded too,
    P_pred = L (Phi P Phi^T + Q) L with N = C_k - R and J = Phi P Phi^T + Q.
    Needs H = [diag(s) 0]."""

    name = "improved-multiple-fading"

    def adapt(self, ctx):
        C = self.innovation_covariance(ctx.innovation, ctx.valid)
        J = ctx.PhiPPhi + ctx.Q
        lam, L = self._factors(C - ctx.R, J, ctx)
        return Adjustment(L @ J @ np.swapaxes(L, -1, -2), None, lam)


class MeasurementFadingFactor(InnovationFading):
    """Single factor on R (ALGORITHMS (2.10); the sway as a measurement disturbance):
    J = Phi P Phi^T + Q, lambda = max(1, tr(C_k - H J H^T) / tr R), R_k = lambda R,
    P_pred = J (not faded)."""

    n_factors = 1
    name = "measurement-fading"

    def adapt(self, ctx):
        C = self.innovation_covariance(ctx.innovation, ctx.valid)
        N = C - _sandwich(ctx.H, ctx.PhiPPhi + ctx.Q)
        lam = self._bound(np.trace(N, axis1=-2, axis2=-1)
                          / np.trace(ctx.R, axis1=-2, axis2=-1))[:, None]
        return Adjustment(None, lam[:, :, None] * ctx.R, lam)


class MeasurementAxisFading(InnovationFading):
    """Per-axis factors on R along local E, N, U (ALGORITHMS (2.11)): with U the
    observation's axes (measurement axes to E, N, U), C^n = U C_k U^T, (H J H^T)^n and
    R^n likewise, lambda_j = max(1, (C^n_jj - (H J H^T)^n_jj) / R^n_jj),
    S = diag(sqrt(lambda)), R_k = U^T S R^n S U; P_pred = J. Fading Q or not makes no
    difference here: the MAKF-R and IMAKF-R forms coincide."""

    n_factors = 3
    name = "measurement-axis-fading"
    needs = frozenset({"axes"})

    def adapt(self, ctx):
        if ctx.axes is None:
            raise ValueError("per-axis measurement factors need the observation's axes")
        U, Ut = ctx.axes, np.swapaxes(ctx.axes, -1, -2)
        C = self.innovation_covariance(ctx.innovation, ctx.valid)
        J_n = U @ _sandwich(ctx.H, ctx.PhiPPhi + ctx.Q) @ Ut
        R_n = U @ ctx.R @ Ut
        diag = lambda A: np.diagonal(A, axis1=-2, axis2=-1)  # noqa: E731
        lam = self._bound((diag(U @ C @ Ut) - diag(J_n)) / diag(R_n))
        self.n_factors = lam.shape[-1]
        s = np.sqrt(lam)
        R_k = Ut @ (s[:, :, None] * R_n * s[:, None, :]) @ U
        return Adjustment(None, R_k, lam)
