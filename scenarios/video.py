"""``aligngym render``: a video (or one frame) of a scenario's episode from the renderer
(``scenarios.render``), with an estimator's attitude errors in the overlay when one is
named (the estimator run passively through the env, ``scenarios.env``, on the same
episode). Kept apart from the renderer so that the env, which draws its ``rgb_array``
frames with the renderer, and this module do not import each other."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aligngym.scenarios.atomic import atomic_path
from aligngym.scenarios.config import ConfigError, ScenarioConfig, load_scenario
from aligngym.scenarios.render import SceneRenderer, error_line


@dataclass(frozen=True)
class EstimatorTrack:
    """An estimator's attitude errors over an episode: epoch times t (K,) s of the
    scenario, errors (K, 3) arcmin (E, N, U), and whether and when it diverged."""

    name: str
    t: np.ndarray
    error_arcmin: np.ndarray
    start: float
    diverged_at: float | None

    def lines(self, t: float) -> list[str]:
        """The overlay's line at time t (s)."""
        if t < self.start:
            return [f"{self.name}: coarse alignment (the filter starts at {self.start:g} s)"]
        k = int(np.searchsorted(self.t, t, side="right")) - 1
        if k < 0:
            return [f"{self.name}: fine alignment starting"]
        text = error_line(self.name, self.error_arcmin[k])
        if self.diverged_at is not None and t >= self.diverged_at:
            text += "  DIVERGED"
        return [text]


def estimator_track(scenario: str, estimator: str, seed: int, until: float
                    ) -> tuple[EstimatorTrack, ScenarioConfig]:
    """Run the estimator passively (``scenarios.env``) on the scenario's episode of this
    seed and record its attitude errors at its epochs up to time until (s). Returns them
    and the scenario as the pipeline runs it (an experiment may set its motion)."""
    from aligngym.scenarios.env import AlignmentEnv

    env = AlignmentEnv(scenario=scenario, estimator=estimator, cache_episodes=0)
    env.reset(seed=seed, options={"episode_seed": seed})
    start = env.alignment_start_s
    times, errors, diverged_at = [], [], None
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    while True:
        _, _, terminated, truncated, info = env.step(action)
        times.append(start + info["time_s"])
        errors.append(info["error_arcmin"])
        if info["diverged"] and diverged_at is None:
            diverged_at = times[-1]
        if terminated or truncated or times[-1] >= until:
            break
    env.close()
    return (EstimatorTrack(name=estimator, t=np.array(times), error_arcmin=np.array(errors),
                           start=start, diverged_at=diverged_at), env.config)


def render_video(config: ScenarioConfig, out: str, seed: int = 0, estimator: str | None = None,
                 fps: float = 20.0, size: tuple[int, int] = (480, 640), start: float = 0.0
                 ) -> dict:
    """Write the scenario's episode of this seed over [start, config.duration] s as an
    MP4 video (H.264, ``fps`` frames per s of the scenario's time), or its frame at start
    as a PNG (out ending in .png), with the estimator's attitude errors in the overlay
    when one is named. Returns {"path", "frames", "seconds", "seconds_per_frame"}."""
    import time
    from pathlib import Path

    import imageio.v2 as imageio

    scenario = config.source or config.name
    if estimator:
        if not config.experiment:
            raise ConfigError(f"--estimator needs a scenario that names an experiment (its "
                              f"file's experiment key); {config.name!r} names none")
        if load_scenario(scenario).with_options(duration=config.duration) != config:
            raise ConfigError(f"--estimator runs the pipeline of the scenario file "
                              f"{scenario}, and this configuration differs from it")
    if not (math.isfinite(fps) and 1.0 <= fps <= 120.0):
        raise ConfigError(f"--fps = {fps:g} is out of range [1, 120]")
    path = Path(out)
    if path.suffix.lower() not in (".mp4", ".png"):
        raise ConfigError(f"--out {out}: the video is written as .mp4 (or one frame, at "
                          "--start, as .png)")
    if not 0.0 <= start <= config.duration:
        raise ConfigError(f"--start = {start:g} s is outside the run [0, {config.duration:g}) s")
    path.parent.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    track = None
    if estimator:       # the picture of the episode the filter ran on
        track, pipeline = estimator_track(scenario, estimator, seed, config.duration)
        config = pipeline.with_options(duration=config.duration)
    renderer = SceneRenderer(config, seed=seed, size=size)
    if path.suffix.lower() == ".png":
        try:
            with atomic_path(path) as tmp:
                imageio.imwrite(tmp, renderer.frame(start, track.lines(start) if track
                                                    else None))
        finally:
            renderer.close()
        seconds = time.perf_counter() - started
        return {"path": path, "frames": 1, "seconds": seconds, "seconds_per_frame": seconds}
    times = start + np.arange(int(math.floor((config.duration - start) * fps + 1e-9)) + 1) / fps
    try:                # a killed or interrupted render leaves the old video, not a short one
        with atomic_path(path, own_directory=True) as tmp, imageio.get_writer(
                tmp, fps=fps, codec="libx264", macro_block_size=8,
                ffmpeg_log_level="error") as writer:
            for t in times:
                writer.append_data(renderer.frame(float(t), track.lines(t) if track else None))
    finally:
        renderer.close()
    seconds = time.perf_counter() - started
    return {"path": path, "frames": times.size, "seconds": seconds,
            "seconds_per_frame": seconds / times.size}
