"""A scenario's sensors besides its IMU, built from its tables, and the one sequence that
measures an episode with them. Importing this module registers every sensor module of
this package (``sensors.base``); a user's sensor registers when its module is imported."""
from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Mapping

import numpy as np

import aligngym.sensors as _package
from aligngym.models.schedule import Schedule
from aligngym.sensors.base import SENSORS, Sensor, SensorRecord, SensorTruth


def _register_package_sensors() -> None:
    """Import every module of aligngym.sensors, whose sensors register themselves."""
    for info in pkgutil.iter_modules(_package.__path__):
        importlib.import_module(f"{_package.__name__}.{info.name}")


_register_package_sensors()


def sensor_types() -> dict[str, type[Sensor]]:
    """The registered sensors by section, in registration order."""
    return dict(SENSORS)


class SensorSuite:
    """The sensors of one scenario (``of``), measured in one sequence (``measure``)."""

    def __init__(self, sensors: list[Sensor]) -> None:
        self.sensors = sensors

    @classmethod
    def of(cls, specs: Mapping[str, object], schedule: Schedule = Schedule()
           ) -> "SensorSuite":
        """The suite of a scenario's sensor specs (section -> spec) under its schedule."""
        return cls([SENSORS[section](spec, schedule) for section, spec in specs.items()])

    def measure(self, truth: SensorTruth, rng: Callable[[str], np.random.Generator],
                ideal: bool) -> dict[str, SensorRecord]:
        """Every sensor's record of one episode, by section; rng(stream): the episode's
        random stream of that name."""
        return {s.section: s.measure(truth, rng(s.stream), ideal) for s in self.sensors}

    def faults(self, records: Mapping[str, SensorRecord], duration: float
               ) -> list[tuple[str, float, float]]:
        """The (kind, start s, end s) rows of the faults the sensors' specs inject."""
        return [row for s in self.sensors for row in s.faults(records[s.section], duration)]
