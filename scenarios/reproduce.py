"""Each paper's claims against what its campaign measures (``aligngym reproduce``).

A claim is one sentence of a paper's text (its comparisons; the result tables were
removed from our copies on purpose), declared by the paper's experiment beside its
pipeline (``Experiment.claims``): the numbers that test it (paths into the campaign's
JSON summary, as ``regress`` flattens it, or functions of the campaign), the test, and,
for a claim that does not hold here, the measured reason (with where the evidence is:
the docs page, the tests, an independent implementation). A claim names the campaign it
needs (setup, settings, filters); claims that need the same campaign share one run
(``campaign.plan.claims_plan``: every paper's campaigns planned and checked before the
first runs).
"""
from __future__ import annotations

import math
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from aligngym.scenarios.atomic import write_text
from aligngym.scenarios.campaign.claims import Claim
from aligngym.scenarios.campaign.plan import ClaimCampaign


@dataclass
class Verdict:
    paper: str
    claim: Claim
    measured: dict[str, float]
    reproduced: bool


def measure(claim: Claim, result, metrics: dict[str, float]) -> dict[str, float]:
    """The claim's numbers from a campaign (its flattened summary, or functions of it)."""
    out = {}
    for label, number in claim.numbers.items():
        if callable(number):
            out[label] = float(number(result))
        else:
            if number not in metrics:
                raise KeyError(f"claim {claim.text[:40]!r}: no {number!r} in the summary")
            out[label] = metrics[number]
    return out


def run_claims(plan: list[ClaimCampaign], out_dir: Path | None = None,
               workers: int | None = None, log: Callable[[str], None] = print
               ) -> list[Verdict]:
    """Run a claims plan's campaigns (``campaign.plan.claims_plan``) and judge each claim;
    with out_dir, each campaign's outputs (tables, results, figures) go to
    out_dir/<paper>/<setup>-<k>/."""
    from aligngym.scenarios.regress import flatten
    from aligngym.scenarios.report import write_outputs

    verdicts = []
    of_paper = Counter(c.paper for c in plan)
    number: Counter[str] = Counter()
    for campaign in plan:
        paper, spec = campaign.paper, campaign.spec
        number[paper] += 1
        first = campaign.claims[0]
        start = time.perf_counter()
        if out_dir is not None:     # matplotlib imported while the campaign's workers run
            from aligngym.scenarios.campaign.executors import while_waiting
            from aligngym.scenarios.figures import load_drawing
            while_waiting(load_drawing)
        result = spec.run(workers=workers, progress=False)
        metrics = flatten(result.summary())
        log(f"{paper}: campaign {number[paper]} of {of_paper[paper]} ({first.setup} setup"
            + "".join(f", {key} = {value}" for key, value in first.settings.items())
            + f"; {spec.episodes} episodes, seed {spec.seed}) in "
            f"{time.perf_counter() - start:.0f} s")
        if out_dir is not None:
            write_outputs(result, Path(out_dir) / paper / spec.label, None,
                          command=["aligngym", "reproduce", paper])
        measuring = time.perf_counter()
        for claim in campaign.claims:
            numbers = measure(claim, result, metrics)
            ok = all(math.isfinite(v) for v in numbers.values()) and bool(claim.holds(numbers))
            verdicts.append(Verdict(paper, claim, numbers, ok))
        seconds = time.perf_counter() - measuring
        if seconds >= MEASURING_SAID_S:   # e.g. a computation claim timing each filter alone
            log(f"{paper}: campaign {number[paper]}'s claims measured in {seconds:.0f} s "
                "(after it)")
    return verdicts


MEASURING_SAID_S = 1.0
"""Claims taking at least this long (s) to measure are logged after their campaign's time
(a claim that times its filters runs them again)."""


def format_numbers(numbers: dict[str, float]) -> str:
    return "; ".join(f"{label} {value:.4g}" for label, value in numbers.items())


def format_verdicts(verdicts: list[Verdict]) -> str:
    """The table printed: per claim, the paper's words, the numbers measured, the verdict."""
    lines = []
    for v in verdicts:
        mark = "REPRODUCED    " if v.reproduced else "NOT REPRODUCED"
        lines += [f"{v.paper} [{mark}] {v.claim.text} ({v.claim.where}; "
                  f"{v.claim.setup} setup)",
                  f"    measured: {format_numbers(v.measured)}"]
        if not v.reproduced:
            lines.append(f"    why: {v.claim.reason}")
    held = sum(v.reproduced for v in verdicts)
    lines.append(f"{held} of {len(verdicts)} claims reproduced")
    return "\n".join(lines)


def verdict_cell(v: Verdict) -> str:
    return "**reproduced**" if v.reproduced else "not reproduced: " + v.claim.reason


def paper_page(paper: str, verdicts: list[Verdict], episodes: int, seed: int | None,
               figures: list[str]) -> str:
    """One paper's page: its claims (claim, where, setup, measured, verdict) and the
    campaigns' error figures below (paths relative to the page)."""
    lines = [f"# {paper}: the paper's claims, reproduced or explained", "",
             f"Written by `aligngym reproduce {paper}` ({episodes} episodes per campaign, "
             f"seed {'the paper' + chr(39) + 's own' if seed is None else seed}). Each claim "
             "is a sentence of the paper's text; the numbers are this run's; a claim that "
             "does not hold says why, measured.", "",
             "| claim | where | setup | measured | verdict |", "| --- | --- | --- | --- | --- |"]
    lines += [f"| {v.claim.text} | {v.claim.where} | {v.claim.setup} | "
              f"{format_numbers(v.measured)} | {verdict_cell(v)} |" for v in verdicts]
    for path in figures:
        lines += ["", f"![{path}]({path})"]
    return "\n".join(lines) + "\n"


def summary_page(verdicts: list[Verdict], episodes: dict[str, int], seconds: float) -> str:
    """All papers' claims, one line each, with links to the papers' pages."""
    lines = ["# The papers' claims, reproduced or explained", "",
             f"`aligngym reproduce`: {', '.join(f'{p} {n}' for p, n in episodes.items())} "
             f"episodes per campaign, {seconds / 60:.1f} min. Each paper's page has the "
             "numbers and the figures.", "", "| paper | claim | setup | verdict |",
             "| --- | --- | --- | --- |"]
    lines += [f"| [{v.paper}]({v.paper}/claims.md) | {v.claim.text} | {v.claim.setup} | "
              f"{'reproduced' if v.reproduced else 'not reproduced'} |" for v in verdicts]
    held = sum(v.reproduced for v in verdicts)
    lines += ["", f"{held} of {len(verdicts)} claims reproduced."]
    return "\n".join(lines) + "\n"


def reproduce(papers: list[str], episodes: int | None = None, seed: int | None = None,
              out_dir: Path | None = None, workers: int | None = None,
              log: Callable[[str], None] = print, plan: list[ClaimCampaign] | None = None
              ) -> tuple[list[Verdict], str]:
    """Every named paper's claims; with out_dir also each campaign's outputs, a page per
    paper (DIR/PAPER/claims.md, with the figures) and DIR/claims.md (every claim, one line
    each). plan: their ``claims_plan``, if made already (it checks every campaign before
    the first runs). Returns the verdicts and the printed table."""
    from aligngym.scenarios.campaign.plan import claims_plan

    start = time.perf_counter()
    papers = list(dict.fromkeys(papers))               # a paper named twice runs once
    plan = claims_plan(papers, episodes, seed) if plan is None else plan
    counts = {c.paper: c.spec.episodes for c in plan}
    verdicts = run_claims(plan, out_dir, workers, log)
    text = format_verdicts(verdicts)
    if out_dir is not None:
        out = Path(out_dir)
        for paper in papers:
            figures = sorted(str(f.relative_to(out / paper))
                             for f in (out / paper).glob("*/fine_error_*.png"))
            write_text(out / paper / "claims.md",
                       paper_page(paper, [v for v in verdicts if v.paper == paper],
                                  counts[paper], seed, figures))
        write_text(out / "claims.md", summary_page(verdicts, counts,
                                                   time.perf_counter() - start))
    return verdicts, text
