"""Prepared episodes: what the filters need of one simulated episode and its truth, saved
and loaded as one .npz each (the campaign's episode storage), and the screened
simulation every pipeline starts from."""
from __future__ import annotations

from abc import ABC
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from aligngym.scenarios.atomic import atomic_path
from aligngym.scenarios.config import ScenarioConfig


@dataclass
class PreparedEpisode(ABC):
    """What the filters need of one episode and its truth at the filter epochs.

    Every prepared episode has: seed; C_s_n_true, C_b_n_true, C_s_b (K+1, 3, 3) at the
    epoch boundaries (truth IMU and body attitude, the gimbal as the encoders read it);
    gyro_bias (3,) rad/s and accel_bias (3,) m/s^2, the drawn constant sensor errors;
    lat (rad) and h (m), the known position. Experiments add their own fields. It saves
    itself as one .npz, atomically: by default every field as one array (fields annotated
    int or float come back as numbers); episodes holding structures override ``arrays``
    and ``from_arrays`` (the fault flags are saved and restored for every episode).
    """

    seed: int
    C_s_n_true: np.ndarray
    C_b_n_true: np.ndarray
    C_s_b: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    lat: float
    h: float
    fault_kind: np.ndarray = field(default_factory=lambda: np.array([], str), kw_only=True)
    fault_time: np.ndarray = field(default_factory=lambda: np.zeros(0), kw_only=True)
    """The data faults the pipeline's screen flagged (``estimators.screen``): kind
    (F,) str and the time (F,) s of each one's first sample."""

    @property
    def fine_start(self) -> float:
        """Scenario time of the fine alignment's start (its first epoch), s. Episodes with
        a ``t`` (scenario time of the epochs) give its first; the others override. The
        campaign's analysis counts its times from here (``FineResult.t - t[0]``)."""
        return float(self.t[0])

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything needed to rebuild the episode, as arrays."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_arrays(cls, f: Any) -> "PreparedEpisode":
        """Rebuild from ``arrays()`` (an npz file or a dict)."""
        number = {"int": int, "float": float}
        return cls(**{field.name: number.get(field.type, np.asarray)(f[field.name])
                      for field in fields(cls)})

    def save(self, path: Path) -> None:
        """Write the episode to path atomically: a file on disk is a complete episode
        (temporary names are unique, so concurrent writers do not collide); it carries
        its layout's version ("schema", ``EPISODE_SCHEMA``)."""
        with atomic_path(path) as tmp:
            np.savez(tmp, **{**self.arrays(), "fault_kind": np.asarray(self.fault_kind, str),
                             "fault_time": np.asarray(self.fault_time, float),
                             "schema": np.asarray(EPISODE_SCHEMA)})

    @classmethod
    def load(cls, path: Path) -> "PreparedEpisode":
        """The episode saved in path. A file that is not this class's episode (not an npz
        archive, damaged, another schema, a field missing, text where numbers go) is a
        one-line ValueError saying what is wrong; OSError passes (the file cannot be
        read)."""
        try:
            # The file opened here: np.load leaves a file it opened itself open when the
            # archive is damaged (a ResourceWarning, a descriptor held until collected).
            with open(path, "rb") as handle:
                archive = np.load(handle)
                if not isinstance(archive, np.lib.npyio.NpzFile):
                    raise ValueError("a single array, not an episode's npz archive")
                with archive as f:
                    return cls._from_archive(f)
        except OSError:
            raise
        except Exception as exc:       # any decoding error of a damaged file: one line
            text = f"{exc}".splitlines()[0][:120] if f"{exc}" else ""
            raise ValueError(text if isinstance(exc, _Refused)
                             else f"{type(exc).__name__}: {text}") from None

    @classmethod
    def _from_archive(cls, f: Any) -> "PreparedEpisode":
        schema = f["schema"].item() if "schema" in f.files else EPISODE_SCHEMA
        if schema != EPISODE_SCHEMA:
            raise _Refused(f"episode file schema {schema!r}, not this aligngym's "
                           f"({EPISODE_SCHEMA})")
        text = [name for name in f.files if name != "fault_kind"
                and f[name].dtype.kind not in "biufc"]
        if text:
            raise _Refused(f"array {text[0]!r} holds {f[text[0]].dtype} data, not numbers")
        try:
            return cls.from_arrays(f)
        except KeyError as exc:            # the names the class reads
            raise _Refused(f"no array {exc.args[0]!r}: not a {cls.__name__} file") from None


class _Refused(ValueError):
    """What is wrong with an episode file, said in full."""


EPISODE_SCHEMA = 1
"""The layout of the episode files (an array "schema" in each; a file without one is of
this layout): a file of another schema is refused, and simulated again where it is read
(docs/campaign-directory.md)."""


@dataclass
class GnssEpisode(PreparedEpisode):
    """An episode cut into filter epochs with GNSS fixes at their boundaries: t (K+1,) s
    epoch boundaries; imu_dt s; dtheta, dv (K, S, 3) raw increments per epoch; gps_lat,
    gps_lon (rad), gps_h (m), gps_v_n (m/s, ENU) of the antenna at the boundaries (NaN
    without a fix)."""

    t: np.ndarray
    imu_dt: float
    dtheta: np.ndarray
    dv: np.ndarray
    gps_lat: np.ndarray
    gps_lon: np.ndarray
    gps_h: np.ndarray
    gps_v_n: np.ndarray

    def gnss_inputs(self) -> dict[str, np.ndarray]:
        """The fields every GNSS-aided model input takes (``loose_gps.GpsInsInputs``), as
        a batch of one, the time from the first epoch."""
        return {"t": self.t - self.t[0], "imu_dt": self.imu_dt, "dtheta": self.dtheta[None],
                "dv": self.dv[None], "gps_lat": self.gps_lat[None],
                "gps_lon": self.gps_lon[None], "gps_h": self.gps_h[None],
                "gps_v_n": self.gps_v_n[None]}


def simulate_screened(config: ScenarioConfig, seed: int):
    """``simulate`` one episode and screen its data as a pipeline must before any filter
    (``estimators.screen``): the IMU (repaired), the gimbal encoders against the
    commands, the odometer against the IMU, the GNSS fixes. Returns the episode with the
    repaired increments on the run's grid, and the flags {"fault_kind", "fault_time"}
    (time order) for the prepared episode."""
    from aligngym.estimators.screen import screen_gimbal, screen_gnss, screen_imu, screen_odometer
    from aligngym.scenarios.simulate import imu_rails, simulate
    episode = simulate(config, seed=seed)
    screened = screen_imu(episode.imu_t, episode.dtheta, episode.dv, config.imu_interval,
                          config.imu_samples, *imu_rails(config))
    episode = replace(episode, imu_t=screened.imu_t, dtheta=screened.dtheta, dv=screened.dv)
    flags = [(screened.kind, screened.start)]
    if config.motion.has_gimbal:
        t = np.arange(config.imu_samples + 1) * config.imu_interval
        flags.append(screen_gimbal(t, episode.gimbal_encoder,
                                   config.motion.expected_gimbal_angles(t),
                                   config.encoder.resolution))
    odometer, fixes = episode.measurements.get("odometer"), episode.measurements.get("gps")
    if odometer is not None:
        forward = np.array([0.0, 1.0, 0.0])         # the body's forward axis (R, F, U)
        if config.motion.has_gimbal:                # in s: C_s_b^T e_F, mid-interval
            from aligngym.models.gimbal import gimbal_C_s_b
            enc = episode.gimbal_encoder
            forward = gimbal_C_s_b(0.5 * (enc[:-1] + enc[1:]))[:, 1, :]
        flags.append(screen_odometer(config.imu_interval, odometer.distance,
                                     np.sum(episode.dv * forward, axis=-1)))
    if fixes is not None:
        flags.append(screen_gnss(fixes.t, fixes.lat, fixes.lon, fixes.h, fixes.v_n,
                                 fixes.valid))
    kind = np.concatenate([k for k, _ in flags])
    time = np.concatenate([t for _, t in flags])
    order = np.argsort(time, kind="stable")
    return episode, {"fault_kind": kind[order], "fault_time": time[order]}


def episode_seeds(seed: int, episodes: int) -> list[int]:
    """Seeds of the campaign's episodes (episode i of campaign seed S: S * 10^6 + i)."""
    return [seed * 1_000_000 + i for i in range(episodes)]


