"""Campaign figures, drawn: the spread of every filter over all episodes of a campaign.

Per starting error, four PNG files (``scenarios.figure_jobs``: which, and drawing them in
worker processes; their captions: ``scenarios.figure_captions``):

- ``fine_error_<start>.png``: attitude error E, N, U (arcmin, linear) over the fine
  alignment, per filter the median over the episodes that did not diverge, their 5-95 %
  band and the filter's mean +-3 sigma; the diverged episodes as faint individual lines,
  counted in the legend; the right column zooms on the experiment's RMS window;
- ``final_error_<start>.png``: box plots of the final error per filter and axis, a
  legend for the box, whiskers, fliers and diverged episodes;
- ``heading_convergence_<start>.png``: the percentage of episodes whose heading has
  converged, against time (empirical CDF of ``heading_convergence_s``);
- ``nees_<start>.png``: mean and median NEES over time with their 95 % chi-square bands
  for the experiment's NEES dimension (``Experiment.nees_dof``); a strip in a filter's
  colour at the top (bottom) of the mean panel marks the epochs where its mean NEES is
  above (below) its band, and its legend entry gives the fraction of such epochs.

Every axis carries its unit, every marker is in a legend, and a filter whose results
equal another's from the same start (``identical_runs``) is marked "(= other)".

The statistics drawn are functions of the campaign result, checked apart from the
drawing (``scenarios.figure_statistics``).
"""
from __future__ import annotations

from typing import Any
from pathlib import Path

import numpy as np

from aligngym.models.units import arcmin
from aligngym.scenarios.atomic import save_figure
from aligngym.scenarios.figure_statistics import (ConvergenceCdf, ErrorBand, NeesCurve,
                                                  NeesExcursion, as_percent, mean_nees_band,
                                                  median_nees_band, nees_excursions)

AXIS_NAMES = ("East", "North", "Up")

PALETTE = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000",
           "#999933")
"""Okabe & Ito's colour-blind safe colours (their yellow replaced by olive, which reads on
white)."""
DASHES = ("solid", (0, (6, 2)), (0, (6, 2, 1.5, 2)), (0, (12, 3)), (0, (3, 2)),
          (0, (6, 2, 1.5, 2, 1.5, 2)), (0, (9, 3, 3, 3)), (0, (2, 1)))
"""Dash patterns of the filters' median lines (none is the fine dotted line of the
+-3 sigma bounds)."""
SIGMA_DASH = (0, (1, 1.5))
MAX_PLOTTED_EPOCHS = 2000
"""Longer series are drawn at every n-th epoch (the statistics use every epoch)."""
DPI = 100
PNG_OPTIONS = {"pil_kwargs": {"compress_level": 1}}
"""PNG compression (zlib) at level 1 of 9: at the default 6 it took a tenth of the
drawing time (0.39 of 4.1 s for paper 003's eight figures), at 1 a small part of that,
for files 11 % larger (1.31 -> 1.45 MB)."""


def line_style(i: int) -> dict:
    """Colour and dash pattern of the i-th filter of a figure: 64 distinct pairs."""
    return {"color": PALETTE[i % len(PALETTE)],
            "linestyle": DASHES[(i + i // len(PALETTE)) % len(DASHES)]}


def _twin(twins: dict | None, item) -> str:
    other = (twins or {}).get((item.filter, item.start))
    return f" (= {other})" if other else ""


# --------------------------------------------------------------------------------------
# Drawing
# --------------------------------------------------------------------------------------

FIGURE_RC = {"axes.titley": 1.0}
"""matplotlib settings the figures are made with: titles at a fixed height above their
axes (where the automatic placement puts them, as no axis has ticks on top), which
spares the title placement's layout pass at every draw (15 % of the drawing time)."""


def pyplot():
    """matplotlib.pyplot on the Agg backend (files only, headless)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def load_drawing() -> None:
    """Import what drawing the figures takes (matplotlib on Agg: 0.5 s), here, once:
    before the figure workers are forked (each would import it again), or earlier while
    the campaign's workers run (``executors.while_waiting``)."""
    pyplot()
    import matplotlib.lines  # noqa: F401
    import matplotlib.patches  # noqa: F401


def subplots(*args: Any, **kwargs: Any):
    """``pyplot.subplots`` under ``FIGURE_RC`` (the caller's own settings untouched)."""
    plt = pyplot()
    with plt.rc_context(FIGURE_RC):
        return plt.subplots(*args, **kwargs)


def _stride(size: int) -> int:
    return max(1, -(-size // MAX_PLOTTED_EPOCHS))


def _limit(values: list[np.ndarray], floor: float = 1e-3) -> float:
    """Symmetric y limit: the largest finite |value|, padded by 8 %."""
    finite = [np.abs(v[np.isfinite(v)]) for v in values]
    top = max((float(v.max()) for v in finite if v.size), default=1.0)
    return 1.08 * max(top, floor)


def _finite_median(values: np.ndarray) -> np.ndarray:
    """The median (1,) of the finite values, or none (0,)."""
    finite = values[np.isfinite(values)]
    return np.median(finite, keepdims=True) if finite.size else finite


def _diverged_label(count: int, episodes: int) -> str:
    return f", {count} of {episodes} diverged" if count else ""


def plot_error_bands(bands: list[ErrorBand], window: float, title: str, path: Path,
                     twins: dict | None = None) -> Path:
    """fine_error_<start>.png: 3 rows (E, N, U) x 2 columns (the whole run; its last
    ``window`` s). Median line in each filter's colour and dash, 5-95 % shade, mean
    +-3 sigma dotted, diverged episodes faint with an x at their end."""
    plt = pyplot()
    fig, axes = subplots(3, 2, figsize=(13, 9.5), sharex="col",
                             gridspec_kw={"width_ratios": (1.5, 1)})
    t_end = max(float(b.t[-1]) for b in bands)
    tail_start = max(0.0, t_end - window) if window < t_end else 0.5 * t_end
    handles = []
    for i, band in enumerate(bands):
        style = line_style(i)
        step = _stride(band.t.size)
        t = band.t[::step]
        for axis in range(3):
            for ax in axes[axis]:
                ax.fill_between(t, band.low_arcmin[::step, axis], band.high_arcmin[::step, axis],
                                color=style["color"], alpha=0.14, lw=0)
                for sign in (1.0, -1.0):
                    ax.plot(t, sign * band.sigma3_arcmin[::step, axis], color=style["color"],
                            linestyle=SIGMA_DASH, lw=0.9)
                for error in band.diverged_error_arcmin:
                    ax.plot(t, error[::step, axis], color=style["color"], lw=0.6, alpha=0.5,
                            marker="x", markevery=[-1], markersize=5)
                line, = ax.plot(t, band.median_arcmin[::step, axis], lw=1.8, **style)
        handles.append((line, f"{band.filter}{_twin(twins, band)}: "
                        f"{band.episodes - band.diverged_count} episodes"
                        f"{_diverged_label(band.diverged_count, band.episodes)}"))
    for axis in range(3):
        full, tail = axes[axis]
        for ax, lo in ((full, 0.0), (tail, tail_start)):
            sel = [b.t >= lo - 1e-9 for b in bands]
            # The whole run: the band sets the scale (the start's 3 sigma would flatten
            # the level axes), with the 3 sigma's median; the tail: band and 3 sigma.
            sigma = ([_finite_median(b.sigma3_arcmin[:, axis]) for b in bands]
                     if ax is full else
                     [b.sigma3_arcmin[s, axis] for b, s in zip(bands, sel)])
            limit = _limit([b.low_arcmin[s, axis] for b, s in zip(bands, sel)]
                           + [b.high_arcmin[s, axis] for b, s in zip(bands, sel)] + sigma)
            ax.set_ylim(-limit, limit)
            ax.axhline(0.0, color="0.5", lw=0.5)
            ax.grid(True, alpha=0.3)
        full.set_xlim(0.0, t_end)
        tail.set_xlim(tail_start, t_end)
        full.set_ylabel(f"{AXIS_NAMES[axis]} error (arcmin)")
        tail.set_ylabel(f"{AXIS_NAMES[axis]} error (arcmin)")
    axes[0, 0].set_title("whole fine alignment")
    axes[0, 1].set_title(f"last {t_end - tail_start:g} s"
                         + (" (the RMS window)" if window < t_end else ""))
    for ax in axes[-1]:
        ax.set_xlabel("time since the start of fine alignment (s)")
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    extra = [(Patch(color="0.6", alpha=0.4), "5-95 % of the episodes not diverged"),
             (Line2D([], [], color="0.3", linestyle=SIGMA_DASH, lw=0.9),
              "filter's mean +-3 sigma"),
             (Line2D([], [], color="0.3", lw=0.6, alpha=0.6, marker="x", markevery=[-1]),
              "a diverged episode")]
    fig.legend([h for h, _ in handles + extra], [label for _, label in handles + extra],
               loc="upper center", ncol=min(4, len(handles) + len(extra)), fontsize=8,
               frameon=False, bbox_to_anchor=(0.5, 0.97))
    fig.suptitle(title + " (line: median)")
    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.06, top=0.87, hspace=0.1,
                        wspace=0.16)   # fixed: tight_layout would double the cost
    save_figure(fig, path, dpi=DPI, **PNG_OPTIONS)
    plt.close(fig)
    return path


FLIER = {"marker": "o", "markersize": 3, "markerfacecolor": "none",
         "markeredgecolor": "k", "linestyle": "none"}
"""The box plot's fliers: an episode beyond the 5-95 % whiskers."""


def plot_final_errors(result, start: str, path: Path, twins: dict | None = None) -> Path:
    """final_error_<start>.png: per axis, a box per filter of the final error (arcmin) of
    the episodes not diverged (box: quartiles, line: median, whiskers: 5-95 %, open
    circles beyond); the diverged ones as black x, clamped to the panel (triangles) when
    off it. A legend explains each marker drawn."""
    plt = pyplot()
    runs = [r for r in result.runs if r.start == start]
    fig, axes = subplots(1, 3, figsize=(13, 4.8))
    positions = np.arange(1, len(runs) + 1)
    drawn = {"flier": False, "x": False, "off": False}
    for axis, ax in enumerate(axes):
        kept, values = [], []
        for i, run in enumerate(runs):
            ok = ~np.asarray(run.diverged, bool)
            final = run.error_n[:, -1, axis] / arcmin
            kept.append(final[ok] if ok.any() else np.array([np.nan]))
            values.append(final[ok])
        boxes = ax.boxplot(kept, positions=positions, whis=(5, 95), widths=0.6,
                           patch_artist=True, flierprops=FLIER)
        drawn["flier"] |= any(len(f.get_ydata()) for f in boxes["fliers"])
        for i, patch in enumerate(boxes["boxes"]):
            patch.set(facecolor=line_style(i)["color"], alpha=0.45)
        for median in boxes["medians"]:
            median.set(color="k", lw=1.5)
        limit = _limit(values)
        ax.set_ylim(-limit, limit)
        for i, run in enumerate(runs):
            bad = run.error_n[np.asarray(run.diverged, bool), -1, axis] / arcmin
            inside = np.abs(bad) <= limit
            ax.plot(np.full(inside.sum(), positions[i]), bad[inside], "kx", markersize=7)
            drawn["x"] |= bool(inside.any())
            drawn["off"] |= bool((~inside).any())
            for value in bad[~inside]:
                ax.plot(positions[i], np.sign(value) * limit * 0.97,
                        "k^" if value > 0 else "kv", markersize=7)
        ax.set_xticks(positions)
        ax.set_xticklabels([run.filter + _twin(twins, run)
                            + (f"\n{int(np.sum(run.diverged))} diverged"
                               if np.any(run.diverged) else "")
                            for run in runs], fontsize=8)
        ax.axhline(0.0, color="0.5", lw=0.5)
        ax.set_title(f"{AXIS_NAMES[axis]}")
        ax.set_ylabel("final error (arcmin)")
        ax.grid(True, axis="y", alpha=0.3)
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    legend = [(Patch(facecolor="0.6", edgecolor="k", alpha=0.6), "quartiles"),
              (Line2D([], [], color="k", lw=2.0), "median"),
              (Line2D([], [], color="k", lw=0.8), "whiskers: 5-95 %")]
    legend += [(Line2D([], [], **FLIER), "an episode beyond the whiskers")] * drawn["flier"]
    legend += [(Line2D([], [], color="k", marker="x", markersize=7, linestyle="none"),
                "a diverged episode")] * drawn["x"]
    legend += [(tuple(Line2D([], [], color="k", marker=m, markersize=7, linestyle="none")
                      for m in "^v"),
                "one off the panel (up, down)")] * drawn["off"]
    from matplotlib.legend_handler import HandlerTuple
    fig.legend([h for h, _ in legend], [label for _, label in legend], loc="upper center",
               ncol=3, fontsize=8, frameon=False, bbox_to_anchor=(0.5, 0.945),
               handler_map={tuple: HandlerTuple(ndivide=None)})
    fig.suptitle(f"Final attitude error from the {start} start, {len(result.seeds)} episodes "
                 "(boxes: those not diverged)")
    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.15, top=0.8, wspace=0.3)
    save_figure(fig, path, dpi=DPI, **PNG_OPTIONS)
    plt.close(fig)
    return path


def plot_heading_convergence(cdfs: list[ConvergenceCdf], threshold_arcmin: float,
                             start: str, path: Path, twins: dict | None = None) -> Path:
    """heading_convergence_<start>.png: per filter the percentage of all episodes whose
    heading has converged by time t (a step at each episode's convergence time); the
    curve ends below 100 % by the diverged and the never converged episodes."""
    plt = pyplot()
    fig, ax = subplots(figsize=(12, 5))
    for i, cdf in enumerate(cdfs):
        times = np.concatenate([[0.0], cdf.times, [cdf.t_end]])
        percent = 100.0 * np.concatenate([[0.0], np.arange(1, cdf.times.size + 1),
                                          [cdf.times.size]]) / cdf.episodes
        label = (f"{cdf.filter}{_twin(twins, cdf)}: {cdf.times.size} of {cdf.episodes} "
                 "converged"
                 + (f", {cdf.not_converged} not" if cdf.not_converged else "")
                 + (f", {cdf.diverged} diverged" if cdf.diverged else ""))
        ax.step(times, percent, where="post", lw=1.8, label=label, **line_style(i))
    ax.set_xlim(0.0, max(c.t_end for c in cdfs))
    ax.set_ylim(-2.0, 102.0)
    ax.set_xlabel("time since the start of fine alignment (s)")
    ax.set_ylabel("episodes converged (% of all)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.set_title(f"Heading convergence from the {start} start: |heading error| <= "
                 f"{threshold_arcmin:g}' from then to the end")
    fig.subplots_adjust(left=0.07, right=0.7, bottom=0.11, top=0.92)
    save_figure(fig, path, dpi=DPI, **PNG_OPTIONS)
    plt.close(fig)
    return path


STRIP = 0.022
"""Height of a filter's strip of epochs outside its band (a fraction of the panel)."""


def _strips(ax, excursions: list[NeesExcursion], colors: list[str]) -> dict[str, bool]:
    """Per excursion with epochs outside its band, a strip in its colour along the top
    (above the band) and one along the bottom (below), in stacked lanes; one collection,
    in axes coordinates for y (no effect on the scale). Returns which kinds were drawn."""
    from matplotlib.collections import PolyCollection
    verts, faces, lanes = [], [], {"above": 0, "below": 0}
    for excursion, color in zip(excursions, colors):
        for kind, mask in (("above", excursion.above), ("below", excursion.below)):
            spans = excursion.spans(mask)
            if not spans:
                continue
            lane = lanes[kind]
            lanes[kind] += 1
            y0 = 1.0 - (lane + 1) * STRIP if kind == "above" else lane * STRIP
            y1 = y0 + 0.8 * STRIP
            verts += [[(x, y0), (x + w, y0), (x + w, y1), (x, y1)] for x, w in spans]
            faces += [color] * len(spans)
    if verts:
        ax.add_collection(PolyCollection(verts, facecolors=faces, edgecolors="none",
                                         transform=ax.get_xaxis_transform()),
                          autolim=False)
    return {kind: bool(n) for kind, n in lanes.items()}


def _excursion_label(excursion: NeesExcursion) -> str:
    if excursion.first_time_outside is None:
        return "\n  inside its band at every epoch" if excursion.band else ""
    return (f"\n  above band {as_percent(excursion.fraction_above)}, below "
            f"{as_percent(excursion.fraction_below)} of epochs; out at "
            f"{excursion.first_time_outside:.4g} s")


def plot_nees(curves: list[NeesCurve], dof: int, start: str, path: Path,
              probability: float = 0.95, twins: dict | None = None) -> Path:
    """nees_<start>.png: top, the mean NEES over the episodes not diverged with the
    chi-square band of a mean of that many consistent episodes, each filter's epochs
    outside its band as a strip in its colour along the top (above) or the bottom (below)
    and their fraction in its legend entry (``nees_excursions``); bottom, the median with
    its order-statistics band (the filters named in the mean panel's legend only; log
    scale; dashed: the expected value ``dof``). The grey
    band is for the most common episode count; a filter with another count has its own
    band edges as thin lines."""
    plt = pyplot()
    from matplotlib.patches import Patch
    from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator
    fig, axes = subplots(2, 1, figsize=(13, 8), sharex=True)
    counts = [c.episodes for c in curves if c.episodes]
    common = max(set(counts), key=counts.count) if counts else 0
    t_end = max(float(c.t[-1]) for c in curves)
    excursions = nees_excursions(curves, dof, probability)
    percent = f"{100.0 * probability:g} %"
    for ax, stat, band, name in ((axes[0], "mean", mean_nees_band, "mean"),
                                 (axes[1], "median", median_nees_band, "median")):
        if common:
            low, high = band(dof, common, probability)
            how = (f"chi2({common * dof})/{common}" if stat == "mean"
                   else f"order stat. of chi2({dof})")
            ax.axhspan(low, high, color="0.6", alpha=0.3, lw=0,
                       label=f"{percent} band, {name} of {common} episodes x {dof} "
                       f"states:\n  {how} in [{low:.3g}, {high:.3g}]")
        ax.axhline(dof, color="0.3", lw=0.8, ls="--",
                   label=f"expected: {dof} (states)")
        for i, (curve, excursion) in enumerate(zip(curves, excursions)):
            style = line_style(i)
            step = _stride(curve.t.size)
            values = getattr(curve, stat)
            label = (f"{curve.filter}{_twin(twins, curve)} ({curve.episodes} episodes"
                     + (f", {curve.diverged} diverged left out" if curve.diverged else "")
                     + ")" + _excursion_label(excursion) if stat == "mean" else None)
            ax.plot(curve.t[::step], values[::step], lw=1.6, label=label, **style)
            if curve.episodes and curve.episodes != common:
                for k, edge in enumerate(band(dof, curve.episodes, probability)):
                    ax.axhline(edge, color=style["color"], lw=0.7, alpha=0.8,
                               label=f"{curve.filter}: its band ({curve.episodes} episodes)"
                               if k == 0 else None)
        handles, labels = ax.get_legend_handles_labels()
        if stat == "median":
            from matplotlib.lines import Line2D
            handles.append(Line2D([], [], color="none"))
            labels.append("filters: the mean panel's lines")
        if stat == "mean":
            own = [(e, line_style(i)["color"]) for i, e in enumerate(excursions)
                   if not _twin(twins, e)]            # a twin's strips are its original's
            drawn = _strips(ax, [e for e, _ in own], [c for _, c in own])
            for kind, where in (("above", "top"), ("below", "bottom")):
                if drawn[kind]:
                    handles.append(Patch(facecolor="0.35"))
                    labels.append(f"{where} strip: epochs {kind} band\n  (filter's colour)")
        ax.set_yscale("log")
        ax.yaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_locator(NullLocator())   # 1-2-5 grid: no minor ticks to draw
        ax.set_ylabel(f"{name} NEES (dimensionless, log scale)")
        ax.grid(True, alpha=0.3)
        ax.legend(handles, labels, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                  frameon=False)
    axes[0].set_xlim(0.0, t_end)
    axes[-1].set_xlabel("time since the start of fine alignment (s)")
    axes[0].set_title(f"NEES of the {dof} states the truth knows, {start} start "
                      "(episodes not diverged)")
    fig.subplots_adjust(left=0.07, right=0.7, bottom=0.07, top=0.95, hspace=0.08)
    save_figure(fig, path, dpi=DPI, **PNG_OPTIONS)
    plt.close(fig)
    return path
