"""Campaign figures and ``aligngym report``: the figures of every paper's campaign, their
statistics against independent oracles, the HTML page's contents, and the page in a
headless browser."""
import base64
import csv
import json
import shutil
from html import escape
from html.parser import HTMLParser
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from aligngym.models.units import arcmin
from aligngym.scenarios.campaign import run_campaign
from aligngym.scenarios.cli import main
from aligngym.scenarios.experiments import experiment
from aligngym.scenarios.figure_statistics import (error_bands, heading_convergence_cdfs,
                                                  mean_nees_band, median_nees_band,
                                                  nees_curves)
from aligngym.scenarios.html_report import render_report
from aligngym.scenarios.report import format_tables, write_outputs

CAMPAIGNS = {
    "paper000": ({"fine_duration": 60.0, "starts": ("coarse",), "coarse_duration": 10.0},
                 ["rdghkf", "ekf"], 1),
    "paper001": ({"fine_duration": 60.0, "coarse_duration": 30.0}, ["lckf", "rakf"], 2),
    "paper002": ({"fine_duration": 30.0}, ["ekf", "ukf"], 2),
    "paper003": ({"fine_duration": 60.0}, ["kf", "makf"], 2),
    "paper004": ({"fine_duration": 60.0, "rms_start": 90.0}, ["stukf", "ekf"], 2),
}
"""Each paper's campaign: settings, filters, episodes; short runs (the figures' contract,
not the filters'); paper 000's episode costs seconds: one, with the shortest coarse stage
(10 s: an 85 s run, not 135 s); paper 001 on a scenario file whose car starts at 40 s
instead of 270 s (``early_figure8``), after 30 s of static coarse alignment: a 90 s
run."""


def early_figure8(directory):
    """figure8-gps with the car starting at 40 s, as a scenario file in directory: the
    car's run of tests/test_paper001.py's and tests/test_floors_car.py's figure-8 (their
    motion, shared through the truth cache when one of those ran first)."""
    from aligngym.scenarios.config import DATA_DIR
    text = (DATA_DIR / "figure8-gps.toml").read_text()
    assert "start_time_s = 270.0" in text
    path = directory / "figure8-early.toml"
    path.write_text(text.replace("start_time_s = 270.0", "start_time_s = 40.0")
                    .replace('name = "figure8-gps"', 'name = "figure8-early"'))
    return str(path)
HOSTILE = "<script>alert('x')</script> & \"quoted\""
"""A command-line argument the page must show as text."""


DRAWN = ("paper003",)
"""The papers whose campaign figures ``campaigns`` draws: paper 003's two starts, each of
the four kinds twice (the figure chromium opens below). The four kinds are the same code
for every paper (``scenarios.figures``; drawn again below from bench_out's paper 002 and
from diverged episodes), so the other papers' are listed (``figure_jobs``: which files,
the NEES one only with a NEES), not drawn; every experiment's own figures (000's
sensor_estimates, 004's consistency: code of their own) are drawn."""


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    """Per paper: (out dir, result, files written, the state dimensions each experiment's
    NEES was computed with, the names of the campaign figures its outputs list)."""
    import aligngym.scenarios.campaign.experiment as declared
    import aligngym.scenarios.report as report
    every_figure = report.figure_jobs
    done = {}
    scenario_file = early_figure8(tmp_path_factory.mktemp("scenario"))
    for paper, (settings, filters, episodes) in CAMPAIGNS.items():
        if paper == "paper001":
            settings = {**settings, "scenario": scenario_file}
        seen, listed = [], set()
        with pytest.MonkeyPatch.context() as mp:     # every truth map's NEES goes here
            original = declared.nees
            mp.setattr(declared, "nees", lambda e, P, f=original: seen.append(e.shape[-1])
                       or f(e, P))
            result = run_campaign(experiment(paper, **settings), episodes=episodes, seed=1,
                                  filters=filters, workers=1, progress=False)

        def figure_jobs(result, out, paper=paper, listed=listed):
            jobs = every_figure(result, out)
            listed.update(next(a for a in job.args if isinstance(a, Path)).name
                          for job in jobs)
            return jobs if paper in DRAWN else []
        out = tmp_path_factory.mktemp(paper)
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(report, "figure_jobs", figure_jobs)
            written = write_outputs(result, out, None, command=["aligngym", "bench", paper,
                                                                 HOSTILE])
        done[paper] = (out, result, written, seen, listed)
    return done


def image_pixels(path):
    from matplotlib.image import imread
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", path
    return imread(path)[..., :3].mean(-1)        # grey levels in [0, 1]


@pytest.mark.parametrize("paper", CAMPAIGNS)
def test_every_campaign_writes_its_figures(campaigns, paper):
    """Four campaign figures per start listed (and drawn, ``DRAWN``), and the experiment's
    own, valid PNGs with drawn content: grey levels spread, and more than 2 % of the
    pixels not white."""
    out, result, written, _, listed = campaigns[paper]
    expected = {f"{kind}_{start}.png" for start in result.experiment.starts
                for kind in ("fine_error", "final_error", "heading_convergence", "nees")}
    pngs = {p.name for p in out.glob("*.png")}
    assert expected <= listed
    if paper in DRAWN:
        assert listed <= pngs
    else:                                       # listed, not drawn
        assert not listed & pngs
    assert pngs == {p.name for p in written if p.suffix == ".png"}
    for name in pngs:
        grey = image_pixels(out / name)
        assert grey.shape[0] > 300 and grey.shape[1] > 600, name
        assert grey.std() > 0.05 and np.mean(grey < 0.95) > 0.02, name


@pytest.mark.parametrize("paper", CAMPAIGNS)
def test_nees_dof_is_the_dimension_the_nees_compares(campaigns, paper):
    """The chi-square band's degrees of freedom are the state count each run's NEES
    was computed with (seen by wrapping the metric)."""
    _, result, _, seen, _ = campaigns[paper]
    assert seen and set(seen) == {result.experiment.nees_dof()}


def fake_run(name, error_arcmin, sigma_arcmin, diverged, heading_convergence=None,
             start="s"):
    B, K, _ = error_arcmin.shape
    return SimpleNamespace(
        filter=name, start=start, error_n=error_arcmin * arcmin,
        diverged=np.asarray(diverged), nees=np.ones((B, K)),
        heading_convergence=(np.zeros(B) if heading_convergence is None
                             else np.asarray(heading_convergence, float)),
        result=SimpleNamespace(t=100.0 + np.arange(K), sigma_n=sigma_arcmin * arcmin))


def test_error_band_is_over_every_episode_not_diverged():
    """101 episodes whose errors at each epoch are a shuffle of 0..100 (times the axis
    number and the epoch), and one diverged episode at 1e6: the 5th, 50th and 95th
    percentiles are 5, 50, 95 exactly (linear interpolation on 101 values), which one
    left-out or one added episode would move; the mean 3 sigma is over the same 101."""
    rng = np.random.default_rng(4)
    K, values = 5, np.arange(101.0)
    scale = (1.0 + np.arange(K))[:, None] * np.array([1.0, 2.0, -3.0])     # (K, 3)
    good = np.stack([rng.permutation(values) for _ in range(K)], 1)[:, :, None] * scale
    error = np.concatenate([good, np.full((1, K, 3), 1e6)])
    sigma = np.concatenate([np.full((101, K, 3), 2.0), np.full((1, K, 3), 1e5)])
    diverged = np.r_[np.zeros(101, bool), True]
    order = rng.permutation(102)                    # the diverged one anywhere
    result = SimpleNamespace(runs=[fake_run("f", error[order], sigma[order],
                                            diverged[order])])
    band, = error_bands(result)
    assert band.episodes == 102 and band.diverged_count == 1
    low, high = np.sort([5 * scale, 95 * scale], axis=0)   # the Up axis is negated
    np.testing.assert_allclose(band.low_arcmin, low, rtol=1e-9)
    np.testing.assert_allclose(band.high_arcmin, high, rtol=1e-9)
    np.testing.assert_allclose(band.median_arcmin, 50 * scale, rtol=1e-9)
    assert np.all((band.low_arcmin <= band.median_arcmin)
                  & (band.median_arcmin <= band.high_arcmin))
    np.testing.assert_allclose(band.sigma3_arcmin, 6.0, rtol=1e-12)
    np.testing.assert_allclose(band.diverged_error_arcmin, np.full((1, K, 3), 1e6))
    np.testing.assert_allclose(band.t, np.arange(K))


def test_error_band_with_every_episode_diverged_is_empty_but_counted():
    error = np.ones((3, 4, 3))
    band, = error_bands(SimpleNamespace(runs=[fake_run("f", error, error, [True] * 3)]))
    assert band.diverged_count == 3 and np.isnan(band.median_arcmin).all()
    assert band.diverged_error_arcmin.shape == (3, 4, 3)


def test_figures_draw_diverged_episodes_without_warnings(tmp_path):
    """A filter with every episode diverged (its errors NaN after the event) and one with
    one of four: the four figures are drawn, without a NaN warning."""
    import warnings
    from aligngym.scenarios.figure_jobs import write_figures
    rng = np.random.default_rng(2)
    K = 50
    error = rng.normal(0.0, 1.0, (4, K, 3)) / (1.0 + np.arange(K))[:, None]
    lost = error.copy()
    lost[:, 20:] = np.nan
    runs = [fake_run("good", error, np.ones_like(error), [False, False, True, False]),
            fake_run("lost", lost, np.ones_like(error), [True] * 4)]
    result = SimpleNamespace(runs=runs, seeds=[0, 1, 2, 3], episodes=[], experiment=SimpleNamespace(
        starts=("s",), rms_window=10.0, heading_threshold_arcmin=0.5, nees_dof=lambda: 3,
        accuracy_window=lambda t, fine_start: t >= t[-1] - 10.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        paths = write_figures(result, tmp_path)
    assert [p.name for p in paths] == ["fine_error_s.png", "final_error_s.png",
                                       "heading_convergence_s.png", "nees_s.png"]
    for path in paths:
        assert image_pixels(path).std() > 0.05


def test_heading_convergence_counts_converged_not_converged_and_diverged():
    """Threshold 5': an episode ending at 7' has not converged (its time is the run's
    end), a diverged one is not counted as converged whatever its error."""
    final_heading = np.array([1.0, -4.0, 7.0, 0.5, 2.0])
    error = np.zeros((5, 3, 3))
    error[:, -1, 2] = final_heading
    run = fake_run("f", error, np.ones_like(error), [False, False, False, False, True],
                   heading_convergence=[40.0, 10.0, 2.0, 25.0, 1.0])
    result = SimpleNamespace(runs=[run],
                             experiment=SimpleNamespace(heading_threshold_arcmin=5.0))
    cdf, = heading_convergence_cdfs(result)
    np.testing.assert_array_equal(cdf.times, [10.0, 25.0, 40.0])
    assert (cdf.episodes, cdf.diverged, cdf.not_converged, cdf.t_end) == (5, 1, 1, 2.0)


def test_nees_curves_leave_diverged_episodes_out():
    error = np.zeros((3, 4, 3))
    run = fake_run("f", error, error + 1, [False, False, True])
    run.nees = np.array([[9.0, 1.0, 2.0, np.nan], [9.0, 3.0, 6.0, np.nan],
                         [9.0, 1e6, 1e6, 1e6]])
    curve, = nees_curves(SimpleNamespace(runs=[run]))
    np.testing.assert_allclose(curve.mean[:2], [2.0, 4.0])
    np.testing.assert_allclose(curve.median[:2], [2.0, 4.0])
    assert np.isnan(curve.mean[2]) and (curve.episodes, curve.diverged) == (2, 1)


@pytest.mark.parametrize("dof, episodes", [(3, 7), (9, 10), (15, 3)])
def test_nees_bands_cover_95_percent_of_consistent_campaigns(dof, episodes):
    """Monte Carlo oracle: 40000 campaigns of chi-square(dof) NEES per episode; the mean
    band holds 95 % of their means, the median band 95 % of their medians (odd episode
    counts; at least 95 % and less than 99.5 % for even ones). A band built with dof
    instead of episodes x dof would hold far more, one without the 1/B far less."""
    rng = np.random.default_rng(11)
    draws = rng.chisquare(dof, size=(40000, episodes))
    low, high = mean_nees_band(dof, episodes)
    inside = np.mean((draws.mean(1) >= low) & (draws.mean(1) <= high))
    assert abs(inside - 0.95) < 0.006
    low, high = median_nees_band(dof, episodes)
    inside = np.mean((np.median(draws, 1) >= low) & (np.median(draws, 1) <= high))
    if episodes % 2:
        assert abs(inside - 0.95) < 0.006
    else:
        assert 0.945 < inside < 0.995


def test_the_bands_are_scipy_stats_numbers_without_importing_it():
    """The quantiles (the NEES bands', the gated strong-tracking factor's threshold) come
    from scipy.special (scipy.stats costs a report 1 s to import): the same numbers as
    scipy.stats' chi2 and beta, bit for bit, and a report's bands and a gated filter's
    update leave scipy.stats unimported."""
    import subprocess
    import sys

    from scipy.stats import beta, chi2

    from aligngym.estimators.metrics import chi2_quantile
    for dof in (1, 2, 3, 9, 15, 150, 4500):
        for q in (0.0005, 0.025, 0.5, 0.975, 0.999):
            assert chi2_quantile(q, dof) == chi2.ppf(q, dof)
    dofs = np.array([1, 2, 3, 6])
    np.testing.assert_array_equal(chi2_quantile(0.999, dofs), chi2.ppf(0.999, dofs))
    code = ("import sys, numpy as np\n"
            "from aligngym.scenarios.figure_statistics import mean_nees_band, median_nees_band\n"
            "from aligngym.estimators.adaptation import AdaptationContext\n"
            "from aligngym.estimators.fading_factors import SingleFadingFactor\n"
            "mean_nees_band(3, 10); median_nees_band(3, 10)\n"
            "p = SingleFadingFactor(outlier_probability=0.999); p.reset(1)\n"
            "ctx = AdaptationContext(innovation=np.ones((1, 2)), valid=np.ones((1, 2), bool),"
            " S=np.eye(2)[None], P_xz=np.zeros((1, 3, 2)), PhiPPhi=np.eye(3)[None],"
            " Q=np.eye(3)[None], R=np.eye(2)[None], H=np.zeros((1, 2, 3)))\n"
            "p._outliers(ctx, ctx.valid)\n"
            "assert 'scipy.stats' not in sys.modules, 'scipy.stats imported'\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    tail = (1.0 - 0.95) / 2.0
    for dof, episodes in ((3, 7), (9, 10), (15, 3), (9, 50)):
        k_low, k_high = (episodes + 1) // 2, episodes // 2 + 1
        assert median_nees_band(dof, episodes) == (
            chi2.ppf(beta.ppf(tail, k_low, episodes + 1 - k_low), dof),
            chi2.ppf(beta.ppf(1.0 - tail, k_high, episodes + 1 - k_high), dof))
        assert mean_nees_band(dof, episodes) == (chi2.ppf(tail, dof * episodes) / episodes,
                                                 chi2.ppf(1.0 - tail, dof * episodes)
                                                 / episodes)


class Page(HTMLParser):
    """Images, links and <pre> texts of an HTML page."""

    def __init__(self, text):
        super().__init__(convert_charrefs=True)
        self.images, self.refs, self.pre, self.text, self._in_pre = [], [], [], [], False
        self.tags = []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append(tag)
        if tag == "img":
            self.images.append(attrs.get("src", ""))
        self.refs += [v for k, v in attrs.items() if k in ("src", "href") and v]
        if tag == "pre":
            self._in_pre = True
            self.pre.append("")

    def handle_endtag(self, tag):
        if tag == "pre":
            self._in_pre = False

    def handle_data(self, data):
        self.text.append(data)
        if self._in_pre:
            self.pre[-1] += data


@pytest.mark.parametrize("paper", CAMPAIGNS)
def test_report_holds_every_figure_and_table(campaigns, paper):
    out, result, _, _, _ = campaigns[paper]
    assert main(["report", str(out)]) == 0
    page = Page((out / "report.html").read_text(encoding="utf-8"))
    pngs = sorted(out.glob("*.png"))
    prefix = "data:image/png;base64,"
    assert len(page.images) == len(pngs) and all(s.startswith(prefix) for s in page.images)
    assert sorted(base64.b64decode(s[len(prefix):]) for s in page.images) == \
        sorted(p.read_bytes() for p in pngs)
    # Nothing to fetch: every reference is a data URI or an anchor on the page.
    assert all(r.startswith(("data:", "#")) for r in page.refs), page.refs
    assert "script" not in page.tags                 # the hostile argument is text
    assert format_tables(result) + "\n" in page.pre
    assert (out / "tables.txt").read_text() in page.pre
    settings = json.loads((out / "settings.json").read_text())
    assert settings["command"][-1] == HOSTILE and any(HOSTILE in p for p in page.pre)
    assert settings["scenario_toml"] in page.pre
    text = " ".join(page.text)
    for run in result.runs:
        assert run.filter in text
    assert f"{settings['paper']} on {settings['scenario']}" in text


@pytest.mark.parametrize("paper", CAMPAIGNS)
def test_summary_and_report_state_the_mean_nees_against_its_band(campaigns, paper):
    """summary.json's "nees_band" (issue 46): per filter and start the band of its
    episodes not diverged and the fraction of the epochs outside it, as the NEES curves
    give them; the report has a row per filter and start in the same words."""
    out, result, _, _, _ = campaigns[paper]
    bands = json.loads((out / "summary.json").read_text())["nees_band"]
    dof = result.experiment.nees_dof()
    for curve in nees_curves(result):
        entry = bands[curve.filter][curve.start]
        assert entry["episodes"] == curve.episodes and entry["dof"] == dof
        if not curve.episodes:                     # every episode diverged: no band
            assert entry["band"] is None and entry["fraction_of_epochs_above"] is None
            continue
        low, high = mean_nees_band(dof, curve.episodes)
        assert entry["band"] == [low, high]
        counted = np.isfinite(curve.mean)
        assert entry["fraction_of_epochs_above"] == pytest.approx(
            np.sum(curve.mean[counted] > high) / counted.sum())
        assert entry["fraction_of_epochs_below"] == pytest.approx(
            np.sum(curve.mean[counted] < low) / counted.sum())
    page = render_report(out)
    for per_start in bands.values():
        for entry in per_start.values():
            assert escape(entry["text"]) in page


def test_report_of_a_directory_of_campaigns(campaigns, tmp_path):
    """bench paper004 --swing all writes one campaign per level under --out: one page,
    a section each, every figure of both (campaigns with figures: paper 004's own one,
    paper 003's eight, ``DRAWN``)."""
    for name, paper in (("mild", "paper004"), ("severe", "paper003")):
        shutil.copytree(campaigns[paper][0], tmp_path / name)
    assert main(["report", str(tmp_path)]) == 0
    page = Page((tmp_path / "report.html").read_text(encoding="utf-8"))
    assert len(page.images) == len(list(tmp_path.glob("*/*.png")))
    assert "#campaign-mild" in page.refs and "#campaign-severe" in page.refs


def test_report_bad_dir_is_a_one_line_error(tmp_path, capsys):
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "campaign.json").write_text("{}")
    (tmp_path / "file.txt").write_text("x")
    (tmp_path / "empty").mkdir()
    cases = {tmp_path / "missing": "no such directory",
             tmp_path / "file.txt": "no such directory",
             tmp_path / "empty": "not a campaign directory",
             tmp_path / "old": "without settings.json, results.csv, tables.txt"}
    for path, message in cases.items():
        assert main(["report", str(path)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"report DIR {path}" in err[0] and message in err[0], err
    assert not (tmp_path / "empty" / "report.html").exists()


BENCH = ["bench", "paper002", "--episodes", "2", "--filters", "ekf", "--workers", "1",
         "--set", "fine_duration=60"]
"""A bench campaign whose directory's contents are under test, not the alignment: 60 s
of fine alignment, not 600 s."""


@pytest.fixture(scope="module")
def bench_out(tmp_path_factory):
    """``BENCH --out DIR`` with its figures: (the arguments, DIR, what it printed, the
    names of the files it wrote), shared by the two tests below."""
    import contextlib
    import io
    out = tmp_path_factory.mktemp("bench") / "b"
    args = BENCH + ["--out", str(out)]
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main(args) == 0
    return args, out, printed.getvalue(), {p.name for p in out.iterdir()}


def test_bench_out_is_self_describing_and_reported(bench_out):
    """bench --out writes its settings (the command, paper, scenario, seed, versions), its
    tables and summary, and aligngym report makes the page from them."""
    args, out, printed, _ = bench_out
    settings = json.loads((out / "settings.json").read_text())
    assert settings["command"] == ["aligngym", *args]
    assert (settings["paper"], settings["scenario"], settings["seed"]) == \
        ("paper002", "static-large-azimuth", 0)
    assert settings["episodes"] == 2 and settings["filters"] == ["ekf"]
    assert settings["versions"]["numpy"] == np.__version__
    assert (out / "tables.txt").read_text() in printed
    assert json.loads((out / "summary.json").read_text())["fine"].keys() == {"ekf"}
    with open(out / "results.csv") as f:       # one batch: its time is one batch's
        assert {row["ms_per_epoch_chunks"] for row in csv.DictReader(f)} == {"1"}
    assert main(["report", str(out)]) == 0
    assert (out / "report.html").stat().st_size > 10_000


def test_no_figures_leaves_out_the_pngs_only(bench_out, tmp_path):
    """bench --no-figures: every other output, the same numbers, no PNG; the report page
    is still made. (The run with figures is ``bench_out``'s, its files as it wrote them.)"""
    _, drawn, _, names = bench_out
    bare = tmp_path / "bare"
    assert main(BENCH + ["--out", str(bare), "--no-figures"]) == 0
    assert list(drawn.glob("*.png")) and not list(bare.glob("*.png"))
    assert {n for n in names if not n.endswith(".png")} == {p.name for p in bare.iterdir()}
    import csv

    def rows(folder):                    # the numbers, without the measured ms/epoch
        with open(folder / "results.csv") as f:
            return [{k: v for k, v in row.items() if k != "ms_per_epoch"}
                    for row in csv.DictReader(f)]
    assert rows(bare) == rows(drawn)
    assert main(["report", str(bare)]) == 0 and (bare / "report.html").is_file()


CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync"]


@pytest.mark.skipif(not CHROMIUM.is_file(), reason="no /usr/bin/chromium (Debian package "
                    "chromium; .ci/run installs it)")
def test_report_renders_in_headless_chromium(campaigns):
    """The page opens in a browser with no console error or page error, and every image
    decodes (complete, natural width > 0)."""
    from playwright.sync_api import sync_playwright

    out = campaigns["paper003"][0]
    assert main(["report", str(out)]) == 0
    errors = []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            page = browser.new_page()
            page.on("console", lambda m: errors.append(f"console {m.type}: {m.text}")
                    if m.type in ("error", "warning") else None)
            page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
            page.goto((out / "report.html").resolve().as_uri(), wait_until="load")
            images = page.evaluate("() => Array.from(document.images).map("
                                   "i => [i.complete, i.naturalWidth, i.alt])")
        finally:
            browser.close()
    assert errors == []
    assert len(images) == len(list(out.glob("*.png")))
    broken = [alt for complete, width, alt in images if not (complete and width > 0)]
    assert broken == []


def _worker_facts(name):
    """A figure job for the test below: this process's pid and the campaign locks it
    holds, as a 'path'."""
    import os
    from aligngym.scenarios.campaign.manifest import _HELD
    return Path(f"{name}-{os.getpid()}-{len(_HELD)}")


def _failing_job():
    raise RuntimeError("a figure failed")


def test_figures_are_drawn_in_workers_that_hold_no_lock(tmp_path, monkeypatch):
    """With two cores the figure jobs run in forked workers (their own pids), which hold
    none of the campaign locks the parent holds; the paths come back in the jobs' order;
    a job's error reaches the caller; no jobs, nothing; processes = 0 is refused."""
    import os
    from functools import partial

    from aligngym.scenarios.figure_jobs import FigureDrawing
    from aligngym.scenarios.campaign import executors
    from aligngym.scenarios.campaign.manifest import campaign_lock
    monkeypatch.setattr(executors, "usable_cores", lambda: 2)
    with campaign_lock(tmp_path):
        drawing = FigureDrawing.start([partial(_worker_facts, n) for n in "abc"])
        paths = drawing.finish()
    names = [p.name.split("-") for p in paths]
    assert [n[0] for n in names] == ["a", "b", "c"]
    assert all(int(n[1]) != os.getpid() and n[2] == "0" for n in names)
    with pytest.raises(RuntimeError, match="a figure failed"):
        FigureDrawing.start([partial(_worker_facts, "x"), _failing_job]).finish()
    assert FigureDrawing.start([]).finish() == []
    with pytest.raises(ValueError, match="figure processes = 0 must be >= 1"):
        FigureDrawing.start([_failing_job], processes=0)


def test_the_cost_column_says_when_a_filter_ran_in_chunks():
    """results.csv's ms_per_epoch of a filter run in chunks is their sum (each paying the
    fixed cost an epoch): the report's cell says so; a directory from before the column,
    or a value that is not a count, shows the time alone."""
    from aligngym.scenarios.html_report import _ms_per_epoch
    rows = [{"ms_per_epoch": "0.5", "ms_per_epoch_chunks": "2"},
            {"ms_per_epoch": "0.7", "ms_per_epoch_chunks": "2"}]
    assert _ms_per_epoch(rows) == "0.6 (sum of 2 chunks)"
    assert _ms_per_epoch([{"ms_per_epoch": "0.6", "ms_per_epoch_chunks": "1"}]) == "0.6"
    assert _ms_per_epoch([{"ms_per_epoch": "0.6"}]) == "0.6"
    assert _ms_per_epoch([{"ms_per_epoch": "0.6", "ms_per_epoch_chunks": "x"}]) == "0.6"
