"""The double-axis gimbal under the IMU: its motion relative to the carrier body b and
the sensor frame s it turns.

Outer axis about body z, inner about x: C_s_b = Rz(outer) Rx(inner); times in s, angles
in rad, rates in rad/s, accelerations in rad/s^2. ``GimbalRates`` is the mixin of the
motions whose gimbal turns at constant rates (or follows an azimuth indexer,
``models.indexer``); ``stalled`` injects stalls (fault injection); ``gimbal_C_s_b`` and
``gimbal_rate_in_sensor`` give the sensor frame's attitude and rate relative to b.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from aligngym.models.attitude import rot_x, rot_z


GimbalMotion = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""The double-axis gimbal's motion relative to the carrier: times t (N,) s -> angles
(rad), angle rates (rad/s) and angle accelerations (rad/s^2), (N, 2) each (outer about
body z, inner about x; C_s_b = Rz(outer) Rx(inner))."""


STALL_RAMP = 0.2
"""s: a stalled gimbal decelerates to rest, and later re-accelerates, over this time
(a septic smoothstep; with the catch-up, built from its derivative, the angles keep
three continuous derivatives)."""
STALL_CATCH_UP = 2.0
"""After a stall of duration d the gimbal catches up with its schedule over
STALL_CATCH_UP x d (s), at up to 1 + 2.19 / STALL_CATCH_UP times its scheduled rate."""


def smoothstep(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The septic smoothstep S(x) = 35x^4 - 84x^5 + 70x^6 - 20x^7 on [0, 1] (0 before, 1
    after; its first three derivatives vanish at both ends), its derivatives
    S'(x) = 140 x^3 (1 - x)^3 and S''(x) = 420 x^2 (1 - x)^2 (1 - 2x), and its integral
    from 0 (1/2 + (x - 1) beyond 1)."""
    inside = np.clip(x, 0.0, 1.0)
    value = inside ** 4 * (35.0 + inside * (-84.0 + inside * (70.0 - 20.0 * inside)))
    slope = 140.0 * inside ** 3 * (1.0 - inside) ** 3
    curvature = 420.0 * inside ** 2 * (1.0 - inside) ** 2 * (1.0 - 2.0 * inside)
    integral = (inside ** 5 * (7.0 + inside * (-14.0 + inside * (10.0 - 2.5 * inside)))
                + np.maximum(x - 1.0, 0.0))
    return value, slope, curvature, integral


def stalled(motion: GimbalMotion, stalls: tuple[tuple[float, float], ...]) -> GimbalMotion:
    """The gimbal ``motion`` with stalls (start s, duration d s; d >= STALL_RAMP): in
    each, every axis stops (a STALL_RAMP deceleration from the start) and stays until
    start + d, then re-accelerates and catches up with its schedule over
    STALL_CATCH_UP x d, as a servo following its command does (a stall of an axis at
    rest changes nothing). A time warp tau(t) with weight w = dtau/dt >= 0:
    angle = base(tau), rate = base_rate(tau) w,
    acceleration = base_accel(tau) w^2 + base_rate(tau) w'."""
    if not stalls:
        return motion

    def state(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        tau, w, dw = t.copy(), np.ones_like(t), np.zeros_like(t)
        for start, duration in stalls:
            for sign, edge in ((1.0, start), (-1.0, start + duration)):    # the stop
                value, slope, _, integral = smoothstep((t - edge) / STALL_RAMP)
                tau -= sign * STALL_RAMP * integral
                w -= sign * value
                dw -= sign * slope / STALL_RAMP
            catch_up = STALL_CATCH_UP * duration                           # the lag made up
            value, slope, curvature, _ = smoothstep((t - start - duration) / catch_up)
            tau += duration * value
            w += duration / catch_up * slope
            dw += duration / catch_up ** 2 * curvature
        angle, rate, accel = motion(tau)
        return angle, rate * w[:, None], accel * (w ** 2)[:, None] + rate * dw[:, None]

    return state


class GimbalRates:
    """Mixin for motions that carry ``gimbal_outer_rate`` and ``gimbal_inner_rate`` (rad/s):
    the double-axis gimbal under the IMU (outer about body z, inner about x,
    C_s_b = Rz(outer) Rx(inner)), turning at constant rates from zero at t = 0."""

    gimbal_outer_rate: float
    gimbal_inner_rate: float
    indexer = None
    """A single-axis azimuth indexer on the outer axis instead (``models.indexer``), where
    the motion has one."""
    gimbal_stalls: tuple[tuple[float, float], ...] = ()
    """Injected stalls (start s, duration s) of the gimbal, where the motion has the field
    (the scenario's [faults] gimbal_stalls; ``stalled``)."""

    @property
    def has_gimbal(self) -> bool:
        return (self.indexer is not None or self.gimbal_outer_rate != 0.0
                or self.gimbal_inner_rate != 0.0)

    def check_indexer(self) -> None:
        """ValueError if an indexer and constant gimbal rates are both given."""
        if self.indexer is not None and (self.gimbal_outer_rate or self.gimbal_inner_rate):
            raise ValueError("motion: with an [indexer] the gimbal rates "
                             "(gimbal_outer_rate_deg_s, gimbal_inner_rate_deg_s) must be 0")

    def gimbal_angles(self, t: np.ndarray) -> np.ndarray:
        """Gimbal angles (N, 2) rad (outer, inner) at times t (N,) s."""
        t = np.asarray(t, dtype=float)
        return np.stack([self.gimbal_outer_rate * t, self.gimbal_inner_rate * t], -1)

    def gimbal_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The gimbal's motion (``GimbalMotion``) at times t (N,) s: the constant rates,
        with the motion's gimbal stalls (fault injection, ``stalled``)."""
        return stalled(self._constant_rates, self.gimbal_stalls)(t)

    def _constant_rates(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        zeros = np.zeros((t.size, 2))
        rates = np.array([self.gimbal_outer_rate, self.gimbal_inner_rate])
        return self.gimbal_angles(t), zeros + rates, zeros

    def expected_gimbal_angles(self, t: np.ndarray) -> np.ndarray:
        """The angles (N, 2) rad a pipeline expects the encoders to read (less their
        offsets) at times t (N,) s, from the commands alone: the constant rates, or the
        indexer servo's response to its command on a fixed base (MuJoCo's servo without
        the hull's excitation, once per process; the inner axis at rest). A stalled
        gimbal falls behind them (``estimators.screen.screen_gimbal``)."""
        t = np.asarray(t, dtype=float)
        if self.indexer is None:
            return self.gimbal_angles(t)
        from aligngym.models.indexer import indexer_run
        return np.stack([indexer_run(self.indexer, t).state(t)[0], np.zeros(t.size)], -1)


def gimbal_C_s_b(angles: np.ndarray) -> np.ndarray:
    """C_s^b (..., 3, 3) = Rz(outer) Rx(inner) of the double-axis gimbal at angles (..., 2)
    rad (outer, inner)."""
    return rot_z(angles[..., 0]) @ rot_x(angles[..., 1])


def gimbal_rate_in_sensor(angle_rates: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """omega_bs^s (..., 3) rad/s of the double-axis gimbal from its angle rates (..., 2)
    rad/s (outer, inner) at inner angles (...) rad:
    omega_bs^s = Rx(inner)^T [0, 0, outer_rate] + [inner_rate, 0, 0]."""
    outer_rate, inner_rate = angle_rates[..., 0], angle_rates[..., 1]
    return np.stack([inner_rate, np.sin(inner) * outer_rate, np.cos(inner) * outer_rate], -1)
