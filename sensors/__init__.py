"""Sensor plugins: IMU (gyro + accelerometer), gimbal encoders; later odometer and GPS."""
