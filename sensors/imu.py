"""IMU: ideal angle and velocity increments from the truth, and the datasheet error model.

Three separate objects, as pyins does:

- ``ImuSpec``: the datasheet (1-sigma values and densities, SI units in the docstrings);
- ``ImuRealization``: what one episode's IMU actually has (drawn from the spec with a
  ``numpy.random.Generator``, or fixed by the scenario);
- ``ImuTuning``: what a filter believes (built from the spec by default, editable).

Increments are in the IMU sensor frame s: ``dtheta`` (rad) is the integral of the
inertial angular rate and ``dv`` (m/s) the integral of the specific force over each
IMU interval, as a real IMU outputs them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cache

import numpy as np

from aligngym.models.units import deg_per_h, deg_per_sqrt_h, m_per_s_per_sqrt_h, mg, ug

__all__ = ["TriadSpec", "ImuSpec", "TriadRealization", "ImuRealization", "ImuTuning",
           "ideal_increments", "apply_imu_errors", "IMU_PRESETS", "gauss_markov_sigma"]


@cache
def gm_adev_peak() -> float:
    """Peak of the Allan deviation of a unit-variance first-order Gauss-Markov process.

    sigma_A^2(tau) = 2 sigma^2 / x [1 - (3 - 4 e^-x + e^-2x) / (2x)], x = tau / T_c;
    the peak (0.6174 at x ~ 1.89) does not depend on T_c. Computed on first use (a
    200001-point grid: 8 ms that importing the sensors need not pay).
    """
    x = np.linspace(0.5, 6.0, 200001)
    adev2 = 2.0 / x * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))
    return float(np.sqrt(adev2.max()))


FLICKER_FLOOR_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
"""Allan-deviation floor of flicker bias noise per unit bias instability (0.664)."""


def gauss_markov_sigma(bias_instability: float) -> float:
    """Steady-state sigma of the Gauss-Markov process whose Allan-deviation peak equals the
    datasheet floor 0.664 x bias_instability (same units as the input)."""
    return FLICKER_FLOOR_FACTOR * bias_instability / gm_adev_peak()


@dataclass(frozen=True)
class TriadSpec:
    """Datasheet of three identical orthogonal sensors (gyros or accelerometers).

    Units: gyro / accelerometer.
    bias_sigma: random-constant bias, 1 sigma, drawn per episode; rad/s / m/s^2.
    bias_fixed: bias used instead of a draw, (3,), rad/s / m/s^2; None to draw.
    white_noise_density: angle / velocity random walk; rad/sqrt(s) / m/s/sqrt(s).
    bias_instability: datasheet bias instability (Allan floor / 0.664), modelled as a
        first-order Gauss-Markov process with correlation time ``correlation_time`` (s);
        rad/s / m/s^2.
    random_walk: rate / acceleration random walk; rad/s/sqrt(s) / m/s^2/sqrt(s).
    scale_factor_sigma: 1 sigma, dimensionless. misalignment_sigma: 1 sigma per
        off-diagonal element, rad.
    quantization: one output LSB of the increment; rad / m/s; 0 for none.
    measurement_range: saturation of the rate / specific force; rad/s / m/s^2.
    """

    bias_sigma: float = 0.0
    bias_fixed: tuple[float, float, float] | None = None
    white_noise_density: float = 0.0
    bias_instability: float = 0.0
    correlation_time: float = 100.0
    random_walk: float = 0.0
    scale_factor_sigma: float = 0.0
    misalignment_sigma: float = 0.0
    quantization: float = 0.0
    measurement_range: float = math.inf

    def __post_init__(self) -> None:
        for name in ("bias_sigma", "white_noise_density", "bias_instability", "random_walk",
                     "scale_factor_sigma", "misalignment_sigma", "quantization"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")
        if not self.correlation_time > 0.0:
            raise ValueError(f"correlation_time must be > 0 s, got {self.correlation_time}")
        if not self.measurement_range > 0.0:
            raise ValueError(f"measurement_range must be > 0, got {self.measurement_range}")
        if self.bias_fixed is not None and len(self.bias_fixed) != 3:
            raise ValueError("bias_fixed must have 3 components")

    def error_terms(self) -> set[str]:
        """Names of the error terms this spec switches on."""
        terms = {name for name in ("bias_sigma", "white_noise_density", "bias_instability",
                                   "random_walk", "scale_factor_sigma", "misalignment_sigma",
                                   "quantization") if getattr(self, name) > 0.0}
        if self.bias_fixed is not None:
            terms.add("bias_fixed")
        if math.isfinite(self.measurement_range):
            terms.add("measurement_range")
        return terms

    def draw(self, rng: np.random.Generator) -> "TriadRealization":
        """Per-episode values: random-constant bias, scale factors, misalignment."""
        bias = (np.asarray(self.bias_fixed, dtype=float) if self.bias_fixed is not None
                else self.bias_sigma * rng.standard_normal(3))
        scale = self.scale_factor_sigma * rng.standard_normal(3)
        misalignment = self.misalignment_sigma * rng.standard_normal((3, 3))
        np.fill_diagonal(misalignment, 0.0)
        return TriadRealization(bias=bias, scale_factor=scale, misalignment=misalignment)


@dataclass(frozen=True)
class ImuSpec:
    """Gyro and accelerometer datasheets."""

    gyro: TriadSpec = field(default_factory=TriadSpec)
    accel: TriadSpec = field(default_factory=TriadSpec)

    def draw(self, rng: np.random.Generator) -> "ImuRealization":
        """One episode's IMU."""
        return ImuRealization(gyro=self.gyro.draw(rng), accel=self.accel.draw(rng))


@dataclass(frozen=True)
class TriadRealization:
    """Drawn errors of one triad: bias (3,) rad/s or m/s^2; scale_factor (3,);
    misalignment (3, 3) rad, zero diagonal. Output = (I + diag(scale) + misalignment) x."""

    bias: np.ndarray
    scale_factor: np.ndarray
    misalignment: np.ndarray

    @property
    def error_matrix(self) -> np.ndarray:
        """(I + diag(scale) + misalignment), (3, 3)."""
        return np.eye(3) + np.diag(self.scale_factor) + self.misalignment


@dataclass(frozen=True)
class ImuRealization:
    gyro: TriadRealization
    accel: TriadRealization


@dataclass(frozen=True)
class ImuTuning:
    """A filter's belief about the IMU, SI: bias sigmas (rad/s, m/s^2) and white-noise
    densities (rad/sqrt(s), m/s/sqrt(s))."""

    gyro_bias_sigma: float
    gyro_noise_density: float
    accel_bias_sigma: float
    accel_noise_density: float

    @classmethod
    def from_spec(cls, spec: ImuSpec) -> "ImuTuning":
        """Tuning equal to the datasheet (bias instability folded into the bias sigma)."""
        return cls(gyro_bias_sigma=math.hypot(spec.gyro.bias_sigma, spec.gyro.bias_instability),
                   gyro_noise_density=spec.gyro.white_noise_density,
                   accel_bias_sigma=math.hypot(spec.accel.bias_sigma,
                                               spec.accel.bias_instability),
                   accel_noise_density=spec.accel.white_noise_density)

    def scaled(self, **factors: float) -> "ImuTuning":
        """Copy with fields multiplied by the given factors (a deliberately mistuned filter)."""
        return replace(self, **{k: getattr(self, k) * v for k, v in factors.items()})


def ideal_increments(t: np.ndarray, omega_is_s: np.ndarray, f_s: np.ndarray,
                     decimation: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ideal IMU increments from the inertial rate omega_is_s (N, 3) rad/s and specific
    force f_s (N, 3) m/s^2 sampled uniformly at times t (N,) s, ``decimation`` x the
    IMU rate.

    Composite Simpson's rule over each IMU interval (decimation must be even): the error is
    O(h^4) of the rate's fourth derivative, ~1e-13 rad per interval for ship motion.
    Returns imu_t (M,) s, the end time of each interval; dtheta (M, 3) rad; dv (M, 3) m/s.
    """
    if decimation < 2 or decimation % 2:
        raise ValueError(f"decimation must be an even integer >= 2, got {decimation}")
    n = t.size - 1
    if np.shape(omega_is_s) != (t.size, 3) or np.shape(f_s) != (t.size, 3):
        raise ValueError(f"omega_is_s and f_s must be ({t.size}, 3) like t, got "
                         f"{np.shape(omega_is_s)} and {np.shape(f_s)}")
    if n < decimation or n % decimation:
        raise ValueError(f"truth must have k*{decimation}+1 samples, got {t.size}")
    h = np.diff(t)
    if not np.allclose(h, h[0], rtol=1e-9, atol=0.0):
        raise ValueError("truth samples must be uniformly spaced")
    h = (t[-1] - t[0]) / n
    weights = np.ones(decimation + 1)
    weights[1:-1:2] = 4.0
    weights[2:-1:2] = 2.0
    weights *= h / 3.0

    def integrate(x: np.ndarray) -> np.ndarray:
        m = n // decimation
        idx = np.arange(m)[:, None] * decimation + np.arange(decimation + 1)
        return np.einsum("j,mjk->mk", weights, x[idx])

    return t[decimation::decimation], integrate(omega_is_s), integrate(f_s)


def _triad_errors(x: np.ndarray, dt: float, spec: TriadSpec, real: TriadRealization,
                  rng: np.random.Generator, bias_rotation: np.ndarray | None = None,
                  white_noise: np.ndarray | None = None) -> np.ndarray:
    """Increments x (M, 3) with the triad's errors applied; bias_rotation (M, 3, 3): the
    constant bias is constant in another frame and rotated into the sensor frame per
    interval (None: constant in the sensor frame); white_noise (M,): the white-noise
    density per interval where a schedule changes it (None: the spec's)."""
    m = x.shape[0]
    bias = real.bias if bias_rotation is None else np.einsum("mij,j->mi", bias_rotation,
                                                            real.bias)
    y = x @ real.error_matrix.T + bias * dt
    if white_noise is not None:
        y += white_noise[:, None] * math.sqrt(dt) * rng.standard_normal((m, 3))
    elif spec.white_noise_density > 0.0:
        y += spec.white_noise_density * math.sqrt(dt) * rng.standard_normal((m, 3))
    if spec.bias_instability > 0.0:
        sigma = gauss_markov_sigma(spec.bias_instability)
        phi = math.exp(-dt / spec.correlation_time)
        drive = sigma * math.sqrt(1.0 - phi * phi) * rng.standard_normal((m, 3))
        drive[0] = sigma * rng.standard_normal(3)
        from scipy.signal import lfilter   # lazy: reading a scenario stays light
        y += dt * lfilter([1.0], [1.0, -phi], drive, axis=0)
    if spec.random_walk > 0.0:
        steps = spec.random_walk * math.sqrt(dt) * rng.standard_normal((m, 3))
        y += dt * np.cumsum(steps, axis=0)
    if math.isfinite(spec.measurement_range):
        y = np.clip(y, -spec.measurement_range * dt, spec.measurement_range * dt)
    if spec.quantization > 0.0:
        # Pulse output: the running sum is quantized, the residual carries over.
        total = np.floor(np.cumsum(y, axis=0) / spec.quantization) * spec.quantization
        y = np.diff(total, axis=0, prepend=np.zeros((1, 3)))
    return y


def apply_imu_errors(dtheta: np.ndarray, dv: np.ndarray, dt: float, spec: ImuSpec,
                     realization: ImuRealization, rng: np.random.Generator,
                     bias_rotation: np.ndarray | None = None,
                     white_noise: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Measured increments from ideal ones (M, 3) at interval dt (s). bias_rotation
    (M, 3, 3), optional: the drawn constant biases are constant in a frame h and
    C_h^s over each interval rotates them into the sensor frame (e.g. h = the hull of a
    rotary IMU: no modulation). white_noise: the gyro's and the accelerometer's
    white-noise density per interval (M,) where a schedule changes it (a vibration
    burst), else None (the spec's)."""
    if not dt > 0.0:
        raise ValueError(f"dt must be > 0 s, got {dt}")
    return (_triad_errors(dtheta, dt, spec.gyro, realization.gyro, rng, bias_rotation,
                          white_noise[0]),
            _triad_errors(dv, dt, spec.accel, realization.accel, rng, bias_rotation,
                          white_noise[1]))


# Paper presets: exactly the terms each paper states (SPEC section 4; noise per section 2:
# "random drift x" is white noise whose 1-s average has sigma x, i.e. density x/sqrt(Hz)).
IMU_PRESETS: dict[str, ImuSpec] = {
    "paper000-fog": ImuSpec(
        gyro=TriadSpec(bias_sigma=0.02 * deg_per_h, white_noise_density=0.01 * deg_per_h),
        accel=TriadSpec(bias_sigma=1e-4 * 9.8, white_noise_density=1e-5 * 9.8)),
    "paper001-van": ImuSpec(
        gyro=TriadSpec(bias_sigma=1.0 * deg_per_h, white_noise_density=0.1 * deg_per_sqrt_h),
        accel=TriadSpec(bias_sigma=1e-5)),
    "paper002-static": ImuSpec(
        gyro=TriadSpec(bias_sigma=0.01 * deg_per_h, white_noise_density=0.01 * deg_per_h),
        accel=TriadSpec(bias_sigma=50 * ug)),
    "paper003-rotary": ImuSpec(
        gyro=TriadSpec(bias_sigma=0.01 * deg_per_h, white_noise_density=0.001 * deg_per_h),
        accel=TriadSpec(bias_sigma=100 * ug, white_noise_density=10 * ug)),
    "paper004-mems": ImuSpec(
        gyro=TriadSpec(bias_sigma=2.0 * deg_per_h, white_noise_density=0.1 * deg_per_sqrt_h),
        accel=TriadSpec(bias_sigma=2 * mg,
                        white_noise_density=0.03 * m_per_s_per_sqrt_h)),
}
