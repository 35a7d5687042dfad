"""Replacing some episodes of a running batch by new ones (the vector env's slots that
reset while the others go on): every per-episode array of a model, a filter or their
parts takes the rows of a freshly made object of the same kind for the new episodes.

``copy_members(target, fresh, members)`` walks both objects' attributes alike: an array
whose leading axis is the batch (B in target, len(members) in fresh) gets its rows
``members`` replaced; dicts, lists, tuples and objects are walked in; everything else
(time grids, tunings, constants) must be equal in both, else ``MemberStateError`` names
the attribute. So a model or policy that keeps per-episode state in anything but an
array along the batch axis fails loudly instead of carrying one episode's state into
the next.
"""
from __future__ import annotations

from dataclasses import is_dataclass

import numpy as np


class MemberStateError(ValueError):
    """A state that is neither per-episode (batch axis first) nor the same in both."""


def _rows(old, new, batch: int, count: int) -> bool:
    return (isinstance(old, np.ndarray) and isinstance(new, np.ndarray) and old.ndim >= 1
            and old.ndim == new.ndim and old.shape[0] == batch and new.shape[0] == count
            and old.shape[1:] == new.shape[1:])


def _equal(old, new) -> bool:
    if isinstance(old, np.ndarray) or isinstance(new, np.ndarray):
        return (isinstance(old, np.ndarray) and isinstance(new, np.ndarray)
                and old.shape == new.shape
                and np.array_equal(old, new, equal_nan=old.dtype.kind in "fc"))
    try:
        return bool(old == new)
    except (TypeError, ValueError):
        return False


def _copied(old, new, members: np.ndarray, batch: int, path: str):
    """old with the rows ``members`` taken from new (the same object where it can be
    changed in place, else a new one)."""
    count = len(members)
    if _rows(old, new, batch, count):
        if not old.flags.writeable:            # a broadcast view or a read-only array
            old = old.copy()
        old[members] = new
        return old
    if isinstance(old, dict) and isinstance(new, dict) and old.keys() == new.keys():
        for key in new:
            old[key] = _copied(old[key], new[key], members, batch, f"{path}[{key!r}]")
        return old
    if isinstance(old, list) and isinstance(new, list) and len(old) == batch \
            and len(new) == count:
        for b, value in zip(members, new):
            old[b] = value
        return old
    if isinstance(old, tuple) and isinstance(new, tuple) and len(old) == len(new):
        return type(old)(_copied(o, n, members, batch, f"{path}[{i}]")
                         for i, (o, n) in enumerate(zip(old, new)))
    if type(old) is type(new) and hasattr(new, "__dict__") and not callable(new) \
            and not isinstance(new, type):
        copy_members(old, new, members, batch=batch, path=path)
        return old
    if old is new or _equal(old, new):
        return old
    raise MemberStateError(f"{path}: {type(old).__name__} is neither one row per episode "
                           "(batch axis first) nor the same for every episode, so a new "
                           "episode cannot take it over")


def copy_members(target, fresh, members, batch: int | None = None,
                 skip: tuple[str, ...] = (), path: str | None = None) -> None:
    """Replace episodes ``members`` (indices into target's batch of B) of ``target`` by
    those of ``fresh`` (an object of the same type over len(members) new episodes, in
    that order): see the module docstring. batch: B (default ``target.batch``); skip:
    attributes left as they are (the batch size itself, scratch values of one epoch)."""
    members = np.asarray(members, int)
    batch = target.batch if batch is None else batch
    path = type(target).__name__ if path is None else path
    missing = (set(vars(target)) ^ set(vars(fresh))) - set(skip)
    if missing:
        raise MemberStateError(f"{path}.{sorted(missing)[0]}: set on one object only (state "
                               "made after the episodes began), so a new episode cannot "
                               "take it over; declare it scratch if it lives one epoch")
    for name, new in vars(fresh).items():
        if name in skip or name == "batch":
            continue
        old = vars(target)[name]
        value = _copied(old, new, members, batch, f"{path}.{name}")
        if value is not old:
            if is_dataclass(target):
                object.__setattr__(target, name, value)
            else:
                setattr(target, name, value)
