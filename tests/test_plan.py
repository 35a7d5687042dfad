"""Campaigns planned, then executed (``scenarios.campaign.plan``): bench's sweep gives one
campaign per value, reproduce's claims one per distinct campaign they need, regress the
declared one; every spec of a plan is checked before the first one runs."""
import pytest

from aligngym.scenarios.campaign.plan import (CampaignSpec, bench_plan, claims_plan,
                                              regress_plan)
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.experiments import experiment_class, experiment_names
from aligngym.scenarios.experiments import regress_campaigns


def test_a_sweep_is_one_campaign_per_value_and_one_setting_is_one_campaign():
    swept = bench_plan("paper004", "default", {"swing": "all"}, 3, 5, ["ekf"])
    levels = experiment_class("paper004").__dataclass_fields__["swing"].metadata["choices"]
    assert swept.sweep == "swing" and [s.label for s in swept.specs] == list(levels)
    assert [s.experiment.swing for s in swept.specs] == list(levels)
    assert {(s.episodes, s.seed, s.filters) for s in swept.specs} == {(3, 5, ("ekf",))}
    single = bench_plan("paper002", "default", {}, None, 0, None)
    (spec,) = single.specs
    assert single.sweep is None and spec.label == ""
    assert spec.episodes == experiment_class("paper002").default_episodes
    assert spec.filters == tuple(spec.experiment.default_filters)


def test_every_campaign_is_checked_before_any_runs(monkeypatch):
    """A sweep whose last value cannot run (here: it would take more memory than the
    machine has) is refused before the first campaign runs."""
    from aligngym.scenarios.campaign import engine
    checked = []

    def check(experiment, episodes, filters):
        checked.append(experiment.swing)
        if len(checked) == 3:
            raise ConfigError("--episodes 3 needs about 99 GB")
    monkeypatch.setattr(engine, "check_campaign", check)
    monkeypatch.setattr(CampaignSpec, "run", lambda *a, **k: pytest.fail("ran"))
    with pytest.raises(ConfigError, match="99 GB"):
        bench_plan("paper004", "default", {"swing": "all"}, 3, 5, ["ekf"])
    assert len(checked) == 3
    with pytest.raises(ConfigError, match="--filters is empty"):
        bench_plan("paper002", "default", {}, 3, 5, [])
    refused = []

    def refuse_the_second(experiment, episodes, filters):
        refused.append(experiment.scenario)
        if len(refused) == 2:
            raise ConfigError(f"{experiment.scenario} refused")
    monkeypatch.setattr(engine, "check_campaign", refuse_the_second)
    with pytest.raises(ConfigError, match="ship-sway-rotary-paper refused"):
        claims_plan(["paper003"], episodes=3)    # its paper setup's campaign, the second


def test_claims_share_the_campaigns_they_need():
    plan = claims_plan(list(experiment_names()), episodes=2, seed=9)
    for paper in experiment_names():
        campaigns = [c for c in plan if c.paper == paper]
        claims = [claim for c in campaigns for claim in c.claims]
        assert sorted(map(id, claims)) == sorted(map(id, experiment_class(paper).claims))
        keys = [c.claims[0].campaign_key() for c in campaigns]
        assert len(set(keys)) == len(keys)                    # one campaign per key
        for k, c in enumerate(campaigns):
            assert {claim.campaign_key() for claim in c.claims} == {keys[k]}
            assert c.spec.label == f"{c.claims[0].setup}-{k + 1}"
            assert (c.spec.episodes, c.spec.seed) == (2, 9)
    default = claims_plan(["paper002"])[0].spec
    assert (default.episodes, default.seed) == (50, 0)       # the paper's own counts


def test_regress_plans_every_paper_declared():
    papers = list(regress_campaigns())
    plan = regress_plan(papers)
    assert list(plan) == papers
    for paper, declared in regress_campaigns().items():
        spec = plan[paper]
        assert (spec.episodes, spec.seed, spec.filters) == (
            declared["episodes"], declared["seed"], tuple(declared["filters"]))
        for name, value in declared.get("experiment", {}).items():
            have = getattr(spec.experiment, name)
            assert (list(have) if isinstance(have, tuple) else have) == value


@pytest.fixture
def refuse_the_last(monkeypatch):
    """engine.check_campaign refusing paper004's campaigns (of the last paper named)
    but its first swing level's (the first campaign of its sweep), and a
    CampaignSpec.run that records what ran."""
    from aligngym.scenarios.campaign import engine
    first_level = experiment_class("paper004").__dataclass_fields__["swing"].metadata[
        "choices"][0]
    ran = []

    def check(experiment, episodes, filters):
        if type(experiment).__module__.endswith("paper004") and experiment.swing != first_level:
            raise ConfigError("the last campaign refused")
    monkeypatch.setattr(engine, "check_campaign", check)
    monkeypatch.setattr(CampaignSpec, "run", lambda spec, **k: ran.append(spec))
    return ran


def test_the_commands_refuse_before_their_first_campaign_runs(refuse_the_last, capsys):
    """bench's sweep (its last value), regress and reproduce (their last paper): a
    campaign that cannot run is refused before the first one runs."""
    from aligngym.scenarios.cli import main
    from aligngym.scenarios.regress import regress
    assert main(["bench", "paper004", "--swing", "all", "--episodes", "1", "--filters",
                 "ekf"]) == 2
    assert main(["reproduce", "paper003,paper004", "--episodes", "1"]) == 2
    assert capsys.readouterr().err.count("the last campaign refused") == 2
    with pytest.raises(ConfigError, match="the last campaign refused"):
        regress(["paper003", "paper004"])
    assert refuse_the_last == []
