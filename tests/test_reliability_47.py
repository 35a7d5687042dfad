"""Issue 47, items 4-8: NaN is never inside a band (convergence time, per-episode and
paper metrics); the JSON written is strict (NaN and inf are null); an --episodes the
machine cannot hold is refused before anything is written; the env's step count is the
one its truncation uses; the truth cache leaves no lock file."""
import json
import math
import multiprocessing
import os
from dataclasses import replace

import numpy as np
import pytest

from aligngym.estimators.metrics import convergence_time
from aligngym.scenarios import truth_cache
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.experiments import experiment

QUICK = {"fine_duration": 30.0}
"""Paper 002's static base for 30 s: an episode costs a few ms."""


def quick(**settings):
    return experiment("paper002", **{**QUICK, **settings})


def strict_loads(text: str):
    """json.loads that refuses NaN, Infinity and -Infinity as a strict parser does."""
    def refuse(name):
        raise ValueError(f"bare {name} in the JSON")
    return json.loads(text, parse_constant=refuse)


# --- item 4: NaN is never inside a band ------------------------------------------------
def test_a_non_finite_error_is_outside_the_convergence_band():
    t = np.arange(5.0)
    nan, inf = np.nan, np.inf
    error = np.array([[nan, nan, nan, nan, nan],      # NaN throughout: never (t[-1])
                      [0.1, 0.1, 0.1, 0.1, nan],      # NaN at the end: never
                      [nan, nan, 0.1, 0.1, 0.1],      # inside from t = 2
                      [0.1, nan, 0.1, -0.1, 0.1],     # a NaN epoch, then inside: t = 2
                      [5.0, 0.1, -inf, 0.1, 0.1]])    # inf is outside too: t = 3
    np.testing.assert_array_equal(convergence_time(t, error, 1.0), [4.0, 4.0, 2.0, 2.0, 3.0])


@pytest.fixture(scope="module")
def nan_run():
    """A real ekf run on two quick episodes, then the same run with its estimate and
    sigma NaN throughout (a filter that broke at once), analysed as the campaign does."""
    from aligngym.scenarios.campaign.runs import analyse_run, run_filter
    exp = quick()
    episodes = [exp.prepare_episode(s) for s in (1, 2)]
    good = run_filter("ekf", "large-azimuth", exp.start_errors(episodes)["large-azimuth"],
                      episodes, exp)
    r = good.result
    broken = replace(r, C_s_n=np.full_like(r.C_s_n, np.nan),
                     sigma_n=np.full_like(r.sigma_n, np.nan), P=np.full_like(r.P, np.nan))
    return exp, episodes, good, analyse_run("ekf", "large-azimuth", broken, episodes, exp)


def test_a_filter_nan_throughout_is_diverged_and_never_converged(nan_run):
    from aligngym.scenarios.campaign.runs import episode_metrics
    exp, episodes, good, bad = nan_run
    end = float(bad.result.t[-1] - bad.result.t[0])
    assert list(bad.status) == ["diverged", "diverged"]
    np.testing.assert_array_equal(bad.heading_convergence, [end, end])
    row = episode_metrics(bad, 0, exp, episodes[0].fine_start)
    assert row["status"] == "diverged"
    assert row["heading_convergence_s"] == end          # the run's end: never converged
    assert math.isnan(row["final_phi_U_arcmin"])
    assert list(good.status) != ["diverged", "diverged"]


def test_paper_metrics_count_nan_as_outside(nan_run):
    """Paper 004's run metrics (its own convergence and 3-sigma fractions) on a run that
    is NaN throughout: never converged, never inside its 3 sigma, outside the 1-deg."""
    from aligngym.scenarios.analyses import paper004
    exp, episodes, _, bad = nan_run

    class Episode:
        fine_start = 0.0

    class Window:
        def accuracy_window(self, t, fine_start):
            return np.ones(t.size, bool)

        def nees_dof(self):
            return 9

    out = paper004.run_metrics(bad, [Episode()], Window())
    end = float(bad.result.t[-1] - bad.result.t[0])
    assert out["convergence_s"] == end and out["convergence_p90_s"] == end
    assert out["heading_inside_3sigma"] == 0.0
    assert out["heading_outside_1deg_fraction"] == 1.0


# --- item 5: strict JSON -----------------------------------------------------------------
def test_write_json_writes_null_for_non_finite_numbers(tmp_path):
    from aligngym.scenarios.atomic import write_json
    value = {"a": float("nan"), "b": [1.0, float("inf"), -float("inf")],
             "c": {"d": np.float64("nan"), "e": np.float32(2.5), "f": np.int64(3)},
             "g": (np.nan, 2), "h": np.array([1.0, np.nan]), "i": None, "j": True, "k": "NaN"}
    path = write_json(tmp_path / "x.json", value)
    assert strict_loads(path.read_text()) == {
        "a": None, "b": [1.0, None, None], "c": {"d": None, "e": 2.5, "f": 3},
        "g": [None, 2], "h": [1.0, None], "i": None, "j": True, "k": "NaN"}


def test_summary_and_json_of_a_campaign_with_nan_metrics_are_strict(tmp_path, monkeypatch):
    """A campaign whose summary holds NaN (a metric over no episode) writes summary.json,
    settings.json and --json strictly; the HTML report and regress's flatten read them
    back (null -> NaN)."""
    from aligngym.scenarios.cli import main
    from aligngym.scenarios.experiments.paper002 import Paper002Experiment
    from aligngym.scenarios.regress import flatten
    original = Paper002Experiment.summary

    def with_nan(self, result):
        out = original(self, result)
        out["nan_metric"] = float("nan")
        out["inf_list"] = [float("inf"), 1.0]
        return out
    monkeypatch.setattr(Paper002Experiment, "summary", with_nan)
    out, js = tmp_path / "camp", tmp_path / "s.json"
    assert main(["bench", "paper002", "--episodes", "2", "--filters", "ekf", "--set",
                 "fine_duration=30", "--workers", "1", "--no-figures", "--out", str(out),
                 "--json", str(js)]) == 0
    for path in (js, out / "summary.json", out / "settings.json", out / "campaign.json"):
        strict_loads(path.read_text())
    loaded = strict_loads(js.read_text())
    assert loaded["nan_metric"] is None and loaded["inf_list"] == [None, 1.0]
    flat = flatten(loaded)
    assert math.isnan(flat["nan_metric"]) and math.isnan(flat["inf_list/0"])
    assert main(["report", str(out)]) == 0
    assert (out / "report.html").is_file()


# --- item 6: an --episodes the machine cannot hold ----------------------------------------
@pytest.fixture
def no_huge_allocation(monkeypatch):
    """The seeds list of a huge campaign is where it ran out of memory: here it raises
    MemoryError at once instead of trying (the refusal must come before it)."""
    from aligngym.scenarios.campaign import engine, episodes
    real = episodes.episode_seeds

    def seeds(seed, count):
        if count > 10 ** 6:
            raise MemoryError
        return real(seed, count)
    monkeypatch.setattr(engine, "episode_seeds", seeds)
    monkeypatch.setattr(episodes, "episode_seeds", seeds)
    from aligngym.scenarios import bank
    real_split = bank.split_seeds

    def split(name, count, first=0):
        lo, hi = bank.check_split(name)
        if count > 10 ** 6 and lo + first + count <= hi:   # beyond: refused, not listed
            raise MemoryError
        return real_split(name, count, first)
    monkeypatch.setattr(bank, "split_seeds", split)


@pytest.mark.parametrize("memory", [None, 4e9])
def test_too_many_episodes_are_refused_in_one_line_before_anything_is_written(
        memory, tmp_path, monkeypatch, capsys, no_huge_allocation):
    from aligngym.scenarios import simulate
    from aligngym.scenarios.cli import main
    if memory is not None:
        monkeypatch.setattr(simulate, "available_memory", lambda: memory)
    out = tmp_path / "new" / "campaign"
    assert main(["bench", "paper002", "--episodes", "2000000000", "--filters", "ekf",
                 "--set", "fine_duration=30", "--workers", "1", "--no-figures", "--out",
                 str(out), "--json", str(tmp_path / "s.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aligngym: error: --episodes 2000000000 ")
    assert "at most " in err[0] and "episodes" in err[0]
    assert not (tmp_path / "new").exists() and not (tmp_path / "s.json").exists()


def test_the_episode_limit_follows_the_available_memory(tmp_path, monkeypatch,
                                                        no_huge_allocation):
    from aligngym.scenarios import simulate
    from aligngym.scenarios.campaign import run_campaign
    from aligngym.scenarios.campaign.engine import check_campaign_memory
    monkeypatch.setattr(simulate, "available_memory", lambda: 1e9)
    exp = quick()
    with pytest.raises(ConfigError, match=r"^--episodes 100000 needs about .* at most "
                                          r"(\d+) episodes") as err:
        run_campaign(exp, episodes=100000, filters=["ekf"], out_dir=tmp_path / "out",
                     progress=False)
    assert not (tmp_path / "out").exists()
    limit = int(str(err.value).split("at most ")[1].split()[0])
    assert 1000 < limit < 100000
    check_campaign_memory(exp, limit, ["ekf"])            # the limit itself runs
    with pytest.raises(ConfigError):
        check_campaign_memory(exp, limit + 1, ["ekf"])
    with pytest.raises(ConfigError):                     # more filters: fewer episodes
        check_campaign_memory(exp, limit, ["ekf", "ukf"])
    monkeypatch.setattr(simulate, "available_memory", lambda: None)   # unknown: no limit
    check_campaign_memory(exp, 10 ** 9, ["ekf"])


def test_reproduce_and_bank_refuse_a_huge_episodes_before_writing(tmp_path, capsys,
                                                                  no_huge_allocation):
    from aligngym.scenarios.cli import main
    assert main(["reproduce", "paper002", "--episodes", "2000000000", "--out",
                 str(tmp_path / "rep")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--episodes 2000000000" in err[0] and "at most" in err[0]
    assert not (tmp_path / "rep").exists()
    for count in ("1000000000", "2000000000"):      # within the train split, beyond it
        assert main(["bank", "static-large-azimuth", "--episodes", count, "--out",
                     str(tmp_path / "bank"), "--episode-length", "30"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("aligngym: error: ")
        assert not (tmp_path / "bank").exists()


# --- item 7: one step count ----------------------------------------------------------------
@pytest.mark.parametrize("length, epoch, steps", [
    (5.0, 0.3, 16), (5.0, 0.7, 7), (5.0, 1.1, 4), (600.0, 0.3, 2000), (600.0, 0.7, 857),
    (600.0, 1.1, 545), (0.3, 0.1, 3), (0.7, 0.1, 7), (1.0, 0.1, 10), (600.0, 1.0, 600),
    (5.0, 5.0, 1), (0.6, 0.2, 3)])
def test_the_step_count_is_the_whole_epochs_in_the_episode(length, epoch, steps):
    from aligngym.scenarios.env_core import episode_step_count
    assert episode_step_count(length, epoch) == steps


@pytest.mark.parametrize("length, epoch", [(5.0, 0.3), (5.0, 0.7), (5.0, 1.1), (0.3, 0.1),
                                           (600.0, 1.1)])
def test_the_env_truncates_after_episode_steps(length, epoch):
    from aligngym.scenarios.env import AlignmentEnv
    from aligngym.scenarios.vector_env import AlignmentVectorEnv
    env = AlignmentEnv(scenario="static-large-azimuth", estimator="ekf",
                       episode_length=length, epoch_length=epoch)
    env.reset(seed=1)
    zero = np.zeros(env.action_space.shape)
    steps = 0
    while True:
        _, _, terminated, truncated, info = env.step(zero)
        steps += 1
        if terminated or truncated:
            break
    assert truncated and not terminated
    assert steps == env.episode_steps
    assert info["time_s"] == pytest.approx(env.episode_steps * epoch)
    env.close()
    if length > 10.0:
        return
    venv = AlignmentVectorEnv(2, scenario="static-large-azimuth", estimator="ekf",
                              episode_length=length, epoch_length=epoch)
    venv.reset(seed=1)
    for k in range(venv.episode_steps):
        _, _, terminated, truncated, _ = venv.step(np.zeros((2,) + zero.shape))
        assert not terminated.any()
        assert truncated.all() == (k == venv.episode_steps - 1)
    venv.close()


# --- item 8: the truth cache's locks ------------------------------------------------------
@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv(truth_cache.TRUTH_CACHE_ENV, str(tmp_path / "truth"))
    monkeypatch.setattr(truth_cache, "FREE_BYTES_KEPT", 0)
    monkeypatch.setattr(truth_cache, "_reported", set())
    return tmp_path / "truth"


def test_stores_loads_and_eviction_leave_no_lock_file(cache, monkeypatch):
    arrays = {"x": np.arange(1000.0)}                          # 8 kB an entry
    monkeypatch.setattr(truth_cache._trim, "__defaults__", (5 * 8400,))   # 5 entries
    for i in range(12):                      # stored (and the oldest evicted), then loaded
        got = truth_cache.cached_arrays("test", (i,), lambda: arrays)
        np.testing.assert_array_equal(got["x"], arrays["x"])
    for i in range(12):
        truth_cache.cached_arrays("test", (i,), lambda: arrays)
    names = [p.name for p in cache.iterdir()]
    assert names and all(n.endswith(".npz") for n in names), names
    assert len(names) <= 5


def test_lock_files_left_by_an_earlier_version_are_removed_when_free(cache):
    import fcntl
    cache.mkdir(parents=True)
    stale = cache / "old-0123.lock"
    stale.write_text("")
    held = cache / "held-4567.lock"
    with open(held, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)                 # another process computing
        truth_cache.cached_arrays("test", (1,), lambda: {"x": np.zeros(3)})
        assert not stale.exists() and held.exists()
    truth_cache.cached_arrays("test", (2,), lambda: {"x": np.zeros(3)})
    assert not held.exists()
    assert not list(cache.glob("*.lock"))


def _store_slowly(folder: str, start, queue) -> None:
    os.environ[truth_cache.TRUTH_CACHE_ENV] = folder
    truth_cache.FREE_BYTES_KEPT = 0
    calls = []

    def compute():
        calls.append(1)
        import time
        time.sleep(0.3)
        return {"x": np.arange(50000.0)}
    start.wait()
    arrays = truth_cache.cached_arrays("race", ("same",), compute)
    queue.put((len(calls), float(arrays["x"].sum())))


def test_two_processes_storing_one_entry_at_once_make_one_valid_entry(cache):
    context = multiprocessing.get_context("fork")
    start, queue = context.Event(), context.Queue()
    workers = [context.Process(target=_store_slowly, args=(str(cache), start, queue))
               for _ in range(3)]
    for w in workers:
        w.start()
    start.set()
    results = [queue.get(timeout=60) for _ in workers]
    for w in workers:
        w.join(timeout=60)
        assert w.exitcode == 0
    assert sorted(c for c, _ in results) == [0, 0, 1]      # simulated once, loaded twice
    assert all(s == float(np.arange(50000.0).sum()) for _, s in results)
    (entry,) = cache.iterdir()
    assert entry.suffix == ".npz"
    with np.load(entry) as f:
        np.testing.assert_array_equal(f["x"], np.arange(50000.0))


@pytest.mark.parametrize("epoch", [0.3, 1.1])
def test_paper003s_env_steps_whole_epochs_that_do_not_divide_the_episode(epoch):
    """The ship's env (paper 003's inertial-frame model) over 5 s in epochs that do not
    divide it: floor(5 / epoch) steps, then truncated (it refused: its model cut
    round(5 / epoch) steps, one beyond the data)."""
    import gymnasium as gym
    from aligngym.scenarios.env_core import episode_step_count
    env = gym.make("aligngym/ShipSwayRotary-v1", episode_length=5.0, epoch_length=epoch)
    env.reset(seed=0)
    steps, truncated = 0, False
    while not truncated:
        _, _, terminated, truncated, _ = env.step(np.zeros(env.action_space.shape))
        steps += 1
        assert not terminated
    assert steps == episode_step_count(5.0, epoch) == int(5.0 // epoch)
    env.close()
