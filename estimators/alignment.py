"""A fine alignment: one filter on one model for a batch of episodes, advanced one epoch
at a time (a campaign runs all epochs; the gymnasium env steps it and may rescale the
noise each epoch). Generic over models (``estimators.model.FilterModel``)."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from aligngym.estimators.adaptation import PolicyTuning
from aligngym.estimators.filters import GaussianFilter, UpdateReport
from aligngym.estimators.model import FilterModel, Scale


@dataclass
class FineResult:
    """Time series of a fine-alignment run for B episodes at the K+1 epoch boundaries.

    t (K+1,) s since t0; C_s_n (B, K+1, 3, 3) estimated attitude of the IMU frame;
    P (B, K+1, n, n) in the state's frames; sigma_n (B, K+1, 3) rad, 1-sigma
    misalignment along E, N, U (Euler-error sigmas for Euler models); x (B, K+1, n)
    the state after feedback (with C_s_n and P: one consistent estimate); factors
    (B, K, k); diverged (B,), diverged_time (B,) s, diverged_reason; repairs (B,)
    predicted covariances repaired; seconds_per_epoch: wall time per epoch for these
    episodes (a share of their batch's, ``batch_slice``; summed over a batch's chunks);
    series: the model's own time series (``FilterModel.series``) up to the same epoch.
    """

    t: np.ndarray
    C_s_n: np.ndarray
    P: np.ndarray
    sigma_n: np.ndarray
    x: np.ndarray
    factors: np.ndarray
    diverged: np.ndarray
    diverged_time: np.ndarray
    diverged_reason: list[str]
    repairs: np.ndarray
    seconds_per_epoch: float
    series: dict[str, np.ndarray] = field(default_factory=dict)
    nis: np.ndarray | None = None
    """(B, K) normalised innovation squared e^T S^-1 e of each update with the predicted
    (unadapted) S (NaN: none): the innovation test's statistic, chi-square with
    ``nis_dof`` degrees of freedom for a consistent filter."""
    nis_dof: np.ndarray | None = None


class AlignmentRun:
    """Filter ``filt`` on ``model`` (see the module docstring)."""

    def __init__(self, filt: GaussianFilter, model: FilterModel) -> None:
        self.filt, self.model = filt, model
        B, K, n = model.batch, model.epochs, model.layout.n
        self.batch, self.epochs = B, K
        x0, P0 = model.initial()
        filt.reset(x0, P0, model.layout.angles)
        self.C_s_n = np.empty((B, K + 1, 3, 3))
        self.P = np.empty((B, K + 1, n, n))
        self.sigma_n = np.empty((B, K + 1, 3))
        self.x = np.zeros((B, K + 1, n))
        self.x[:, 0] = filt.x
        self.factors: np.ndarray | None = None
        self.nis = np.full((B, K), np.nan)
        self.nis_dof = np.zeros((B, K), int)
        self.k = 0
        self.compute_seconds = 0.0
        self._record()

    @property
    def done(self) -> bool:
        return self.k >= self.epochs

    @property
    def t(self) -> np.ndarray:
        return self.model.t

    @property
    def diverged(self) -> np.ndarray:
        """(B,) the episodes the filter's guards have flagged diverged so far (frozen)."""
        return self.filt.health.diverged.copy()

    def _record(self) -> None:
        k, filt = self.k, self.filt
        self.C_s_n[:, k] = self.model.attitude(k, filt.x)
        self.P[:, k] = filt.P
        self.sigma_n[:, k] = self.model.attitude_sigma(k, filt.P)

    def step(self, q_scale: tuple[Scale, Scale] = (1.0, 1.0), r_scale: Scale = 1.0,
             tuning: PolicyTuning | None = None) -> UpdateReport:
        """One epoch. q_scale multiplies the (gyro, accelerometer) white-noise variances,
        r_scale the measurement-noise variance (1 = as tuned), each a number or one per
        episode, (B,); tuning: a retune of the adaptation policy (``PolicyTuning``).
        Returns the epoch's ``UpdateReport`` (before the model's feedback)."""
        if self.done:
            raise RuntimeError("the fine alignment is finished")
        start = time.perf_counter()
        k, filt, model = self.k, self.filt, self.model
        filt.predict(model.transition(k, q_scale))
        report = filt.update(model.observation(k, r_scale), tuning)
        width = report.factors.shape[-1]
        if self.factors is None:
            self.factors = np.zeros((self.batch, self.epochs, width))
        elif width > self.factors.shape[-1]:  # m grew: widen, NaN where not formed
            grown = np.full((self.batch, self.epochs, width), np.nan)
            grown[..., : self.factors.shape[-1]] = self.factors
            self.factors = grown
        self.factors[:, k] = np.nan
        self.factors[:, k, :width] = report.factors
        # the epoch an episode diverges at counts too (the report's NIS: live before)
        self.nis[:, k] = report.nis
        self.nis_dof[:, k] = report.nis_dof
        filt.x, filt.P = model.feedback(report.x, report.P, filt.live)   # the posterior
        self.x[:, k + 1] = filt.x
        self.k += 1
        self._record()
        self.compute_seconds += time.perf_counter() - start
        return report

    def result(self) -> FineResult:
        """The run so far (all epochs once done)."""
        k, health = self.k, self.filt.health
        factors = (self.factors[:, :k] if self.factors is not None
                   else np.zeros((self.batch, 0, 0)))
        return FineResult(t=self.t[: k + 1], C_s_n=self.C_s_n[:, : k + 1],
                          P=self.P[:, : k + 1], sigma_n=self.sigma_n[:, : k + 1],
                          x=self.x[:, : k + 1], factors=factors,
                          diverged=health.diverged.copy(), diverged_time=health.time.copy(),
                          diverged_reason=list(health.reason), repairs=health.repairs.copy(),
                          seconds_per_epoch=self.compute_seconds / max(k, 1),
                          series={name: values[:, : k + 1]
                                  for name, values in self.model.series().items()},
                          nis=self.nis[:, :k].copy(), nis_dof=self.nis_dof[:, :k].copy())


def run_alignment(filt: GaussianFilter, model: FilterModel) -> FineResult:
    """Run one filter over all epochs of a model (see AlignmentRun)."""
    run = AlignmentRun(filt, model)
    while not run.done:
        run.step()
    return run.result()
