"""The truth cache (``scenarios.truth_cache``): another process loads what one simulated,
the same episode bit for bit; a damaged entry is simulated again; a cache that cannot be
written is reported once; processes needing one entry at once simulate it once; the
least recently used entries go first."""
import os
import time

import numpy as np
import pytest

from aligngym.scenarios import simulate as sim
from aligngym.scenarios import world_truth
from aligngym.scenarios import truth_cache
from aligngym.scenarios.config import load_scenario


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv(truth_cache.TRUTH_CACHE_ENV, str(tmp_path / "truth"))
    monkeypatch.setattr(truth_cache, "FREE_BYTES_KEPT", 0)   # written on a fuller disk too
    monkeypatch.setattr(truth_cache, "_reported", set())
    world_truth.prescribed_world_truth.cache_clear()   # the per-process level: only the disk's
    yield tmp_path / "truth"
    world_truth.prescribed_world_truth.cache_clear()


def ship(duration=20.0):
    return load_scenario("ship-sway-rotary").with_options(duration=duration)


def same(a, b):
    for name, value in a.arrays().items():
        np.testing.assert_array_equal(b.arrays()[name], value, err_msg=name)


def no_simulation(*args, **kwargs):
    raise AssertionError("simulated although the cache holds the truth")


def test_an_entry_is_loaded_instead_of_simulated_and_gives_the_same_episode(cache,
                                                                           monkeypatch):
    first = sim.simulate(ship(), seed=3)
    assert len(list(cache.glob("ship-prescribed-*.npz"))) == 1
    world_truth.prescribed_world_truth.cache_clear()
    monkeypatch.setattr(world_truth, "_prescribed_truth", no_simulation)
    same(first, sim.simulate(ship(), seed=3))
    with pytest.raises(ValueError, match="read-only"):
        sim.simulate(ship(), seed=3).truth.q_b_n[0, 0] = 1.0


def test_a_damaged_entry_is_simulated_again(cache):
    first = sim.simulate(ship(), seed=4)
    (entry,) = cache.glob("*.npz")
    entry.write_bytes(entry.read_bytes()[:1000])          # cut short, as by a full disk
    world_truth.prescribed_world_truth.cache_clear()
    same(first, sim.simulate(ship(), seed=4))
    with np.load(entry) as f:
        assert "dtheta" in f.files                         # written whole again


def test_a_cache_that_cannot_be_written_is_reported_once(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    monkeypatch.setenv(truth_cache.TRUTH_CACHE_ENV, str(blocker / "truth"))
    monkeypatch.setattr(truth_cache, "_reported", set())
    world_truth.prescribed_world_truth.cache_clear()
    with pytest.warns(RuntimeWarning, match="cannot be written.*simulating without it"):
        first = sim.simulate(ship(), seed=5)
    world_truth.prescribed_world_truth.cache_clear()
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        again = sim.simulate(ship(), seed=5)
    same(first, again)
    world_truth.prescribed_world_truth.cache_clear()


def test_off_and_another_code_version_use_no_entry(cache, monkeypatch):
    """Other simulation code (``truth_versions``) names other entries; other preparation
    code alone (a filter's or an experiment's edit: ``simulation_versions``) the same."""
    assert truth_cache.cache_directory() == cache
    name = truth_cache.entry_name("k", (1.0, "x"))
    monkeypatch.setattr(truth_cache, "simulation_versions", lambda: "another filter's code")
    assert truth_cache.entry_name("k", (1.0, "x")) == name
    monkeypatch.setattr(truth_cache, "truth_versions", lambda: "another simulation code")
    assert truth_cache.entry_name("k", (1.0, "x")) != name
    monkeypatch.setenv(truth_cache.TRUTH_CACHE_ENV, "off")
    assert truth_cache.cache_directory() is None
    assert truth_cache.cached_arrays("k", (1,), lambda: {"a": np.ones(2)})["a"].sum() == 2
    assert not cache.exists()


def _entry_at_once(folder: str, log: str, start) -> None:
    """Wait for the other process, then ask for the slow entry; log who computed it."""
    os.environ[truth_cache.TRUTH_CACHE_ENV] = folder
    start.wait()

    def compute():
        with open(log, "a") as f:
            f.write("computed\n")
        time.sleep(0.5)
        return {"a": np.arange(3.0)}
    total = float(truth_cache.cached_arrays("slow", (1,), compute)["a"].sum())
    with open(log, "a") as f:
        f.write(f"{os.getpid()} {total}\n")


def test_processes_needing_one_entry_at_once_simulate_it_once(tmp_path, monkeypatch):
    import multiprocessing
    monkeypatch.setattr(truth_cache, "FREE_BYTES_KEPT", 0)    # the forked workers' too
    fork = multiprocessing.get_context("fork")
    log, start = tmp_path / "log", fork.Barrier(2)
    workers = [fork.Process(target=_entry_at_once, args=(str(tmp_path / "truth"), str(log),
                                                         start)) for _ in range(2)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(30)
    lines = log.read_text().splitlines()
    assert lines.count("computed") == 1
    done = [line.split() for line in lines if line != "computed"]
    assert sorted(pid for pid, _ in done) == sorted(str(w.pid) for w in workers)
    assert all(total == "3.0" for _, total in done)


def test_an_entry_that_cannot_be_touched_is_still_loaded_and_kept(cache, monkeypatch):
    """Another user's entry, or a read-only cache: it loads, and nothing removes it."""
    first = truth_cache.cached_arrays("k", (2,), lambda: {"a": np.arange(4.0)})
    (entry,) = cache.glob("*.npz")
    os.utime(entry, (1000.0, 1000.0))

    def refused(*args, **kwargs):
        raise PermissionError(1, "Operation not permitted")
    with monkeypatch.context() as patch:
        patch.setattr(os, "utime", refused)
        again = truth_cache.cached_arrays("k", (2,), no_simulation)
    np.testing.assert_array_equal(again["a"], first["a"])
    assert entry.is_file()
    truth_cache.cached_arrays("k", (2,), no_simulation)
    assert entry.stat().st_mtime > 1000.0      # a load marks it recently used


def test_a_disk_nearly_full_is_not_filled(cache, monkeypatch):
    monkeypatch.setattr(truth_cache, "FREE_BYTES_KEPT", 10 ** 18)
    with pytest.warns(RuntimeWarning, match="would stay free"):
        truth_cache.cached_arrays("k", (3,), lambda: {"a": np.arange(4.0)})
    assert not list(cache.glob("*.npz"))


def test_the_least_recently_used_entries_go_first(tmp_path):
    for k, name in enumerate(("old", "mid", "new")):
        path = tmp_path / f"{name}.npz"
        path.write_bytes(b"x" * 100)
        os.utime(path, (1000.0 + k, 1000.0 + k))
    writing = tmp_path / ".new.123.abcd1234.tmp.npz"   # another process's, being written
    writing.write_bytes(b"x" * 1000)
    os.utime(writing, (900.0, 900.0))
    truth_cache._trim(tmp_path, limit=250)
    assert sorted(p.stem for p in tmp_path.glob("[!.]*.npz")) == ["mid", "new"]
    assert writing.is_file()


def test_the_code_hash_covers_every_module_a_simulation_runs():
    """Every package module ``scenarios.simulate`` imports (at any depth, the sensors'
    modules too, function-level imports included) is in ``TRUTH_SOURCES``, so that editing
    it changes the truth cache's key (and, as ``SIMULATION_SOURCES`` holds them all, the
    bank's); only the cache itself, the file writer and the names' registry are not."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    from test_import_graph import ROOT, import_graph, modules
    graph, files = import_graph(), modules()
    seen, stack = set(), ["aligngym.scenarios.simulate", "aligngym.sensors.dvl"]
    while stack:
        name = stack.pop()
        if name not in seen:
            seen.add(name)
            stack.extend(graph[name])
    assert set(truth_cache.TRUTH_SOURCES) <= set(truth_cache.SIMULATION_SOURCES)
    outside = sorted(str(files[m].relative_to(ROOT)) for m in seen
                     if not truth_cache.in_truth_sources(files[m]))
    assert outside == ["scenarios/atomic.py", "scenarios/registry.py",
                       "scenarios/truth_cache.py"]


def test_a_filters_edit_keeps_the_truth_entries(monkeypatch):
    """The entries are keyed on the simulation code alone (``TRUTH_SOURCES``): an edit of a
    filter, an experiment or the campaign code changes the bank's and the manifest's hash
    (``SIMULATION_SOURCES``), not the entries' names."""
    monkeypatch.setattr(truth_cache, "_sources_sha256", lambda parts: "|".join(parts))
    monkeypatch.setattr(truth_cache, "_CODE_SHA256", None)
    monkeypatch.setattr(truth_cache, "_TRUTH_SHA256", None)
    truth_cache.remember_code()
    for part in ("estimators", "scenarios/experiments", "scenarios/campaign"):
        assert part in truth_cache._CODE_SHA256.split("|")
        assert part not in truth_cache._TRUTH_SHA256.split("|")
    assert truth_cache._TRUTH_SHA256.split("|") == list(truth_cache.TRUTH_SOURCES)


def test_the_entries_names_follow_the_simulation_code_alone(monkeypatch):
    """``entry_name`` through ``truth_versions``: another hash of ``TRUTH_SOURCES`` names
    other entries, another hash of the preparation code alone the same ones."""
    def clear():
        truth_cache.truth_versions.cache_clear()
        truth_cache.simulation_versions.cache_clear()
    truth_cache.remember_code()
    clear()
    try:
        name = truth_cache.entry_name("k", (1.0, "x"))
        monkeypatch.setattr(truth_cache, "_CODE_SHA256", "another filter's code")
        clear()
        assert truth_cache.entry_name("k", (1.0, "x")) == name
        monkeypatch.setattr(truth_cache, "_TRUTH_SHA256", "another simulation's code")
        clear()
        assert truth_cache.entry_name("k", (1.0, "x")) != name
    finally:
        clear()                     # no name of the patched hashes outlives the test
