"""The world: units, WGS-84 earth, frames and attitude, MuJoCo bodies and their motion."""
import os

# Off-screen rendering by default (the testbed runs headless); set MUJOCO_GL before
# importing to choose another backend.
os.environ.setdefault("MUJOCO_GL", "egl")
