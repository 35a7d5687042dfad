"""``aligngym report DIR``: one self-contained HTML page of a campaign directory.

The page holds the scenario and its TOML, the settings and the command line, the
paper-shaped tables (``tables.txt``), a per-filter summary of the tidy table
(``results.csv``), the mean NEES against its chi-square band (summary.json's
"nees_band"), the coarse-alignment errors (``coarse.csv``), the data faults flagged
and every figure (PNG) of the directory, embedded as base64 data URIs: no external
resource, so the file can be mailed or attached as it is. A directory of campaign
directories (``bench paper004 --swing all --out DIR``) gives one page with a section
each. Here the page is rendered; the files are read and checked (a one-line refusal
naming the file and what to do) by ``report_inputs``.
"""
from __future__ import annotations

import base64
import csv
import io
import json
from html import escape
from pathlib import Path

import numpy as np

from aligngym.estimators.metrics import STATUSES
from aligngym.scenarios.atomic import write_text
from aligngym.scenarios.config import ConfigError
from aligngym.scenarios.figure_statistics import as_percent
from aligngym.scenarios.figure_captions import FIGURE_CAPTIONS, figure_caption
from aligngym.scenarios.report_inputs import (PNG_SIGNATURE, _number, _read_results,
                                              _read_settings, _read_summary, _read_text,
                                              _refuse, campaign_dirs)

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1300px;
       padding: 0 1em; color: #222; }
h1 { font-size: 1.6em; } h2 { border-bottom: 2px solid #0072B2; padding-bottom: .2em; }
pre { background: #f5f5f5; padding: .8em; overflow-x: auto; font-size: .85em; }
table { border-collapse: collapse; font-size: .85em; margin: .5em 0 1em; }
th, td { border: 1px solid #ccc; padding: .25em .6em; text-align: left; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
th { background: #eef3f8; }
figure { margin: 1.5em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: .9em; color: #444; max-width: 70em; }
.note { color: #555; font-size: .9em; }
"""


def write_report(directory: str | Path) -> Path:
    """Write DIR/report.html (module docstring); returns its path."""
    root = Path(directory)
    text = render_report(root)
    path = root / "report.html"
    try:
        write_text(path, text)
    except OSError as exc:
        raise ConfigError(f"report DIR {root}: cannot write report.html "
                          f"({exc.strerror})") from None
    return path


def render_report(directory: str | Path) -> str:
    """The report page of a campaign directory (or a directory of them), as HTML text."""
    root = Path(directory)
    dirs = campaign_dirs(root)
    sections = [_campaign_section(d, d.name if d != root else "") for d in dirs]
    settings = [_read_settings(d) for d in dirs]
    title = "aligngym campaign: " + ", ".join(
        dict.fromkeys(f"{s['paper']} on {s['scenario']}" for s in settings))
    toc = ""
    if len(dirs) > 1:
        toc = "<ul>" + "".join(f'<li><a href="#{escape(_anchor(d.name))}">'
                               f"{escape(d.name)}</a></li>" for d in dirs) + "</ul>"
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
            f"<title>{escape(title)}</title>\n<link rel=\"icon\" href=\"data:,\">\n"
            f"<style>{STYLE}</style>\n</head>\n<body>\n<h1>{escape(title)}</h1>\n"
            f"<p class=\"note\">Report of {escape(str(root.resolve()))}; each figure and "
            "table below is read from that directory.</p>\n" + toc
            + "\n".join(sections) + "\n</body>\n</html>\n")


def _anchor(name: str) -> str:
    return "campaign-" + "".join(c if c.isalnum() else "-" for c in name)


def _campaign_section(directory: Path, name: str) -> str:
    settings = _read_settings(directory)
    heading = f"{settings['paper']} on {settings['scenario']}" + (f": {name}" if name else "")
    parts = [f'<section id="{escape(_anchor(name or "main"))}">',
             f"<h2>{escape(heading)}</h2>", "<h3>Settings</h3>", _settings_table(settings)]
    if settings.get("command"):
        parts += ["<h3>Command line</h3>",
                  f"<pre>{escape(' '.join(map(str, settings['command'])))}</pre>"]
    if settings.get("scenario_toml"):
        parts += [f"<h3>Scenario {escape(settings['scenario'])}</h3>",
                  f"<details><summary>{escape(str(settings.get('scenario_file', '')))}"
                  f"</summary><pre>{escape(settings['scenario_toml'])}</pre></details>"]
    parts += ["<h3>Paper-shaped tables</h3>",
              f"<pre class=\"tables\">{escape(_read_text(directory / 'tables.txt'))}</pre>",
              "<h3>Results by filter and start</h3>",
              "<p class=\"note\">From results.csv (one row per episode, filter and start); "
              "final errors and NEES over the episodes not diverged: median, and in "
              "brackets the 95th percentile of |final error| or the 90th of the "
              "convergence time.</p>",
              _results_summary(directory / "results.csv")]
    if (directory / "coarse.csv").is_file():
        parts += ["<h3>Coarse alignment error per episode</h3>",
                  "<details><summary>coarse.csv</summary>"
                  + _csv_table(directory / "coarse.csv") + "</details>"]
    summary = (_read_summary(directory / "summary.json")
               if (directory / "summary.json").is_file() else {})
    nees_band = _nees_band(summary)
    if nees_band:
        parts += ["<h3>Mean NEES against its band</h3>",
                  "<p class=\"note\">From summary.json (\"nees_band\"): per filter and start, "
                  "the epochs where the mean NEES of the episodes not diverged is outside the "
                  "two-sided chi-square band of a mean of that many consistent episodes "
                  "(chi-square(episodes x states) / episodes), as the NEES figure's strips "
                  "mark them.</p>", nees_band]
    faults = _faults(summary) if summary else ""
    if faults:
        parts += ["<h3>Data faults flagged</h3>", f"<p>{escape(faults)}</p>"]
    parts += ["<h3>Figures</h3>"]
    parts += [_figure(path) for path in _figures(directory, settings.get("starts", []))]
    parts.append("</section>")
    return "\n".join(parts)


def _settings_table(settings: dict) -> str:
    rows = [("paper", settings["paper"]), ("scenario", settings["scenario"]),
            ("campaign seed", settings.get("seed")),
            ("episodes", settings.get("episodes")),
            ("filters", ", ".join(settings.get("filters", []))),
            ("starting errors", ", ".join(settings.get("starts", []))),
            ("NEES states", settings.get("nees_dof"))]
    rows += [(f"experiment: {k}", v) for k, v in settings["experiment"].items()]
    rows += [(f"version: {k}", v) for k, v in settings.get("versions", {}).items()]
    rows += [("platform", settings.get("platform")), ("written (UTC)",
                                                      settings.get("written_utc"))]
    return ("<table class=\"kv\">" + "".join(
        f"<tr><th>{escape(str(k))}</th><td>{escape(_text(v))}</td></tr>" for k, v in rows)
        + "</table>")


def _text(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, (list, tuple, dict)):
        return json.dumps(value)
    return str(value)


def _results_summary(path: Path) -> str:
    """Per (filter, start): episodes, how many in each status (converged, not converged,
    diverged, lost: docs/estimators.md), |final error| E, N, U median [p95] and heading
    convergence median [p90] (s), NEES mean (median over episodes), covariance repairs,
    ms per epoch (``_ms_per_epoch``); over the episodes not diverged."""
    rows = _read_results(path)
    groups: dict[tuple[str, str], list[dict]] = {}
    for row in rows:
        groups.setdefault((row["filter"], row["start"]), []).append(row)
    head = ["filter", "start", "episodes", *STATUSES, "|final E| (')", "|final N| (')",
            "|final U| (')", "heading convergence (s)", "NEES mean", "covariance repairs",
            "ms / epoch"]
    body = []
    for (name, start), group in groups.items():
        status = [r.get("status") or ("diverged" if r["diverged"] == "True" else "")
                  for r in group]                  # a directory from before the statuses
        diverged = np.array([st == "diverged" for st in status])
        ok = [r for r, d in zip(group, diverged) if not d]
        col = lambda key: np.array([_number(r[key]) for r in ok])  # noqa: E731

        def stat(key: str, q: float, absolute: bool = True) -> str:
            values = col(key)
            values = np.abs(values) if absolute else values
            values = values[np.isfinite(values)]
            if not values.size:
                return "-"
            return f"{np.median(values):.4g} [{np.percentile(values, q):.4g}]"

        nees = col("nees_mean")
        nees = nees[np.isfinite(nees)]
        cells = [name, start, str(len(group)),
                 *("-" if "" in status and st != "diverged" else str(status.count(st))
                   for st in STATUSES),
                 *(stat(f"final_{a}_arcmin", 95) for a in ("phi_E", "phi_N", "phi_U")),
                 stat("heading_convergence_s", 90, absolute=False),
                 f"{np.median(nees):.4g}" if nees.size else "-",
                 str(int(sum(_number(r["covariance_repairs"]) for r in group))),
                 _ms_per_epoch(group)]
        body.append("<tr>" + "".join(
            ("<td>" if i < 2 else '<td class="num">') + escape(c) + "</td>"
            for i, c in enumerate(cells)) + "</tr>")
    return ("<table class=\"results\"><tr>" + "".join(f"<th>{escape(h)}</th>" for h in head)
            + "</tr>" + "".join(body) + "</table>")


def _ms_per_epoch(group: list[dict]) -> str:
    """The mean ms per epoch of a filter's rows, and the chunks its batch ran in where
    more than one (their times summed, each paying the fixed cost an epoch: not the time
    of one batch; results.csv's ms_per_epoch_chunks, absent from older directories)."""
    ms = f"{np.nanmean([_number(r['ms_per_epoch']) for r in group]):.3g}"
    counts = [_number(r.get("ms_per_epoch_chunks") or "1") for r in group]
    chunks = max((int(c) for c in counts if np.isfinite(c)), default=1)
    return ms + (f" (sum of {chunks} chunks)" if chunks > 1 else "")


def _csv_table(path: Path) -> str:
    try:
        rows = list(csv.reader(io.StringIO(_read_text(path), newline="")))
    except csv.Error as exc:
        raise _refuse(path, f"is not CSV ({exc})") from None
    if not rows:
        return "<p>(empty)</p>"
    return ("<table><tr>" + "".join(f"<th>{escape(h)}</th>" for h in rows[0]) + "</tr>"
            + "".join("<tr>" + "".join(f"<td class=\"num\">{escape(c)}</td>" for c in row)
                      + "</tr>" for row in rows[1:]) + "</table>")


def _nees_band(summary: dict) -> str:
    """A table, per filter and start, of the mean NEES against its band, from
    summary.json's "nees_band" (``figure_statistics.nees_band_summary``; '' without one)."""
    bands = summary.get("nees_band") or {}
    percent = lambda v: "-" if v is None else as_percent(v)  # noqa: E731
    head = ["filter", "start", "band", "above", "below", "first outside (s)", "in words"]
    rows = []
    for name, per_start in bands.items():
        for start, entry in per_start.items():
            band = entry.get("band")
            first = entry.get("first_time_outside_s")
            cells = [name, start,
                     "-" if not band or None in band else (
                         f"{_g(entry.get('probability', 0.95), 100.0)} %: "
                         f"[{band[0]:.3g}, {band[1]:.3g}]"),
                     percent(entry.get("fraction_of_epochs_above")),
                     percent(entry.get("fraction_of_epochs_below")),
                     "-" if first is None else f"{first:.4g}", f"{name}: {entry.get('text', '')}"]
            rows.append("<tr>" + "".join(
                ("<td>" if i in (0, 1, 6) else '<td class="num">') + escape(str(c)) + "</td>"
                for i, c in enumerate(cells)) + "</tr>")
    if not rows:
        return ""
    return ("<table class=\"nees-band\"><tr>" + "".join(f"<th>{escape(h)}</th>" for h in head)
            + "</tr>" + "".join(rows) + "</table>")


def _g(value, scale: float = 1.0) -> str:
    """A number of summary.json as text ("-" for null, a number that was not finite)."""
    return "-" if value is None else f"{scale * value:g}"


def _faults(summary: dict) -> str:
    """A sentence on the data faults flagged, from summary.json's "data_faults"."""
    faults = summary.get("data_faults", {})
    if not faults.get("flagged_episodes"):
        return "No data fault flagged."
    kinds = ", ".join(f"{k} {n}" for k, n in sorted(faults.get("by_kind", {}).items()))
    return (f"{faults['flagged_episodes']} of {faults['episodes']} episodes flagged "
            f"({kinds}); IMU data are repaired before the filters, the other faults "
            "are left to them.")


def _figures(directory: Path, starts: list[str]) -> list[Path]:
    """Every PNG of the directory: the campaign figures per start in the order of
    ``FIGURE_CAPTIONS``, then the others by name."""
    pngs = sorted(directory.glob("*.png"))
    first = [directory / f"{kind}_{start}.png" for start in starts for kind in FIGURE_CAPTIONS]
    ordered = [p for p in first if p in pngs]
    return ordered + [p for p in pngs if p not in ordered]


def _figure(path: Path) -> str:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise _refuse(path, f"cannot be read ({exc.strerror or exc})") from None
    if not raw.startswith(PNG_SIGNATURE):
        raise ConfigError(f"report {path}: not a PNG image (a damaged or foreign file); "
                          "delete it (bench ... --resume without --no-figures draws the "
                          "campaign's figures again)")
    data = base64.b64encode(raw).decode("ascii")
    return (f'<figure><img src="data:image/png;base64,{data}" alt="{escape(path.name)}">'
            f"<figcaption><b>{escape(path.name)}</b>: {escape(figure_caption(path.name))}"
            "</figcaption></figure>")
