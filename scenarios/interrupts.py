"""Ctrl-C that is never lost. Python raises KeyboardInterrupt wherever the main thread
happens to be, and inside a finaliser (``__del__``, a weakref callback) the exception is
only printed and dropped, so a long campaign could run on after a Ctrl-C. The command
line installs ``remember_interrupts``: the handler records the interrupt as well as
raising it, and the campaign's checkpoints (``raise_if_interrupted``: each finished
episode, each filter run) raise it again if it was dropped."""
from __future__ import annotations

import signal
from contextlib import contextmanager
from typing import Iterator

_interrupted = False


def _handler(signum, frame) -> None:
    global _interrupted
    _interrupted = True
    raise KeyboardInterrupt


@contextmanager
def remember_interrupts() -> Iterator[None]:
    """Within the block, the recording SIGINT handler (main thread only; the CLI's
    commands run in it); afterwards the previous handler, and no interrupt remembered."""
    global _interrupted
    _interrupted = False
    try:
        previous = signal.signal(signal.SIGINT, _handler)
    except ValueError:             # not the main thread (an embedding): Python's default
        previous = None
    try:
        yield
    finally:
        _interrupted = False
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def raise_if_interrupted() -> None:
    """Raise KeyboardInterrupt if a Ctrl-C arrived (and was dropped on the way)."""
    if _interrupted:
        raise KeyboardInterrupt
