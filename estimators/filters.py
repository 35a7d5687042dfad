"""The generic Gaussian filter on a batch of independent episodes.

A filter = process/measurement model x integration rule x adaptation policy (SPEC 5).
The Kalman loop exists once, here (the named filters are in ``estimators.catalogue``).
Every update keeps P symmetric, checks it (and the innovation covariance) positive
definite and finite; an episode that fails is marked diverged with the time and the
reason and frozen, while the rest of the batch goes on. ``update`` returns what it
computed (``UpdateReport``); nothing is left behind on the filter but its state.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.adaptation import (AdaptationContext, AdaptationPolicy, Adjustment,
                                            PolicyTuning)
from aligngym.estimators.linalg import (floor_eigenvalues, identity_where_not,
                                        positive_definite, solve_each)
from aligngym.estimators.members import copy_members
from aligngym.estimators.model import Observation, Transition, wrap_angle
from aligngym.estimators.rules import IntegrationRule, symmetric


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

    def flag(self, mask: np.ndarray, t: float | np.ndarray, reason: str) -> None:
        """Mark the episodes of mask (B,) diverged at t s (one time, or one per episode
        (B,)) for reason, those not diverged already."""
        for b in np.flatnonzero(mask & ~self.diverged):
            self.diverged[b], self.reason[b] = True, reason
            self.time[b] = t if np.ndim(t) == 0 else t[b]


@dataclass(frozen=True)
class UpdateReport:
    """What one measurement update computed, for B episodes, n states and m measurement
    components (in the units of the model's measurement).

    x (B, n), P (B, n, n): the posterior, the filter's new state itself (not a copy: an
    episode frozen by a divergence keeps its last). innovation (B, m): z - z_hat (z_hat
    the rule's predicted measurement) that the gain used, zero where unused; S (B, m, m):
    its covariance after the adaptation (unit rows and columns where unused); valid
    (B, m): the components used (present, not rejected by the policy).
    unadapted_innovation, unadapted_S, unadapted_valid: the same before the adaptation
    and any rejection, what an innovation test looks at. nis (B,): the normalised
    innovation squared of those, chi-square with nis_dof (B,) degrees of freedom for a
    consistent filter (NaN: no component, or the episode diverged before this update).
    factors (B, k): the adaptation policy's factors.
    """

    x: np.ndarray
    P: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    valid: np.ndarray
    unadapted_innovation: np.ndarray
    unadapted_S: np.ndarray
    unadapted_valid: np.ndarray
    nis: np.ndarray
    nis_dof: np.ndarray
    factors: np.ndarray


def _innovation(observation: Observation, z: np.ndarray, z_hat: np.ndarray,
                valid: np.ndarray) -> np.ndarray:
    """z - z_hat (B, m), angle components wrapped, zero where the measurement is missing."""
    innovation = z - z_hat
    if observation.angles:
        idx = list(observation.angles)
        innovation[:, idx] = wrap_angle(innovation[:, idx])
    return np.where(valid, innovation, 0.0)


def normalised_innovation_squared(innovation: np.ndarray, S: np.ndarray, valid: np.ndarray,
                                  live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """e^T S^-1 e over the valid components (B,) and their count (B,): NaN where none is
    valid, where the episode is not live, or where S is singular."""
    used = live[:, None] & valid
    e = np.where(used, innovation, 0.0)
    S = identity_where_not(used[:, :, None] & used[:, None, :], S)
    S = identity_where_not(np.isfinite(S), S)
    nis = np.einsum("bi,bi->b", e, solve_each(S, e[..., None])[0][..., 0])
    dof = valid.sum(-1)
    return np.where((dof > 0) & live, nis, np.nan), dof


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
        self._pending = None
        bad = ~positive_definite(self.P)
        self.health.flag(bad, 0.0, "initial covariance not positive definite")

    def restart(self, members: np.ndarray, fresh: "GaussianFilter") -> None:
        """Replace the episodes ``members`` (indices into the batch) by those of
        ``fresh``, the same filter just reset for len(members) new episodes; the others
        go on (the vector env's resets). Between epochs only."""
        if self._pending is not None or fresh._pending is not None:
            raise RuntimeError("restart() between a predict() and its update()")
        members = np.asarray(members, int)
        self.x[members], self.P[members] = fresh.x, fresh.P
        copy_members(self.health, fresh.health, members, batch=self.x.shape[0])
        self.adaptation.restart(members)

    @property
    def live(self) -> np.ndarray:
        """(B,) episodes not diverged."""
        return ~self.health.diverged

    def predict(self, transition: Transition) -> None:
        """Propagate through the process map (its noise Q is added at the update, where
        the adaptation policy may fade it)."""
        live = self.live
        if self._pending is not None:  # no update since the last predict: P_pred + Q,
            self.P = np.where(live[:, None, None],    # frozen where diverged
                              self._pending[0] + self._pending[1], self.P)
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
                identity_where_not(live[:, None, None], P))

    def update(self, observation: Observation, tuning: PolicyTuning | None = None
               ) -> UpdateReport:
        """Measurement update at observation.t (s); missing components are skipped.
        tuning: an agent's retune of the adaptation policy, from this update on (None:
        as it is). Returns what the update computed."""
        if self._pending is None:
            raise RuntimeError("update() needs a predict() first")
        if tuning is not None:
            self.adaptation.tune(tuning)
        PhiPPhi, Q = self._pending
        self._pending = None
        t, R = observation.t, observation.noise
        live_before = self.live
        P_pred = self._predicted_covariance(PhiPPhi + Q, t)
        valid = observation.valid() & self.live[:, None]
        z = np.where(valid, observation.z, 0.0)
        x_in, P_pred = self._harmless(self.x, self._repair(P_pred, t))
        z_hat, P_zz, P_xz = self.rule.moments(observation, x_in, P_pred)
        innovation = _innovation(observation, z, z_hat, valid)
        unadapted = (innovation, P_zz + R, valid)    # before adaptation and rejection
        adjustment = self.adaptation.adapt(self._context(observation, innovation, valid,
                                                         P_pred, P_zz, P_xz, PhiPPhi, Q, R))
        valid, innovation, R, P_pred, P_zz, P_xz = self._adapted(
            observation, adjustment, z, valid, innovation, R, P_pred, P_zz, P_xz)
        H, HP, S, R = self._innovation_covariance(observation, valid, R, P_pred, P_zz, P_xz)
        K = self._gain(S, HP, t)
        self._correct(observation, K, innovation, H, R, S, P_pred, t)
        nis, dof = normalised_innovation_squared(*unadapted, live_before)
        return UpdateReport(x=self.x, P=self.P, innovation=innovation, S=S, valid=valid,
                            unadapted_innovation=unadapted[0], unadapted_S=unadapted[1],
                            unadapted_valid=unadapted[2],
                            nis=nis, nis_dof=dof, factors=adjustment.factors)

    def _predicted_covariance(self, P_pred: np.ndarray, t: float | np.ndarray) -> np.ndarray:
        """Phi P Phi^T + Q made symmetric, its non-finite episodes (or states) flagged."""
        P_pred = symmetric(P_pred)
        finite = np.all(np.isfinite(P_pred), axis=(-2, -1)) & np.all(np.isfinite(self.x), -1)
        # flag() passes over episodes already diverged: no mask by the live ones needed
        self.health.flag(~finite, t, "predicted state or covariance NaN/inf")
        return P_pred

    def _context(self, observation: Observation, innovation: np.ndarray, valid: np.ndarray,
                 P_pred: np.ndarray, P_zz: np.ndarray, P_xz: np.ndarray,
                 PhiPPhi: np.ndarray, Q: np.ndarray, R: np.ndarray) -> AdaptationContext:
        """What the adaptation policy sees (H: the model's, or for a nonlinear
        measurement the statistical linearisation P_xz^T P_pred^-1)."""
        if observation.linear:
            H = observation.matrix
        else:
            H = np.swapaxes(np.linalg.pinv(P_pred, hermitian=True) @ P_xz, -1, -2)
        return AdaptationContext(innovation=innovation, valid=valid, S=P_zz + R, P_xz=P_xz,
                                 PhiPPhi=PhiPPhi, Q=Q, R=R, H=H, axes=observation.axes,
                                 motion=observation.motion,
                                 directions=observation.directions, t=observation.t)

    def _adapted(self, observation: Observation, adjustment: Adjustment, z: np.ndarray,
                 valid: np.ndarray, innovation: np.ndarray, R: np.ndarray,
                 P_pred: np.ndarray, P_zz: np.ndarray, P_xz: np.ndarray) -> tuple:
        """The policy's adjustment applied: rejected components left out, its R and
        P_pred taken (not where the epoch has no measurement), and a nonlinear
        measurement's moments recomputed from the adapted P_pred. Returns valid,
        innovation, R, P_pred, P_zz, P_xz."""
        silent = ~valid.any(-1)[:, None, None]  # no measurement: no adaptation either
        if adjustment.rejected is not None and adjustment.rejected.any():
            valid = valid & ~adjustment.rejected
            innovation = np.where(valid, innovation, 0.0)
        if adjustment.R is not None:
            R = np.where(silent, R, adjustment.R)
        if adjustment.P_pred is not None:
            adapted = np.where(silent, P_pred, adjustment.P_pred)
            P_pred = self._repair(symmetric(adapted), observation.t)
            if not observation.linear:  # re-update with the adapted prediction
                x_in, P_pred = self._harmless(self.x, P_pred)
                z_hat, P_zz, P_xz = self.rule.moments(observation, x_in, P_pred)
                innovation = _innovation(observation, z, z_hat, valid)
        return valid, innovation, R, P_pred, P_zz, P_xz

    @staticmethod
    def _innovation_covariance(observation: Observation, valid: np.ndarray, R: np.ndarray,
                               P_pred: np.ndarray, P_zz: np.ndarray, P_xz: np.ndarray
                               ) -> tuple:
        """H (linear measurement; None otherwise), H P_pred (P_xz^T), S and R with the
        missing components' rows of H and columns of P_xz zero and a unit diagonal in S
        and R, so that their gain columns are exactly zero. Returns H, HP, S, R."""
        missing = ~valid
        any_missing = bool(missing.any())
        if any_missing:
            cross_valid = valid[:, :, None] & valid[:, None, :]
            R = identity_where_not(cross_valid, R)
        if observation.linear:
            H = observation.matrix
            if any_missing:
                H = np.where(valid[:, :, None], H, 0.0)
            HP = H @ P_pred
            return H, HP, HP @ np.swapaxes(H, -1, -2) + R, R
        if any_missing:
            P_xz = np.where(valid[:, None, :], P_xz, 0.0)
            P_zz = np.where(cross_valid, P_zz, 0.0)
        return None, np.swapaxes(P_xz, -1, -2), P_zz + R, R

    def _gain(self, S: np.ndarray, HP: np.ndarray, t: float | np.ndarray) -> np.ndarray:
        """K = (S^-1 H P)^T (B, n, m); an episode whose S is not positive definite or is
        singular is flagged (and gets a zero gain)."""
        self.health.flag(~positive_definite(S), t, "innovation covariance not positive "
                         "definite")
        live = self.live
        S_safe = identity_where_not(live[:, None, None], S)
        S_inv_HP, solved = solve_each(S_safe, HP)
        if not solved.all():               # an episode's S singular to working precision
            self.health.flag(~solved, t, "innovation covariance singular")
            S_inv_HP = np.where(solved[:, None, None], S_inv_HP, 0.0)
        return np.swapaxes(S_inv_HP, -1, -2)

    def _correct(self, observation: Observation, K: np.ndarray, innovation: np.ndarray,
                 H: np.ndarray | None, R: np.ndarray, S: np.ndarray, P_pred: np.ndarray,
                 t: float | np.ndarray) -> None:
        """x + K e and P (Joseph form for a linear measurement), kept for the live
        episodes whose P stays positive definite and x finite (the others flagged)."""
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

    def _repair(self, P_pred: np.ndarray, t: float | np.ndarray) -> np.ndarray:
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
