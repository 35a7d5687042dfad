"""What an experiment needs of a scenario, declared once (``Experiment.requires``) from
reusable checks, each a one-line error naming what is missing before any episode is
simulated."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from aligngym.scenarios.config import ConfigError, ScenarioConfig, SettingError


def experiment_name(experiment: Any) -> str:
    """The name errors give the experiment: its paper's ("paper001")."""
    return f"paper{experiment.paper}"


@dataclass(frozen=True)
class SensorTable:
    """The scenario carries the sensor of this table (``sensors.base``: "gps",
    "odometer", "dvl", ...)."""

    section: str

    def check(self, experiment: Any, config: ScenarioConfig) -> None:
        if self.section not in config.sensor_specs():
            article = "an" if self.section[0] in "aeiou" else "a"
            raise ConfigError(f"{experiment_name(experiment)} needs {article} "
                              f"[{self.section}] table; scenario {config.name!r} has none")


@dataclass(frozen=True)
class StrapdownImu:
    """The IMU is fixed to the carrier (no gimbal turns it)."""

    def check(self, experiment: Any, config: ScenarioConfig) -> None:
        if config.motion.has_gimbal:
            raise ConfigError(f"{experiment_name(experiment)} needs a strapdown IMU: "
                              "motion.gimbal_outer_rate_deg_s and gimbal_inner_rate_deg_s "
                              "must be 0")


@dataclass(frozen=True)
class StepOnFixes:
    """The filter step (the experiment's ``filter_step``, s) is a whole number (>= 1) of
    the GNSS receiver's fix intervals; ``noun`` names the receiver in the error."""

    noun: str = "GNSS"

    def check(self, experiment: Any, config: ScenarioConfig) -> None:
        fix = 1.0 / config.gps.rate
        step = experiment.filter_step
        ratio = step / fix
        if not (abs(ratio - round(ratio)) < 1e-9 and round(ratio) >= 1):
            raise SettingError("filter_step", step, f"= {step:g} s must be a multiple of "
                               f"the {self.noun} interval {fix:g} s")
