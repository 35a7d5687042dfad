"""The car's parameters: geometry (m), masses (kg), suspension and tyres, and the
instruments' offsets on the chassis (``models.car`` builds the car from them)."""
from __future__ import annotations

import math
from dataclasses import dataclass

WHEEL_CENTRE_Z = -0.25
"""Wheel centres below the chassis origin at rest, m."""


@dataclass(frozen=True)
class CarParams:
    """Car geometry (m), masses (kg), suspension and tyres. imu_offset_b: IMU site from the
    chassis origin in the body frame (R, F, U), m."""

    wheelbase: float = 2.7
    track: float = 1.6
    wheel_radius: float = 0.33
    wheel_width: float = 0.22
    chassis_mass: float = 1400.0
    wheel_mass: float = 20.0
    suspension_stiffness: float = 7.0e4
    suspension_damping: float = 4.0e3
    tyre_friction: float = 1.0
    max_steer: float = math.radians(35.0)
    imu_offset_b: tuple[float, float, float] = (0.0, 0.3, 0.2)
    gps_antenna_b: tuple[float, float, float] = (0.0, -0.5, 1.2)
    roughness_rms: float = 0.0
    """Road roughness (heightfield) RMS height, m; 0 for a smooth plane."""
    gimbal: bool = False
    """The IMU rides a double-axis gimbal (drawn only: its motion is analytic)."""

    @property
    def rear_axle_b(self) -> tuple[float, float, float]:
        """Centre of the rear axle from the chassis origin (R, F, U), m, at rest: the
        point of the body whose velocity is along the body's forward axis when the
        rear tyres do not slip."""
        return (0.0, -self.wheelbase / 2, WHEEL_CENTRE_Z)
