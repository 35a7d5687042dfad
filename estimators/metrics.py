"""Per-episode alignment metrics from an estimate, its covariance and the truth."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.models.attitude import dcm_to_euler, dcm_to_rotvec
from aligngym.models.earth import OMEGA_IE, normal_gravity
from aligngym.models.units import arcmin as ARCMIN


def chi2_quantile(probability: float | np.ndarray, dof: float | np.ndarray
                  ) -> float | np.ndarray:
    """The chi-square(dof) quantile 2 P^-1(dof / 2, probability) (P: the regularised lower
    incomplete gamma function), as ``scipy.stats.chi2.ppf`` computes it (the same numbers,
    a test) from ``scipy.special`` alone: scipy.stats takes a second to import."""
    from scipy.special import gammaincinv
    return 2 * gammaincinv(np.asarray(dof) / 2, probability)


def misalignment(C_true: np.ndarray, C_est: np.ndarray) -> np.ndarray:
    """Misalignment phi (..., 3) rad, C_true = exp([phi x]) C_est (in C's target frame)."""
    return dcm_to_rotvec(C_true @ np.swapaxes(C_est, -1, -2))


def euler_error(C_b_n_true: np.ndarray, C_b_n_est: np.ndarray) -> np.ndarray:
    """Estimated minus true [pitch, roll, heading] (..., 3) rad, heading clockwise from
    north and wrapped to (-pi, pi]."""
    est, true = dcm_to_euler(C_b_n_est), dcm_to_euler(C_b_n_true)
    d = est - true
    d[..., 2] = -d[..., 2]  # heading = -yaw
    return (d + np.pi) % (2 * np.pi) - np.pi


def convergence_time(t: np.ndarray, error: np.ndarray, threshold: float) -> np.ndarray:
    """First time (B,) after which |error| (B, K) stays within threshold; t[-1] if never.
    A non-finite error (NaN, inf) is outside any band: an episode whose error is NaN at
    its last epoch never converged (t[-1]: the run's end, a time censored there, so that
    means and percentiles over episodes stay defined and a broken filter counts as the
    slowest, never as converged at once)."""
    outside = ~(np.abs(error) <= threshold)     # NaN <= threshold is False: outside
    last_out = np.where(outside.any(axis=1), outside.shape[1] - 1 - np.argmax(
        outside[:, ::-1], axis=1), -1)
    return t[np.minimum(last_out + 1, t.size - 1)]     # out at the last epoch: t[-1]


def nees(error: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared e^T P^-1 e for error (..., n), P (..., n, n)."""
    return np.einsum("...i,...i->...", error, np.linalg.solve(P, error[..., None])[..., 0])


STATUSES = ("converged", "not converged", "diverged", "lost")
"""An episode's alignment status, from the best to the worst (``StatusRule``)."""
FAILED = ("diverged", "lost")
"""The statuses that fail a run (``aligngym.testing.assert_alignment``, the claims)."""


@dataclass(frozen=True)
class StatusRule:
    """One status per episode from its final attitude error (E, N, U, rad; less the
    experiment's unmodelled floor where it has one) and the filter's own 1-sigma of it
    (docs/estimators.md, "Episode status"). In this order, the first that holds:

    - ``diverged``: the filter flagged numerical trouble (its reason kept), or its final
      error or sigma is not finite (NaN is never inside a bound);
    - ``lost``: |error| > ``lost_bound`` rad (10 deg) on an axis, whatever the sigma;
    - ``diverged``: |error| > ``ratio`` x 3 sigma and > ``floor`` rad (1') on an axis: the
      filter is wrong and confident;
    - ``not converged``: |error| > the experiment's convergence band on an axis, or the
      sigma > ``sigma_bound`` rad (pi: a Gaussian belief of an angle that says nothing):
      the error is large, but within 5 x the filter's own 3 sigma (not confidently
      wrong);
    - ``converged``: otherwise."""

    ratio: float = 5.0
    floor: float = 2.9088820866572157e-4      # 1 arcmin
    lost_bound: float = 0.17453292519943295    # 10 deg
    sigma_bound: float = np.pi

    def apply(self, final_error: np.ndarray, final_sigma: np.ndarray, band: float,
              flagged: np.ndarray, reasons: list[str]) -> tuple[np.ndarray, list[str]]:
        """Statuses (B,) (strings of ``STATUSES``) and their reasons ("" if converged)
        of final_error, final_sigma (B, 3) rad, with the convergence band (rad, every
        axis), the filter's flags (B,) and their reasons."""
        error = np.abs(final_error)
        broken = ~np.all(np.isfinite(error), axis=-1) | ~np.all(np.isfinite(final_sigma),
                                                                 axis=-1)
        lost = np.any(error > self.lost_bound, axis=-1)
        wrong = np.any((error > self.ratio * 3.0 * final_sigma) & (error > self.floor),
                       axis=-1)
        wide = np.any(final_sigma > self.sigma_bound, axis=-1)
        outside = np.any(error > band, axis=-1)
        status, out = [], []
        for b, flag_reason in enumerate(reasons):
            if flagged[b] or broken[b]:
                status.append("diverged")
                out.append(flag_reason if flagged[b] else "final error or sigma not finite")
            elif lost[b]:
                status.append("lost")
                out.append(f"final error > {np.degrees(self.lost_bound):g} deg")
            elif wrong[b]:
                status.append("diverged")
                out.append(f"final error > {self.ratio:g} x 3 sigma")
            elif wide[b] or outside[b]:
                status.append("not converged")
                out.append(f"attitude sigma > {np.degrees(self.sigma_bound):g} deg" if wide[b]
                           else f"final error > the {band / ARCMIN:g}' band")
            else:
                status.append("converged")
                out.append("")
        return np.array(status, dtype="<U13"), out


def status_fractions(status: np.ndarray) -> dict[str, float]:
    """{"converged_fraction", "not_converged_fraction", "diverged_fraction",
    "lost_fraction"}: the fraction of the episodes (status (B,)) in each status."""
    status = np.asarray(status)
    return {f"{s.replace(' ', '_')}_fraction": float(np.mean(status == s)) if status.size
            else 0.0 for s in STATUSES}


def static_alignment_floor(C_to_n: np.ndarray, gyro_bias: np.ndarray,
                           accel_bias: np.ndarray, lat: float, h: float = 0.0
                           ) -> np.ndarray:
    """The misalignment phi E, N, U (..., 3) rad that constant sensor biases leave in a
    static self-alignment (the physical floor): phi_E = -nabla_N/g, phi_N = nabla_E/g,
    phi_U = -eps_E/(Omega cos L) + phi_N tan L, with the gyro drift (rad/s) and the
    accelerometer bias (m/s^2) given in the frame C_to_n (..., 3, 3) maps to ENU, at
    latitude lat (rad) and height h (m)."""
    eps_n = np.einsum("...ij,...j->...i", C_to_n, gyro_bias)
    nabla_n = np.einsum("...ij,...j->...i", C_to_n, accel_bias)
    g = normal_gravity(lat, h)
    phi_N = nabla_n[..., 0] / g
    return np.stack([-nabla_n[..., 1] / g, phi_N,
                     -eps_n[..., 0] / (OMEGA_IE * np.cos(lat)) + phi_N * np.tan(lat)], -1)
