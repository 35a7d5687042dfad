"""Wheel odometer from the simulated wheel encoders: pulses per revolution, nominal versus
effective wheel radius, scale-factor error dK_D and mounting angles to the IMU."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aligngym.sensors import number_rows
from aligngym.sensors.base import Sensor, SensorRecord, SensorTruth, register_sensor


@dataclass(frozen=True)
class OdometerSpec:
    """pulses_per_rev: encoder resolution; nominal_radius: the wheel radius the odometer
    assumes, m; scale_error: dK_D, the odometer's relative scale-factor error (fixed);
    scale_error_sigma: 1 sigma of dK_D drawn per episode instead (0: use scale_error);
    mounting_pitch, mounting_heading: the IMU case's mounting on the chassis, rad: the
    simulation turns the IMU axes by C_s^b = Rz(heading) Rx(pitch) from the chassis (the
    odometer's) axes, so the odometer velocity in the IMU frame is
    C_b^s [0, v, 0] (the distance is unaffected); slips: faults (time s, duration s,
    extra m): a driven wheel spins, the odometer counting ``extra`` metres more than the
    car travels, spread evenly over the burst (and kept after it)."""

    pulses_per_rev: int = 1024
    nominal_radius: float = 0.33
    scale_error: float = 0.003
    scale_error_sigma: float = 0.0
    mounting_pitch: float = math.radians(0.5)
    mounting_heading: float = math.radians(0.5)
    slips: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "slips", number_rows(self.slips, 3, "odometer.slips",
                                                      "(time_s, duration_s, extra_m)"))
        if any(duration <= 0.0 for _, duration, _ in self.slips):
            raise ValueError("odometer.slips: each burst's duration_s must be > 0")
        if not (isinstance(self.pulses_per_rev, int) and self.pulses_per_rev >= 1):
            raise ValueError(f"odometer.pulses_per_rev must be an integer >= 1, got "
                             f"{self.pulses_per_rev}")
        if not self.nominal_radius > 0.0:
            raise ValueError(f"odometer.nominal_radius must be > 0 m, got {self.nominal_radius}")
        for name in ("mounting_pitch", "mounting_heading"):
            value = getattr(self, name)
            if not (math.isfinite(value) and abs(value) <= math.radians(10.0)):
                raise ValueError(f"odometer.{name} must be within +-10 deg, got "
                                 f"{math.degrees(value):g} deg")
        if not abs(self.scale_error) < 0.5:
            raise ValueError(f"odometer.scale_error must be in (-0.5, 0.5), got "
                             f"{self.scale_error}")

    def draw_scale_error(self, rng: np.random.Generator) -> float:
        """dK_D of one episode."""
        if self.scale_error_sigma > 0.0:
            return float(self.scale_error_sigma * rng.standard_normal())
        return self.scale_error

    def distance(self, wheel_angles: np.ndarray, scale_error: float,
                 t: np.ndarray | None = None) -> np.ndarray:
        """Cumulative distance (N,) m from the driven wheels' unwrapped angles (N, k) rad at
        times t (N,) s: the mean wheel angle (with the slip bursts' extra spin) counted in
        whole pulses, times the nominal circumference, times (1 + dK_D)."""
        angle = np.mean(wheel_angles, axis=1) - np.mean(wheel_angles[0])
        for start, duration, extra in (self.slips if t is not None else ()):
            angle = angle + extra / self.nominal_radius * np.clip((t - start) / duration,
                                                                   0.0, 1.0)
        pulses = np.floor(angle / (2 * math.pi) * self.pulses_per_rev)
        return pulses / self.pulses_per_rev * 2 * math.pi * self.nominal_radius * (
            1.0 + scale_error)


ODOMETER_PRESETS = {
    # 000: scale-factor error, encoder quantization, mounting pitch/heading (values assumed).
    "paper000": OdometerSpec(),
}


@dataclass(frozen=True)
class OdometerDistance(SensorRecord):
    """The odometer's cumulative distance (N+1,) m at the times t (N+1,) s (the IMU
    interval boundaries), the episode's scale-factor error dK_D and the IMU case's
    mounting (pitch, heading) rad on the chassis."""

    PREFIX = "odo_"
    t: np.ndarray
    distance: np.ndarray
    scale_error: np.ndarray
    mounting: np.ndarray


@register_sensor
class WheelOdometer(Sensor):
    """The car's wheel odometer ([odometer]): the driven wheels' encoder pulses."""

    section = "odometer"
    spec_type = OdometerSpec
    units = {"pulses_per_rev": "", "nominal_radius": "_m", "scale_error": "",
             "scale_error_sigma": "", "mounting_pitch": "_deg", "mounting_heading": "_deg",
             "slips": ""}
    presets = ODOMETER_PRESETS
    needs = frozenset({"wheels"})
    stream = "odometer"

    def check(self, duration: float, imu_rate: float, world: str) -> None:
        for when, burst, _ in self.spec.slips:
            if not 0.0 <= when <= duration - burst:
                raise ValueError(f"odometer.slips time = {when:g} s is out of range "
                                 f"[0, {duration - burst:g}]")

    def measure(self, truth: SensorTruth, rng: np.random.Generator, ideal: bool
                ) -> OdometerDistance:
        odo, t = self.spec, truth.truth.t
        scale = 0.0 if ideal else odo.draw_scale_error(rng)
        return OdometerDistance(
            t=t, distance=odo.distance(truth.rear_wheels, scale, t),
            scale_error=np.array(scale),
            mounting=np.array([odo.mounting_pitch, odo.mounting_heading]))

    def faults(self, record: SensorRecord, duration: float
               ) -> list[tuple[str, float, float]]:
        return [("odometer_slip", start, start + burst) for start, burst, _ in self.spec.slips]
