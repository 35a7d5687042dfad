"""``aligngym regress``: the papers' fixed-seed campaigns against their stored baselines."""
import json

import pytest

from aligngym.scenarios.experiments import paper003
from aligngym.scenarios.cli import main
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.regress import Difference, campaigns, compare, regress


FROM_THE_WHEEL = "paper002"
"""Run against its baseline by tests/test_wheel.py::test_paper002_regress_from_the_wheel
(the installed wheel, the same code and baseline, one worker): not run twice."""


def test_regress_passes_on_the_landed_code(capsys):
    """Every declared campaign against its baseline (paper 002's from the wheel)."""
    assert FROM_THE_WHEEL in campaigns()
    papers = [paper for paper in campaigns() if paper != FROM_THE_WHEEL]
    assert papers
    assert main(["regress", "--papers", ",".join(papers)]) == 0
    out = capsys.readouterr().out
    for paper in papers:
        assert f"{paper}: " in out and "0 beyond tolerance" in out


def test_regress_fails_when_a_filter_is_perturbed(monkeypatch):
    """R margin 1.25 -> 1.5 (the fine alignment's measurement noise): the KF's errors and
    NEES move beyond tolerance and are reported; the coarse alignment does not move."""
    monkeypatch.setattr(paper003, "SWAY_R_MARGIN", 1.5)
    passed, report = regress(["paper003"], workers=1)
    assert not passed
    flagged = [line.split()[0] for line in report.splitlines() if "REGRESSION" in line]
    assert "fine/kf/mean/rms_arcmin/2" in flagged
    assert "nees_final_mean/kf/mean" in flagged
    assert not any(path.startswith("coarse/") for path in flagged)


def test_tolerances_by_kind():
    base = {"fine/kf/mean/rms_arcmin/2": 0.25, "fine/kf/mean/diverged_fraction": 0.0,
            "fine/ekf/mean/convergence_s": 120.0, "gone": 1.0}
    now = {"fine/kf/mean/rms_arcmin/2": 0.25 * (1 + 5e-5),      # rounding: moved, ok
           "fine/kf/mean/diverged_fraction": 0.02,               # one episode flipped
           "fine/ekf/mean/convergence_s": 121.0,                 # one filter step
           "new": 1.0}
    diffs, missing = compare(base, now)
    verdict = {d.path: (d.moved, d.ok) for d in diffs}
    assert verdict["fine/kf/mean/rms_arcmin/2"] == (True, True)
    assert verdict["fine/kf/mean/diverged_fraction"] == (True, False)
    assert verdict["fine/ekf/mean/convergence_s"] == (True, True)
    assert missing == ["gone", "new"]
    assert not Difference("fine/kf/mean/rms_arcmin/2", 0.25, 0.2501).ok


def test_baseline_made_with_other_settings_is_refused(tmp_path):
    (tmp_path / "regress_paper003.json").write_text(json.dumps(
        {"settings": {"episodes": 1}, "metrics": {}}))
    with pytest.raises(ConfigError, match="other settings"):
        regress(["paper003"], directory=tmp_path)
    with pytest.raises(ConfigError, match="unknown"):
        regress(["paper009"], directory=tmp_path)
    assert main(["regress", "--papers", "paper002", "--baselines", str(tmp_path)]) == 2
