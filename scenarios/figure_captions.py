"""The captions of the campaign figures (``scenarios.figures``) in the HTML report
(``scenarios.html_report``), by the figure's file name."""
from __future__ import annotations

from pathlib import Path


FIGURE_CAPTIONS = {
    "fine_error": "Attitude error (E, N, U; arcmin) over the fine alignment: per filter the "
                  "median over the episodes not diverged (line), their 5-95 % band (shade) "
                  "and the filter's mean +-3 sigma (dotted); diverged episodes as faint lines "
                  "ending in x. Right: the experiment's RMS window.",
    "final_error": "Final attitude error per filter and axis (arcmin): box = quartiles, "
                   "thick line = median, whiskers = 5-95 % of the episodes not diverged, "
                   "open circle = an episode beyond the whiskers; x = a diverged episode "
                   "(a triangle when off the panel).",
    "heading_convergence": "Percentage of all episodes whose heading error stays within the "
                           "experiment's threshold from time t to the end (empirical CDF of "
                           "the convergence time); diverged and never converged episodes "
                           "keep a curve below 100 %.",
    "nees": "NEES (dimensionless) over time against its 95 % chi-square band (grey) for the "
            "mean (top; chi-square(n x states) / n for n episodes) and the median (bottom) "
            "of the episodes not diverged; dashed: the state count. A strip in a filter's "
            "colour at the top (bottom) of the mean panel marks the epochs where its mean "
            "NEES is above (below) the band; its legend entry and the table \"Mean NEES "
            "against its band\" give the fraction of such epochs.",
}


def figure_caption(name: str) -> str:
    """Caption of a campaign figure from its file name (an experiment's own figure: a
    generic one)."""
    stem = Path(name).stem
    for prefix, caption in FIGURE_CAPTIONS.items():
        if stem.startswith(prefix + "_"):
            return caption
    return "The experiment's own figure (README, the paper's section)."
