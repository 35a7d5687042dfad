"""Field units to SI. Multiply a value in the named unit to get SI; divide to convert back.

SI inside the code: rad, rad/s, m/s^2, m/s, s. Noise densities:
gyro angle random walk in rad/sqrt(s), accelerometer velocity random walk in m/s/sqrt(s).
"""
import math

G0 = 9.80665
"""Standard gravity for g-based units (ug, mg), m/s^2."""

deg = math.pi / 180.0
arcmin = deg / 60.0
arcsec = deg / 3600.0
hour = 3600.0

deg_per_h = deg / hour
"""Gyro bias, deg/h -> rad/s."""
deg_per_sqrt_h = deg / math.sqrt(hour)
"""Angle random walk, deg/sqrt(h) -> rad/sqrt(s)."""
deg_per_h_per_sqrt_hz = deg_per_h
"""Gyro white-noise density, deg/h/sqrt(Hz) -> rad/s/sqrt(Hz) = rad/sqrt(s)."""

mg = 1e-3 * G0
ug = 1e-6 * G0
ug_per_sqrt_hz = ug
"""Accelerometer white-noise density, ug/sqrt(Hz) -> m/s^2/sqrt(Hz) = m/s/sqrt(s)."""
m_per_s_per_sqrt_h = 1.0 / math.sqrt(hour)
"""Velocity random walk, m/s/sqrt(h) -> m/s/sqrt(s)."""
ppm = 1e-6
