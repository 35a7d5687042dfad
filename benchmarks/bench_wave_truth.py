"""Benchmark: the wave-driven ship's truth, its fidelity against its cost. Each option
(MuJoCo step, steps between hydrodynamic wrench updates, MuJoCo's piecewise-constant
discrete motion or its smooth reconstruction) simulates a 600 s ideal episode and runs
the fidelity check (SPEC 3); the prescribed ship is the reference.
Run: python benchmarks/bench_wave_truth.py [--duration S]"""
from __future__ import annotations

import argparse
import time

import aligngym.models.waves
from aligngym import models
from aligngym.models.units import arcsec
from aligngym.scenarios.config import load_scenario
from aligngym.scenarios.fidelity import fidelity_errors

OPTIONS = (  # timestep (s), force period (steps), smooth truth
    (0.002, 5, False),     # before: wrench at 100 Hz, MuJoCo's discrete motion
    (0.002, 1, False),
    (0.001, 1, False),
    (0.0005, 1, False),
    (0.002, 5, True),
    (0.002, 1, True),      # the default
)


WaveShipWorld = models.waves.WaveShipWorld


def world_with(timestep: float, force_period: int, smooth: bool) -> type:
    """WaveShipWorld with other defaults (``simulate`` builds the world itself)."""

    class Variant(WaveShipWorld):
        smooth_truth = smooth

        def __init__(self, motion, rng):
            super().__init__(motion, rng, timestep=timestep, force_period=force_period)
    return Variant


def measure(name: str, duration: float) -> tuple[dict[str, float], float]:
    config = load_scenario(name).with_options(duration=duration)
    start = time.perf_counter()
    err = fidelity_errors(config, seed=1)
    return err, time.perf_counter() - start


def report(label: str, err: dict[str, float], seconds: float) -> None:
    print(f"{label:34s} {err['attitude_rad'] / arcsec:9.4f} {err['velocity_m_s'] * 1e3:9.4f}"
          f" {err['position_m']:9.4f} {seconds:9.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=600.0)
    duration = parser.parse_args().duration
    print(f"{duration:g} s at 100 Hz, seed 1    {'arcsec':>9s} {'mm/s':>9s} {'m':>9s} "
          f"{'wall s':>9s}")
    report("prescribed ship (reference)", *measure("ship-sway-rotary", duration))
    try:
        for timestep, period, smooth in OPTIONS:
            models.waves.WaveShipWorld = world_with(timestep, period, smooth)
            label = (f"waves {timestep * 1e3:g} ms, wrench /{period}, "
                     f"{'smooth' if smooth else 'discrete'}")
            report(label, *measure("ship-waves-rotary", duration))
    finally:
        models.waves.WaveShipWorld = WaveShipWorld


if __name__ == "__main__":
    main()
