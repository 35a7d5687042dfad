"""A MuJoCo car driven around ring and figure-8 tracks (papers 000 and 001).

The car: a chassis (body "carrier", free joint) on four slide-joint suspensions; front
wheels steered by position servos about their kingpins (Ackermann angles from the
controller); rear wheels driven through a fixed-tendon differential by one velocity
servo; ellipsoid tyres with friction on a ground plane, or on a heightfield with road
roughness. A pure-pursuit controller (6 m look-ahead) with a speed ramp follows the
track; the car starts at the plane origin heading north.

Physics runs at 2 ms with the implicitfast integrator. For it MuJoCo updates the
velocity first and then moves the free joint with the new velocity: over step k the
body rotates at the constant body rate omega_{k+1} and its origin moves at the constant
world velocity v_{k+1}. ``CarWorld.run`` records exactly these, so the IMU increments
can be made consistent with the discrete motion to rounding (``discrete_imu``).

The scene (visual only, ``models.car_scenery``: massless, contact-free geoms; the physics
is bit-identical without them): the chassis box is the lower body of a red saloon with a
cabin, windows, bumpers, lights, wheel arches and rims; the IMU case with its sensor axes
(x red, y green, z blue) and, with a gimbal, its two frames; the GPS antenna on a mast;
the track painted on the ground (asphalt road, dashed yellow path, white lane edges).
The IMU sits inside the body: hide geom groups 0 and 1 to see the instruments. The
tracks and the driver are ``models.car_track``'s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aligngym.models.car_params import WHEEL_CENTRE_Z, CarParams
from aligngym.models.car_scenery import CAR_MATERIALS, car_body, rim, track_scenery
from aligngym.models.car_track import (G_LATERAL_MAX, RADIUS_MAX, ROUGH_RADIUS_MAX, DriveProfile,
                                       PurePursuit, Track, figure8_track, ring_track)
from aligngym.models.discrete_run import DiscreteRun
from aligngym.models.gimbal import GimbalRates
from aligngym.models.scene import geom
from aligngym.models.world import IMU_SENSORS_MJCF, skip_sensors

def car_mjcf(p: CarParams, roughness_seed: int = 0, extent: float = 600.0,
             track: Track | None = None, dressed: bool = True) -> tuple[str, dict]:
    """MJCF of the car and the ground, with the track painted on it if given; returns
    (xml, assets) (the heightfield data). The car body, the instruments and the track are
    visual only (``models.scene``): the physics does not depend on them, and dressed=False
    leaves them out (with the horizon and the rims: the model to simulate, not to draw)."""
    hw, hl = p.track / 2, p.wheelbase / 2
    z_wheel = WHEEL_CENTRE_Z
    spring_ref = 0.0
    wheels = []
    for name, x, y, steer in (("fl", -hw, hl, True), ("fr", hw, hl, True),
                              ("rl", -hw, -hl, False), ("rr", hw, -hl, False)):
        steer_joint = (f'<joint name="{name}_steer" type="hinge" axis="0 0 1" '
                       f'range="{-p.max_steer:.5f} {p.max_steer:.5f}" damping="50"/>'
                       if steer else "")
        wheels.append(f"""
      <body name="{name}_susp" pos="{x:g} {y:g} {z_wheel:g}">
        <joint name="{name}_susp" type="slide" axis="0 0 1" range="-0.12 0.12"
               stiffness="{p.suspension_stiffness:g}" springref="{spring_ref:g}"
               damping="{p.suspension_damping:g}"/>
        <geom type="sphere" size="0.05" mass="15" contype="0" conaffinity="0"/>
        <body name="{name}_hub">
          {steer_joint}
          <geom type="sphere" size="0.04" mass="5" contype="0" conaffinity="0"/>
          <body name="{name}_wheel">
            <joint name="{name}_spin" type="hinge" axis="-1 0 0" damping="0.5"/>
            <geom name="{name}_tyre" type="ellipsoid"
                  size="{p.wheel_width / 2:g} {p.wheel_radius:g} {p.wheel_radius:g}"
                  mass="{p.wheel_mass:g}" friction="{p.tyre_friction:g} 0.02 0.001"
                  condim="3" rgba=".1 .1 .1 1"/>
            {rim(p, -1.0 if x < 0 else 1.0) if dressed else ""}
          </body>
        </body>
      </body>""")
    # Ground: a plane, or a heightfield whose RMS height is the road roughness.
    assets = {}
    if p.roughness_rms > 0.0:
        from scipy.ndimage import gaussian_filter
        cell = 0.2  # m; correlation length ~0.4 m: wheel-hop band at road speeds
        n = int(math.ceil(2 * extent / cell)) + 1
        rng = np.random.default_rng(roughness_seed)
        f = gaussian_filter(rng.standard_normal((n, n)), sigma=2.0, mode="wrap")
        heights = p.roughness_rms * (f - f.mean()) / f.std()
        low, high = float(heights.min()), float(heights.max())
        ground = (f'<geom name="ground" type="hfield" hfield="road" pos="0 0 {low:.6f}" '
                  f'friction="{p.tyre_friction:g} 0.02 0.001" material="ground"/>')
        spacing = 2 * extent / (n - 1)
        ring = np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1]), -1).reshape(-1, 2)

        def ground_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
            """Highest grid height around (x, y) (rows along y, columns along x), m."""
            col = np.rint((x + extent) / spacing).astype(int)[..., None] + ring[:, 0]
            row = np.rint((y + extent) / spacing).astype(int)[..., None] + ring[:, 1]
            return heights[np.clip(row, 0, n - 1), np.clip(col, 0, n - 1)].max(-1)
        hfield = (f'<hfield name="road" nrow="{n}" ncol="{n}" '
                  f'size="{extent:g} {extent:g} {high - low:.6f} 0.1"/>')
        assets["road"] = ((heights - low) / (high - low)).astype(np.float32)
    else:
        ground = (f'<geom name="ground" type="plane" size="{extent:g} {extent:g} 1" '
                  f'friction="{p.tyre_friction:g} 0.02 0.001" material="ground"/>')
        hfield = ""

        def ground_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
            return np.zeros(np.shape(x))
    ix, iy, iz = p.imu_offset_b
    track_assets, track_geoms = track_scenery(track, ground_height, p.roughness_rms > 0.0) if track else ("", "")
    body_assets, body_geoms = car_body(p) if dressed else ("", "")
    # The renderer's scale (its near clipping plane is 0.01 extent): the plane's own
    # statistic (0.2 x its size), which the track would widen; the heightfield's
    # (its diagonal) would clip views closer than ~6 m. Visual only.
    statistic = f'<statistic extent="{0.2 * extent!r}" center="0 0 0"/>'
    # Grass beyond the ground's edge, just below it, out to the far clipping plane.
    low = min(0.0, float(heights.min())) if hfield else 0.0
    horizon = geom("horizon", "plane", (20 * extent, 20 * extent, 1), (0, 0, low - 0.05),
                   material="ground") if dressed else ""
    xml = f"""
<mujoco model="car">
  <option timestep="0.002" integrator="implicitfast" iterations="20" ls_iterations="10"/>
  <visual><global offwidth="640" offheight="480"/></visual>
  {statistic}
  <asset>{hfield}
    {CAR_MATERIALS}
    {track_assets}
    {body_assets}
  </asset>
  <worldbody>
    <light pos="0 0 100" dir="0 0 -1" directional="true" castshadow="false" diffuse=".6 .6 .6"/>
    <light name="sun" mode="trackcom" pos="6 -8 30" dir="-0.2 0.27 -1" cutoff="50"
           diffuse=".4 .4 .4" castshadow="true"/>
    {ground}
    {horizon}
    {track_geoms}
    <body name="carrier" pos="0 0 {p.wheel_radius - z_wheel:g}">
      <freejoint name="chassis"/>
      <geom name="chassis" type="box" size="0.85 2.2 0.3" mass="{p.chassis_mass:g}"
            rgba=".7 .1 .1 1" contype="0" conaffinity="0"/>
      <site name="imu" pos="{ix:g} {iy:g} {iz:g}" size="0.05"/>
      {body_geoms}
      {''.join(wheels)}
    </body>
  </worldbody>
  <tendon>
    <fixed name="rear_diff">
      <joint joint="rl_spin" coef="0.5"/>
      <joint joint="rr_spin" coef="0.5"/>
    </fixed>
  </tendon>
  <actuator>
    <position name="steer_fl" joint="fl_steer" kp="4000" ctrlrange="{-p.max_steer:.5f} {p.max_steer:.5f}"/>
    <position name="steer_fr" joint="fr_steer" kp="4000" ctrlrange="{-p.max_steer:.5f} {p.max_steer:.5f}"/>
    <velocity name="drive" tendon="rear_diff" kv="2000" forcerange="-4000 4000"/>
  </actuator>
{IMU_SENSORS_MJCF}
</mujoco>
"""
    return xml, assets


# --- the world ------------------------------------------------------------------------------

class CarWorld:
    """The car and its driver in MuJoCo."""

    smooth_truth = False
    """The truth is MuJoCo's discrete motion itself (``models.discrete_run.discrete_imu``): wheel
    contacts on a rough road change the rates within a step."""

    def __init__(self, params: CarParams, track: Track, profile: DriveProfile,
                 roughness_seed: int = 0, control_period: int = 25,
                 pictures: bool = False) -> None:
        """pictures: dress the model to be drawn (the car's body, the instruments, the
        road and its lanes: visual geoms only). Without them the simulation is bit for bit
        the same, and 10 % cheaper per step (``mj_step`` computes every geom's pose)."""
        import mujoco
        self.params, self.track, self.profile = params, track, profile
        reach = np.abs(track.points).max() + 30.0
        xml, assets = car_mjcf(params, roughness_seed, extent=float(reach),
                               track=track if pictures else None, dressed=pictures)
        self.model = mujoco.MjModel.from_xml_string(xml)
        if "road" in assets:
            self.model.hfield_data[:] = assets["road"].ravel()
        skip_sensors(self.model)
        self.data = mujoco.MjData(self.model)
        self.control_period = control_period
        m = self.model
        self._spin_qpos = [m.joint(f"{w}_spin").qposadr[0] for w in ("fl", "fr", "rl", "rr")]
        self._settle()

    def _settle(self, seconds: float = 2.0) -> None:
        """Let the suspension settle at rest before time zero (brakes on)."""
        import mujoco
        m, d = self.model, self.data
        for _ in range(int(seconds / m.opt.timestep)):
            d.ctrl[:] = 0.0
            mujoco.mj_step(m, d)
        d.qvel[:] = 0.0
        d.time = 0.0
        # Re-centre at the origin heading north after settling.
        d.qpos[0:2] = 0.0
        mujoco.mj_forward(m, d)

    def run(self, duration: float) -> DiscreteRun:
        """Drive for duration (s), recording every physics step."""
        import mujoco
        m, d, p = self.model, self.data, self.params
        dt = m.opt.timestep
        n = int(round(duration / dt))
        qpos_hist = np.empty((n + 1, m.nq))
        qvel_hist = np.empty((n + 2, m.nv))
        control_steps = np.arange(0, n + 1, self.control_period)
        xtrack = np.empty(control_steps.size)
        driver = PurePursuit(self.track, p)
        qpos, qvel, ctrl = d.qpos, d.qvel, d.ctrl
        rear_offset = np.array([0.0, -p.wheelbase / 2])
        period = self.control_period
        for k in range(n + 1):
            qpos_hist[k] = qpos
            qvel_hist[k] = qvel
            if k % period == 0:
                w, x, y, z = qpos[3], qpos[4], qpos[5], qpos[6]
                # yaw from C = quat_to_dcm(q): atan2(-C[0, 1], C[1, 1])
                yaw = math.atan2(-2 * (x * y - w * z), 1 - 2 * (x * x + z * z))
                fx, fy = 2 * (x * y - w * z), 1 - 2 * (x * x + z * z)  # C[0, 1], C[1, 1]
                rear = (qpos[0] + fx * rear_offset[1], qpos[1] + fy * rear_offset[1])
                left, right, xtrack[k // period] = driver.steer(rear, yaw)
                ctrl[0], ctrl[1] = left, right
                ctrl[2] = self.profile.target_speed(k * dt) / p.wheel_radius
            mujoco.mj_step(m, d)
        qvel_hist[n + 1] = qvel
        wheels = qpos_hist[:, self._spin_qpos]
        return DiscreteRun(dt=dt, t=np.arange(n + 1) * dt, pos=qpos_hist[:, 0:3],
                      quat=qpos_hist[:, 3:7], vel=qvel_hist[:, 0:3], omega=qvel_hist[:, 3:6],
                      wheel_angles=np.unwrap(wheels, axis=0),
                      cross_track=np.repeat(xtrack, period)[: n + 1],
                           imu_offset_b=np.asarray(p.imu_offset_b), qpos=qpos_hist)


@dataclass(frozen=True)
class VehicleMotion(GimbalRates):
    """What the car does: track "ring" (radius = circle radius, m) or "figure8"
    (radius = half-width of the lemniscate, m); speed, m/s; still until start_time, s;
    brake at stop_time, s; accel, m/s^2; road roughness RMS, m; IMU and GPS-antenna
    offsets from the chassis origin (R, F, U), m."""

    track: str = "ring"
    radius: float = 100.0
    speed: float = 8.0
    start_time: float = 0.0
    stop_time: float = math.inf
    accel: float = 1.5
    roughness_rms: float = 0.0
    imu_offset_b: tuple[float, float, float] = (0.0, 0.3, 0.2)
    gps_antenna_b: tuple[float, float, float] = (0.0, -0.5, 1.2)
    gimbal_outer_rate: float = 0.0
    """Optional double-axis gimbal under the IMU (``GimbalRates``), rad/s; both 0 for a
    strapdown IMU."""
    gimbal_inner_rate: float = 0.0
    gimbal_stalls: tuple[tuple[float, float], ...] = ()
    """Injected stalls (start s, duration s) of that gimbal (``models.gimbal.stalled``)."""

    def make_track(self) -> Track:
        if self.track == "ring":
            return ring_track(self.radius)
        if self.track == "figure8":
            return figure8_track(self.radius)
        raise ValueError(f"motion.track = {self.track!r}; valid choices: figure8, ring")

    def car_params(self) -> CarParams:
        return CarParams(imu_offset_b=self.imu_offset_b, gps_antenna_b=self.gps_antenna_b,
                         roughness_rms=self.roughness_rms, gimbal=self.has_gimbal)

    def profile(self) -> DriveProfile:
        return DriveProfile(speed=self.speed, start_time=self.start_time,
                            stop_time=self.stop_time, accel=self.accel)

    def check(self) -> None:
        """Raise ValueError naming the field if the car cannot drive this."""
        if self.track not in ("ring", "figure8"):
            raise ValueError(f"motion.track = {self.track!r}; valid choices: figure8, ring")
        if not 0.0 < self.radius <= RADIUS_MAX:
            raise ValueError(f"motion.radius = {self.radius:g} m is out of range "
                             f"(0, {RADIUS_MAX:g}]")
        if self.roughness_rms > 0.0 and self.radius > ROUGH_RADIUS_MAX:
            raise ValueError(f"motion.radius = {self.radius:g} m with a rough road: at most "
                             f"{ROUGH_RADIUS_MAX:g} m (the road's heightfield grows with the "
                             "track's square)")
        if not 0.0 <= self.speed <= 40.0:
            raise ValueError(f"motion.speed = {self.speed:g} m/s is out of range [0, 40]")
        p = self.car_params()
        turning = p.wheelbase / math.tan(p.max_steer)
        r_min = self.make_track().min_radius()
        if r_min < turning + p.track:
            raise ValueError(f"motion.radius = {self.radius:g} m gives curves of {r_min:.1f} m"
                             f" radius, tighter than the car can steer ({turning + p.track:.1f} m)")
        lateral = self.speed ** 2 / r_min
        if lateral > G_LATERAL_MAX:
            raise ValueError(
                f"motion.speed = {self.speed:g} m/s on curves of {r_min:.1f} m radius needs "
                f"{lateral:.2f} m/s^2 lateral acceleration; the car holds at most "
                f"{G_LATERAL_MAX:.2f} (speed <= {math.sqrt(G_LATERAL_MAX * r_min):.1f} m/s)")
        if not self.accel > 0.0:
            raise ValueError(f"motion.accel = {self.accel:g} m/s^2 must be > 0")
        for name, reach in (("imu_offset_b", 5.0), ("gps_antenna_b", 10.0)):
            offset = getattr(self, name)
            if not all(math.isfinite(v) and abs(v) <= reach for v in offset):
                raise ValueError(f"motion.{name} = {list(offset)} m: each component must be "
                                 f"within +-{reach:g} m of the chassis origin (on the car)")
