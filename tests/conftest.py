import os
import shutil
import sys
import tempfile

import numpy as np
import pytest

from aligngym.models.earth import TangentPlane
from aligngym.models.units import deg
from aligngym.scenarios.config import load_scenario

BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                "VECLIB_MAXIMUM_THREADS")
"""One BLAS thread in the processes the run starts (a value the user set is kept): its
xdist workers, which already take every core (BLAS threads inside them only
oversubscribe: paper 003's campaign in one process measured 16 % less CPU, the same
numbers), the campaign workers forked from them and the command-line subprocesses. The
pytest process itself loaded NumPy with the aligngym plugin, so a -n 0 run keeps its
threads."""
_ENVIRONMENT = {name: os.environ.get(name)
                for name in (*BLAS_THREADS, "PYTHONDONTWRITEBYTECODE")}
"""The variables this conftest sets, as they were: restored when the run ends."""


def pytest_configure(config):
    for name in BLAS_THREADS:
        os.environ.setdefault(name, "1")
    # Bytecode caches (__pycache__, git-ignored) written and read by every process of the
    # run, even where PYTHONDONTWRITEBYTECODE or -B says not to: without them each xdist
    # worker and each command-line subprocess compiles the package and rewrites the test
    # modules again (on a machine that sets the variable, collection 5.4 s -> 2.6 s per
    # worker). Restored when the run ends.
    config._aligngym_dont_write_bytecode = sys.dont_write_bytecode
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    sys.dont_write_bytecode = False
    _share_truth_cache(config)


def _share_truth_cache(config):
    """One truth cache for the whole run (``scenarios.truth_cache``), shared by the xdist
    workers, the campaigns' worker processes and the command-line subprocesses (they
    inherit the environment), and removed at the end: the suite neither reads nor fills
    the user's cache. ALIGNGYM_TRUTH_CACHE=off runs the suite without one."""
    chosen = os.environ.get("ALIGNGYM_TRUTH_CACHE", "")
    if hasattr(config, "workerinput") or chosen.lower() == "off":
        return                    # an xdist worker (it has the controller's), or no cache
    folder = tempfile.mkdtemp(prefix="aligngym-truth-")
    config._aligngym_truth_cache = (os.environ.get("ALIGNGYM_TRUTH_CACHE"), folder)
    os.environ["ALIGNGYM_TRUTH_CACHE"] = folder


FILE_SECONDS = {
    "test_paper003.py": 39, "test_assert_alignment.py": 34, "test_vehicle.py": 29,
    "test_env.py": 26, "test_paper002.py": 23, "test_regress.py": 21,
    "test_paper004.py": 19, "test_waves.py": 18, "test_floors_car.py": 17,
    "test_floors_ship.py": 17, "test_wheel.py": 16, "test_changing_scenarios.py": 14,
    "test_paper000.py": 14, "test_report.py": 12, "test_ray.py": 11, "test_faults.py": 11,
    "test_usv.py": 8, "test_fuzz.py": 8, "test_render.py": 7, "test_docs_blocks.py": 7}
"""The test files that take longest, s on two cores (``--durations=0``, 2026-12-06); the
rest take under 7 s each."""


def pytest_collection_modifyitems(config, items):
    """The longest test files first (``FILE_SECONDS``), the others after them in their
    order: pytest-xdist hands whole files to its workers in this order (``--dist
    loadfile --no-loadscope-reorder``), so that no long file starts last while the other
    worker has nothing left to do (longest first balances two workers within a short
    file's time)."""
    rank = {name: -seconds for name, seconds in FILE_SECONDS.items()}
    items.sort(key=lambda item: rank.get(item.path.name, 0))   # a stable sort


def pytest_unconfigure(config):
    for name, value in _ENVIRONMENT.items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value
    sys.dont_write_bytecode = getattr(config, "_aligngym_dont_write_bytecode",
                                      sys.dont_write_bytecode)
    saved = getattr(config, "_aligngym_truth_cache", None)
    if saved is None:
        return
    before, folder = saved
    shutil.rmtree(folder, ignore_errors=True)
    if before is None:
        os.environ.pop("ALIGNGYM_TRUTH_CACHE", None)
    else:
        os.environ["ALIGNGYM_TRUTH_CACHE"] = before


@pytest.fixture(scope="session")
def ship_config():
    return load_scenario("ship-sway-rotary")


@pytest.fixture(scope="session")
def plane():
    return TangentPlane(40 * deg, 118 * deg, 0.0)


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)
