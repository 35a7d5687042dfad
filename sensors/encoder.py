"""Gimbal angle encoders: a constant offset per episode and quantization to the resolution."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


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
