"""The episode bank's key leaves out the settings that concern the filters only
(``Experiment.filter_settings``): ``prepare_episode`` reads none of them, on each
paper's default settings and the variants that take other preparation paths, so
retuning a filter reuses the bank's episodes; a setting that shapes the episodes still
moves the key."""
import copy
from dataclasses import fields, replace

import pytest

from aligngym.scenarios.bank import bank_directory, bank_key
from aligngym.scenarios.experiments import experiment

SHORT = {"paper000": {"coarse_duration": 10.0, "fine_duration": 20.0},
         "paper001": {"coarse_duration": 5.0, "fine_duration": 20.0},
         "paper002": {"fine_duration": 20.0},
         "paper003": {"coarse_duration": 10.0, "t_k1": 4.0, "t_k2": 10.0,
                      "fine_duration": 20.0},
         "paper004": {"coarse_duration": 5.0, "fine_duration": 20.0}}
"""Short runs: which settings the preparation reads does not depend on the length (paper
001's moving coarse alignment read none of the filter settings either when this test ran
it once, 2026-12-06; it waits for the car to drive off at 270 s, too long a run for the
suite)."""
VARIANTS = [("paper000", {}), ("paper001", {}), ("paper001", {"setup": "paper"}),
            ("paper002", {}), ("paper003", {}),
            ("paper003", {"setup": "paper"}), ("paper004", {}),
            ("paper004", {"case": "consistency"})]


def settings_read_by_prepare(exp) -> set[str]:
    """The settings (fields) of exp that its prepare_episode reads, at any depth (every
    attribute read of the experiment object is seen)."""
    names, seen = {f.name for f in fields(exp)}, set()

    class Spy(type(exp)):
        def __getattribute__(self, name):
            if name in names:
                seen.add(name)
            return object.__getattribute__(self, name)

    spy = copy.copy(exp)
    object.__setattr__(spy, "__class__", Spy)
    spy.prepare_episode(3)
    return seen


@pytest.mark.parametrize("paper, settings", VARIANTS)
def test_the_preparation_reads_no_filter_setting(paper, settings):
    exp = experiment(paper, **SHORT[paper], **settings)
    declared = exp.filter_settings
    assert declared <= {f.name for f in fields(exp)}            # no stale name
    read = settings_read_by_prepare(exp)
    assert "fine_duration" in read                             # the spy sees reads
    assert not read & declared, sorted(read & declared)


@pytest.mark.parametrize("paper", sorted(SHORT))
def test_a_filter_setting_keeps_the_bank_and_an_episode_setting_moves_it(paper):
    exp = experiment(paper, **SHORT[paper])
    key = bank_directory("bank", bank_key(exp))
    changes = {"rms_window": exp.rms_window * 2}
    if "default_filters" in exp.filter_settings:
        changes["default_filters"] = exp.default_filters[:1]
    retuned = replace(exp, **changes)
    assert bank_directory("bank", bank_key(retuned)) == key
    longer = replace(exp, fine_duration=exp.fine_duration + 10.0)
    assert bank_directory("bank", bank_key(longer)) != key


def test_the_bank_is_keyed_on_the_code_the_process_runs(monkeypatch):
    """The bank's code hash is the one this process took when it loaded the simulation
    (``truth_cache.remember_code``), not the files' at the time of asking: code edited on
    disk during a run cannot label the episodes the old code prepared."""
    from aligngym.scenarios import truth_cache
    exp = experiment("paper003")
    truth_cache.remember_code()
    before = bank_key(exp)["code_sha256"]
    assert before == truth_cache._CODE_SHA256
    monkeypatch.setattr(truth_cache, "simulation_code_sha256", lambda: "the files now")
    assert bank_key(exp)["code_sha256"] == before
    monkeypatch.setattr(truth_cache, "_CODE_SHA256", "another process's code")
    assert bank_key(exp)["code_sha256"] == "another process's code"
