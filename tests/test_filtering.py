"""A campaign's filter phase (``scenarios.campaign.filtering``): its filters run alongside
each other in worker processes, a batch split only into chunks that keep enough work,
never more processes than cores, and every run the one a single batch gives, to the bit."""
import numpy as np
import pytest

from aligngym.scenarios.campaign import episode_seeds, prepare_all
from aligngym.estimators.catalogue import filter_entry
from aligngym.scenarios.campaign import filtering
from aligngym.scenarios.campaign.runs import run_filter_starts
from aligngym.scenarios.experiments import experiment


@pytest.fixture(scope="module")
def short002():
    exp = experiment("paper002", fine_duration=30.0)
    episodes = prepare_all(exp, episode_seeds(5, 3), None, False, 1, progress=False)
    errors = exp.start_errors(episodes)
    return exp, episodes, {s: errors[s] for s in exp.starts}


def test_processes_and_chunks_give_the_runs_of_one_batch_to_the_bit(short002, monkeypatch):
    """Forced into worker processes with sghkf-3 split over two of them (the workers' own
    pids seen), every array of their runs sent back as a shared file
    (``transport.shared_arrays``): each run's every field, factors included, equals that
    of the filters run one after another on the whole batch."""
    import os

    from aligngym.scenarios.campaign import transport

    exp, episodes, starts = short002
    monkeypatch.setattr(transport, "SHARED_ARRAY_BYTES", 1)
    received = transport.RECEIVED
    monkeypatch.setattr(filtering, "PARALLEL_MIN_WORK", 0.0)
    monkeypatch.setattr(filtering, "MIN_CHUNK_POINTS", 100)
    monkeypatch.setattr(filtering, "usable_cores", lambda: 2)
    pids, analysed = [], []
    real = filtering._run_in_processes

    def spy(tasks, processes, results, *rest):
        real(tasks, processes, results, *rest)
        for r in results.values():       # a whole batch comes back analysed (FilterRuns)
            pids.append((r[0].result if isinstance(r, list) else r).series["pid"][0])
            analysed.append(isinstance(r, list))
    monkeypatch.setattr(filtering, "_run_in_processes", spy)
    run_members = filtering.run_members

    def tagged(name, index, *args):          # runs in the worker (forked: it inherits
        result = run_members(name, index, *args)    # this patch): its pid in the series
        result.series["pid"] = np.full(index.size, os.getpid())
        return result
    monkeypatch.setattr(filtering, "run_members", tagged)
    names = ["ekf", "sghkf-3"]
    tasks = filtering.plan_filter_tasks(names, exp, len(episodes), 31, 2)
    assert [(t.name, t.index.tolist()) for t in tasks] == [
        ("ekf", [0, 1, 2]), ("sghkf-3", [0, 1]), ("sghkf-3", [2])]
    runs = filtering.run_filters(names, starts, episodes, exp, workers=2, epochs=31)
    assert len(pids) == 3 and os.getpid() not in pids          # run in forked workers
    assert sorted(analysed) == [False, False, True]     # ekf's whole batch analysed there
    serial = [run for name in names for run in run_filter_starts(name, starts, episodes, exp)]
    assert [(r.filter, r.start) for r in runs] == [(r.filter, r.start) for r in serial]
    for a, b in zip(runs, serial):
        for field in ("C_s_n", "P", "x", "sigma_n", "nis", "nis_dof", "factors",
                      "diverged", "diverged_time", "repairs"):
            np.testing.assert_array_equal(getattr(a.result, field), getattr(b.result, field))
        assert a.result.diverged_reason == b.result.diverged_reason
        for key, values in b.result.series.items():
            np.testing.assert_array_equal(a.result.series[key], values)
        np.testing.assert_array_equal(a.status, b.status)
        for field in ("error_n", "euler_error", "nees", "heading_convergence"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
        assert a.reason == b.reason
    assert transport.RECEIVED >= received + 3 * 6          # every run's arrays as files
    # the split filter's time is the sum of its chunks', and says so (the cost column)
    assert [(r.filter, r.result.chunks) for r in runs] == [
        (r.filter, 2 if r.filter == "sghkf-3" else 1) for r in serial]
    from aligngym.scenarios.campaign.results import CampaignResult
    from aligngym.scenarios.experiments.paper002 import format_tables
    seeds = list(range(len(episodes)))
    notes = [format_tables(CampaignResult(exp, seeds, episodes, starts, runs=r)).splitlines()[-1]
             for r in (runs, serial)]
    assert "each chunk paying the fixed cost an epoch: sghkf-3 in 2)" in notes[0]
    assert "chunk" not in notes[1]


def test_the_plan_never_splits_below_the_chunk_size_nor_beyond_the_processes(short002):
    """sghkf-4 (1981 points) splits from 21 members on, each chunk keeping at least
    MIN_CHUNK_POINTS (to one member), into at most one chunk per process; the UKF (21
    points) stays one batch below 1905 members; no chunk is empty."""
    exp = short002[0]
    points = {"sghkf-4": 1981, "ukf": 21}
    for members in (1, 10, 11, 32, 64, 1000):
        for processes in (1, 2, 16):
            for name in points:
                tasks = filtering.plan_filter_tasks([name], exp, members, 100, processes)
                sizes = [t.index.size for t in tasks]
                assert sum(sizes) == members and min(sizes) >= 1
                assert len(tasks) <= processes
                assert len(tasks) == 1 or (min(sizes) + 1) * points[name] >= \
                    filtering.MIN_CHUNK_POINTS
    assert len(filtering.plan_filter_tasks(["sghkf-4"], exp, 21, 100, 2)) == 2
    assert len(filtering.plan_filter_tasks(["sghkf-4"], exp, 20, 100, 2)) == 1
    assert len(filtering.plan_filter_tasks(["ukf"], exp, 1000, 100, 16)) == 1


def test_more_workers_than_cores_start_no_more_processes(short002, monkeypatch):
    """--workers 16 on a 2-core machine plans for 2 processes: the same chunks as
    --workers 2."""
    exp, episodes, starts = short002
    seen = []
    plan = filtering.plan_filter_tasks
    monkeypatch.setattr(filtering, "usable_cores", lambda: 2)
    monkeypatch.setattr(filtering, "plan_filter_tasks",
                        lambda *args: seen.append(args[-1]) or plan(*args))
    (run,) = filtering.run_filters(["ekf"], starts, episodes, exp, workers=16, epochs=31)
    assert seen == [2] and run.filter == "ekf"
    assert filtering.run_filters(["ekf"], starts, [], exp, workers=2, epochs=31) == []


def test_work_queued_for_the_wait_runs_once_here_while_the_workers_run(short002, monkeypatch):
    """``executors.while_waiting``: a queued task runs once, in this process, after the
    worker processes have started (the episode preparation's and the filter phase's);
    one that raises does not stop the campaign, whose runs stay those of a serial run."""
    import multiprocessing
    import os

    from aligngym.scenarios.campaign import executors

    exp, episodes, starts = short002
    monkeypatch.setattr(executors, "usable_cores", lambda: 2)
    monkeypatch.setattr(filtering, "PARALLEL_MIN_WORK", 0.0)
    monkeypatch.setattr(filtering, "usable_cores", lambda: 2)
    seen = []

    def task():
        seen.append((os.getpid(), len(multiprocessing.active_children())))

    def failing():
        raise ImportError("no such module")

    executors.while_waiting(task)
    executors.while_waiting(failing)
    again = prepare_all(exp, episode_seeds(5, 3), None, False, 2, progress=False)
    assert seen == [(os.getpid(), 2)] and not executors._WHILE_WAITING
    for a, b in zip(again, episodes):
        np.testing.assert_array_equal(a.C_b_n_true, b.C_b_n_true)
    executors.while_waiting(task)
    runs = filtering.run_filters(["ekf", "ukf"], starts, episodes, exp, workers=2, epochs=31)
    assert seen[1:] == [(os.getpid(), 2)]
    serial = [run for name in ("ekf", "ukf")
              for run in run_filter_starts(name, starts, episodes, exp)]
    for a, b in zip(runs, serial):
        np.testing.assert_array_equal(a.result.x, b.result.x)


def test_a_split_that_shortens_the_phase_is_made_and_one_that_does_not_is_not():
    """Paper 001's three filters of one task each on two processes: one is split in two
    (four tasks, two a process: by their measured costs, the estimated phase 3.3 s
    against 3.9 s unsplit); on four processes none is (each has a process of its own
    already). Paper
    000's measured cost a member (``member_points``, 650 points of paper 002's model)
    splits its 64 members (two starts) in two for every filter, where its rules' 7-36
    points would not."""
    e001 = experiment("paper001")
    plan = filtering.plan_filter_tasks(["lckf", "rakf", "swakf"], e001, 32, 100, 2)
    assert [(t.name, t.index.size) for t in plan] == [("lckf", 16), ("lckf", 16),
                                                      ("rakf", 32), ("swakf", 32)]
    assert len(filtering.plan_filter_tasks(["lckf", "rakf", "swakf"], e001, 32, 100, 4)) == 3
    e000 = experiment("paper000")
    plan = filtering.plan_filter_tasks(list(e000.default_filters), e000, 64, 100, 2)
    assert [t.index.size for t in plan] == [32] * 8


def test_measured_filter_costs_weigh_the_tasks_and_order_them():
    """``Experiment.filter_costs``: paper 004's four filters, 10.3, 6.3, 9.5 and 9.4 s on
    32 episodes by their measured costs, are weighed by them (no longer as equal: the plan
    had handed stekf out second, leaving two of the three dear ones to one process); a
    filter the experiment has not measured keeps its rule's points and the fixed cost of
    ``EPOCH_OVERHEAD_POINTS``."""
    e004 = experiment("paper004")
    plan = filtering.plan_filter_tasks(list(e004.default_filters), e004, 32, 1941, 2)
    for task in plan:
        us, ms = e004.filter_costs[task.name]
        assert task.work == pytest.approx(1941 * (ms * 1e3 + 32 * us) / filtering.POINT_US)
    order = [t.name for t in sorted(plan, key=lambda t: -t.work)]
    assert order == ["stukf", "ukf-3n", "ekf", "stekf"]
    e002 = experiment("paper002")
    (ukf,) = filtering.plan_filter_tasks(["ukf"], e002, 3, 100, 2)
    points = filter_entry("ukf").rule().point_count(e002.state_count)
    assert not e002.filter_costs and ukf.work == 100 * (filtering.EPOCH_OVERHEAD_POINTS
                                                        + 3 * points)


def test_the_makespan_hands_the_largest_task_out_first():
    assert filtering.makespan([3.0, 3.0, 2.0, 2.0, 2.0], 2) == 7.0
    assert filtering.makespan([5.0, 1.0, 1.0], 2) == 5.0
    assert filtering.makespan([1.0, 1.0, 1.0], 4) == 1.0


def test_a_campaign_on_workers_loads_the_kernels_once_before_it_forks(short002, monkeypatch):
    """``estimators.kernels.load_compiled_kernels`` runs in the campaign's process before
    its preparation workers are forked (they and the filter workers inherit the kernels:
    every preparation screens its IMU with one), and not at all on one worker; in a fresh
    process it leaves every compiled kernel loaded, in the one signature the work calls (a
    step of paper 004's map on read-only points compiles no second one)."""
    import subprocess
    import sys

    from aligngym.estimators import kernels
    from aligngym.scenarios.campaign import executors, run_campaign

    exp = short002[0]
    order = []
    monkeypatch.setattr(kernels, "load_compiled_kernels", lambda: order.append("load"))
    monkeypatch.setattr(executors, "usable_cores", lambda: 2)
    forked = executors._prepare_in_processes
    monkeypatch.setattr(executors, "_prepare_in_processes",
                        lambda *args: order.append("fork") or forked(*args))
    run_campaign(exp, episodes=3, seed=5, filters=["ekf"], workers=2, progress=False)
    assert order == ["load", "fork"]
    order.clear()
    run_campaign(exp, episodes=3, seed=5, filters=["ekf"], workers=1, progress=False)
    assert order == []
    code = ("from aligngym.estimators.kernels import load_compiled_kernels as load; load()\n"
            "from aligngym.estimators import euler_kernel as e, screen_kernel as s, "
            "strapdown_kernel as k, rotation_vector_kernel as r\n"
            "from aligngym.models import attitude_kernel as a\n"
            "import numpy as np\nfrom aligngym.estimators.rotation_vector import "
            "runge_kutta_step\nx = np.zeros((2, 3, 15)); x.flags.writeable = False\n"
            "runge_kutta_step(x, 0.5, False, (np.zeros((3, 2, 3, 3)),) + (np.zeros((3, 2, 3)),)"
            " * 6 + (np.zeros((3, 2)),) * 2)\n"
            "print([len(f.signatures) for f in (e.midpoint_points, s.spike_candidates, "
            "k.compensate_increments, k.mechanize, a.quat_scan, r.runge_kutta_points)])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[1, 1, 1, 1, 1, 1]"


def test_a_campaign_uses_no_more_threads_than_its_workers(monkeypatch):
    """``executors.thread_budget``: one worker holds BLAS and the MuJoCo rollout to one
    thread (before, a one-worker campaign prepared on every core); a pool held to fewer
    threads keeps them; both come back after."""
    from threadpoolctl import threadpool_info

    from aligngym.models import world
    from aligngym.scenarios.campaign import executors

    monkeypatch.setattr(executors, "usable_cores", lambda: 4)
    monkeypatch.setattr(world, "ROLLOUT_THREADS", 4)
    before = [pool["num_threads"] for pool in threadpool_info()]
    with executors.thread_budget(1):
        assert world.ROLLOUT_THREADS == 1
        assert all(pool["num_threads"] == 1 for pool in threadpool_info())
    with executors.thread_budget(2):
        assert world.ROLLOUT_THREADS == 2
        assert [pool["num_threads"] for pool in threadpool_info()] == \
            [min(n, 2) for n in before]
        with executors.thread_budget(1), executors.thread_budget(4):   # lowered, not raised
            assert all(pool["num_threads"] == 1 for pool in threadpool_info())
    assert world.ROLLOUT_THREADS == 4
    assert [pool["num_threads"] for pool in threadpool_info()] == before
