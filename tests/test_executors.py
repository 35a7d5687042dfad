"""The executor registry: a campaign's episodes prepared by an executor registered by
name (``register_executor``) give the local executor's campaign, to the bit; names and
addresses are checked in one line; the command line offers the built-in ones."""
import numpy as np
import pytest

from aligngym.scenarios.campaign import EXECUTORS, register_executor, run_campaign
from aligngym.scenarios.campaign.executors import LocalProcesses, executor_named
from aligngym.scenarios.cli import build_parser
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.experiments import experiment

SMALL = dict(episodes=3, seed=4, filters=["ekf"], progress=False, workers=1)


class Backwards:
    """Prepares the seeds last first, in this process, and records what it was asked."""

    takes_address = True

    def __init__(self):
        self.asked = []

    def prepare(self, experiment, seeds, finish, workers, address):
        self.asked.append((list(seeds), workers, address))
        for seed in reversed(seeds):
            finish(seed, experiment.prepare_episode(seed))


@pytest.fixture
def backwards():
    executor = Backwards()
    register_executor("backwards", executor)
    yield executor
    del EXECUTORS["backwards"]


def test_a_registered_executor_runs_the_campaign(backwards):
    exp = experiment("paper002", fine_duration=60.0)
    local = run_campaign(exp, **SMALL)
    mine = run_campaign(exp, executor="backwards", address="cluster:1", **SMALL)
    assert backwards.asked == [(local.seeds, 1, "cluster:1")]
    assert mine.seeds == local.seeds
    for a, b in zip(mine.runs, local.runs):
        np.testing.assert_array_equal(a.error_n, b.error_n)
        np.testing.assert_array_equal(a.result.P, b.result.P)


def test_registry_refuses_in_one_line(backwards):
    with pytest.raises(ValueError, match="'backwards' is registered already"):
        register_executor("backwards", Backwards())
    with pytest.raises(TypeError, match="lacks prepare, takes_address"):
        register_executor("nothing", object())
    with pytest.raises(ConfigError, match=r"--executor 'dask' is unknown; valid: local, "
                                          r"ray, backwards$"):
        executor_named("dask")
    with pytest.raises(ConfigError, match="--address needs --executor ray or backwards"):
        executor_named("local", address="auto")
    assert isinstance(executor_named("local"), LocalProcesses)


def test_the_command_line_offers_the_built_in_executors():
    parser = build_parser()
    for command in ("bench", "bank"):
        sub = parser._subparsers._group_actions[0].choices[command]
        (action,) = [a for a in sub._actions if a.dest == "executor"]
        assert tuple(action.choices) == ("local", "ray") == tuple(EXECUTORS)[:2]


def _worker_threads():
    import gc

    from threadpoolctl import threadpool_info

    from aligngym.models import world
    return (world.ROLLOUT_THREADS, [pool["num_threads"] for pool in threadpool_info()],
            gc.get_freeze_count())


def test_a_worker_takes_one_thread_of_each_pool():
    """A local worker (``executors.start_worker``: preparation, filters, figures) runs its
    BLAS/OpenMP pools and MuJoCo's kinematic rollout on one thread: the processes take
    the cores (two workers with two BLAS threads each prepared episodes 2.5-3.5x slower);
    the objects it inherited are frozen out of its garbage collections."""
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor

    from aligngym.scenarios.campaign.executors import start_worker
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("fork"),
                             initializer=start_worker, initargs=(os.getpid(),)) as pool:
        rollout, pools, frozen = pool.submit(_worker_threads).result()
    assert rollout == 1 and pools and set(pools) == {1}
    assert frozen > 10_000              # the parent's objects, not a handful


class _Doubling:
    """A stand-in experiment whose episode is twice its seed."""

    def prepare_episode(self, seed: int) -> int:
        return 2 * seed


class _Refused(Exception):
    """Raised by a stand-in pool that only records its start method."""


def _recorded_contexts(monkeypatch, start: bool) -> list:
    """Replace the preparation's ProcessPoolExecutor by one that records its mp_context
    (and starts the real pool only if ``start``)."""
    from aligngym.scenarios.campaign import executors
    contexts, real = [], executors.ProcessPoolExecutor

    def recording(*args, mp_context=None, **kwargs):
        contexts.append(mp_context)
        if not start:
            raise _Refused
        return real(*args, mp_context=mp_context, **kwargs)

    monkeypatch.setattr(executors, "ProcessPoolExecutor", recording)
    return contexts


def test_the_preparation_workers_are_forked_whatever_the_default(monkeypatch):
    """On Linux the preparation pool forks its workers (they inherit the loaded kernels and
    send arrays as shared files), where the default start method is another too (Python
    3.14's forkserver, whose workers are not the campaign's children)."""
    import multiprocessing

    import pytest

    from aligngym.scenarios.campaign import executors
    if not executors.can_fork_workers():
        pytest.skip("workers are forked on Linux only")
    monkeypatch.setattr(multiprocessing.context._default_context, "_actual_context",
                        multiprocessing.get_context("forkserver"))
    assert multiprocessing.get_start_method() == "forkserver"
    contexts = _recorded_contexts(monkeypatch, start=True)
    done = {}
    executors._prepare_in_processes(_Doubling(), [1, 2, 3], done.__setitem__, workers=2)
    assert done == {1: 2, 2: 4, 3: 6}
    assert [c.get_start_method() for c in contexts] == ["fork"]


def test_the_preparation_workers_are_spawned_where_they_may_not_be_forked(monkeypatch):
    """Off Linux, or in a Ray driver (``can_fork_workers`` false), the preparation pool
    spawns its workers, whatever the default start method."""
    import pytest

    from aligngym.scenarios.campaign import executors
    monkeypatch.setattr(executors, "can_fork_workers", lambda: False)
    contexts = _recorded_contexts(monkeypatch, start=False)
    with pytest.raises(_Refused):
        executors._prepare_in_processes(_Doubling(), [1, 2], lambda *_: None, workers=2)
    assert [c.get_start_method() for c in contexts] == ["spawn"]
