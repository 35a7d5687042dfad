"""The sensor role: what every sensor a scenario carries besides its IMU (the gimbal
encoders, the odometer, the GNSS receiver, a Doppler velocity log, a user's own) is
and does, and the registry that maps a scenario file's table to it.

A sensor is a class registered with ``register_sensor``: its TOML table (``section``),
the units of that table's keys, its presets and spec dataclass, the worlds that can carry
it and the random stream it draws from; ``measure`` turns the truth an episode's motion
gives (``SensorTruth``) into a typed record (``SensorRecord``). One file plus a table in
a scenario file adds a sensor: ``sensors.suite`` imports every module of this package,
and a user's module registers its class when it is imported."""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from aligngym.models.schedule import Schedule

if TYPE_CHECKING:
    from aligngym.models.earth import TangentPlane
    from aligngym.models.truth import NavigationTruth


@dataclass(frozen=True)
class SensorTruth:
    """What an episode's sensors see of its motion. truth: at the IMU interval boundaries
    (N+1 samples; q_b_n carrier body (R, F, U) to ENU, v_n of the IMU site, m/s);
    plane: the local tangent plane at the scenario's origin; antenna: the GNSS antenna's
    (t (G,) s, position (G, 3) m, velocity (G, 3) m/s in the plane) at the fix times, or
    None; rear_wheels: the car's driven wheels' unwrapped angles (N+1, 2) rad, or None;
    has_gimbal: the IMU turns on a gimbal. Arrays may be shared: read-only."""

    truth: NavigationTruth
    plane: TangentPlane
    antenna: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    rear_wheels: np.ndarray | None = None
    has_gimbal: bool = False


@dataclass(frozen=True)
class SensorRecord:
    """A sensor's output of one episode: a frozen dataclass of arrays. ``arrays()`` gives
    them by their names in the exported data files (``PREFIX`` + field name, unless the
    field says otherwise in ``NAMES``)."""

    PREFIX: ClassVar[str] = ""
    NAMES: ClassVar[dict[str, str]] = {}

    def arrays(self) -> dict[str, np.ndarray]:
        """The record's arrays, by their export names (a field that is None is left out)."""
        return {self.NAMES.get(f.name, self.PREFIX + f.name): np.asarray(getattr(self, f.name))
                for f in fields(self) if getattr(self, f.name) is not None}


@dataclass(frozen=True)
class FaultLog(SensorRecord):
    """Every fault injected into an episode (F,): its kind ("imu_spike", "gnss_outage",
    "odometer_slip", ...), start and end, s."""

    PREFIX = "fault_"
    kind: np.ndarray
    start: np.ndarray
    end: np.ndarray


class Sensor(ABC):
    """One sensor of a scenario, built from its spec (the section's dataclass, in SI:
    the file's _deg and _arcsec keys arrive in rad, _hz in Hz, _m in m, _s in s).

    Class attributes: ``section`` (its scenario-file table and the key of its record in
    ``Episode.measurements``); ``spec_type`` (the table's dataclass); ``units`` (each key's
    unit suffix in the file: "_m", "_s", "_hz", "_deg", "_deg_s", "_arcsec" or "" for
    none); ``presets`` (name -> spec, for ``preset = "..."``); ``needs`` (what the world
    must give it: "antenna" (a GNSS antenna on the carrier), "wheels" (a car's), "hull"
    (a hull under water); a world declares what it ``gives``); ``stream`` (its random
    stream of the episode, ``simulate.episode_rngs``: a name of its own);
    ``schedulable`` (the spec's fields a [[schedule]] entry may change within the
    episode: ``measure`` reads them through ``profile``)."""

    section: ClassVar[str]
    spec_type: ClassVar[type]
    units: ClassVar[dict[str, str]] = {}
    presets: ClassVar[dict[str, Any]] = {}
    needs: ClassVar[frozenset[str]] = frozenset()
    stream: ClassVar[str]
    schedulable: ClassVar[tuple[str, ...]] = ()

    def __init__(self, spec: Any, schedule: Schedule = Schedule()) -> None:
        self.spec, self.schedule = spec, schedule

    def profile(self, name: str, t: np.ndarray) -> np.ndarray:
        """The spec's field ``name`` at times t (N,) s, as the schedule changes it."""
        return self.schedule.profile(self.section, name, getattr(self.spec, name), t)

    def check(self, duration: float, imu_rate: float, world: str) -> None:
        """Raise ValueError naming ``section.field`` where the spec cannot serve a run of
        duration (s) at imu_rate (Hz) in world (the spec's own checks ran already)."""

    @abstractmethod
    def measure(self, truth: SensorTruth, rng: np.random.Generator, ideal: bool
                ) -> SensorRecord:
        """The sensor's record of one episode; ideal: without any error (no draw needed
        from rng)."""

    def faults(self, record: SensorRecord, duration: float
               ) -> list[tuple[str, float, float]]:
        """The faults the spec injects, as (kind, start s, end s) rows of the episode's
        fault record (``Episode.faults``)."""
        return []


def outside_windows(t: np.ndarray, windows: tuple[tuple[float, float], ...]
                    ) -> np.ndarray:
    """(N,) True where the times t (N,) s lie in none of the [start, end) windows (s): a
    receiver's outages, a DVL's dropouts."""
    keep = np.ones(np.shape(t), bool)
    for start, end in windows:
        keep &= ~((t >= start) & (t < end))
    return keep


def window_faults(kind: str, windows: tuple[tuple[float, float], ...], duration: float
                  ) -> list[tuple[str, float, float]]:
    """Fault rows (kind, start s, end s) of the windows that begin within a run of
    duration s, each cut at its end."""
    return [(kind, start, min(end, duration)) for start, end in windows if start < duration]


def same_class(a: type, b: type) -> bool:
    """The same class, or its module reloaded (a registry may take it again)."""
    return (a.__module__, a.__qualname__) == (b.__module__, b.__qualname__)


SENSORS: dict[str, type[Sensor]] = {}
"""Registered sensors by their section (``register_sensor``)."""


RESERVED_SECTIONS = ("origin", "run", "imu", "motion", "filter", "indexer", "faults",
                     "schedule", "name", "paper", "experiment", "world")
"""A scenario file's own tables and keys: no sensor's section."""
RESERVED_STREAMS = ("motion", "imu_realization", "imu_noise")
"""The episode's random streams of the world and the IMU: no sensor's stream."""


def register_sensor(cls: type[Sensor]) -> type[Sensor]:
    """Register a sensor class under its section (a class decorator). Refused: a section
    that is one of the file's own tables or keys (``RESERVED_SECTIONS``) or another
    class's; a stream of the world's or the IMU's (``RESERVED_STREAMS``) or another
    sensor's (a sensor's draws never change another's)."""
    name = getattr(cls, "section", "")
    if not (isinstance(name, str) and name.isidentifier()) or name in RESERVED_SECTIONS:
        raise ValueError(f"sensor section {name!r} must be a name other than "
                         + ", ".join(RESERVED_SECTIONS))
    held = SENSORS.get(name)
    if held is not None and not same_class(held, cls):
        raise ValueError(f"sensor section [{name}] is taken by {held.__module__}."
                         f"{held.__qualname__}")
    stream = getattr(cls, "stream", None)
    if not isinstance(stream, str):
        raise ValueError(f"sensor {cls.__name__} must name its random stream")
    taken = [s for s in SENSORS.values() if s.stream == stream and not same_class(s, cls)]
    if stream in RESERVED_STREAMS or taken:
        raise ValueError(f"sensor {cls.__name__}'s stream {stream!r} is taken (by "
                         + (taken[0].__name__ if taken else "the world or the IMU")
                         + "); name a stream of its own")
    SENSORS[name] = cls
    return cls
