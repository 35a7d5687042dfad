"""Quaternion strapdown mechanization in ENU on a batch of episodes (leading axis B).

Per IMU interval of length T with increments (dtheta, dv) in the sensor frame:

- attitude: rotation vector with two-sample coning compensation,
  phi = dtheta + 1/12 dtheta_prev x dtheta, and q_b_n <- q(-omega_in T) q_b_n q(phi);
- velocity: the increment in the start-of-interval body frame,
  dv_b = integral of C_b(tau)^b(0) f dtau, is computed to second order in the rotation
  from the linear rate and specific-force models that the current and previous
  increments define (this contains the classical rotation and two-sample sculling
  terms, plus the second-order term ~1/6..1/12 dtheta x (dtheta x dv) that otherwise
  leaves ~1.6 ug under the dual-axis rotation at 100 Hz);
- gravity, Coriolis and the n-frame rotation at the mid-interval position and velocity
  (extrapolated), position by the trapezoid rule.

Here "b" is whatever frame the increments are in (the IMU sensor frame s on a gimbal).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aligngym.models.attitude import cross


@dataclass
class StrapdownState:
    """Navigation state of B episodes: q_b_n (B, 4); v_n (B, 3) m/s ENU; lat, lon (B,) rad;
    h (B,) m."""

    q_b_n: np.ndarray
    v_n: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray

    @classmethod
    def from_arrays(cls, q_b_n, v_n, lat, lon, h) -> "StrapdownState":
        q = np.atleast_2d(np.asarray(q_b_n, dtype=float)).copy()
        return cls(q, np.atleast_2d(np.asarray(v_n, dtype=float)).copy(),
                   np.atleast_1d(np.asarray(lat, dtype=float)).copy(),
                   np.atleast_1d(np.asarray(lon, dtype=float)).copy(),
                   np.atleast_1d(np.asarray(h, dtype=float)).copy())


def body_rate_at(dtheta: np.ndarray, dt: float, boundary) -> np.ndarray:
    """The body rate (..., K, 3) rad/s at increment boundaries (K,) (integers in [0, S]) of
    increments dtheta (..., S >= 2, 3) rad over intervals of dt s: the two intervals' mean
    rates nearest each boundary, interpolated (inside) or extrapolated linearly (at the
    ends, e.g. 1.5 r[S-1] - 0.5 r[S-2], r[j] the mean rate of interval j). Second order
    and without lag: a mean over the last 0.1 s lags by 0.05 s, which through a GNSS
    antenna's lever-arm velocity biased the heading of a boat rolling at 3 s periods by
    2.5 deg (measured on ideal sensors). ValueError for boundaries outside [0, S]."""
    rate = np.asarray(dtheta) / dt
    k = np.atleast_1d(np.asarray(boundary))
    S = rate.shape[-2]
    if S < 2 or k.min() < 0 or k.max() > S:
        raise ValueError(f"boundaries must lie in [0, {S}] of {S} >= 2 increments, got "
                         f"{k.min()}..{k.max()}")
    low = np.clip(k - 1, 0, S - 2)
    step = (k - (low + 0.5))[:, None]
    return rate[..., low, :] + step * (rate[..., low + 1, :] - rate[..., low, :])


def body_velocity_increment(dtheta: np.ndarray, dv: np.ndarray, dtheta_prev: np.ndarray,
                            dv_prev: np.ndarray) -> np.ndarray:
    """Velocity increment (..., 3) m/s resolved in the start-of-interval body frame.

    Fits omega(tau) = a + b tau and f(tau) = c + d tau (tau in [-1, 1], time normalised to
    the interval) to the previous and current increments and integrates
    [phi x f] + 1/2 [alpha x (alpha x f)] exactly, alpha(tau) = a tau + b tau^2 / 2 the
    integrated rate and phi = alpha + 1/2 int alpha x omega its rotation vector (Bortz): the
    coning part (a x b) tau^3 / 6 is of the order of the kept alpha x (alpha x f) (in the
    code's halved increments, (a x e) x (c / 24 + d / 30)).
    """
    a = 0.5 * (dtheta + dtheta_prev)
    e = 0.5 * (dtheta - dtheta_prev)
    c = 0.5 * (dv + dv_prev)
    d = dv - dv_prev
    ac, ad, ec, ed = cross(a, c), cross(a, d), cross(e, c), cross(e, d)
    first = ac / 2.0 + ad / 3.0 + ec / 3.0 + ed / 4.0
    second = 0.5 * (cross(a, ac) / 3.0 + cross(a, ad) / 4.0
                    + (cross(a, ec) + cross(e, ac)) / 4.0
                    + (cross(a, ed) + cross(e, ad)) / 5.0
                    + cross(e, ec) / 5.0 + cross(e, ed) / 6.0)
    coning = cross(cross(a, e), c / 24.0 + d / 30.0)
    return dv + first + second + coning


def coning_rotation_vector(dtheta: np.ndarray, dtheta_prev: np.ndarray) -> np.ndarray:
    """Attitude rotation vector (..., 3) rad of one interval, two-sample coning term."""
    return dtheta + cross(dtheta_prev, dtheta) / 12.0


def compensate(dtheta: np.ndarray, dv: np.ndarray, dtheta_first_prev: np.ndarray | None = None,
               dv_first_prev: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Coning and sculling/rotation compensation of a sequence of increments dtheta (rad)
    and dv (m/s), each (B, M, 3).

    The interval before the first uses the given increments, or the first ones (constant
    rate and force). Returns (phi, dv_b), each (B, M, 3): ``coning_rotation_vector`` and
    ``body_velocity_increment`` of each interval and the one before it, compiled
    (``strapdown_kernel.compensate_increments``, the same numbers).
    """
    from aligngym.estimators.strapdown_kernel import compensate_increments  # Numba
    dtheta = np.ascontiguousarray(dtheta, dtype=float)
    dv = np.ascontiguousarray(dv, dtype=float)
    if dtheta.ndim != 3 or dtheta.shape[-1] != 3 or dv.shape != dtheta.shape:
        raise ValueError(f"dtheta and dv must both be (B, M, 3), got {dtheta.shape} and "
                         f"{dv.shape}")
    phi, dv_b = np.empty_like(dtheta), np.empty_like(dv)
    if dtheta.shape[1] == 0:
        return phi, dv_b
    first = np.ascontiguousarray(dtheta[:, 0] if dtheta_first_prev is None
                                 else dtheta_first_prev, dtype=float)
    first_dv = np.ascontiguousarray(dv[:, 0] if dv_first_prev is None else dv_first_prev,
                                    dtype=float)
    if first.shape != dtheta[:, 0].shape or first_dv.shape != first.shape:
        raise ValueError(f"the increments before the first must be (B, 3) = "
                         f"{dtheta[:, 0].shape}, got {first.shape} and {first_dv.shape}")
    compensate_increments(dtheta, dv, first, first_dv, phi, dv_b)   # the formulas below
    return phi, dv_b


def _run(state: StrapdownState, a_n: np.ndarray, phi: np.ndarray, dv_b: np.ndarray,
         dt: float) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The compiled mechanization from a state over compensated increments (B, M, 3)."""
    B, M = phi.shape[:2]
    out = {"q_b_n": np.empty((B, M + 1, 4)), "v_n": np.empty((B, M + 1, 3)),
           "lat": np.empty((B, M + 1)), "lon": np.empty((B, M + 1)), "h": np.empty((B, M + 1))}
    a_end = np.empty((B, 3))
    from aligngym.estimators.strapdown_kernel import mechanize   # Numba: loaded when run
    mechanize(state.q_b_n, state.v_n, state.lat, state.lon, state.h, a_n,
               np.ascontiguousarray(phi, dtype=float), np.ascontiguousarray(dv_b, dtype=float),
               float(dt), out["q_b_n"], out["v_n"], out["lat"], out["lon"], out["h"], a_end)
    return out, a_end


class Strapdown:
    """Strapdown integrator for B episodes at a fixed IMU interval dt (s)."""

    def __init__(self, state: StrapdownState, dt: float) -> None:
        if not dt > 0.0:
            raise ValueError(f"dt must be > 0 s, got {dt}")
        self.state = state
        self.dt = float(dt)
        # the previous call's last increments (B, 3); NaN: none yet (an episode's first)
        self._dtheta_prev = np.full_like(state.v_n, np.nan)
        self._dv_prev = np.full_like(state.v_n, np.nan)
        self._a_n = np.zeros_like(state.v_n)

    def _previous(self, dtheta: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The increments before dtheta, dv (B, 3): the previous call's, or for an
        episode that has none yet its first ones again."""
        first = np.isnan(self._dtheta_prev[:, :1])
        if not first.any():
            return self._dtheta_prev, self._dv_prev
        return (np.where(first, dtheta, self._dtheta_prev),
                np.where(first, dv, self._dv_prev))

    def update(self, dtheta: np.ndarray, dv: np.ndarray) -> StrapdownState:
        """Advance one IMU interval with raw increments dtheta (B, 3) rad, dv (B, 3) m/s."""
        # first interval: assume constant rate and force
        dtheta_prev, dv_prev = self._previous(dtheta, dv)
        phi = coning_rotation_vector(dtheta, dtheta_prev)
        dv_b = body_velocity_increment(dtheta, dv, dtheta_prev, dv_prev)
        self._dtheta_prev, self._dv_prev = dtheta, dv
        return self.update_compensated(phi, dv_b)

    def run(self, dtheta: np.ndarray, dv: np.ndarray) -> dict[str, np.ndarray]:
        """Advance M intervals with raw increments (B, M, 3) (rad, m/s), coning and
        sculling compensated across the previous call's last increment; returns the
        trajectory at the M+1 boundaries (``run_strapdown``'s arrays, the first being
        the state before the call) and keeps the last state."""
        phi, dv_b = compensate(dtheta, dv, *self._previous(dtheta[:, 0], dv[:, 0]))
        self._dtheta_prev, self._dv_prev = dtheta[:, -1], dv[:, -1]
        out, self._a_n = _run(self.state, self._a_n, phi, dv_b, self.dt)
        self.state = StrapdownState(*(out[key][:, -1].copy() for key in
                                      ("q_b_n", "v_n", "lat", "lon", "h")))
        return out

    def update_compensated(self, phi: np.ndarray, dv_b: np.ndarray) -> StrapdownState:
        """Advance one interval with the compensated rotation vector phi (B, 3) rad and
        body-frame velocity increment dv_b (B, 3) m/s (see ``compensate``): the
        rotation of q_b_n by phi and by the n frame's turn, the velocity increment
        resolved in n at mid-interval, gravity, Coriolis and transport at the
        mid-interval position and (extrapolated) velocity, position by the trapezoid rule."""
        out, self._a_n = _run(self.state, self._a_n, phi[:, None], dv_b[:, None], self.dt)
        self.state = StrapdownState(out["q_b_n"][:, 1], out["v_n"][:, 1], out["lat"][:, 1],
                                    out["lon"][:, 1], out["h"][:, 1])
        return self.state


@dataclass
class AidedInsInputs:
    """What every aided fine-alignment model reads, for B episodes and K epochs of S IMU
    intervals: t (K+1,) s, the epoch boundaries; imu_dt s; dtheta, dv (B, K, S, 3) raw
    increments (rad, m/s, IMU frame); the INS start q_b_n0 (B, 4), v_n0 (B, 3) m/s ENU,
    lat0, lon0 (B,) rad, h0 (B,) m. Models add their aiding sensor's fields."""

    t: np.ndarray
    imu_dt: float
    dtheta: np.ndarray
    dv: np.ndarray
    q_b_n0: np.ndarray
    v_n0: np.ndarray
    lat0: np.ndarray
    lon0: np.ndarray
    h0: np.ndarray

    def strapdown(self) -> "AidedStrapdown":
        """The INS these inputs start."""
        return AidedStrapdown(self.q_b_n0, self.v_n0, self.lat0, self.lon0, self.h0,
                              self.imu_dt)


class AidedStrapdown(Strapdown):
    """The strapdown of an aided, closed-loop filter model: B episodes started from
    arrays, the increments compensated with the accumulated sensor-bias estimates
    gyro_bias (B, 3) rad/s and accel_bias (B, 3) m/s^2 before mechanization."""

    def __init__(self, q_b_n0: np.ndarray, v_n0: np.ndarray, lat0: np.ndarray,
                 lon0: np.ndarray, h0: np.ndarray, dt: float) -> None:
        super().__init__(StrapdownState.from_arrays(q_b_n0, v_n0, lat0, lon0, h0), dt)
        B = self.state.q_b_n.shape[0]
        self.gyro_bias = np.zeros((B, 3))
        self.accel_bias = np.zeros((B, 3))

    def run_compensated(self, dtheta: np.ndarray, dv: np.ndarray
                        ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
        """``run`` on the raw increments (B, M, 3) less the bias estimates; returns the
        trajectory and the compensated increments."""
        dtheta = dtheta - self.gyro_bias[:, None] * self.dt
        dv = dv - self.accel_bias[:, None] * self.dt
        return self.run(dtheta, dv), dtheta, dv


def run_strapdown(initial: StrapdownState, dtheta: np.ndarray, dv: np.ndarray, dt: float
                  ) -> dict[str, np.ndarray]:
    """Integrate increments (B, M, 3) (or (M, 3)) from the initial state; returns the
    trajectory at the M+1 interval boundaries: q_b_n (B, M+1, 4), v_n (B, M+1, 3),
    lat, lon, h (B, M+1).
    """
    if not dt > 0.0:
        raise ValueError(f"dt must be > 0 s, got {dt}")
    dtheta = np.asarray(dtheta, dtype=float)
    dv = np.asarray(dv, dtype=float)
    if dtheta.ndim == 2:
        dtheta, dv = dtheta[None], dv[None]
    phi, dv_b = compensate(dtheta, dv)
    return _run(initial, np.zeros_like(initial.v_n), phi, dv_b, dt)[0]
