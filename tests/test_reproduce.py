"""aligngym reproduce: each paper's claims judged on its campaigns; claims that need the same
campaign share one run; a claim that does not hold says why; the page lists them all."""
from dataclasses import replace

import pytest

from aligngym.scenarios.campaign.claims import Claim
from aligngym.scenarios.campaign.plan import claims_plan
from aligngym.scenarios.cli import main
from aligngym.scenarios.experiments import experiment_class, experiment_names
from aligngym.scenarios.reproduce import format_verdicts, reproduce


def test_every_paper_declares_its_claims_with_a_reason_where_they_may_fail():
    for name in experiment_names():
        claims = experiment_class(name).claims
        assert claims, name
        for claim in claims:
            assert isinstance(claim, Claim) and claim.text and claim.where and claim.numbers
            assert len(claim.reason) > 20, claim.text      # said, measured, when it fails
            assert claim.setup == "default" or claim.setup in experiment_class(name).setups


def test_paper003_claims_share_two_campaigns_and_the_page_is_written(tmp_path,
                                                                     monkeypatch):
    """The command's contract is under test (the claims' grouping into campaigns, their
    numbers measured and the time that took said, the pages written), not the alignment: the plan ``reproduce``
    makes (``claims_plan``, 2 episodes) with 60 s of fine alignment, not the paper's
    600 s. The paper setup's campaign draws all its figures; the default setup's, whose
    figures tests/test_report.py draws and checks (paper003's campaign), only the
    fine_error ones the page links."""
    import aligngym.scenarios.report as report
    from aligngym.scenarios.figures import plot_error_bands
    plan = [replace(c, spec=replace(c.spec, experiment=replace(c.spec.experiment,
                                                               fine_duration=60.0)))
            for c in claims_plan(["paper003"], 2)]
    every_figure = report.figure_jobs

    def figure_jobs(result, out):
        jobs = every_figure(result, out)
        if result.experiment.setup == "paper":
            return jobs
        return [j for j in jobs if j.func is plot_error_bands]      # fine_error_*.png
    monkeypatch.setattr(report, "figure_jobs", figure_jobs)
    import aligngym.scenarios.reproduce as reproducing
    monkeypatch.setattr(reproducing, "MEASURING_SAID_S", 0.0)  # every measuring time said
    log = []
    verdicts, text = reproduce(["paper003"], episodes=2, out_dir=tmp_path, workers=1,
                               log=log.append, plan=plan)
    # default and paper setups: one campaign each, and the time its claims took after it
    assert [line.split(": ")[1].split(" ")[0:2] for line in log] == [
        ["campaign", "1"], ["campaign", "1's"], ["campaign", "2"], ["campaign", "2's"]]
    assert len(verdicts) == len(experiment_class("paper003").claims)
    assert {v.claim.setup for v in verdicts} == {"default", "paper"}
    for v in verdicts:
        assert set(v.measured) == set(v.claim.numbers)
    page = (tmp_path / "paper003" / "claims.md").read_text()
    assert page.count("\n| ") == len(verdicts) + 2 and "fine_error_" in page
    assert "paper003/claims.md" in (tmp_path / "claims.md").read_text()
    assert (tmp_path / "paper003" / "paper-2" / "results.csv").exists()
    assert f"of {len(verdicts)} claims reproduced" in text


def test_a_claim_that_does_not_hold_prints_its_reason():
    from aligngym.scenarios.reproduce import Verdict
    claim = Claim("x beats y", "sec. 1", {"x": "a", "y": "b"}, lambda n: n["x"] < n["y"],
                  "y is the better here, measured")
    text = format_verdicts([Verdict("paperX", claim, {"x": 2.0, "y": 1.0}, False)])
    assert "NOT REPRODUCED" in text and "why: y is the better here, measured" in text
    assert "0 of 1 claims reproduced" in text


@pytest.mark.parametrize("argv, message", [
    (["reproduce", "paper009"], "reproduce: unknown paper 'paper009'; valid: all, paper000"),
    (["reproduce", "paper002", "--episodes", "0"], "--episodes must be an integer >= 1")])
def test_bad_reproduce_arguments_are_one_line(argv, message, capsys):
    try:
        status = main(argv)
    except SystemExit as exc:     # argparse's own refusal
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1]
