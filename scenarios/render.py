"""Pictures of a scenario: the carrier's MuJoCo scene at any time of an episode, seen by a
camera that follows it, with a close-up of the IMU (on its gimbal, where it has one) as
an inset and an overlay of the time, the carrier's attitude and an estimator's attitude
errors. ``scenarios.video`` writes them as a video (``aligngym render``); the env's
``rgb_array`` frames are the same pictures. The renderer imports nothing above it (not
the env: the estimator's overlay is the video module's).

Prescribed worlds (the swaying ship, the marble platform) are posed from their analytic
motion at the frame's time; dynamic worlds (the car, the wave-driven ship) are run once
over the duration (the episode's own run: the same seed gives the same motion) and posed
from the recorded steps.
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from aligngym.scenarios.config import ConfigError, ScenarioConfig
from aligngym.scenarios.simulate import episode_rngs
from aligngym.scenarios.worlds import make_dynamic_world, make_world, run_gimbal, world_of


def check_size(size: tuple[int, int]) -> None:
    """One-line ConfigError for a frame size (height, width) outside the renderer's."""
    height, width = size
    if not (16 <= height <= 2160 and 16 <= width <= 3840):
        raise ConfigError(f"render size = {height}x{width} is out of range: height in "
                          "[16, 2160], width in [16, 3840] pixels")


@dataclass(frozen=True)
class View:
    """A camera on a world: distance (m) from the point looked at, elevation (deg, below
    the horizon negative) and azimuth (deg) relative to the carrier's heading (0: looking
    along its forward axis); inset: the close-up's distance (m) from the IMU."""

    distance: float
    elevation: float
    azimuth: float
    inset: float


def world_view(config: ScenarioConfig) -> View:
    """The follow camera and close-up of the scenario's world (``World.camera``)."""
    return View(*world_of(config).camera(config))


class SceneRenderer:
    """Frames (height, width, 3) uint8 of one episode of a scenario (seed: the episode's,
    which draws the motion's random phases, the sea or the road) over [0, duration] s."""

    def __init__(self, config: ScenarioConfig, seed: int = 0, duration: float | None = None,
                 size: tuple[int, int] = (480, 640)) -> None:
        import mujoco

        check_size(size)
        height, width = size
        self.config, self.view, self.seed = config, world_view(config), seed
        self.duration = config.duration if duration is None else float(duration)
        rngs = episode_rngs(seed)
        self._run = None
        carrier = world_of(config)
        self._look_between = carrier.look_between
        if carrier.dynamic:
            self.world = make_dynamic_world(config, rngs, pictures=True)
            self._run = self.world.run(self.duration)
        else:
            self.world = make_world(config, rngs["motion"])
        self.model, self.data = self.world.model, self.world.data
        model = self.model
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        # One GL context for both pictures (a context costs 0.2-0.3 s to make): MuJoCo's
        # Renderer draws into the lower-left corner of the model's offscreen buffer, so
        # the close-up is the same renderer with a smaller rectangle (``_sized``).
        self._renderer = mujoco.Renderer(model, height, width)
        self._inset_size = (height // 3, width // 3)
        self._camera, self._close = mujoco.MjvCamera(), mujoco.MjvCamera()
        self._inset_option = mujoco.MjvOption()
        if carrier.close_up_groups is not None:     # e.g. the car's instruments alone
            self._inset_option.geomgroup[:] = carrier.close_up_groups
        self._carrier = model.body("carrier").id
        self._imu_site = model.site("imu").id
        self._gimbal_qpos = getattr(self.world, "_gimbal_qpos", None)
        self._sea = model.hfield("sea").id if any(
            model.hfield(i).name == "sea" for i in range(model.nhfield)) else None
        if self._sea is not None:       # the heightfield's points in the plane, m
            rows, cols = model.hfield_nrow[self._sea], model.hfield_ncol[self._sea]
            half_x, half_y = model.hfield_size[self._sea][:2]
            self._sea_xy = np.meshgrid(np.linspace(-half_x, half_x, cols),
                                       np.linspace(-half_y, half_y, rows))

    # --- posing ------------------------------------------------------------------------
    def pose(self, t: float) -> None:
        """Put the world's MuJoCo data at time t (s) of the episode."""
        import mujoco

        if not 0.0 <= t <= self.duration + 1e-9:
            raise ValueError(f"render time {t:g} s is outside the run [0, {self.duration:g}] s")
        data = self.data
        if self._run is None:
            qpos, qvel, _ = self.world.joint_state(np.array([t]))
            data.qpos[:], data.qvel[:] = qpos[0], qvel[0]
        else:
            run = self._run
            k = int(np.clip(np.rint(t / run.dt), 0, run.t.size - 1))
            data.qpos[:] = run.qpos[k]          # every joint: wheels, steering, suspension
            gimbal = run_gimbal(run, self.config.motion)
            if self._gimbal_qpos is not None and gimbal is not None:   # with its stalls
                data.qpos[self._gimbal_qpos] = gimbal(np.array([t]))[0][0]
        mujoco.mj_forward(self.model, data)
        if self._sea is not None:
            self._waves(t)

    def _waves(self, t: float) -> None:
        """Fill the sea's heightfield with the waves at time t and upload it to the
        renderer's GL context."""
        import mujoco

        model, hid = self.model, self._sea
        top = model.hfield_size[hid][2]                  # from -crest to +crest, m
        eta = self.world.sea_surface(t, *self._sea_xy)
        start = model.hfield_adr[hid]
        model.hfield_data[start:start + eta.size] = np.clip(eta / top + 0.5, 0.0, 1.0).ravel()
        renderer = self._renderer
        context = getattr(renderer, "_gl_context", None)   # MuJoCo's own, private
        if context is not None and getattr(renderer, "_mjr_context", None) is not None:
            context.make_current()                         # (no GL: nothing to upload)
            mujoco.mjr_uploadHField(model, renderer._mjr_context, hid)

    def _heading_deg(self) -> float:
        """The carrier's forward axis' direction in the plane, deg from east, CCW."""
        forward = self.data.xmat[self._carrier].reshape(3, 3)[:, 1]
        return math.degrees(math.atan2(forward[1], forward[0]))

    def _aim(self) -> None:
        view, data = self.view, self.data
        carrier, imu = data.xpos[self._carrier], data.site_xpos[self._imu_site]
        self._camera.lookat[:] = 0.5 * (carrier + imu) if self._look_between else imu
        self._camera.distance, self._camera.elevation = view.distance, view.elevation
        self._camera.azimuth = self._heading_deg() + view.azimuth
        self._close.lookat[:] = imu
        self._close.distance, self._close.elevation = view.inset, -18.0
        self._close.azimuth = self._heading_deg() + view.azimuth + 20.0

    # --- pictures ----------------------------------------------------------------------
    def frame(self, t: float, lines: list[str] | None = None) -> np.ndarray:
        """The scene at time t (s): the follow camera's picture with the IMU's close-up in
        its lower right corner, and the overlay (time, attitude, and the given lines)."""
        self.pose(t)
        self._aim()
        self._renderer.update_scene(self.data, self._camera)
        image = self._renderer.render().copy()
        with _sized(self._renderer, self._inset_size):
            self._renderer.update_scene(self.data, self._close,
                                        scene_option=self._inset_option)
            close = self._renderer.render()
        h, w = close.shape[:2]
        image[-h - 4:, -w - 4:] = 255                       # a white border
        image[-h - 2:-2, -w - 2:-2] = close
        return overlay(image, [self._status(t)] + list(lines or []))

    def segmentation(self, t: float, close_up: bool = False) -> np.ndarray:
        """Geom ids (height, width) int of the follow camera's (or the close-up's)
        picture at time t; -1 where no geom is seen (sites included)."""
        import mujoco

        self.pose(t)
        self._aim()
        renderer, camera = self._renderer, self._close if close_up else self._camera
        size = self._inset_size if close_up else (renderer.height, renderer.width)
        renderer.enable_segmentation_rendering()
        try:
            with _sized(renderer, size):
                renderer.update_scene(self.data, camera,
                                      scene_option=self._inset_option if close_up else None)
                picture = renderer.render()
            ids = np.where(picture[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM),
                           picture[..., 0].astype(int), -1)
        finally:
            renderer.disable_segmentation_rendering()
        return ids

    def _status(self, t: float) -> str:
        from aligngym.models.attitude import dcm_to_euler
        pitch, roll, yaw = np.degrees(dcm_to_euler(
            self.data.xmat[self._carrier].reshape(3, 3)[None])[0])
        # heading: clockwise from north (the PSINS yaw is counter-clockwise)
        return (f"{self.config.name}   t = {t:7.2f} s   roll {roll:+6.2f}  pitch {pitch:+6.2f}"
                f"  heading {(-yaw) % 360.0:6.2f} deg")

    def close(self) -> None:
        """Free the renderer's GL context."""
        self._renderer.close()


@contextmanager
def _sized(renderer, size: tuple[int, int]) -> Iterator[None]:
    """The MuJoCo renderer drawing (height, width) pixels, no larger than its own size,
    for the duration. It sets mujoco.Renderer's private _height, _width and _rect (the
    same in MuJoCo 3.2 to 4.0), restored after; a renderer without them is an error, not
    a picture of the wrong size."""
    import mujoco

    if not all(hasattr(renderer, name) for name in ("_height", "_width", "_rect")):
        raise RuntimeError("this MuJoCo's Renderer has no _height, _width and _rect: the "
                           "close-up cannot share its GL context (scenarios.render._sized)")
    if size[0] > renderer.height or size[1] > renderer.width:
        raise ValueError(f"picture {size[0]}x{size[1]} is larger than the renderer's "
                         f"{renderer.height}x{renderer.width}")
    saved = renderer._height, renderer._width, renderer._rect
    renderer._height, renderer._width = size
    renderer._rect = mujoco.MjrRect(0, 0, size[1], size[0])
    try:
        yield
    finally:
        renderer._height, renderer._width, renderer._rect = saved


def overlay(image: np.ndarray, lines: list[str]) -> np.ndarray:
    """The image with the lines of text written in its upper left corner on a dark band."""
    from PIL import Image, ImageDraw, ImageFont

    picture = Image.fromarray(image)
    draw = ImageDraw.Draw(picture, "RGBA")
    size = max(10, image.shape[0] // 36)
    try:
        font = ImageFont.load_default(size=size)
    except TypeError:                   # Pillow < 10.1: a fixed bitmap font
        font = ImageFont.load_default()
    height = int(1.35 * size) * len(lines) + 8
    draw.rectangle([0, 0, image.shape[1], height], fill=(0, 0, 0, 150))
    for i, line in enumerate(lines):
        draw.text((6, 4 + i * int(1.35 * size)), line, fill=(255, 255, 255, 255), font=font)
    return np.asarray(picture)


def error_line(estimator: str, error_arcmin: np.ndarray) -> str:
    """The overlay's line of an estimator's attitude error E, N, U (3,) arcmin."""
    e = error_arcmin
    return f"{estimator}: attitude error E {e[0]:+8.2f}'  N {e[1]:+8.2f}'  U {e[2]:+8.2f}'"
