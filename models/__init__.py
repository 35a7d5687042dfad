"""The world: units, WGS-84 earth, frames and attitude, MuJoCo bodies and their motion."""
