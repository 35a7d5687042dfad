"""Campaigns on Ray (``--executor ray``): the same results as local processes, and a
worker killed mid-campaign loses no episode."""
import os
import sys
from dataclasses import dataclass

import numpy as np
import pytest
import ray

from aligngym.scenarios.campaign import episode_seeds, run_campaign
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.experiments import experiment
from aligngym.scenarios.experiments.paper002 import Paper002Experiment

SMALL = dict(episodes=3, seed=4, filters=["ekf"], progress=False)


@pytest.fixture(scope="module")
def local_ray():
    """A local Ray instance; without the truth cache, so that Ray's workers and the local
    processes each simulate their episodes (the comparison is across processes)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("ALIGNGYM_TRUTH_CACHE", "off")
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        # Classes of this test module reach Ray's workers by value.
        ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
        yield
        ray.shutdown()


def short_paper002():
    return experiment("paper002", fine_duration=60.0)


@pytest.fixture(scope="module")
def local(local_ray):
    """The campaign on local processes (truth cache off, as local_ray sets it): the
    reference of both Ray tests."""
    return run_campaign(short_paper002(), workers=2, **SMALL)


def test_ray_campaign_identical_to_local(local_ray, local, tmp_path):
    on_ray = run_campaign(short_paper002(), executor="ray", out_dir=tmp_path, **SMALL)
    assert sorted(p.name for p in (tmp_path / "episodes").iterdir()) == [
        f"seed_{s}.npz" for s in sorted(local.seeds)]
    for a, b in zip(local.runs, on_ray.runs):
        np.testing.assert_array_equal(a.error_n, b.error_n)
        np.testing.assert_array_equal(a.result.P, b.result.P)


@dataclass(frozen=True)
class KillsItsWorkerOnce(Paper002Experiment):
    """Kills the Ray worker preparing episode ``victim``, the first time only (the file
    ``marker`` remembers): Ray retries the task on a new worker."""

    victim: int = -1
    marker: str = ""

    def prepare_episode(self, seed, config=None):
        if seed == self.victim and not os.path.exists(self.marker):
            open(self.marker, "w").close()
            os._exit(1)
        return super().prepare_episode(seed, config)


def test_killed_worker_loses_no_episode(local_ray, local, tmp_path):
    seeds = episode_seeds(SMALL["seed"], SMALL["episodes"])
    exp = KillsItsWorkerOnce(fine_duration=60.0, victim=seeds[1],
                             marker=str(tmp_path / "killed"))
    result = run_campaign(exp, executor="ray", out_dir=tmp_path / "out", **SMALL)
    assert (tmp_path / "killed").exists()                      # a worker did die
    np.testing.assert_array_equal(result.runs[0].error_n, local.runs[0].error_n)
    assert len(list((tmp_path / "out" / "episodes").glob("seed_*.npz"))) == 3


def test_executor_options_checked():
    with pytest.raises(ConfigError, match="--executor 'dask' is unknown"):
        run_campaign(short_paper002(), executor="dask", **SMALL)
    with pytest.raises(ConfigError, match="--address needs --executor ray"):
        run_campaign(short_paper002(), address="auto", **SMALL)
