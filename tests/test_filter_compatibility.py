"""Each experiment declares what its model gives the filters
(``Experiment.observation_features``) and each filter what it needs
(``IntegrationRule.needs``, ``AdaptationPolicy.needs``), so that a filter the model
cannot run is refused before any episode is simulated. The declarations are checked
here against the filters themselves: every catalogue filter on a short episode of every
shipped experiment runs if and only if ``check_filters`` accepts it."""
import warnings

import numpy as np
import pytest

from aligngym.estimators.catalogue import filter_entry, filter_names
from aligngym.scenarios.campaign import run_filter
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.experiments import experiment
from aligngym.scenarios.registry import experiment_names

NAMES = [n.replace("-N", "-2") for n in filter_names() if n != "ghkf-N"]


@pytest.mark.parametrize("name", experiment_names())
def test_declared_compatibility_is_what_the_filters_do(name):
    exp = experiment(name, fine_duration=10.0)
    episode = exp.prepare_episode(1)
    start = exp.start_errors([episode])[exp.starts[0]]
    accepted, ran = set(), set()
    for filt in NAMES:
        try:
            exp.check_filters([filt])
        except ConfigError:
            continue
        accepted.add(filt)
    for filt in NAMES:
        variant = filter_entry(filt).model
        if variant and variant not in exp.model_variants:
            continue                         # a model variant the experiment does not build
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                run = run_filter(filt, exp.starts[0], start, [episode], exp)
        except (ValueError, ConfigError):
            continue
        assert np.all(np.isfinite(run.error_n)), filt
        ran.add(filt)
    assert accepted == ran, (f"accepted, does not run: {sorted(accepted - ran)}; "
                             f"runs, refused: {sorted(ran - accepted)}")
    assert set(exp.runnable_filters()) >= {n for n in accepted if not n.endswith("-2")}

