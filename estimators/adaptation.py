"""Adaptation policies: what a filter does with its innovation statistics. A policy sees
one ``AdaptationContext`` per update (innovation, S, P_xz, the propagated covariance, Q,
R, the measurement's axes, a motion flag) and returns an ``Adjustment``: a new predicted
covariance and/or a new R (the filter then redoes the update with them). The Kalman loop
is elsewhere (``estimators.filters``). This module is the policies' protocol (the
context, the adjustment, an agent's ``PolicyTuning``, ``AdaptationPolicy``), the
observation features a policy may need of a model, and the conventional filter's
``NoAdaptation``; the fading-factor policies are in ``estimators.fading_factors``, Yang's
robust adaptive family in ``estimators.robust_adaptive``.

All act on a batch of B episodes. Notation (ALGORITHMS.md section 2.2):
``PhiPPhi = Phi P Phi^T`` (the propagated covariance without process noise; a sigma-point
rule's equivalent for a nonlinear process), ``Q`` the discrete process noise, ``H`` the
measurement matrix (a nonlinear measurement's statistical linearisation
P_xz^T P_pred^-1), ``R`` the measurement noise, ``e`` the innovation ``z - z_hat``.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class AdaptationContext:
    """What a policy sees at one update, for B episodes, m measurements, n states.

    innovation (B, m), zero where missing; valid (B, m) measurement present; S (B, m, m)
    innovation covariance with the unadapted P_pred; P_xz (B, n, m); PhiPPhi (B, n, n);
    Q (B, n, n); R (B, m, m); H (B, m, n); axes (B, m, m) rotation of the measurement
    axes to E, N, U or None; motion (B,) bool or None; directions (B, m, n) the state
    direction each measurement measures directly (``Observation.directions``) or None;
    t (s; one per episode (B,) with per-episode epochs).
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
    t: float | np.ndarray = 0.0


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

    def restart(self, members: np.ndarray) -> None:
        """Start the episodes ``members`` (indices into the batch) again while the others
        go on (the vector env's slots that reset alone): their state as ``reset`` leaves
        it. Every policy says how (a stateless one: nothing to do)."""
        raise NotImplementedError(
            f"adaptation {self.name!r} ({type(self).__name__}) has no restart(members): "
            "the vector env's slots that reset alone need it (a stateless policy: "
            "def restart(self, members): pass)")

    def tune(self, tuning: PolicyTuning) -> None:
        """Take an agent's retune (``PolicyTuning``) from this update on; ValueError for a
        policy without fading factors."""
        raise ValueError(f"adaptation {self.name!r} has no fading factors to retune")

    @abstractmethod
    def adapt(self, ctx: AdaptationContext) -> Adjustment:
        """The adjustment for this update."""


class NoAdaptation(AdaptationPolicy):
    """The conventional Kalman filter: P_pred = Phi P Phi^T + Q, R as modelled."""

    def restart(self, members: np.ndarray) -> None:
        """Stateless: nothing to restart."""

    def adapt(self, ctx):
        return Adjustment(None, None, np.zeros((ctx.PhiPPhi.shape[0], 0)))
