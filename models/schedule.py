"""Disturbances that change within an episode: a scenario file's [[schedule]] list, each
entry a time, a ramp and new values of some parameters of one table ("gps", "imu", ...),
and the profile of one parameter over time that the sensors and worlds read."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ScheduleEntry:
    """From time (s) the parameters of table ``section`` go to ``values`` ((name, value)
    pairs, SI), linearly over ``ramp`` s (0: a step at ``time``)."""

    time: float
    ramp: float
    section: str
    values: tuple[tuple[str, float], ...]
    label: str = ""
    """How errors name the entry (a scenario file's ``schedule[i]``)."""


@dataclass(frozen=True)
class Schedule:
    """A scenario's schedule: its entries in time order. A parameter keeps its table's
    value until the first entry naming it; one entry's ramp ends before the next entry
    naming the same parameter starts (``check``)."""

    entries: tuple[ScheduleEntry, ...] = ()
    checked_to: float = 0.0
    """s: the run the entries were checked against (the file's), when a shorter run
    left out those it does not reach (``within``); 0: none left out."""

    def __bool__(self) -> bool:
        return bool(self.entries)

    def within(self, duration: float, checked_to: float) -> "Schedule":
        """The schedule of a run of duration s shorter than the checked_to s the entries
        were checked against: the entries after its end are left out (the run ends
        before they start), a ramp still going at its end is kept as it is, so that the
        shorter run is the longer one's beginning."""
        kept = tuple(e for e in self.entries if e.time <= duration)
        return Schedule(kept, max(checked_to, self.checked_to)) if kept else Schedule()

    def touches(self, section: str, name: str) -> bool:
        """Some entry changes section.name."""
        return any(e.section == section and name in dict(e.values) for e in self.entries)

    def changes(self, section: str, name: str) -> list[tuple[float, float, float]]:
        """(time s, ramp s, value) of the entries that change section.name, in time order."""
        return [(e.time, e.ramp, dict(e.values)[name]) for e in self.entries
                if e.section == section and name in dict(e.values)]

    def boundaries(self) -> tuple[float, ...]:
        """The times (s, sorted, distinct) where a change starts or a ramp ends: the edges
        of the segments within which every scheduled parameter is constant or on one
        ramp (an oracle that knows the schedule retunes at these)."""
        edges = {e.time for e in self.entries} | {e.time + e.ramp for e in self.entries
                                                   if e.ramp > 0.0}
        return tuple(sorted(edges))

    def profile(self, section: str, name: str, base: float, t: np.ndarray) -> np.ndarray:
        """The value of section.name at times t (N,) s: base, then each entry's value,
        reached linearly over its ramp from the value before it."""
        t = np.asarray(t, dtype=float)
        value = np.full(t.shape, float(base))
        before = float(base)
        for time, ramp, target in self.changes(section, name):
            if ramp > 0.0:
                share = np.clip((t - time) / ramp, 0.0, 1.0)
                ramped = np.where(share >= 1.0, target, before + (target - before) * share)
                value = np.where(t >= time, ramped, value)
            else:
                value = np.where(t >= time, target, value)
            before = target
        return value

    def check(self, duration: float) -> None:
        """ValueError naming the entry (``schedule[i]``, from 0) whose time is outside
        [0, duration] s, whose ramp is negative or outlasts the run, that comes before the
        previous entry, or that changes a parameter still ramping to an earlier value."""
        last, ramping = 0.0, {}
        duration = max(duration, self.checked_to)
        for i, e in enumerate(self.entries):
            where = e.label or f"schedule[{i}]"
            if not (np.isfinite(e.time) and 0.0 <= e.time <= duration):
                raise ValueError(f"{where}.time_s = {e.time:g} s is out of range "
                                 f"[0, {duration:g}]")
            if not (np.isfinite(e.ramp) and 0.0 <= e.ramp <= duration - e.time):
                raise ValueError(f"{where}.ramp_s = {e.ramp:g} s is out of range "
                                 f"[0, {duration - e.time:g}] (the run ends at {duration:g} s)")
            if e.time < last:
                raise ValueError(f"{where}.time_s = {e.time:g} s comes before the previous "
                                 f"entry's {last:g} s; list the entries in time order")
            for name, _ in e.values:
                end = ramping.get((e.section, name), -np.inf)
                if e.time < end:
                    raise ValueError(f"{where}: {e.section}.{name} still ramps to an "
                                     f"earlier value until {end:g} s")
                ramping[(e.section, name)] = e.time + e.ramp
            last = e.time
