import numpy as np
import pytest

from aligngym.models.earth import TangentPlane
from aligngym.models.units import deg
from aligngym.scenarios.config import load_scenario


@pytest.fixture(scope="session")
def ship_config():
    return load_scenario("ship-sway-rotary")


@pytest.fixture(scope="session")
def plane():
    return TangentPlane(40 * deg, 118 * deg, 0.0)


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)
