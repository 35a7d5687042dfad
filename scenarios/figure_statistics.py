"""The statistics the campaign figures draw, as functions of a campaign result, so that they
are checked apart from the drawing (``scenarios.figures``): per filter and start the
attitude error's median and percentile band over the episodes (``error_bands``), the
mean and median NEES over time (``nees_curves``) against their chi-square bands
(``mean_nees_band``, ``median_nees_band``) and the epochs outside them
(``nees_excursions``; in summary.json as "nees_band", ``nees_band_summary``), the
heading convergence CDF (``heading_convergence_cdfs``), and the filters whose results
equal another's (``identical_runs``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.estimators.metrics import chi2_quantile
from aligngym.models.units import arcmin


@dataclass
class ErrorBand:
    """One filter's attitude error from one start over a campaign's episodes: t (K,) s
    since the start of fine alignment; median_arcmin, low_arcmin, high_arcmin (K, 3) the
    median and the 5th and 95th percentiles (E, N, U) over the episodes that did not
    diverge (``included``, (B,)); sigma3_arcmin (K, 3) the mean over those episodes of
    the filter's 3 sigma; diverged_error_arcmin (D, K, 3) the diverged episodes' errors.
    With every episode diverged, the band is NaN and the mean 3 sigma is over all."""

    filter: str
    start: str
    t: np.ndarray
    median_arcmin: np.ndarray
    low_arcmin: np.ndarray
    high_arcmin: np.ndarray
    sigma3_arcmin: np.ndarray
    included: np.ndarray
    diverged_error_arcmin: np.ndarray

    @property
    def episodes(self) -> int:
        return int(self.included.size)

    @property
    def diverged_count(self) -> int:
        return int(self.included.size - self.included.sum())


def error_bands(result, percentiles: tuple[float, float] = (5.0, 95.0)) -> list[ErrorBand]:
    """Per run of the campaign (filter x start) its ``ErrorBand``: median and the
    ``percentiles`` (%) of the misalignment over the episodes not diverged (``run.diverged``,
    the campaign's flag: numerical trouble or a final error beyond 5x its 3 sigma)."""
    bands = []
    for run in result.runs:
        error = run.error_n / arcmin                       # (B, K, 3)
        included = ~np.asarray(run.diverged, bool)
        sigma3 = 3.0 * run.result.sigma_n / arcmin
        if included.any():
            low, median, high = np.percentile(error[included],
                                              [percentiles[0], 50.0, percentiles[1]], axis=0)
            sigma3_mean = sigma3[included].mean(axis=0)
        else:
            low = median = high = np.full(error.shape[1:], np.nan)
            sigma3_mean = sigma3.mean(axis=0)
        bands.append(ErrorBand(run.filter, run.start, run.result.t - run.result.t[0],
                               median, low, high, sigma3_mean, included, error[~included]))
    return bands


@dataclass
class NeesCurve:
    """One filter's NEES from one start: t (K,) s; mean and median (K,) over the
    episodes not diverged (NaN where none has a NEES); episodes: how many those are;
    diverged: how many are left out."""

    filter: str
    start: str
    t: np.ndarray
    mean: np.ndarray
    median: np.ndarray
    episodes: int
    diverged: int


def nees_curves(result) -> list[NeesCurve]:
    """Per run the mean and median NEES over the episodes not diverged, per epoch (the
    first epoch, the prior, left out as in the tidy table's nees_mean)."""
    curves = []
    for run in result.runs:
        included = ~np.asarray(run.diverged, bool)
        nees = np.asarray(run.nees, float)[included, 1:]
        finite = np.isfinite(nees)
        mean = np.full(nees.shape[1], np.nan)
        median = np.full(nees.shape[1], np.nan)
        has = finite.any(axis=0)
        if has.any():
            mean[has] = np.nanmean(nees[:, has], axis=0)
            median[has] = np.nanmedian(nees[:, has], axis=0)
        t = run.result.t - run.result.t[0]
        curves.append(NeesCurve(run.filter, run.start, t[1:], mean, median,
                                int(included.sum()), int((~included).sum())))
    return curves


def mean_nees_band(dof: int, episodes: int, probability: float = 0.95
                   ) -> tuple[float, float]:
    """Two-sided ``probability`` band of the mean NEES of ``episodes`` consistent
    episodes with ``dof`` states: the sum is chi-square with episodes x dof degrees of
    freedom (Bar-Shalom, Li, Kirubarajan 2001, 5.4.2)."""
    tail = (1.0 - probability) / 2.0
    n = episodes * dof
    return float(chi2_quantile(tail, n) / episodes), float(chi2_quantile(1.0 - tail, n)
                                                            / episodes)


def median_nees_band(dof: int, episodes: int, probability: float = 0.95
                     ) -> tuple[float, float]:
    """Two-sided ``probability`` band of the median NEES of ``episodes`` consistent
    episodes with ``dof`` states, from the order statistics: the k-th smallest of B
    uniforms is Beta(k, B + 1 - k), mapped through the chi-square(dof) quantile. For even
    B (the median averages the B/2-th and the B/2+1-th) the band spans the lower one's
    lower and the upper one's upper quantile (coverage at least ``probability``)."""
    from scipy.special import betaincinv
    tail = (1.0 - probability) / 2.0
    k_low, k_high = (episodes + 1) // 2, episodes // 2 + 1
    low = chi2_quantile(betaincinv(k_low, episodes + 1 - k_low, tail), dof)
    high = chi2_quantile(betaincinv(k_high, episodes + 1 - k_high, 1.0 - tail), dof)
    return float(low), float(high)


@dataclass
class NeesExcursion:
    """One filter's mean NEES from one start against the ``probability`` band of the
    mean of ``episodes`` consistent episodes with ``dof`` states (``mean_nees_band``;
    None without an episode left): t (K,) s as in its ``NeesCurve``; counted (K,) the
    epochs with a mean NEES; above, below (K,) those where it is above or below the band."""

    filter: str
    start: str
    band: tuple[float, float] | None
    dof: int
    episodes: int
    probability: float
    t: np.ndarray
    counted: np.ndarray
    above: np.ndarray
    below: np.ndarray

    def _fraction(self, mask: np.ndarray) -> float | None:
        epochs = int(self.counted.sum())
        return float(mask.sum() / epochs) if epochs and self.band else None

    @property
    def fraction_above(self) -> float | None:
        """Fraction of the epochs with a mean NEES where it is above the band."""
        return self._fraction(self.above)

    @property
    def fraction_below(self) -> float | None:
        return self._fraction(self.below)

    @property
    def first_time_outside(self) -> float | None:
        """s since the start of fine alignment of the first epoch outside the band."""
        outside = np.flatnonzero(self.above | self.below)
        return float(self.t[outside[0]]) if outside.size else None

    def spans(self, mask: np.ndarray) -> list[tuple[float, float]]:
        """The runs of consecutive epochs of mask as (t start, width) s, each epoch
        covering the time half-way to its neighbours (``broken_barh``'s spans)."""
        if not mask.any():
            return []
        t = self.t
        edges = np.concatenate([t[:1], 0.5 * (t[1:] + t[:-1]), t[-1:]])
        step = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
        first, last = np.flatnonzero(step == 1), np.flatnonzero(step == -1)
        return [(float(edges[a]), float(edges[b] - edges[a])) for a, b in zip(first, last)]

    def sentence(self) -> str:
        """In words: e.g. "mean NEES of 6 episodes (9 states) against its 95 % chi-square
        band [5.93, 12.7]: above in 34 % of the epochs, below in 0 %, first outside at
        191 s"."""
        if not self.band or not self.counted.any():
            return "no mean NEES (no episode left)"
        head = (f"mean NEES of {self.episodes} episodes ({self.dof} states) against its "
                f"{100.0 * self.probability:g} % chi-square band [{self.band[0]:.3g}, "
                f"{self.band[1]:.3g}]: ")
        if self.first_time_outside is None:
            return head + "inside at every epoch"
        return (head + f"above in {as_percent(self.fraction_above)} of the epochs, below in "
                f"{as_percent(self.fraction_below)}, first outside at "
                f"{self.first_time_outside:.4g} s")

    def summary(self) -> dict:
        """The JSON form (summary.json's "nees_band")."""
        return {"band": list(self.band) if self.band else None, "dof": self.dof,
                "episodes": self.episodes, "probability": self.probability,
                "epochs": int(self.counted.sum()),
                "fraction_of_epochs_above": self.fraction_above,
                "fraction_of_epochs_below": self.fraction_below,
                "first_time_outside_s": self.first_time_outside, "text": self.sentence()}


def as_percent(fraction: float) -> str:
    """A fraction as a whole percentage; "<1 %" and ">99 %" short of 0 and 1."""
    if 0.0 < fraction < 0.005:
        return "<1 %"
    return ">99 %" if 0.995 <= fraction < 1.0 else f"{100.0 * fraction:.0f} %"


def nees_excursions(curves: list[NeesCurve], dof: int, probability: float = 0.95
                    ) -> list[NeesExcursion]:
    """Per curve its ``NeesExcursion``: the epochs where the mean NEES over its episodes
    (those not diverged) is outside the ``probability`` band of a mean of that many
    consistent episodes (``mean_nees_band``)."""
    out = []
    for curve in curves:
        counted = np.isfinite(curve.mean)
        band = (mean_nees_band(dof, curve.episodes, probability)
                if dof and curve.episodes else None)
        if band:
            with np.errstate(invalid="ignore"):
                above, below = counted & (curve.mean > band[1]), counted & (curve.mean < band[0])
        else:
            above = below = np.zeros_like(counted)
        out.append(NeesExcursion(curve.filter, curve.start, band, dof, curve.episodes,
                                 probability, curve.t, counted, above, below))
    return out


def nees_band_summary(result, probability: float = 0.95) -> dict:
    """summary.json's "nees_band": {filter: {start: ``NeesExcursion.summary()``}}; empty
    for an experiment without a NEES (``nees_dof`` 0)."""
    dof = result.experiment.nees_dof()
    out: dict[str, dict[str, dict]] = {}
    if dof:
        for excursion in nees_excursions(nees_curves(result), dof, probability):
            out.setdefault(excursion.filter, {})[excursion.start] = excursion.summary()
    return out


@dataclass
class ConvergenceCdf:
    """One filter's heading convergence from one start: times (C,) s, sorted, of the C
    episodes that converged (heading error within the threshold from then to the end,
    not diverged); episodes B in all; diverged; t_end s, the run's length."""

    filter: str
    start: str
    times: np.ndarray
    episodes: int
    diverged: int
    t_end: float

    @property
    def not_converged(self) -> int:
        return self.episodes - self.diverged - int(self.times.size)


def heading_convergence_cdfs(result) -> list[ConvergenceCdf]:
    """Per run the convergence times (``run.heading_convergence``, the tidy table's
    heading_convergence_s) of the episodes whose final heading error is within the
    experiment's threshold and that did not diverge."""
    threshold = result.experiment.heading_threshold_arcmin * arcmin
    cdfs = []
    for run in result.runs:
        diverged = np.asarray(run.diverged, bool)
        converged = ~diverged & (np.abs(run.error_n[:, -1, 2]) <= threshold)
        t = run.result.t - run.result.t[0]
        cdfs.append(ConvergenceCdf(run.filter, run.start,
                                   np.sort(np.asarray(run.heading_convergence)[converged]),
                                   int(diverged.size), int(diverged.sum()), float(t[-1])))
    return cdfs


def _same_results(a, b) -> bool:
    """Whether two runs drew the same figures: attitude errors, the filter's sigma, NEES
    and divergence flags equal element for element (NaN equal to NaN: a run lost midway
    is NaN from then on). The fading factors themselves may differ (a factor held at 1)."""
    pairs = ((a.error_n, b.error_n), (a.result.sigma_n, b.result.sigma_n),
             (a.nees, b.nees), (a.diverged, b.diverged))
    for x, y in pairs:
        x, y = np.asarray(x), np.asarray(y)
        if not np.array_equal(x, y, equal_nan=x.dtype.kind in "fc" and y.dtype.kind in "fc"):
            return False
    return True


def identical_runs(result) -> dict[tuple[str, str], str]:
    """Runs whose results equal an earlier run's from the same start, bit for bit
    (``_same_results``; a fading-factor filter whose factors never left 1 is its KF;
    makf-r and imakf-r are one filter): (filter, start) -> the first filter of its group.
    Their curves coincide; the legends and the box plot's labels say so."""
    twins: dict[tuple[str, str], str] = {}
    for i, run in enumerate(result.runs):
        for earlier in result.runs[:i]:
            if (earlier.start == run.start and (earlier.filter, earlier.start) not in twins
                    and earlier.filter != run.filter and _same_results(earlier, run)):
                twins[(run.filter, run.start)] = earlier.filter
                break
    return twins
