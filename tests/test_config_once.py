"""A campaign parses and validates its scenario file once (an experiment holds its
loaded scenario), whatever the experiment asks of it (model, NEES, duration, tables)."""
import pytest

from aligngym.scenarios import config
from aligngym.scenarios.campaign import run_campaign
from aligngym.scenarios.experiments import experiment


@pytest.mark.parametrize("paper, settings", [
    ("paper002", {"fine_duration": 20.0}),
    ("paper001", {"fine_duration": 20.0}),
])
def test_a_two_episode_campaign_loads_its_scenario_once(monkeypatch, paper, settings):
    loads = []
    build = config._build
    monkeypatch.setattr(config, "_build", lambda raw, source: loads.append(source)
                        or build(raw, source))
    exp = experiment(paper, **settings)
    result = run_campaign(exp, episodes=2, seed=0, workers=1, progress=False)
    result.summary()
    exp.format_tables(result)
    assert len(loads) == 1, loads


def test_the_env_loads_a_scenario_file_once(monkeypatch, tmp_path):
    """experiment_for reads the file to find its experiment and hands it over: the env's
    experiment does not parse it again."""
    from aligngym.scenarios.experiments import experiment_for
    loads = []
    build = config._build
    monkeypatch.setattr(config, "_build", lambda raw, source: loads.append(source)
                        or build(raw, source))
    exp = experiment_for("static-large-azimuth", fine_duration=20.0)
    exp.scenario_config()
    exp.tuning()
    assert len(loads) == 1, loads
