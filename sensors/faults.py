"""IMU data faults of a scenario (its ``[faults]`` table, SPEC 4.6), injected into the
increments after the sensor errors, and recorded with the episode so a test can check
their detection (``estimators.screen``).

Rows, times in s of the run: ``spikes = [[time_s, gyro_deg_s, accel_m_s2], ...]`` (one
sample's rate and specific force offset by these on every axis); ``saturation =
[[start_s, duration_s], ...]`` (the gyro and accelerometer x axes stuck at full scale);
``gaps = [[start_s, duration_s], ...]`` (samples missing from the stream: their
timestamps are absent, the others keep theirs); ``nans = [time_s, ...]`` (one sample of
NaN on every axis); ``gimbal_stalls = [[start_s, duration_s], ...]`` (the gimbal stops,
then catches up with its schedule, ``models.gimbal.stalled``; the scenario's motion
carries them, and the encoders show them).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aligngym.sensors import number_rows

GYRO_FULL_SCALE = math.radians(2000.0)
"""Full scale of a gyro without a finite measurement_range, rad/s (*assumed*, a common
MEMS range; the rail a saturation fault sticks to)."""
ACCEL_FULL_SCALE = 50.0 * 9.80665
"""Full scale of an accelerometer without a finite measurement_range, m/s^2 (*assumed*)."""


def full_scale(measurement_range: float, default: float) -> float:
    """The rail of a triad: its measurement_range if finite, else the default."""
    return measurement_range if math.isfinite(measurement_range) else default


@dataclass(frozen=True)
class ImuFaults:
    """The [faults] table: spikes (time s, gyro deg/s, accel m/s^2), saturation and gaps
    (start s, duration s) windows, nans (times s); see the module docstring."""

    spikes: tuple[tuple[float, float, float], ...] = ()
    saturation: tuple[tuple[float, float], ...] = ()
    gaps: tuple[tuple[float, float], ...] = ()
    nans: tuple[float, ...] = ()
    gimbal_stalls: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "spikes", number_rows(self.spikes, 3, "faults.spikes",
                                                       "[time_s, gyro_deg_s, accel_m_s2]"))
        for name in ("saturation", "gaps", "gimbal_stalls"):
            rows = number_rows(getattr(self, name), 2, f"faults.{name}",
                               "[start_s, duration_s]")
            if any(d <= 0.0 for _, d in rows):
                raise ValueError(f"faults.{name}: each duration must be > 0 s")
            object.__setattr__(self, name, rows)
        from aligngym.models.gimbal import STALL_CATCH_UP, STALL_RAMP
        stalls = sorted(self.gimbal_stalls)
        if any(d < STALL_RAMP for _, d in stalls):
            raise ValueError(f"faults.gimbal_stalls: each duration must be >= {STALL_RAMP:g} s "
                             "(the gimbal's stop)")
        if any(s2 < s1 + (1.0 + STALL_CATCH_UP) * d1
               for (s1, d1), (s2, _) in zip(stalls, stalls[1:])):
            raise ValueError("faults.gimbal_stalls: stalls must not overlap (each starts "
                             f"after the previous one's catch-up, {STALL_CATCH_UP:g} x its "
                             "duration after its end)")
        try:
            nans = tuple(float(v) for v in self.nans)
        except (TypeError, ValueError):
            raise ValueError("faults.nans must be a list of times (s)") from None
        if not all(math.isfinite(v) for v in nans):
            raise ValueError("faults.nans must be a list of finite times (s)")
        object.__setattr__(self, "nans", nans)

    def check(self, duration: float) -> None:
        """ValueError naming the field for a fault outside the run [0, duration] s."""
        for name, rows in (("spikes", self.spikes), ("saturation", self.saturation),
                           ("gaps", self.gaps), ("nans", [(t,) for t in self.nans]),
                           ("gimbal_stalls", self.gimbal_stalls)):
            for row in rows:
                end = row[0] + (row[1] if len(row) == 2 else 0.0)
                if not (0.0 < row[0] and end <= duration):
                    raise ValueError(f"faults.{name}: {row[0]:g} s (to {end:g} s) is outside "
                                     f"the run (0, {duration:g}] s")

    @property
    def any(self) -> bool:
        """Whether the IMU increments carry a fault (the stalls are in the motion)."""
        return bool(self.spikes or self.saturation or self.gaps or self.nans)

    def apply(self, imu_t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, dt: float,
              gyro_rail: float, accel_rail: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """The increments (M, 3) at end times imu_t (M,) s with the faults injected, and
        the record {"fault_kind": (F,) str, "fault_start": (F,) s, "fault_end": (F,) s}
        (the interval end times of the first and last sample each fault touches).
        Gaps remove samples (and their times) last."""
        dtheta, dv = dtheta.copy(), dv.copy()
        kinds, starts, ends = [], [], []

        def window(start: float, duration: float) -> np.ndarray:
            """Samples whose interval overlaps (start, start + duration]; for a duration
            of 0, the one whose interval holds start (the first ending after it)."""
            if duration == 0.0:
                k = int(np.searchsorted(imu_t, start, side="right"))
                return np.arange(k, min(k + 1, imu_t.size))
            return np.flatnonzero((imu_t > start) & (imu_t - dt < start + duration))

        def record(kind: str, idx: np.ndarray) -> None:
            if idx.size == 0:       # past the last sample (check() keeps faults inside)
                return
            kinds.append(kind)
            starts.append(float(imu_t[idx[0]]))
            ends.append(float(imu_t[idx[-1]]))

        for when, gyro, accel in self.spikes:
            k = window(when, 0.0)[:1]
            dtheta[k] += math.radians(gyro) * dt
            dv[k] += accel * dt
            record("spike", k)
        for start, duration in self.saturation:
            k = window(start, duration)
            dtheta[k, 0] = gyro_rail * dt
            dv[k, 0] = accel_rail * dt
            record("saturation", k)
        for when in self.nans:
            k = window(when, 0.0)[:1]
            dtheta[k] = np.nan
            dv[k] = np.nan
            record("nan", k)
        keep = np.ones(imu_t.size, bool)
        for start, duration in self.gaps:
            k = window(start, duration)
            keep[k] = False
            record("gap", k)
        return (imu_t[keep], dtheta[keep], dv[keep],
                {"fault_kind": np.array(kinds, dtype=str), "fault_start": np.array(starts),
                 "fault_end": np.array(ends)})
