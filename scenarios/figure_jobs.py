"""The campaign figure jobs: which figures a campaign gets (``figure_jobs``, one callable
per figure drawn by ``scenarios.figures``) and drawing them, alongside each other, in
forked worker processes while the campaign goes on (``FigureDrawing``; ``write_figures``
draws and waits)."""
from __future__ import annotations

from typing import Any, Callable
from pathlib import Path

import numpy as np

from aligngym.scenarios.figure_statistics import (error_bands, heading_convergence_cdfs,
                                                  identical_runs, nees_curves)
from aligngym.scenarios.figures import (load_drawing, plot_error_bands, plot_final_errors,
                                        plot_heading_convergence, plot_nees)


def write_figures(result, out: Path, processes: int | None = None) -> list[Path]:
    """The four campaign figures per starting error (``scenarios.figures``) in out; the NEES
    figure only for an experiment with a NEES, drawn alongside each other in up to
    ``processes`` worker processes (``FigureDrawing``; None: the cores, 1: here).
    Returns the paths written."""
    return FigureDrawing.start(figure_jobs(result, out), processes).finish()


class FigureDrawing:
    """Figures being drawn: each job (a callable that draws one figure and returns its
    path) in a forked worker process, up to ``processes`` of them (None: the cores),
    while this process goes on (``start``); ``finish`` waits and returns the paths in
    the jobs' order, ``cancel`` stops the workers. One job, one process, a platform other
    than Linux, a process that has started Ray, or workers that cannot be started: the
    jobs run in ``finish``, here. A figure's PNG is written atomically by whoever draws
    it."""

    def __init__(self, jobs: list[Callable[[], Path]], pool: Any = None,
                 futures: list | None = None) -> None:
        self.jobs, self.pool, self.futures = jobs, pool, futures

    @classmethod
    def start(cls, jobs: list[Callable[[], Path]], processes: int | None = None
              ) -> "FigureDrawing":
        import multiprocessing
        import os
        from concurrent.futures import ProcessPoolExecutor

        from aligngym.scenarios.campaign.executors import can_fork_workers, usable_cores
        wanted = usable_cores() if processes is None else processes
        if wanted < 1:
            raise ValueError(f"figure processes = {processes} must be >= 1")
        n = min(len(jobs), usable_cores(), wanted)
        if n < 2 or not can_fork_workers():
            return cls(jobs)
        load_drawing()                  # once, inherited by the workers
        try:
            pool = ProcessPoolExecutor(max_workers=n, initializer=_figure_worker,
                                       initargs=(os.getpid(), jobs),
                                       mp_context=multiprocessing.get_context("fork"))
        except OSError:                 # no process to be had: draw them here
            return cls(jobs)
        drawing = cls(jobs, pool, [])
        try:
            order = sorted(range(len(jobs)), key=lambda i: -_drawing_cost(jobs[i]))
            futures = {i: pool.submit(_draw, i) for i in order}   # the longest first
            drawing.futures = [futures[i] for i in range(len(jobs))]
        except OSError:                 # a worker could not be started: draw them here
            drawing.cancel()
            return cls(jobs)
        except BaseException:
            drawing.cancel()
            raise
        return drawing

    def cancel(self) -> None:
        """Stop the workers at once (an error or Ctrl-C while the figures are drawn)."""
        from aligngym.scenarios.campaign.executors import stop_pool
        if self.pool is not None:
            stop_pool(self.pool)
            self.pool = None

    def finish(self) -> list[Path]:
        """The paths written, in the jobs' order (a worker's error raised here)."""
        if self.pool is None:
            return [job() for job in self.jobs]
        from aligngym.scenarios.campaign.executors import stopped_on_error
        with stopped_on_error(self.pool):
            return [future.result() for future in self.futures]


def _drawing_cost(job: Callable[[], Path]) -> float:
    """A figure job's relative drawing time (``DRAWING_COST`` by its plot function; 1 for
    another callable), so that the workers take the longest first and end together."""
    return DRAWING_COST.get(getattr(job, "func", None), 1.0)


_JOBS: list = []
"""A figure worker's jobs (``FigureDrawing``), set when it starts."""


def _figure_worker(parent: int, jobs: list) -> None:
    """A figure worker's start (``executors.start_worker``) and its jobs (inherited from
    the fork, not copied)."""
    global _JOBS
    from aligngym.scenarios.campaign.executors import start_worker
    start_worker(parent)
    _JOBS = jobs


def _draw(index: int) -> Path:
    """Draw job ``index`` of this worker's ``FigureDrawing``."""
    return _JOBS[index]()


def figure_jobs(result, out: Path) -> list[Callable[[], Path]]:
    """The campaign figures to draw (``write_figures``), each a callable drawing one and
    returning its path."""
    from functools import partial
    exp = result.experiment
    bands, cdfs = error_bands(result), heading_convergence_cdfs(result)
    curves = nees_curves(result)
    dof = exp.nees_dof()
    twins = identical_runs(result)
    t = result.runs[0].result.t - result.runs[0].result.t[0] if result.runs else np.zeros(1)
    in_window = exp.accuracy_window(t, result.episodes[0].fine_start if result.episodes
                                    else 0.0)
    window = float(t[-1] - t[in_window][0]) if in_window.any() else exp.rms_window
    jobs = []
    for start in exp.starts:
        pick = lambda items: [x for x in items if x.start == start]  # noqa: E731
        if not pick(bands):
            continue
        jobs.append(partial(
            plot_error_bands, pick(bands), window,
            f"Attitude error from the {start} start over {len(result.seeds)} episodes",
            out / f"fine_error_{start}.png", twins))
        jobs.append(partial(plot_final_errors, result, start,
                            out / f"final_error_{start}.png", twins))
        jobs.append(partial(plot_heading_convergence, pick(cdfs),
                            exp.heading_threshold_arcmin, start,
                            out / f"heading_convergence_{start}.png", twins))
        nees = pick(curves)
        if dof and any(np.isfinite(c.mean).any() for c in nees):
            jobs.append(partial(plot_nees, nees, dof, start, out / f"nees_{start}.png",
                                twins=twins))
    return jobs


DRAWING_COST = {plot_error_bands: 4.0, plot_nees: 3.0, plot_final_errors: 2.0,
                plot_heading_convergence: 1.0}
"""Relative drawing time of the campaign figures (paper 003, ten episodes: 0.45-0.50,
0.26-0.38, 0.23 and 0.11 s)."""
