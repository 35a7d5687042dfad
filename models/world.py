"""A MuJoCo world with prescribed (kinematic) motion, read out through MuJoCo's sensors.

MuJoCo's world frame is the earth-fixed tangent plane ``t`` (ENU axes at the scenario
origin). A prescribed world writes analytic joint positions, velocities and
accelerations, runs MuJoCo's kinematics, velocity and acceleration passes (the
sensor-relevant part of ``mj_inverse``) and reads the IMU site's pose, velocity, gyro
and accelerometer. Those are exact to rounding (gyro to ~1e-12 rad/s).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import mujoco
import numpy as np

from models.attitude import quat_rotate


@dataclass(frozen=True)
class WorldSamples:
    """Kinematics of the IMU site and the carrier body at sample times, in plane frame t.

    t: (N,) s. r_t, v_t, a_t: (N, 3) IMU position (m), velocity (m/s) and acceleration
    (m/s^2) relative to the earth-fixed plane. q_s_t, q_b_t: (N, 4) IMU sensor frame and
    carrier body to plane. omega_ts_s: (N, 3) angular rate of s relative to t in s, rad/s.
    gimbal_angles: (N, 2) rad (outer, inner); zeros without a gimbal.
    """

    t: np.ndarray
    r_t: np.ndarray
    v_t: np.ndarray
    a_t: np.ndarray
    q_s_t: np.ndarray
    q_b_t: np.ndarray
    omega_ts_s: np.ndarray
    gimbal_angles: np.ndarray


# Sensors every world's MJCF declares, in this order, on site "imu" and body "carrier".
IMU_SENSORS_MJCF = """
  <sensor>
    <gyro name="imu_gyro" site="imu"/>
    <accelerometer name="imu_accel" site="imu"/>
    <framepos name="imu_pos" objtype="site" objname="imu"/>
    <framequat name="imu_quat" objtype="site" objname="imu"/>
    <framelinvel name="imu_linvel" objtype="site" objname="imu"/>
    <framequat name="carrier_quat" objtype="xbody" objname="carrier"/>
  </sensor>
"""


class PrescribedWorld(ABC):
    """A MuJoCo model whose joints follow analytic trajectories."""

    gimbal_joints: tuple[str, str] | None = None

    def __init__(self, mjcf: str) -> None:
        self.model = mujoco.MjModel.from_xml_string(mjcf)
        self.data = mujoco.MjData(self.model)
        self._adr = {name: (self.model.sensor(name).adr[0], self.model.sensor(name).dim[0])
                     for name in ("imu_gyro", "imu_accel", "imu_pos", "imu_quat",
                                  "imu_linvel", "carrier_quat")}
        self._gimbal_qpos = ([self.model.joint(j).qposadr[0] for j in self.gimbal_joints]
                             if self.gimbal_joints else None)

    @abstractmethod
    def joint_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Analytic (qpos, qvel, qacc) at times t (N,) s: (N, nq), (N, nv), (N, nv)."""

    def sample(self, t: np.ndarray) -> WorldSamples:
        """Run MuJoCo at times t (N,) s and read the IMU kinematics."""
        t = np.asarray(t, dtype=float)
        qpos, qvel, qacc = self.joint_state(t)
        m, d = self.model, self.data
        sensordata = np.empty((t.size, m.nsensordata))
        d_qpos, d_qvel, d_qacc, d_sensor = d.qpos, d.qvel, d.qacc, d.sensordata
        for k in range(t.size):
            d_qpos[:] = qpos[k]
            d_qvel[:] = qvel[k]
            d_qacc[:] = qacc[k]
            # The sensor path of mj_inverse, without collision and inverse dynamics.
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            mujoco.mj_sensorPos(m, d)
            mujoco.mj_comVel(m, d)
            mujoco.mj_sensorVel(m, d)
            mujoco.mj_rnePostConstraint(m, d)
            mujoco.mj_sensorAcc(m, d)
            sensordata[k] = d_sensor

        def read(name: str) -> np.ndarray:
            adr, dim = self._adr[name]
            return sensordata[:, adr:adr + dim]

        q_s_t = read("imu_quat")
        # MuJoCo's accelerometer reads C_t_s (a - g_model); recover the kinematic a_t.
        a_t = quat_rotate(q_s_t, read("imu_accel")) + m.opt.gravity
        gimbal = (qpos[:, self._gimbal_qpos] if self._gimbal_qpos is not None
                  else np.zeros((t.size, 2)))
        return WorldSamples(t=t, r_t=read("imu_pos").copy(), v_t=read("imu_linvel").copy(),
                            a_t=a_t, q_s_t=q_s_t.copy(), q_b_t=read("carrier_quat").copy(),
                            omega_ts_s=read("imu_gyro").copy(), gimbal_angles=gimbal)
