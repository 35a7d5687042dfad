import os
import shutil
import tempfile

import numpy as np
import pytest

from aligngym.models.earth import TangentPlane
from aligngym.models.units import deg
from aligngym.scenarios.config import load_scenario


def pytest_configure(config):
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


def pytest_unconfigure(config):
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
