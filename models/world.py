"""MuJoCo worlds: the IMU sensors every world's MJCF declares, and prescribed worlds'
IMU kinematics.

Prescribed worlds (``PrescribedWorld``) read MuJoCo's sensors on analytic motion;
dynamic worlds (the car, the wave-driven ship) record MuJoCo's discrete steps
(``DiscreteRun``) whose IMU increments ``discrete_imu`` integrates exactly (both in
``models.discrete_run``). The double-axis gimbal is ``models.gimbal``.

MuJoCo's world frame is the earth-fixed tangent plane ``t`` (ENU axes at the scenario
origin). A prescribed world gives MuJoCo analytic joint positions, velocities and
accelerations and reads the IMU site's pose, velocity, gyro and accelerometer, exact to
rounding (gyro to ~1e-12 rad/s). It does so for all sample times in one
``mujoco.rollout`` call (C threads, no Python per sample) on a kinematic twin of the
model: every body nearly massless, every joint with a large armature A and the
applied generalised force A qacc, so that one forward-dynamics step's acceleration is
the prescribed qacc to rounding (relative error ~M/A ~1e-21) and the sensors of that
step read the prescribed state.
"""
from __future__ import annotations

import copy
import os
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from aligngym.models.attitude import quat_rotate

if TYPE_CHECKING:                   # MuJoCo is loaded when a world is built
    import mujoco


@dataclass(frozen=True)
class WorldSamples:
    """Kinematics of the IMU site and the carrier body at sample times, in plane frame t.

    t: (N,) s. r_t, v_t, a_t: (N, 3) IMU position (m), velocity (m/s) and acceleration
    (m/s^2) relative to the earth-fixed plane. q_s_t, q_b_t: (N, 4) IMU sensor frame and
    carrier body to plane. omega_ts_s: (N, 3) angular rate of s relative to t in s, rad/s.
    gimbal_angles: (N, 2) rad (outer, inner); zeros without a gimbal. antenna_r_t,
    antenna_v_t: (N, 3) the GNSS antenna's position (m) and velocity (m/s) in t, where the
    world has an antenna (else None).
    """

    t: np.ndarray
    r_t: np.ndarray
    v_t: np.ndarray
    a_t: np.ndarray
    q_s_t: np.ndarray
    q_b_t: np.ndarray
    omega_ts_s: np.ndarray
    gimbal_angles: np.ndarray
    antenna_r_t: np.ndarray | None = None
    antenna_v_t: np.ndarray | None = None


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


def skip_sensors(model: "mujoco.MjModel") -> None:
    """Stop MuJoCo computing the declared sensors at each step (``mjDSBL_SENSOR``). The
    dynamic worlds record qpos and qvel and derive the IMU from them
    (``discrete_imu``), so their sensor stage, the accelerometer's post-constraint
    pass above all, is wasted: skipping it leaves the motion bit for bit the same and
    saves about a fifth of the car's step."""
    import mujoco
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR.value


# Optional sensors of a GNSS antenna on site "antenna" (read where the MJCF declares them).
ANTENNA_SENSORS_MJCF = """
  <sensor>
    <framepos name="antenna_pos" objtype="site" objname="antenna"/>
    <framelinvel name="antenna_linvel" objtype="site" objname="antenna"/>
  </sensor>
"""


KINEMATIC_ARMATURE = 1e9
"""Armature of the kinematic twin's joints (kg m^2 or kg); its bodies weigh 1e-12 kg."""


def kinematic_twin(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of model whose forward dynamics follow an applied generalised force
    qfrc = KINEMATIC_ARMATURE qacc exactly: bodies of 1e-12 kg and 1e-15 kg m^2, joints
    of armature KINEMATIC_ARMATURE, constraints, contacts, springs, dampers, actuators and
    warm starts off, Euler integration (the step's result is not used)."""
    import mujoco
    twin = copy.deepcopy(model)
    twin.body_mass[1:] = 1e-12
    twin.body_inertia[1:] = 1e-15
    twin.dof_armature[:] = KINEMATIC_ARMATURE
    bits = mujoco.mjtDisableBit
    for flag in (bits.mjDSBL_CONSTRAINT, bits.mjDSBL_CONTACT, bits.mjDSBL_EQUALITY,
                 bits.mjDSBL_FRICTIONLOSS, bits.mjDSBL_LIMIT, bits.mjDSBL_SPRING,
                 bits.mjDSBL_DAMPER, bits.mjDSBL_ACTUATION, bits.mjDSBL_WARMSTART):
        twin.opt.disableflags |= flag.value
    twin.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER.value
    return twin


ROLLOUT_THREADS = max(1, min(4, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                               else os.cpu_count() or 1))
"""Threads of the prescribed worlds' sensor rollout."""


class PrescribedWorld(ABC):
    """A MuJoCo model whose joints follow analytic trajectories."""

    gimbal_joints: tuple[str, str] | None = None

    def __init__(self, mjcf: str) -> None:
        import mujoco
        self.model = mujoco.MjModel.from_xml_string(mjcf)
        self.data = mujoco.MjData(self.model)
        self._twin = kinematic_twin(self.model)
        names = [self.model.sensor(i).name for i in range(self.model.nsensor)]
        self._adr = {name: (self.model.sensor(name).adr[0], self.model.sensor(name).dim[0])
                     for name in ("imu_gyro", "imu_accel", "imu_pos", "imu_quat",
                                  "imu_linvel", "carrier_quat", "antenna_pos",
                                  "antenna_linvel") if name in names}
        self._gimbal_qpos = ([self.model.joint(j).qposadr[0] for j in self.gimbal_joints]
                             if self.gimbal_joints else None)

    @abstractmethod
    def joint_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Analytic (qpos, qvel, qacc) at times t (N,) s: (N, nq), (N, nv), (N, nv)."""

    def sample(self, t: np.ndarray) -> WorldSamples:
        """Run MuJoCo at times t (N,) s and read the IMU kinematics."""
        import mujoco
        t = np.asarray(t, dtype=float)
        qpos, qvel, qacc = self.joint_state(t)
        m, twin = self.model, self._twin
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS
        state = np.zeros((t.size, mujoco.mj_stateSize(twin, full)))
        state[:, 0] = t                        # FULLPHYSICS: time, qpos, qvel, ...
        state[:, 1:1 + m.nq] = qpos
        state[:, 1 + m.nq:1 + m.nq + m.nv] = qvel
        force = (KINEMATIC_ARMATURE * qacc)[:, None, :]
        threads = [mujoco.MjData(twin) for _ in range(min(ROLLOUT_THREADS, t.size))]
        from mujoco import rollout
        _, sensordata = rollout.rollout(twin, threads, state, force, nstep=1,
                                        control_spec=mujoco.mjtState.mjSTATE_QFRC_APPLIED.value)
        sensordata = sensordata[:, 0]

        def read(name: str) -> np.ndarray:
            adr, dim = self._adr[name]
            return sensordata[:, adr:adr + dim]

        q_s_t = read("imu_quat")
        # MuJoCo's accelerometer reads C_t_s (a - g_model); recover the kinematic a_t.
        a_t = quat_rotate(q_s_t, read("imu_accel")) + m.opt.gravity
        gimbal = (qpos[:, self._gimbal_qpos] if self._gimbal_qpos is not None
                  else np.zeros((t.size, 2)))
        antenna = ((read("antenna_pos"), read("antenna_linvel"))
                   if "antenna_pos" in self._adr else (None, None))
        # Views into the rollout's fresh output (no copies: 6 strided copies cost 18 ms).
        return WorldSamples(t=t, r_t=read("imu_pos"), v_t=read("imu_linvel"), a_t=a_t,
                            q_s_t=q_s_t, q_b_t=read("carrier_quat"),
                            omega_ts_s=read("imu_gyro"), gimbal_angles=gimbal,
                            antenna_r_t=antenna[0], antenna_v_t=antenna[1])
