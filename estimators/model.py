"""The model side of a Gaussian filter: a named state layout and, per epoch, the process
and measurement maps with their noise (SPEC 5; STYLE "the filter family as
composition").

A fine-alignment model (``InertialFineModel``, ``EulerLargeMisalignmentModel``, ...) hands
the generic filter one ``Transition`` and one ``Observation`` per epoch. Each is a map of
the state with additive Gaussian noise, given in the forms the model can offer:

- ``matrix``: the map is linear, y = M x (the KF's fast path; every rule is exact);
- ``fn``: the map itself, batched over episodes and points, x (B, P, n) -> y (B, P, d);
- ``jacobian``: dy/dx at the mean (B, n) -> (B, d, n), for the EKF (central differences
  of ``fn`` when absent);
- ``conditional``: the conditionally linear form y = F(zeta) x + g(zeta) in which only
  the states ``nonlinear`` (zeta) enter nonlinearly (000 eqs. 21-24), for the
  reduced-dimension Gauss-Hermite rule.

Batch axis B = episodes, P = integration points. Angles listed in ``angles`` are wrapped
to (-pi, pi] and averaged around a reference, so that points straddling +-pi average
correctly.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Callable, TypeVar

import numpy as np

Array = np.ndarray
Batch = TypeVar("Batch")


def stack_episodes(parts: list[Batch], shared: tuple[str, ...] = ("t",)) -> Batch:
    """One batch from several episodes' batched dataclasses (leading axis B): the fields
    in ``shared`` (time grids) must be equal and are taken once, the others are
    concatenated along the batch axis; ValueError otherwise."""
    if not parts:
        raise ValueError("no episodes to stack")
    for other in parts[1:]:
        if not all(np.array_equal(getattr(other, n), getattr(parts[0], n)) for n in shared):
            raise ValueError("episodes must share the filter time grid")
    return type(parts[0])(**{
        f.name: (getattr(parts[0], f.name) if f.name in shared
                 else np.concatenate([getattr(p, f.name) for p in parts]))
        for f in fields(parts[0])})


def wrap_angle(a: Array) -> Array:
    """Angles wrapped to (-pi, pi], rad."""
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


@dataclass(frozen=True)
class StateLayout:
    """Named blocks of a state vector; ``angles``: indices of states that are angles
    (rad, wrapped to (-pi, pi])."""

    blocks: dict[str, slice]
    angles: tuple[int, ...] = ()

    @property
    def n(self) -> int:
        return max(s.stop for s in self.blocks.values())

    def __getitem__(self, name: str) -> slice:
        return self.blocks[name]

    def indices(self, *names: str) -> np.ndarray:
        """Flat indices of the named blocks, in order."""
        return np.concatenate([np.arange(self.n)[self.blocks[n]] for n in names])


@dataclass
class GaussianMap:
    """y = map(x) + v, v ~ N(0, noise). Give ``matrix`` (linear) or ``fn`` (nonlinear),
    optionally ``jacobian`` and ``conditional`` (see the module docstring).

    noise: (B, d, d); matrix: (B, d, n); angles: indices of y that are angles;
    nonlinear: indices of the states on which ``conditional`` depends nonlinearly.
    """

    noise: Array
    matrix: Array | None = None
    fn: Callable[[Array], Array] | None = None
    jacobian: Callable[[Array], Array] | None = None
    conditional: Callable[[Array], tuple[Array, Array]] | None = None
    nonlinear: tuple[int, ...] = ()
    angles: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if (self.matrix is None) == (self.fn is None):
            raise ValueError("a GaussianMap needs either a matrix (linear) or a function, "
                             "not both")

    @property
    def linear(self) -> bool:
        return self.matrix is not None

    def __call__(self, x: Array) -> Array:
        """The map at points x (B, P, n) -> (B, P, d)."""
        if self.fn is not None:
            return self.fn(x)
        return np.einsum("bij,bpj->bpi", self.matrix, x)

    def jacobian_at(self, x: Array, step: Array | float = 1e-6) -> Array:
        """dy/dx (B, d, n) at x (B, n): the matrix, the model's Jacobian, or central
        differences of ``fn`` with the given step (scalar or per state (n,))."""
        if self.matrix is not None:
            return self.matrix
        if self.jacobian is not None:
            return self.jacobian(x)
        n = x.shape[-1]
        h = np.broadcast_to(np.asarray(step, dtype=float), (n,))
        offsets = np.concatenate([np.diag(h), -np.diag(h)])           # (2n, n)
        y = self.fn(x[:, None, :] + offsets[None])                      # (B, 2n, d)
        diff = y[:, :n] - y[:, n:]
        if self.angles:
            idx = list(self.angles)
            diff[..., idx] = wrap_angle(diff[..., idx])
        return np.swapaxes(diff / (2.0 * h[None, :, None]), -1, -2)


@dataclass
class Transition(GaussianMap):
    """One epoch's process: x_k = f(x_{k-1}) + w, w ~ N(0, Q = noise)."""


@dataclass
class Observation(GaussianMap):
    """One epoch's measurement z (B, m) = h(x) + v, v ~ N(0, R = noise).

    NaN components of z are missing: the update uses the others (none: no update).
    t: time of the measurement, s (one per episode, (B,), with per-episode epochs).
    axes: optional (B, m, m) rotation from the measurement axes to local East, North, Up
    (per-axis adaptation along E, N, U).
    motion: optional (B,) bool, the carrier is moving (policies that act only in motion).
    directions: optional (B, m, n), per measurement the unit direction in state space of
    the state it measures directly (zero row: none), for selective weights (001 eq. 15-20).
    """

    z: Array | None = None
    t: float | Array = 0.0
    axes: Array | None = None
    motion: Array | None = None
    directions: Array | None = None

    def valid(self) -> Array:
        """(B, m) True where the measurement component is present and finite."""
        return np.isfinite(self.z)


Scale = float | Array
"""A noise multiplier: one number for every episode, or one per episode ((B,) or (B, 1, 1))."""


def whole_steps(duration: float, step: float) -> int:
    """Whole steps of step s within duration s (floor: a step that would end after the
    data is not taken; 5 s in 0.3 s steps is 16), with a tolerance of 1e-9 of a step
    for float rounding (0.3 s in 0.1 s steps is 3, though 0.3 / 0.1 < 3)."""
    return int(np.floor(duration / step + 1e-9))


Epoch = int | Array
"""An epoch boundary index: one int for every episode of the batch (a campaign), or one
per episode, (B,) ints (the vector env's episodes, each at its own epoch)."""


def at_epoch(values: Array, k: Epoch) -> Array:
    """values (B, K+1, ...) (or (1, K+1, ...), shared by the batch) at each episode's
    epoch k (``Epoch``): (B, ...) (for shared values and one k: (1, ...))."""
    if np.ndim(k) == 0:
        return values[:, k]
    return values[0 if values.shape[0] == 1 else np.arange(len(k)), k]


def set_at_epoch(values: Array, k: Epoch, new: Array) -> None:
    """values (B, K+1, ...) at each episode's epoch k (``Epoch``) set to new (B, ...)."""
    if np.ndim(k) == 0:
        values[:, k] = new
    else:
        values[np.arange(len(k)), k] = new


def epoch_of(k: Epoch, members: Array) -> Epoch:
    """The epoch of the episodes ``members`` (indices into the batch): k itself for
    one epoch for all, else k[members]."""
    return k if np.ndim(k) == 0 else k[members]


def epoch_time(t: Array, k: Epoch) -> float | Array:
    """The time grid t (K+1,) s at boundary k: a float, or (B,) for one epoch per
    episode."""
    return float(t[k]) if np.ndim(k) == 0 else t[k]


def add_once_per_epoch(total: Array, last: Array, k: Epoch,
                       increment: Callable[[], Array]) -> tuple[Array, Array]:
    """A running sum over epochs (B, d) that an observation reads: increment() (B, d),
    epoch k's term, added for the episodes whose last epoch summed (B,) is not k yet
    (an epoch observed twice adds once); epochs must come in order (else ValueError).
    Returns the sum and the last epochs."""
    due = last != k
    if not due.any():
        return total, last
    if np.any(due & (k != last + 1)):
        raise ValueError(f"observation({k}) after observation({last}): epochs must be "
                         "taken in order")
    return np.where(due[:, None], total + increment(), total), np.where(due, k, last)


def per_member(scale: Scale, batch: int) -> Array:
    """A noise multiplier as (B, 1, 1), to multiply a (B, n, n) covariance; ``[:, 0]``
    gives (B, 1) for a (B, n) diagonal."""
    if isinstance(scale, (int, float)):          # one number (most calls): no broadcast
        return np.full((batch, 1, 1), float(scale))
    return np.broadcast_to(np.reshape(np.asarray(scale, float), (-1, 1, 1)), (batch, 1, 1))


class FilterModel:
    """A fine-alignment model run by ``estimators.alignment.AlignmentRun``: its state
    layout, its initial state and covariance, one transition and observation per epoch,
    the feedback of the estimate into the model's own navigation solution, and the
    attitude it implies.

    Subclasses set ``layout``, ``batch`` (B episodes), ``epochs`` (K) and ``t`` ((K+1,) s
    at the epoch boundaries) and implement the methods below.
    """

    layout: StateLayout
    batch: int
    epochs: int
    t: Array
    scratch: tuple[str, ...] = ()
    """Attributes that hold values of the current epoch only (from its transition to
    its observation): left alone when new episodes take over some of the batch's
    (``estimators.members.copy_members``); every other attribute is per-episode state
    or the same for every episode."""

    def initial(self) -> tuple[Array, Array]:
        """x0 (B, n) and P0 (B, n, n)."""
        raise NotImplementedError

    def transition(self, k: int, q_scale: tuple[Scale, Scale] = (1.0, 1.0)) -> Transition:
        """Process from boundary k to k+1; q_scale multiplies the (gyro, accelerometer)
        white-noise variances (1: as tuned), each a number or one per episode
        (``per_member``)."""
        raise NotImplementedError

    def observation(self, k: int, r_scale: Scale = 1.0) -> Observation:
        """Measurement at boundary k+1; r_scale multiplies R (1: as tuned), a number or
        one per episode (``per_member``)."""
        raise NotImplementedError

    def feedback(self, x: Array, P: Array, live: Array) -> tuple[Array, Array]:
        """Inject the estimate into the model's navigation solution for the live (B,)
        episodes and return the reset state and covariance (default: open loop)."""
        return x, P

    def series(self) -> dict[str, Array]:
        """Time series (B, K+1, ...) the model keeps at the epoch boundaries besides the
        attitude (e.g. its navigation solution); none by default."""
        return {}

    def attitude(self, k: int, x: Array) -> Array:
        """Estimated C_s^n (B, 3, 3) at boundary k given the filter state x (B, n)."""
        raise NotImplementedError

    def attitude_sigma(self, k: int, P: Array) -> Array:
        """1-sigma misalignment along E, N, U (B, 3), rad, from P (B, n, n)."""
        raise NotImplementedError
