"""The smooth truth of a floating hull (``models.discrete_run.SmoothRun``), checked on a known
analytic motion: MuJoCo's exact sensors on the prescribed ship."""
import numpy as np

from aligngym.models.attitude import quat_angle, quat_conj, quat_mul, quat_to_dcm, quat_to_rotvec
from aligngym.models.ship import ShipSwayMotion, ShipWorld
from aligngym.models.discrete_run import DiscreteRun, SmoothRun

H = 0.002          # s, the physics step
DURATION = 20.0    # s


def staircase_run(motion: ShipSwayMotion) -> DiscreteRun:
    """The prescribed ship recorded the way MuJoCo records a free body: exact positions
    and attitudes at the steps, and over each step the constant body rate that turns one
    attitude into the next (the carrier origin moves at its mean velocity)."""
    t = np.arange(int(round(DURATION / H)) + 1) * H
    pos, _, _ = motion.sway_centre(t)
    quat = ShipWorld(motion).joint_state(t)[0][:, 3:7]
    step_rate = quat_to_rotvec(quat_mul(quat_conj(quat[:-1]), quat[1:])) / H
    pad = np.zeros((1, 3))
    return DiscreteRun(dt=H, t=t, pos=pos, quat=quat,
                       vel=np.concatenate([pad, np.diff(pos, axis=0) / H, pad]),
                       omega=np.concatenate([pad, step_rate, pad]),
                       imu_offset_b=np.asarray(motion.lever_arm_b))


def test_smooth_run_recovers_the_analytic_motion_and_its_imu():
    """From MuJoCo-like staircase records of a smooth motion (the 003 ship: 33 m lever
    arm, gimbal at 6 and 18 deg/s), the smooth truth gives back the motion's attitude and
    the IMU increments MuJoCo's own gyro and accelerometer integrate to (no earth, no
    gravity), to rounding: the spline's rate and acceleration errors are O(h^5)."""
    motion = ShipSwayMotion()
    smooth = SmoothRun(staircase_run(motion))
    world = ShipWorld(motion)
    exact = world.sample(smooth.t)
    # Attitude: the integrated smooth rotations stay on the analytic attitude.
    assert quat_angle(smooth.quat, exact.q_b_t).max() < 1e-12   # rad (measured 6e-15)
    # IMU point kinematics at the steps.
    site, v_site = smooth.imu_trajectory()
    np.testing.assert_allclose(site, exact.r_t, atol=1e-10)      # m (2e-13)
    np.testing.assert_allclose(v_site, exact.v_t, atol=1e-9)     # m/s (3e-11)
    # Increments over 10 ms against 5-node Gauss-Legendre integrals of MuJoCo's sensors.
    n = smooth.t.size - 1
    dtheta, dv = smooth.imu_increments(np.zeros(3), np.zeros((n, 3)), motion.gimbal_state)
    nodes, weights = np.polynomial.legendre.leggauss(5)
    t0 = smooth.t[:-1]
    ref_theta, ref_v = np.zeros((n, 3)), np.zeros((n, 3))
    for x, w in zip(nodes, weights):
        s = world.sample(t0 + H * (x + 1) / 2)
        ref_theta += w * H / 2 * s.omega_ts_s
        ref_v += w * H / 2 * np.einsum("nji,nj->ni", quat_to_dcm(s.q_s_t), s.a_t)
    k = 5
    per_sample = lambda a: a.reshape(-1, k, 3).sum(1)   # noqa: E731
    err_theta = np.abs(per_sample(dtheta - ref_theta)).max()
    err_v = np.abs(per_sample(dv - ref_v)).max()
    assert err_theta < 1e-14      # rad per 10 ms (measured 6e-16)
    assert err_v < 5e-10          # m/s per 10 ms (measured 3e-11)
