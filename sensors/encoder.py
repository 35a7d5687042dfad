"""Gimbal angle encoders: a constant offset per episode and quantization to the resolution."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aligngym.sensors.base import Sensor, SensorRecord, SensorTruth, register_sensor


@dataclass(frozen=True)
class GimbalEncoderSpec:
    """resolution: one count, rad (0 for an ideal encoder); offset_sigma: zero-offset
    1 sigma per axis, rad, drawn per episode."""

    resolution: float = 2 * math.pi / 2 ** 20
    offset_sigma: float = 0.0

    def __post_init__(self) -> None:
        for name in ("resolution", "offset_sigma"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0 rad, got {value}")

    def draw_offsets(self, rng: np.random.Generator, axes: int = 2) -> np.ndarray:
        """Zero offsets (axes,) rad of one episode."""
        return self.offset_sigma * rng.standard_normal(axes)

    def measure(self, angles: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """Encoder readings (N, axes) rad of true angles (N, axes) rad."""
        reading = np.asarray(angles, dtype=float) + offsets
        if self.resolution > 0.0:
            reading = np.round(reading / self.resolution) * self.resolution
        return reading


@dataclass(frozen=True)
class EncoderAngles(SensorRecord):
    """The gimbal encoders' readings (N+1, 2) rad (outer, inner) at the IMU interval
    boundaries: the true angles where the IMU has no gimbal or the data are ideal."""

    NAMES = {"angles": "gimbal_encoder"}
    angles: np.ndarray


@register_sensor
class GimbalEncoders(Sensor):
    """The gimbal's angle encoders ([encoder]; every scenario has them
    (``ScenarioConfig.sensor_specs``), with the default 20-bit spec when the file has no
    table)."""

    section = "encoder"
    spec_type = GimbalEncoderSpec
    units = {"resolution": "_arcsec", "offset_sigma": "_arcsec"}
    stream = "encoder"

    def measure(self, truth: SensorTruth, rng: np.random.Generator, ideal: bool
                ) -> EncoderAngles:
        angles = truth.truth.gimbal_angles
        if ideal or not truth.has_gimbal:
            return EncoderAngles(angles.copy())
        return EncoderAngles(self.spec.measure(angles, self.spec.draw_offsets(rng)))
