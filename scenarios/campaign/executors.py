"""Where episodes are prepared: executors, chosen by name from a registry (``EXECUTORS``:
"local" processes, "ray" tasks; ``register_executor`` adds one); each finished episode
is saved at once, so an interrupted campaign keeps it."""
from __future__ import annotations

import os
import signal
import sys
import zipfile
import zlib
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import Callable, Iterator, Protocol
from pathlib import Path

from aligngym.scenarios.campaign.episodes import PreparedEpisode
from aligngym.scenarios.campaign.experiment import Experiment
from aligngym.scenarios.campaign.transport import shared_arrays
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.interrupts import raise_if_interrupted

Finish = Callable[[int, PreparedEpisode], None]
"""What an executor hands each prepared episode to, with its seed, as it arrives."""

_WHILE_WAITING: list[Callable[[], None]] = []
"""Work queued by ``while_waiting``."""


def while_waiting(task: Callable[[], None]) -> None:
    """Run ``task`` (no arguments; e.g. imports the outputs will need) once in this
    process, the next time it waits for its worker processes, after they have started:
    on a core the workers leave over rather than on the critical path, and inherited by
    the processes forked later. Never run if no wait comes (the work is then done where
    it is needed). A task's exception is left to whoever needs the work (the same
    import fails again there): it is not raised into the campaign. A task queued already
    is not queued again."""
    if task not in _WHILE_WAITING:
        _WHILE_WAITING.append(task)


def run_waiting_work() -> None:
    """The tasks queued by ``while_waiting``, each once, in their order (called by this
    process's loops that wait for worker processes, once these have started)."""
    while _WHILE_WAITING:
        task = _WHILE_WAITING.pop(0)
        try:
            task()
        except Exception:           # the work is done again, and fails loudly, where needed
            pass


class Executor(Protocol):
    """Prepares a campaign's episodes somewhere: ``prepare`` calls
    ``experiment.prepare_episode(seed)`` for every seed, in any order and anywhere, and
    hands each episode to ``finish(seed, episode)`` in this process as soon as it has
    it (``finish`` saves it; it raises on Ctrl-C, which must stop the work)."""

    takes_address: bool
    """Whether the executor joins a cluster at ``--address``."""

    def prepare(self, experiment: Experiment, seeds: list[int], finish: Finish,
                workers: int, address: str | None) -> None: ...


class LocalProcesses:
    """Local worker processes, no more than ``workers`` and the cores (one process, this
    one, for a single worker or a single episode)."""

    takes_address = False

    def prepare(self, experiment: Experiment, seeds: list[int], finish: Finish,
                workers: int, address: str | None = None) -> None:
        if workers <= 1 or len(seeds) <= 1:
            for s in seeds:
                finish(s, experiment.prepare_episode(s))
        else:
            _prepare_in_processes(experiment, seeds, finish, workers)


class RayTasks:
    """One Ray task per episode, on a local Ray instance of ``workers`` CPUs or the
    cluster at ``address`` (``_prepare_on_ray``)."""

    takes_address = True

    def prepare(self, experiment: Experiment, seeds: list[int], finish: Finish,
                workers: int, address: str | None = None) -> None:
        _prepare_on_ray(experiment, seeds, finish, workers, address)


EXECUTORS: dict[str, Executor] = {"local": LocalProcesses(), "ray": RayTasks()}
"""The executors by the name ``--executor`` and ``run_campaign(executor=)`` take."""


def register_executor(name: str, executor: Executor) -> None:
    """Make executor available as ``run_campaign(..., executor=name)`` (a name taken is
    refused: one name, one executor)."""
    if name in EXECUTORS:
        raise ValueError(f"executor {name!r} is registered already")
    missing = [a for a in ("prepare", "takes_address") if not hasattr(executor, a)]
    if missing:
        raise TypeError(f"executor {name!r} lacks {', '.join(missing)} (the Executor "
                        "protocol)")
    EXECUTORS[name] = executor


def executor_named(name: str, address: str | None = None) -> Executor:
    """The registered executor of that name (one-line ConfigError naming the valid ones),
    checked against address."""
    if name not in EXECUTORS:
        raise ConfigError(f"--executor {name!r} is unknown; valid: " + ", ".join(EXECUTORS))
    executor = EXECUTORS[name]
    if address is not None and not executor.takes_address:
        takers = [n for n, e in EXECUTORS.items() if e.takes_address]
        raise ConfigError(f"--address needs --executor {' or '.join(takers)}")
    return executor


def prepare_all(experiment: Experiment, seeds: list[int], out_dir: Path | None,
                resume: bool, workers: int, progress: bool = True, executor: str = "local",
                address: str | None = None) -> list[PreparedEpisode]:
    """Prepare the episodes with the executor of that name (``EXECUTORS``: local
    processes, Ray tasks; ``address``: a Ray cluster's, None starts a local instance with
    ``workers`` CPUs); each episode is saved by this process as soon as it arrives, so
    an interrupted campaign keeps its finished episodes whichever executor ran them.
    With resume, episodes already on disk are loaded instead (one that does not load is
    named and simulated again)."""
    from tqdm import tqdm

    runner = executor_named(executor, address)      # before anything is made or drawn
    episode_dir = out_dir / "episodes" if out_dir is not None else None
    if episode_dir is not None:
        episode_dir.mkdir(parents=True, exist_ok=True)

    def path(s: int) -> Path:
        return episode_dir / f"seed_{s}.npz"

    done = {}
    if resume and episode_dir is not None:
        for s in seeds:
            if path(s).is_file():
                episode = load_checked(experiment.episode_class, path(s), s)
                if episode is not None:
                    done[s] = episode
    todo = [s for s in seeds if s not in done]
    bar = tqdm(total=len(seeds), initial=len(done), disable=not progress, desc="episodes")

    def finish(s: int, episode: PreparedEpisode) -> None:
        raise_if_interrupted()
        if episode_dir is not None:
            episode.save(path(s))
        done[s] = episode
        bar.update()

    try:
        runner.prepare(experiment, todo, finish, workers, address)
    finally:
        bar.close()                # before any message about an interruption
    return [done[s] for s in seeds]


def usable_cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:                      # no affinity on this platform
        return os.cpu_count() or 1


def _prepare_in_processes(experiment: Experiment, seeds: list[int], finish,
                          workers: int) -> None:
    """Local worker processes (which ignore Ctrl-C), no more than the cores (more would
    only share them); on an interruption or an error the pool is stopped at once, the
    finished episodes being saved already."""
    import multiprocessing
    # forked where possible (whatever the default start method): the workers inherit the
    # loaded kernels (``kernels.load_compiled_kernels``) and send arrays as shared files;
    # elsewhere spawned (a forkserver's workers are not this process's children, and a
    # Ray driver must not fork)
    context = multiprocessing.get_context("fork" if can_fork_workers() else "spawn")
    with shared_arrays():             # the episodes come back as shared files
        pool = ProcessPoolExecutor(max_workers=max(1, min(workers, usable_cores(), len(seeds))),
                                   mp_context=context, initializer=start_worker,
                                   initargs=(os.getpid(),))
        with stopped_on_error(pool):
            futures = {pool.submit(experiment.prepare_episode, s): s for s in seeds}
            run_waiting_work()
            for fut in as_completed(futures):
                finish(futures[fut], fut.result())


@contextmanager
def stopped_on_error(pool: ProcessPoolExecutor) -> Iterator[ProcessPoolExecutor]:
    """Shut the pool down when the block ends; on an interruption or an error stop it at
    once (queued tasks cancelled, running workers terminated) and re-raise."""
    try:
        yield pool
    except BaseException:
        stop_pool(pool)
        raise
    pool.shutdown()


def stop_pool(pool: ProcessPoolExecutor) -> None:
    """Stop a pool at once: its queued tasks cancelled, its running workers terminated.
    The workers go first, then the pool is shut down waiting for its manager thread
    (which finds them gone, fails what was pending and ends): ``shutdown(wait=False)``
    before killing them let that thread, still running, replace the dead workers of a
    pool whose state was already reset, an error and a hang at exit (CPython gh-132969,
    fixed after 3.13). A worker killed half-way through sending its result leaves that
    thread reading the rest for ever, as this process holds the result pipe's write end
    too: once the workers are dead that end is closed, and the thread reads the end of
    the pipe instead (seen once under load: a Ctrl-C test hung 60 s in ``recv``)."""
    running = list((getattr(pool, "_processes", None) or {}).values())
    for process in running:
        process.terminate()
    for process in running:
        process.join(timeout=10)
    writer = getattr(getattr(pool, "_result_queue", None), "_writer", None)
    if writer is not None and not any(process.is_alive() for process in running):
        try:
            writer.close()
        except OSError:
            pass
    pool.shutdown(wait=True, cancel_futures=True)


HEAP_ARRAY_BYTES = 64 << 20
"""Arrays up to this size come from the heap once ``keep_freed_memory`` has run."""
HEAP_KEPT_BYTES = 512 << 20
"""Freed memory at the top of the heap up to this size stays with the process."""


def keep_freed_memory() -> None:
    """glibc's allocator told (mallopt) to take arrays of up to ``HEAP_ARRAY_BYTES`` from the
    heap and to keep up to ``HEAP_KEPT_BYTES`` of freed memory, for this process and the
    workers it forks: a campaign makes and frees many arrays of a few MB an epoch or an
    episode, and each was otherwise mapped, faulted in page by page and unmapped again
    (paper 003's bench, 32 episodes, one worker: 221 000 page faults and 1.2 s of system
    time, 57 000 and 0.6 s with this; the glibc settings MALLOC_MMAP_THRESHOLD_ and
    MALLOC_TRIM_THRESHOLD_). Both are set, or neither: either alone turns off glibc's
    adaptive threshold and faults more. Nothing is done off glibc, or once done. For the
    whole process and its forks, so the command line does it (``cli.main``), not the
    library's ``run_campaign``: a program that runs a campaign keeps its own settings."""
    global _MEMORY_KEPT
    if _MEMORY_KEPT or not sys.platform.startswith("linux"):
        return
    _MEMORY_KEPT = True
    import ctypes
    try:
        libc = ctypes.CDLL(None)
        mallopt = libc.mallopt
    except (OSError, AttributeError):         # not glibc (musl has no mallopt)
        return
    M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
    if mallopt(M_MMAP_THRESHOLD, HEAP_ARRAY_BYTES):
        mallopt(M_TRIM_THRESHOLD, HEAP_KEPT_BYTES)


_MEMORY_KEPT = False


@contextmanager
def thread_budget(workers: int) -> Iterator[None]:
    """This process's BLAS and OpenMP pools and MuJoCo's kinematic rollout held to
    ``workers`` threads (and the cores) for the block: ``--workers K`` uses at most K cores,
    whether the work runs in K processes of one thread each or here (one worker: one
    thread; before, a one-worker campaign prepared its episodes on every core, paper 001's
    on 1.9 of two). A pool already held to fewer threads keeps them. Restored when the
    block ends."""
    from threadpoolctl import ThreadpoolController

    from aligngym.models import world
    threads = max(1, min(workers, usable_cores()))
    rollout = world.ROLLOUT_THREADS
    lowered = []
    try:
        world.ROLLOUT_THREADS = min(rollout, threads)
        # each library lowered, never raised (a user's OMP_NUM_THREADS=1 stays 1); by
        # library, not by name: NumPy's and SciPy's OpenBLAS share one; one that cannot
        # say its threads is left alone
        for lib in ThreadpoolController().lib_controllers:
            if isinstance(lib.num_threads, int) and lib.num_threads > threads:
                lowered.append((lib, lib.num_threads))
                lib.set_num_threads(threads)
        yield
    finally:
        for lib, before in lowered:
            lib.set_num_threads(before)
        world.ROLLOUT_THREADS = rollout


def can_fork_workers() -> bool:
    """Local workers may be forked here: Linux (where they inherit the parent's data
    without copying it), and no Ray started in this process (a Ray driver must not
    fork)."""
    ray = sys.modules.get("ray")
    return sys.platform.startswith("linux") and not (
        ray is not None and getattr(ray, "is_initialized", lambda: False)())


def load_checked(episode_class: type, path: Path, seed: int) -> PreparedEpisode | None:
    """A saved episode, or None (its name and the reason in one line on stderr: it is
    simulated again) when the file does not load or holds another seed."""
    try:
        episode = episode_class.load(path)
        problem = None if int(episode.seed) == seed else f"it holds seed {int(episode.seed)}"
    except (OSError, EOFError, ValueError, KeyError, TypeError, zipfile.BadZipFile,
            zlib.error) as exc:
        episode, problem = None, f"{type(exc).__name__}: {exc}".splitlines()[0][:120]
    if problem is None:
        return episode
    print(f"aligngym: {path} does not load ({problem}); simulating seed {seed} again",
          file=sys.stderr)
    return None


def ignore_interrupt() -> None:
    """Worker processes leave Ctrl-C to the parent (which stops them): no traceback from
    every worker."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def start_worker(parent: int) -> None:
    """What a local worker process does first: Ctrl-C left to the parent
    (``ignore_interrupt``); the campaign locks it inherited closed (the parent's
    descriptor holds the lock); and, on Linux, a SIGTERM when the parent dies, so that a
    killed campaign (SIGKILL, out of memory) leaves no worker behind holding its
    directory; its BLAS and OpenMP pools and MuJoCo's kinematic rollout limited to one
    thread (the processes already take the cores: two workers on two cores, each with two
    BLAS threads, prepared an episode 2.5-3.5x slower than one process did); and the
    objects it starts with frozen (``gc.freeze``; a forked worker's are the parent's), so
    that its garbage collections traverse only those it makes (the parent's 230 000
    objects made a figure worker's collections a tenth of its drawing time; garbage it
    inherited is not collected, and the worker is short-lived). parent: the parent's pid
    (a worker whose parent is already gone exits)."""
    import gc

    from threadpoolctl import threadpool_limits

    from aligngym.models import world
    gc.freeze()                        # the parent's objects: out of the collector's reach
    ignore_interrupt()
    threadpool_limits(1)
    world.ROLLOUT_THREADS = 1          # the same states from any number of threads
    from aligngym.scenarios.campaign.manifest import _HELD
    for fd in _HELD.values():
        os.close(fd)
    _HELD.clear()
    if sys.platform.startswith("linux"):
        import ctypes
        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)   # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:
        os._exit(1)


def _prepare_task(experiment: Experiment, seed: int) -> PreparedEpisode:
    return experiment.prepare_episode(seed)


def _prepare_on_ray(experiment: Experiment, seeds: list[int], finish, workers: int,
                    address: str | None) -> None:
    """One Ray task per episode; results are handed to finish as they complete. A task
    whose worker dies is retried by Ray (3 times); if it still fails the campaign stops
    with Ray's error, the episodes already finished being on disk. An initialised Ray
    (or RAY_ADDRESS) is used as it is: workers only size a local instance we start."""
    if not seeds:                  # all resumed: nothing to run
        return
    try:
        import ray
    except ImportError:
        raise ConfigError("--executor ray needs Ray: pip install -e '.[ray]'") from None
    address = address or os.environ.get("RAY_ADDRESS")
    if not ray.is_initialized():
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    task = ray.remote(max_retries=3)(_prepare_task)
    shared = ray.put(experiment)   # pickled once for all tasks
    pending = {task.remote(shared, s): s for s in seeds}
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            finish(pending.pop(ref), ray.get(ref))


