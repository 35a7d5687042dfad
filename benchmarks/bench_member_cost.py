"""Benchmark: each paper's default filters' cost per member and epoch of a batch, and their
fixed cost per epoch, from two batch sizes (half and all of the 32-episode campaign's
members, episodes x starts), one BLAS thread, on the campaign's own episodes. Printed per
filter: its rule's points, the two times, the cost per member-epoch (us), per point (us)
and the fixed cost per epoch (ms); per paper the least cost per member-epoch in points of
paper 002's model (``filtering.POINT_US``, ``EPOCH_OVERHEAD_POINTS``' unit), which its
experiment declares as ``member_points``, and the ``filter_costs`` line it may declare
(the filter phase's plan weighs a named filter's tasks by them).

Run: python benchmarks/bench_member_cost.py [paper000 paper001 ...]  (about 3 min for all
five on 2 cores; time it alone)
"""
from __future__ import annotations

import sys
import time

import numpy as np
from threadpoolctl import threadpool_limits

from aligngym.estimators.catalogue import filter_entry
from aligngym.scenarios.campaign import episode_seeds, prepare_all
from aligngym.scenarios.campaign.engine import campaign_epochs
from aligngym.scenarios.campaign.filtering import POINT_US
from aligngym.scenarios.campaign.runs import member_batch, run_members
from aligngym.scenarios.experiments import experiment



def main() -> None:
    threadpool_limits(1)
    papers = sys.argv[1:] or ["paper000", "paper001", "paper002", "paper003", "paper004"]
    for paper in papers:
        exp = experiment(paper)
        episodes = prepare_all(exp, episode_seeds(0, 32), None, False, 2, progress=False)
        members, starts = member_batch(exp.start_errors(episodes), episodes)
        M, K = len(members), campaign_epochs(exp)
        costs, declared = [], {}
        for name in exp.default_filters:
            points = filter_entry(name).rule().point_count(exp.state_count)
            run_members(name, np.arange(2), members, starts, exp)        # warm-up
            seconds = {}
            for m in (M // 2, M):
                start = time.perf_counter()
                run_members(name, np.arange(m), members, starts, exp)
                seconds[m] = time.perf_counter() - start
            small, large = M // 2, M
            member = (seconds[large] - seconds[small]) / (large - small) / K
            fixed = seconds[small] / K - member * small
            costs.append(member)
            declared[name] = (round(member * 1e6, 1), round(fixed * 1e3, 2))
            print(f"{paper} {name:8s} {points:5d} points, {K} epochs: {seconds[small]:.2f} s "
                  f"({small}), {seconds[large]:.2f} s ({large}); {member * 1e6:7.1f} us a "
                  f"member-epoch, {member * 1e6 / points:7.2f} us a point, "
                  f"{fixed * 1e3:5.2f} ms fixed an epoch", flush=True)
        print(f"{paper}: least cost a member-epoch {min(costs) * 1e6:.1f} us = "
              f"{min(costs) * 1e6 / POINT_US:.0f} points (declared: "
              f"{exp.member_points:g})", flush=True)
        print(f"{paper}: filter_costs = {declared}", flush=True)


if __name__ == "__main__":
    main()
