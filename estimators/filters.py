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

from aligngym.estimators.adaptation import (AdaptationContext, AdaptationPolicy,
                                   ImprovedMultipleFadingFactors, MeasurementAxisFading, MeasurementFadingFactor,
                                   MultipleFadingFactors, NoAdaptation, RobustAdaptive,
                                   SelectiveWeights, SingleFadingFactor)
from aligngym.estimators.linalg import floor_eigenvalues, positive_definite, solve_each
from aligngym.estimators.model import Observation, Transition, wrap_angle
from aligngym.estimators.rules import (CubatureRule, GaussHermiteRule, IntegrationRule, symmetric,
                              LinearizationRule, ReducedGaussHermiteRule,
                              SparseGridGaussHermiteRule, UnscentedRule)


@dataclass
class FilterHealth:
    """Per-episode status: diverged (B,), time of divergence (B,) s (nan if none), reason;
    repairs (B,): predicted covariances made positive definite by flooring their
    eigenvalues (rules with negative weights, ALGORITHMS 3.2 caution 1), each logged."""

    diverged: np.ndarray
    time: np.ndarray
    reason: list[str]
    repairs: np.ndarray

    @classmethod
    def healthy(cls, batch: int) -> "FilterHealth":
        return cls(np.zeros(batch, bool), np.full(batch, np.nan), [""] * batch,
                   np.zeros(batch, int))

    def flag(self, mask: np.ndarray, t: float, reason: str) -> None:
        for b in np.flatnonzero(mask & ~self.diverged):
            self.diverged[b], self.time[b], self.reason[b] = True, t, reason


def _innovation(observation: Observation, z: np.ndarray, z_hat: np.ndarray,
                valid: np.ndarray) -> np.ndarray:
    """z - z_hat (B, m), angle components wrapped, zero where the measurement is missing."""
    innovation = z - z_hat
    if observation.angles:
        idx = list(observation.angles)
        innovation[:, idx] = wrap_angle(innovation[:, idx])
    return np.where(valid, innovation, 0.0)


class GaussianFilter:
    """Kalman-type filter with a pluggable integration rule and adaptation policy.

    State x (B, n), covariance P (B, n, n). Per epoch ``predict(transition)`` then
    ``update(observation)`` (``estimators.model``): the rule computes the moments of the
    model's maps, the adaptation policy may change P_pred and R from the update's
    context, missing measurement components (NaN) are left out of the update. Only
    numerical failure (a covariance not positive definite, a NaN state) marks an
    episode diverged; it is then frozen while the rest of the batch goes on.
    """

    def __init__(self, name: str, rule: IntegrationRule, adaptation: AdaptationPolicy,
                 joseph: bool = True) -> None:
        self.name, self.rule, self.adaptation, self.joseph = name, rule, adaptation, joseph
        self.x = self.P = None
        self.factors = np.zeros((0, 0))
        self.innovation = self.S = None
        self.angles: tuple[int, ...] = ()
        self._pending: tuple[np.ndarray, np.ndarray] | None = None

    def reset(self, x0: np.ndarray, P0: np.ndarray, angles: tuple[int, ...] = ()) -> None:
        """Start B episodes from x0 (B, n), P0 (B, n, n); angles: indices of angle states
        (wrapped to (-pi, pi])."""
        self.x = np.array(x0, dtype=float)
        self.P = symmetric(P0)
        self.angles = tuple(angles)
        batch = self.x.shape[0]
        self.health = FilterHealth.healthy(batch)
        self.adaptation.reset(batch)
        self.factors = np.zeros((batch, self.adaptation.n_factors))
        self.innovation = self.S = None
        self._pending = None
        bad = ~positive_definite(self.P)
        self.health.flag(bad, 0.0, "initial covariance not positive definite")

    @property
    def live(self) -> np.ndarray:
        """(B,) episodes not diverged."""
        return ~self.health.diverged

    def predict(self, transition: Transition) -> None:
        """Propagate through the process map (its noise Q is added at the update, where
        the adaptation policy may fade it)."""
        if self._pending is not None:  # no update since the last predict
            self.P = self._pending[0] + self._pending[1]
        live = self.live
        # Diverged (frozen) episodes go through the rule at a harmless point, so that
        # their state cannot turn the batch's linear algebra into NaN.
        x_in, P_in = self._harmless(self.x, self.P)
        x_pred, PhiPPhi, _ = self.rule.moments(transition, x_in, P_in)
        if self.angles:
            idx = list(self.angles)
            x_pred[:, idx] = wrap_angle(x_pred[:, idx])
        self.x = np.where(live[:, None], x_pred, self.x)
        self._pending = (PhiPPhi, transition.noise)

    def _harmless(self, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x and P with the diverged episodes' replaced by zero and the identity."""
        live = self.live
        if live.all():
            return x, P
        return (np.where(live[:, None], x, 0.0),
                np.where(live[:, None, None], P, np.eye(P.shape[-1])))

    def update(self, observation: Observation) -> None:
        """Measurement update at observation.t (s); missing components are skipped."""
        if self._pending is None:
            raise RuntimeError("update() needs a predict() first")
        PhiPPhi, Q = self._pending
        self._pending = None
        t, R = observation.t, observation.noise
        P_pred = symmetric(PhiPPhi + Q)
        finite = np.all(np.isfinite(P_pred), axis=(-2, -1)) & np.all(np.isfinite(self.x), -1)
        # flag() passes over episodes already diverged: no mask by the live ones needed
        self.health.flag(~finite, t, "predicted state or covariance NaN/inf")
        live = self.live
        valid = observation.valid() & live[:, None]
        z = np.where(valid, observation.z, 0.0)
        P_pred = self._repair(P_pred, t)
        x_in, P_pred = self._harmless(self.x, P_pred)
        z_hat, P_zz, P_xz = self.rule.moments(observation, x_in, P_pred)
        innovation = _innovation(observation, z, z_hat, valid)
        if observation.linear:
            H = observation.matrix
        else:  # statistical linearisation P_xz^T P_pred^-1, for the policies
            H = np.swapaxes(np.linalg.pinv(P_pred, hermitian=True) @ P_xz, -1, -2)
        # Before adaptation and rejection: what the innovation test looks at.
        self.predicted = (innovation, P_zz + R, valid)
        ctx = AdaptationContext(innovation=innovation, valid=valid, S=P_zz + R, P_xz=P_xz,
                                PhiPPhi=PhiPPhi, Q=Q, R=R, H=H, axes=observation.axes,
                                motion=observation.motion, directions=observation.directions,
                                t=t)
        adjustment = self.adaptation.adapt(ctx)
        silent = ~valid.any(-1)[:, None, None]  # no measurement: no adaptation either
        if adjustment.rejected is not None and adjustment.rejected.any():
            valid = valid & ~adjustment.rejected
            innovation = np.where(valid, innovation, 0.0)
        if adjustment.R is not None:
            R = np.where(silent, R, adjustment.R)
        if adjustment.P_pred is not None:
            adapted = np.where(silent, P_pred, adjustment.P_pred)
            P_pred = symmetric(adapted)
            P_pred = self._repair(P_pred, t)
            if not observation.linear:  # re-update with the adapted prediction
                x_in, P_pred = self._harmless(self.x, P_pred)
                z_hat, P_zz, P_xz = self.rule.moments(observation, x_in, P_pred)
                innovation = _innovation(observation, z, z_hat, valid)
        # Missing components: zero rows of H / columns of P_xz, unit diagonal in S and
        # R, so that their gain columns are exactly zero.
        missing = ~valid
        any_missing = bool(missing.any())
        if any_missing:
            cross_valid = valid[:, :, None] & valid[:, None, :]
            eye = np.broadcast_to(np.eye(R.shape[-1]), R.shape)
            R = np.where(cross_valid, R, eye)
        if observation.linear:
            H = observation.matrix
            if any_missing:
                H = np.where(valid[:, :, None], H, 0.0)
            HP = H @ P_pred
            S = HP @ np.swapaxes(H, -1, -2) + R
        else:
            if any_missing:
                P_xz = np.where(valid[:, None, :], P_xz, 0.0)
                P_zz = np.where(cross_valid, P_zz, 0.0)
            HP = np.swapaxes(P_xz, -1, -2)
            S = P_zz + R
        self.health.flag(~positive_definite(S), t, "innovation covariance not positive "
                         "definite")
        live = self.live
        S_safe = np.where(live[:, None, None], S, np.eye(S.shape[-1]))
        S_inv_HP, solved = solve_each(S_safe, HP)
        if not solved.all():               # an episode's S singular to working precision
            self.health.flag(~solved, t, "innovation covariance singular")
            live = self.live
            S_inv_HP = np.where(solved[:, None, None], S_inv_HP, 0.0)
        K = np.swapaxes(S_inv_HP, -1, -2)
        x_new = self.x + np.einsum("bij,bj->bi", K, innovation)
        if self.angles:
            x_new[:, list(self.angles)] = wrap_angle(x_new[:, list(self.angles)])
        if observation.linear and self.joseph:
            I_KH = -(K @ H)
            I_KH[..., np.arange(I_KH.shape[-1]), np.arange(I_KH.shape[-1])] += 1.0
            P_new = I_KH @ P_pred @ np.swapaxes(I_KH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
        else:
            P_new = P_pred - K @ S @ np.swapaxes(K, -1, -2)
        P_new = symmetric(P_new)
        P_ok = positive_definite(P_new) & np.all(np.isfinite(x_new), axis=-1)
        self.health.flag(~P_ok, t, "covariance not positive definite or state NaN")
        live = self.live
        self.x = np.where(live[:, None], x_new, self.x)
        self.P = np.where(live[:, None, None], P_new, self.P)
        self.innovation, self.S, self.valid = innovation, S, valid
        self.factors = adjustment.factors

    def _repair(self, P_pred: np.ndarray, t: float) -> np.ndarray:
        """Floor the eigenvalues of a predicted covariance that a rule with negative
        weights left indefinite (ALGORITHMS 3.2 caution 1), counting each repair; a
        non-finite one is flagged. Other rules' covariances are left to the checks of
        the update, which flag them."""
        if not self.rule.has_negative_weights:
            return P_pred
        ok = positive_definite(P_pred)
        live = self.live
        bad = ~ok & live
        if not bad.any():
            return P_pred
        finite = np.all(np.isfinite(P_pred), axis=(-2, -1))
        self.health.flag(bad & ~finite, t, "predicted covariance NaN/inf")
        fix = bad & finite
        if fix.any():
            repaired = P_pred.copy()
            repaired[fix] = floor_eigenvalues(P_pred[fix])
            self.health.repairs[fix] += 1
            still = ~positive_definite(repaired) & fix
            self.health.flag(still, t, "predicted covariance not positive definite")
            return repaired
        return P_pred


@dataclass(frozen=True)
class FilterEntry:
    """A named filter of the catalogue: rule and adaptation factories and its source.
    fading: the adaptation takes the fading-factor options (rho, floor, cap); model: a
    model variant the experiment must build for it ("" = the experiment's model)."""

    rule: Callable[[], IntegrationRule]
    adaptation: Callable[..., AdaptationPolicy]
    description: str
    fading: bool = False
    model: str = ""


SGKF_WARM_UP = 60.0
"""s after the fine start before the strong-tracking factor (and its V_k) starts: the
filter settles first (ALGORITHMS 4.3 step 7: 60 s worked from both of 000's starts, 10 s
did not)."""


def _strong_tracking(**options):
    return SingleFadingFactor(derivative_free=True, warm_up=SGKF_WARM_UP,
                              in_motion_only=True, **options)


def _strong_tracking_gated(**options):
    return _strong_tracking(outlier_probability=0.999, **options)


def _local_level(policy):
    return lambda **options: policy(axes="local-level", **options)


FILTERS: dict[str, FilterEntry] = {
    "kf": FilterEntry(LinearizationRule, NoAdaptation, "conventional Kalman filter"),
    "ekf": FilterEntry(LinearizationRule, NoAdaptation,
                       "extended KF (model Jacobian or central differences)"),
    "sakf": FilterEntry(LinearizationRule, SingleFadingFactor,
                        "single fading factor (Xia et al. 1994)", True),
    "makf": FilterEntry(LinearizationRule, MultipleFadingFactors,
                        "multiple fading factors (003 eq. 37)", True),
    "imakf": FilterEntry(LinearizationRule, ImprovedMultipleFadingFactors,
                         "improved multiple fading factors (003 eqs. 41-42, 50)", True),
    "makf-n": FilterEntry(LinearizationRule, _local_level(MultipleFadingFactors),
                          "MAKF with factors along local E, N, U", True),
    "imakf-n": FilterEntry(LinearizationRule, _local_level(ImprovedMultipleFadingFactors),
                           "IMAKF with factors along local E, N, U", True),
    "sakf-r": FilterEntry(LinearizationRule, MeasurementFadingFactor,
                          "single fading factor on R (the sway as a measurement "
                          "disturbance, ALGORITHMS 2.10)", True),
    "makf-r": FilterEntry(LinearizationRule, MeasurementAxisFading,
                          "fading factors on R along local E, N, U (ALGORITHMS 2.11)", True),
    "imakf-r": FilterEntry(LinearizationRule, MeasurementAxisFading,
                           "IMAKF on R: the same as makf-r (fading Q makes no difference "
                           "when R is scaled)", True),
    "kf-sway": FilterEntry(LinearizationRule, NoAdaptation,
                           "KF with the sway velocity as narrow-band states per local axis "
                           "(ALGORITHMS 2.12-2.13; beyond paper 003)", model="sway-aware"),
    "lckf": FilterEntry(LinearizationRule, NoAdaptation,
                        "classic loosely coupled GPS/INS KF, position and velocity (001)",
                        model="position-velocity"),
    "rakf": FilterEntry(LinearizationRule, RobustAdaptive,
                        "robust adaptive KF with the GPS heading (Yang; 001 scheme 2)"),
    "swakf": FilterEntry(LinearizationRule, SelectiveWeights,
                         "selective-weight adaptive KF with the GPS heading, m = 2.5 "
                         "(001 eqs. 14-21)"),
    "rdghkf": FilterEntry(lambda: ReducedGaussHermiteRule(7), NoAdaptation,
                          "reduced-dimension Gauss-Hermite KF, 7 points on the model's "
                          "nonlinear states (000 eqs. 40-57)"),
    "sgkf": FilterEntry(lambda: ReducedGaussHermiteRule(7), _strong_tracking,
                        "reduced-dimension GH with the strong-tracking fading factor "
                        "(000's SGKF; rho 0.95, beta 1; fading from 60 s on, not while "
                        "still: ALGORITHMS 4.3 step 7)", True),
    "sgkf-gated": FilterEntry(lambda: ReducedGaussHermiteRule(7), _strong_tracking_gated,
                              "sgkf whose fading factor skips a sensor's outlier (an "
                              "innovation beyond chi-square 0.999, at most 2 epochs in a "
                              "row; beyond paper 000)", True),
    "stukf": FilterEntry(lambda: UnscentedRule(spread=STUKF_SPREAD), NoAdaptation,
                         "state-transformation UKF on the rotation-vector model (004; n + "
                         "kappa = 1.5: the points at 1.22 sigma, STUKF_SPREAD)", model="st"),
    "stukf-3n": FilterEntry(lambda: UnscentedRule(kappa=None), NoAdaptation,
                            "the STUKF with kappa = 3 - n (points at sqrt(3) sigma: 78 deg "
                            "of tilt, 104 deg of heading from 004's P0)", model="st"),
    "stekf": FilterEntry(LinearizationRule, NoAdaptation,
                         "state-transformation EKF (004; ALGORITHMS 6.7)", model="st-linear"),
    "ukf": FilterEntry(UnscentedRule, NoAdaptation,
                       "unscented KF (alpha 1, beta 2, kappa 0)"),
    "ukf-3n": FilterEntry(lambda: UnscentedRule(kappa=None), NoAdaptation,
                          "unscented KF with kappa = 3 - n (PSINS's UKF; on the "
                          "experiment's own model: 004's classic UKF)"),
    "ckf": FilterEntry(CubatureRule, NoAdaptation, "cubature KF"),
}
STUKF_SPREAD = 1.5
"""n + kappa of the STUKF's points (kappa = -13.5 for its 15 states). With 004's P0 (45,
45, 60 deg) kappa = 3 - n puts the points at 78 deg of tilt and 104 deg of heading and
the heading swings the wrong way in the first fixes; at sqrt(1.5) sigma, 50 episodes of
the moderate swing (seeds 0 and 1): heading RMS over 600-2000 s 0.58 -> 0.56 and 0.87 ->
0.54 deg, mean NEES(9) 12.6 -> 11.0 and 27.3 -> 11.6. alpha = 0.3 (the scaled UT at 1.16
sigma) matched it at seed 0 and not at seed 1 (0.86 deg, NEES 26); kappa = 0 (3.9 sigma)
loses 95 % of the episodes."""
SPARSE_GRID_LEVELS = range(1, 7)
TENSOR_GH_ORDERS = range(1, 10)
_PATTERNS = {
    "sghkf": ("sparse-grid Gauss-Hermite KF, level L (m_l = 2l - 1)", SPARSE_GRID_LEVELS,
              "sparse-grid level", SparseGridGaussHermiteRule),
    "ghkf": ("tensor-product Gauss-Hermite KF of order m", TENSOR_GH_ORDERS,
             "Gauss-Hermite order", GaussHermiteRule),
}


class UnknownFilter(KeyError):
    """An unknown filter name or an invalid level/order; str() is the plain message."""

    def __str__(self) -> str:
        return str(self.args[0])


BUILT_IN = frozenset(FILTERS)
"""The catalogue's own names (``register_filter`` will not replace them)."""


def register_filter(name: str, rule: Callable[[], IntegrationRule],
                    adaptation: Callable[..., AdaptationPolicy] = NoAdaptation,
                    description: str = "", model: str = "", fading: bool = False
                    ) -> FilterEntry:
    """Add a filter to the catalogue under name, for every campaign, ``evaluate`` and the
    env of this process: a rule factory (an ``IntegrationRule``: the moments of a map of
    a Gaussian), an adaptation factory (an ``AdaptationPolicy``; fading: it takes the
    fading-factor options rho, floor, cap), and the model variant it needs ("" = each
    experiment's own). A name already registered is replaced, a built-in one is not."""
    if not (isinstance(name, str) and name and not any(c.isspace() or c in ",:" for c in name)):
        raise ValueError(f"filter name {name!r}: a non-empty name without spaces, commas "
                         "or colons")
    if name in BUILT_IN or name.rpartition("-")[0] in _PATTERNS:
        raise ValueError(f"filter name {name!r} is a built-in filter (or a sghkf-N/ghkf-N "
                         "name); choose another name")
    if not callable(rule) or not callable(adaptation):
        raise TypeError(f"filter {name!r}: rule and adaptation must be factories "
                        "(callables returning an IntegrationRule / AdaptationPolicy)")
    for factory, kind, options in ((rule, IntegrationRule, {}),
                                   (adaptation, AdaptationPolicy,
                                    {"rho": 0.95} if fading else {})):
        try:                       # built once here: a wrong factory fails now, named
            made = factory(**options)
        except Exception as exc:
            raise TypeError(f"filter {name!r}: {getattr(factory, '__name__', factory)!s}() "
                            f"raised {type(exc).__name__}: {exc}") from None
        if not isinstance(made, kind):
            raise TypeError(f"filter {name!r}: {getattr(factory, '__name__', factory)!s}() "
                            f"returned {type(made).__name__}, not an {kind.__name__}")
    entry = FilterEntry(rule, adaptation, description or f"user filter {name}", fading, model)
    FILTERS[name] = entry
    return entry


def _import_entry(spec: str) -> FilterEntry:
    """The FilterEntry of "module.path:factory" (factory() returns a FilterEntry, an
    IntegrationRule, or an IntegrationRule class), registered under that name."""
    import importlib
    module_name, _, attribute = spec.partition(":")
    try:
        factory = getattr(importlib.import_module(module_name), attribute)
    except (ImportError, AttributeError) as exc:
        raise UnknownFilter(f"filter {spec!r}: cannot import {attribute!r} from "
                            f"{module_name!r} ({exc})") from None
    try:
        made = factory()
    except Exception as exc:      # the user's code: report it in one line, named
        raise UnknownFilter(f"filter {spec!r}: {attribute}() raised "
                            f"{type(exc).__name__}: {exc}") from None
    if isinstance(made, FilterEntry):
        entry = made
    elif isinstance(made, IntegrationRule):
        entry = FilterEntry(factory, NoAdaptation, f"user filter {spec}")
    elif isinstance(made, type) and issubclass(made, IntegrationRule):
        entry = FilterEntry(made, NoAdaptation, f"user filter {spec}")
    else:
        raise UnknownFilter(f"filter {spec!r}: {attribute}() must return a FilterEntry, "
                            f"an IntegrationRule or its class, not {type(made).__name__}")
    FILTERS[spec] = entry
    return entry


def filter_names() -> list[str]:
    """The registry's names and name patterns, for messages."""
    return sorted(FILTERS) + [f"{p}-N" for p in _PATTERNS]


def filter_entry(name: str) -> FilterEntry:
    """The catalogue entry of a filter name (including sghkf-L and ghkf-m); a one-line
    KeyError for unknown names or an invalid level/order."""
    if name in FILTERS:
        return FILTERS[name]
    if ":" in name:
        return _import_entry(name)
    family, _, number = name.rpartition("-")
    if family in _PATTERNS:
        description, valid, what, rule = _PATTERNS[family]
        if not (number.isdigit() and int(number) in valid):
            raise UnknownFilter(f"filter {name!r}: {what} must be an integer in "
                           f"[{valid.start}, {valid.stop - 1}]")
        value = int(number)
        return FilterEntry(lambda: rule(value), NoAdaptation,
                           description.replace(" L ", f" {value} ").replace(" m", f" {value}"))
    raise UnknownFilter(f"unknown filter {name!r}; known filters: " + ", ".join(filter_names()))


def filter_needs(name: str, **adaptation_options) -> frozenset[str]:
    """What the named filter's rule and adaptation need of a model
    (``adaptation.OBSERVATION_FEATURES``)."""
    entry = filter_entry(name)
    policy = entry.adaptation(**(adaptation_options if entry.fading else {}))
    return frozenset(entry.rule().needs) | frozenset(policy.needs)


def make_filter(name: str, **adaptation_options) -> GaussianFilter:
    """A filter of the registry by name; fading-factor options (rho, floor, cap) apply
    to the fading filters only."""
    entry = filter_entry(name)
    adaptation = entry.adaptation(**(adaptation_options if entry.fading else {}))
    return GaussianFilter(name, entry.rule(), adaptation)
