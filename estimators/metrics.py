"""Per-episode alignment metrics from an estimate, its covariance and the truth."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.models.attitude import dcm_to_euler, dcm_to_rotvec
from aligngym.models.earth import OMEGA_IE, normal_gravity


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
    """First time (B,) after which |error| (B, K) stays within threshold; t[-1] if never."""
    outside = np.abs(error) > threshold
    last_out = np.where(outside.any(axis=1), outside.shape[1] - 1 - np.argmax(
        outside[:, ::-1], axis=1), -1)
    idx = np.minimum(last_out + 1, t.size - 1)
    return np.where(last_out == t.size - 1, t[-1], t[idx])


def nees(error: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared e^T P^-1 e for error (..., n), P (..., n, n)."""
    return np.einsum("...i,...i->...", error, np.linalg.solve(P, error[..., None])[..., 0])


@dataclass(frozen=True)
class DivergenceRule:
    """An episode is diverged if the filter flagged numerical trouble; or its final
    attitude error exceeds ``ratio`` times its own 3-sigma bound on an axis and also
    ``floor`` rad (a filter lost while confident); or its final attitude sigma exceeds
    ``sigma_bound`` rad on an axis (a filter lost and knowing it: past pi its Gaussian
    belief says nothing about an angle, and the first test can no longer fire; a NaN
    sigma counts); or its final error is not finite (NaN is never inside a bound)."""

    ratio: float = 5.0
    floor: float = 2.9088820866572157e-4  # 1 arcmin
    sigma_bound: float = np.pi

    def apply(self, final_error: np.ndarray, final_sigma: np.ndarray,
              flagged: np.ndarray, reasons: list[str]) -> tuple[np.ndarray, list[str]]:
        lost = np.any((np.abs(final_error) > self.ratio * 3.0 * final_sigma)
                      & (np.abs(final_error) > self.floor), axis=-1)
        blown = np.any(~(final_sigma <= self.sigma_bound), axis=-1)   # NaN counts
        broken = np.any(~np.isfinite(final_error), axis=-1)          # never "inside"
        out = [r if f else ("final error not finite" if n else
                            f"final error > {self.ratio:g} x 3 sigma" if l else
                            f"attitude sigma > {np.degrees(self.sigma_bound):g} deg"
                            if b else "")
               for f, n, l, b, r in zip(flagged, broken, lost, blown, reasons)]
        return flagged | broken | lost | blown, out


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
