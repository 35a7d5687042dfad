"""Issue 46 item 4, the campaign figures say what they show: the mean NEES against its
chi-square band (the epochs outside it, in the figure, summary.json and the report),
every axis with its unit, every marker in a legend, and every filter whose results equal
another's marked "(= other)". On hand-built campaigns: no filter runs, the figures drawn
but not rasterised (``save_figure`` replaced), so the file takes about a second."""
import json
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.lines import Line2D
from scipy.stats import chi2

from aligngym.models.units import arcmin
from aligngym.scenarios import figures
from aligngym.scenarios.figure_jobs import write_figures
from aligngym.scenarios.figure_statistics import (identical_runs, nees_band_summary,
                                                  nees_curves, nees_excursions)
from aligngym.scenarios.html_report import render_report

DOF, EPISODES = 4, 5


def closed_form_band(dof, episodes, probability=0.95):
    """The mean of `episodes` chi-square(dof) NEES: chi-square(dof x episodes) / episodes."""
    tail = (1.0 - probability) / 2.0
    return (chi2.ppf(tail, dof * episodes) / episodes,
            chi2.ppf(1.0 - tail, dof * episodes) / episodes)


def run(name, error_arcmin, nees, diverged, start="s", sigma_arcmin=None):
    """A FilterRun's fields the figures read; t = 100, 101, ... s."""
    B, K, _ = error_arcmin.shape
    sigma = np.ones_like(error_arcmin) if sigma_arcmin is None else sigma_arcmin
    return SimpleNamespace(
        filter=name, start=start, error_n=error_arcmin * arcmin, nees=np.asarray(nees, float),
        diverged=np.asarray(diverged, bool), heading_convergence=np.full(B, 3.0),
        result=SimpleNamespace(t=100.0 + np.arange(K), sigma_n=sigma * arcmin))


def campaign(runs, dof=DOF, starts=("s",)):
    B = runs[0].error_n.shape[0]
    return SimpleNamespace(runs=runs, seeds=list(range(B)), episodes=[], experiment=SimpleNamespace(
        starts=starts, rms_window=3.0, heading_threshold_arcmin=0.5, nees_dof=lambda: dof,
        accuracy_window=lambda t, fine_start: t >= t[-1] - 3.0))


def band_series():
    """Five episodes whose NEES at each epoch is the same value (their mean), a sixth
    diverged at 1e6, the prior epoch at 1e9 (both left out): epochs 1..10 at t = 1..10 s
    inside, just inside below the top, above x2, inside, below, no NEES, inside, above,
    inside."""
    low, high = closed_form_band(DOF, EPISODES)
    mean = np.array([DOF, 0.99 * high, 1.01 * high, 1.5 * high, DOF, 0.99 * low, np.nan,
                     1.01 * low, 1.01 * high, DOF])
    nees = np.concatenate([[1e9], mean])[None].repeat(EPISODES + 1, 0)
    nees[-1] = 1e6
    diverged = np.r_[np.zeros(EPISODES, bool), True]
    return nees, diverged, (low, high)


def test_mean_nees_band_and_the_epochs_outside_it_against_the_closed_form():
    """The band is chi-square(dof x n) / n for the n = 5 episodes not diverged (not 6,
    not dof x (n + 1)), epochs just inside its edges are inside, the epoch without a NEES
    is not counted: 3 of 9 above, 1 of 9 below, first out at 3 s; the strips' spans
    cover each run of epochs out to the midpoints of its neighbours."""
    nees, diverged, (low, high) = band_series()
    error = np.zeros((EPISODES + 1, 11, 3))
    curve, = nees_curves(campaign([run("kf", error, nees, diverged)]))
    excursion, = nees_excursions([curve], DOF)
    np.testing.assert_allclose(excursion.band, (low, high), rtol=1e-12)
    assert excursion.episodes == EPISODES and excursion.dof == DOF
    assert np.flatnonzero(excursion.above).tolist() == [2, 3, 8]
    assert np.flatnonzero(excursion.below).tolist() == [5]
    assert excursion.counted.sum() == 9
    assert excursion.fraction_above == pytest.approx(3 / 9)
    assert excursion.fraction_below == pytest.approx(1 / 9)
    assert excursion.first_time_outside == 3.0
    assert excursion.spans(excursion.above) == [(2.5, 2.0), (8.5, 1.0)]
    assert excursion.spans(excursion.below) == [(5.5, 1.0)]
    assert excursion.sentence().endswith(
        "above in 33 % of the epochs, below in 11 %, first outside at 3 s")


def test_nees_band_summary_key():
    """summary.json's "nees_band" per filter and start; a filter whose every episode
    diverged has no band; an experiment without a NEES has none."""
    nees, diverged, (low, high) = band_series()
    error = np.zeros((EPISODES + 1, 11, 3))
    result = campaign([run("kf", error, nees, diverged),
                       run("lost", error, nees, np.ones(EPISODES + 1, bool))])
    summary = json.loads(json.dumps(nees_band_summary(result)))    # JSON as written
    entry = summary["kf"]["s"]
    np.testing.assert_allclose(entry["band"], [low, high], rtol=1e-12)
    assert (entry["dof"], entry["episodes"], entry["probability"], entry["epochs"]) == \
        (DOF, EPISODES, 0.95, 9)
    assert entry["fraction_of_epochs_above"] == pytest.approx(3 / 9)
    assert entry["fraction_of_epochs_below"] == pytest.approx(1 / 9)
    assert entry["first_time_outside_s"] == 3.0
    assert "above in 33 % of the epochs" in entry["text"]
    lost = summary["lost"]["s"]
    assert lost["band"] is None and lost["fraction_of_epochs_above"] is None
    assert lost["first_time_outside_s"] is None and lost["episodes"] == 0
    assert nees_band_summary(campaign(result.runs, dof=0)) == {}


def test_report_states_the_mean_nees_against_its_band(tmp_path):
    """The HTML page has a row per filter and start from summary.json's "nees_band"."""
    nees, diverged, _ = band_series()
    result = campaign([run("kf", np.zeros((EPISODES + 1, 11, 3)), nees, diverged)])
    (tmp_path / "settings.json").write_text(json.dumps(
        {"paper": "paper003", "scenario": "x", "experiment": {}}))
    from aligngym.scenarios.report import TIDY_COLUMNS
    text = {"filter": "kf", "start": "s", "status": "converged", "status_reason": "",
            "diverged": "False", "diverged_time_s": ""}
    (tmp_path / "results.csv").write_text(",".join(TIDY_COLUMNS) + "\n" + ",".join(
        text.get(c, "0") for c in TIDY_COLUMNS) + "\n")
    (tmp_path / "tables.txt").write_text("(the campaign's tables)\n")
    faults = {"flagged_episodes": 0, "episodes": EPISODES, "by_kind": {}, "flags": {}}
    (tmp_path / "summary.json").write_text(json.dumps(
        {"data_faults": faults, "nees_band": nees_band_summary(result)}))
    page = render_report(tmp_path)
    assert "Mean NEES against its band" in page
    assert ("kf: mean NEES of 5 episodes (4 states) against its 95 % chi-square band "
            in page and "above in 33 % of the epochs, below in 11 %" in page)
    (tmp_path / "summary.json").write_text(json.dumps({"data_faults": faults}))  # older
    assert "Mean NEES against its band" not in render_report(tmp_path)


def twin_campaign():
    """kf; sakf with kf's results (a lost episode NaN from epoch 4 on); makf one ulp off
    kf's error in one element; imakf with makf's results; rkf with kf's errors but another
    sigma (another NEES figure): sakf and imakf are twins, makf and rkf are not."""
    rng = np.random.default_rng(3)
    B, K = 4, 12
    error = rng.normal(0.0, 1.0, (B, K, 3))
    error[1, 4:] = np.nan
    nees = rng.chisquare(DOF, (B, K))
    nees[1, 4:] = np.nan
    diverged = np.array([False, True, False, False])
    off = error.copy()
    off[2, 7, 1] = np.nextafter(off[2, 7, 1], np.inf)
    return campaign([run("kf", error, nees, diverged),
                     run("sakf", error.copy(), nees.copy(), diverged.copy()),
                     run("makf", off, nees, diverged),
                     run("imakf", off.copy(), nees.copy(), diverged.copy()),
                     run("rkf", error, nees, diverged,
                         sigma_arcmin=np.full_like(error, 2.0))])


def test_identical_filters_are_found_from_their_results():
    assert identical_runs(twin_campaign()) == {("sakf", "s"): "kf", ("imakf", "s"): "makf"}


@pytest.fixture
def drawn(monkeypatch):
    """The figures of a campaign as drawn, not rasterised: name -> figure."""
    def draw(result):
        figs = {}
        monkeypatch.setattr(figures, "save_figure",
                            lambda fig, path, **_: figs.setdefault(Path(path).stem, fig))
        write_figures(result, Path("unused"), processes=1)   # drawn here, to be seen
        return figs
    return draw


def legend_texts(fig):
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    return [t.get_text() for legend in legends for t in legend.get_texts()]


def test_every_figure_marks_every_twin(drawn):
    """sakf (= kf) and imakf (= makf) in every legend, and under the final error's boxes."""
    figs = drawn(twin_campaign())
    assert set(figs) == {"fine_error_s", "final_error_s", "heading_convergence_s", "nees_s"}
    for name, fig in figs.items():
        if name.startswith("final_error"):
            texts = [t.get_text() for ax in fig.axes for t in ax.get_xticklabels()]
        else:
            texts = legend_texts(fig)
        for twin in ("sakf (= kf)", "imakf (= makf)"):
            assert any(t.startswith(twin) for t in texts), (name, twin, texts)
        assert not any(re.match(r"(kf|makf|rkf) \(=", t) for t in texts), (name, texts)


UNIT = re.compile(r"\(.*\S.*\)|\[.*\S.*\]")


def unit_campaign():
    """Two filters, 40 episodes: errors spread enough to draw fliers, one filter with a
    diverged episode inside the panel and two far off it (x and triangles)."""
    rng = np.random.default_rng(5)
    B, K = 40, 30
    error = rng.standard_t(2, (B, K, 3))
    bad = error.copy()
    bad[0, -1] = 0.5
    bad[1, -1] = 1e4
    bad[2, -1] = -1e4
    nees = rng.chisquare(DOF, (B, K)) * np.linspace(0.3, 3.0, K)
    return campaign([run("kf", error, nees, np.zeros(B, bool)),
                     run("makf", bad, nees * 1.1, np.r_[True, True, True, np.zeros(B - 3, bool)])])


def test_every_axis_has_a_unit_and_every_marker_a_legend(drawn):
    """Each panel's y label, and each x label drawn, names a unit in brackets (the final
    error's categorical x axis has the filters' names as ticks); every marker drawn in a panel has a
    legend entry with that marker, and the NEES figure's strips theirs."""
    figs = drawn(unit_campaign())
    for name, fig in figs.items():
        for ax in fig.axes:
            assert UNIT.search(ax.get_ylabel()), (name, ax.get_ylabel())
            if ax.get_xlabel():
                assert UNIT.search(ax.get_xlabel()), (name, ax.get_xlabel())
        if name.startswith("final_error"):            # categorical: the filters' names
            assert all(t.get_text() for ax in fig.axes for t in ax.get_xticklabels())
        else:
            assert any(UNIT.search(ax.get_xlabel()) for ax in fig.axes), name
        legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
        explained = {line.get_marker() for legend in legends
                     for line in legend.findobj(Line2D)}
        used = {line.get_marker() for ax in fig.axes for line in ax.get_lines()
                if len(line.get_xdata())} - {"None", "", None, " "}
        assert used <= explained, (name, used - explained)
    final = figs["final_error_s"]
    assert {"o", "x", "^", "v"} <= {line.get_marker() for ax in final.axes
                                    for line in ax.get_lines() if len(line.get_xdata())}
    texts = legend_texts(final)
    assert any("beyond the whiskers" in t for t in texts) and "quartiles" in texts
    assert "one off the panel (up, down)" in texts and "a diverged episode" in texts
    nees_texts = legend_texts(figs["nees_s"])
    assert any("chi2(160)/40" in t and f"40 episodes x {DOF} states" in t for t in nees_texts)
    assert any("top strip: epochs above band" in t for t in nees_texts)
