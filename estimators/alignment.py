"""A fine alignment: one filter on one model for a batch of episodes, advanced one epoch
at a time (a campaign runs all epochs; the gymnasium env steps it and may rescale the
noise each epoch). Generic over models (``estimators.model.FilterModel``).

A campaign's episodes all start together. The vector env's run is ``staggered``: each
episode has its own epoch, and ``restart`` replaces some episodes by new ones at epoch 0
while the others go on, so that slots resetting at different steps still share one
batched filter."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from aligngym.estimators.adaptation import PolicyTuning
from aligngym.estimators.filters import GaussianFilter, UpdateReport
from aligngym.estimators.members import copy_members
from aligngym.estimators.model import FilterModel, Scale, set_at_epoch


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
    series: the model's own time series (``FilterModel.series``) up to the same epoch;
    chunks: the batch chunks the run was made of (``concatenate_results``: its
    seconds_per_epoch sums theirs, each chunk a batch of its own paying the filter's fixed
    cost an epoch, side by side in worker processes or one after another, so that it is
    not the time of one batch).
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
    chunks: int = 1

    @property
    def seconds_per_episode_epoch(self) -> float:
        """seconds_per_epoch shared among the B episodes (s): what results.csv and the
        papers' summaries report per episode (summed over ``chunks``)."""
        return self.seconds_per_epoch / self.C_s_n.shape[0]


class AlignmentRun:
    """Filter ``filt`` on ``model`` (see the module docstring); staggered: one epoch per
    episode, ``k`` (B,) ints, else one for all, ``k`` an int."""

    def __init__(self, filt: GaussianFilter, model: FilterModel, staggered: bool = False
                 ) -> None:
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
        self.k = np.zeros(B, int) if staggered else 0
        self.compute_seconds = 0.0
        self.member_seconds = np.zeros(B) if staggered else None
        """Staggered: each episode's share of the step times since it began, s."""
        self._record()

    @property
    def done(self) -> bool:
        """Every episode is at its last epoch (staggered: any, as the batched step cannot
        go on)."""
        return bool(np.any(self.k >= self.epochs))

    @property
    def t(self) -> np.ndarray:
        return self.model.t

    @property
    def diverged(self) -> np.ndarray:
        """(B,) the episodes the filter's guards have flagged diverged so far (frozen)."""
        return self.filt.health.diverged.copy()

    def _record(self) -> None:
        k, filt = self.k, self.filt
        set_at_epoch(self.C_s_n, k, self.model.attitude(k, filt.x))
        set_at_epoch(self.P, k, filt.P)
        set_at_epoch(self.sigma_n, k, self.model.attitude_sigma(k, filt.P))

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
        factors = np.full((self.batch, self.factors.shape[-1]), np.nan)
        factors[:, :width] = report.factors
        set_at_epoch(self.factors, k, factors)
        # the epoch an episode diverges at counts too (the report's NIS: live before)
        set_at_epoch(self.nis, k, report.nis)
        set_at_epoch(self.nis_dof, k, report.nis_dof)
        filt.x, filt.P = model.feedback(report.x, report.P, filt.live)   # the posterior
        set_at_epoch(self.x, k + 1, filt.x)
        self.k = k + 1
        self._record()
        elapsed = time.perf_counter() - start
        self.compute_seconds += elapsed
        if self.member_seconds is not None:
            self.member_seconds += elapsed / self.batch
        return report

    def result(self, members: np.ndarray | None = None) -> FineResult:
        """The run so far (all epochs once done) of all episodes, or of ``members``
        (indices into the batch; staggered: episodes at the same epoch)."""
        b = slice(None) if members is None else np.asarray(members, int)
        k = self.k if np.ndim(self.k) == 0 else self.k[b]
        if np.ndim(k):
            if len(k) and np.any(k != k[0]):
                raise ValueError(f"result() of episodes at different epochs {k.tolist()}")
            k = int(k[0]) if len(k) else 0
        health = self.filt.health
        factors = (self.factors[b, :k] if self.factors is not None
                   else np.zeros((len(health.diverged[b]), 0, 0)))
        return FineResult(t=self.t[: k + 1], C_s_n=self.C_s_n[b, : k + 1],
                          P=self.P[b, : k + 1], sigma_n=self.sigma_n[b, : k + 1],
                          x=self.x[b, : k + 1], factors=factors,
                          diverged=health.diverged[b].copy(),
                          diverged_time=health.time[b].copy(),
                          diverged_reason=list(np.array(health.reason, object)[b]),
                          repairs=health.repairs[b].copy(),
                          seconds_per_epoch=(self.compute_seconds if self.member_seconds
                                             is None else self.member_seconds[b].sum())
                          / max(k, 1),
                          series={name: values[b, : k + 1]
                                  for name, values in self.model.series().items()},
                          nis=self.nis[b, :k].copy(), nis_dof=self.nis_dof[b, :k].copy())

    def restart(self, members: np.ndarray, fresh: "AlignmentRun") -> None:
        """Staggered: replace the episodes ``members`` (indices into the batch) by those of
        ``fresh``, a new staggered run of the same filter and model kind on len(members)
        episodes (at epoch 0); the others go on. Each episode's numbers are those of a
        run of it alone."""
        if np.ndim(self.k) == 0:
            raise RuntimeError("restart() needs a staggered run")
        members = np.asarray(members, int)
        copy_members(self.model, fresh.model, members, skip=self.model.scratch)
        self.filt.restart(members, fresh.filt)
        for name in ("C_s_n", "P", "sigma_n", "x", "nis", "nis_dof"):
            getattr(self, name)[members] = getattr(fresh, name)
        if self.factors is not None:
            self.factors[members] = 0.0
        self.k[members] = 0
        self.member_seconds[members] = 0.0


def run_alignment(filt: GaussianFilter, model: FilterModel) -> FineResult:
    """Run one filter over all epochs of a model (see AlignmentRun)."""
    run = AlignmentRun(filt, model)
    while not run.done:
        run.step()
    return run.result()
