"""A ship floating in irregular waves (the wave-driven motion source of SPEC 4.1).

The hull is a MuJoCo free body. Each physics step the hydrodynamic generalised forces are
applied at its centre of mass (``xfrc_applied``): linear hydrostatic restoring in heave,
roll and pitch towards the instantaneous wave surface at the hull (elevation and slopes
of a JONSWAP sea at the mooring point, Froude-Krylov long-wave approximation), linear
radiation damping, weak surge/sway/yaw restoring (mooring or dynamic positioning) and a
heading autopilot. The stiffnesses come from the natural periods, so the hull's response
has the paper's character (periods 5-8 s, degrees of roll and pitch, decimetres of
heave) with the randomness of a real sea. The rotary IMU sits on the double-axis gimbal
at the lever arm; MuJoCo's discrete steps are recorded and ``models.discrete_run.SmoothRun``
makes the truth and the increments from them.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from aligngym.models.discrete_run import DiscreteRun
from aligngym.models.gimbal import GimbalRates, stalled
from aligngym.models.indexer import IndexerMotion, IndexerSpec
from aligngym.models.ship import HULL_SIZE_RANGE, REFERENCE_HULL, ship_mjcf
from aligngym.models.units import deg
from aligngym.models.world import skip_sensors

RHO_G = 1025.0 * 9.81
WAVE_TIMESTEP = 0.002
"""MuJoCo's step of the wave-driven hull, s (500 Hz, ``scenarios.worlds.ShipInWaves.physics_rate``)."""


@dataclass(frozen=True)
class WaveShipMotion(GimbalRates):
    """Sea state, hull response and IMU mounting. Heights m, periods s, angles rad,
    rates rad/s.

    significant_wave_height, peak_period, peak_enhancement (JONSWAP gamma) and
    wave_direction (direction the waves travel, CCW from north); components: number of
    wave frequencies; heave/roll/pitch natural periods and damping ratios; heading: the
    autopilot's yaw (PSINS, CCW). lever_arm_b: IMU from the hull origin (R, F, U);
    gimbal rates as in ``ShipSwayMotion``; indexer: a single-axis azimuth indexer
    (``models.indexer``) on the outer gimbal axis, its servo a MuJoCo actuator in the
    floating hull's model (the rates 0 then); antenna_b: the GNSS antenna from the hull
    origin (R, F, U), m (None: at the IMU); hull_size: beam, length, depth, m (the mass
    properties scale with it, ``models.ship.hull_mass_properties``); gimbal_stalls:
    injected stalls (start s, duration s) of the gimbal (``models.gimbal.stalled``).
    """

    significant_wave_height: float = 1.5
    peak_period: float = 7.0
    peak_enhancement: float = 3.3
    wave_direction: float = 60 * deg
    components: int = 60
    heave_period: float = 8.0
    roll_period: float = 6.0
    pitch_period: float = 5.0
    damping_ratio: float = 0.15
    heading: float = 30 * deg
    lever_arm_b: tuple[float, float, float] = (10.0, 30.0, 10.0)
    gimbal_outer_rate: float = 6 * deg
    gimbal_inner_rate: float = 18 * deg
    indexer: IndexerSpec | None = None
    antenna_b: tuple[float, float, float] | None = None
    hull_size: tuple[float, float, float] = REFERENCE_HULL[0]
    gimbal_stalls: tuple[tuple[float, float], ...] = ()

    def gimbal_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The constant-rate gimbal's motion (``GimbalRates``). With an indexer the motion
        is the servo's, simulated with the hull: ``DiscreteRun.gimbal`` of the run."""
        if self.indexer is not None:
            raise ValueError("the wave-driven indexer's motion comes from the hull's run "
                             "(WaveShipWorld.run().gimbal), not from the motion settings")
        return super().gimbal_state(t)

    @property
    def gps_antenna_b(self) -> tuple[float, float, float]:
        """The GNSS antenna on the hull (R, F, U), m."""
        return self.lever_arm_b if self.antenna_b is None else self.antenna_b

    def check(self) -> None:
        """Raise ValueError naming the field for values outside their range."""
        self.check_indexer()
        if self.indexer is not None and abs(self.indexer.servo_step - WAVE_TIMESTEP) > 1e-12:
            raise ValueError(f"indexer.servo_step = {self.indexer.servo_step:g} s: on the "
                             f"wave-driven hull the servo steps with the physics, "
                             f"{WAVE_TIMESTEP:g} s")
        low, high = HULL_SIZE_RANGE
        for i, size in enumerate(self.hull_size):
            if not low <= size <= high:
                raise ValueError(f"motion.hull_size[{i}] = {size:g} m is out of range "
                                 f"[{low:g}, {high:g}]")
        for name, low, high in (("significant_wave_height", 0.0, 15.0),
                                ("peak_period", 2.0, 25.0), ("heave_period", 2.0, 30.0),
                                ("roll_period", 2.0, 30.0), ("pitch_period", 2.0, 30.0),
                                ("damping_ratio", 0.01, 2.0), ("peak_enhancement", 1.0, 7.0)):
            value = getattr(self, name)
            if not low <= value <= high:
                raise ValueError(f"motion.{name} = {value:g} is out of range [{low:g}, {high:g}]")
        if not 4 <= self.components <= 1000:
            raise ValueError(f"motion.components = {self.components} is out of range [4, 1000]")


def jonswap_density(motion: WaveShipMotion, w: np.ndarray) -> np.ndarray:
    """JONSWAP wave spectrum S(w) (m^2 s/rad) at angular frequencies w (rad/s),
    DNV-RP-C205 3.5.5, from the significant wave height, peak period and gamma."""
    wp = 2 * math.pi / motion.peak_period
    Hs, gamma = motion.significant_wave_height, motion.peak_enhancement
    sigma = np.where(w <= wp, 0.07, 0.09)
    pm = 5.0 / 16.0 * Hs ** 2 * wp ** 4 * w ** -5 * np.exp(-1.25 * (w / wp) ** -4)
    return (1 - 0.287 * math.log(gamma)) * pm * gamma ** np.exp(
        -0.5 * ((w - wp) / (sigma * wp)) ** 2)


def sea_band(motion: WaveShipMotion) -> tuple[float, float]:
    """The angular frequencies (rad/s) the synthesized sea spans: 0.5 to 3 peak
    frequencies (99 % of the JONSWAP energy for the shipped sea)."""
    wp = 2 * math.pi / motion.peak_period
    return 0.5 * wp, 3.0 * wp


def jonswap_components(motion: WaveShipMotion, rng: np.random.Generator
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Amplitudes (m), angular frequencies (rad/s), wavenumbers (rad/m, deep water) and
    random phases of the sea, from the JONSWAP spectrum sampled at jittered frequencies
    in ``sea_band``."""
    n = motion.components
    edges = np.linspace(*sea_band(motion), n + 1)
    w = edges[:-1] + rng.uniform(0.0, 1.0, n) * np.diff(edges)
    amplitude = np.sqrt(2 * jonswap_density(motion, w) * np.diff(edges))
    return amplitude, w, w ** 2 / 9.81, rng.uniform(0.0, 2 * math.pi, n)


def heave_response(motion: WaveShipMotion, w: np.ndarray) -> np.ndarray:
    """Heave of the centre of mass per unit wave elevation at w (rad/s), complex:
    1 / (1 - r^2 + 2 i zeta r), r = w / w_heave (the hull's heave force, restoring to
    the wave surface at the centre with damping on the hull's own velocity)."""
    r = np.asarray(w) * motion.heave_period / (2 * math.pi)
    return 1.0 / (1.0 - r * r + 2j * motion.damping_ratio * r)


def heave_velocity_density(motion: WaveShipMotion, points: int = 4000
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Angular frequencies w (rad/s) over the sea's band and the spectral density of the
    centre of mass's heave velocity there, w^2 |H(w)|^2 S(w) (m^2/s^2 per rad/s)."""
    w = np.linspace(*sea_band(motion), points)
    return w, w ** 2 * np.abs(heave_response(motion, w)) ** 2 * jonswap_density(motion, w)


def sway_centre_velocity(motion: WaveShipMotion) -> tuple[np.ndarray, np.ndarray]:
    """Std (3,) m/s and mean zero-crossing period (3,) s of the centre of mass's velocity
    along E, N, U, from the sea spectrum and the hull's response. The hull feels no
    horizontal wave force (only the weak mooring), so E and N are zero (measured: 6
    um/s); U is the heave velocity (``heave_velocity_density`` integrated; within 4 % of
    the measured std on the shipped sea). Periods of E and N: inf."""
    w, density = heave_velocity_density(motion)
    m0 = np.trapezoid(density, w)
    m2 = np.trapezoid(w ** 2 * density, w)
    return (np.array([0.0, 0.0, math.sqrt(m0)]),
            np.array([math.inf, math.inf, 2 * math.pi * math.sqrt(m0 / m2)]))


def heave_velocity_band(motion: WaveShipMotion) -> tuple[float, float]:
    """The heave velocity as a narrow-band process: the period (s) and damping ratio of
    the oscillator whose autocorrelation exp(-zeta w tau) cos(w tau) fits, by least
    squares over three periods, the one of ``heave_velocity_density`` (its cosine
    transform). The half-power bandwidth would overstate zeta (0.094 against 0.059 on
    the shipped sea): the response spectrum is peaked, not Lorentzian."""
    from scipy.optimize import least_squares

    w, density = heave_velocity_density(motion)
    w_peak = float(w[np.argmax(density)])
    tau = np.linspace(0.0, 3 * 2 * math.pi / w_peak, 200)
    rho = np.trapezoid(density * np.cos(w * tau[:, None]), w, axis=1) / np.trapezoid(density, w)
    fit = least_squares(lambda p: np.exp(-p[1] * p[0] * tau) * np.cos(p[0] * tau) - rho,
                        [w_peak, 0.1], bounds=([0.5 * w_peak, 0.0], [2 * w_peak, 1.0]))
    return 2 * math.pi / float(fit.x[0]), float(fit.x[1])


class WaveShipWorld:
    """The 003 ship's MJCF (hull, gimbal, IMU) as a dynamic body in a random sea."""

    smooth_truth = True
    """The truth is the smooth motion MuJoCo's steps sample (``models.discrete_run.SmoothRun``):
    a hull turns smoothly, and its piecewise-constant rates would read as coning."""

    def __init__(self, motion: WaveShipMotion, rng: np.random.Generator,
                 timestep: float = WAVE_TIMESTEP, force_period: int = 1,
                 sea_state: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
        """timestep: MuJoCo step, s (several per IMU sample keep the discrete rotation
        smooth for the strapdown's coning term); force_period: steps between updates of
        the hydrodynamic wrench (held in between). Every step by default: a wrench held
        over 10 ms steps the acceleration at the IMU's own rate, which a strapdown's
        sculling term rectifies (0.63 mm/s over 120 s, against 0.005 mm/s). sea_state:
        the significant wave height (m) at times t (N,) s where it changes within the run
        (a building or calming sea: every component's amplitude scales with it, the
        spectrum's shape kept); None: motion.significant_wave_height throughout."""
        import mujoco
        if motion.indexer is not None and abs(motion.indexer.servo_step - timestep) > 1e-12:
            raise ValueError(f"indexer.servo_step = {motion.indexer.servo_step:g} s: the "
                             f"wave-driven hull's servo steps with the physics, {timestep:g} s")
        self.motion = motion
        self.force_period = force_period
        self._sea_state = sea_state
        # The rendered sea: a few peak wavelengths around the hull, crests to 1.2 Hs.
        wavelength = 9.81 * motion.peak_period ** 2 / (2 * math.pi)
        patch = (max(3.0 * max(motion.hull_size), 2.0 * wavelength),
                 max(1.2 * motion.significant_wave_height, 0.05))
        xml = ship_mjcf(motion.lever_arm_b, floating=True, antenna_b=motion.antenna_b,
                        hull_size=motion.hull_size, indexer=motion.indexer,
                        sea_patch=patch).replace(
            '<option timestep="0.005" integrator="implicitfast"/>',
            f'<option timestep="{timestep:g}" integrator="implicitfast"/>')
        self.model = mujoco.MjModel.from_xml_string(xml)
        skip_sensors(self.model)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._hull = m.body("carrier").id
        self._gimbal_dof = [m.joint(j).dofadr[0] for j in ("gimbal_outer", "gimbal_inner")]
        self._gimbal_qpos = [m.joint(j).qposadr[0] for j in ("gimbal_outer", "gimbal_inner")]
        self.sea = jonswap_components(motion, rng)
        beta = motion.wave_direction  # waves travel along (-sin beta, cos beta) in E, N
        self._direction = np.array([-math.sin(beta), math.cos(beta)])
        mass = float(m.body_subtreemass[self._hull])
        inertia = self._hull_inertia()
        w = {name: 2 * math.pi / getattr(motion, f"{name}_period")
             for name in ("heave", "roll", "pitch")}
        zeta = motion.damping_ratio
        # Heave, pitch (about body x, the right axis) and roll (about y, forward):
        # stiffness and damping from the natural periods and the damping ratio.
        modal = np.array([mass, inertia[0], inertia[1]])
        w_n = np.array([w["heave"], w["pitch"], w["roll"]])
        self._k = (modal * w_n ** 2).tolist()
        self._c = (2 * zeta * modal * w_n).tolist()
        # Weak horizontal restoring (60 s period) and a heading autopilot (10 s), both
        # critically damped.
        self._k_h, self._c_h = mass * (2 * math.pi / 60) ** 2, 2 * mass * (2 * math.pi / 60)
        self._k_yaw = inertia[2] * (2 * math.pi / 10) ** 2
        self._c_yaw = 2 * inertia[2] * (2 * math.pi / 10)
        self._mass = mass
        self._gravity = -float(m.opt.gravity[2])
        # Views into MjData's buffers, read every physics step by the wrench.
        self._hull_xmat = self.data.xmat[self._hull]
        self._hull_xipos = self.data.xipos[self._hull]
        self._hull_qvel = self.data.qvel[0:6]

    def _hull_inertia(self) -> np.ndarray:
        """Principal moments (3,) kg m^2 of the whole ship about its centre of mass."""
        import mujoco
        mujoco.mj_forward(self.model, self.data)
        return self.model.body_inertia[self._hull].copy() * (
            self.model.body_subtreemass[self._hull] / self.model.body_mass[self._hull])

    def sea_surface(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Elevation (m) of the sea at time t (s) at plane points x, y (m, any shape):
        the long-crested waves are a profile along their direction, sampled at 1024
        points across the region and interpolated."""
        a, w, k, phase = self.sea
        along = x * self._direction[0] + y * self._direction[1]
        s = np.linspace(along.min(), along.max(), 1024)
        profile = np.cos(np.outer(s, k) - w * t + phase) @ a
        return np.interp(along, s, profile) * self._sea_scale(np.array([t]))[0]

    def _sea_scale(self, t: np.ndarray) -> np.ndarray:
        """The waves' amplitude at times t (N,) s relative to the spectrum's (1 without a
        changing sea state)."""
        if self._sea_state is None:
            return np.ones(t.shape)
        return self._sea_state(t) / self.motion.significant_wave_height

    def wave_at(self, t: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Elevation (m) and slope (dη/dE, dη/dN) of the sea at plane point xy (2,) m,
        times t (N,) s: (N,) and (N, 2)."""
        a, w, k, phase = self.sea
        t = np.asarray(t, dtype=float)
        eta, rise = np.empty(t.size), np.empty(t.size)
        for start in range(0, t.size, 20000):      # blocks of (20000, components)
            arg = k * (xy @ self._direction) - np.outer(t[start:start + 20000], w) + phase
            eta[start:start + 20000] = np.cos(arg) @ a
            rise[start:start + 20000] = -(np.sin(arg) @ (a * k))
        return eta, rise[:, None] * self._direction

    def run(self, duration: float) -> DiscreteRun:
        """Float for duration (s), recording every physics step. The gimbal turns at its
        rates (velocity-level kinematic drive: its joints are reset each step), or the
        indexer's servo follows its command (the inner axis held at zero), reacting on
        the hull; its recorded motion is the run's ``gimbal``. The wrench is computed
        from the state at the start of each step (between ``mj_step1`` and
        ``mj_step2``) every force_period steps."""
        import mujoco
        m, d, motion = self.model, self.data, self.motion
        dt = m.opt.timestep
        n = int(round(duration / dt))
        t = np.arange(n + 1) * dt
        d.qpos[3:7] = [math.cos(motion.heading / 2), 0.0, 0.0, math.sin(motion.heading / 2)]
        indexer = motion.indexer
        if indexer is not None:
            command = indexer.command(t, t[-1])
            d.qpos[self._gimbal_qpos[0]] = command[0]
        mujoco.mj_forward(m, d)
        qpos_hist = np.empty((n + 1, m.nq))
        qvel_hist = np.empty((n + 2, m.nv))
        rates = (motion.gimbal_outer_rate, motion.gimbal_inner_rate)
        kinematic = (0, 1) if indexer is None else (1,)
        qpos, qvel, xfrc = d.qpos, d.qvel, d.xfrc_applied[self._hull]
        # The sea at the mooring point (the plane origin), where the centre of mass stays
        # (no horizontal wave force: it moves by micrometres), for every step at once.
        eta, slope = self.wave_at(t, np.zeros(2))
        if self._sea_state is not None:
            scale = self._sea_scale(t)
            eta, slope = eta * scale, slope * scale[:, None]
        eta, slope = eta.tolist(), slope.tolist()
        for k in range(n + 1):
            for i in kinematic:  # kinematic gimbal: angle = rate t exactly
                qpos[self._gimbal_qpos[i]] = rates[i] * t[k]
                qvel[self._gimbal_dof[i]] = rates[i]
            if indexer is not None:
                d.ctrl[0] = command[k]
            qpos_hist[k] = qpos
            qvel_hist[k] = qvel
            mujoco.mj_step1(m, d)
            if k % self.force_period == 0:
                xfrc[:] = self._hydrodynamic_wrench(eta[k], slope[k])
            mujoco.mj_step2(m, d)
        qvel_hist[n + 1] = qvel
        if not (np.all(np.isfinite(qpos_hist)) and np.all(np.isfinite(qvel_hist))):
            raise FloatingPointError("the wave-driven hull's simulation produced non-finite "
                                     "states")
        gimbal = None
        if indexer is not None:
            # A stall is injected into the recorded motion (the rotor's reaction on the
            # hull during it is not simulated: ~1e-6 of the hull's inertia).
            gimbal = stalled(IndexerMotion.from_steps(t, qpos_hist[:, self._gimbal_qpos[0]],
                                                      qvel_hist[:-1, self._gimbal_dof[0]],
                                                      command).gimbal_state,
                             motion.gimbal_stalls)
        return DiscreteRun(dt=dt, t=t, pos=qpos_hist[:, 0:3],
                           quat=qpos_hist[:, 3:7], vel=qvel_hist[:, 0:3],
                           omega=qvel_hist[:, 3:6],
                           imu_offset_b=np.asarray(motion.lever_arm_b, dtype=float),
                           gimbal=gimbal, qpos=qpos_hist)

    def _hydrodynamic_wrench(self, eta: float, slope: tuple[float, float]) -> list[float]:
        """Force and torque (6,) in world axes at the hull's centre of mass, from the
        state whose kinematics MuJoCo has computed (``mj_step1`` or ``mj_forward``) and
        the sea's elevation eta (m) and slope (2,) at the hull. Scalar arithmetic: it
        runs every physics step."""
        c00, c01, c02, c10, c11, c12, c20, c21, c22 = self._hull_xmat.tolist()  # hull to plane
        pitch = math.asin(max(-1.0, min(1.0, c21)))   # PSINS Euler angles
        roll = math.atan2(-c20, c22)
        yaw = math.atan2(-c01, c11)
        centre = self._hull_xipos.tolist()
        vx, vy, vz, wx, wy, wz = self._hull_qvel.tolist()
        k, c = self._k, self._c
        # Wave slopes seen along the body's right (x) and forward (y) axes.
        slope_right = slope[0] * c00 + slope[1] * c10
        slope_fwd = slope[0] * c01 + slope[1] * c11
        # Roll (about body y) follows the sideways slope, pitch (about x) the lengthwise.
        tx = -k[1] * (pitch - math.atan(slope_fwd)) - c[1] * wx
        ty = -k[2] * (roll + math.atan(slope_right)) - c[2] * wy
        tz = -self._k_yaw * _wrap(yaw - self.motion.heading) - self._c_yaw * wz
        return [-self._k_h * centre[0] - self._c_h * vx,
                -self._k_h * centre[1] - self._c_h * vy,
                self._mass * self._gravity - k[0] * (centre[2] - eta) - c[0] * vz,
                c00 * tx + c01 * ty + c02 * tz, c10 * tx + c11 * ty + c12 * tz,
                c20 * tx + c21 * ty + c22 * tz]


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi
