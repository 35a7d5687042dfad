"""Sensor plugins: IMU (gyro + accelerometer), gimbal encoders, odometer, GPS."""
from __future__ import annotations

from aligngym.models.checks import number_rows  # noqa: F401  (the sensors' tables use it)
