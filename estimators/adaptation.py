"""Adaptation policies: what a filter does with its innovation statistics. A policy sees
one ``AdaptationContext`` per update (innovation, S, P_xz, the propagated covariance, Q,
R, the measurement's axes, a motion flag) and returns an ``Adjustment``: a new predicted
covariance and/or a new R (the filter then redoes the update with them). The Kalman loop
is elsewhere (``estimators.filters``).

All act on a batch of B episodes. Notation (ALGORITHMS.md section 2.2):
``PhiPPhi = Phi P Phi^T`` (the propagated covariance without process noise; a sigma-point
rule's equivalent for a nonlinear process), ``Q`` the discrete process noise, ``H`` the
measurement matrix (a nonlinear measurement's statistical linearisation
P_xz^T P_pred^-1), ``R`` the measurement noise, ``e`` the innovation ``z - z_hat``. The
innovation covariance is estimated recursively (003 eq. 50, with C_{k-1} on the
right-hand side): C_1 = e e^T, C_k = (rho C_{k-1} + e e^T) / (1 + rho).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from aligngym.estimators.linalg import identity_where_not, solve_each
from aligngym.estimators.metrics import chi2_quantile

FACTOR_AXES = ("measurement", "local-level")
"""Axes along which per-axis factors are formed: the measurement's own (the papers), or
local East, North, Up (the observation's ``axes`` rotation)."""


@dataclass(frozen=True)
class AdaptationContext:
    """What a policy sees at one update, for B episodes, m measurements, n states.

    innovation (B, m), zero where missing; valid (B, m) measurement present; S (B, m, m)
    innovation covariance with the unadapted P_pred; P_xz (B, n, m); PhiPPhi (B, n, n);
    Q (B, n, n); R (B, m, m); H (B, m, n); axes (B, m, m) rotation of the measurement
    axes to E, N, U or None; motion (B,) bool or None; directions (B, m, n) the state
    direction each measurement measures directly (``Observation.directions``) or None;
    t (s).
    """

    innovation: np.ndarray
    valid: np.ndarray
    S: np.ndarray
    P_xz: np.ndarray
    PhiPPhi: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    H: np.ndarray
    axes: np.ndarray | None = None
    motion: np.ndarray | None = None
    directions: np.ndarray | None = None
    t: float = 0.0


@dataclass(frozen=True)
class PolicyTuning:
    """An agent's retune of an adaptation policy at an update: floor (> 0), the new lower
    bound of the fading factors, one number or one per episode (B,) (the policies with
    fading factors only)."""

    floor: float | np.ndarray


@dataclass(frozen=True)
class Adjustment:
    """A policy's decision: P_pred (B, n, n) and R (B, m, m), None = unchanged
    (PhiPPhi + Q and the model's R); factors (B, k) for the record; rejected (B, m):
    measurement components to leave out of this update (an outlier given zero weight:
    exactly zero gain), None = none."""

    P_pred: np.ndarray | None
    R: np.ndarray | None
    factors: np.ndarray
    rejected: np.ndarray | None = None


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


OBSERVATION_FEATURES = {
    "selection-H": "H = [diag(s) 0] up to a selection of the states (each measurement "
                   "one state)",
    "unit-selection-H": "H = [I 0] (each measurement one state, unscaled)",
    "axes": "the measurement's local-level axes (Observation.axes)",
    "directions": "the directly measured state directions (Observation.directions)",
    "conditionally-linear": "maps conditionally linear in a few nonlinear states "
                            "(GaussianMap.conditional)",
}
"""What a policy (``AdaptationPolicy.needs``) or an integration rule
(``IntegrationRule.needs``) may need of a model, and an experiment's model declares it
gives (``Experiment.observation_features``)."""


class AdaptationPolicy(ABC):
    """Decides P_pred and R from the update's context; reports its factors (B, k)."""

    n_factors: int = 0
    name: str = "none"

    @property
    def needs(self) -> frozenset[str]:
        """What the policy needs of the model's observation (keys of
        ``OBSERVATION_FEATURES``); checked against an experiment before any episode is
        simulated (``Experiment.check_filters``)."""
        return frozenset()

    def reset(self, batch: int) -> None:
        """Start a new batch of episodes."""

    def tune(self, tuning: PolicyTuning) -> None:
        """Take an agent's retune (``PolicyTuning``) from this update on; ValueError for a
        policy without fading factors."""
        raise ValueError(f"adaptation {self.name!r} has no fading factors to retune")

    @abstractmethod
    def adapt(self, ctx: AdaptationContext) -> Adjustment:
        """The adjustment for this update."""


class NoAdaptation(AdaptationPolicy):
    """The conventional Kalman filter: P_pred = Phi P Phi^T + Q, R as modelled."""

    def adapt(self, ctx):
        return Adjustment(None, None, np.zeros((ctx.PhiPPhi.shape[0], 0)))


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

    def reset(self, batch: int) -> None:
        self._C = None
        self._started = np.zeros(batch, bool)

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
