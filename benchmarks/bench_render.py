"""Cost of the pictures: seconds per frame of each world (480x640, the follow camera, the
IMU's close-up and the overlay), and of a whole video (``aligngym render``).

    python benchmarks/bench_render.py
"""
import time

import numpy as np

from aligngym.scenarios.config import load_scenario
from aligngym.scenarios.render import SceneRenderer
from aligngym.scenarios.video import render_video

SCENARIOS = ("ship-sway-rotary", "usv-mems-swing", "ship-waves-rotary", "usv-mems-waves",
             "static-large-azimuth", "ring-road-odometer", "figure8-gps")


def main() -> None:
    for name in SCENARIOS:
        config = load_scenario(name).with_options(duration=30.0)
        start = time.perf_counter()
        renderer = SceneRenderer(config, seed=0)
        setup = time.perf_counter() - start
        times = np.linspace(5.0, 25.0, 40)
        start = time.perf_counter()
        for t in times:
            renderer.frame(float(t))
        per_frame = (time.perf_counter() - start) / times.size
        renderer.close()
        print(f"{name:22s} set-up {setup:5.2f} s   {per_frame * 1e3:6.1f} ms per frame")
    done = render_video(load_scenario("ship-sway-rotary").with_options(duration=30.0),
                        "/tmp/bench_render.mp4", seed=0, estimator="imakf")
    print(f"video ship-sway-rotary 30 s at 20 fps with imakf: {done['frames']} frames in "
          f"{done['seconds']:.1f} s ({done['seconds_per_frame'] * 1e3:.0f} ms per frame)")


if __name__ == "__main__":
    main()
